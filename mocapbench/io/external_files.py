"""External references of a scene file (a glTF buffer or image ``uri``), confined to the scene file's folder.

A glTF names its buffers by URI. Followed blindly, ``"../../../secret.bin"``, ``"/etc/passwd"`` or
``"/dev/zero"`` would be read as animation data: a service compressing uploads would hand back another user's
file, or read until memory runs out. Here a reference is refused, in one line naming the URI, before anything
is opened, unless it is

* a ``data:`` URI (base64), whose encoded length is checked against the declared byte length before decoding;
* or a relative reference (percent-encoded as RFC 3986 allows; no scheme, no absolute path, no backslash, no
  NUL) that resolves, after every symbolic link is followed, to a regular file inside the scene file's folder
  (a link to another file of that folder is fine; ``..`` is fine while it stays inside).

The file is then opened without following a final link swapped in meanwhile (``O_NOFOLLOW`` on the resolved
path), checked again on the open descriptor (a regular file of at least the declared length) and read up to the
declared length only, never further.
"""

from __future__ import annotations

import base64
import binascii
import os
import stat
from collections.abc import Callable
from pathlib import Path
from urllib.parse import unquote

__all__ = ["check_reference", "read_data_uri", "read_reference"]

_Error = Callable[[str], Exception]


def check_reference(folder: Path, uri: str, what: str, error: _Error, *, must_exist: bool = True) -> Path:
    """The file a relative ``uri`` names inside ``folder``, or ``error(...)`` naming the URI.

    Parameters
    ----------
    folder : Path
        The folder of the file that holds the reference.
    uri : str
        The reference as written (not a ``data:`` URI).
    what : str
        Where it is written (``"buffers[0]"``), for the message.
    error : callable
        One-line message -> exception.
    must_exist : bool, keyword-only
        Refuse a missing file (a buffer); False for a reference that is checked but never read (an image).

    Returns
    -------
    Path
        The resolved path (every link followed), inside ``folder``: an existing regular file when ``must_exist``.
    """
    shown = _shown(uri)
    if not isinstance(uri, str) or not uri:
        raise error(f"{what}: expected a relative file name as uri, got {uri!r}")
    try:
        name = unquote(uri, errors="strict")
    except UnicodeDecodeError:
        raise error(f"{what}: uri {shown!r} percent-encodes bytes that are not UTF-8") from None
    if ":" in name.split("/", 1)[0]:
        raise error(f"{what}: uri {shown!r} has a scheme; only data: URIs and files inside the glTF's folder are read")
    if name.startswith("/") or "\\" in name or "\0" in name:
        raise error(f"{what}: uri {shown!r} is an absolute path or holds a backslash or NUL; expected a relative "
                    f"file name inside the glTF's folder")
    base = Path(os.path.realpath(folder))
    try:
        target = Path(os.path.realpath(base / name))
    except (OSError, ValueError) as problem:
        reason = getattr(problem, "strerror", None) or problem
        raise error(f"{what}: uri {shown!r} cannot be resolved ({reason})") from None
    if not target.is_relative_to(base) or target == base:
        raise error(f"{what}: uri {shown!r} leads outside the glTF's folder {folder}; refused")
    try:
        info = os.stat(target)
    except OSError as problem:
        if not must_exist and isinstance(problem, FileNotFoundError):
            return target
        raise error(f"{what}: uri {shown!r} cannot be read: {problem.strerror or problem}") from None
    if not stat.S_ISREG(info.st_mode):
        raise error(f"{what}: uri {shown!r} is not a regular file (a device, pipe, socket or folder); refused")
    return target


def _shown(uri: object) -> str:
    """A URI as a message shows it: at most 80 characters."""
    text = str(uri)
    return text if len(text) <= 80 else text[:77] + "..."


def read_reference(folder: Path, uri: str, byte_length: int, what: str, error: _Error) -> bytes:
    """The first ``byte_length`` bytes of the file ``uri`` names inside ``folder`` (see :func:`check_reference`).

    Raises ``error(...)`` naming the URI when the reference leaves the folder, is not a regular file, changed
    between the check and the open, or holds fewer than ``byte_length`` bytes.
    """
    target = check_reference(folder, uri, what, error)
    shown = _shown(uri)
    try:
        handle = os.open(target, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as problem:
        raise error(f"{what}: uri {shown!r} cannot be opened: {problem.strerror or problem}") from None
    with os.fdopen(handle, "rb") as file:
        info = os.fstat(file.fileno())
        if not stat.S_ISREG(info.st_mode):
            raise error(f"{what}: uri {shown!r} is not a regular file; refused")
        if info.st_size < byte_length:
            raise error(f"{what} declares {byte_length} bytes, uri {shown!r} holds {info.st_size}")
        data = file.read(byte_length)
    if len(data) < byte_length:
        raise error(f"{what} declares {byte_length} bytes, uri {shown!r} gave {len(data)}")
    return data


def read_data_uri(uri: str, byte_length: int, what: str, error: _Error) -> bytes:
    """The bytes of a base64 ``data:`` URI holding at least ``byte_length`` bytes (first ``byte_length`` returned).

    The encoded text is checked against the declared length before it is decoded: base64 of ``n`` bytes is
    ``4 ceil(n / 3)`` characters, so a longer text is refused (padding aside) without decoding it.
    """
    head, _, encoded = uri.partition(",")
    if not head.endswith(";base64"):
        raise error(f"{what}: expected a base64 data URI, found {head[:60]!r}")
    longest = 4 * -(-byte_length // 3)
    if len(encoded) > longest:
        raise error(f"{what}: the data URI holds {len(encoded):,} base64 characters, more than the "
                    f"{longest:,} its declared {byte_length:,} bytes take")
    try:
        data = base64.b64decode(encoded, validate=True)
    except (ValueError, binascii.Error):
        raise error(f"{what}: the data URI is not valid base64") from None
    if len(data) < byte_length:
        raise error(f"{what} declares {byte_length} bytes, its data URI holds {len(data)}")
    return data[:byte_length]
