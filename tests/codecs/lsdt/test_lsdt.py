"""The LSDT codecs and their spatial DCT / DWT baselines (Hou et al. 2016): schemes, closed loop, latency, bytes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapbench import metrics
from mocapbench.codecs import BitstreamError, create
from mocapbench.codecs.base import NotFittedError
from mocapbench.codecs.lsdt.bases import COMMITTED_SPARSITIES, committed_provenance, load_committed_bases
from mocapbench.codecs.lsdt.clip import clip_forward, clip_inverse
from mocapbench.codecs.lsdt.frame import FrameEncoder, frame_closed_loop, frame_reconstruct
from mocapbench.codecs.lsdt.spatial import dct_matrix
from mocapbench.codecs.lsdt.vectors import COUNT_CODINGS, code_vectors, decode_vectors
from mocapbench.motion import Motion, Skeleton
from mocapbench.synthetic import sinusoidal_motion

NAMES = ["lsdt-frame", "lsdt-clip", "dct-spatial-frame", "dct-spatial-clip", "dwt-spatial-frame", "dwt-spatial-clip"]
J = 31


def _joint_error_bound(step: float, num_joints: int = J) -> float:
    """Worst case per-joint error of one coded frame: ||c - ĉ||_2 <= sqrt(3 J) Δ / 2 (orthonormal transforms)."""
    return np.sqrt(3 * num_joints) * step / 2


def _concatenate(first: Motion, second: Motion) -> Motion:
    return Motion(
        skeleton=first.skeleton,
        fps=first.fps,
        root_positions=np.concatenate([first.root_positions, second.root_positions]),
        rotations=np.concatenate([first.rotations, second.rotations]),
    )


# -- committed model --------------------------------------------------------------------------------------


@pytest.mark.parametrize("sparsity", COMMITTED_SPARSITIES)
def test_committed_bases_are_orthogonal_and_documented(sparsity):
    bases = load_committed_bases(sparsity)
    assert bases.shape == (3, J, J) and bases.dtype == np.float64
    for basis in bases:
        assert np.abs(basis @ basis.T - np.eye(J)).max() < 1e-10
    provenance = committed_provenance()
    assert provenance["training_split"] == "cmu_train" and provenance["training_frames"] == 13063
    assert f"P{sparsity}" in provenance["bases"]


def test_model_bytes_counts_the_bases_and_fixed_transforms_cost_nothing():
    assert create("lsdt-frame").model_bytes == 3 * J * J * 8
    assert create("lsdt-clip", sparsity=5).model_bytes == 3 * J * J * 8
    assert create("dct-spatial-frame").model_bytes == 0
    assert create("dwt-spatial-clip").model_bytes == 0


def test_uncommitted_sparsity_needs_fit():
    with pytest.raises(ValueError, match="sparsity=3 has no committed bases"):
        create("lsdt-frame", sparsity=3)
    codec = create("lsdt-frame", sparsity=3, basis="fit")
    with pytest.raises(NotFittedError, match="needs bases fit on clips of this skeleton: `mocapbench fit"):
        codec.encode(sinusoidal_motion(num_frames=10, seed=1))


# -- round trips ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("step", [0.05, 1.0])
def test_round_trip_from_bytes_within_the_quantization_bound(name, step, synthetic_motion):
    data = create(name, step_cm=step).encode(synthetic_motion)
    decoded = create(name, step_cm=7.0).decode(bytes(data))  # the step travels in the stream
    reference = synthetic_motion.positions()
    assert decoded.positions.shape == reference.shape
    error = metrics.max_joint_error(reference, decoded.positions)
    mean = metrics.mean_joint_error(reference, decoded.positions)
    # Two-sided: within the worst-case bound, but not lossless (the step does something).
    assert error <= _joint_error_bound(step) and mean > 0.02 * step
    assert len(data) < metrics.raw_position_bytes(J, synthetic_motion.num_frames)


@pytest.mark.parametrize("name", NAMES)
def test_larger_step_gives_fewer_bytes_and_more_error(name, synthetic_motion):
    reference = synthetic_motion.positions()
    sizes, errors = [], []
    for step in (0.1, 0.5, 2.0):
        codec = create(name, step_cm=step)
        data = codec.encode(synthetic_motion)
        sizes.append(len(data))
        errors.append(metrics.mean_joint_error(reference, codec.decode(data).positions))
    assert sizes[0] > sizes[1] > sizes[2]
    assert errors[0] < errors[1] < errors[2]


def test_threshold_zeroes_more_coefficients(synthetic_motion):
    plain = create("lsdt-clip", step_cm=0.5)
    plain.encode(synthetic_motion)
    thresholded = create("lsdt-clip", step_cm=0.5, threshold_steps=1.5)
    thresholded.encode(synthetic_motion)
    assert thresholded.last_encode_stats["nonzero_coefficients"] < plain.last_encode_stats["nonzero_coefficients"]


@pytest.mark.parametrize("num_frames", [1, 7, 119, 120, 121, 250])
def test_clip_codec_codes_the_final_partial_clip(num_frames):
    motion = sinusoidal_motion(num_frames=num_frames, seed=4)
    codec = create("lsdt-clip", step_cm=0.1, clip_length=120)
    decoded = codec.decode(codec.encode(motion)).positions
    assert decoded.shape == (num_frames, J, 3)
    tail = slice(120 * (num_frames // 120), num_frames)
    error = metrics.joint_errors(motion.positions(), decoded)
    assert error.max() <= _joint_error_bound(0.1)
    assert error[tail].size == 0 or error[tail].max() <= _joint_error_bound(0.1)
    assert codec.latency_frames == 120


def test_clip_transform_is_equations_4_and_5():
    rng = np.random.default_rng(1)
    frames = rng.normal(size=(2, 16, 3, J)) * 50  # (n, L, 3, J)
    bases = load_committed_bases(8)
    coefficients = clip_forward(frames, bases)
    for n in range(2):
        for d in range(3):
            clip = frames[n, :, d, :].T  # M~^d, J × L
            expected = bases[d] @ (clip @ dct_matrix(16).T)  # C = B (M~ U_t), U_t = DCT matrix transposed
            np.testing.assert_allclose(coefficients[n, d].T, expected, atol=1e-9)
    np.testing.assert_allclose(clip_inverse(coefficients, bases), frames, atol=1e-9)


@pytest.mark.parametrize("clip_length", [60, 120, 240])
def test_clip_latency_is_reported(clip_length, synthetic_motion):
    codec = create("lsdt-clip", clip_length=clip_length)
    codec.encode(synthetic_motion)
    assert codec.latency_frames == clip_length
    frame = create("lsdt-frame")
    frame.encode(synthetic_motion)
    assert frame.latency_frames == 0


# -- the frame scheme: closed loop and zero latency ---------------------------------------------------------


@pytest.mark.parametrize("threshold_steps", [0.5, 1.5])
def test_closed_loop_error_does_not_drift_over_a_long_motion(threshold_steps):
    motion = sinusoidal_motion(num_frames=6000, seed=2, max_frequency_hz=3.0)
    step = 0.5
    codec = create("lsdt-frame", step_cm=step, threshold_steps=threshold_steps)
    decoded = codec.decode(codec.encode(motion)).positions
    errors = metrics.joint_errors(motion.positions(), decoded)
    assert errors.max() <= _joint_error_bound(2 * threshold_steps * step)  # |c - ĉ| <= threshold per coefficient
    errors = errors.mean(axis=1)  # (F,) mean over joints
    first, last = errors[:1000].mean(), errors[-1000:].mean()
    assert last < 1.3 * first, f"error grew from {first:.3f} to {last:.3f} cm"


def test_an_open_loop_predictor_would_drift():
    """The test above can fail: predicting from the *original* previous frame accumulates quantization error."""
    motion = sinusoidal_motion(num_frames=6000, seed=2, max_frequency_hz=3.0)
    step = 0.5
    frames = motion.positions().transpose(0, 2, 1)  # (F, 3, J)
    bases = load_committed_bases(8)
    residuals = np.diff(frames, axis=0, prepend=0.0)
    coefficients = np.einsum("dij,fdj->fdi", bases, residuals)
    decoded_residuals = np.einsum("dji,fdj->fdi", bases, np.rint(coefficients / step) * step)
    decoded = np.cumsum(decoded_residuals, axis=0)
    errors = np.linalg.norm(decoded - frames, axis=1).mean(axis=1)
    assert errors[-1000:].mean() > 3 * errors[:1000].mean()


def test_frame_i_is_coded_without_reading_later_frames():
    """Two motions equal up to frame 150 and different after: frames 0..149 decode identically (zero latency)."""
    head = sinusoidal_motion(num_frames=150, seed=1)
    first = _concatenate(head, sinusoidal_motion(num_frames=100, seed=8))
    second = _concatenate(head, sinusoidal_motion(num_frames=100, seed=9))
    codec = create("lsdt-frame", step_cm=0.3)
    decoded_first = codec.decode(codec.encode(first)).positions
    decoded_second = codec.decode(codec.encode(second)).positions
    np.testing.assert_array_equal(decoded_first[:150], decoded_second[:150])
    assert not np.allclose(decoded_first[150:], decoded_second[150:])


@pytest.mark.parametrize("threshold_steps", [0.5, 1.5])
def test_frame_encoder_pushes_one_frame_at_a_time_and_matches_the_vectorized_loop(threshold_steps, synthetic_motion):
    """The literal closed loop of §3.1 (one frame in, residual against the reconstruction) gives the codec's indices."""
    step = 0.3
    bases = load_committed_bases(8)
    frames = synthetic_motion.positions().transpose(0, 2, 1)
    batch = frame_closed_loop(frames, bases, step, threshold_steps * step)
    decoded = frame_reconstruct(batch, bases, step)
    encoder = FrameEncoder(bases, step, threshold_steps * step)
    for i, frame in enumerate(frames):
        np.testing.assert_array_equal(encoder.push(frame), batch[i])  # it gets one frame: it cannot look ahead
        np.testing.assert_allclose(encoder.reconstruction.T, decoded[i], atol=1e-9)


