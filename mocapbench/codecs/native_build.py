"""Compile a codec's native library once, on first use, into mocapbench's build cache.

The codecs with native code (the ``acl`` shim, C++; ``mcb-rot``'s runtime, C) build it with the system compiler the
first time they need it. Both do it the same way, here:

* the library goes into ``<cache root>/<name>-<hash>/`` (:func:`cache_root`), where the hash covers everything the
  build depends on (the sources' bytes, the compiler's path and version, its flags, the include folders): editing a
  source or switching compiler builds anew, and a library is never rebuilt in place;
* the build runs under an exclusive file lock in that folder, so that parallel jobs wait for one compile instead of
  racing, and the library is written under a temporary name and renamed into place (never a half-written file);
* the compiler's command and output are kept in ``build.log`` beside it; a failed compile raises the caller's error
  with the compiler's first error line and the log's path (one line).

Nothing here runs at import time.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

__all__ = ["cache_root", "find_program", "compiler_version", "build_library"]


def cache_root() -> Path:
    """Root of mocapbench's build cache: ``$MOCAPBENCH_CACHE_DIR``, else ``$XDG_CACHE_HOME/mocapbench``, else
    ``~/.cache/mocapbench``."""
    if os.environ.get("MOCAPBENCH_CACHE_DIR"):
        return Path(os.environ["MOCAPBENCH_CACHE_DIR"]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "mocapbench"


def find_program(names: Iterable[str | None]) -> str | None:
    """Path of the first of ``names`` on ``$PATH`` (None entries, e.g. an unset ``$CC``, are skipped), or None."""
    for name in names:
        if name and (path := shutil.which(name)):
            return path
    return None


def compiler_version(compiler: str) -> str:
    """First line of ``compiler --version`` ("" if it prints nothing); OSError if it cannot run."""
    result = subprocess.run([compiler, "--version"], capture_output=True, text=True, timeout=30, check=False)
    return result.stdout.splitlines()[0] if result.stdout else ""


def build_library(
    name: str,
    library_name: str,
    key_parts: Sequence[bytes],
    command: Callable[[str], list[str]],
    error: Callable[[str], Exception],
    what: str,
) -> Path:
    """The library ``<cache root>/<name>-<hash of key_parts>/<library_name>``, compiled if the cache lacks it.

    Parameters
    ----------
    name : str
        Prefix of the cache folder (``acl``, ``mcbrot``).
    library_name : str
        File name of the library (``libmcbrot.so``).
    key_parts : sequence of bytes
        Everything the build depends on (sources, compiler, flags, include folders).
    command : callable
        ``command(output_path)``: the compiler's argument list writing the library to ``output_path``.
    error : callable
        Builds the exception raised when the compile fails, from its one-line message.
    what : str
        What is compiled, for that message ("the ACL shim against <folder>", "the runtime").

    Returns
    -------
    Path
        The library.
    """
    key = hashlib.sha256()
    for part in key_parts:
        key.update(part)
        key.update(b"\0")
    folder = cache_root() / f"{name}-{key.hexdigest()[:16]}"
    library = folder / library_name
    if library.is_file():
        return library
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "build.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # another job may be compiling the same key: wait for it
        if library.is_file():
            return library
        stem, _, suffix = library_name.partition(".")
        fd, partial = tempfile.mkstemp(prefix=f"{stem}.", suffix=f".{suffix}.partial", dir=folder)
        os.close(fd)
        arguments = command(partial)
        result = subprocess.run(arguments, capture_output=True, text=True, check=False)
        log = folder / "build.log"
        log.write_text(" ".join(arguments) + "\n" + result.stdout + result.stderr)
        if result.returncode != 0:
            os.unlink(partial)
            first = next((line for line in result.stderr.splitlines() if "error" in line), "unknown error")
            raise error(f"compiling {what} failed: {first.strip()} (log: {log})")
        os.replace(partial, library)
    return library
