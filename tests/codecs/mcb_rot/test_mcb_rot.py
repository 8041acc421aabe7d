"""mcb-rot: decoded rotations put every joint within eps on every frame, on any skeleton and motion."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapbench import metrics
from mocapbench.codecs import BitstreamError, container, create
from mocapbench.codecs.mcb_rot import decoder
from mocapbench.codecs.mcb_rot.quaternions import exp_map, log_map, multiply, sign_continuous
from mocapbench.motion import Motion, Skeleton
from mocapbench.synthetic import sinusoidal_motion


def random_motion(seed: int, num_joints: int, num_frames: int, zero_bones: float, speed: float) -> Motion:
    """A random joint tree (some bones of length 0) with random-walk rotations, root and random sign flips."""
    rng = np.random.default_rng(seed)
    parents = np.array([-1] + [int(rng.integers(0, j)) for j in range(1, num_joints)])
    offsets = rng.normal(0.0, 15.0, (num_joints, 3)) * (rng.random((num_joints, 1)) >= zero_bones)
    orders = tuple(rng.choice(["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"], num_joints))
    skeleton = Skeleton(tuple(f"j{j}" for j in range(num_joints)), parents, offsets, orders)
    steps = rng.normal(0.0, speed, (num_frames, num_joints, 3))
    rotvecs = np.cumsum(steps, axis=0) + rng.normal(0.0, 1.0, (1, num_joints, 3))
    quats = exp_map(rotvecs)
    quats *= np.where(rng.random((num_frames, num_joints, 1)) < 0.3, -1.0, 1.0)  # sign flips cost nothing
    roots = np.cumsum(rng.normal(0.0, 2.0, (num_frames, 3)), axis=0)
    return Motion(skeleton, 60.0, roots, quats)


@settings(max_examples=30, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(
    seed=st.integers(0, 10_000),
    joints=st.integers(1, 24),
    frames=st.integers(1, 150),
    eps=st.sampled_from([0.01, 0.1, 0.5, 2.0]),
    zero_bones=st.sampled_from([0.0, 0.3, 1.0]),
    speed=st.sampled_from([0.0, 0.02, 0.3]),
    segment=st.sampled_from([1, 16, 128]),
)
def test_bound_holds_on_random_skeletons_and_motions(seed, joints, frames, eps, zero_bones, speed, segment):
    motion = random_motion(seed, joints, frames, zero_bones, speed)
    data = create("mcb-rot", eps_cm=eps, segment_frames=segment).encode(motion)
    decoded = create("mcb-rot").decode(data)  # a fresh codec: nothing travels beside the bytes
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= eps
    np.testing.assert_allclose(decoded.motion.positions(), decoded.positions, atol=1e-9)


@settings(max_examples=10, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), frames=st.integers(1, 300), amplitude=st.floats(0.0, 90.0))
def test_bound_holds_on_sinusoidal_cmu_like_motions(seed, frames, amplitude):
    motion = sinusoidal_motion(num_frames=frames, seed=seed, amplitude_deg=amplitude, max_frequency_hz=6.0)
    codec = create("mcb-rot", eps_cm=0.2)
    assert metrics.max_joint_error(motion.positions(), codec.decode(codec.encode(motion)).positions) <= 0.2


@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(
    seed=st.integers(0, 10_000),
    joints=st.integers(15, 40),
    topology=st.sampled_from(["biped", "quadruped", "random"]),
    frames=st.integers(1, 150),
    eps=st.sampled_from([0.02, 0.1, 1.0]),
    shell=st.sampled_from([0.5, 3.0, 10.0]),
)
def test_shell_bound_holds_on_synthetic_rigs(seed, joints, topology, frames, eps, shell):
    """With shell_cm > 0 ACL's virtual vertices at that distance stay within eps too, as do the joints."""
    from mocapbench.synthetic import rig_motion

    motion = rig_motion(num_joints=joints, topology=topology, num_frames=frames, seed=seed, amplitude_deg=60.0)
    data = create("mcb-rot", eps_cm=eps, shell_cm=shell).encode(motion)
    decoded = create("mcb-rot").decode(data)
    assert metrics.motion_shell_errors(motion, decoded.motion, shell).max() <= eps
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= eps


