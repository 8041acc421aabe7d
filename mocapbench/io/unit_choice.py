"""Which unit and up axis each file of a run is read with: ``--units`` per file, a sidecar beside the file, a default.

A run over many files (``compare``, ``fit``) can hold files in different units. The unit of one file comes from,
first to last:

1. ``--units FILE:UNIT`` on the command line (``FILE`` a path, or a bare file name that matches that name in any
   folder);
2. a sidecar beside the file, ``FILE.units`` (e.g. ``walk.bvh.units``), holding ``units: inch`` and/or ``up: z``
   lines (a bare unit on the first line also works);
3. ``--units UNIT`` without a file: every other file;
4. the format's own default (:func:`mocapbench.io.formats.read_motion`).

The up axis follows the same order (``--up`` has no per-file form; the sidecar's ``up:`` gives one).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from pathlib import Path

from mocapbench.io.format_table import default_unit_source
from mocapbench.io.units import parse_units, parse_up_axis

__all__ = ["SIDECAR_SUFFIX", "UnitChoice", "read_sidecar", "sidecar_path", "verdict"]

SIDECAR_SUFFIX = ".units"
_SIDECAR_MAX_BYTES = 4096  # a sidecar is a line or two; anything longer is not one


def sidecar_path(path: str | Path) -> Path:
    """``FILE.units`` beside ``FILE`` (the suffix appended: ``walk.bvh.units``)."""
    path = Path(path)
    return path.with_name(path.name + SIDECAR_SUFFIX)


def read_sidecar(path: str | Path) -> dict[str, str]:
    """The ``units`` and ``up`` a sidecar of ``path`` gives (empty when there is none).

    Raises
    ------
    ValueError
        A sidecar that is a link, too long, not text, or holds an unknown key or a bad value: one line naming it.
    """
    sidecar = sidecar_path(path)
    if not sidecar.exists() and not sidecar.is_symlink():
        return {}
    if sidecar.is_symlink() or not sidecar.is_file():
        raise ValueError(f"{sidecar}: a units sidecar must be a plain file, not a link or a folder.")
    with open(sidecar, "rb") as handle:
        data = handle.read(_SIDECAR_MAX_BYTES + 1)
    if len(data) > _SIDECAR_MAX_BYTES:
        raise ValueError(f"{sidecar}: a units sidecar holds a line or two, got over {_SIDECAR_MAX_BYTES} bytes.")
    try:
        lines = [line.split("#")[0].strip() for line in data.decode("utf-8").splitlines()]
    except UnicodeDecodeError:
        raise ValueError(f"{sidecar}: a units sidecar must be UTF-8 text (`units: inch`, `up: z`).") from None
    lines = [line for line in lines if line]
    values: dict[str, str] = {}
    for number, line in enumerate(lines, 1):
        key, sep, value = line.partition(":")
        key, value = (key.strip().lower(), value.strip()) if sep else ("units", line)
        if key not in ("units", "up") or not value or key in values:
            raise ValueError(f"{sidecar}: line {number}: expected `units: UNIT` or `up: y|z` once each, got {line!r}.")
        try:
            parse_units(value) if key == "units" else parse_up_axis(value)
        except ValueError as error:
            raise ValueError(f"{sidecar}: line {number}: {error}") from None
        values[key] = value
    return values


@dataclasses.dataclass(frozen=True)
class UnitChoice:
    """The ``--units`` and ``--up`` of a command, resolved per file (see the module's docstring).

    Attributes
    ----------
    default_units : str or None
        ``--units UNIT`` without a file.
    per_file : tuple of (file, unit)
        ``--units FILE:UNIT`` pairs, in the order given.
    up : str or None
        ``--up``.
    """

    default_units: str | None = None
    per_file: tuple[tuple[str, str], ...] = ()
    up: str | None = None

    @classmethod
    def parse(cls, values: str | Iterable[str] | None, up: str | None = None) -> UnitChoice:
        """From ``--units`` values (each ``UNIT`` or ``FILE:UNIT``; also comma-separated) and ``--up``.

        Raises
        ------
        ValueError
            A bad unit, or two defaults: one line naming the value.
        """
        if values is None:
            values = []
        elif isinstance(values, str):
            values = [values]
        default, pairs = None, []
        for value in (part.strip() for text in values for part in str(text).split(",")):
            if not value:
                continue
            file, sep, unit = value.rpartition(":")
            parse_units(unit)  # checked now: one line before any file is read
            if not sep:
                if default is not None and default != unit:
                    raise ValueError(f"--units: two units for every file ({default} and {unit}); name the file of "
                                     f"one of them (--units FILE:{unit}).")
                default = unit
            else:
                pairs.append((file, unit))
        return cls(default, tuple(pairs), None if up is None else parse_up_axis(up))

    def _match(self, path: Path) -> str | None:
        for file, unit in self.per_file:
            named = Path(file)
            same_name = named.name == path.name and named.parent == Path(".")
            if same_name or named.resolve() == path.resolve():
                return unit
        return None

    def units_for(self, path: str | Path) -> tuple[str | None, str]:
        """``(units to pass to read_motion, where it comes from)`` for one file.

        ``units`` is None when the sidecar (which :func:`~mocapbench.io.formats.read_motion` reads) or the format's
        default decides; the second item says which, for the per-file verdict.
        """
        path = Path(path)
        unit = self._match(path)
        if unit is not None:
            return unit, f"--units {path.name}:{unit}"
        sidecar = read_sidecar(path)
        if "units" in sidecar:
            return None, f"sidecar {sidecar_path(path).name}"
        if self.default_units is not None:
            return self.default_units, "--units"
        return None, default_unit_source(path)

    def unmatched(self, paths: Iterable[str | Path]) -> list[str]:
        """``FILE`` parts of ``--units FILE:UNIT`` that name none of ``paths`` (a typo the user must hear about)."""
        paths = [Path(p) for p in paths]
        return [file for file, _ in self.per_file
                if not any(UnitChoice(per_file=((file, "cm"),))._match(path) for path in paths)]


def verdict(path: str | Path, motion, unit_source: str, up_source: str | None, warnings: list[str]) -> str:
    """One line on how a file was read: its unit and where it came from, its up axis and why, its height or warning.

    ``walk.bvh: inch (sidecar walk.bvh.units), z up (detected: ...), 162 cm tall: ok``. ``up_source`` is None when
    the axis was detected (the reason is measured here), else where it came from (``"--up"``, ``"the file"``).
    """
    from mocapbench.io.units import body_shape, detect_up_axis, rest_up_axis, unit_label

    if up_source is None:
        up = f"{motion.up_axis} up (detected: {detect_up_axis(motion)[1]})"
    else:
        up = f"{motion.up_axis} up ({up_source})"
    height = body_shape(motion.skeleton, rest_up_axis(motion)).stature_cm
    status = "ok" if not warnings else "WARNING " + "; ".join(w.split(": ", 1)[-1] for w in warnings)
    return f"{Path(path).name}: {unit_label(motion.source_unit_cm)} ({unit_source}), {up}, {height:.0f} cm tall: {status}"
