"""pga-ik (Tournier et al. 2008): Karcher mean, PGA, end-joint choice, paper ratio, stream checks, a real clip."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapbench import metrics
from mocapbench.codecs import BitstreamError, container, create
from mocapbench.codecs.pga.codec import PgaIkCodec, select_end_joints
from mocapbench.codecs.pga.geodesics import fit_pga, geodesic_poses, variance_count
from mocapbench.codecs.pga.karcher import karcher_mean
from mocapbench.codecs.pga.model_motion import geodesic_model_motion as model_motion
from mocapbench.motion import Skeleton
from mocapbench.synthetic import cmu_like_skeleton, sinusoidal_motion


# -- Karcher mean ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("angle", [0.3, 1.0, 3.0])
def test_karcher_mean_recovers_the_centre_of_symmetric_spreads(angle):
    rng = np.random.default_rng(int(angle * 10))
    centre = Rotation.from_rotvec(rng.normal(size=(4, 3)) * angle / np.sqrt(3))  # 4 joints, up to ~pi
    noise = rng.normal(scale=0.4, size=(25, 4, 3))
    noise = np.concatenate([noise, -noise])  # symmetric in the tangent space at the centre
    samples = (centre * Rotation.from_rotvec(noise)).as_quat()
    samples *= rng.choice([-1.0, 1.0], size=samples.shape[:2] + (1,))  # sign flips
    mean = karcher_mean(samples)
    assert np.max((mean.inv() * centre).magnitude()) < 1e-10


def test_karcher_mean_is_not_the_chordal_mean_of_skewed_data():
    # Intrinsic vs extrinsic: for a skewed spread the fixed point must zero the mean tangent vector.
    rng = np.random.default_rng(0)
    samples = Rotation.from_rotvec(np.abs(rng.normal(scale=1.0, size=(200, 1, 3))))
    mean = karcher_mean(samples)
    tangent = (mean.inv() * samples).as_rotvec()
    assert np.max(np.abs(tangent.mean(axis=0))) < 1e-10


# -- PGA -----------------------------------------------------------------------------------------------------------
def test_pga_recovers_an_exact_k_geodesic_model():
    k = 4
    motion, mean, directions, coords = model_motion(num_frames=200, k=k, seed=11)
    model = fit_pga(motion.rotations[:, 1:], k + 3)
    total = model.variances.sum()
    assert model.variances[k:].sum() / total < 1e-20  # nothing beyond k
    assert model.variances[k - 1] / total > 1e-5  # ... and all k are used
    assert variance_count(model.variances, 0.999999) == k
    assert np.max((Rotation.from_quat(model.mean).inv() * Rotation.from_quat(mean)).magnitude()) < 1e-10
    fitted = model.directions[:k].reshape(k, -1)
    true = directions.reshape(k, -1)
    np.testing.assert_allclose(fitted.T @ fitted, true.T @ true, atol=1e-9)  # same subspace
    rebuilt = geodesic_poses(model.mean, model.directions[:k], model.coordinates[:, :k])
    assert np.max((rebuilt.inv() * Rotation.from_quat(motion.rotations[:, 1:])).magnitude()) < 1e-9


def test_pga_of_non_commuting_directions_is_close_to_k():
    # General directions: the product of exponentials leaves only second-order terms off the k-plane.
    rng = np.random.default_rng(4)
    k, n = 3, 10
    directions = np.linalg.qr(rng.normal(size=(3 * n, k)))[0].T.reshape(k, n, 3)
    coords = rng.normal(scale=[0.3, 0.2, 0.1], size=(300, k))
    coords -= coords.mean(axis=0)
    poses = geodesic_poses(Rotation.identity(n), directions, coords)
    model = fit_pga(poses, k)
    assert model.explained_variance() > 0.99


def test_pga_rejects_bad_k():
    with pytest.raises(ValueError, match="num_geodesics"):
        fit_pga(np.tile([0, 0, 0, 1.0], (5, 2, 1)), 7)


# -- end joints, ratio, config -----------------------------------------------------------------------------------
def test_end_joints_by_cmu_asf_bvh_names_and_leaves():
    bvh = cmu_like_skeleton()
    assert [bvh.names[j] for j in select_end_joints(bvh)] == ["LeftHand", "RightHand", "LeftFoot", "RightFoot", "Head"]
    asf_names = ("root", "lhand", "rhand", "lfoot", "rfoot", "head", "x")
    asf = Skeleton(names=asf_names, parents=np.array([-1, 0, 0, 0, 0, 0, 5]), offsets=np.ones((7, 3)))
    assert select_end_joints(asf) == [1, 2, 3, 4, 5]
    odd = Skeleton(names=("a", "b", "c", "d"), parents=np.array([-1, 0, 1, 0]), offsets=np.ones((4, 3)))
    assert select_end_joints(odd) == [2, 3]  # the leaves


def test_paper_ratio_of_the_table_2_setting():
    # 09_06: 141 frames, 31 joints, 6 geodesics, 4 of 9 levels kept = 5 samples per coordinate:
    # 3 * 31 * 141 / ((6 + 1) * 90 + 7 * 3 * 5) = 13113 / 735 (the paper prints 1:18).
    motion = sinusoidal_motion(num_frames=141, seed=2)
    codec = create("pga-ik", num_geodesics=6, root_levels_dropped=5, end_levels_dropped=5)
    codec.encode(motion)
    stats = codec.last_encode_stats
    assert stats["root_lod"] == "4/9" and stats["end_lod"] == "4/9"
    assert stats["paper_compression_ratio"] == pytest.approx(13113 / 735)
    assert stats["K"] == 6 and 0 < stats["explained_variance"] <= 1


def test_variance_fraction_chooses_k():
    motion, _, directions, _ = model_motion(num_frames=100, k=3, seed=2)
    codec = create("pga-ik", num_geodesics=20, variance_fraction=0.999999)
    codec.encode(motion)
    assert codec.last_encode_stats["K"] == 3


def test_config_rejects_out_of_range_values():
    with pytest.raises(ValueError, match="variance_fraction must be in"):
        create("pga-ik", variance_fraction=1.5)
    with pytest.raises(ValueError, match="lm_iterations must be in"):
        create("pga-ik", lm_iterations=0)


# -- bitstream -----------------------------------------------------------------------------------------------------
def test_round_trip_from_bytes_is_deterministic_and_describable():
    motion = sinusoidal_motion(num_frames=77, seed=5)
    params = dict(num_geodesics=10, root_levels_dropped=1, end_levels_dropped=2, trajectory_bits=10)
    data = create("pga-ik", **params).encode(motion)
    first = create("pga-ik").decode(bytes(data))  # the settings travel in the stream
    second = create("pga-ik", num_geodesics=3).decode(bytes(data))
    np.testing.assert_array_equal(first.positions, second.positions)
    assert first.motion.num_frames == 77
    np.testing.assert_allclose(first.motion.positions(), first.positions, atol=1e-9)
    header, payload = container.unpack(data, "pga-ik")
    info = PgaIkCodec().describe_payload(header, payload)
    assert info["num_geodesics"] == 10 and info["end_levels_dropped"] == 2
    assert info["end_joints"] == ["LeftHand", "RightHand", "LeftFoot", "RightFoot", "Head"]


def test_dropping_levels_costs_error_and_saves_bytes():
    motion = sinusoidal_motion(num_frames=240, seed=1)
    fine = create("pga-ik", num_geodesics=12, root_levels_dropped=0, end_levels_dropped=0)
    coarse = create("pga-ik", num_geodesics=12, root_levels_dropped=4, end_levels_dropped=4)
    data_fine, data_coarse = fine.encode(motion), coarse.encode(motion)
    assert len(data_coarse) < 0.6 * len(data_fine)
    err_fine = metrics.max_joint_error(motion.positions(), fine.decode(data_fine).positions)
    err_coarse = metrics.max_joint_error(motion.positions(), coarse.decode(data_coarse).positions)
    assert err_coarse > err_fine


def _payload(motion, **params) -> bytes:
    data = create("pga-ik", **params).encode(motion)
    return bytes(container.unpack(data, "pga-ik")[1])


def test_inconsistent_payload_with_valid_crc_is_a_bitstream_error():
    motion = sinusoidal_motion(num_frames=20, seed=3)
    payload = _payload(motion, num_geodesics=4, root_levels_dropped=0, end_levels_dropped=0)
    # Same payload declared for fewer frames: the coefficient count no longer matches.
    wrong = container.pack("pga-ik", 19, motion.num_joints, motion.fps, payload)
    with pytest.raises(BitstreamError):
        create("pga-ik").decode(wrong)
    with pytest.raises(BitstreamError):
        create("pga-ik").decode(container.pack("pga-ik", 20, motion.num_joints, motion.fps, payload + b"\0"))


def test_motion_with_only_a_root_is_rejected():
    skeleton = Skeleton(names=("root",), parents=np.array([-1]), offsets=np.zeros((1, 3)))
    from mocapbench.motion import Motion

    motion = Motion(skeleton, 30.0, np.zeros((4, 3)), np.tile([0, 0, 0, 1.0], (4, 1, 1)))
    with pytest.raises(ValueError, match="pga-ik: needs a skeleton of at least 2 joints"):
        create("pga-ik").encode(motion)


# -- one real clip (fast) ------------------------------------------------------------------------------------------
def test_cmu_09_06_lossless_trajectories_and_paper_setting(cmu_09_06):
    motion = cmu_09_06
    reference = motion.positions()
    lossless = create("pga-ik", num_geodesics=12, root_levels_dropped=0, end_levels_dropped=0)
    decoded = lossless.decode(lossless.encode(motion)).positions
    assert metrics.kg_distortion(reference, decoded) < 1.5  # measured 0.55 %
    assert metrics.max_joint_error(reference, decoded) < 10.0  # measured 5.9 cm
    paper = create("pga-ik", num_geodesics=6, root_levels_dropped=5, end_levels_dropped=5)
    data = paper.encode(motion)
    assert paper.last_encode_stats["paper_compression_ratio"] == pytest.approx(13113 / 735)
    assert metrics.raw_position_bytes(31, 141) / len(data) > 15


# -- long captures: the encoder's closed loop --------------------------------------------------------------------
def _capture_with_one_rare_window(window: int, windows: int):
    """A synthetic capture of ``windows`` windows in which the sixth alone has hands, feet, toes and head turning
    fast and independently (80 frames): poses the window's few geodesics hold badly, as in a rare movement."""
    from mocapbench.motion import Motion

    motion = sinusoidal_motion(num_frames=window * windows, seed=4)
    rotations = np.array(motion.rotations)
    rare = slice(5 * window + 20, 5 * window + 100)
    time_s = np.arange(80) / motion.fps
    envelope = np.sin(np.pi * time_s / time_s[-1]) ** 2
    rng = np.random.default_rng(0)
    for joint, name in enumerate(motion.skeleton.names):
        if name in ("LeftFoot", "RightFoot", "LeftHand", "RightHand", "Head", "LeftToeBase", "RightToeBase"):
            hz, phase = rng.uniform(1.0, 4.0, 3), rng.uniform(0.0, 2 * np.pi, 3)
            turn = Rotation.from_rotvec(0.8 * envelope[:, None] * np.sin(2 * np.pi * hz * time_s[:, None] + phase))
            rotations[rare, joint] = (Rotation.from_quat(rotations[rare, joint]) * turn).as_quat()
    return Motion(motion.skeleton, motion.fps, motion.root_positions, rotations)


