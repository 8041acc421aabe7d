"""Bit- and byte-level I/O for codec payloads: the only place (with :mod:`.huffman`) that lays out bits.

Bit level
    :class:`BitWriter` / :class:`BitReader`: fixed-width unsigned fields of 0-64 bits, MSB first (big-endian bit
    order), one at a time or as whole numpy arrays (vectorized through ``numpy.unpackbits``/``packbits`` and
    bitarray, no per-value Python loop). ``getvalue()`` pads the last byte with zero bits.
Byte level
    :class:`ByteWriter` / :class:`ByteReader`: little-endian fixed-size integers and floats, unsigned LEB128
    varints (and zigzag-signed ones), raw numpy arrays, length-prefixed byte blobs. Codecs use these to lay out their
    payloads.
Signed integers
    :func:`zigzag_encode` / :func:`zigzag_decode` map int64 to uint64 and back (0, -1, 1, -2, ... -> 0, 1, 2, 3, ...)
    so that small magnitudes get short varints or narrow fixed-width fields.

Every read checks the remaining length first and raises :class:`~mocapbench.entropy.errors.BitstreamError` naming
what it was reading, how much it needed and how much was left (``"expected 8 bytes for scale, found 3"``); bad
arguments on the writing side raise ``ValueError``.
"""

from __future__ import annotations

import struct

import numpy as np
from bitarray import bitarray, frozenbitarray
from bitarray.util import ba2int, int2ba, zeros

from mocapbench.entropy.errors import BitstreamError

__all__ = [
    "MAX_VARINT_BYTES",
    "BitReader",
    "BitWriter",
    "ByteReader",
    "ByteWriter",
    "decode_varint",
    "decode_varints",
    "encode_varint",
    "encode_varints",
    "zigzag_decode",
    "zigzag_encode",
]

#: A uint64 needs at most 10 LEB128 bytes (7 payload bits each).
MAX_VARINT_BYTES = 10

_INT64_MIN = -(1 << 63)
_INT64_MAX = (1 << 63) - 1
_UINT64_MAX = (1 << 64) - 1

# Arrays are packed/unpacked in chunks of this many values to bound the (count, 64) uint8 temporaries (4 MiB).
_CHUNK = 1 << 16


# --------------------------------------------------------------------------------------------------------------------
# zigzag


def _as_int_array(values, name: str) -> np.ndarray:
    """``values`` as a numpy integer array (empty input of any dtype becomes an empty int64 array)."""
    arr = np.asarray(values)
    if arr.size == 0:
        return arr.astype(np.int64)
    if arr.dtype == np.bool_ or not np.issubdtype(arr.dtype, np.integer):
        if arr.dtype == object:
            raise ValueError(f"`{name}` must hold integers that fit in 64 bits, got Python objects (too large?)")
        raise ValueError(f"`{name}` must be an integer array, got dtype {arr.dtype}")
    return arr


def zigzag_encode(values) -> np.ndarray:
    """Map signed integers to unsigned ones, small magnitudes first: 0, -1, 1, -2, 2 -> 0, 1, 2, 3, 4.

    Parameters
    ----------
    values : array_like of int, any shape
        Values in the int64 range.

    Returns
    -------
    ndarray of uint64, same shape
        ``2 * v`` for ``v >= 0`` and ``-2 * v - 1`` for ``v < 0``.

    Raises
    ------
    ValueError
        If ``values`` are not integers or do not fit in int64.
    """
    arr = _as_int_array(values, "values")
    if arr.dtype == np.uint64 and arr.size and arr.max() > _INT64_MAX:
        raise ValueError(f"`values` must fit in int64, got {arr.max()}")
    signed = arr.astype(np.int64)
    return (signed.view(np.uint64) << np.uint64(1)) ^ (signed >> np.int64(63)).view(np.uint64)


def zigzag_decode(codes) -> np.ndarray:
    """Inverse of :func:`zigzag_encode`.

    Parameters
    ----------
    codes : array_like of non-negative int, any shape
        Values in the uint64 range.

    Returns
    -------
    ndarray of int64, same shape

    Raises
    ------
    ValueError
        If ``codes`` are not integers or are negative.
    """
    arr = _as_int_array(codes, "codes")
    if arr.size and np.issubdtype(arr.dtype, np.signedinteger) and arr.min() < 0:
        raise ValueError(f"`codes` must be non-negative, got {arr.min()}")
    unsigned = arr.astype(np.uint64)
    return ((unsigned >> np.uint64(1)) ^ (np.uint64(0) - (unsigned & np.uint64(1)))).view(np.int64)


