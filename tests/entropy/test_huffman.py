"""Canonical Huffman blobs: round trips on arbitrary int arrays, code optimality, table limits, corruption."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from mocapbench.entropy import (
    BitstreamError,
    ByteReader,
    ByteWriter,
    decode_symbols,
    encode_symbols,
    encode_varint,
    huffman_code_lengths,
    huffman_payload_bits,
)
from mocapbench.entropy import huffman

INT64_MIN, INT64_MAX = -(2**63), 2**63 - 1


def _round_trip(symbols) -> bytes:
    arr = np.asarray(symbols)
    blob = encode_symbols(arr)
    assert isinstance(blob, bytes) and len(blob) > 0
    decoded, end = decode_symbols(blob)
    assert decoded.dtype == np.int64
    assert end == len(blob)
    np.testing.assert_array_equal(decoded, arr.astype(np.int64))
    return blob


def _kraft_sum(lengths: np.ndarray) -> float:
    return float(np.sum(2.0 ** -lengths.astype(np.float64)))


# --------------------------------------------------------------------------------------------------------------------
# round trips


@pytest.mark.parametrize(
    "symbols",
    [
        np.zeros(0, dtype=np.int64),
        np.array([7]),
        np.array([-3]),
        np.full(1000, 42),
        np.full(3, INT64_MIN),
        np.array([1, 2]),
        np.array([INT64_MIN, INT64_MAX, 0, INT64_MAX]),
        np.arange(-500, 501),
        np.array([0] * 10_000 + [1, -1, 2**40]),
        np.array([5, 5, 5, 5, 9], dtype=np.uint8),
        np.array([-128, 127, 0], dtype=np.int8),
        np.array([2**63 - 1, 0], dtype=np.uint64),
    ],
    ids=["empty", "one", "one-negative", "one-distinct", "one-distinct-min", "two", "int64-extremes", "dense-1001",
         "skewed-outliers", "uint8", "int8", "uint64-in-int64"],
)
def test_round_trip_special_cases(symbols):
    _round_trip(symbols)


def test_lists_and_empty_float_arrays_are_accepted():
    _round_trip([3, -1, 3, 3])
    assert decode_symbols(encode_symbols([]))[0].shape == (0,)


def test_single_distinct_symbol_costs_no_payload_bits():
    assert len(encode_symbols(np.full(10**6, -9))) == len(encode_varint(10**6)) + 1 + 1
    assert huffman_payload_bits(np.full(100, 3)) == 0


def test_empty_blob_is_one_byte():
    assert encode_symbols(np.zeros(0, dtype=np.int64)) == b"\x00"


@settings(max_examples=150, deadline=None)
@given(st.lists(st.integers(INT64_MIN, INT64_MAX), max_size=60))
def test_round_trip_arbitrary_int64(values):
    _round_trip(np.array(values, dtype=np.int64))


@settings(max_examples=120, deadline=None)
@given(hnp.arrays(dtype=st.sampled_from([np.int8, np.uint8, np.int16, np.int32, np.int64]),
                  shape=st.integers(0, 301)))
def test_round_trip_numpy_dtypes_and_odd_lengths(arr):
    _round_trip(arr)


@settings(max_examples=150, deadline=None)
@given(
    alphabet=st.lists(st.integers(-(10**12), 10**12), min_size=1, max_size=12, unique=True),
    weights=st.lists(st.integers(1, 1000), min_size=12, max_size=12),
    n=st.integers(1, 2000),
    seed=st.integers(0, 2**32 - 1),
)
def test_round_trip_skewed_distributions(alphabet, weights, n, seed):
    p = np.asarray(weights[: len(alphabet)], dtype=np.float64) ** 3  # cubing makes the skew strong
    rng = np.random.default_rng(seed)
    _round_trip(rng.choice(np.asarray(alphabet), size=n, p=p / p.sum()))


def test_round_trip_large_sparse_alphabet():
    rng = np.random.default_rng(1)
    symbols = rng.integers(-(2**50), 2**50, 70_000)  # ~70k distinct values, sorted path of np.unique
    _round_trip(symbols)


def test_round_trip_large_dense_alphabet():
    rng = np.random.default_rng(2)
    symbols = np.rint(rng.laplace(0, 3000, 200_000)).astype(np.int64)  # bincount path, ~20k distinct
    _round_trip(symbols)


def test_blobs_concatenate_and_decode_at_offsets():
    parts = [np.array([1, 1, 2]), np.zeros(0, dtype=np.int64), np.full(5, -4), np.arange(-20, 20)]
    data = b"head" + b"".join(encode_symbols(p) for p in parts) + b"tail"
    offset = 4
    for part in parts:
        decoded, offset = decode_symbols(data, offset)
        np.testing.assert_array_equal(decoded, part)
    assert data[offset:] == b"tail"
    decoded, _ = decode_symbols(memoryview(data), 4)  # memoryview works too
    np.testing.assert_array_equal(decoded, parts[0])


def test_encoding_is_deterministic():
    rng = np.random.default_rng(3)
    symbols = rng.integers(-50, 50, 5000)
    assert encode_symbols(symbols) == encode_symbols(symbols.copy())


# --------------------------------------------------------------------------------------------------------------------
# the code itself


@settings(max_examples=100, deadline=None)
@given(st.lists(st.integers(-30, 30), min_size=2, max_size=500).filter(lambda v: len(set(v)) >= 2))
def test_code_is_complete_and_within_one_bit_of_entropy(values):
    symbols = np.asarray(values)
    alphabet, lengths = huffman_code_lengths(symbols)
    np.testing.assert_array_equal(alphabet, np.unique(symbols))
    assert _kraft_sum(lengths) == 1.0  # complete prefix code: every bit pattern decodes
    counts = np.array([np.sum(symbols == a) for a in alphabet])
    bits = huffman_payload_bits(symbols)
    assert bits == int((counts * lengths).sum())
    p = counts / counts.sum()
    entropy_bits = float(-(counts * np.log2(p)).sum())
    assert entropy_bits - 1e-9 <= bits < entropy_bits + symbols.size  # Huffman: H <= L < H + 1 per symbol


def test_blob_size_is_header_table_and_payload():
    rng = np.random.default_rng(4)
    symbols = rng.geometric(0.3, 10_001) - 1
    blob = encode_symbols(symbols)
    payload_bytes = -(-huffman_payload_bits(symbols) // 8)
    alphabet, _ = huffman_code_lengths(symbols)
    # header + table is small: a few bytes of counts and about a byte per distinct symbol
    assert payload_bytes < len(blob) <= payload_bytes + 8 + 2 * alphabet.size


def test_skewed_source_compresses_below_fixed_width():
    rng = np.random.default_rng(5)
    symbols = np.rint(rng.laplace(0, 2.0, 100_000)).astype(np.int64)
    blob = encode_symbols(symbols)
    fixed_bits = np.ceil(np.log2(np.ptp(symbols) + 1))
    assert 8 * len(blob) / symbols.size < fixed_bits - 1


def _fibonacci_counts(k: int) -> np.ndarray:
    fib = [1, 1]
    while len(fib) < k:
        fib.append(fib[-1] + fib[-2])
    return np.array(fib[:k], dtype=np.int64)


def test_fibonacci_counts_give_the_deepest_tree_and_the_limit_flattens_it():
    counts = _fibonacci_counts(30)
    unlimited = huffman._code_lengths(counts, 64)
    assert unlimited.max() == 29  # the worst case: one more bit per symbol
    for limit in (5, 8, 12, 20):
        limited = huffman._code_lengths(counts, limit)
        assert limited.max() <= limit
        assert _kraft_sum(limited) == 1.0
    with pytest.raises(ValueError, match=r"31 distinct symbols cannot be coded with codes of at most 4 bits"):
        huffman._code_lengths(np.ones(31, dtype=np.int64), 4)


def test_length_limited_blob_round_trips(monkeypatch):
    counts = _fibonacci_counts(20)
    symbols = np.repeat(np.arange(20) * 7 - 50, counts)
    np.random.default_rng(6).shuffle(symbols)
    assert huffman_code_lengths(symbols)[1].max() == 19  # unlimited
    monkeypatch.setattr(huffman, "MAX_CODE_LENGTH", 6)
    blob = _round_trip(symbols)
    reader = ByteReader(blob)
    assert (reader.read_varint(), reader.read_varint()) == (symbols.size, 20)
    assert reader.read_u8() == 6  # the longest code written is the limit
    assert huffman_code_lengths(symbols)[1].max() == 6
    assert 8 * len(blob) > huffman_payload_bits(symbols)


# --------------------------------------------------------------------------------------------------------------------
# input validation


def test_encode_rejects_bad_input():
    with pytest.raises(ValueError, match=r"Expected `symbols` to be 1-D, got shape \(2, 2\); pass symbols.ravel\(\)"):
        encode_symbols(np.zeros((2, 2), dtype=np.int64))
    with pytest.raises(ValueError, match=r"`symbols` must be integers, got dtype float64"):
        encode_symbols(np.array([1.0, 2.0]))
    with pytest.raises(ValueError, match=r"`symbols` must fit in int64, got 9223372036854775808"):
        encode_symbols(np.array([2**63], dtype=np.uint64))


# --------------------------------------------------------------------------------------------------------------------
# corrupt and truncated blobs


CORRUPTION_CASES = {
    "empty": np.zeros(0, dtype=np.int64),
    "one-distinct": np.full(300, -77),
    "two": np.array([0, 1, 1, 0, 1]),
    "laplace": np.rint(np.random.default_rng(7).laplace(0, 4, 150)).astype(np.int64),
    "sparse": np.random.default_rng(8).integers(-(2**40), 2**40, 20),
}


@pytest.mark.parametrize("name", sorted(CORRUPTION_CASES))
def test_every_truncation_raises(name):
    blob = encode_symbols(CORRUPTION_CASES[name])
    for cut in range(len(blob)):
        with pytest.raises(BitstreamError):
            decode_symbols(blob[:cut])


@pytest.mark.parametrize("name", sorted(CORRUPTION_CASES))
def test_every_single_bit_flip_raises_or_keeps_the_count(name):
    symbols = CORRUPTION_CASES[name]
    blob = bytearray(encode_symbols(symbols))
    outcomes = {"error": 0, "decoded": 0}
    for bit in range(8 * len(blob)):
        blob[bit // 8] ^= 0x80 >> (bit % 8)
        try:
            decoded, end = decode_symbols(bytes(blob), expected_count=symbols.size)
        except BitstreamError:
            outcomes["error"] += 1
        else:
            outcomes["decoded"] += 1
            assert decoded.shape == symbols.shape and decoded.dtype == np.int64
            assert 0 < end <= len(blob)
        blob[bit // 8] ^= 0x80 >> (bit % 8)
    assert outcomes["error"] > 0


@settings(max_examples=60, deadline=None)
@given(
    values=st.lists(st.integers(-40, 40), min_size=1, max_size=200),
    flips=st.lists(st.integers(0, 10**6), min_size=1, max_size=4),
)
def test_random_bit_flips_raise_or_keep_the_count(values, flips):
    symbols = np.asarray(values)
    blob = bytearray(encode_symbols(symbols))
    for flip in flips:
        bit = flip % (8 * len(blob))
        blob[bit // 8] ^= 0x80 >> (bit % 8)
    try:
        decoded, _ = decode_symbols(bytes(blob), expected_count=symbols.size)
    except BitstreamError:
        return
    assert decoded.shape == symbols.shape


def test_garbage_never_raises_anything_but_bitstream_error():
    rng = np.random.default_rng(9)
    for size in range(0, 64):
        for _ in range(20):
            data = rng.integers(0, 256, size, dtype=np.uint8).tobytes()
            try:
                decoded, end = decode_symbols(data)
            except BitstreamError:
                continue
            assert end <= len(data)


def _blob(n: int, k: int, max_len: int | None = None, counts=(), table=(), payload=b"") -> bytes:
    writer = ByteWriter()
    writer.write_varint(n)
    writer.write_varint(k)
    if max_len is not None:
        writer.write_u8(max_len)
    for value in (*counts, *table):
        writer.write_varint(value)
    writer.write_bytes(payload)
    return writer.getvalue()


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (b"", r"expected 1 more byte for varint Huffman symbol count \(byte 1\), found 0"),
        (_blob(5, 6), r"expected a Huffman alphabet size in \[1, 5\] for 5 symbols, found 6"),
        (_blob(5, 0), r"expected a Huffman alphabet size in \[1, 5\] for 5 symbols, found 0"),
        (_blob(4, 2, 0), r"expected a longest Huffman code length in \[1, 31\] for 2 symbols, found 0"),
        (_blob(4, 2, 32), r"expected a longest Huffman code length in \[1, 31\] for 2 symbols, found 32"),
        (_blob(4, 3, 1), r"expected a longest Huffman code length in \[2, 31\] for 3 symbols, found 1"),
        (_blob(4, 3, 2, [1, 1]), r"expected Huffman code-length counts summing to 3 with codes of length 2"),
        (_blob(4, 3, 2, [2, 0]), r"expected Huffman code-length counts summing to 3"),
        (_blob(4, 3, 3, [1, 1, 1]), r"complete prefix code \(Kraft sum 1\), found Kraft sum 0.875"),
        (_blob(4, 2, 1, [2], [8, 0]), r"expected at least 1 bytes for 4 Huffman codes, found 0"),
        (_blob(4, 3, 2, [1, 2], [0, 8, 2**64 - 1]), r"increasing within each code length"),
        (_blob(8, 3, 2, [1, 2], [0, 10, 0], b"\xff"),
         r"expected 8 Huffman codes in the 1 bytes after the table, decoding failed"),
        (_blob(4, 2, 1, [2], [0, 0], b"\x51"), r"expected zero padding bits"),
        (_blob(4, 2, 1, [2], [0]), r"expected 2 varints for Huffman symbol table, found 1"),
    ],
    ids=["empty", "k>n", "k=0", "len0", "len32", "len-too-short", "count-sum-low", "count-last-zero", "kraft<1",
         "no-payload", "table-decrease", "payload-short", "padding", "table-truncated"],
)
def test_invalid_blobs_raise_with_a_message_naming_the_field(data, message):
    with pytest.raises(BitstreamError, match=message):
        decode_symbols(data)


def test_hand_written_blob_decodes():
    # 4 symbols, 2 distinct: table zigzag(0) -> 0, then 8 - 0 - 1 = 7 -> symbols [0, 8]; codes 0 -> 0, 1 -> 8.
    decoded, end = decode_symbols(_blob(4, 2, 1, [2], [0, 7], b"\x50"))
    np.testing.assert_array_equal(decoded, [0, 8, 0, 8])
    assert end == 7


def test_declared_count_is_bounded_before_allocating():
    one_symbol = _blob(10**15, 1) + encode_varint(0)
    with pytest.raises(BitstreamError, match=r"expected at most 67108864 Huffman symbols \(max_count\), "
                                             r"the header declares 1000000000000000"):
        decode_symbols(one_symbol)
    with pytest.raises(BitstreamError, match=r"expected at most 10 Huffman symbols"):
        decode_symbols(encode_symbols(np.zeros(11, dtype=np.int64)), max_count=10)


def test_expected_count_mismatch_raises():
    blob = encode_symbols(np.arange(10))
    with pytest.raises(BitstreamError, match=r"expected 11 Huffman symbols, the header declares 10"):
        decode_symbols(blob, expected_count=11)
    assert decode_symbols(blob, expected_count=10)[0].size == 10
