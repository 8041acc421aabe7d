"""Synthetic users' rigs: joint counts, topologies, axes, units, Euler orders, T-pose frames, cuts, BVH export."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapbench.io import read_bvh, write_bvh
from mocapbench.synthetic import (
    concatenate_takes,
    rig_motion,
    rig_skeleton,
    user_case,
    user_cases,
    with_tpose_first_frame,
    write_case_bvh,
)
from mocapbench.synthetic.rigs import EULER_ORDERS, TOPOLOGIES, USER_CASE_NAMES, UNITS_CM, RigConfig, rotate_to_z_up


@pytest.mark.parametrize("topology", TOPOLOGIES)
@pytest.mark.parametrize("num_joints", [15, 23, 31, 52, 70])
def test_every_topology_and_joint_count(topology, num_joints):
    skeleton = rig_skeleton(num_joints=num_joints, topology=topology, seed=4)
    assert skeleton.num_joints == num_joints
    assert skeleton.parents[0] == -1 and all(0 <= p < j for j, p in enumerate(skeleton.parents[1:], 1))
    # Depth-first: every joint's subtree is a contiguous index range right after it.
    for joint in range(num_joints):
        below = skeleton.descendants(joint)
        assert below == list(range(joint + 1, joint + 1 + len(below)))
    # Leaves carry an End Site; bone lengths are those of a body, not of a point.
    leaves = [j for j in range(num_joints) if not skeleton.children(j)]
    assert sorted(skeleton.end_site_parents.tolist()) == leaves
    assert 30.0 < skeleton.rest_height() < 250.0


def test_topologies_differ_and_seed_is_deterministic():
    biped, quadruped = rig_skeleton(num_joints=31), rig_skeleton(num_joints=31, topology="quadruped")
    assert biped.names != quadruped.names
    first, again = rig_motion(topology="random", seed=3), rig_motion(topology="random", seed=3)
    other = rig_motion(topology="random", seed=4)
    np.testing.assert_array_equal(first.rotations, again.rotations)
    assert first.skeleton.same_structure(again.skeleton)
    assert not first.skeleton.same_structure(other.skeleton)
    assert np.abs(first.rotations - rig_motion(topology="random", seed=3, num_frames=240).rotations).max() == 0


def test_z_up_is_the_y_up_motion_turned():
    y_up = rig_motion(num_joints=22, seed=2)
    z_up = rig_motion(num_joints=22, seed=2, up_axis="z")
    assert (y_up.up_axis, z_up.up_axis) == ("y", "z")
    turned = y_up.positions() @ Rotation.from_euler("X", 90, degrees=True).as_matrix().T
    np.testing.assert_allclose(z_up.positions(), turned, atol=1e-9)
    # Standing on the floor, head up: the Z extent of the Z-up rig is a body height, its Y extent a step length.
    positions = z_up.positions()
    assert 140 < np.ptp(positions[0, :, 2]) < 200
    assert np.ptp(positions[0, :, 1]) < 60
    np.testing.assert_allclose(rotate_to_z_up(y_up).positions(), z_up.positions(), atol=1e-9)


def test_mixed_euler_orders_cover_all_six():
    skeleton = rig_skeleton(num_joints=15, euler_orders="mixed")
    assert set(skeleton.channel_orders) == set(EULER_ORDERS)
    assert set(rig_skeleton(euler_orders="YXZ").channel_orders) == {"YXZ"}


@pytest.mark.parametrize("unit", sorted(UNITS_CM))
def test_bvh_round_trip_in_every_unit_and_order(tmp_path, unit):
    motion = rig_motion(num_joints=27, unit=unit, euler_orders="mixed", up_axis="z", num_frames=30, seed=1)
    assert motion.source_unit_cm == UNITS_CM[unit]
    path = write_bvh(motion, tmp_path / "rig.bvh", length_unit_cm=motion.source_unit_cm)
    text = path.read_text()
    # The file really is in the unit: the root height line's numbers are the cm ones divided by the unit.
    first_frame = np.array(text.split("Frame Time:")[1].splitlines()[1].split(), float)
    np.testing.assert_allclose(first_frame[:3], motion.root_positions[0] / UNITS_CM[unit], rtol=1e-5, atol=1e-5)
    back = read_bvh(path, length_unit_cm=UNITS_CM[unit])
    assert back.skeleton.names == motion.skeleton.names
    assert back.skeleton.channel_orders == motion.skeleton.channel_orders
    np.testing.assert_allclose(back.positions(), motion.positions(), atol=1e-3)


def test_frame_counts_from_2_to_20000():
    assert rig_motion(num_frames=2).num_frames == 2
    long = rig_motion(num_frames=20_000, num_joints=15)
    assert long.num_frames == 20_000 and np.all(np.isfinite(long.rotations))


def test_tpose_first_frame():
    motion = rig_motion(num_frames=50)
    with_tpose = with_tpose_first_frame(motion)
    assert with_tpose.num_frames == 51
    np.testing.assert_allclose(np.abs(with_tpose.rotations[0, :, 3]), 1.0)
    np.testing.assert_allclose(with_tpose.rotations[1:], motion.rotations, atol=1e-15)
    # A T-pose: the hands stand level with the shoulders, arms spread along X.
    skeleton = motion.skeleton
    positions = with_tpose.positions()[0]
    left_hand, left_arm = skeleton.index("LeftHand"), skeleton.index("LeftArm")
    assert abs(positions[left_hand, 1] - positions[left_arm, 1]) < 1e-9
    assert positions[left_hand, 0] - positions[left_arm, 0] > 50


def test_two_takes_concatenated_have_a_cut():
    case = user_case("biped-31-two-takes")
    motion = case.motion
    assert motion.num_frames == 480
    step = np.linalg.norm(np.diff(motion.root_positions, axis=0), axis=1)
    assert np.argmax(step) == 239 and step[239] > 250 and np.delete(step, 239).max() < 5
    with pytest.raises(ValueError, match="different skeletons"):
        concatenate_takes(rig_motion(num_joints=15), rig_motion(num_joints=16))
    with pytest.raises(ValueError, match="differ in fps"):
        concatenate_takes(rig_motion(fps=30.0), rig_motion(fps=60.0))


def _motion_rows(text: str) -> np.ndarray:
    return np.array([line.split() for line in text.split("Frame Time:")[1].splitlines()[1:]], float)


def test_bvh_position_channels_on_every_joint(tmp_path):
    motion = rig_motion(num_joints=19, euler_orders="mixed", unit="inch", num_frames=12, seed=5)
    unit = motion.source_unit_cm
    root_only = write_bvh(motion, tmp_path / "root.bvh", length_unit_cm=unit).read_text()
    every = write_bvh(motion, tmp_path / "all.bvh", length_unit_cm=unit, position_channels="all").read_text()
    channel_lines = [line.split() for line in every.splitlines() if line.strip().startswith("CHANNELS")]
    assert len(channel_lines) == 19 and all(words[1] == "6" for words in channel_lines)
    assert all(words[2:5] == ["Xposition", "Yposition", "Zposition"] for words in channel_lines)
    rows, reference = _motion_rows(every), _motion_rows(root_only)
    assert rows.shape == (12, 19 * 6) and reference.shape == (12, 3 + 19 * 3)
    per_joint = rows.reshape(12, 19, 6)
    # Rotations equal the root-only file's; non-root positions are the joint's OFFSET (file units) in every frame.
    np.testing.assert_array_equal(per_joint[:, :, 3:].reshape(12, -1), reference[:, 3:])
    np.testing.assert_array_equal(per_joint[:, 0, :3], reference[:, :3])
    np.testing.assert_allclose(per_joint[:, 1:, :3], np.broadcast_to(motion.skeleton.offsets[1:] / unit, (12, 18, 3)),
                               atol=1e-6)
    with pytest.raises(ValueError, match="position_channels.*'root' or 'all'"):
        write_bvh(motion, tmp_path / "bad.bvh", position_channels="joints")


def test_user_cases_cover_issue_16(tmp_path):
    cases = user_cases()
    assert [case.name for case in cases] == list(USER_CASE_NAMES[:-1])
    joints = [case.motion.num_joints for case in cases]
    assert min(joints) == 15 and max(joints) == 70
    assert {case.motion.up_axis for case in cases} == {"y", "z"}
    assert {case.motion.source_unit_cm for case in cases} >= {0.1, 1.0, 100.0, 2.54}
    assert min(case.motion.num_frames for case in cases) == 2
    assert any(case.bvh_position_channels == "all" for case in cases)
    case = user_case("biped-22-zup-mm-xyz")
    path = write_case_bvh(case, tmp_path / "case.bvh")
    back = read_bvh(path, length_unit_cm=0.1)
    np.testing.assert_allclose(back.positions(), case.motion.positions(), atol=1e-3)
    with pytest.raises(KeyError, match="No synthetic case 'nope'"):
        user_case("nope")


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("num_joints", 14, r"num_joints must be in \[15, 70\], got 14"),
        ("num_joints", 71, r"num_joints must be in \[15, 70\], got 71"),
        ("topology", "spider", "topology must be one of"),
        ("up_axis", "x", "up_axis must be one of"),
        ("euler_orders", "XYX", "euler_orders must be one of"),
        ("unit", "furlong", "unit must be one of"),
        ("num_frames", 0, "num_frames must be"),
    ],
)
def test_bad_config_one_line(field, value, message):
    with pytest.raises(ValueError, match=message):
        RigConfig(**{field: value})
