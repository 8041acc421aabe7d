"""A classed rANS *unit* a native sampler decodes in natural order: two interleaved 32-bit states, static tables.

:mod:`.ans` codes a stream's values sorted by class (one vectorized ``constriction`` call per class): fast in numpy,
but a decoder in C must rebuild that order before it knows which value is which, and ``constriction``'s models are
quantized from floats by an algorithm of its own. A unit here codes the values in the order they are used, each
with its class's table, so that a decoder (Python's, compiled with numba, or the C runtime's ``mcbrot_rans.h``)
reads one value after the other, and every table is integer data both sides share.

Layout of a unit::

    varint B | B bytes of rANS data (0 iff the unit holds no value) | sign and raw bits (MSB first, zero padded to a
    byte; their length follows from the decoded tokens)

Binarization as :mod:`.ans` (``|v| < 16`` is token ``|v|``, larger magnitudes token ``16 + bit_length - 5`` then
``bit_length - 1`` raw bits), limited to ``|v| < 2^31`` (tokens up to :data:`MAX_TOKEN`). The bits follow the values:
for a nonzero value its sign (1: negative), then for an escaped token its raw bits.

rANS: two 32-bit states (value ``i`` uses state ``i & 1``: a decoder's two chains of dependent multiplies overlap),
byte renormalization to ``[2^23, 2^31)``, probabilities in 2^-15 units. The data starts with the decoder's initial
states (state 0 then state 1, u32 little-endian), then the renormalization bytes in reading order; a decoder ends
with both states at ``2^23`` and every byte read, which checks the unit's integrity.
"""

from __future__ import annotations

from functools import cache

import numpy as np

from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError

__all__ = ["PRECISION", "MAX_TOKEN", "RansTables", "quantize_counts", "encode_unit", "decode_unit"]

PRECISION = 15  # probabilities in 2^-15 units
_LOW = 1 << 23  # states lie in [2^23, 2^31) between values
#: Largest token a unit may hold: magnitudes below 2^31.
MAX_TOKEN = 16 + 31 - 5
_COARSE_SHIFT = PRECISION - 6  # 64 coarse buckets per class: the first token of each, then a short linear scan