# -- stream checks ----------------------------------------------------------------------------------------


def test_a_stream_coded_with_other_bases_is_rejected(synthetic_motion):
    data = create("lsdt-frame", sparsity=8).encode(synthetic_motion)
    with pytest.raises(BitstreamError, match="coded with bases"):
        create("lsdt-frame", sparsity=5).decode(data)


def test_the_learned_bases_need_the_skeleton_they_were_trained_on():
    skeleton = Skeleton(names=("root", "a", "b"), parents=np.array([-1, 0, 1]), offsets=np.array([[0, 0, 0], [0, 10, 0], [0, 10, 0]]))
    rng = np.random.default_rng(0)
    rotations = rng.normal(size=(50, 3, 4))
    motion = Motion(skeleton=skeleton, fps=120.0, root_positions=rng.normal(size=(50, 3)), rotations=rotations)
    with pytest.raises(NotFittedError, match="bases are 31 x 31 but the motion has 3 joints.*mocapbench fit"):
        create("lsdt-clip").encode(motion)
    # basis='fit' learns bases for this skeleton; the fixed transforms work for any J.
    with pytest.raises(ValueError, match="sparsity=8 exceeds the 3 joints"):
        create("lsdt-clip", basis="fit").fit([motion])
    fitted = create("lsdt-clip", basis="fit", sparsity=2, step_cm=0.05, train_iterations=20).fit([motion])
    assert fitted.model_bytes == 3 * 3 * 3 * 8
    for codec in (fitted, create("dct-spatial-frame", step_cm=0.05)):
        decoded = codec.decode(codec.encode(motion)).positions
        assert metrics.max_joint_error(motion.positions(), decoded) <= _joint_error_bound(0.05, 3)


