"""Uniform quantizers: exhaustive over every range bit width (ACL test_scalar_packing style), hypothesis on steps."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from mocapbench.entropy import (
    BitReader,
    BitWriter,
    RangeQuantizer,
    dequantize,
    dequantize_range,
    quantize,
    quantize_range,
)
from mocapbench.entropy.quantize import MAX_RANGE_BITS, MIN_RANGE_BITS

ALL_WIDTHS = range(MIN_RANGE_BITS, MAX_RANGE_BITS + 1)
# Widths up to this are checked on every index; wider ones on 2**20 indices that include both ends.
EXHAUSTIVE_MAX_BITS = 20


def _tolerance(values: np.ndarray, step: float, origin: float = 0.0) -> np.ndarray:
    """step / 2 plus the float rounding of x / step and of origin + index * step (a few ulp of each term)."""
    return step / 2 * (1 + 1e-12) + 4 * np.spacing(np.abs(values)) + 4 * np.spacing(step) + 4 * np.spacing(abs(origin))


# --------------------------------------------------------------------------------------------------------------------
# step-based


def test_quantize_rounds_to_nearest_multiple():
    np.testing.assert_array_equal(quantize([0.24, -0.26, 1.0, 0.75, -0.75], 0.5), [0, -1, 2, 2, -2])


def test_quantize_returns_int64_and_dequantize_float64_with_shape_kept():
    values = np.linspace(-3, 3, 12).reshape(3, 4)
    indices = quantize(values, 0.1)
    assert indices.dtype == np.int64 and indices.shape == (3, 4)
    restored = dequantize(indices, 0.1)
    assert restored.dtype == np.float64 and restored.shape == (3, 4)


def test_quantize_empty():
    assert quantize(np.zeros((0, 3)), 1.0).shape == (0, 3)
    assert dequantize(np.zeros(0, dtype=np.int64), 1.0).shape == (0,)


@settings(max_examples=150, deadline=None)
@given(
    values=st.lists(st.floats(-1e9, 1e9, allow_nan=False, allow_infinity=False), min_size=1, max_size=50),
    step=st.floats(1e-6, 1e4, allow_nan=False, allow_infinity=False),
)
def test_step_quantizer_error_at_most_half_step(values, step):
    x = np.asarray(values)
    assume(np.abs(x).max() / step < 2.0**62)
    err = np.abs(dequantize(quantize(x, step), step) - x)
    num_errors = int((err > _tolerance(x, step)).sum())
    assert num_errors == 0, f"max error {err.max()!r} > step/2 = {step / 2!r}"


@settings(deadline=None)
@given(indices=st.lists(st.integers(-(2**40), 2**40), min_size=1, max_size=50),
       step=st.sampled_from([0.5, 0.25, 1.0, 2.0, 0.125]))
def test_step_quantizer_reproduces_its_own_levels(indices, step):
    # Dyadic steps: index * step is exact, so quantizing a level gives back its index.
    idx = np.asarray(indices, dtype=np.int64)
    np.testing.assert_array_equal(quantize(dequantize(idx, step), step), idx)


@pytest.mark.parametrize("step", [0, -1.0, math.nan, math.inf, -math.inf, "abc", None])
def test_step_must_be_finite_and_positive(step):
    with pytest.raises(ValueError, match=r"`step` must be a finite number > 0, got"):
        quantize([1.0], step)
    with pytest.raises(ValueError, match=r"`step` must be a finite number > 0"):
        dequantize([1], step)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_quantize_rejects_non_finite_values_naming_the_index(bad):
    with pytest.raises(ValueError, match=r"`values` must be finite, found .* at index \(1, 0\)"):
        quantize(np.array([[0.0], [bad]]), 0.1)


def test_quantize_rejects_a_step_too_small_for_int64():
    with pytest.raises(ValueError, match=r"`step` 1e-300 is too small"):
        quantize([1.0], 1e-300)


def test_dequantize_rejects_float_indices():
    with pytest.raises(ValueError, match=r"`indices` must be integers, got dtype float64"):
        dequantize([1.5], 1.0)


# --------------------------------------------------------------------------------------------------------------------
# range-based: every bit width


@pytest.mark.parametrize("bits", ALL_WIDTHS)
def test_range_quantizer_round_trips_every_level_and_packs_in_bits(bits):
    """ACL test_scalar_packing: each index -> value -> index and -> bits -> index, counting errors."""
    lo, hi = -1.75, 3.3  # step is not a power of two, so the levels are not exact floats
    quantizer = RangeQuantizer(bits, lo, hi)
    top = (1 << bits) - 1
    if bits <= EXHAUSTIVE_MAX_BITS:
        indices = np.arange(top + 1, dtype=np.uint32)
    else:
        rng = np.random.default_rng(bits)
        indices = np.concatenate(([0, 1, top - 1, top], rng.integers(0, top + 1, 1 << 20))).astype(np.uint32)
    levels = quantizer.dequantize(indices)
    num_errors = int((quantizer.quantize(levels) != indices).sum())
    assert num_errors == 0

    writer = BitWriter()
    writer.write_array(indices, bits)
    unpacked = BitReader(writer.getvalue()).read_array(indices.size, bits)
    assert int((unpacked != indices).sum()) == 0
    assert len(writer.getvalue()) == -(-indices.size * bits // 8)


@pytest.mark.parametrize("bits", ALL_WIDTHS)
def test_range_quantizer_error_at_most_half_step_on_random_values(bits):
    rng = np.random.default_rng(100 + bits)
    values = np.concatenate(([-7.25, 12.5], rng.uniform(-7.25, 12.5, 20_000)))
    indices, lo, hi = quantize_range(values, bits)
    assert (lo, hi) == (-7.25, 12.5)
    assert indices.dtype == np.uint32 and indices.max() <= (1 << bits) - 1
    step = (hi - lo) / ((1 << bits) - 1)
    err = np.abs(dequantize_range(indices, bits, lo, hi) - values)
    num_errors = int((err > _tolerance(values, step)).sum())
    assert num_errors == 0, f"bits={bits}: max error {err.max()!r} > step/2 = {step / 2!r}"


@settings(max_examples=120, deadline=None)
@given(
    values=st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=1, max_size=40),
    bits=st.integers(MIN_RANGE_BITS, MAX_RANGE_BITS),
)
def test_range_quantizer_error_bound_hypothesis(values, bits):
    x = np.asarray(values)
    indices, lo, hi = quantize_range(x, bits)
    step = (hi - lo) / ((1 << bits) - 1)
    err = np.abs(dequantize_range(indices, bits, lo, hi) - x)
    # lo + index * step rounds at the scale of |lo|, |hi| (e.g. x = 0 inside [-1e6, 1e6]).
    assert int((err > _tolerance(x, step, max(abs(lo), abs(hi)))).sum()) == 0


@pytest.mark.parametrize("bits", [1, 8, 24])
def test_range_quantizer_ends_are_exact(bits):
    quantizer = RangeQuantizer(bits, -0.1, 0.7)
    np.testing.assert_array_equal(quantizer.dequantize([0, (1 << bits) - 1]), [-0.1, 0.7])
    np.testing.assert_array_equal(quantizer.quantize([-0.1, 0.7]), [0, (1 << bits) - 1])


@pytest.mark.parametrize("bits", [1, 12, 24])
def test_constant_input_has_zero_step_and_is_exact(bits):
    values = np.full((4, 3), 2.5)
    indices, lo, hi = quantize_range(values, bits)
    assert lo == hi == 2.5 and RangeQuantizer(bits, lo, hi).step == 0.0
    np.testing.assert_array_equal(indices, np.zeros((4, 3)))
    np.testing.assert_array_equal(dequantize_range(indices, bits, lo, hi), values)


def test_range_quantizer_keeps_shapes():
    values = np.linspace(0, 1, 24).reshape(2, 3, 4)
    indices, lo, hi = quantize_range(values, 10)
    assert indices.shape == (2, 3, 4)
    assert dequantize_range(indices, 10, lo, hi).shape == (2, 3, 4)


@pytest.mark.parametrize("bits", [0, 25, -1, 1.5, True, "8"])
def test_bits_must_be_an_int_in_range(bits):
    with pytest.raises(ValueError, match=r"`bits` must be"):
        quantize_range([0.0, 1.0], bits)
    with pytest.raises(ValueError, match=r"`bits` must be"):
        RangeQuantizer(bits, 0.0, 1.0)


def test_range_quantizer_validation_messages():
    with pytest.raises(ValueError, match=r"`lo` must be <= `hi`, got lo=2.0 > hi=1.0"):
        RangeQuantizer(8, 2.0, 1.0)
    with pytest.raises(ValueError, match=r"`hi` must be a finite number, got inf"):
        RangeQuantizer(8, 0.0, math.inf)
    with pytest.raises(ValueError, match=r"range hi - lo must be finite"):
        RangeQuantizer(8, -1e308, 1e308)
    with pytest.raises(ValueError, match=r"`values` must not be empty"):
        quantize_range([], 8)
    with pytest.raises(ValueError, match=r"`values` must be finite, found nan at index \(2,\)"):
        quantize_range([0.0, 1.0, math.nan], 8)
    with pytest.raises(ValueError, match=r"`values` must lie in \[lo, hi\] = \[0.0, 1.0\], got min 0.0 and max 1.5"):
        RangeQuantizer(8, 0.0, 1.0).quantize([0.0, 1.5])
    with pytest.raises(ValueError, match=r"`indices` must lie in \[0, 255\] for bits=8, got min 0 and max 256"):
        dequantize_range([0, 256], 8, 0.0, 1.0)
    with pytest.raises(ValueError, match=r"`indices` must be integers"):
        dequantize_range([0.5], 8, 0.0, 1.0)