def test_shell_option_bounds_the_shell_error_and_costs_little(synthetic_motion):
    plain = create("mcb-rot", eps_cm=0.5)
    shelled = create("mcb-rot", eps_cm=0.5, shell_cm=3.0)
    plain_data, shell_data = plain.encode(synthetic_motion), shelled.encode(synthetic_motion)
    shell_error = {name: metrics.motion_shell_errors(synthetic_motion, create("mcb-rot").decode(data).motion).max()
                   for name, data in (("plain", plain_data), ("shell", shell_data))}
    assert shell_error["shell"] <= 0.5 < shell_error["plain"], "without the option the shell is not bounded"
    assert len(shell_data) < 1.3 * len(plain_data)
    header, payload = container.unpack(shell_data, "mcb-rot")
    assert create("mcb-rot").describe_payload(header, payload)["shell distance cm (bound also on vertices)"] == 3.0


@pytest.mark.parametrize("value, message", [
    (-1.0, r"shell_cm must be in \[0.0, 100.0\] cm, got -1.0"),
    (float("nan"), "shell_cm must be finite, got nan"),
    ("3", "shell_cm must be of type float, got '3'"),
])
def test_a_bad_shell_distance_gets_one_clear_line(value, message):
    with pytest.raises(ValueError, match=message):
        create("mcb-rot", shell_cm=value)


def test_decodes_to_a_motion_on_the_same_skeleton_and_uses_the_bound(synthetic_motion):
    codec = create("mcb-rot", eps_cm=1.0)
    data = codec.encode(synthetic_motion)
    decoded = codec.decode(data)
    assert decoded.motion.skeleton.names == synthetic_motion.skeleton.names
    np.testing.assert_allclose(decoded.motion.skeleton.offsets, synthetic_motion.skeleton.offsets, atol=1e-5)
    error = metrics.max_joint_error(synthetic_motion.positions(), decoded.positions)
    assert 0.3 < error <= 1.0, "the bound should be used, not wasted"
    baseline = create("quant-rot-zstd").encode(synthetic_motion)
    assert len(data) < len(baseline) / 3


def test_compensated_quantization_saves_rate_and_keeps_the_bound(synthetic_motion):
    """Joints coded against their decoded parents: the ancestors' errors no longer add up at the extremities."""
    sizes = {}
    for compensate in (True, False):
        codec = create("mcb-rot", eps_cm=0.1, compensate=compensate)
        data = codec.encode(synthetic_motion)
        assert metrics.max_joint_error(synthetic_motion.positions(), codec.decode(data).positions) <= 0.1
        sizes[compensate] = len(data)
    assert sizes[True] < 0.95 * sizes[False]


def test_rate_falls_as_the_bound_grows(synthetic_motion):
    sizes = [len(create("mcb-rot", eps_cm=eps).encode(synthetic_motion)) for eps in (0.05, 0.5, 5.0)]
    assert sizes == sorted(sizes, reverse=True) and sizes[0] > 2 * sizes[-1]


def test_quaternion_sign_flips_do_not_change_the_stream(synthetic_motion):
    rng = np.random.default_rng(3)
    flips = np.where(rng.random(synthetic_motion.rotations.shape[:2] + (1,)) < 0.5, -1.0, 1.0)
    flipped = Motion(synthetic_motion.skeleton, synthetic_motion.fps, synthetic_motion.root_positions,
                     synthetic_motion.rotations * flips)
    codec = create("mcb-rot", eps_cm=0.5)
    assert codec.encode(flipped) == codec.encode(synthetic_motion)


def test_half_turns_and_full_spins_keep_the_bound():
    """A root spinning 3 turns in 2 s and a joint swinging through +-180 deg (where Euler angles wrap)."""
    base = sinusoidal_motion(num_frames=240, seed=4)
    t = np.arange(240) / 120.0
    quats = np.array(base.rotations)
    quats[:, 0] = exp_map(np.stack([0 * t, 3 * np.pi * t, 0 * t], axis=1))
    quats[:, 18] = exp_map(np.stack([np.pi * np.sin(2 * t) + 0.01, 0 * t, 0 * t], axis=1))
    motion = Motion(base.skeleton, base.fps, base.root_positions, quats)
    codec = create("mcb-rot", eps_cm=0.3)
    data = codec.encode(motion)
    assert metrics.max_joint_error(motion.positions(), codec.decode(data).positions) <= 0.3
    still = Motion(base.skeleton, base.fps, base.root_positions, base.rotations)
    assert len(data) < 1.5 * len(codec.encode(still))


