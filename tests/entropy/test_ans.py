"""Class-conditional ANS coding: exact round trips, code lengths near the model's entropy, corrupt-stream errors."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from mocapbench.entropy import BitstreamError, ByteReader, ByteWriter, decode_varint, encode_varint
from mocapbench.entropy.ans import (
    MAX_MAGNITUDE_BITS,
    TOKEN_COUNT,
    ClassTables,
    decode_classed,
    encode_classed,
    laplace_token_probabilities,
    tokenize,
)


def _tables(scales=(0.05, 0.5, 4.0, 200.0)) -> ClassTables:
    return ClassTables(np.maximum(1, np.rint([laplace_token_probabilities(s, 0.4) * 1e6 for s in scales])).astype(int))


def _round_trip(values, classes, tables):
    writer = ByteWriter()
    encode_classed(writer, values, classes, tables)
    data = writer.getvalue()
    reader = ByteReader(data)
    decoded = decode_classed(reader, classes, tables, "test")
    reader.expect_end()
    return decoded, data


@settings(max_examples=60, deadline=None)
@given(
    values=hnp.arrays(np.int64, st.integers(0, 300), elements=st.integers(-(2**39) + 1, 2**39 - 1)),
    seed=st.integers(0, 1000),
)
def test_round_trip_is_exact_for_any_values_and_classes(values, seed):
    tables = _tables()
    classes = np.random.default_rng(seed).integers(0, tables.num_classes, values.size)
    decoded, _ = _round_trip(values, classes, tables)
    np.testing.assert_array_equal(decoded, values)


def test_tokens_cover_the_magnitude_categories():
    tokens, raw, widths = tokenize(np.array([0, 1, -15, 16, -31, 32, 2**39]))
    np.testing.assert_array_equal(tokens, [0, 1, 15, 16, 16, 17, TOKEN_COUNT - 1])
    np.testing.assert_array_equal(widths, [0, 0, 0, 4, 4, 5, 39])
    np.testing.assert_array_equal(raw, [0, 0, 0, 0, 15, 0, 0])
    with pytest.raises(ValueError, match=f"magnitudes must be < 2\\^{MAX_MAGNITUDE_BITS}"):
        tokenize(np.array([2**MAX_MAGNITUDE_BITS]))


def test_code_length_is_close_to_the_model_entropy():
    """Values drawn from a class's own distribution cost its entropy plus sign and raw bits, within 1 %."""
    tables = _tables()
    rng = np.random.default_rng(0)
    values = np.round(rng.laplace(0, 0.5 * 4, 50_000)).astype(np.int64)  # mostly |v| < 16
    classes = np.full(values.size, 1)
    tokens, _, widths = tokenize(values)
    ideal = tables.code_length_bits(tokens, classes) + np.count_nonzero(values) + widths.sum()
    _, data = _round_trip(values, classes, tables)
    assert len(data) * 8 < 1.01 * ideal + 64


def test_near_certain_zeros_cost_almost_nothing():
    tables = _tables()
    zeros = np.zeros(100_000, dtype=np.int64)
    _, data = _round_trip(zeros, np.zeros(zeros.size, dtype=int), tables)  # class of scale 0.05: p(0) ~ 1
    assert len(data) < 100  # a Huffman code would need 12,500 bytes


def test_counts_must_be_positive_and_shaped():
    with pytest.raises(ValueError, match=r"counts must be \(K, 52\) positive integers"):
        ClassTables(np.zeros((3, TOKEN_COUNT), dtype=int))
    with pytest.raises(ValueError, match="expected 2 classes"):
        encode_classed(ByteWriter(), np.array([1, 2]), np.array([0]), _tables())
    with pytest.raises(ValueError, match=r"classes must lie in \[0, 4\)"):
        encode_classed(ByteWriter(), np.array([1]), np.array([4]), _tables())


def test_truncated_and_corrupt_streams_raise_bitstream_errors():
    tables = _tables()
    values = np.random.default_rng(1).integers(-40, 40, 2000)
    classes = np.full(values.size, 2)
    _, data = _round_trip(values, classes, tables)
    for cut in range(0, len(data), 7):
        with pytest.raises(BitstreamError):
            reader = ByteReader(data[:cut])
            decode_classed(reader, classes, tables, "test")
            reader.expect_end()
    num_words, offset = decode_varint(data)
    too_many = encode_varint(10**6) + data[offset:]  # an ANS word count far past the end
    with pytest.raises(BitstreamError, match="expected 1000000 ANS words"):
        decode_classed(ByteReader(too_many), classes, tables, "test")
    too_few = encode_varint(num_words - 1) + data[offset:]  # words left over as sign bits: decodes wrongly
    with pytest.raises(BitstreamError):
        reader = ByteReader(too_few)
        decode_classed(reader, classes, tables, "test")
        reader.expect_end()


