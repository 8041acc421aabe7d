"""Bit and byte I/O: round trips (hypothesis, exhaustive small widths), zigzag, varints, and every error path."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from bitarray import bitarray
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapbench.entropy import (
    BitReader,
    BitstreamError,
    BitWriter,
    ByteReader,
    ByteWriter,
    decode_varint,
    decode_varints,
    encode_varint,
    encode_varints,
    zigzag_decode,
    zigzag_encode,
)

INT64_MIN, INT64_MAX, UINT64_MAX = -(2**63), 2**63 - 1, 2**64 - 1


@st.composite
def fields(draw):
    """An (value, nbits) pair with value < 2**nbits, nbits in 0..64."""
    nbits = draw(st.integers(0, 64))
    return draw(st.integers(0, (1 << nbits) - 1)), nbits


# --------------------------------------------------------------------------------------------------------------------
# BitWriter / BitReader


@settings(max_examples=150, deadline=None)
@given(st.lists(fields(), max_size=40))
def test_scalar_fields_round_trip(items):
    writer = BitWriter()
    for value, nbits in items:
        writer.write(value, nbits)
    total = sum(nbits for _, nbits in items)
    assert len(writer) == total
    data = writer.getvalue()
    assert len(data) == -(-total // 8)
    reader = BitReader(data)
    assert [reader.read(nbits) for _, nbits in items] == [value for value, _ in items]
    assert reader.bits_left == 8 * len(data) - total < 8
    assert reader.read(reader.bits_left) == 0  # padding is zero bits


@settings(max_examples=120, deadline=None)
@given(
    prefix=st.lists(fields(), max_size=3),
    nbits=st.integers(0, 64),
    data=st.data(),
)
def test_array_fields_round_trip_at_any_bit_offset(prefix, nbits, data):
    values = data.draw(st.lists(st.integers(0, (1 << nbits) - 1), max_size=75))
    dtype = np.uint64 if nbits == 64 else np.int64
    arr = np.asarray(values, dtype=dtype)
    writer = BitWriter()
    for value, width in prefix:
        writer.write(value, width)
    writer.write_array(arr, nbits)
    writer.write(1, 1)  # a sentinel after the array: the array must not eat into it
    reader = BitReader(writer.getvalue())
    assert [reader.read(width) for _, width in prefix] == [value for value, _ in prefix]
    out = reader.read_array(arr.size, nbits)
    assert out.dtype == np.uint64 and out.shape == (arr.size,)
    assert out.tolist() == values
    assert reader.read(1) == 1


@pytest.mark.parametrize("nbits", range(1, 13))
def test_every_value_of_small_widths_packs_like_scalar_writes(nbits):
    values = np.arange(1 << nbits)
    vectorized, scalar = BitWriter(), BitWriter()
    vectorized.write_array(values, nbits)
    for value in values.tolist():
        scalar.write(value, nbits)
    assert vectorized.getvalue() == scalar.getvalue()
    out = BitReader(vectorized.getvalue()).read_array(values.size, nbits)
    assert int((out != values).sum()) == 0


def test_write_array_spans_several_chunks():
    rng = np.random.default_rng(0)
    values = rng.integers(0, 1 << 37, 200_003, dtype=np.int64)  # > 3 chunks of 2**16, odd length
    writer = BitWriter()
    writer.write(3, 2)
    writer.write_array(values, 37)
    reader = BitReader(writer.getvalue())
    assert reader.read(2) == 3
    np.testing.assert_array_equal(reader.read_array(values.size, 37), values)


def test_write_array_accepts_any_shape_in_c_order():
    writer = BitWriter()
    writer.write_array(np.array([[1, 2], [3, 0]], dtype=np.uint8), 2)
    assert writer.getvalue() == bytes([0b01101100])


def test_bits_and_alignment():
    writer = BitWriter()
    writer.write_bits(bitarray("101"))
    writer.write_bits("11")
    writer.pad_to_byte()
    writer.write(0xAB, 8)
    assert writer.getvalue() == bytes([0b10111000, 0xAB])
    reader = BitReader(writer.getvalue())
    assert reader.read_bits(5) == bitarray("10111")
    reader.align()
    assert reader.position == 8 and reader.read(8) == 0xAB


def test_reading_past_the_end_names_the_field_and_what_is_left():
    reader = BitReader(b"\xff")
    reader.read(3)
    with pytest.raises(BitstreamError, match=r"expected 6 bits for scale, found 5"):
        reader.read(6, "scale")
    with pytest.raises(BitstreamError, match=r"expected 12 bits for weights \(3 x 4-bit fields\), found 5"):
        reader.read_array(3, 4, "weights")
    assert reader.bits_left == 5  # a failed read consumes nothing


def test_huge_array_read_fails_before_allocating():
    with pytest.raises(BitstreamError, match=r"expected 64000000000000 bits"):
        BitReader(b"\x00" * 4).read_array(10**12, 64)


@pytest.mark.parametrize(
    ("value", "nbits", "message"),
    [
        (8, 3, r"`value` must be in \[0, 2\*\*3 - 1\] for nbits=3, got 8"),
        (-1, 8, r"`value` must be in \[0, 2\*\*8 - 1\] for nbits=8, got -1"),
        (1, 0, r"`value` must be in \[0, 2\*\*0 - 1\] for nbits=0, got 1"),
        (0, 65, r"`nbits` must be an int in \[0, 64\], got 65"),
        (0, -1, r"`nbits` must be an int in \[0, 64\], got -1"),
        (1.0, 8, r"`value` must be an int, got 1.0"),
    ],
)
def test_write_rejects_values_that_do_not_fit(value, nbits, message):
    with pytest.raises(ValueError, match=message):
        BitWriter().write(value, nbits)


def test_write_array_rejects_values_that_do_not_fit():
    with pytest.raises(ValueError, match=r"`values` must be < 2\*\*4 for nbits=4, got max 16"):
        BitWriter().write_array([1, 16], 4)
    with pytest.raises(ValueError, match=r"`values` must be non-negative for unsigned fields, got min -2"):
        BitWriter().write_array([1, -2], 4)
    with pytest.raises(ValueError, match=r"`values` must be an integer array, got dtype float64"):
        BitWriter().write_array([1.5], 4)
    with pytest.raises(ValueError, match=r"`values` must be 0 for nbits=0, got max 1"):
        BitWriter().write_array([0, 1], 0)


# --------------------------------------------------------------------------------------------------------------------
# zigzag


def test_zigzag_interleaves_signs():
    np.testing.assert_array_equal(zigzag_encode([0, -1, 1, -2, 2, INT64_MIN, INT64_MAX]),
                                  np.array([0, 1, 2, 3, 4, UINT64_MAX, UINT64_MAX - 1], dtype=np.uint64))


def test_zigzag_exhaustive_on_int16():
    values = np.arange(-(2**15), 2**15, dtype=np.int64)
    codes = zigzag_encode(values)
    expected = np.where(values >= 0, 2 * values, -2 * values - 1)
    assert int((codes.astype(np.int64) != expected).sum()) == 0
    assert int((zigzag_decode(codes) != values).sum()) == 0
    assert np.unique(codes).size == values.size  # a bijection onto 0 .. 2**16 - 1
    assert codes.max() == 2**16 - 1


@settings(deadline=None)
@given(st.lists(st.integers(INT64_MIN, INT64_MAX), max_size=50))
def test_zigzag_round_trips_int64(values):
    arr = np.asarray(values, dtype=np.int64)
    codes = zigzag_encode(arr)
    assert codes.dtype == np.uint64
    assert zigzag_decode(codes).tolist() == values


def test_zigzag_rejects_bad_input():
    with pytest.raises(ValueError, match=r"`values` must fit in int64"):
        zigzag_encode(np.array([2**63], dtype=np.uint64))
    with pytest.raises(ValueError, match=r"`codes` must be non-negative, got -1"):
        zigzag_decode([-1])
    with pytest.raises(ValueError, match=r"integer array, got dtype float64"):
        zigzag_encode([0.5])


# --------------------------------------------------------------------------------------------------------------------
# varints


@pytest.mark.parametrize(
    ("value", "encoded"),
    [(0, "00"), (1, "01"), (127, "7f"), (128, "8001"), (300, "ac02"), (16383, "ff7f"), (16384, "808001"),
     (UINT64_MAX, "ffffffffffffffffff01")],
)
def test_varint_known_encodings(value, encoded):
    assert encode_varint(value).hex() == encoded
    assert encode_varints([value] if value <= INT64_MAX else np.array([value], dtype=np.uint64)).hex() == encoded
    assert decode_varint(bytes.fromhex(encoded)) == (value, len(encoded) // 2)


@settings(deadline=None)
@given(st.lists(st.integers(0, UINT64_MAX), max_size=150), st.binary(max_size=3))  # both sides of _FEW_VARINTS
def test_varints_scalar_and_vectorized_agree_and_round_trip(values, prefix):
    scalar = b"".join(encode_varint(v) for v in values)
    assert encode_varints(np.array(values, dtype=np.uint64)) == scalar
    data = prefix + scalar + b"\x80"  # trailing incomplete varint must not matter
    decoded, end = decode_varints(data, len(prefix), len(values))
    assert decoded.tolist() == values and end == len(prefix) + len(scalar)
    offset, out = len(prefix), []
    for _ in values:
        value, offset = decode_varint(data, offset)
        out.append(value)
    assert out == values and offset == end


def test_over_long_varint_is_rejected():
    over_long = b"\x80" * 10 + b"\x01"
    with pytest.raises(BitstreamError, match=r"varint frame count longer than 10 bytes"):
        decode_varint(over_long, what="frame count")
    with pytest.raises(BitstreamError, match=r"varint 0 of table longer than 10 bytes"):
        decode_varints(over_long, 0, 1, "table")
    with pytest.raises(BitstreamError, match=r"varint joints longer than 2 bytes"):
        ByteReader(encode_varint(1 << 14)).read_varint("joints", max_bytes=2)


def test_varint_beyond_64_bits_is_rejected():
    data = b"\xff" * 9 + b"\x02"
    with pytest.raises(BitstreamError, match=r"exceeds 64 bits"):
        decode_varint(data)
    with pytest.raises(BitstreamError, match=r"exceeds 64 bits"):
        decode_varints(data, 0, 1)


def test_non_minimal_varint_is_rejected():
    with pytest.raises(BitstreamError, match=r"varint n is not minimal"):
        decode_varint(b"\x81\x00", what="n")
    with pytest.raises(BitstreamError, match=r"varint 1 of t is not minimal"):
        decode_varints(b"\x05\x81\x00", 0, 2, "t")


def test_truncated_varints_name_what_is_missing():
    with pytest.raises(BitstreamError, match=r"expected 1 more byte for varint count \(byte 2\), found 0"):
        decode_varint(b"\x80", what="count")
    with pytest.raises(BitstreamError, match=r"expected 3 varints for table, found 2 complete ones"):
        decode_varints(b"\x01\x02\x83", 0, 3, "table")


def test_varint_encoding_rejects_out_of_range():
    with pytest.raises(ValueError, match=r"varint value must be in \[0, 2\*\*64 - 1\], got -1"):
        encode_varint(-1)
    with pytest.raises(ValueError, match=r"varint value must be in \[0, 2\*\*64 - 1\], got 18446744073709551616"):
        encode_varint(2**64)
    with pytest.raises(ValueError, match=r"`values` must be non-negative, got min -3"):
        encode_varints([1, -3])


# --------------------------------------------------------------------------------------------------------------------
# ByteWriter / ByteReader


def _payload() -> tuple[bytes, list]:
    writer = ByteWriter()
    writer.write_u8(7)
    writer.write_u16(513)
    writer.write_u32(70000)
    writer.write_u64(2**63 + 5)
    writer.write_f32(1.5)
    writer.write_f64(-2.25)
    writer.write_varint(300)
    writer.write_svarint(-5)
    writer.write_varints([1, 200, 0])
    writer.write_array(np.array([[0.5, -1.0], [2.0, 3.25]]), "f4")
    writer.write_array([1, 65535], "u2")
    writer.write_blob(b"name")
    writer.write_bytes(b"\x01\x02")
    return writer.getvalue(), [7, 513, 70000, 2**63 + 5, 1.5, -2.25, 300, -5, [1, 200, 0],
                               [0.5, -1.0, 2.0, 3.25], [1, 65535], b"name", b"\x01\x02"]


def _read_all(reader: ByteReader) -> list:
    return [
        reader.read_u8("a"), reader.read_u16("b"), reader.read_u32("c"), reader.read_u64("d"),
        reader.read_f32("e"), reader.read_f64("f"), reader.read_varint("g"), reader.read_svarint("h"),
        reader.read_varints(3, "i").tolist(), reader.read_array(4, "f4", "j").tolist(),
        reader.read_array(2, "u2", "k").tolist(), reader.read_blob("l"), reader.read_bytes(2, "m"),
    ]


def test_byte_fields_round_trip():
    data, expected = _payload()
    reader = ByteReader(data)
    assert _read_all(reader) == expected
    assert reader.remaining == 0
    reader.expect_end()


def test_byte_layout_is_little_endian():
    writer = ByteWriter()
    writer.write_u32(1)
    writer.write_f64(1.0)
    writer.write_array([1], "i2")
    assert writer.getvalue() == struct.pack("<Id", 1, 1.0) + b"\x01\x00"


def test_byte_reader_starts_at_offset_and_reads_arrays_native_endian():
    data = b"junk" + np.array([1.0, 2.0], dtype="<f8").tobytes()
    out = ByteReader(data, 4).read_array(2, np.float64)
    assert out.dtype == np.dtype(np.float64) and out.tolist() == [1.0, 2.0]


def test_every_truncation_raises_bitstream_error():
    data, _ = _payload()
    for cut in range(len(data)):
        with pytest.raises(BitstreamError, match=r"expected"):
            _read_all(ByteReader(data[:cut]))


def test_byte_read_errors_name_the_field():
    reader = ByteReader(b"\x01\x02\x03")
    with pytest.raises(BitstreamError, match=r"expected 4 bytes for frame count, found 3"):
        reader.read_u32("frame count")
    with pytest.raises(BitstreamError, match=r"expected 8 bytes for scale, found 3"):
        reader.read_f64("scale")
    with pytest.raises(BitstreamError, match=r"expected 8000000000000 bytes for weights \(1000000000000 x float64\), "
                                             r"found 3"):
        reader.read_array(10**12, "f8", "weights")
    assert reader.offset == 0
    with pytest.raises(BitstreamError, match=r"expected the end of payload, found 3 more bytes"):
        reader.expect_end()


def test_blob_length_is_bounded_before_reading():
    data = encode_varint(1000) + b"abc"
    with pytest.raises(BitstreamError, match=r"expected at most 10 bytes for name, the length field says 1000"):
        ByteReader(data).read_blob("name", max_size=10)
    with pytest.raises(BitstreamError, match=r"expected 1000 bytes for name, found 3"):
        ByteReader(data).read_blob("name")


def test_byte_writer_rejects_values_that_do_not_fit():
    with pytest.raises(ValueError, match=r"cannot write u8 256"):
        ByteWriter().write_u8(256)
    with pytest.raises(ValueError, match=r"cannot write u16 -1"):
        ByteWriter().write_u16(-1)
    with pytest.raises(ValueError, match=r"`values` must fit in uint16 \[0, 65535\], got \[0, 65536\]"):
        ByteWriter().write_array([0, 65536], "u2")
    with pytest.raises(ValueError, match=r"signed varint value must fit in int64"):
        ByteWriter().write_svarint(2**63)
    with pytest.raises(ValueError, match=r"`offset` must be in \[0, 3\], got 4"):
        ByteReader(b"abc", 4)