def _zigzag_int(value: int) -> int:
    """Scalar zigzag of a Python int in the int64 range."""
    if not _INT64_MIN <= value <= _INT64_MAX:
        raise ValueError(f"signed varint value must fit in int64, got {value}")
    return (value << 1) ^ (value >> 63) if value < 0 else value << 1


def _unzigzag_int(code: int) -> int:
    return (code >> 1) ^ -(code & 1)


# --------------------------------------------------------------------------------------------------------------------
# bit level


def _check_nbits(nbits) -> int:
    if isinstance(nbits, bool) or not isinstance(nbits, (int, np.integer)) or not 0 <= nbits <= 64:
        raise ValueError(f"`nbits` must be an int in [0, 64], got {nbits!r}")
    return int(nbits)


class BitWriter:
    """Append unsigned fixed-width fields, MSB first, and return them as bytes.

    Examples
    --------
    >>> w = BitWriter()
    >>> w.write(5, 3)
    >>> w.write_array([1, 2, 3], 2)
    >>> w.getvalue()
    b'\\xad\\x80'
    >>> len(w)
    9
    """

    def __init__(self) -> None:
        self._bits = bitarray(endian="big")

    def __len__(self) -> int:
        """Number of bits written so far (before padding)."""
        return len(self._bits)

    def write(self, value: int, nbits: int) -> None:
        """Append ``value`` as an ``nbits``-bit unsigned field.

        Parameters
        ----------
        value : int
            In ``[0, 2**nbits - 1]``; with ``nbits == 0`` only 0 is allowed (nothing is written).
        nbits : int
            Field width in [0, 64].

        Raises
        ------
        ValueError
            If ``nbits`` is outside [0, 64] or ``value`` does not fit.
        """
        nbits = _check_nbits(nbits)
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise ValueError(f"`value` must be an int, got {value!r}")
        value = int(value)
        if not 0 <= value < (1 << nbits):
            raise ValueError(f"`value` must be in [0, 2**{nbits} - 1] for nbits={nbits}, got {value}")
        if nbits:
            self._bits.extend(int2ba(value, length=nbits, endian="big"))

    def write_array(self, values, nbits: int) -> None:
        """Append every element of ``values`` (flattened, C order) as an ``nbits``-bit unsigned field.

        Parameters
        ----------
        values : array_like of int, any shape
            Each in ``[0, 2**nbits - 1]``.
        nbits : int
            Field width in [0, 64].

        Raises
        ------
        ValueError
            If ``values`` are not integers or one does not fit in ``nbits`` bits.
        """
        nbits = _check_nbits(nbits)
        arr = _as_int_array(values, "values").ravel()
        if arr.size == 0 or nbits == 0:
            if arr.size and arr.max() != 0:
                raise ValueError(f"`values` must be 0 for nbits=0, got max {arr.max()}")
            return
        if np.issubdtype(arr.dtype, np.signedinteger) and arr.min() < 0:
            raise ValueError(f"`values` must be non-negative for unsigned fields, got min {arr.min()}")
        if nbits < 64 and arr.max() >= (1 << nbits):
            raise ValueError(f"`values` must be < 2**{nbits} for nbits={nbits}, got max {arr.max()}")
        big_endian = arr.astype(">u8")
        for start in range(0, arr.size, _CHUNK):
            chunk = big_endian[start : start + _CHUNK].view(np.uint8).reshape(-1, 8)
            bits = np.unpackbits(chunk, axis=1)[:, 64 - nbits :]
            self._bits.pack(np.ascontiguousarray(bits).tobytes())

    def write_bits(self, bits) -> None:
        """Append a :class:`bitarray.bitarray` (or a ``'0101'`` string) bit for bit."""
        self._bits.extend(bits if isinstance(bits, bitarray) else bitarray(bits, endian="big"))

    def pad_to_byte(self) -> None:
        """Append zero bits up to the next byte boundary."""
        pad = self._bits.padbits
        if pad:
            self._bits.extend(zeros(pad, endian="big"))

    def getvalue(self) -> bytes:
        """The bits written so far, padded with zero bits to a whole number of bytes."""
        return self._bits.tobytes()