def test_closed_loop_recodes_the_window_of_a_rare_pose_and_no_other(monkeypatch):
    from mocapbench.codecs.pga import codec as pga

    window, windows = 129, 8
    motion = _capture_with_one_rare_window(window, windows)
    monkeypatch.setattr(pga, "WINDOW_FRAMES", 256)  # 1,032 frames count as a long capture
    params = dict(num_geodesics=6, root_levels_dropped=2, end_levels_dropped=2, window_frames=window)
    open_loop, closed_loop = create("pga-ik", **params, refine_ratio=0.0), create("pga-ik", **params)
    assert closed_loop.config.refine_ratio == 1.5  # on by default
    plain, refined = open_loop.encode(motion), closed_loop.encode(motion)
    stats = closed_loop.last_encode_stats
    before = np.linalg.norm(open_loop.decode(plain).positions - motion.positions(), axis=-1)
    after = np.linalg.norm(closed_loop.decode(refined).positions - motion.positions(), axis=-1)
    per_window = [(before[s : s + window].max(), after[s : s + window].max()) for s in range(0, len(before), window)]
    typical = np.median([b for b, _ in per_window])
    assert per_window[5][0] > 5 * typical  # the rare window blows up without the loop (22 cm against 1.3)
    assert per_window[5][1] < 0.75 * per_window[5][0]  # the loop lowers it (to 14 cm)
    for index, (b, a) in enumerate(per_window):
        if index != 5:
            assert a == b  # every other window keeps its stream
    assert stats["refined_windows"] == 1 and stats["window_linf_max_cm"] == pytest.approx(after.max(), rel=1e-6)
    assert len(plain) < len(refined) < 1.15 * len(plain)  # one window's extra geodesics / samples
    # The refined window's stream says what it holds: more geodesics or fewer dropped end-joint levels.
    header, payload = container.unpack(refined, "pga-ik")
    windows, corrections = closed_loop._windows(payload, motion.num_frames)
    start, stop, part = windows[5]
    parsed = closed_loop._read(pga.Header("pga-ik", stop - start, motion.num_joints, motion.fps), part, corrections)
    assert parsed["k"] > 6 or parsed["settings"][3] < 2


