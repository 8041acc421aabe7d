"""Coding integers with trained, class-conditional distributions and an ANS coder (``constriction``).

Transform coefficients are far from identically distributed: a low-frequency coefficient of the first PCA
component is large, a high-frequency one of the fortieth is almost always 0. A coder that knows, for every
coefficient, *which* distribution it comes from spends a small fraction of a bit on the near-certain zeros and the
full cost only where the signal is. This module codes an int64 array given a *class* per value (computed by the
caller, identically in encoder and decoder, from side information such as the value's frequency, channel and
quantization step) and a table of trained token distributions, one per class.

Binarization (as JPEG's magnitude categories)
    ``a = |v|``; ``a < 16`` is token ``a``; larger ``a`` is token ``16 + (bit_length(a) - 5)`` followed by the
    ``bit_length(a) - 1`` low bits of ``a`` sent raw; a nonzero value's sign is one raw bit. Tokens cover
    ``|v| < 2^40``.
Entropy coding
    Tokens are coded with a range-variant ANS stack coder (``constriction.stream.stack.AnsCoder``), one categorical
    model per class built from integer training counts (``counts / counts.sum()`` is computed with correctly
    rounded IEEE division only, so every machine builds the same model and decodes the same stream). Each class's
    tokens are coded as one vectorized call: decoding runs at tens of millions of tokens per second.
Layout
    ``varint n_words, n_words uint32 ANS words | packed sign bits | packed raw bits``.

Every count is checked before allocation; a corrupt stream raises :class:`BitstreamError`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import constriction
import numpy as np

from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError

__all__ = [
    "MAX_MAGNITUDE_BITS",
    "TOKEN_COUNT",
    "ClassTables",
    "decode_classed",
    "encode_classed",
    "laplace_token_probabilities",
    "tokenize",
]

_DIRECT = 16  # magnitudes 0..15 are tokens of their own
_FIRST_ESCAPE_BITS = 5  # bit_length of 16
#: Largest magnitude bit length the tokens cover (|v| < 2^40).
MAX_MAGNITUDE_BITS = 40
#: Size of the token alphabet.
TOKEN_COUNT = _DIRECT + MAX_MAGNITUDE_BITS - _FIRST_ESCAPE_BITS + 1


def tokenize(values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split int64 values into tokens, raw low bits and their widths.

    Returns
    -------
    tokens : ndarray, shape (N,), int32, in ``[0, TOKEN_COUNT)``
    raw : ndarray, shape (N,), int64: the low bits of escaped magnitudes (0 elsewhere)
    widths : ndarray, shape (N,), int64: how many raw bits each value carries (0 for ``|v| < 16``)

    Raises
    ------
    ValueError
        If a magnitude needs more than ``MAX_MAGNITUDE_BITS`` bits.
    """
    magnitude = np.abs(np.asarray(values, dtype=np.int64))
    if magnitude.size and int(magnitude.max()) >= 1 << MAX_MAGNITUDE_BITS:
        raise ValueError(f"ans: magnitudes must be < 2^{MAX_MAGNITUDE_BITS}, got {int(magnitude.max())}.")
    bit_length = _bit_length(magnitude)
    escaped = magnitude >= _DIRECT
    tokens = np.where(escaped, _DIRECT + bit_length - _FIRST_ESCAPE_BITS, magnitude).astype(np.int32)
    widths = np.where(escaped, bit_length - 1, 0)
    raw = np.where(escaped, magnitude - (np.int64(1) << np.maximum(widths, 0)), 0)
    return tokens, raw, widths


def _bit_length(magnitude: np.ndarray) -> np.ndarray:
    """Bit length of non-negative int64 values below 2^52 (exact through float64's exponent)."""
    _, exponent = np.frexp(magnitude.astype(np.float64))
    return exponent.astype(np.int64)


def _token_widths(tokens: np.ndarray) -> np.ndarray:
    """Raw bit count of each token (inverse of :func:`tokenize`'s widths)."""
    return np.where(tokens >= _DIRECT, tokens.astype(np.int64) - _DIRECT + _FIRST_ESCAPE_BITS - 1, 0)


