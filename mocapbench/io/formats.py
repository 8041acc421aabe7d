"""Read and write motion files by suffix, with their unit and up axis recorded and checked.

One entry point for every command that reads or writes motion (``compress``, ``decompress``, ``compare``,
``fit``, ...), so that ``--units``/``--up`` mean the same everywhere. Both dispatch through the one table of
formats, :data:`mocapbench.io.format_table.FORMATS`; what its rows do:

===========  ===============  ================================  ==========================================
suffix       read             default unit                      write
===========  ===============  ================================  ==========================================
``.bvh``     yes              cm (``--units`` to change)         yes, in the source unit (or ``--units``)
``.amc``     yes (+ ``.asf``)  the ASF's ``:units length``       no
``.gltf``    yes              m (the glTF standard)             yes, in m, Y-up (a glTF viewer plays it)
``.glb``     yes              m                                 yes, binary glTF
``.fbx``     yes (ufbx)       the file's UnitScaleFactor        no
===========  ===============  ================================  ==========================================
"""

from __future__ import annotations

from pathlib import Path

from mocapbench.io.format_table import FORMATS, READ_SUFFIXES, WRITE_SUFFIXES, ReadRequest, default_unit_source
from mocapbench.io.text import MotionFileNotFoundError
from mocapbench.io.units import parse_units, rest_height_warning, with_source
from mocapbench.motion import Motion, MotionFormatError

__all__ = ["READ_SUFFIXES", "WRITE_SUFFIXES", "UnitCheckError", "default_unit_source", "read_motion", "write_motion"]

class UnitCheckError(MotionFormatError):
    """Under ``--strict``, a file whose body is not a body's size in the unit it is read with."""


def read_motion(
    path: str | Path,
    *,
    units: str | float | None = None,
    up: str | None = None,
    asf: str | Path | None = None,
    drop_first_frame: bool = False,
    fps: float | None = None,
    strict: bool = False,
) -> tuple[Motion, list[str]]:
    """Read a BVH, AMC, glTF, GLB or FBX file into a Motion in cm, with its source unit and up axis set.

    Parameters
    ----------
    path : str or Path
    units : str or float, optional, keyword-only
        ``--units``: a unit name or cm per unit (:func:`mocapbench.io.units.parse_units`). Default: the sidecar's
        (``FILE.units`` beside the file, :func:`mocapbench.io.unit_choice.read_sidecar`), else cm for BVH, m for
        glTF/GLB, the ASF's own for AMC, the file's own for FBX.
    up : str, optional, keyword-only
        ``"y"`` or ``"z"``; default the sidecar's, else detected from the frames
        (:func:`mocapbench.io.units.detect_up_axis`; glTF is always Y-up, FBX says its own).
    asf : str or Path, optional, keyword-only
        Skeleton of an AMC file; default the ``.asf`` beside it.
    drop_first_frame : bool, keyword-only
        Drop frame 0 of a BVH file (the CMU reference pose).
    fps : float, optional, keyword-only
        Sampling rate of a glTF animation (default: its key spacing); the frame rate of an AMC file (default 120).
    strict : bool, keyword-only
        ``--strict``: a unit warning is an error (:class:`UnitCheckError`) instead of a line in ``warnings``.

    Returns
    -------
    motion : Motion
        ``source_unit_cm`` and ``up_axis`` set.
    warnings : list of str
        One line each (a rest height that is not a body's), for the command to print.

    Raises
    ------
    MotionFormatError
        A missing, unknown or malformed file, in one line naming it.
    ValueError
        A bad ``units`` or ``up`` value, or a bad sidecar, in one line.
    UnitCheckError
        With ``strict``: the size of the body says the unit is wrong (the warning's line).
    """
    from mocapbench.io.unit_choice import read_sidecar
    from mocapbench.io.units import parse_up_axis

    path = Path(path)
    if not path.exists():
        raise MotionFileNotFoundError(f"{path}: no such file.")
    if units is None or up is None:
        sidecar = read_sidecar(path)
        units = sidecar.get("units") if units is None else units
        up = sidecar.get("up") if up is None else up
    unit_cm = None if units is None else parse_units(units)
    up_axis = None if up is None else parse_up_axis(up)
    suffix = path.suffix.lower()
    row = FORMATS.get(suffix)
    if row is None:
        raise MotionFormatError(
            f"{path}: expected a motion file ({', '.join(READ_SUFFIXES)}), got {suffix or 'no extension'}."
        )
    request = ReadRequest(unit_cm, up_axis, Path(asf) if asf else None, drop_first_frame, fps)
    motion, unit_cm, up_axis = row.read(path, request)
    motion = with_source(motion, unit_cm=unit_cm, up_axis=up_axis)
    warning = rest_height_warning(motion)
    if warning and strict:
        raise UnitCheckError(f"{path}: {warning} (--strict)")
    return motion, [f"{path}: {warning}"] if warning else []


def write_motion(motion: Motion, path: str | Path, *, units: str | float | None = None, force: bool = False) -> Path:
    """Write ``motion`` as BVH (in ``motion.source_unit_cm`` unless ``units``) or glTF/GLB (in m, Y-up).

    Raises
    ------
    MotionFormatError
        An unknown suffix, in one line listing the known ones.
    """
    path = Path(path)
    unit_cm = None if units is None else parse_units(units)
    suffix = path.suffix.lower()
    row = FORMATS.get(suffix)
    if row is None or row.write is None:
        raise MotionFormatError(
            f"{path}: expected a {', '.join(WRITE_SUFFIXES)} output, got {suffix or 'no extension'}."
        )
    return row.write(motion, path, unit_cm, force)
