"""Cuts (a T-pose frame, a cut between takes) are found, travel in the stream, and cost the clip codecs little."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mocapbench import metrics
from mocapbench.codecs import BitstreamError, create
from mocapbench.codecs.segments import find_cuts, read_cuts, segment_bounds, window_lengths, write_cuts
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.synthetic import sinusoidal_motion
from mocapbench.synthetic.rigs import concatenate_takes, with_tpose_first_frame


def _two_takes(first, second, shift_cm=(300.0, 0.0, 0.0)):
    """Two takes one after the other, the second 3 m to the side: a cut between them."""
    return concatenate_takes(first, dataclasses.replace(second, root_positions=second.root_positions + shift_cm))


@pytest.fixture(scope="module")
def walk():
    return sinusoidal_motion(num_frames=480, seed=3, amplitude_deg=30.0)


def test_a_continuous_motion_has_no_cut(walk):
    assert find_cuts(walk.positions()).size == 0
    assert find_cuts(np.zeros((50, 4, 3))).size == 0  # still: no noise-driven cut
    assert find_cuts(np.zeros((1, 4, 3))).size == 0


def test_a_tpose_frame_is_isolated_and_a_cut_between_takes_found(walk):
    assert find_cuts(with_tpose_first_frame(walk).positions()).tolist() == [1]
    takes = _two_takes(walk, sinusoidal_motion(num_frames=200, seed=4))
    assert find_cuts(takes.positions()).tolist() == [480]
    both = with_tpose_first_frame(takes)
    assert find_cuts(both.positions()).tolist() == [1, 481]


def test_windows_never_straddle_a_cut():
    assert window_lengths(10, 4) == [4, 4, 2]
    assert window_lengths(10, 4, [1, 7]) == [1, 4, 2, 3]
    assert segment_bounds(10, [1, 7]) == [(0, 1), (1, 7), (7, 10)]


def test_cut_lists_round_trip_and_bad_ones_are_refused():
    writer = ByteWriter()
    write_cuts(writer, [1, 5, 90])
    assert read_cuts(ByteReader(writer.getvalue()), 100, "t").tolist() == [1, 5, 90]
    with pytest.raises(BitstreamError, match="cuts must increase within frames 1..49"):
        read_cuts(ByteReader(writer.getvalue()), 50, "t")
    writer = ByteWriter()
    writer.write_varint(60)
    with pytest.raises(BitstreamError, match="at most 49 cuts"):
        read_cuts(ByteReader(writer.getvalue()), 50, "t")


CLIP_CODECS = {
    "mcb-linf": {"eps_cm": 1.0},
    "lsdt-clip": {"step_cm": 1.0},
    "dct-spatial-clip": {"step_cm": 1.0},
    "dwt-spatial-clip": {"step_cm": 1.0},
}


@pytest.mark.parametrize("name", sorted(CLIP_CODECS))
def test_a_tpose_frame_costs_a_clip_codec_at_most_ten_percent(name, walk):
    """The target of issue 16: a T-pose frame costs at most 10 % of the ratio of coding the parts apart.

    Without cut detection the same frame costs far more (the check that the test can fail).
    """
    codec = create(name, **CLIP_CODECS[name])
    with_tpose = with_tpose_first_frame(walk)
    tpose_alone = dataclasses.replace(
        with_tpose, root_positions=with_tpose.root_positions[:1], rotations=with_tpose.rotations[:1]
    )
    data = codec.encode(with_tpose)
    apart = len(codec.encode(tpose_alone)) + len(codec.encode(walk))
    assert len(data) <= apart / 0.9
    decoded = codec.decode(data).positions
    error = metrics.max_joint_error(with_tpose.positions(), decoded)
    assert error <= (1.0 if name == "mcb-linf" else 3.0)
    blind = create(name, **CLIP_CODECS[name], cut_detection=False)
    assert len(blind.encode(with_tpose)) > 1.1 * len(data)


@pytest.mark.parametrize("name", sorted(CLIP_CODECS))
def test_a_cut_between_takes_costs_a_clip_codec_at_most_ten_percent(name, walk):
    codec = create(name, **CLIP_CODECS[name])
    second = sinusoidal_motion(num_frames=300, seed=5, amplitude_deg=30.0)
    takes = _two_takes(walk, second)
    shifted = dataclasses.replace(second, root_positions=second.root_positions + np.array([300.0, 0.0, 0.0]))
    data = codec.encode(takes)
    assert codec.last_encode_stats["cuts"] == 1
    assert len(data) <= (len(codec.encode(walk)) + len(codec.encode(shifted))) / 0.9
    assert codec.decode(data).positions.shape == (780, 31, 3)


def test_lsdt_with_committed_bases_fits_its_own_on_another_skeleton():
    """basis='cmu-v1' keeps the committed 31 x 31 bases on CMU skeletons and learns bases for any other one."""
    from mocapbench.motion import Motion, Skeleton
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(1)
    joints, frames = 12, 60
    skeleton = Skeleton(
        names=tuple(f"j{i}" for i in range(joints)), parents=np.array([-1, 0, 1, 2, 3, 0, 5, 6, 0, 8, 9, 10]),
        offsets=np.vstack([[0, 0, 0], rng.normal(0, 10, (joints - 1, 3))]),
    )
    rotations = Rotation.from_rotvec(np.cumsum(rng.normal(0, 0.03, (frames * joints, 3)), axis=0) * 0.1).as_quat()
    motion = Motion(skeleton, 60.0, np.zeros((frames, 3)), rotations.reshape(frames, joints, 4))
    codec = create("lsdt-clip", step_cm=0.1, train_iterations=20).fit([motion])
    assert codec.model_bytes == 3 * joints * joints * 8
    decoded = codec.decode(codec.encode(motion)).positions
    assert metrics.max_joint_error(motion.positions(), decoded) < 0.5
    assert create("lsdt-clip").fit([sinusoidal_motion(num_frames=20)]).model_bytes == 3 * 31 * 31 * 8


@pytest.mark.parametrize("name", ["mcb-linf", "lsdt-clip"])
def test_a_training_set_of_two_skeletons_fits_one_model_each(name):
    """A folder of mixed rigs: each skeleton gets its model, each clip is coded with its own skeleton's."""
    from mocapbench.motion import Motion, Skeleton
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(2)
    joints, frames = 10, 80
    skeleton = Skeleton(
        names=tuple(f"j{i}" for i in range(joints)), parents=np.array([-1, 0, 1, 2, 0, 4, 5, 0, 7, 8]),
        offsets=np.vstack([[0, 0, 0], rng.normal(0, 10, (joints - 1, 3))]),
    )
    rotations = Rotation.from_rotvec(np.cumsum(rng.normal(0, 0.01, (frames * joints, 3)), axis=0)).as_quat()
    small = Motion(skeleton, 60.0, np.zeros((frames, 3)), rotations.reshape(frames, joints, 4))
    cmu_like = sinusoidal_motion(num_frames=120, seed=7)
    settings = {"eps_cm": 0.5} if name == "mcb-linf" else {"basis": "fit", "step_cm": 0.2, "train_iterations": 10}
    codec = create(name, **settings).fit([small, cmu_like, sinusoidal_motion(num_frames=60, seed=8)])
    for motion in (small, cmu_like):
        data = codec.encode(motion)
        if name == "mcb-linf":
            assert codec.last_encode_stats["model_mode"] == "model"
        assert codec.model_bytes > 0
        error = metrics.max_joint_error(motion.positions(), codec.decode(data).positions)
        assert error <= (0.5 if name == "mcb-linf" else 1.0)
    if name == "lsdt-clip":
        assert codec._bases(joints).shape == (3, joints, joints) and codec._bases(31).shape == (3, 31, 31)