def _concatenate(a: Motion, b: Motion) -> Motion:
    return Motion(a.skeleton, a.fps, np.concatenate([a.root_positions, b.root_positions]),
                  np.concatenate([a.rotations, b.rotations]))


def test_a_cut_between_takes_costs_at_most_ten_percent():
    first = sinusoidal_motion(num_frames=300, seed=5)
    second = sinusoidal_motion(num_frames=200, seed=6)
    second = Motion(second.skeleton, second.fps, second.root_positions + [50.0, 0.0, -80.0], second.rotations)
    codec = create("mcb-rot", eps_cm=0.5)
    joined = codec.encode(_concatenate(first, second))
    assert codec.last_encode_stats["cuts"] == 1
    apart = len(codec.encode(first)) + len(codec.encode(second))
    assert len(joined) <= 1.10 * apart
    assert metrics.max_joint_error(_concatenate(first, second).positions(), codec.decode(joined).positions) <= 0.5


def test_a_t_pose_first_frame_costs_at_most_ten_percent():
    take = sinusoidal_motion(num_frames=400, seed=7)
    rest = Motion(take.skeleton, take.fps, take.root_positions[:1], np.tile([0.0, 0.0, 0.0, 1.0], (1, 31, 1)))
    codec = create("mcb-rot", eps_cm=0.5)
    with_pose = codec.encode(_concatenate(rest, take))
    assert codec.last_encode_stats["cuts"] == 1
    assert len(with_pose) <= 1.10 * (len(codec.encode(rest)) + len(codec.encode(take)))


def test_the_encoder_waits_for_the_whole_clip(synthetic_motion):
    """The first segment's decode depends on frames far after it (one step and one class table per stream): the
    latency reported is the whole clip, not a segment."""
    codec = create("mcb-rot", eps_cm=0.5)
    other = sinusoidal_motion(num_frames=240, seed=2)
    rotations = synthetic_motion.rotations.copy()
    rotations[160:] = other.rotations[160:]
    roots = synthetic_motion.root_positions.copy()
    roots[160:] = other.root_positions[160:] + roots[159] - other.root_positions[159]
    late_change = Motion(synthetic_motion.skeleton, synthetic_motion.fps, roots, rotations)
    first = codec.decode_frames(codec.encode(synthetic_motion), 0, 80).positions
    changed = codec.decode_frames(codec.encode(late_change), 0, 80).positions
    assert codec.latency_frames == -1
    assert np.abs(first - changed).max() > 1e-6


