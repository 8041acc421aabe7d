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
    "TokenRun",
    "class_groups",
    "laplace_token_probabilities",
    "read_tokens",
    "tokenize",
    "values_of_tokens",
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


#: Raw bit count of every token (inverse of :func:`tokenize`'s widths): 0 below ``_DIRECT``, then 4, 5, ... 39.
_TOKEN_WIDTHS = np.concatenate(
    [np.zeros(_DIRECT, dtype=np.int64), np.arange(_FIRST_ESCAPE_BITS - 1, MAX_MAGNITUDE_BITS, dtype=np.int64)]
)


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
    def probability_rows(self) -> np.ndarray:
        """(K, TOKEN_COUNT) every class's token probabilities, as :meth:`probabilities` (for per-value models)."""
        return np.stack([self.probabilities(klass) for klass in range(self.num_classes)])

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


def class_groups(classes: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int]]]:
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


def encode_classed(writer: ByteWriter, values: np.ndarray, classes: np.ndarray, tables: ClassTables) -> None:
    """Append ``values`` (int64, (N,)) coded with each one's class distribution to ``writer``.

    The decoder needs N, the classes and the tables (see :func:`decode_classed`).
    """
    values = np.asarray(values, dtype=np.int64).ravel()
    classes = _check_classes(classes, values.size, tables)
    tokens, raw, widths = tokenize(values)
    coder = constriction.stream.stack.AnsCoder()
    order, groups = class_groups(classes)
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
    """Read ``len(classes)`` values written by :func:`encode_classed` (int64, (N,)).

    Memory beside the N values: the classes, an int32 sort order and the int32 tokens (the histograms and the
    sort go a chunk at a time, see :func:`_stable_class_order`).
    """
    classes = _check_classes(classes, len(classes), tables)
    counts = _histogram(classes, tables.num_classes)
    present = np.flatnonzero(counts)
    order = _stable_class_order(classes, counts)
    run = read_tokens(reader, list(zip(present.tolist(), counts[present].tolist())), tables, what)
    placed = np.empty(len(classes), dtype=np.int32)  # one stream: put in place as int32, then widened
    placed[order] = run.tokens
    del order
    run = TokenRun(np.zeros(0, dtype=np.int32), run.nonzero, run.raw_bits, run.signs, run.raw)
    tokens = placed.astype(np.int64)
    del placed
    return _signed_values(tokens, [run])


#: Values per chunk of :func:`_histogram` and :func:`_stable_class_order` (bounds their temporaries).
_ORDER_CHUNK = 1 << 14


def _histogram(values: np.ndarray, size: int) -> np.ndarray:
    """``np.bincount(values, minlength=size)`` a chunk at a time (bincount casts its whole input to int64 first);
    every value must be below ``size``."""
    counts = np.zeros(size, dtype=np.int64)
    for start in range(0, len(values), _ORDER_CHUNK):
        counts += np.bincount(values[start : start + _ORDER_CHUNK], minlength=size)[:size]
    return counts


