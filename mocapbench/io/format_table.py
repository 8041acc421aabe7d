"""The motion file formats by suffix: how each is read, how (if at all) it is written, where its unit comes from.

The lowest module of the readers: one row of :data:`FORMATS` per suffix, which
:func:`mocapbench.io.formats.read_motion` and :func:`~mocapbench.io.formats.write_motion` dispatch through and
:mod:`mocapbench.io.unit_choice` asks where a unit came from; adding a format is adding a row. Each row's reader
imports its format's module on first use, so importing the table costs nothing.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:
    from mocapbench.motion import Motion

__all__ = ["FORMATS", "READ_SUFFIXES", "WRITE_SUFFIXES", "MotionFormat", "ReadRequest", "default_unit_source",
           "motion_files"]

GLTF_UNIT_CM = 100.0  # glTF 2.0: "the units for all linear distances are meters"


@dataclass(frozen=True)
class ReadRequest:
    """What the caller of :func:`~mocapbench.io.formats.read_motion` asked for, before the file is read.

    Attributes
    ----------
    unit_cm : float or None
        cm per file unit from ``--units`` or the sidecar; ``None``: the format's own.
    up_axis : str or None
        ``"y"`` or ``"z"`` from ``--up`` or the sidecar; ``None``: the format's own, else detected.
    asf : Path or None
        The skeleton of an AMC file; ``None``: the ``.asf`` beside it.
    drop_first_frame : bool
        Drop frame 0 of a BVH file (the CMU reference pose).
    fps : float or None
        Sampling rate of a glTF or FBX animation, frame rate of an AMC file; ``None``: the file's own.
    """

    unit_cm: float | None = None
    up_axis: str | None = None
    asf: Path | None = None
    drop_first_frame: bool = False
    fps: float | None = None


#: ``read(path, request) -> (motion, unit_cm, up_axis)``: the motion in cm, the cm per file unit it was read with,
#: the up axis if the format (or the request) fixes it, else ``None`` (then detected from the frames).
Reader = Callable[[Path, ReadRequest], "tuple[Motion, float, str | None]"]
#: ``write(motion, path, unit_cm, force) -> path``: ``unit_cm`` from ``--units`` or ``None`` for the format's own.
Writer = Callable[["Motion", Path, "float | None", bool], Path]


@dataclass(frozen=True)
class MotionFormat:
    """One motion file format: its reader, its writer (``None``: read only) and where its unit comes from.

    Attributes
    ----------
    read : Reader
    write : Writer or None
    default_unit_source : str
        Where the unit of a file read without ``--units`` comes from, for reports.
    """

    read: Reader
    write: Writer | None
    default_unit_source: str


def _read_bvh(path: Path, request: ReadRequest):
    from mocapbench.io.bvh import read_bvh

    unit_cm = request.unit_cm or 1.0
    return read_bvh(path, length_unit_cm=unit_cm, drop_first_frame=request.drop_first_frame), unit_cm, request.up_axis


def _write_bvh(motion: Motion, path: Path, unit_cm: float | None, force: bool) -> Path:
    from mocapbench.io.bvh import write_bvh

    return write_bvh(motion, path, length_unit_cm=unit_cm or motion.source_unit_cm, overwrite=force)


def _read_amc(path: Path, request: ReadRequest):
    from mocapbench.io.asf_amc import find_asf, read_amc, read_asf

    skeleton = read_asf(request.asf or find_asf(path), cm_per_unit=request.unit_cm)
    motion = read_amc(path, skeleton, **({"fps": request.fps} if request.fps else {}))
    return motion, skeleton.cm_per_unit, request.up_axis


def _read_gltf(path: Path, request: ReadRequest):
    from mocapbench.io.gltf import read_gltf

    unit_cm = request.unit_cm or GLTF_UNIT_CM
    return read_gltf(path, length_unit_cm=unit_cm, fps=request.fps), unit_cm, request.up_axis or "y"


def _write_gltf(motion: Motion, path: Path, unit_cm: float | None, force: bool) -> Path:
    from mocapbench.io.gltf import write_gltf

    return write_gltf(motion, path, length_unit_cm=unit_cm or GLTF_UNIT_CM, force=force)


def _read_fbx(path: Path, request: ReadRequest):
    from mocapbench.io.fbx import read_fbx

    motion = read_fbx(path, length_unit_cm=request.unit_cm, fps=request.fps)
    return motion, motion.source_unit_cm, request.up_axis or motion.up_axis


#: The one table: suffix (lower case) -> format, in the order messages list them. Only BVH has no unit of its own.
FORMATS: dict[str, MotionFormat] = {
    ".bvh": MotionFormat(_read_bvh, _write_bvh, "default; --units to change"),
    ".amc": MotionFormat(_read_amc, None, "declared by the ASF's :units length"),
    ".gltf": MotionFormat(_read_gltf, _write_gltf, "the glTF standard: metres"),
    ".glb": MotionFormat(_read_gltf, _write_gltf, "the glTF standard: metres"),
    ".fbx": MotionFormat(_read_fbx, None, "declared by the file's UnitScaleFactor"),
}
READ_SUFFIXES = tuple(FORMATS)
WRITE_SUFFIXES = tuple(suffix for suffix, row in FORMATS.items() if row.write is not None)


def default_unit_source(path: str | Path) -> str:
    """Where :func:`~mocapbench.io.formats.read_motion` takes a file's unit from when no ``--units`` or sidecar says
    it, for reports: ``"declared by the file's UnitScaleFactor"`` for FBX, ``"default; --units to change"`` for BVH
    (the one format that declares no unit), ...; ``"the format's default"`` for another suffix."""
    row = FORMATS.get(Path(path).suffix.lower())
    return row.default_unit_source if row else "the format's default"


def motion_files(paths, suffixes: tuple[str, ...] = READ_SUFFIXES, *, recurse: bool = False) -> list[Path]:
    """The motion files of ``paths``: a file as given, a folder's files with a readable suffix in path order.

    The one place a folder argument becomes files (``fit``, ``compare`` and the ``folder`` dataset), so that every
    command reads the same formats of a folder. A folder's other files are ignored; its sub-folders too unless
    ``recurse`` (``fit`` and ``compare`` recurse unless ``--no-recurse``). A link inside a folder is not followed.

    Parameters
    ----------
    paths : iterable of str or Path
    suffixes : tuple of str, optional
        Lower-case suffixes a folder contributes (default every readable format, ``.fbx`` included).
    recurse : bool, keyword-only
        Search the sub-folders too.
    """
    files: list[Path] = []
    for path in map(Path, paths):
        if path.is_dir():
            found = path.rglob("*") if recurse else path.iterdir()
            files += sorted(p for p in found if p.suffix.lower() in suffixes and p.is_file() and not p.is_symlink())
        else:
            files.append(path)
    return files