def test_fit_mode_retrains_and_round_trips(synthetic_motion, training_motions):
    codec = create("lsdt-frame", basis="fit", train_iterations=30, step_cm=0.2).fit(training_motions)
    assert all(np.all(np.diff(objective) <= 1e-9 * objective[:-1]) for objective in codec.training_objective)
    data = codec.encode(synthetic_motion)
    fresh = create("lsdt-frame", basis="fit", train_iterations=30, step_cm=0.2).fit(training_motions)
    assert metrics.max_joint_error(synthetic_motion.positions(), fresh.decode(data).positions) <= _joint_error_bound(0.2)
    with pytest.raises(BitstreamError, match="coded with bases"):
        create("lsdt-frame").decode(data)


@settings(max_examples=60, deadline=None)
@given(
    st.integers(min_value=1, max_value=40),
    st.integers(min_value=1, max_value=33),
    st.floats(min_value=0.0, max_value=1.0),
    st.integers(min_value=0, max_value=2**31),
    st.sampled_from(COUNT_CODINGS),
)
def test_vector_coding_round_trips(num_vectors, num_joints, density, seed, count_coding):
    rng = np.random.default_rng(seed)
    values = rng.integers(-5000, 5000, size=(num_vectors, num_joints))
    indices = np.where(rng.random((num_vectors, num_joints)) < density, values, 0)
    data = code_vectors(indices, count_coding)
    np.testing.assert_array_equal(decode_vectors(data, num_vectors, num_joints, count_coding), indices)