def _stable_class_order(classes: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """The permutation of :func:`class_groups`, as int32 (int64 past 2**31 values), sorted chunk by chunk;
    ``counts`` is the histogram of the classes.

    A counting sort of the chunks' stable sorts into each class's slots: the same permutation as one
    ``argsort(kind="stable")``, without its N-long int64 result and radix buffer.
    """
    if len(classes) <= _ORDER_CHUNK:
        return np.argsort(classes, kind="stable")
    order = np.empty(len(classes), dtype=np.int32 if len(classes) < 1 << 31 else np.int64)
    slots = np.cumsum(counts) - counts  # the next free place of each class in `order`
    for start in range(0, len(classes), _ORDER_CHUNK):
        chunk = classes[start : start + _ORDER_CHUNK]
        local = np.argsort(chunk, kind="stable")
        local_counts = np.bincount(chunk, minlength=len(counts))
        taken = 0
        for klass in np.flatnonzero(local_counts).tolist():
            count = int(local_counts[klass])
            order[slots[klass] : slots[klass] + count] = local[taken : taken + count] + start
            slots[klass] += count
            taken += count
    return order


@dataclass(frozen=True)
class TokenRun:
    """The tokens of one stream of :func:`encode_classed` in class order, and its sign and raw bytes, unparsed.

    Returned by :func:`read_tokens`; :func:`values_of_tokens` turns any number of them into values in one pass.
    """

    tokens: np.ndarray  # (N,) int32, sorted by class (the order they were coded in)
    nonzero: int  # how many tokens are not 0 (= sign bits)
    raw_bits: int  # total raw bits
    signs: bytes
    raw: bytes


def read_tokens(reader: ByteReader, groups: list[tuple[int, int]], tables: ClassTables, what: str) -> TokenRun:
    """The ANS part of one stream of :func:`encode_classed` and the bytes of its signs and raw bits.

    ``groups`` lists ``(class, count)`` of the classes present, in increasing class order (the stream codes the
    values sorted by class, stably). Splitting the read from :func:`values_of_tokens` lets a decoder with many small
    streams (one per random-access chunk) do the ANS calls stream by stream and everything else once.

    Raises
    ------
    BitstreamError
        If the ANS words run past the data, do not decode, or hold more than the counts of ``groups``.
    """
    num_words = reader.read_varint(f"{what}: ANS word count")
    if num_words > reader.remaining // 4:
        raise BitstreamError(f"{what}: expected {num_words} ANS words, only {reader.remaining} bytes left.")
    words = np.frombuffer(reader.read_bytes(4 * num_words, f"{what}: ANS words"), dtype="<u4").astype(np.uint32)
    try:
        coder = constriction.stream.stack.AnsCoder(words)
        parts, small = [], []
        for klass, count in groups:
            if count < _MERGE_BELOW:
                small.append((klass, count))
                continue
            if small:
                parts += _decode_small_groups(coder, tables, small)
                small = []
            parts.append(coder.decode(tables.model(klass), count))
        if small:
            parts += _decode_small_groups(coder, tables, small)
        finished = coder.is_empty()
    except (ValueError, RuntimeError, AssertionError) as error:
        raise BitstreamError(f"{what}: the ANS stream does not decode ({error}).") from None
    if not finished:
        raise BitstreamError(f"{what}: the ANS stream holds more data than its {sum(c for _, c in groups)} values.")
    tokens = np.concatenate(parts) if len(parts) > 1 else parts[0] if parts else np.zeros(0, dtype=np.int32)
    nonzero = int(np.count_nonzero(tokens))
    # The widths of the escaped tokens only (an N-long bool mask, not an N-long array of widths): the same sum.
    raw_bits = int(_TOKEN_WIDTHS[tokens[tokens >= _DIRECT]].sum()) if nonzero else 0
    signs = reader.read_bytes((nonzero + 7) // 8, f"{what}: signs")
    raw = reader.read_bytes((raw_bits + 7) // 8, f"{what}: raw bits")
    return TokenRun(tokens, nonzero, raw_bits, signs, raw)


#: Consecutive classes with fewer values than this are decoded in one call, with a model per value, when there are
#: at least :data:`_MERGE_GROUPS` of them: a call with a class model costs about 0.4 us beside its values, building
#: the per-value models about 4 us, then 30 ns a value (17 ns with a class model).
_MERGE_BELOW = 8
_MERGE_GROUPS = 6
_CATEGORICAL = constriction.stream.model.Categorical(perfect=False)


def _decode_small_groups(coder, tables: ClassTables, groups: list[tuple[int, int]]) -> list[np.ndarray]:
    """Tokens of consecutive small class groups: in one ANS call, each value with its class's model, when there are
    many of them, else one call per class.

    constriction builds the per-value models with the same quantization as :meth:`ClassTables.model` (a test
    checks every class), so the values decode exactly as with one call per class.
    """
    if len(groups) < _MERGE_GROUPS:
        return [coder.decode(tables.model(klass), count) for klass, count in groups]
    classes, counts = zip(*groups)
    return [coder.decode(_CATEGORICAL, tables.probability_rows[np.repeat(classes, counts)])]


def values_of_tokens(runs: list[TokenRun], order: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Values (int64, (N,)) of the streams ``runs``, concatenated in stream order (written into ``out`` if given).

    ``order`` (N,) is the permutation that sorts the streams' concatenated classes stream by stream and, inside a
    stream, stably by class: ``values[order]`` is the runs' tokens concatenated.
    """
    tokens = np.empty(len(order), dtype=np.int64) if out is None else out
    at = 0
    for run in runs:  # order is a permutation: every value is written
        tokens[order[at : at + len(run.tokens)]] = run.tokens
        at += len(run.tokens)
    return _signed_values(tokens, runs)


_EIGHT = np.arange(8)


def _signed_values(tokens: np.ndarray, runs: list[TokenRun]) -> np.ndarray:
    """``tokens`` (int64, (N,), in value order) turned into the values in place with the signs and raw bits of
    ``runs`` (their ``tokens`` are not read), and returned."""
    # Most values are 0: the rest of the work touches only the nonzero ones.
    nonzero = np.flatnonzero(tokens)
    if nonzero.size == 0:
        return tokens
    magnitudes = tokens[nonzero]
    # Each stream's sign bits start on a byte and follow its nonzero values in order.
    negative = np.concatenate([np.unpackbits(np.frombuffer(run.signs, dtype=np.uint8), count=run.nonzero)
                               for run in runs]) if len(runs) > 1 else np.unpackbits(
        np.frombuffer(runs[0].signs, dtype=np.uint8), count=runs[0].nonzero)
    escaped = np.flatnonzero(magnitudes >= _DIRECT)
    if escaped.size:
        width = _TOKEN_WIDTHS[magnitudes[escaped]]
        counts = np.cumsum([run.nonzero for run in runs]) if len(runs) > 1 else [runs[0].nonzero]
        bits = np.array([run.raw_bits for run in runs], dtype=np.int64)
        raw_bytes = np.array([len(run.raw) for run in runs], dtype=np.int64)
        stream = np.searchsorted(counts, escaped, side="right")  # the stream of each escaped value
        # Bit position of each escaped value's raw bits: its stream's first raw bit + the widths before it there.
        position = np.cumsum(width) - width + (8 * (np.cumsum(raw_bytes) - raw_bytes) - (np.cumsum(bits) - bits))[stream]
        data = np.frombuffer(b"".join([run.raw for run in runs] + [bytes(8)]), dtype=np.uint8)
        # The 8 bytes from the first raw bit's byte, read as one big-endian word: width + 7 <= 46 bits needed.
        byte = position >> 3
        if escaped.size <= _ORDER_CHUNK:  # gathered at once (an (n, 8) index: few values)
            window = data[byte[:, None] + _EIGHT].view(">u8")[:, 0].astype(np.uint64)
        else:  # a byte at a time (temporaries of n values)
            window = np.zeros(escaped.size, dtype=np.uint64)
            for i in range(8):
                window |= data[byte + i].astype(np.uint64) << np.uint64(56 - 8 * i)
        raw = ((window << (position & 7).astype(np.uint64)) >> (64 - width).astype(np.uint64)).astype(np.int64)
        magnitudes[escaped] = (np.int64(1) << width) + raw
    magnitudes *= 1 - 2 * negative.view(np.int8)  # -1 where the sign bit is set
    tokens[nonzero] = magnitudes
    return tokens