def laplace_token_probabilities(scale: float, rounding: float) -> np.ndarray:
    """Token probabilities of a Laplace(0, ``scale``) value quantized with a dead zone (offset ``rounding``).

    The value ``x`` (in steps) maps to ``sign(x) floor(|x| + rounding)``; |q| = a >= 1 has probability
    ``(θ^(a - r) - θ^(a + 1 - r)) ``, θ = exp(-1/scale), summed over each escape token's magnitude range. Used as the
    prior that training counts are added to. Returns (TOKEN_COUNT,) float64 summing to 1.
    """
    theta_log = -1.0 / max(scale, 1e-6)
    low = np.concatenate([[0], np.arange(1, _DIRECT), 2.0 ** np.arange(_FIRST_ESCAPE_BITS - 1, MAX_MAGNITUDE_BITS)])
    # P(|q| >= a) = exp(-(a - r) / s) for a >= 1, 1 for a = 0.
    survival = np.where(low == 0, 1.0, np.exp(np.minimum(0.0, theta_log * (low - rounding))))
    probabilities = survival - np.append(survival[1:], 0.0)
    return np.maximum(probabilities, 0.0) / probabilities.sum()


@dataclass(frozen=True, eq=False)
class ClassTables:
    """Token distributions, one per class, from integer counts.

    Attributes
    ----------
    counts : ndarray, shape (K, TOKEN_COUNT), int64, all >= 1
        Trained token counts of each class (row k is class k).
    """

    counts: np.ndarray
    _models: dict = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        counts = np.asarray(self.counts)
        if counts.ndim != 2 or counts.shape[1] != TOKEN_COUNT or counts.size == 0 or counts.min() < 1:
            raise ValueError(f"ans: counts must be (K, {TOKEN_COUNT}) positive integers, got shape {counts.shape}.")
        object.__setattr__(self, "counts", counts.astype(np.int64))

    @property
    def num_classes(self) -> int:
        return self.counts.shape[0]

    def probabilities(self, klass: int) -> np.ndarray:
        row = self.counts[klass].astype(np.float64)
        return row / row.sum()

    def model(self, klass: int):
        """The constriction categorical model of a class (built once)."""
        if klass not in self._models:
            self._models[klass] = constriction.stream.model.Categorical(self.probabilities(klass), perfect=False)
        return self._models[klass]

    @cached_property
    def log2_probabilities(self) -> np.ndarray:
        """(K, TOKEN_COUNT) log2 of every class's token probabilities (for the encoder's cost estimates)."""
        return np.log2(self.counts) - np.log2(self.counts.sum(axis=1, keepdims=True))

    def code_length_bits(self, tokens: np.ndarray, classes: np.ndarray) -> float:
        """Ideal code length of ``tokens`` under the classes' distributions (bits, excluding raw bits)."""
        return float(-self.log2_probabilities[classes, tokens].sum())


def _check_classes(classes: np.ndarray, count: int, tables: ClassTables) -> np.ndarray:
    classes = np.asarray(classes)
    if classes.shape != (count,):
        raise ValueError(f"ans: expected {count} classes, got shape {classes.shape}.")
    if count and (classes.min() < 0 or classes.max() >= tables.num_classes):
        raise ValueError(f"ans: classes must lie in [0, {tables.num_classes}), got [{classes.min()}, {classes.max()}].")
    return classes.astype(np.uint8 if tables.num_classes <= 256 else np.int64)  # uint8 sorts by radix: O(N)