class BitReader:
    """Read fixed-width unsigned fields, MSB first, from bytes written by :class:`BitWriter`.

    Parameters
    ----------
    data : bytes-like
        The coded bytes. Trailing pad bits are readable like any other bits; the reader does not know where the
        writer stopped.
    """

    def __init__(self, data) -> None:
        bits = bitarray(endian="big")
        bits.frombytes(bytes(data))
        self._bits = frozenbitarray(bits)
        self._pos = 0

    @property
    def position(self) -> int:
        """Number of bits consumed so far."""
        return self._pos

    @property
    def bits_left(self) -> int:
        """Number of bits not yet read (pad bits included)."""
        return len(self._bits) - self._pos

    def _take(self, nbits: int, what: str) -> frozenbitarray:
        left = self.bits_left
        if nbits > left:
            raise BitstreamError(f"expected {nbits} bits for {what}, found {left}")
        out = self._bits[self._pos : self._pos + nbits]
        self._pos += nbits
        return out

    def read(self, nbits: int, what: str = "value") -> int:
        """Read one ``nbits``-bit unsigned field (``nbits`` in [0, 64]; 0 bits read as 0).

        Raises
        ------
        BitstreamError
            If fewer than ``nbits`` bits are left; the message names ``what``.
        """
        nbits = _check_nbits(nbits)
        return ba2int(self._take(nbits, what)) if nbits else 0

    def read_array(self, count: int, nbits: int, what: str = "array") -> np.ndarray:
        """Read ``count`` consecutive ``nbits``-bit unsigned fields.

        Returns
        -------
        ndarray of uint64, shape (count,)

        Raises
        ------
        BitstreamError
            If fewer than ``count * nbits`` bits are left (checked before anything is allocated).
        ValueError
            If ``count`` is negative or ``nbits`` is outside [0, 64].
        """
        nbits = _check_nbits(nbits)
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
            raise ValueError(f"`count` must be a non-negative int, got {count!r}")
        count = int(count)
        bits = self._take(count * nbits, f"{what} ({count} x {nbits}-bit fields)")
        out = np.zeros(count, dtype=np.uint64)
        if nbits == 0 or count == 0:
            return out
        for start in range(0, count, _CHUNK):
            stop = min(count, start + _CHUNK)
            rows = np.frombuffer(bits[start * nbits : stop * nbits].unpack(), dtype=np.uint8).reshape(-1, nbits)
            padded = np.zeros((stop - start, 64), dtype=np.uint8)
            padded[:, 64 - nbits :] = rows
            out[start:stop] = np.packbits(padded, axis=1).view(">u8").ravel()
        return out

    def read_bits(self, nbits: int, what: str = "bits") -> frozenbitarray:
        """Read ``nbits`` raw bits as a (big-endian) frozenbitarray."""
        if isinstance(nbits, bool) or not isinstance(nbits, (int, np.integer)) or nbits < 0:
            raise ValueError(f"`nbits` must be a non-negative int, got {nbits!r}")
        return self._take(int(nbits), what)

    def align(self) -> None:
        """Skip to the next byte boundary (the pad bits of :meth:`BitWriter.pad_to_byte`)."""
        self._pos = min(len(self._bits), -(-self._pos // 8) * 8)


# --------------------------------------------------------------------------------------------------------------------
# varints


def encode_varint(value: int) -> bytes:
    """Unsigned LEB128: 7 bits per byte, least significant group first, high bit set on all but the last byte.

    Raises ValueError if ``value`` is not an int in ``[0, 2**64 - 1]``.

    Examples
    --------
    >>> encode_varint(300).hex()
    'ac02'
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"varint value must be an int, got {value!r}")
    value = int(value)
    if not 0 <= value <= _UINT64_MAX:
        raise ValueError(f"varint value must be in [0, 2**64 - 1], got {value}")
    out = bytearray()
    while value >= 0x80:
        out.append((value & 0x7F) | 0x80)
        value >>= 7
    out.append(value)
    return bytes(out)


def decode_varint(data, offset: int = 0, what: str = "varint", max_bytes: int = MAX_VARINT_BYTES) -> tuple[int, int]:
    """Decode one unsigned LEB128 varint from ``data[offset:]``.

    Parameters
    ----------
    data : bytes-like
    offset : int
        Byte position of the first varint byte.
    what : str
        Name of the field, used in error messages.
    max_bytes : int
        Longest accepted encoding, in [1, 10]; use less to bound a field (5 bytes: < 2**35).

    Returns
    -------
    value : int
    new_offset : int
        Position just after the varint.

    Raises
    ------
    BitstreamError
        If the data ends inside the varint, the varint is longer than ``max_bytes``, the value exceeds 64 bits, or the
        encoding is not minimal (a redundant trailing zero group).
    """
    view = memoryview(data).cast("B") if not isinstance(data, (bytes, bytearray)) else data
    value = 0
    shift = 0
    pos = offset
    end = len(view)
    for i in range(max_bytes):
        if pos >= end:
            raise BitstreamError(f"expected 1 more byte for varint {what} (byte {i + 1}), found 0")
        byte = view[pos]
        pos += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            if byte == 0 and i > 0:
                raise BitstreamError(f"varint {what} is not minimal: it ends in a zero byte after {i} bytes")
            if value > _UINT64_MAX:
                raise BitstreamError(f"varint {what} exceeds 64 bits (value {value})")
            return value, pos
    raise BitstreamError(f"varint {what} longer than {max_bytes} bytes")


#: Up to this many values, :func:`encode_varints` codes them one by one in Python (the same bytes).
_FEW_VARINTS = 64


def encode_varints(values) -> bytes:
    """Unsigned LEB128 of every element of ``values`` (flattened), concatenated; vectorized.

    Raises ValueError if ``values`` are not non-negative integers.
    """
    arr = _as_int_array(values, "values").ravel()
    if arr.size == 0:
        return b""
    if np.issubdtype(arr.dtype, np.signedinteger) and arr.min() < 0:
        raise ValueError(f"`values` must be non-negative, got min {arr.min()}")
    if arr.size <= _FEW_VARINTS:  # a few values: a loop costs less than the array calls below
        out = bytearray()
        for value in arr.tolist():
            while value >= 0x80:
                out.append((value & 0x7F) | 0x80)
                value >>= 7
            out.append(value)
        return bytes(out)
    u = arr.astype(np.uint64)
    nbytes = np.ones(u.size, dtype=np.int64)
    rest = u >> np.uint64(7)
    while rest.any():
        nbytes += rest != 0
        rest >>= np.uint64(7)
    ends = np.cumsum(nbytes)
    out = np.empty(int(ends[-1]), dtype=np.uint8)
    starts = ends - nbytes
    for j in range(int(nbytes.max())):
        has = nbytes > j
        group = ((u[has] >> np.uint64(7 * j)) & np.uint64(0x7F)).astype(np.uint8)
        more = (nbytes[has] > j + 1).astype(np.uint8) << 7
        out[starts[has] + j] = group | more
    return out.tobytes()


def decode_varints(data, offset: int, count: int, what: str = "varints") -> tuple[np.ndarray, int]:
    """Decode ``count`` consecutive unsigned LEB128 varints; vectorized.

    Only ``data[offset : offset + 10 * count + 1]`` is scanned, so the cost does not grow with what follows.

    Returns
    -------
    values : ndarray of uint64, shape (count,)
    new_offset : int

    Raises
    ------
    BitstreamError
        If fewer than ``count`` varints are present, one is longer than 10 bytes, exceeds 64 bits or is not minimal.
    """
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
        raise ValueError(f"`count` must be a non-negative int, got {count!r}")
    count = int(count)
    if count == 0:
        return np.zeros(0, dtype=np.uint64), offset
    # One byte more than count maximal varints: if that window holds too few terminators, one is over-long.
    window = MAX_VARINT_BYTES * count + 1
    buf = np.frombuffer(data, dtype=np.uint8)[offset : offset + window]
    head = buf[:count]
    if len(head) == count and head.max() < 0x80:  # every varint is one byte (small values): nothing to scan
        return head.astype(np.uint64), offset + count
    ends = np.flatnonzero(buf < 0x80)
    if ends.size < count:
        if buf.size == window:
            raise BitstreamError(f"a varint of {what} is longer than {MAX_VARINT_BYTES} bytes")
        raise BitstreamError(
            f"expected {count} varints for {what}, found {ends.size} complete ones in the remaining {buf.size} bytes"
        )
    ends = ends[:count]
    starts = np.empty(count, dtype=np.int64)
    starts[0] = 0
    starts[1:] = ends[:-1] + 1
    lengths = ends - starts + 1
    longest = int(lengths.max())
    if longest > MAX_VARINT_BYTES:
        bad = int(np.argmax(lengths > MAX_VARINT_BYTES))
        raise BitstreamError(f"varint {bad} of {what} longer than {MAX_VARINT_BYTES} bytes")
    if ((buf[ends] == 0) & (lengths > 1)).any():
        bad = int(np.argmax((buf[ends] == 0) & (lengths > 1)))
        raise BitstreamError(f"varint {bad} of {what} is not minimal: it ends in a zero byte")
    if longest == MAX_VARINT_BYTES and (buf[ends[lengths == MAX_VARINT_BYTES]] > 1).any():
        raise BitstreamError(f"a varint of {what} exceeds 64 bits")
    values = np.zeros(count, dtype=np.uint64)
    for j in range(longest):
        has = lengths > j
        values[has] |= (buf[starts[has] + j] & np.uint8(0x7F)).astype(np.uint64) << np.uint64(7 * j)
    return values, offset + int(ends[-1]) + 1


# --------------------------------------------------------------------------------------------------------------------
# byte level


def _pack(fmt: str, what: str, value) -> bytes:
    try:
        return struct.pack(fmt, value)
    except struct.error as exc:
        raise ValueError(f"cannot write {what} {value!r} as {fmt!r}: {exc}") from None


class ByteWriter:
    """Build a payload from little-endian fields, varints, arrays and blobs.

    Examples
    --------
    >>> w = ByteWriter()
    >>> w.write_varint(300); w.write_f32(1.5); w.write_blob(b"ab")
    >>> r = ByteReader(w.getvalue())
    >>> r.read_varint("n"), r.read_f32("scale"), r.read_blob("name")
    (300, 1.5, b'ab')
    """

    def __init__(self) -> None:
        self._buf = bytearray()

    def __len__(self) -> int:
        """Number of bytes written so far."""
        return len(self._buf)

    def write_bytes(self, data) -> None:
        """Append raw bytes (no length prefix)."""
        self._buf += data

    def write_u8(self, value: int) -> None:
        """Append an unsigned 8-bit integer."""
        self._buf += _pack("<B", "u8", value)

    def write_u16(self, value: int) -> None:
        """Append a little-endian unsigned 16-bit integer."""
        self._buf += _pack("<H", "u16", value)

    def write_u32(self, value: int) -> None:
        """Append a little-endian unsigned 32-bit integer."""
        self._buf += _pack("<I", "u32", value)

    def write_u64(self, value: int) -> None:
        """Append a little-endian unsigned 64-bit integer."""
        self._buf += _pack("<Q", "u64", value)

    def write_f32(self, value: float) -> None:
        """Append a little-endian IEEE float32 (``value`` is rounded to float32)."""
        self._buf += _pack("<f", "f32", value)

    def write_f64(self, value: float) -> None:
        """Append a little-endian IEEE float64."""
        self._buf += _pack("<d", "f64", value)

    def write_varint(self, value: int) -> None:
        """Append an unsigned LEB128 varint, ``value`` in ``[0, 2**64 - 1]``."""
        self._buf += encode_varint(value)

    def write_svarint(self, value: int) -> None:
        """Append a zigzag-coded signed varint, ``value`` in the int64 range."""
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise ValueError(f"signed varint value must be an int, got {value!r}")
        self._buf += encode_varint(_zigzag_int(int(value)))

    def write_varints(self, values) -> None:
        """Append one unsigned varint per element of ``values`` (no count; the reader must know it)."""
        self._buf += encode_varints(values)

    def write_array(self, values, dtype) -> None:
        """Append ``values`` (flattened, C order) as raw little-endian ``dtype`` (e.g. ``"f4"``, ``"u2"``), no count.

        Raises ValueError if a value changes when cast to ``dtype`` (integer overflow, NaN into an int type); float
        narrowing (float64 -> float32) is allowed and rounds.
        """
        dt = np.dtype(dtype).newbyteorder("<")
        arr = np.asarray(values).ravel()
        if np.issubdtype(dt, np.integer):
            ints = _as_int_array(arr, "values")
            if ints.size:
                info = np.iinfo(dt)
                if ints.min() < info.min or ints.max() > info.max:
                    raise ValueError(
                        f"`values` must fit in {dt.name} [{info.min}, {info.max}], got [{ints.min()}, {ints.max()}]"
                    )
        self._buf += arr.astype(dt).tobytes()

    def write_blob(self, data) -> None:
        """Append ``len(data)`` as a varint followed by the bytes."""
        data = bytes(data)
        self.write_varint(len(data))
        self._buf += data

    def getvalue(self) -> bytes:
        """Everything written so far."""
        return bytes(self._buf)


class ByteReader:
    """Read what :class:`ByteWriter` wrote; every read checks the remaining length first.

    Parameters
    ----------
    data : bytes-like
        Not copied.
    offset : int
        Position of the first byte to read.
    """

    def __init__(self, data, offset: int = 0) -> None:
        self._data = memoryview(data).cast("B")
        if not 0 <= offset <= len(self._data):
            raise ValueError(f"`offset` must be in [0, {len(self._data)}], got {offset}")
        self._pos = int(offset)

    @property
    def offset(self) -> int:
        """Position of the next byte to read."""
        return self._pos

    @property
    def remaining(self) -> int:
        """Number of bytes not yet read."""
        return len(self._data) - self._pos

    def _need(self, nbytes: int, what: str) -> None:
        if nbytes > self.remaining:
            raise BitstreamError(f"expected {nbytes} bytes for {what}, found {self.remaining}")

    def read_bytes(self, nbytes: int, what: str = "bytes") -> bytes:
        """Read ``nbytes`` raw bytes."""
        if nbytes < 0:
            raise ValueError(f"`nbytes` must be >= 0, got {nbytes}")
        self._need(nbytes, what)
        out = self._data[self._pos : self._pos + nbytes].tobytes()
        self._pos += nbytes
        return out

    def _unpack(self, fmt: str, what: str):
        size = struct.calcsize(fmt)
        self._need(size, what)
        (value,) = struct.unpack_from(fmt, self._data, self._pos)
        self._pos += size
        return value

    def read_u8(self, what: str = "u8") -> int:
        """Read an unsigned 8-bit integer."""
        return self._unpack("<B", what)

    def read_u16(self, what: str = "u16") -> int:
        """Read a little-endian unsigned 16-bit integer."""
        return self._unpack("<H", what)

    def read_u32(self, what: str = "u32") -> int:
        """Read a little-endian unsigned 32-bit integer."""
        return self._unpack("<I", what)

    def read_u64(self, what: str = "u64") -> int:
        """Read a little-endian unsigned 64-bit integer."""
        return self._unpack("<Q", what)

    def read_f32(self, what: str = "f32") -> float:
        """Read a little-endian IEEE float32 (returned as a Python float; may be NaN/inf if the data says so)."""
        return self._unpack("<f", what)

    def read_f64(self, what: str = "f64") -> float:
        """Read a little-endian IEEE float64."""
        return self._unpack("<d", what)

    def read_varint(self, what: str = "varint", max_bytes: int = MAX_VARINT_BYTES) -> int:
        """Read an unsigned LEB128 varint of at most ``max_bytes`` bytes (see :func:`decode_varint`)."""
        value, self._pos = decode_varint(self._data, self._pos, what, max_bytes)
        return value

    def read_svarint(self, what: str = "signed varint") -> int:
        """Read a zigzag-coded signed varint; the result is in the int64 range."""
        return _unzigzag_int(self.read_varint(what))

    def read_varints(self, count: int, what: str = "varints") -> np.ndarray:
        """Read ``count`` unsigned varints as a uint64 array of shape (count,)."""
        values, self._pos = decode_varints(self._data, self._pos, count, what)
        return values

    def read_array(self, count: int, dtype, what: str = "array") -> np.ndarray:
        """Read ``count`` little-endian ``dtype`` values into a new native-endian array of shape (count,).

        The length is checked against the remaining bytes before anything is allocated.
        """
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
            raise ValueError(f"`count` must be a non-negative int, got {count!r}")
        dt = np.dtype(dtype).newbyteorder("<")
        nbytes = int(count) * dt.itemsize
        self._need(nbytes, f"{what} ({count} x {dt.name})")
        out = np.frombuffer(self._data, dtype=dt, count=int(count), offset=self._pos).astype(dt.newbyteorder("="))
        self._pos += nbytes
        return out

    def read_blob(self, what: str = "blob", max_size: int | None = None) -> bytes:
        """Read a varint length and that many bytes; ``max_size`` bounds the declared length."""
        size = self.read_varint(f"length of {what}")
        if max_size is not None and size > max_size:
            raise BitstreamError(f"expected at most {max_size} bytes for {what}, the length field says {size}")
        return self.read_bytes(size, what)

    def expect_end(self, what: str = "payload") -> None:
        """Raise :class:`BitstreamError` if unread bytes remain (the data is longer than its fields)."""
        if self.remaining:
            raise BitstreamError(f"expected the end of {what}, found {self.remaining} more bytes")
