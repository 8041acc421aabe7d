"""mcb-linf: the L-infinity bound holds on every joint of every frame, whatever the motion."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapbench import metrics
from mocapbench.codecs import BitstreamError, create
from mocapbench.codecs.mcb_linf.codec import _BCC_NEIGHBOURS, bcc_quantize
from mocapbench.synthetic import sinusoidal_motion


@settings(max_examples=25, deadline=None, derandomize=True)
@given(
    seed=st.integers(0, 10_000),
    frames=st.integers(1, 400),
    eps=st.sampled_from([0.05, 0.3, 1.0, 2.5, 7.0]),
    clip=st.sampled_from([4, 17, 120]),
    representation=st.sampled_from(["pca", "bone", "absolute"]),
    amplitude=st.floats(0.0, 60.0),
)
def test_bound_holds_on_random_synthetic_motions(seed, frames, eps, clip, representation, amplitude):
    motion = sinusoidal_motion(num_frames=frames, seed=seed, amplitude_deg=amplitude, max_frequency_hz=6.0)
    entropy = "trained" if representation == "pca" else "bands"  # trained + bone/absolute needs fit(): below
    codec = create("mcb-linf", eps_cm=eps, clip_frames=clip, representation=representation, entropy=entropy)
    decoded = create("mcb-linf").decode(codec.encode(motion))  # a fresh codec: nothing beside the bytes
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= eps


def test_bound_is_used_not_wasted(synthetic_motion):
    """The error is close to eps (a codec that codes losslessly would also meet the bound, at a high rate)."""
    codec = create("mcb-linf", eps_cm=1.0)
    data = codec.encode(synthetic_motion)
    error = metrics.max_joint_error(synthetic_motion.positions(), codec.decode(data).positions)
    assert 0.5 < error <= 1.0
    baseline = create("quant-delta-zstd", step_cm=2 / np.sqrt(3)).encode(synthetic_motion)
    assert len(data) < len(baseline), "mcb-linf should beat the generic baseline at equal L-inf"


def test_rate_falls_as_the_bound_grows(synthetic_motion):
    sizes = [len(create("mcb-linf", eps_cm=eps).encode(synthetic_motion)) for eps in (0.1, 0.5, 2.0, 8.0)]
    assert sizes == sorted(sizes, reverse=True) and sizes[0] > 2 * sizes[-1]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-50, 50), min_size=3, max_size=3), st.floats(0.01, 10.0))
def test_bcc_lattice_covers_within_radius(point, radius):
    coords, half_cell = bcc_quantize(np.array([point]), radius)
    assert np.all(coords % 2 == coords[0, 0] % 2)  # all even or all odd
    assert np.linalg.norm(coords[0] * half_cell - point) <= radius * (1 + 1e-12)


def test_static_motion_and_single_frame(synthetic_motion):
    still = synthetic_motion.slice(0, 1)
    codec = create("mcb-linf", eps_cm=0.2)
    decoded = codec.decode(codec.encode(still))
    assert metrics.max_joint_error(still.positions(), decoded.positions) <= 0.2


def test_bad_config_values_are_rejected():
    with pytest.raises(ValueError, match=r"eps_cm must be in \[0.001, 100.0\] cm, got 0.0"):
        create("mcb-linf", eps_cm=0.0)
    with pytest.raises(ValueError, match="representation must be one of"):
        create("mcb-linf", representation="quaternion")


def test_decoder_with_another_model_refuses_the_stream(synthetic_motion, training_motions):
    fitted = create("mcb-linf", eps_cm=0.5).fit(training_motions)
    data = fitted.encode(synthetic_motion)
    with pytest.raises(BitstreamError, match=r"coded with model 0x[0-9a-f]{8} \(pca, 31 joints\); this decoder holds"):
        create("mcb-linf").decode(data)  # holds the shipped CMU basis, not this one
    refit = create("mcb-linf").fit(training_motions)
    assert metrics.max_joint_error(synthetic_motion.positions(), refit.decode(data).positions) <= 0.5


def test_shipped_model_is_orthonormal_and_reported():
    from mocapbench.codecs.mcb_linf.codec import load_default_model

    model = load_default_model()
    assert model.num_joints == 31 and model.representation == "pca"
    np.testing.assert_allclose(model.basis @ model.basis.T, np.eye(90), atol=1e-5)
    arrays = 4 * (90 * 90 + 90) + 4 * model.band_scale.size + 8 * model.class_edges.size
    arrays += 4 * (model.tables.counts.size + model.lattice_tables.counts.size)
    assert create("mcb-linf").model_bytes == arrays + 1 + 4 + 4  # + representation, joints, clip length
    assert create("mcb-linf", representation="bone", entropy="bands").model_bytes == 0


def test_pca_on_another_skeleton_asks_for_fit_when_told_to():
    from mocapbench.codecs import NotFittedError
    from mocapbench.motion import Motion, Skeleton

    skeleton = Skeleton(names=("a", "b"), parents=np.array([-1, 0]), offsets=np.array([[0, 0, 0], [0, 10.0, 0]]))
    motion = Motion(skeleton, 30.0, np.zeros((5, 3)), np.tile([0, 0, 0, 1.0], (5, 2, 1)))
    with pytest.raises(NotFittedError, match="model is for 31 joints, the motion has 2"):
        create("mcb-linf", on_missing_model="error").encode(motion)
    with pytest.raises(NotFittedError, match="entropy='trained' with representation='bone' needs a model"):
        create("mcb-linf", representation="bone", on_missing_model="error").encode(motion)


@pytest.mark.parametrize("representation", ["pca", "bone"])
def test_a_skeleton_without_a_model_is_coded_untrained_within_the_bound(representation):
    from mocapbench.motion import Motion, Skeleton

    rng = np.random.default_rng(0)
    joints, frames = 7, 90
    skeleton = Skeleton(
        names=tuple(f"j{i}" for i in range(joints)), parents=np.array([-1, 0, 1, 2, 0, 4, 5]),
        offsets=np.vstack([[0, 0, 0], rng.normal(0, 10, (joints - 1, 3))]),
    )
    angles = np.cumsum(rng.normal(0, 0.02, (frames, joints, 3)), axis=0)
    from scipy.spatial.transform import Rotation

    rotations = Rotation.from_rotvec(angles.reshape(-1, 3)).as_quat().reshape(frames, joints, 4)
    motion = Motion(skeleton, 30.0, np.cumsum(rng.normal(0, 1, (frames, 3)), axis=0), rotations)
    codec = create("mcb-linf", eps_cm=0.5, representation=representation)
    data = codec.encode(motion)
    assert "untrained (bone, bands)" in codec.last_encode_stats["model_mode"]
    assert codec.model_bytes == 0
    decoded = create("mcb-linf").decode(data)  # no model needed to decode
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= 0.5
    assert len(data) < 0.25 * metrics.raw_position_bytes(joints, frames)


def test_bound_holds_on_a_real_clip(cmu_09_06):
    motion = cmu_09_06
    for eps in (0.5, 2.0):
        decoded = create("mcb-linf").decode(create("mcb-linf", eps_cm=eps).encode(motion))
        assert metrics.max_joint_error(motion.positions(), decoded.positions) <= eps


@pytest.mark.cmu
@pytest.mark.parametrize("eps", [0.1, 0.5, 1.0, 2.0, 3.0, 10.0])
def test_bound_holds_on_every_frame_of_cmu_test(eps, cmu_full_dir):
    from mocapbench.datasets.cmu import load_split

    for motion in load_split("cmu_test", data_dir=cmu_full_dir):
        decoded = create("mcb-linf").decode(create("mcb-linf", eps_cm=eps).encode(motion))
        error = metrics.joint_errors(motion.positions(), decoded.positions)
        assert error.max() <= eps, f"{motion.name}: {error.max()} cm > {eps} cm"


@pytest.mark.parametrize("representation", ["bone", "absolute"])
def test_trained_entropy_on_a_fitted_skeleton(synthetic_motion, training_motions, representation):
    codec = create("mcb-linf", eps_cm=0.5, representation=representation).fit(training_motions)
    data = codec.encode(synthetic_motion)
    assert metrics.max_joint_error(synthetic_motion.positions(), codec.decode(data).positions) <= 0.5
    with pytest.raises(BitstreamError, match=f"model fit for representation '{representation}'.*holds none"):
        create("mcb-linf", representation=representation).decode(data)


def test_trained_entropy_beats_per_band_tables_on_a_real_clip(cmu_09_06):
    trained = len(create("mcb-linf", eps_cm=1.0).encode(cmu_09_06))
    bands = len(create("mcb-linf", eps_cm=1.0, entropy="bands").encode(cmu_09_06))
    assert trained < 0.85 * bands


@pytest.mark.parametrize("target", [0.05, 0.2])
def test_mean_target_is_met_and_the_bound_still_holds(synthetic_motion, target):
    codec = create("mcb-linf", eps_cm=2.0, mean_cm=target)
    decoded = codec.decode(codec.encode(synthetic_motion)).positions
    error = metrics.joint_errors(synthetic_motion.positions(), decoded)
    assert error.max() <= 2.0
    assert target / 3 < error.mean() <= target  # met, and not by coding far finer than asked
    assert codec.last_encode_stats["mean_error_cm"] == pytest.approx(error.mean(), rel=1e-6)


def test_a_tighter_mean_target_costs_more(synthetic_motion):
    sizes = [len(create("mcb-linf", eps_cm=3.0, mean_cm=mean).encode(synthetic_motion)) for mean in (0.02, 0.1, 0.5)]
    assert sizes == sorted(sizes, reverse=True)


def test_corrupt_payloads_past_the_crc_fail_cleanly(synthetic_motion):
    """Bytes changed *inside* a valid container (as a buggy writer would): a BitstreamError or a well-formed result."""
    from mocapbench.codecs.container import Header

    codec = create("mcb-linf", eps_cm=0.5)
    payload = codec.encode_payload(synthetic_motion)
    header = Header("mcb-linf", synthetic_motion.num_frames, synthetic_motion.num_joints, synthetic_motion.fps)
    rng = np.random.default_rng(0)
    outcomes = {"error": 0, "decoded": 0}
    for _ in range(300):
        corrupt = bytearray(payload)
        position = int(rng.integers(len(corrupt)))
        corrupt[position] ^= int(rng.integers(1, 256))
        try:
            positions, _ = codec.decode_payload(header, memoryview(bytes(corrupt)))
        except BitstreamError:
            outcomes["error"] += 1
            continue
        assert positions.shape == synthetic_motion.positions().shape
        outcomes["decoded"] += 1
    assert outcomes["error"] > 0


@pytest.mark.parametrize("frames", [2, 5])
def test_fit_from_clips_shorter_than_their_channel_count(frames, synthetic_motion):
    """Fewer frames than the 3 (J - 1) root-relative channels used to crash the PCA (issue 16)."""
    training = [sinusoidal_motion(num_frames=frames, seed=seed) for seed in (21, 22)]
    codec = create("mcb-linf", eps_cm=0.5).fit(training)
    data = codec.encode(synthetic_motion)
    assert codec.last_encode_stats["model_mode"] == "model"
    assert metrics.max_joint_error(synthetic_motion.positions(), codec.decode(data).positions) <= 0.5


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_corrected_joints_coded_joint_by_joint_read_back(seed):
    """Any set of corrected joints, some joints never corrected and some on every frame, reads back exactly."""
    from mocapbench.codecs.mcb_linf.codec import _read_joint_flags, _write_joint_flags
    from mocapbench.entropy.bitio import ByteReader, ByteWriter

    rng = np.random.default_rng(seed)
    frames, joints = 37, 9
    flags = rng.random((frames, joints)) < rng.random(joints)  # a rate per joint
    flags[:, 0], flags[:, 1] = False, True
    corrected = np.flatnonzero(flags.ravel())
    writer = ByteWriter()
    _write_joint_flags(writer, corrected, frames, joints)
    reader = ByteReader(writer.getvalue())
    np.testing.assert_array_equal(_read_joint_flags(reader, frames, joints), corrected)
    reader.expect_end()


def test_corrected_joint_flags_that_disagree_with_their_counts_are_refused():
    from mocapbench.codecs.mcb_linf.codec import _read_joint_flags, _write_joint_flags
    from mocapbench.entropy.bitio import ByteReader, ByteWriter

    frames, joints = 40, 3
    flags = np.zeros((frames, joints), dtype=bool)
    flags[::3, 1] = True
    writer = ByteWriter()
    _write_joint_flags(writer, np.flatnonzero(flags.ravel()), frames, joints)
    good = bytearray(writer.getvalue())
    too_many = bytearray(good)
    too_many[1] = frames + 1  # joint 1 corrected on more frames than the window has
    with pytest.raises(BitstreamError, match="corrected on 41 frames"):
        _read_joint_flags(ByteReader(bytes(too_many)), frames, joints)
    other_count = bytearray(good)
    other_count[1] += 1  # the flags no longer sum to the count
    with pytest.raises(BitstreamError, match="corrected-joint flags"):
        _read_joint_flags(ByteReader(bytes(other_count)), frames, joints)
    with pytest.raises(BitstreamError):
        _read_joint_flags(ByteReader(bytes(good[:-2])), frames, joints)


def _stream_settings(codec, motion) -> tuple[float, bool]:
    """(frequency slope, corrected joints coded joint by joint?) of the stream of one window."""
    from mocapbench.codecs.mcb_linf.codec import _read_settings
    from mocapbench.entropy.bitio import ByteReader

    settings = _read_settings(ByteReader(codec.encode_payload(motion)))
    return settings[2], settings[-1]


def test_a_30_fps_clip_keeps_the_smaller_of_two_frequency_slopes():
    motion = sinusoidal_motion(num_frames=150, fps=30.0, seed=3, max_frequency_hz=6.0)
    searched = create("mcb-linf", eps_cm=0.1)
    fixed = create("mcb-linf", eps_cm=0.1, low_fps_slope=0.0)
    data = searched.encode(motion)
    assert len(data) <= len(fixed.encode(motion))
    assert _stream_settings(searched, motion)[0] in (2.0, 0.25)
    assert metrics.max_joint_error(motion.positions(), create("mcb-linf").decode(data).positions) <= 0.1


def test_a_120_fps_clip_is_coded_with_the_configured_slope_only(synthetic_motion):
    searched = create("mcb-linf", eps_cm=0.5)
    assert searched.encode(synthetic_motion) == create("mcb-linf", eps_cm=0.5, low_fps_slope=0.0).encode(
        synthetic_motion
    )
    assert _stream_settings(searched, synthetic_motion)[0] == 2.0


def test_the_encoder_codes_corrected_joints_the_smaller_way_and_keeps_the_bound():
    """A fine bound on a fast 30 fps motion corrects many joints: the joint-by-joint coding is chosen there."""
    motion = sinusoidal_motion(num_frames=120, fps=30.0, seed=5, max_frequency_hz=8.0, amplitude_deg=40.0)
    codec = create("mcb-linf", eps_cm=0.05)
    data = codec.encode(motion)
    assert _stream_settings(codec, motion)[1]
    assert metrics.max_joint_error(motion.positions(), create("mcb-linf").decode(data).positions) <= 0.05


def test_rate_distortion_rounding_only_moves_values_towards_zero():
    """Each value is its nearest integer or one or two steps nearer zero, never farther; with rd_lambda 0 it is
    plain rounding; a lone 0.6 where the class expects zeros goes to 0, a 40.4 stays 40."""
    from mocapbench.codecs.mcb_linf.codec import _rate_distortion_round
    from mocapbench.codecs.mcb_linf.model import load_default_model

    tables = load_default_model().tables
    rng = np.random.default_rng(0)
    scaled = rng.laplace(0.0, 3.0, 5000)
    classes = rng.integers(0, tables.num_classes, scaled.size)
    nearest = np.sign(scaled) * np.floor(np.abs(scaled) + 0.5)
    assert np.array_equal(_rate_distortion_round(scaled, classes, tables, 0.0), nearest)
    rounded = _rate_distortion_round(scaled, classes, tables, 0.3)
    assert np.all(np.abs(rounded) <= np.abs(nearest)) and np.all(np.abs(nearest) - np.abs(rounded) <= 2)
    assert np.all(rounded * np.sign(scaled) >= 0) and np.any(rounded != nearest)
    zero_class = int(np.argmax(tables.log2_probabilities[:, 0]))  # the class most sure of a zero
    assert _rate_distortion_round(np.array([0.6, -0.6, 40.4]), np.full(3, zero_class), tables, 0.3).tolist() == [0, 0, 40]


def test_the_cheapest_lattice_point_is_within_the_radius_and_never_costlier():
    from mocapbench.codecs.mcb_linf.codec import _cheapest_lattice_points
    from mocapbench.codecs.mcb_linf.layers import lattice_symbols
    from mocapbench.codecs.mcb_linf.model import load_default_model
    from mocapbench.entropy.ans import tokenize

    model = load_default_model()
    radius = 0.1
    residual = np.random.default_rng(1).uniform(-0.4, 0.4, (4000, 3))
    nearest, half_cell = bcc_quantize(residual, radius)
    chosen = _cheapest_lattice_points(residual, nearest, half_cell, radius, model)
    assert np.all(np.linalg.norm(residual - chosen * half_cell, axis=1) <= radius)
    assert np.all((chosen % 2 == chosen[:, :1] % 2).all(axis=1))  # lattice points: all even or all odd

    def cost(points):
        tokens, _, widths = tokenize(lattice_symbols(points)[0])
        return widths - model.lattice_tables.log2_probabilities[0, tokens]

    assert np.all(cost(chosen) <= cost(nearest)) and np.any(cost(chosen) < cost(nearest))


@pytest.mark.parametrize("eps", [0.05, 0.5])
def test_rate_distortion_rounding_keeps_the_bound_and_shrinks_a_30_fps_stream(eps):
    motion = sinusoidal_motion(num_frames=200, fps=30.0, seed=7, max_frequency_hz=6.0, amplitude_deg=30.0)
    plain = create("mcb-linf", eps_cm=eps, rd_lambda=0.0).encode(motion)
    rounded = create("mcb-linf", eps_cm=eps).encode(motion)
    for data in (plain, rounded):
        assert metrics.max_joint_error(motion.positions(), create("mcb-linf").decode(data).positions) <= eps
    assert len(rounded) < len(plain)


def _sphere_flag(codec, motion) -> bool:
    from mocapbench.codecs.mcb_linf.codec import _read_settings
    from mocapbench.entropy.bitio import ByteReader

    return _read_settings(ByteReader(codec.encode_payload(motion)))[-2]


@pytest.mark.parametrize("eps", [0.05, 0.1, 0.5])
def test_bones_held_to_spheres_keep_the_bound_and_shrink_the_stream(eps):
    """Rigid bones (a rotation-driven motion): the sphere is used at a fine bound, the stream is smaller than
    without it, and a fresh decoder keeps every joint within eps."""
    motion = sinusoidal_motion(num_frames=240, fps=30.0, seed=9, max_frequency_hz=6.0, amplitude_deg=35.0)
    held = create("mcb-linf", eps_cm=eps)
    plain = create("mcb-linf", eps_cm=eps, bone_spheres=False)
    data, plain_data = held.encode(motion), plain.encode(motion)
    assert not _sphere_flag(plain, motion)
    if eps < 0.5:
        assert _sphere_flag(held, motion) and len(data) < len(plain_data)
    assert len(data) <= len(plain_data)
    for stream in (data, plain_data):
        assert metrics.max_joint_error(motion.positions(), create("mcb-linf").decode(stream).positions) <= eps


def test_a_translated_joint_is_not_held_to_a_sphere():
    """A joint whose local translation moves (a game rig's pelvis) gets no sphere; the rigid bones do; the bound
    holds on the decoded motion."""
    import dataclasses

    from mocapbench.codecs.mcb_linf.codec import _rigid_bones

    motion = sinusoidal_motion(num_frames=100, fps=30.0, seed=4, max_frequency_hz=6.0, amplitude_deg=30.0)
    stretched = 5
    translations = np.broadcast_to(motion.skeleton.offsets, (motion.num_frames, motion.num_joints, 3)).copy()
    translations[:, 0] = motion.root_positions
    translations[:, stretched] += np.linspace(0.0, 2.0, motion.num_frames)[:, None] * np.array([0.0, 1.0, 0.0])
    moved = dataclasses.replace(motion, translations=translations)
    positions, parents = moved.positions(), moved.skeleton.parents
    codes = _rigid_bones(positions, parents, 0.1)
    assert codes[0] == 0 and codes[stretched] == 0
    rigid = [j for j in range(1, moved.num_joints)
             if _bone_spread(positions, parents, j) < 1e-6 and np.linalg.norm(positions[0, j] - positions[0, parents[j]]) > 0.1]
    assert len(rigid) > moved.num_joints // 2 and all(codes[j] == j - parents[j] for j in rigid)
    decoded = create("mcb-linf").decode(create("mcb-linf", eps_cm=0.1).encode(moved))
    assert metrics.max_joint_error(positions, decoded.positions) <= 0.1


def _is_below(parents, joint, ancestor) -> bool:
    while joint >= 0:
        if joint == ancestor:
            return True
        joint = parents[joint]
    return False


def _bone_spread(positions, parents, joint) -> float:
    return float(np.ptp(np.linalg.norm(positions[:, joint] - positions[:, parents[joint]], axis=-1)))


def test_sphere_codes_read_back_and_codes_naming_a_later_joint_or_cut_short_are_refused():
    from mocapbench.codecs.mcb_linf.codec import _read_sphere_joints, _write_sphere_joints
    from mocapbench.entropy.bitio import ByteReader, ByteWriter

    for codes in ([0, 1, 0, 3, 1, 2, 6, 1, 1, 9], [0], [0, 0, 0], [0] + [1] * 20):
        writer = ByteWriter()
        _write_sphere_joints(writer, np.array(codes))
        reader = ByteReader(writer.getvalue())
        assert _read_sphere_joints(reader, len(codes)).tolist() == codes and reader.remaining == 0
    for bad in ([0, 1, 3, 0], [0, 0, 3, 0]):  # a code of 1 off the chain bits; joint 2 would hang from joint -1
        writer = ByteWriter()
        writer.write_bytes(np.packbits(np.array(bad[1:]) > 0).tobytes())
        writer.write_bytes(np.packbits(np.zeros(1, bool)).tobytes())
        writer.write_varints(np.array([b for b in bad[1:] if b]))
        with pytest.raises(BitstreamError, match="earlier joint"):
            _read_sphere_joints(ByteReader(writer.getvalue()), 4)
    writer = ByteWriter()
    writer.write_bytes(np.packbits(np.array([0, 1, 0, 0, 0, 0, 0, 0, 0, 0], bool)).tobytes())
    writer.write_bytes(b"\x00")
    writer.write_varints(np.array([1]))  # a code of 1 outside the chain bits
    with pytest.raises(BitstreamError, match="earlier joint"):
        _read_sphere_joints(ByteReader(writer.getvalue()), 11)
    with pytest.raises(BitstreamError):
        _read_sphere_joints(ByteReader(b"\xff"), 8)  # the chain bits and parents missing


def test_a_stream_with_spheres_refuses_a_corrupt_sphere_section(monkeypatch):
    """A stream whose sphere section names a later joint (a hostile writer): the decoder (here the encoder's own
    check of its stream) raises BitstreamError, never a wrong decode."""
    import mocapbench.codecs.mcb_linf.codec as codec_module

    motion = sinusoidal_motion(num_frames=120, fps=30.0, seed=9, max_frequency_hz=6.0, amplitude_deg=35.0)
    write = codec_module._write_sphere_joints

    def hostile(writer, codes):
        codes = codes.copy()
        held = np.flatnonzero(codes)
        codes[held[0]] = held[0] + 5  # a parent before the first joint
        write(writer, codes)

    monkeypatch.setattr(codec_module, "_write_sphere_joints", hostile)
    with pytest.raises(BitstreamError, match="earlier joint"):
        create("mcb-linf", eps_cm=0.1).encode_payload(motion)


def test_default_settings_are_written_compact_and_others_in_full(synthetic_motion):
    """A default encode names its step and slope by index (eps written negated); a root step off the table is
    written as float64 as before; both decode within the bound."""
    from mocapbench.codecs.mcb_linf.codec import _COMPACT_SHAPES, _RDO_STEPS, _read_settings
    from mocapbench.entropy.bitio import ByteReader

    motion = synthetic_motion.slice(0, 200)
    for settings, compact in (({}, True), ({"root_step_rel": 0.3}, False), ({"rdo": False, "base_step_rel": 1.7}, False)):
        codec = create("mcb-linf", eps_cm=0.25, **settings)
        payload = codec.encode_payload(motion)
        assert (np.frombuffer(payload[:8], "<f8")[0] < 0) == compact
        eps, step, slope, root_step_rel = _read_settings(ByteReader(payload))[:4]
        assert eps == 0.25 and step == codec.last_encode_stats["base_step_cm"]
        if compact:
            assert any(step == 0.25 * rel for rel in _RDO_STEPS) and (slope, root_step_rel) in _COMPACT_SHAPES
        decoded = create("mcb-linf").decode(codec.encode(motion))
        assert metrics.max_joint_error(motion.positions(), decoded.positions) <= 0.25


@pytest.mark.parametrize("step_index, shape", [(25, 0), (255, 0), (3, 2), (3, 255)])
def test_compact_settings_off_the_tables_are_refused(step_index, shape):
    from mocapbench.codecs.mcb_linf.codec import _read_settings
    from mocapbench.entropy.bitio import ByteReader, ByteWriter

    writer = ByteWriter()
    writer.write_f64(-0.5)
    writer.write_u8(step_index)
    writer.write_u8(shape)
    writer.write_bytes(bytes(16))
    with pytest.raises(BitstreamError, match="base step index"):
        _read_settings(ByteReader(writer.getvalue()))


def test_the_rate_search_steps_are_exact_eighth_octaves():
    """The table a compact stream indexes: powers of two times float literals, equal to 2^(i/8) here and the
    quarter octaves of the earlier grid at the even entries."""
    from mocapbench.codecs.mcb_linf.codec import _RDO_STEPS

    assert len(_RDO_STEPS) == 25 and _RDO_STEPS[8] == 1.0 and _RDO_STEPS[0] == 0.5 and _RDO_STEPS[-1] == 4.0
    assert np.allclose(_RDO_STEPS, 2.0 ** (np.arange(-8, 17) / 8), rtol=1e-15, atol=0)


def test_the_encoder_holds_a_bone_only_where_that_corrects_no_more_frames():
    """A joint with a purely radial base error stays held (the sphere removes it); the codes used are a subset of
    those offered; every final residual is within the radius."""
    from mocapbench.codecs.mcb_linf.codec import _refine, _rigid_bones

    motion = sinusoidal_motion(num_frames=60, fps=30.0, seed=2, amplitude_deg=30.0)
    positions, parents = motion.positions(), motion.skeleton.parents
    codes = _rigid_bones(positions, parents, 0.1)
    radial = int(np.flatnonzero(codes)[-1])
    bone = positions[:, radial] - positions[:, parents[radial]]
    base = positions + np.random.default_rng(3).normal(0.0, 0.04, positions.shape)
    base[:, radial] = positions[:, radial] + 0.3 * bone / np.linalg.norm(bone, axis=-1, keepdims=True) * np.where(
        np.arange(len(base)) % 2, 1.0, -1.0
    )[:, None]  # 0.3 cm along the bone, alternating: the mean length stays, every frame needs a correction unheld
    corrected, lattice, residual, used = _refine(positions, base, 0.1, None, codes)
    assert used[radial] == codes[radial]
    assert np.all((used == 0) | (used == codes)) and np.all(np.linalg.norm(residual, axis=-1) <= 0.1)
    assert len(corrected) == len(lattice) < positions.shape[0] * positions.shape[1]


def _refine_joint_by_joint(positions, base, radius, model, codes):
    """The refinement with bone spheres one joint at a time, parents first, as the decoder applies it: the
    reference that :func:`_refine`'s level-at-a-time version must match bit for bit."""
    from mocapbench.codecs.mcb_linf.codec import _bone_lengths, _lattice_points_for, _onto_sphere

    num_frames, num_joints, _ = positions.shape
    half_cell = 2.0 * radius / np.sqrt(5.0)
    lengths, final, codes = _bone_lengths(base, codes), base.copy(), codes.copy()
    residual = np.empty_like(base)
    lattices = np.zeros((num_frames, num_joints, 3), dtype=np.int64)
    flags = np.zeros((num_frames, num_joints), dtype=bool)
    for joint in range(num_joints):
        if codes[joint]:
            held = _onto_sphere(final[:, joint], final[:, joint - codes[joint]], lengths[joint])
            if np.count_nonzero(np.sum((positions[:, joint] - held) ** 2, axis=-1) > radius**2) <= np.count_nonzero(
                np.sum((positions[:, joint] - final[:, joint]) ** 2, axis=-1) > radius**2
            ):
                final[:, joint] = held
            else:
                codes[joint] = 0
        error = positions[:, joint] - final[:, joint]
        mine = np.sum(error**2, axis=-1) > radius**2
        lattice = _lattice_points_for(error[mine], radius, model)
        final[mine, joint] += lattice * half_cell
        error[mine] -= lattice * half_cell
        residual[:, joint], lattices[mine, joint], flags[:, joint] = error, lattice, mine
    corrected = np.flatnonzero(flags.ravel())
    return corrected, lattices.reshape(-1, 3)[corrected], residual.reshape(-1, 3), codes


@pytest.mark.parametrize("trained", [False, True])
def test_the_refinement_a_level_at_a_time_is_the_joint_by_joint_one(trained):
    """The encoder refines the held bones a level of their chains at a time; its corrections, lattice points,
    residuals and held bones are exactly those of one joint at a time (the decoder's order)."""
    from mocapbench.codecs.mcb_linf.codec import _refine, _rigid_bones
    from mocapbench.codecs.mcb_linf.model import load_default_model

    motion = sinusoidal_motion(num_frames=90, fps=30.0, seed=7, amplitude_deg=40.0)
    positions, parents = motion.positions(), motion.skeleton.parents
    codes = _rigid_bones(positions, parents, 0.1)
    assert np.count_nonzero(codes[np.flatnonzero(codes) - codes[np.flatnonzero(codes)]]) > 3  # chains of held bones
    rng = np.random.default_rng(1)  # base errors of another size on each joint: some held bones lose, and go
    base = positions + rng.normal(0.0, 0.04, positions.shape) * rng.uniform(0.2, 2.0, (1, positions.shape[1], 1))
    model = load_default_model() if trained else None
    got = _refine(positions, base, 0.1, model, codes)
    want = _refine_joint_by_joint(positions, base, 0.1, model, codes)
    assert 0 < len(want[0]) < positions.shape[0] * positions.shape[1] and np.any(want[3] != codes)
    for mine, theirs in zip(got, want):
        assert np.array_equal(mine, theirs)


def test_the_encoders_cost_tables_are_the_token_arithmetic():
    """The rounding's and the lattice points' bits read from per-table caches are exactly the per-value arithmetic
    on tokens (magnitudes past the rounding's table, lattice points past the reach included)."""
    from mocapbench.codecs.mcb_linf.codec import _cheapest_lattice_points, _rate_distortion_round
    from mocapbench.codecs.mcb_linf.layers import lattice_symbols
    from mocapbench.codecs.mcb_linf.model import load_default_model
    from mocapbench.entropy.ans import tokenize

    model = load_default_model()
    tables = model.tables
    rng = np.random.default_rng(2)
    scaled = np.concatenate([rng.laplace(0.0, 3.0, 4000), rng.laplace(0.0, 3000.0, 200)])
    classes = rng.integers(0, tables.num_classes, scaled.size)
    magnitude = np.abs(scaled)
    chosen = np.floor(magnitude + 0.5).astype(np.int64)

    def bits(values):
        tokens, _, widths = tokenize(values)
        return widths + (values != 0) - tables.log2_probabilities[classes, tokens]

    for _ in range(2):
        lower = np.maximum(chosen - 1, 0)
        gain = (magnitude - lower) ** 2 - (magnitude - chosen) ** 2 + 0.1 * (bits(lower) - bits(chosen))
        chosen = np.where((chosen > 0) & (gain < 0), lower, chosen)
    assert chosen.max() > 4096
    assert np.array_equal(_rate_distortion_round(scaled, classes, tables, 0.1), np.where(scaled < 0, -chosen, chosen))

    radius = 0.1
    for spread in (0.4, 4.0):  # within the lattice's reach, then past it (escaped points)
        residual = rng.uniform(-spread, spread, (3000, 3))
        nearest, half_cell = bcc_quantize(residual, radius)
        candidates = nearest[:, None, :] + np.concatenate([np.zeros((1, 3), dtype=np.int64), _BCC_NEIGHBOURS])[None]
        valid = np.sum((residual[:, None, :] - candidates * half_cell) ** 2, axis=-1) <= radius**2
        valid[:, 0] = True
        tokens, _, widths = tokenize(lattice_symbols(candidates.reshape(-1, 3))[0])
        cost = (widths - model.lattice_tables.log2_probabilities[0, tokens]).reshape(valid.shape)
        want = candidates[np.arange(len(candidates)), np.argmin(np.where(valid, cost, np.inf), axis=1)]
        assert np.array_equal(_cheapest_lattice_points(residual, nearest, half_cell, radius, model), want)


def test_the_rate_search_walks_downhill_past_one_bump_and_stops_after_two_misses():
    """:func:`_descend` from position 8 finds a minimum behind a one-step bump, calls each position at most once,
    and gives up a way after two positions in a row without a smaller size (a deeper minimum behind a wider bump
    is missed: the documented simplification)."""
    from mocapbench.codecs.mcb_linf.codec import _descend

    def walk(sizes):
        calls = []
        _descend(lambda position: calls.append(position) or sizes[position], len(sizes), 8, 2)
        assert len(calls) == len(set(calls))
        return min(calls, key=lambda position: sizes[position]), calls

    found, calls = walk([9, 8, 7, 6, 5, 4, 5, 6, 7, 8, 9, 10, 11])
    assert found == 5 and sorted(calls) == [3, 4, 5, 6, 7, 8, 9, 10]
    assert walk([9, 9, 9, 9, 9, 3, 4, 7, 5, 6, 7, 8, 9])[0] == 5  # the bump at 7 is one position wide
    found, calls = walk([9, 9, 9, 9, 9, 3, 7, 7, 5, 6, 7, 8, 9])  # two positions wide: the walk stops at 6
    assert found == 8 and sorted(calls) == [6, 7, 8, 9, 10]
