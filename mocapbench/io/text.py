"""Reading a motion file's text, every failure one :class:`~mocapbench.motion.MotionFormatError` naming the file.

A missing file raises :class:`MotionFileNotFoundError`, which is both a ``MotionFormatError`` and a
``FileNotFoundError``.
"""

from __future__ import annotations

from pathlib import Path

from mocapbench.motion import MotionFormatError

__all__ = ["MotionFileNotFoundError", "read_text"]


class MotionFileNotFoundError(MotionFormatError, FileNotFoundError):
    """A motion or skeleton file does not exist (catchable as ``MotionFormatError`` or ``FileNotFoundError``)."""


def read_text(path: str | Path, what: str) -> str:
    """The whole text of ``path``, with every failure as a :class:`MotionFormatError` naming the file.

    Parameters
    ----------
    path : str or Path
    what : str
        The kind of file for messages, e.g. ``"BVH file"``.

    Raises
    ------
    MotionFileNotFoundError
        ``path`` does not exist.
    MotionFormatError
        ``path`` is a folder, cannot be read, is not UTF-8 text, or is empty (only whitespace).
    """
    path = Path(path)
    if not path.exists():
        raise MotionFileNotFoundError(f"{path}: {what} does not exist.")
    if path.is_dir():
        raise MotionFormatError(f"{path}: expected a {what}, got a folder.")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise MotionFormatError(f"{path}: expected a {what} as text, got undecodable bytes ({error.reason}).") from None
    except OSError as error:
        raise MotionFormatError(f"{path}: cannot read the {what}: {error.strerror or error}.") from None
    if not text.strip():
        raise MotionFormatError(f"{path}: the {what} is empty.")
    return text