def quantize_counts(counts: np.ndarray) -> np.ndarray:
    """Integer token counts (K, T) >= 1 scaled to frequencies summing to 2^15 per row, each >= 1 (int64).

    ``f = max(1, c * 2^15 // total)``; what is left (positive or negative) goes to the row's most frequent token.
    Integer arithmetic only, so the C runtime's tables (generated from these) are the same on every machine.
    """
    counts = np.asarray(counts, dtype=np.int64)
    total = counts.sum(axis=1, keepdims=True)
    freq = np.maximum(1, (counts << PRECISION) // total)
    top = np.argmax(freq, axis=1)
    freq[np.arange(len(freq)), top] += (1 << PRECISION) - freq.sum(axis=1)
    if freq.min() < 1:
        raise ValueError("rans6: a table's most frequent token cannot absorb the rounding.")
    return freq


class RansTables:
    """Frequencies (K, T), their cumulative sums (K, T + 1) and each class's coarse lookup (K, 64), uint32."""

    def __init__(self, freq: np.ndarray) -> None:
        freq = np.asarray(freq, dtype=np.int64)
        if freq.ndim != 2 or freq.min() < 1 or np.any(freq.sum(axis=1) != 1 << PRECISION):
            raise ValueError(f"rans6: frequencies must be (K, T) positive rows summing to 2^{PRECISION}.")
        self.freq = freq.astype(np.uint32)
        self.cum = np.concatenate([np.zeros((len(freq), 1), np.int64), np.cumsum(freq, axis=1)], axis=1).astype(np.uint32)
        buckets = np.arange(64, dtype=np.int64) << _COARSE_SHIFT
        self.coarse = np.stack([np.searchsorted(row, buckets, side="right") - 1 for row in self.cum]).astype(np.uint32)

    @property
    def num_classes(self) -> int:
        return len(self.freq)


def _encode(values, classes, freq, cum, data, bits):  # pragma: no cover (runs compiled)
    """The kernel: writes the rANS bytes at the end of ``data`` (returns where they start) and the bit stream into
    ``bits`` (returns its length in bits)."""
    count = values.shape[0]
    # Bits, forward: sign, then the raw bits of an escaped magnitude.
    at = 0
    for i in range(count):
        v = values[i]
        if v == 0:
            continue
        a = -v if v < 0 else v
        if v < 0:
            bits[at >> 3] |= np.uint8(0x80 >> (at & 7))
        at += 1
        if a >= 16:
            width = 0
            while (a >> (width + 1)) != 0:
                width += 1
            for b in range(width - 1, -1, -1):
                if (a >> b) & 1:
                    bits[at >> 3] |= np.uint8(0x80 >> (at & 7))
                at += 1
    # rANS, backward: bytes collected from the end of ``data`` towards its start.
    states = np.full(2, _LOW, dtype=np.uint64)
    pos = data.shape[0]
    for i in range(count - 1, -1, -1):
        v = values[i]
        a = -v if v < 0 else v
        if a < 16:
            token = a
        else:
            width = 0
            while (a >> width) != 0:
                width += 1
            token = 16 + width - 5
        k = classes[i]
        f = np.uint64(freq[k, token])
        x = states[i & 1]
        limit = f << np.uint64(16)  # ((2^23 >> 15) << 8) * f
        while x >= limit:
            pos -= 1
            data[pos] = np.uint8(x & np.uint64(0xFF))
            x >>= np.uint64(8)
        states[i & 1] = ((x // f) << np.uint64(PRECISION)) + (x % f) + np.uint64(cum[k, token])
    for s in (1, 0):
        x = states[s]
        for b in range(3, -1, -1):
            pos -= 1
            data[pos] = np.uint8((x >> np.uint64(8 * b)) & np.uint64(0xFF))
    # data[pos:] now reads: state 0, state 1 (little-endian), the renormalization bytes.
    return pos, at


def _decode(data, start, end, bits_end, classes, freq, cum, coarse, out):  # pragma: no cover (runs compiled)
    """The kernel: decodes ``len(out)`` values from ``data[start:end]`` (rANS) and the bits from ``end`` on (not
    past ``bits_end``). Returns (status, first byte after the bits): status 0 ok, 1 rANS data truncated, 2 a token
    above MAX_TOKEN, 3 states or bytes left over, 4 bits truncated."""
    count = out.shape[0]
    if count == 0:
        return (0, end) if start == end else (3, end)
    if end - start < 8:
        return 1, end
    x0 = np.uint64(0)
    x1 = np.uint64(0)
    for b in range(4):
        x0 |= np.uint64(data[start + b]) << np.uint64(8 * b)
        x1 |= np.uint64(data[start + 4 + b]) << np.uint64(8 * b)
    pos = start + 8
    mask = np.uint64((1 << PRECISION) - 1)
    bit = end * 8
    bit_limit = bits_end * 8
    for i in range(count):
        x = x0 if (i & 1) == 0 else x1
        k = classes[i]
        slot = x & mask
        token = coarse[k, slot >> np.uint64(_COARSE_SHIFT)]
        while np.uint64(cum[k, token + 1]) <= slot:
            token += 1
        x = np.uint64(freq[k, token]) * (x >> np.uint64(PRECISION)) + slot - np.uint64(cum[k, token])
        while x < np.uint64(_LOW):
            if pos >= end:
                return 1, end
            x = (x << np.uint64(8)) | np.uint64(data[pos])
            pos += 1
        if (i & 1) == 0:
            x0 = x
        else:
            x1 = x
        if token > MAX_TOKEN:
            return 2, end
        if token == 0:
            out[i] = 0
            continue
        if bit >= bit_limit:
            return 4, end
        negative = (data[bit >> 3] >> (7 - (bit & 7))) & 1
        bit += 1
        magnitude = np.int64(token)
        if token >= 16:
            width = token - 16 + 4
            if bit + width > bit_limit:
                return 4, end
            magnitude = np.int64(1)
            for _ in range(width):
                magnitude = (magnitude << 1) | np.int64((data[bit >> 3] >> (7 - (bit & 7))) & 1)
                bit += 1
        out[i] = -magnitude if negative else magnitude
    if x0 != np.uint64(_LOW) or x1 != np.uint64(_LOW) or pos != end:
        return 3, end
    return 0, (bit + 7) >> 3


@cache
def _kernels():
    """The two kernels compiled (numba imported here, on first use; cached in ``__pycache__``)."""
    import numba

    jit = numba.njit(cache=True, nogil=True)
    return jit(_encode), jit(_decode)


def encode_unit(writer: ByteWriter, values: np.ndarray, classes: np.ndarray, tables: RansTables) -> None:
    """Append the unit of ``values`` (N,) int, each coded with the table of its class (N,) in ``[0, K)``."""
    values = np.ascontiguousarray(values, dtype=np.int64).ravel()
    classes = np.ascontiguousarray(classes, dtype=np.int64).ravel()
    if classes.shape != values.shape:
        raise ValueError(f"rans6: expected {values.size} classes, got {classes.size}.")
    if values.size == 0:
        writer.write_varint(0)
        return
    if np.abs(values).max() >= 1 << 31 or classes.min() < 0 or classes.max() >= tables.num_classes:
        raise ValueError("rans6: values must be below 2^31 in magnitude and classes within the tables.")
    data = np.zeros(8 + 4 * values.size + 16, dtype=np.uint8)
    bits = np.zeros(4 * values.size + 1, dtype=np.uint8)
    encode, _ = _kernels()
    start, nbits = encode(values, classes, tables.freq, tables.cum, data, bits)
    rans = data[start:]
    writer.write_varint(len(rans))
    writer.write_bytes(rans.tobytes())
    writer.write_bytes(bits[: (nbits + 7) // 8].tobytes())


_ERRORS = {
    1: "the rANS data ends before its values",
    2: "a value exceeds 2^31",
    3: "the rANS data does not end where it should (corrupt)",
    4: "the sign and raw bits end before their values",
}


def decode_unit(reader: ByteReader, classes: np.ndarray, tables: RansTables, what: str,
                limit: int | None = None) -> np.ndarray:
    """Read a unit of ``len(classes)`` values (int64) from ``reader`` (its bits may run up to byte ``limit`` of
    the reader's data, default its end); the reader is left after the unit.

    Raises
    ------
    BitstreamError
        If the unit is truncated or corrupt.
    """
    classes = np.ascontiguousarray(classes, dtype=np.int64)
    size = reader.read_varint(f"{what}: rANS size")
    if size > reader.remaining:
        raise BitstreamError(f"{what}: expected {size} rANS bytes, only {reader.remaining} left.")
    data = np.frombuffer(reader._data, dtype=np.uint8)
    start = reader.offset
    out = np.empty(len(classes), dtype=np.int64)
    if len(classes) and (classes.min() < 0 or classes.max() >= tables.num_classes):
        raise ValueError("rans6: classes outside the tables.")
    _, decode = _kernels()
    status, end = decode(data, start, start + size, len(data) if limit is None else limit, classes, tables.freq,
                         tables.cum, tables.coarse, out)
    if status:
        raise BitstreamError(f"{what}: {_ERRORS[status]}.")
    reader.read_bytes(end - start, what)
    return out
