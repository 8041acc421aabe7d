"""Write output files safely: atomically, in the target's own folder, never through a link.

Every file mocapbench writes for a user (bitstreams, ``.npy`` positions, BVH, glTF, reports, figures, tables)
goes through this module, so that the same three promises hold everywhere:

* **Atomic.** The bytes go to a temporary file created exclusively (``O_EXCL``) in the target's folder, are
  flushed to disk, and the temporary takes the target's name in one rename. A reader sees the old file or the
  whole new one, never half a file; a failure at any point (a full disk, an exception while the content is
  produced, ``KeyboardInterrupt``) removes the temporary and leaves the target as it was.
* **No link is followed at the output path.** A symbolic link at the output path is never opened: with
  ``force=True`` the link itself is replaced by the new file (its target is untouched); without it the link is
  refused, dangling or not. The rename replaces a name, it never writes into what a name points at.
* **Nothing is replaced silently.** Without ``force`` an existing path of any kind (file, link, dangling link,
  folder) is refused with :class:`OutputExistsError`; the final step then uses ``link(2)``, which fails if the
  name appeared meanwhile, so even a file created between the check and the write is never overwritten. A
  folder is refused even with ``force``.

* **No temporary outlives its write.** A write killed outright (``kill -9``, a power cut) cannot remove its
  temporary; the next write to the same name does. A temporary is removed only when it is certainly one of ours
  and dead: its name is exactly this module's pattern for that target (``.<name>.<8 random characters>.tmp``), it
  is a regular file (never a link, never followed) owned by the current user, older than
  :data:`STALE_TEMPORARY_S`, and no process holds the advisory lock every live write keeps on its temporary
  (``flock``: the kernel drops it when the writer dies). Where ``flock`` does not exist nothing is removed.

Names that become a single path component (a report name, a run name) are checked with :func:`check_name`.

Examples
--------
>>> import tempfile, pathlib
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> write_bytes(folder / "a.mcb", b"MCB")
PosixPath('...a.mcb')
>>> write_bytes(folder / "a.mcb", b"new")
Traceback (most recent call last):
...
mocapbench.io.safe_output.OutputExistsError: ...a.mcb exists; pass --force (force=True) to replace it.
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
import re
import stat
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np

try:
    import fcntl
except ImportError:  # Windows: no flock, so no stale temporary can be told from a live one
    fcntl = None  # type: ignore[assignment]

__all__ = [
    "OutputError",
    "OutputExistsError",
    "check_output",
    "check_name",
    "open_output",
    "write_bytes",
    "write_text",
    "save_npy",
]

# Characters a name that becomes one path component must not hold (a separator, NUL, or a control character).
_FORBIDDEN_NAME_CHARACTERS = frozenset("/\\\0") | frozenset(chr(c) for c in range(32)) | {chr(127)}
MAX_NAME_LENGTH = 128
#: Seconds a temporary must have existed before a write may remove it as stale (a live write takes its lock
#: microseconds after creating it, so this only closes that window).
STALE_TEMPORARY_S = 1.0
_TEMPORARY_RANDOM = r"[a-z0-9_]{8}"  # tempfile.mkstemp's random part


class OutputError(OSError):
    """An output path that cannot be written safely (its folder is missing, it is a folder, a bad name)."""


class OutputExistsError(OutputError, FileExistsError):
    """The output path exists (a file, a link, a dangling link) and ``force`` was not given."""


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def check_output(path: str | os.PathLike, *, force: bool = False) -> Path:
    """Check that ``path`` can be written; call it before expensive work so that a refusal comes first.

    Parameters
    ----------
    path : str or PathLike
        The output file. Its folder must exist.
    force : bool, keyword-only
        Allow replacing an existing file or link (the link itself is replaced, never its target).

    Returns
    -------
    Path
        ``path`` as a :class:`~pathlib.Path`.

    Raises
    ------
    OutputExistsError
        ``path`` exists (or is a link, dangling or not) and ``force`` is False.
    OutputError
        ``path`` is a folder, has no file name, or its folder does not exist or is not a folder.
    """
    path = Path(path)
    if path.name in ("", ".", ".."):
        raise OutputError(f"{path}: expected a file name as output, got a folder.")
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        info = None
    except NotADirectoryError:
        raise OutputError(f"{path}: the folder of this output is not a folder.") from None
    if info is not None:
        if stat.S_ISDIR(info.st_mode):
            raise OutputError(f"{path} is a folder; expected a file name as output.")
        if not force:
            kind = "a link" if stat.S_ISLNK(info.st_mode) else "exists"
            what = f"{path} is {kind}" if kind == "a link" else f"{path} exists"
            raise OutputExistsError(f"{what}; pass --force (force=True) to replace it.")
    parent = path.parent
    if not parent.is_dir():
        raise OutputError(f"the folder of {path} does not exist." if not parent.exists() else
                          f"{parent} is not a folder, so {path} cannot be written.")
    return path


@contextlib.contextmanager
def open_output(
    path: str | os.PathLike, mode: str = "wb", *, force: bool = False, encoding: str = "utf-8"
) -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; on a clean exit it becomes ``path`` atomically.

    Parameters
    ----------
    path : str or PathLike
        The output file (see :func:`check_output`).
    mode : {"wb", "w"}
        Binary or text.
    force : bool, keyword-only
        Replace an existing file or link at ``path`` (never writing through the link).
    encoding : str, keyword-only
        Text mode only. Newlines are written as ``\\n``.

    Yields
    ------
    file object
        Write the content to it; do not close it.

    Raises
    ------
    OutputExistsError, OutputError
        As :func:`check_output`; also if ``path`` appears while the content is written and ``force`` is False.
    """
    if mode not in ("wb", "w"):
        raise ValueError(f"open_output: mode must be 'wb' or 'w', got {mode!r}.")
    path = check_output(path, force=force)
    prefix = f".{path.name[:64]}."
    _remove_stale_temporaries(path.parent, prefix)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=prefix, suffix=".tmp")
    try:
        if fcntl is not None:
            with contextlib.suppress(OSError):  # a file system without locks: then no cleaner can take it either
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)  # held until this process closes it or dies
        os.fchmod(handle, 0o666 & ~_umask())
        raw = os.fdopen(handle, "wb")
        file: IO[Any] = raw if mode == "wb" else io.TextIOWrapper(raw, encoding=encoding, newline="\n")
        with file:
            yield file
            file.flush()
            os.fsync(raw.fileno())
        _commit(Path(temporary), path, force)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
        raise