def test_refine_ratio_is_off_or_at_least_one():
    with pytest.raises(ValueError, match="refine_ratio must be 0 .off. or >= 1"):
        create("pga-ik", refine_ratio=0.5)
    assert create("pga-ik", refine_ratio=0).config.refine_ratio == 0.0


def test_joined_takes_continue_the_root_and_play_back_and_forth_and_window_linf_counts_each_frame_once():
    from mocapbench.benchmarks.pga.long import joined_takes, synthetic_capture, window_linf

    takes = [sinusoidal_motion(num_frames=n, seed=s) for n, s in ((5, 1), (7, 2))]
    motion, cuts = joined_takes(takes, 30)
    roots = np.asarray(motion.root_positions)
    assert motion.num_frames == 30 and list(cuts) == [5, 18, 27]  # passes of 12 frames: forwards, back, forwards
    # The second take starts where the first ended (x, z), at its own height; backwards retraces the same path.
    np.testing.assert_allclose(roots[5, [0, 2]], roots[4, [0, 2]])
    np.testing.assert_allclose(roots[12:23], roots[10::-1])
    np.testing.assert_allclose(np.asarray(motion.rotations)[12:23], np.asarray(motion.rotations)[10::-1])
    assert synthetic_capture(40).num_frames == 40
    error = np.zeros(7700)
    error[7699], error[7000] = 5.0, 9.0  # 7,700 frames: windows of 1,025, the last lengthened backwards over 7,175
    worst = window_linf(error, 1025, 16)
    assert len(worst) == 8 and worst[6] == 9.0 and worst[7] == 5.0  # frame 7,000 counts for window 6 only
    assert list(window_linf(error[:7680], 1025, 16)) == [9.0]  # a clip up to 7,680 frames is one window


