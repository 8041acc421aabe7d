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
    24+n    4     (version 2) source length unit, cm per unit, float32 (1 cm, 0.1 mm, 100 m, 2.54 inch, ...)
    28+n    1     (version 2) source up axis, ASCII ``x``, ``y``, ``z`` or ``?`` (unknown)
    +0      4     P, payload length in bytes
    +4      P     codec payload

Version 1 streams (no unit, no axis) are still read: their unit is 1 cm and their up axis ``?``. The unit and
axis are metadata for writing the decoded motion back as the user's file (``decompress``); the payload is in cm
whatever the source unit.

Every size field is checked against a limit before anything is allocated, and every way a stream can be
wrong (wrong magic, unknown version, another codec's stream, truncation at any byte, a flipped bit, a payload
length that disagrees with the data) raises :class:`BitstreamError` naming what was expected and what was found.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass

from mocapbench.entropy.errors import BitstreamError

__all__ = [
    "MAGIC", "MIN_FPS", "MAX_FPS", "MIN_UNIT_CM", "MAX_UNIT_CM", "FORMAT_VERSION", "FORMAT_VERSIONS", "Header", "pack",
    "unpack", "read_header", "unit_in_range", "BitstreamError",
]

MAGIC = b"MCB\x00"
# BE CAREFUL WHEN CHANGING: versions are only ever appended, so that old streams stay readable.
FORMAT_VERSIONS = {
    1: "initial layout: magic, version, crc32, codec name, F, J, fps, payload length",
    2: "adds the source length unit (cm per unit, float32) and up axis (one ASCII byte) after fps",
}
FORMAT_VERSION = 2

MAX_FRAMES = 100_000_000  # ~10 days at 120 fps
MAX_JOINTS = 4096
MAX_PAYLOAD_BYTES = 1 << 31
MAX_NAME_BYTES = 64
# Source length units a stream may carry, cm per unit: 1 micrometre to 1 km. Outside this range a unit is a
# corrupt field (a unit of 1e-45 cm would write a BVH with values near 1e46); float32 rounding is allowed at both ends.
MIN_UNIT_CM = 1e-4
MAX_UNIT_CM = 1e5
UP_AXES = ("x", "y", "z", "?")
# Frame rates a stream may carry, frames per second: one frame per 1000 s to 100,000 per second. Outside this
# range a rate is a corrupt field (fps = 5e-324 or 1e308 would write "Frame Time: inf" to a BVH file).
MIN_FPS = 1e-3
MAX_FPS = 1e5

