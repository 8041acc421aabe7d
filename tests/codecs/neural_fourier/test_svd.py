"""svd: low-rank SVD of the neural Fourier paper's pose matrix (its baseline, Tojo et al. 2022 §4.1)."""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench import metrics
from mocapbench.codecs import BitstreamError, container, create
from mocapbench.codecs.neural_fourier.pose_params import num_pose_parameters, pose_matrix
from mocapbench.codecs.neural_fourier.svd import low_rank_factors
from mocapbench.motion import Motion
from mocapbench.synthetic import sinusoidal_motion


@pytest.fixture(scope="module")
def motion():
    return sinusoidal_motion(num_frames=150, seed=5)


def _error(codec, motion) -> float:
    data = codec.encode(motion)
    decoded = create("svd", **codec.config.as_dict()).decode(data)
    return metrics.max_joint_error(motion.positions(), decoded.positions)


def test_error_falls_with_rank_and_full_rank_is_near_lossless(motion):
    errors = [_error(create("svd", rank=r), motion) for r in (2, 8, 32, 97)]
    assert errors == sorted(errors, reverse=True), errors
    assert errors[0] > 5.0  # rank 2 cannot follow 31 joints' independent sinusoids
    assert errors[-1] < 0.1  # full rank: only float16 rounding of the factors is left


def test_low_rank_factors_reconstruct_and_rank_is_clipped():
    rng = np.random.default_rng(0)
    y = rng.normal(size=(5, 9))
    mean, a, b = low_rank_factors(y, 100)
    assert a.shape == (5, 5) and b.shape == (9, 5)
    np.testing.assert_allclose(mean + a @ b.T, y, atol=1e-12)
    mean_w, a_w, b_w = low_rank_factors(y, 100, weights=np.linspace(0.0, 2.0, 9))  # a zero weight counts as 1
    np.testing.assert_allclose(mean_w + a_w @ b_w.T, y, atol=1e-12)
    with pytest.raises(ValueError, match="rank"):
        low_rank_factors(y, 0)


def test_weighted_svd_spends_the_rank_on_joint_positions(motion):
    """Weighting by eq. (3)'s w balances cm of translation against radians: lower joint error at the same rank."""
    plain = _error(create("svd", rank=6), motion)
    weighted = _error(create("svd", rank=6, weighted=True), motion)
    assert weighted < plain


def test_stats_follow_the_paper_count_and_rank_clipping(motion):
    short = motion.slice(0, 20)
    codec = create("svd", rank=50)
    data = codec.encode(short)
    stats = codec.last_encode_stats
    m = num_pose_parameters(31)
    assert stats["rank"] == 20  # min(F, m)
    assert stats["num_parameters"] == 20 * (20 + m) + m
    assert stats["paper_compression_ratio"] == pytest.approx(20 * m / stats["num_parameters"])
    decoded = codec.decode(data)
    assert isinstance(decoded.motion, Motion)
    np.testing.assert_allclose(decoded.motion.positions(), decoded.positions, atol=1e-9)
    header, payload = container.unpack(data, "svd")
    assert codec.describe_payload(header, payload)["rank"] == 20


def test_uniform_factors_are_smaller_and_decode(motion):
    half = create("svd", rank=8)
    ten = create("svd", rank=8, factor_format="uniform", factor_bits=10)
    six = create("svd", rank=8, factor_format="uniform", factor_bits=6)
    assert len(six.encode(motion)) < len(ten.encode(motion)) < len(half.encode(motion))
    assert _error(half, motion) < _error(ten, motion) < 5.0 < _error(six, motion)  # measured 0.47, 1.3, 37 cm


def test_same_input_same_bytes(motion):
    assert create("svd", rank=4).encode(motion) == create("svd", rank=4).encode(motion)


def test_pose_matrix_mean_is_stored_not_rederived(motion):
    """A constant motion is coded exactly by its mean at any rank."""
    still = Motion(motion.skeleton, motion.fps, np.repeat(motion.root_positions[:1], 30, 0), np.repeat(motion.rotations[:1], 30, 0))
    assert _error(create("svd", rank=1), still) < 0.05
    assert pose_matrix(still).std(axis=0).max() < 1e-12


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"rank": 0}, r"rank must be in \[1, 4096\]"),
        ({"factor_format": "int4"}, "factor_format must be one of"),
        ({"factor_bits": 17}, r"factor_bits must be in \[2, 16\]"),
        ({"weighted": "yes"}, "weighted must be of type bool"),
    ],
)
def test_bad_config_values_are_rejected(params, message):
    with pytest.raises(ValueError, match=message):
        create("svd", **params)


def test_inconsistent_payload_is_a_bitstream_error(motion):
    codec = create("svd", rank=3)
    header, payload = container.unpack(codec.encode(motion), "svd")
    with pytest.raises(BitstreamError):
        codec.decode_payload(header, memoryview(bytes(payload)[:-1]))
    with pytest.raises(BitstreamError):
        codec.decode_payload(header, memoryview(bytes(payload) + b"\x00"))