def _remove_stale_temporaries(folder: Path, prefix: str) -> None:
    """Remove the temporaries of dead writes named ``<prefix><random>.tmp`` in ``folder`` (see the module docstring).

    Each candidate is opened without following a link, checked on the open descriptor (a regular file, the same
    one the name showed, ours, old enough) and removed only if its lock can be taken. Any failure skips it.
    """
    if fcntl is None:
        return
    pattern = re.compile(re.escape(prefix) + _TEMPORARY_RANDOM + r"\.tmp")
    try:
        entries = [entry.name for entry in os.scandir(folder) if pattern.fullmatch(entry.name)]
    except OSError:
        return
    now = time.time()
    for name in entries:
        with contextlib.suppress(OSError):
            seen = os.lstat(folder / name)
            if not stat.S_ISREG(seen.st_mode) or seen.st_uid != os.getuid() or now - seen.st_mtime < STALE_TEMPORARY_S:
                continue
            handle = os.open(folder / name, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
            try:
                opened = os.fstat(handle)
                if (opened.st_dev, opened.st_ino) != (seen.st_dev, seen.st_ino) or not stat.S_ISREG(opened.st_mode):
                    continue
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)  # fails while a live write holds it
                current = os.lstat(folder / name)
                if (current.st_dev, current.st_ino) == (seen.st_dev, seen.st_ino):
                    os.unlink(folder / name)
            finally:
                os.close(handle)


def _commit(temporary: Path, path: Path, force: bool) -> None:
    """Give ``temporary`` the name ``path``: replace it (``force``) or fail if the name exists."""
    if force:
        os.replace(temporary, path)  # rename(2) replaces the name; a link at ``path`` is replaced, not followed
        return
    try:
        os.link(temporary, path, follow_symlinks=False)  # fails with EEXIST on any existing name, links included
    except FileExistsError:
        raise OutputExistsError(f"{path} appeared while it was written; pass --force (force=True) to replace it.") \
            from None
    except OSError as error:
        if error.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EXDEV, errno.EMLINK):
            raise
        # A file system without hard links: check once more and rename (a tiny window remains there).
        check_output(path, force=False)
        os.replace(temporary, path)
        return
    os.unlink(temporary)


def write_bytes(path: str | os.PathLike, data: bytes, *, force: bool = False) -> Path:
    """Write ``data`` to ``path`` atomically (see the module docstring); returns ``path``."""
    with open_output(path, "wb", force=force) as file:
        file.write(data)
    return Path(path)


def write_text(path: str | os.PathLike, text: str, *, force: bool = False, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically with ``\\n`` newlines; returns ``path``."""
    with open_output(path, "w", force=force, encoding=encoding) as file:
        file.write(text)
    return Path(path)


def save_npy(path: str | os.PathLike, array: np.ndarray, *, force: bool = False) -> Path:
    """Save ``array`` in ``.npy`` format at exactly ``path`` (no suffix is added), atomically; returns ``path``."""
    with open_output(path, "wb", force=force) as file:
        np.save(file, np.asarray(array), allow_pickle=False)
    return Path(path)


def check_name(name: str, what: str = "name") -> str:
    """Check that ``name`` can be used as one path component (e.g. a report folder suffix).

    Refused: empty, ``.`` or ``..``, longer than 128 characters, a path separator (``/`` or ``\\``), NUL or
    another control character, a leading ``-`` (it would read as an option in the printed commands).

    Returns
    -------
    str
        ``name``.

    Raises
    ------
    ValueError
        One line naming ``what``, the name and the reason.
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"{what} must be a non-empty string, got {name!r}.")
    if name in (".", ".."):
        raise ValueError(f"{what} {name!r} is not a name; expected a plain name such as 'cmu-run'.")
    bad = sorted(set(name) & _FORBIDDEN_NAME_CHARACTERS)
    if bad:
        raise ValueError(f"{what} {name!r} holds {bad[0]!r}; expected a plain name without path separators.")
    if name.startswith("-"):
        raise ValueError(f"{what} {name!r} starts with '-'; expected a plain name.")
    if len(name) > MAX_NAME_LENGTH:
        raise ValueError(f"{what} is {len(name)} characters long; the limit is {MAX_NAME_LENGTH}.")
    return name