def test_per_value_models_code_exactly_as_the_class_models():
    """Small class groups are decoded in one call with a model per value (ans._decode_small_groups): that is exact
    only if constriction quantizes the per-value models as it quantizes the class's own model, for every class."""
    import constriction

    from mocapbench.codecs.mcb_rot.stream import tables as mcb_rot_tables

    family = constriction.stream.model.Categorical(perfect=False)
    tokens = np.concatenate([np.arange(TOKEN_COUNT), np.zeros(40, dtype=np.int64), [TOKEN_COUNT - 1] * 3]).astype(np.int32)
    for tables in (_tables(), mcb_rot_tables(float(np.float32(0.45)))):
        for klass in range(tables.num_classes):
            one = constriction.stream.stack.AnsCoder()
            one.encode_reverse(tokens, tables.model(klass))
            per_value = constriction.stream.stack.AnsCoder()
            per_value.encode_reverse(tokens, family, np.repeat(tables.probability_rows[klass][None], len(tokens), 0))
            assert np.array_equal(one.get_compressed(), per_value.get_compressed()), klass


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), streams=st.integers(1, 6), bits=st.integers(1, MAX_MAGNITUDE_BITS))
def test_streams_read_apart_and_finished_together_equal_one_decode_each(seed, streams, bits):
    """read_tokens per stream, then one values_of_tokens over all: what the mcb-rot decoder does per block."""
    from mocapbench.entropy.ans import class_groups, read_tokens, values_of_tokens

    rng = np.random.default_rng(seed)
    tables = _tables()
    writer, parts = ByteWriter(), []
    for _ in range(streams):
        size = int(rng.integers(0, 200))
        values = rng.integers(-(2 ** (bits - 1)), 2 ** (bits - 1), size) * (rng.random(size) < 0.5)
        classes = rng.integers(0, tables.num_classes, size).astype(np.uint8)
        encode_classed(writer, values, classes, tables)
        parts.append((values, classes))
    reader = ByteReader(writer.getvalue())
    runs, orders, at = [], [], 0
    for values, classes in parts:
        order, groups = class_groups(classes)
        runs.append(read_tokens(reader, groups, tables, "test"))
        orders.append(order + at)
        at += len(values)
    reader.expect_end()
    decoded = values_of_tokens(runs, np.concatenate(orders) if orders else np.zeros(0, np.int64))
    np.testing.assert_array_equal(decoded, np.concatenate([v for v, _ in parts]).astype(np.int64))


@pytest.mark.parametrize("small_groups", [1, 3, 5, 6, 12])
def test_runs_of_small_class_groups_decode_alike_merged_or_one_call_each(small_groups):
    """A run of small class groups is decoded one call per class below ans._MERGE_GROUPS groups, in one call with
    per-value models from there: both give the values back, between large groups and at the end of the stream."""
    from mocapbench.codecs.mcb_rot.stream import tables as mcb_rot_tables
    from mocapbench.entropy import ans

    assert ans._MERGE_GROUPS in range(2, 12)
    tables = mcb_rot_tables(float(np.float32(0.45)))
    rng = np.random.default_rng(small_groups)
    small = [(klass, 1 + klass % (ans._MERGE_BELOW - 1)) for klass in range(10, 10 + small_groups)]
    layout = [(5, 40)] + small + [(40, 30)] + [(klass + 40, count) for klass, count in small]
    classes = np.repeat([k for k, _ in layout], [c for _, c in layout])
    rng.shuffle(classes)
    values = (rng.standard_normal(len(classes)) * 2.0 ** (classes / 4.0 - 3.0)).astype(np.int64)
    writer = ByteWriter()
    encode_classed(writer, values, classes, tables)
    reader = ByteReader(writer.getvalue())
    np.testing.assert_array_equal(decode_classed(reader, classes, tables, "test"), values)
    reader.expect_end()