def test_vector_coding_rejects_trailing_bytes_and_unknown_coding():
    indices = np.array([[0, 3, 0], [1, 0, 0]])
    with pytest.raises(BitstreamError, match="more bytes"):
        decode_vectors(code_vectors(indices) + b"\x00", 2, 3)
    with pytest.raises(ValueError, match="Unknown count coding 'gzip'"):
        code_vectors(indices, "gzip")


@pytest.mark.parametrize("name", ["lsdt-frame", "lsdt-clip"])
def test_huffman_counts_round_trip_and_save_bytes_at_high_compression(name, synthetic_motion):
    fixed = create(name, step_cm=4.0)
    huffman = create(name, step_cm=4.0, count_coding="huffman")
    data_fixed, data_huffman = fixed.encode(synthetic_motion), huffman.encode(synthetic_motion)
    assert len(data_huffman) < len(data_fixed)
    # The coding travels in the stream: either codec decodes either stream, to the same positions.
    np.testing.assert_array_equal(fixed.decode(data_huffman).positions, huffman.decode(data_fixed).positions)


# -- real data (fast) ---------------------------------------------------------------------------------------


def test_real_clip_09_06_round_trip(cmu_09_06):
    motion = cmu_09_06
    reference = motion.positions()
    for name, step in (("lsdt-frame", 0.5), ("lsdt-clip", 0.5)):
        codec = create(name, step_cm=step)
        data = codec.encode(motion)
        decoded = create(name, step_cm=step).decode(data).positions
        ratio = metrics.raw_position_bytes(J, motion.num_frames) / len(data)
        distortion = metrics.mean_joint_error(reference, decoded)
        assert 0.01 < distortion < 0.5 and ratio > 5, f"{name}: D={distortion:.3f} cm, CR={ratio:.1f}"


def test_set_bases_validates_and_is_used(synthetic_motion):
    with pytest.raises(ValueError, match="needs basis='fit'"):
        create("lsdt-frame").set_bases(load_committed_bases(8))
    with pytest.raises(ValueError, match="must be orthogonal"):
        create("lsdt-frame", basis="fit").set_bases(2 * load_committed_bases(8))
    data = create("lsdt-frame", basis="fit").set_bases(load_committed_bases(8)).encode(synthetic_motion)
    assert create("lsdt-frame").decode(data).positions.shape == (240, J, 3)  # same bases, same fingerprint