_PREFIX = struct.Struct("<4sBI")  # magic, version, crc32
_FIELDS = {  # by version: frames, joints, fps, [unit cm, up axis,] payload length
    1: struct.Struct("<IHdI"),
    2: struct.Struct("<IHdfcI"),
}


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
    source_unit_cm : float
        Centimetres per length unit of the source file (1 for version 1 streams). float32 precision.
    up_axis : str
        Up axis of the source: ``"x"``, ``"y"``, ``"z"`` or ``"?"`` (unknown; every version 1 stream).
    """

    codec: str
    num_frames: int
    num_joints: int
    fps: float
    version: int = FORMAT_VERSION
    header_bytes: int = 0
    payload_bytes: int = 0
    source_unit_cm: float = 1.0
    up_axis: str = "?"


def unit_in_range(unit_cm: float) -> bool:
    """Whether ``unit_cm`` (cm per source unit) lies in [MIN_UNIT_CM, MAX_UNIT_CM], up to float32 rounding."""
    relative = 2.0**-23  # float32 rounding of the header field
    return MIN_UNIT_CM * (1 - relative) <= unit_cm <= MAX_UNIT_CM * (1 + relative)


def pack(
    codec: str,
    num_frames: int,
    num_joints: int,
    fps: float,
    payload: bytes,
    *,
    source_unit_cm: float = 1.0,
    up_axis: str = "?",
) -> bytes:
    """Wrap a codec payload in the container (always the newest version, :data:`FORMAT_VERSION`).

    Parameters
    ----------
    codec : str
        Registry key, ASCII, at most 64 bytes.
    num_frames, num_joints : int
        F in [1, 1e8], J in [1, 4096].
    fps : float
        In [MIN_FPS, MAX_FPS] = [0.001, 100000].
    payload : bytes
        What the codec wrote.
    source_unit_cm : float, keyword-only
        Centimetres per length unit of the source file, in [:data:`MIN_UNIT_CM`, :data:`MAX_UNIT_CM`]. Default 1 (cm).
    up_axis : str, keyword-only
        ``"x"``, ``"y"``, ``"z"`` or ``"?"`` (unknown, the default).
    """
    name = codec.encode("ascii")
    if not 0 < len(name) <= MAX_NAME_BYTES:
        raise ValueError(f"Codec name must be 1..{MAX_NAME_BYTES} ASCII bytes, got {codec!r}.")
    if not 1 <= num_frames <= MAX_FRAMES:
        raise ValueError(f"num_frames must be in [1, {MAX_FRAMES}], got {num_frames}.")
    if not 1 <= num_joints <= MAX_JOINTS:
        raise ValueError(f"num_joints must be in [1, {MAX_JOINTS}], got {num_joints}.")
    if not MIN_FPS <= fps <= MAX_FPS:
        raise ValueError(f"fps must be in [{MIN_FPS:g}, {MAX_FPS:g}], got {fps}.")
    if not unit_in_range(source_unit_cm):
        raise ValueError(f"source_unit_cm must be in [{MIN_UNIT_CM:g}, {MAX_UNIT_CM:g}] cm, got {source_unit_cm}.")
    if up_axis not in UP_AXES:
        raise ValueError(f"up_axis must be one of {list(UP_AXES)}, got {up_axis!r}.")
    if len(payload) >= MAX_PAYLOAD_BYTES:
        raise ValueError(f"Payload of {len(payload)} bytes exceeds the container limit of {MAX_PAYLOAD_BYTES}.")
    fields = _FIELDS[FORMAT_VERSION].pack(
        num_frames, num_joints, float(fps), float(source_unit_cm), up_axis.encode("ascii"), len(payload)
    )
    body = bytes([len(name)]) + name + fields + bytes(payload)
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
    fields = _FIELDS[version]
    fixed = 1 + name_length + fields.size
    if not 0 < name_length <= MAX_NAME_BYTES:
        raise BitstreamError(f"Corrupt header: codec name length must be 1..{MAX_NAME_BYTES}, found {name_length}.")
    if len(body) < fixed:
        raise BitstreamError(
            f"Bitstream is truncated: expected {_PREFIX.size + fixed} header bytes, found {len(view)}."
        )
    if version == 1:
        num_frames, num_joints, fps, payload_length = fields.unpack_from(body, 1 + name_length)
        unit_cm, axis = 1.0, b"?"
    else:
        num_frames, num_joints, fps, unit_cm, axis, payload_length = fields.unpack_from(body, 1 + name_length)
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
    if not 1 <= num_frames <= MAX_FRAMES or not 1 <= num_joints <= MAX_JOINTS or not MIN_FPS <= fps <= MAX_FPS:
        raise BitstreamError(
            f"Corrupt header: expected 1 <= F <= {MAX_FRAMES}, 1 <= J <= {MAX_JOINTS}, {MIN_FPS:g} <= fps <= {MAX_FPS:g}; "
            f"found F={num_frames}, J={num_joints}, fps={fps}."
        )
    if not unit_in_range(unit_cm) or axis not in b"xyz?":
        raise BitstreamError(
            f"Corrupt header: expected a source unit in [{MIN_UNIT_CM:g}, {MAX_UNIT_CM:g}] cm and an up axis x, y, z "
            f"or ?; "
            f"found {unit_cm} cm and {bytes(axis)!r}."
        )
    header = Header(
        codec=codec,
        num_frames=num_frames,
        num_joints=num_joints,
        fps=fps,
        version=version,
        header_bytes=_PREFIX.size + fixed,
        payload_bytes=payload_length,
        source_unit_cm=float(unit_cm),
        up_axis=axis.decode("ascii"),
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
