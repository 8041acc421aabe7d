"""The rANS unit of payload format 6: round trips, its limits, and corrupt units refused with one line."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapbench.codecs.mcb_rot import classes as model
from mocapbench.codecs.mcb_rot.stream import runtime_tables
from mocapbench.entropy.ans import ClassTables, encode_classed
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.entropy.rans6 import PRECISION, RansTables, decode_unit, encode_unit, quantize_counts


def _unit(values, classes) -> bytes:
    writer = ByteWriter()
    encode_unit(writer, np.asarray(values), np.asarray(classes), runtime_tables())
    return writer.getvalue()


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(-(2**31) + 1, 2**31 - 1), st.integers(0, 127)), max_size=300),
       st.binary(max_size=4))
def test_a_unit_decodes_to_its_values_and_leaves_what_follows(pairs, tail):
    values = np.array([v for v, _ in pairs], dtype=np.int64)
    classes = np.array([c for _, c in pairs], dtype=np.int64)
    reader = ByteReader(_unit(values, classes) + tail)
    np.testing.assert_array_equal(decode_unit(reader, classes, runtime_tables(), "unit"), values)
    assert reader.remaining == len(tail)


def test_laplace_values_cost_about_what_the_sorted_classed_coder_spends():
    rng = np.random.default_rng(3)
    classes = rng.integers(0, 64, 20000)
    values = np.round(rng.laplace(0, 2.0 ** ((classes - 16) / 4))).astype(np.int64)
    writer = ByteWriter()
    encode_classed(writer, values, classes, ClassTables(model.tables(0.45).counts))
    assert len(_unit(values, classes)) < 1.01 * len(writer.getvalue()) + 16


def test_every_table_sums_to_the_precision_and_keeps_every_token():
    freq = runtime_tables().freq.astype(np.int64)
    assert freq.shape == (128, 52) and freq.min() >= 1
    assert np.all(freq.sum(axis=1) == 1 << PRECISION)
    np.testing.assert_array_equal(quantize_counts(np.full((1, 4), 7)), [[8192] * 4])


@pytest.mark.parametrize("cut", [1, 3, 8, 11])
def test_a_truncated_unit_is_refused(cut):
    classes = np.zeros(200, dtype=np.int64) + 20
    data = _unit(np.arange(200) - 100, classes)
    with pytest.raises(BitstreamError, match="unit"):
        decode_unit(ByteReader(data[:-cut]), classes, runtime_tables(), "unit")


def test_a_flipped_byte_is_refused_or_decodes_other_values():
    classes = np.full(64, 30)
    values = np.arange(64) - 32
    data = bytearray(_unit(values, classes))
    for at in range(1, len(data)):
        bad = bytearray(data)
        bad[at] ^= 0x10
        try:
            decoded = decode_unit(ByteReader(bytes(bad)), classes, runtime_tables(), "unit")
        except BitstreamError:
            continue
        assert not np.array_equal(decoded, values) or at >= len(data) - 8  # (padding bits may flip unseen)


def test_values_beyond_31_bits_are_refused_by_the_encoder():
    with pytest.raises(ValueError, match="2\\^31"):
        _unit([2**31], [0])
    with pytest.raises(ValueError):
        RansTables(np.ones((2, 3)))
