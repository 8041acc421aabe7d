"""The motion file formats by suffix: which can be read and written, and where a file's unit comes from.

The lowest module of the readers: :mod:`mocapbench.io.formats` reads and writes by these suffixes and
:mod:`mocapbench.io.unit_choice` says where a unit came from; neither imports the other for them.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["READ_SUFFIXES", "WRITE_SUFFIXES", "default_unit_source", "motion_files"]

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
