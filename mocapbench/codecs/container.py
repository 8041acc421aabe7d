"""The mocapbench bitstream container: every stream is self-describing and checked before it is decoded.

Layout (little-endian; ``len(bytes)`` of the whole thing is the rate, header included)::

    offset  size  field
    0       4     magic  b"MCB\\x00"
    4       1     format version (append-only numbering; see FORMAT_VERSIONS)
    5       4     CRC32 of every byte after this field
    9       1     n = length of the codec name
    10      n     codec name, ASCII (the registry key, e.g. "lsdt-clip")
    10+n    4     F, frame count
    14+n    2     J, joint count
    16+n    8     fps, float64
    24+n    4     P, payload length in bytes
    28+n    P     codec payload

Every size field is checked against a limit before anything is allocated, and every way a stream can be
wrong (wrong magic, unknown version, another codec's stream, truncation at any byte, a flipped bit, a payload
length that disagrees with the data) raises :class:`BitstreamError` naming what was expected and what was found.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass

from mocapbench.entropy.errors import BitstreamError

__all__ = ["MAGIC", "FORMAT_VERSION", "FORMAT_VERSIONS", "Header", "pack", "unpack", "read_header", "BitstreamError"]

MAGIC = b"MCB\x00"
# BE CAREFUL WHEN CHANGING: versions are only ever appended, so that old streams stay readable.
FORMAT_VERSIONS = {1: "initial layout: magic, version, crc32, codec name, F, J, fps, payload length"}
FORMAT_VERSION = 1

MAX_FRAMES = 100_000_000  # ~10 days at 120 fps
MAX_JOINTS = 4096
MAX_PAYLOAD_BYTES = 1 << 31
MAX_NAME_BYTES = 64

_PREFIX = struct.Struct("<4sBI")  # magic, version, crc32
_FIELDS = struct.Struct("<IHdI")  # frames, joints, fps, payload length


@dataclass(frozen=True)
class Header:
    """The container fields of a stream.

    Attributes
    ----------
    codec : str
        Registry key of the codec that wrote the stream.
    num_frames, num_joints : int
        F and J of the coded motion.
    fps : float
        Frames per second.
    version : int
        Container format version.
    header_bytes, payload_bytes : int
        Sizes of the two parts; their sum is the stream length.
    """

    codec: str
    num_frames: int
    num_joints: int
    fps: float
    version: int = FORMAT_VERSION
    header_bytes: int = 0
    payload_bytes: int = 0


def pack(codec: str, num_frames: int, num_joints: int, fps: float, payload: bytes) -> bytes:
    """Wrap a codec payload in the container.

    Parameters
    ----------
    codec : str
        Registry key, ASCII, at most 64 bytes.
    num_frames, num_joints : int
        F in [1, 1e8], J in [1, 4096].
    fps : float
        Finite, > 0.
    payload : bytes
        What the codec wrote.
    """
    name = codec.encode("ascii")
    if not 0 < len(name) <= MAX_NAME_BYTES:
        raise ValueError(f"Codec name must be 1..{MAX_NAME_BYTES} ASCII bytes, got {codec!r}.")
    if not 1 <= num_frames <= MAX_FRAMES:
        raise ValueError(f"num_frames must be in [1, {MAX_FRAMES}], got {num_frames}.")
    if not 1 <= num_joints <= MAX_JOINTS:
        raise ValueError(f"num_joints must be in [1, {MAX_JOINTS}], got {num_joints}.")
    if not (fps > 0 and fps < float("inf")):
        raise ValueError(f"fps must be finite and > 0, got {fps}.")
    if len(payload) >= MAX_PAYLOAD_BYTES:
        raise ValueError(f"Payload of {len(payload)} bytes exceeds the container limit of {MAX_PAYLOAD_BYTES}.")
    body = bytes([len(name)]) + name + _FIELDS.pack(num_frames, num_joints, float(fps), len(payload)) + bytes(payload)
    return _PREFIX.pack(MAGIC, FORMAT_VERSION, zlib.crc32(body)) + body


def read_header(data: bytes) -> tuple[Header, memoryview]:
    """Parse and verify the container; return the header and a view of the payload.

    Raises
    ------
    BitstreamError
        On any malformed, truncated or corrupted stream (the message says what was expected and found).
    """
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise BitstreamError(f"Expected the bitstream as bytes, got {type(data).__name__}.")
    view = memoryview(data).cast("B")
    if len(view) < _PREFIX.size + 1:
        raise BitstreamError(
            f"Bitstream is truncated: expected at least {_PREFIX.size + 1} header bytes, found {len(view)}."
        )
    magic, version, crc = _PREFIX.unpack_from(view, 0)
    if magic != MAGIC:
        raise BitstreamError(f"Not a mocapbench bitstream: expected magic {MAGIC!r}, found {bytes(magic)!r}.")
    if version not in FORMAT_VERSIONS:
        raise BitstreamError(
            f"Unknown container format version: expected one of {sorted(FORMAT_VERSIONS)}, found {version}."
        )
    body = view[_PREFIX.size :]
    name_length = body[0]
    fixed = 1 + name_length + _FIELDS.size
    if not 0 < name_length <= MAX_NAME_BYTES:
        raise BitstreamError(f"Corrupt header: codec name length must be 1..{MAX_NAME_BYTES}, found {name_length}.")
    if len(body) < fixed:
        raise BitstreamError(
            f"Bitstream is truncated: expected {_PREFIX.size + fixed} header bytes, found {len(view)}."
        )
    num_frames, num_joints, fps, payload_length = _FIELDS.unpack_from(body, 1 + name_length)
    if len(body) - fixed != payload_length:
        what = "truncated" if len(body) - fixed < payload_length else "longer than its header says"
        raise BitstreamError(
            f"Bitstream is {what}: the header declares a {payload_length}-byte payload, "
            f"found {len(body) - fixed} bytes after the header."
        )
    if zlib.crc32(body) != crc:
        raise BitstreamError(
            f"Bitstream is corrupted: CRC32 expected {crc:#010x} (from the header), computed {zlib.crc32(body):#010x}."
        )
    try:
        codec = bytes(body[1 : 1 + name_length]).decode("ascii")
    except UnicodeDecodeError:
        raise BitstreamError("Corrupt header: the codec name is not ASCII.") from None
    if not 1 <= num_frames <= MAX_FRAMES or not 1 <= num_joints <= MAX_JOINTS or not 0 < fps < float("inf"):
        raise BitstreamError(
            f"Corrupt header: expected 1 <= F <= {MAX_FRAMES}, 1 <= J <= {MAX_JOINTS}, fps > 0; "
            f"found F={num_frames}, J={num_joints}, fps={fps}."
        )
    header = Header(
        codec=codec,
        num_frames=num_frames,
        num_joints=num_joints,
        fps=fps,
        version=version,
        header_bytes=_PREFIX.size + fixed,
        payload_bytes=payload_length,
    )
    return header, body[fixed:]


def unpack(data: bytes, expected_codec: str) -> tuple[Header, memoryview]:
    """:func:`read_header`, and check that the stream was written by ``expected_codec``."""
    header, payload = read_header(data)
    if header.codec != expected_codec:
        raise BitstreamError(
            f"Codec mismatch: the {expected_codec!r} decoder was given a stream written by {header.codec!r}."
        )
    return header, payload
