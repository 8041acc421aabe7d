"""Metrics: properties (hypothesis), known values on constructed cases, and error paths."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mocapbench import metrics

finite = st.floats(min_value=-500, max_value=500, allow_nan=False, allow_infinity=False)


def positions(frames=st.integers(1, 12), joints=st.integers(1, 6)):
    return st.tuples(frames, joints).flatmap(lambda fj: arrays(np.float64, (fj[0], fj[1], 3), elements=finite))


def pairs():
    return positions().flatmap(lambda a: st.tuples(st.just(a), arrays(np.float64, a.shape, elements=finite)))


@given(positions())
def test_zero_error_on_identical_input(a):
    assert metrics.max_joint_error(a, a) == 0.0
    assert metrics.mean_joint_error(a, a) == 0.0
    assert metrics.p99_joint_error(a, a) == 0.0


@given(pairs())
def test_errors_are_symmetric_and_ordered(pair):
    a, b = pair
    assert metrics.max_joint_error(a, b) == pytest.approx(metrics.max_joint_error(b, a))
    assert metrics.mean_joint_error(a, b) == pytest.approx(metrics.mean_joint_error(b, a))
    assert metrics.mean_joint_error(a, b) <= metrics.p99_joint_error(a, b) + 1e-9 or a.size < 300
    assert metrics.p99_joint_error(a, b) <= metrics.max_joint_error(a, b) + 1e-9


@settings(max_examples=50)
@given(pairs(), st.tuples(finite, finite, finite))
def test_kg_is_translation_invariant(pair, shift):
    a, b = pair
    spread = np.linalg.norm(a - a.mean(axis=0))
    if spread < 1e-3:
        return  # static clip: covered by test_kg_static_clip_is_an_error
    shifted = metrics.kg_distortion(a + np.array(shift), b + np.array(shift))
    assert shifted == pytest.approx(metrics.kg_distortion(a, b), rel=1e-6, abs=1e-6)


def test_known_values():
    reference = np.zeros((2, 2, 3))
    decoded = reference.copy()
    decoded[1, 0] = [3.0, 4.0, 0.0]  # one joint off by 5 cm in frame 1
    assert metrics.max_joint_error(reference, decoded) == 5.0
    assert metrics.mean_joint_error(reference, decoded) == 5.0 / 4
    assert metrics.worst_joint_and_frame(reference, decoded) == (0, 1)
    assert metrics.max_joint_error_percent(reference, decoded, height_cm=200.0) == 2.5


def test_kg_known_value():
    reference = np.zeros((2, 1, 3))
    reference[1, 0, 0] = 2.0  # x = 0, 2 -> mean 1, ||A - E(A)|| = sqrt(2)
    decoded = reference + np.array([0.0, 0.0, 1.0])  # every frame 1 cm off -> ||A - Â|| = sqrt(2)
    assert metrics.kg_distortion(reference, decoded) == pytest.approx(100.0)


def test_kg_static_clip_is_an_error():
    still = np.ones((5, 3, 3))
    with pytest.raises(ValueError, match="static clip"):
        metrics.kg_distortion(still, still)


@pytest.mark.parametrize(
    "reference, decoded, match",
    [
        (np.zeros((4, 3)), np.zeros((4, 3)), r"`reference` to have shape \(F, J, 3\).*got \(4, 3\)"),
        (np.zeros((2, 3, 3)), np.zeros((2, 4, 3)), r"shape of `reference` \(2, 3, 3\), got \(2, 4, 3\)"),
        (np.zeros((0, 3, 3)), np.zeros((0, 3, 3)), "F, J > 0"),
        (np.full((1, 1, 3), np.nan), np.zeros((1, 1, 3)), r"`reference` holds a non-finite value at .*\(0, 0, 0\)"),
    ],
)
def test_shape_and_finiteness_errors_name_the_argument(reference, decoded, match):
    with pytest.raises(ValueError, match=match):
        metrics.max_joint_error(reference, decoded)


def test_rate_definitions():
    assert metrics.raw_position_bytes(31, 100) == 12 * 31 * 100
    assert metrics.compression_ratio(1000, 100) == 10.0
    assert metrics.bits_per_joint_frame(12 * 31 * 100, 31, 100) == metrics.RAW_BITS_PER_JOINT_FRAME
    assert metrics.neural_fourier_pose_parameters(31, 10) == 10 * (3 + 4 + 3 * 30)
    assert metrics.pga_raw_numbers(30, 10) == 3 * 31 * 10
    with pytest.raises(ValueError, match="bitstream_bytes` must be a positive integer, got 0"):
        metrics.compression_ratio(10, 0)


def test_time_call_returns_median_and_result():
    seconds, result = metrics.time_call(lambda: 42, repeats=3, warmup=0)
    assert result == 42 and seconds >= 0
    with pytest.raises(ValueError, match="repeats"):
        metrics.time_call(lambda: None, repeats=0)
