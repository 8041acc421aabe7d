"""The motion file formats by suffix: which can be read and written, and where a file's unit comes from.

The lowest module of the readers: :mod:`mocapbench.io.formats` reads and writes by these suffixes and
:mod:`mocapbench.io.unit_choice` says where a unit came from; neither imports the other for them.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["READ_SUFFIXES", "WRITE_SUFFIXES", "default_unit_source"]

READ_SUFFIXES = (".bvh", ".amc", ".gltf", ".glb", ".fbx")
WRITE_SUFFIXES = (".bvh", ".gltf", ".glb")

# Where the unit of a file read without --units comes from, by suffix: only BVH has no unit of its own.
_DEFAULT_UNIT_SOURCES = {
    ".bvh": "default; --units to change",
    ".amc": "declared by the ASF's :units length",
    ".gltf": "the glTF standard: metres",
    ".glb": "the glTF standard: metres",
    ".fbx": "declared by the file's UnitScaleFactor",
}


def default_unit_source(path: str | Path) -> str:
    """Where :func:`~mocapbench.io.formats.read_motion` takes a file's unit from when no ``--units`` or sidecar says it, for reports:
    ``"declared by the file's UnitScaleFactor"`` for FBX, ``"default; --units to change"`` for BVH (the one format
    that declares no unit), ...; ``"the format's default"`` for another suffix."""
    return _DEFAULT_UNIT_SOURCES.get(Path(path).suffix.lower(), "the format's default")