def _class_groups(classes: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """A stable permutation sorting the values by class, and (class, count) of each class present, in order."""
    order = np.argsort(classes, kind="stable")
    counts = np.bincount(classes)
    present = np.flatnonzero(counts)
    return order, list(zip(present.tolist(), counts[present].tolist()))


def _pack_raw_bits(raw: np.ndarray, widths: np.ndarray) -> bytes:
    """Concatenate the ``widths[i]`` low bits of each ``raw[i]`` (MSB first) into bytes."""
    if not widths.any():
        return b""
    positions = np.arange(int(widths.max()))
    selected = widths > 0
    bits = (raw[selected, None] >> (widths[selected, None] - 1 - positions)) & 1
    return np.packbits(bits[positions < widths[selected, None]].astype(np.uint8)).tobytes()


def _unpack_raw_bits(data: bytes, widths: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_pack_raw_bits`."""
    raw = np.zeros(len(widths), dtype=np.int64)
    selected = widths > 0
    if not selected.any():
        return raw
    bits = np.unpackbits(np.frombuffer(data, dtype=np.uint8)).astype(np.int64)
    ends = np.cumsum(widths[selected])
    starts = ends - widths[selected]
    positions = np.arange(int(widths.max()))
    index = starts[:, None] + positions
    valid = positions < widths[selected, None]
    weights = np.where(valid, np.int64(1) << np.maximum(widths[selected, None] - 1 - positions, 0), 0)
    raw[selected] = (bits[np.where(valid, index, 0)] * weights).sum(axis=1)
    return raw


def encode_classed(writer: ByteWriter, values: np.ndarray, classes: np.ndarray, tables: ClassTables) -> None:
    """Append ``values`` (int64, (N,)) coded with each one's class distribution to ``writer``.

    The decoder needs N, the classes and the tables (see :func:`decode_classed`).
    """
    values = np.asarray(values, dtype=np.int64).ravel()
    classes = _check_classes(classes, values.size, tables)
    tokens, raw, widths = tokenize(values)
    coder = constriction.stream.stack.AnsCoder()
    order, groups = _class_groups(classes)
    sorted_tokens = tokens[order]
    end = len(sorted_tokens)
    for klass, count in reversed(groups):  # a stack: encode last what is decoded first
        coder.encode_reverse(sorted_tokens[end - count : end], tables.model(klass))
        end -= count
    words = coder.get_compressed()
    writer.write_varint(words.size)
    writer.write_array(words, "<u4")
    writer.write_bytes(np.packbits(values[values != 0] < 0).tobytes())
    writer.write_bytes(_pack_raw_bits(raw, widths))


def decode_classed(reader: ByteReader, classes: np.ndarray, tables: ClassTables, what: str) -> np.ndarray:
    """Read ``len(classes)`` values written by :func:`encode_classed` (int64, (N,))."""
    classes = _check_classes(classes, len(classes), tables)
    num_words = reader.read_varint(f"{what}: ANS word count")
    if num_words > reader.remaining // 4:
        raise BitstreamError(f"{what}: expected {num_words} ANS words, only {reader.remaining} bytes left.")
    words = reader.read_array(num_words, "<u4", f"{what}: ANS words").astype(np.uint32)
    order, groups = _class_groups(classes)
    try:
        coder = constriction.stream.stack.AnsCoder(words)
        parts = [coder.decode(tables.model(klass), count) for klass, count in groups]
        finished = coder.is_empty()
    except (ValueError, RuntimeError, AssertionError) as error:
        raise BitstreamError(f"{what}: the ANS stream does not decode ({error}).") from None
    if not finished:
        raise BitstreamError(f"{what}: the ANS stream holds more data than its {len(classes)} values.")
    tokens = np.zeros(len(classes), dtype=np.int32)
    if parts:
        tokens[order] = np.concatenate(parts)
    # Most values are 0: the rest of the work touches only the nonzero ones.
    nonzero = np.flatnonzero(tokens)
    tokens = tokens[nonzero].astype(np.int64)
    signs = np.unpackbits(
        np.frombuffer(reader.read_bytes((len(nonzero) + 7) // 8, f"{what}: signs"), dtype=np.uint8)
    )[: len(nonzero)]
    widths = _token_widths(tokens)
    raw = _unpack_raw_bits(reader.read_bytes((int(widths.sum()) + 7) // 8, f"{what}: raw bits"), widths)
    magnitudes = np.where(tokens >= _DIRECT, (np.int64(1) << widths) + raw, tokens)
    values = np.zeros(len(classes), dtype=np.int64)
    values[nonzero] = np.where(signs.astype(bool), -magnitudes, magnitudes)
    return values
