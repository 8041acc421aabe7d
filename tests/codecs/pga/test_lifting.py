"""Lifting scheme (Tournier et al. 2008 §3.5): perfect reconstruction, exactness on lines/geodesics, closed loop."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapbench.codecs.pga.lifting import (
    EUCLIDEAN,
    ROTATIONS,
    level_sizes,
    lifting_decompose,
    lifting_reconstruct,
    num_lifting_levels,
)

LENGTHS = list(range(1, 41)) + [63, 64, 65, 141]


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (Rotation.from_quat(a).inv() * Rotation.from_quat(b)).magnitude()


@pytest.mark.parametrize("length", LENGTHS)
def test_positions_perfect_reconstruction(length):
    rng = np.random.default_rng(length)
    samples = rng.normal(scale=50.0, size=(length, 15))
    coarse, details, rebuilt = lifting_decompose(samples, EUCLIDEAN)
    assert len(details) == num_lifting_levels(length)
    np.testing.assert_allclose(rebuilt, samples, rtol=0, atol=1e-9)
    # The decoder rebuilds the same from the coefficients alone.
    again = lifting_reconstruct(length, coarse, lambda level, predicted: details[level - 1], EUCLIDEAN)
    np.testing.assert_allclose(again, samples, rtol=0, atol=1e-9)


@pytest.mark.parametrize("length", LENGTHS)
def test_rotations_perfect_reconstruction_with_sign_flips(length):
    rng = np.random.default_rng(1000 + length)
    quats = Rotation.from_rotvec(rng.normal(scale=1.5, size=(length, 3))).as_quat()
    quats *= rng.choice([-1.0, 1.0], size=(length, 1))  # quaternion sign flips must not matter
    coarse, details, rebuilt = lifting_decompose(quats, ROTATIONS)
    assert np.max(_angle(rebuilt, quats)) < 1e-9
    again = lifting_reconstruct(length, coarse, lambda level, predicted: details[level - 1], ROTATIONS)
    assert np.max(_angle(again, quats)) < 1e-9


@pytest.mark.parametrize("length", [33, 40, 141])
def test_rotation_turning_past_pi_is_reconstructed(length):
    # Two full turns about a tilted axis: the rotation vector wraps at +-pi several times.
    axis = np.array([0.3, 1.0, -0.2]) / np.linalg.norm([0.3, 1.0, -0.2])
    angles = np.linspace(0.0, 4 * np.pi, length)
    quats = Rotation.from_rotvec(angles[:, None] * axis).as_quat()
    assert np.any(np.abs(np.diff(Rotation.from_quat(quats).as_rotvec(), axis=0)) > np.pi)  # it does wrap
    _, _, rebuilt = lifting_decompose(quats, ROTATIONS)
    assert np.max(_angle(rebuilt, quats)) < 1e-9


def test_level_sizes_match_the_papers_lod_count():
    # 09_06 has 141 frames: the paper's "#LOD" total is 9 (Table 2).
    assert level_sizes(141) == [1, 2, 3, 5, 9, 18, 36, 71, 141]
    assert num_lifting_levels(141) + 1 == 9
    assert num_lifting_levels(6179) + 1 == 14 and num_lifting_levels(22948) + 1 == 16
    assert level_sizes(1) == [1] and level_sizes(2) == [1, 2]


@pytest.mark.parametrize("length", [17, 64, 141])
def test_dropped_levels_keep_lines_exact(length):
    # Every stencil (cubic, quadratic, linear extrapolation) reproduces affine functions.
    t = np.arange(length, dtype=float)[:, None]
    samples = np.hstack([3.0 + 0.5 * t, -2.0 * t, np.full_like(t, 7.0)])
    _, details, rebuilt = lifting_decompose(samples, EUCLIDEAN, levels_dropped=3)
    assert details[-3:] == [None, None, None]
    np.testing.assert_allclose(rebuilt, samples, rtol=0, atol=1e-9)


def test_dropped_levels_keep_geodesics_exact():
    # A rotation at constant angular velocity is a line in the tangent space at any of its points.
    length = 97
    omega = np.array([0.01, -0.02, 0.015])
    base = Rotation.from_rotvec([0.4, 2.9, -0.3])
    quats = (base * Rotation.from_rotvec(np.arange(length)[:, None] * omega)).as_quat()
    _, _, rebuilt = lifting_decompose(quats, ROTATIONS, levels_dropped=2)
    assert np.max(_angle(rebuilt, quats)) < 1e-9


def test_dropping_levels_of_a_wiggle_loses_it():
    # The test above could pass with a scheme that ignores levels_dropped; this one cannot.
    t = np.arange(64, dtype=float)[:, None]
    samples = np.sin(t * np.pi / 2)  # period 4 samples: invisible at stride 4
    _, _, rebuilt = lifting_decompose(samples, EUCLIDEAN, levels_dropped=2)
    assert np.max(np.abs(rebuilt - samples)) > 0.5


@pytest.mark.parametrize("length", [1, 2, 9, 141])
def test_closed_loop_quantization_error_is_half_a_step(length):
    rng = np.random.default_rng(7)
    samples = np.cumsum(rng.normal(scale=3.0, size=(length, 3)), axis=0)
    step = 0.1
    _, _, rebuilt = lifting_decompose(samples, EUCLIDEAN, quantize=lambda level, v: np.rint(v / step) * step)
    # Each sample is its prediction from already quantized samples plus a detail rounded to the step.
    assert np.max(np.abs(rebuilt - samples)) <= step / 2 + 1e-9


def test_bad_inputs_are_named():
    with pytest.raises(ValueError, match="shape \\(N, s\\)"):
        lifting_decompose(np.zeros((0, 3)), EUCLIDEAN)
    with pytest.raises(ValueError, match="levels_dropped"):
        lifting_decompose(np.zeros((4, 3)), EUCLIDEAN, levels_dropped=-1)
    with pytest.raises(ValueError, match="at least one sample"):
        num_lifting_levels(0)