def test_closed_loop_corrects_the_end_joints_across_a_cut_between_takes(monkeypatch):
    """Two takes joined mid-window (the poses jump): the dropped trajectory levels smooth the end joints across the
    jump; the window's corrections (layout 2) bring them back. Layout 1 streams still decode; bad sections fail."""
    from mocapbench.codecs.pga import codec as pga
    from mocapbench.motion import Motion

    window, windows = 129, 8
    first, second = sinusoidal_motion(num_frames=window * windows, seed=4), sinusoidal_motion(
        num_frames=window * windows, seed=9, amplitude_deg=60.0)
    cut = 5 * window + 60
    rotations = np.concatenate([np.asarray(first.rotations)[:cut], np.asarray(second.rotations)[cut:]])
    motion = Motion(first.skeleton, first.fps, first.root_positions, rotations)
    monkeypatch.setattr(pga, "WINDOW_FRAMES", 256)
    params = dict(num_geodesics=6, root_levels_dropped=2, end_levels_dropped=3, window_frames=window)
    open_loop, closed_loop = create("pga-ik", **params, refine_ratio=0.0), create("pga-ik", **params)
    plain, corrected = open_loop.encode(motion), closed_loop.encode(motion)
    stats = closed_loop.last_encode_stats
    before = np.linalg.norm(open_loop.decode(plain).positions - motion.positions(), axis=-1)
    after = np.linalg.norm(closed_loop.decode(corrected).positions - motion.positions(), axis=-1)
    at_cut = slice(5 * window, 6 * window)
    assert before[at_cut].max() > 2 * np.median(before.max(axis=1))
    assert after[at_cut].max() < 0.75 * before[at_cut].max() and after.max() < before.max()
    assert stats["corrections"] > 0
    _, plain_payload = container.unpack(plain, "pga-ik")
    header, payload = container.unpack(corrected, "pga-ik")
    assert plain_payload[1] == 1 and payload[1] == 2  # layout 1 without corrections (as before), 2 with
    assert closed_loop.describe_payload(header, payload)["end_joint_corrections"] >= 0
    # A corrupted corrections section is one BitstreamError: the count past what the window can hold, or cut short.
    windows, _ = closed_loop._windows(payload, motion.num_frames)
    start, stop, part = next(w for w in windows if w[0] <= cut < w[1])
    window_header = pga.Header("pga-ik", stop - start, motion.num_joints, motion.fps)
    fixes = closed_loop._read(window_header, part, True)["corrections"]
    assert len(fixes[0]) > 0 and np.all(fixes[0] < stop - start)
    with pytest.raises(BitstreamError):
        closed_loop._read(window_header, part, False)  # the section is not read as trajectory data
    with pytest.raises(BitstreamError):
        closed_loop._read(window_header, part[:-1], True)
    with pytest.raises(BitstreamError):
        closed_loop._read(window_header, bytes(part) + b"\x00", True)  # a byte after the section
    from mocapbench.entropy.bitio import ByteReader

    too_many = bytes([0x80 | ((5 * (stop - start) + 1) & 0x7F), (5 * (stop - start) + 1) >> 7])  # varint n
    with pytest.raises(BitstreamError, match="at most"):
        pga._read_corrections(too_many, ByteReader(too_many), stop - start, 5)