def test_decode_frames_decodes_only_the_chunks_holding_them(synthetic_motion, monkeypatch):
    codec = create("mcb-rot", eps_cm=0.5, segment_frames=16, chunk_frames=32)
    data = codec.encode(synthetic_motion)
    full = codec.decode(data)
    seen = []
    original = decoder.decode_block

    def spy(info, payload, chunks, *rest):
        seen.extend(chunks.tolist())
        return original(info, payload, chunks, *rest)

    monkeypatch.setattr(decoder, "decode_block", spy)
    monkeypatch.setattr(decoder, "native_clip", lambda info, payload: None)  # the numpy decoder's chunk choice
    monkeypatch.setattr(decoder, "BLOCK_FRAMES", 64)  # several blocks per call
    for start, stop in [(0, 1), (70, 71), (31, 33), (100, 240), (239, 240)]:
        seen.clear()
        part = codec.decode_frames(data, start, stop)
        np.testing.assert_allclose(part.positions, full.positions[start:stop], atol=1e-9)
        np.testing.assert_allclose(part.motion.rotations, full.motion.rotations[start:stop], atol=1e-12)
        assert metrics.max_joint_error(synthetic_motion.positions()[start:stop], part.positions) <= 0.5
        assert seen == list(range(start // 32, (stop - 1) // 32 + 1))
    with pytest.raises(ValueError, match="frame range 5:5 is outside 0:240 or empty"):
        codec.decode_frames(data, 5, 5)
    with pytest.raises(BitstreamError):
        codec.decode_frames(data[:-3], 0, 1)


def test_zero_length_bones_and_a_root_only_skeleton(synthetic_motion):
    flat = Skeleton(synthetic_motion.skeleton.names, synthetic_motion.skeleton.parents,
                    np.zeros((31, 3)), synthetic_motion.skeleton.channel_orders)
    motion = Motion(flat, 120.0, synthetic_motion.root_positions, synthetic_motion.rotations)
    codec = create("mcb-rot", eps_cm=0.1)
    decoded = codec.decode(codec.encode(motion))
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= 0.1
    root = Skeleton(("root",), np.array([-1]), np.zeros((1, 3)))
    single = Motion(root, 30.0, np.zeros((1, 3)), np.array([[[0.0, 0.0, 0.0, 1.0]]]))
    assert codec.decode(codec.encode(single)).positions.shape == (1, 1, 3)


def test_bad_input_gets_one_clear_line(synthetic_motion):
    rotations = np.array(synthetic_motion.rotations)
    rotations[3, 4, 0] = np.nan
    with pytest.raises(ValueError, match=r"`rotations` holds a non-finite value \(NaN or inf\) at index \(3, 4, 0\)"):
        Motion(synthetic_motion.skeleton, 120.0, synthetic_motion.root_positions, rotations)
    roots = np.array(synthetic_motion.root_positions)
    roots[7, 1] = np.inf
    with pytest.raises(ValueError, match="`root_positions` holds a non-finite value"):
        Motion(synthetic_motion.skeleton, 120.0, roots, synthetic_motion.rotations)
    with pytest.raises(ValueError, match="at least one frame, got 0"):
        Motion(synthetic_motion.skeleton, 120.0, np.zeros((0, 3)), np.zeros((0, 31, 4)))
    big = Skeleton(tuple(f"j{j}" for j in range(4097)), np.arange(-1, 4096), np.ones((4097, 3)))
    wide = Motion(big, 30.0, np.zeros((1, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (1, 4097, 1)))
    with pytest.raises(ValueError, match="mcb-rot: the stream holds at most 4096 joints, the motion has 4097"):
        create("mcb-rot").encode(wide)
    with pytest.raises(ValueError, match=r"eps_cm must be in \[0.001, 100.0\] cm, got 0.0"):
        create("mcb-rot", eps_cm=0.0)


def test_quaternion_helpers_round_trip():
    rng = np.random.default_rng(0)
    rotvecs = rng.normal(0.0, 1.0, (500, 3))
    rotvecs /= np.maximum(1.0, np.linalg.norm(rotvecs, axis=1, keepdims=True) / 3.0)  # angles below pi
    rotvecs[:5] *= 1e-9
    np.testing.assert_allclose(log_map(exp_map(rotvecs) * np.sign(exp_map(rotvecs)[:, 3:])), rotvecs, atol=1e-9)
    q = exp_map(rotvecs)
    np.testing.assert_allclose(multiply(q, exp_map(-rotvecs)), np.tile([0, 0, 0, 1.0], (500, 1)), atol=1e-12)
    track = exp_map(np.linspace(0, 3 * np.pi, 200)[:, None] * [0.0, 0.0, 1.0]) * np.sign(rng.random((200, 1)) - 0.5)
    continuous = sign_continuous(track)
    assert np.all(np.sum(continuous[1:] * continuous[:-1], axis=1) > 0)


def test_decompress_writes_bvh(tmp_path, synthetic_motion):
    from mocapbench.cli import main
    from mocapbench.io import read_bvh, write_bvh

    source = tmp_path / "walk.bvh"
    write_bvh(synthetic_motion, source)
    stream, out = tmp_path / "walk.mcb", tmp_path / "back.bvh"
    assert main(["compress", str(source), str(stream), "--codec", "mcb-rot", "--set", "eps_cm=0.5"]) == 0
    assert main(["decompress", str(stream), str(out)]) == 0
    error = metrics.max_joint_error(read_bvh(source).positions(), read_bvh(out).positions())
    assert error <= 0.5 + 1e-3  # the bound, plus the BVH text's rounding of angles


def test_bound_holds_on_a_real_clip_and_beats_quant_rot_zstd(cmu_09_06):
    for eps in (0.05, 1.0):
        data = create("mcb-rot", eps_cm=eps).encode(cmu_09_06)
        decoded = create("mcb-rot").decode(data)
        assert metrics.max_joint_error(cmu_09_06.positions(), decoded.positions) <= eps
    assert len(data) < len(create("quant-rot-zstd").encode(cmu_09_06)) / 5


def _every_fifth(motion: Motion) -> Motion:
    return Motion(motion.skeleton, motion.fps / 5, motion.root_positions[::5], motion.rotations[::5], motion.name)


@pytest.mark.cmu
@pytest.mark.parametrize("split", ["cmu_test", "cmu_all"])
def test_bound_holds_on_every_frame_of_every_cmu_clip(split, cmu_full_dir):
    from mocapbench.datasets.cmu import load_split

    for motion in load_split(split, data_dir=cmu_full_dir):
        for clip in (motion, _every_fifth(motion)):  # 120 fps and 24 fps
            for eps in (0.05, 0.1, 0.5, 1.0):
                decoded = create("mcb-rot").decode(create("mcb-rot", eps_cm=eps).encode(clip))
                error = metrics.joint_errors(clip.positions(), decoded.positions).max()
                assert error <= eps, f"{split} {clip.name} at {clip.fps} fps: {error} cm > {eps} cm"


@pytest.mark.cmu
def test_the_t_pose_frame_of_the_cmu_bvh_files_costs_at_most_ten_percent(cmu_full_dir):
    from mocapbench.datasets.cmu import CMU_CM_PER_UNIT
    from mocapbench.io import read_bvh

    codec = create("mcb-rot", eps_cm=0.5)
    for name in ("02_01", "09_06", "16_07"):
        with_pose = read_bvh(cmu_full_dir / "bvh" / f"{name}.bvh", length_unit_cm=CMU_CM_PER_UNIT)
        joined = len(codec.encode(with_pose))
        assert codec.last_encode_stats["cuts"] >= 1, name
        apart = len(codec.encode(with_pose.slice(0, 1))) + len(codec.encode(with_pose.slice(1, with_pose.num_frames)))
        assert joined <= 1.10 * apart, f"{name}: {joined} bytes joined, {apart} apart"


def test_decoding_is_the_same_whatever_the_block_size_and_buffers_reused(synthetic_motion, monkeypatch):
    """Blocks of chunks and reused work arrays are a speed device: the output must not depend on them, bit for bit
    (the encoder's bound check decodes with the same code)."""
    codec = create("mcb-rot", eps_cm=0.3, segment_frames=32, chunk_frames=32)
    data = codec.encode(synthetic_motion)
    other = create("mcb-rot", eps_cm=1.0).encode(sinusoidal_motion(num_frames=700, seed=2))
    first = codec.decode(data)
    codec.decode(other)  # fills the reused buffers with another stream's arrays
    again = codec.decode(data)
    np.testing.assert_array_equal(first.positions, again.positions)
    monkeypatch.setattr(decoder, "BLOCK_FRAMES", 40)
    small_blocks = codec.decode(data)
    np.testing.assert_array_equal(first.positions, small_blocks.positions)
    np.testing.assert_array_equal(first.motion.rotations, small_blocks.motion.rotations)
    for start, stop in [(0, 240), (33, 97), (200, 201)]:
        np.testing.assert_array_equal(codec.decode_frames(data, start, stop).positions, first.positions[start:stop])
    assert metrics.max_joint_error(synthetic_motion.positions(), first.positions) <= 0.3


def test_the_parsed_header_kept_between_calls_is_not_reused_under_another_container_header():
    """decode_frames keeps the last payload's parsed header; the same payload under a container header with another
    joint count (CRC restamped, as a fuzzer's header mutation) is checked again and refused, never decoded into
    outputs sized by the new header (numba's forward kinematics writes without bounds checks: it corrupted the
    heap)."""
    codec = create("mcb-rot", eps_cm=1.0, step_rel=8.0)
    data = codec.encode(sinusoidal_motion(num_frames=200, seed=3))
    header, payload = container.unpack(data, "mcb-rot")
    assert codec.decode_frames(data, 10, 20).positions.shape == (10, header.num_joints, 3)  # parsed and kept
    for joints in (header.num_joints - 1, header.num_joints + 1):
        edited = container.pack("mcb-rot", header.num_frames, joints, header.fps, bytes(payload))
        with pytest.raises(BitstreamError):
            codec.decode_frames(edited, 10, 20)
    assert np.array_equal(codec.decode_frames(data, 10, 20).positions, codec.decode(data).positions[10:20])
