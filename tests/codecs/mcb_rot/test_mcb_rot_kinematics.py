"""mcb-rot forward kinematics: the compiled kernel gives the bits of the closed loop's numpy kinematics, on any
skeleton and any number of frames, and its outputs whatever their layout."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapbench.codecs.mcb_rot import kinematics
from mocapbench.codecs.mcb_rot.checks import forward_kinematics
from mocapbench.motion import Motion, Skeleton
from mocapbench.synthetic import cmu_like_skeleton, rig_motion, sinusoidal_motion


@st.composite
def rig_motions(draw) -> Motion:
    """Synthetic rigs of 1 to 70 joints (below 15: a rig's first joints; parents come first) with wide rotations."""
    joints = draw(st.integers(1, 70))
    motion = rig_motion(num_joints=max(joints, 15), topology=draw(st.sampled_from(["biped", "quadruped", "random"])),
                        num_frames=draw(st.integers(1, 90)), seed=draw(st.integers(0, 10_000)), amplitude_deg=90.0)
    if joints >= 15:
        return motion
    skeleton = motion.skeleton
    small = Skeleton(skeleton.names[:joints], skeleton.parents[:joints], skeleton.offsets[:joints])
    return Motion(small, motion.fps, motion.root_positions, motion.rotations[:, :joints])


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(rig_motions())
def test_kernel_equals_the_closed_loops_numpy_kinematics_bit_for_bit(motion):
    """The encoder scores its closed loop on :func:`.checks.forward_kinematics`; the decoder returns the kernel's
    positions: the same bits, so the bound the loop checks is the bound of what is decoded."""
    expected, _ = forward_kinematics(motion.rotations, motion.root_positions, motion.skeleton)
    rotations = np.empty_like(motion.rotations)
    placed = kinematics.positions(motion.rotations, motion.root_positions, motion.skeleton, rotations_out=rotations)
    np.testing.assert_array_equal(placed, expected)
    np.testing.assert_array_equal(rotations, motion.rotations)
    np.testing.assert_allclose(placed, motion.positions(), atol=1e-9)


@pytest.mark.parametrize("count", [1, 2, 7, 16, 17])
def test_few_frames_equal_those_frames_of_a_long_block_bit_for_bit(count):
    motion = sinusoidal_motion(num_frames=200, seed=3)
    quats, roots = motion.rotations, motion.root_positions
    block = kinematics.positions(quats, roots, motion.skeleton)
    for first in (0, 50, 200 - count):
        part = kinematics.positions(quats[first : first + count], roots[first : first + count], motion.skeleton)
        np.testing.assert_array_equal(part, block[first : first + count])


def test_outputs_of_any_layout_are_filled():
    """Outputs that are views with strides (a window of a larger array, a transpose) get the same values."""
    motion = sinusoidal_motion(num_frames=30, seed=5)
    quats, roots, skeleton = motion.rotations, motion.root_positions, motion.skeleton
    expected = kinematics.positions(quats, roots, skeleton)
    wide = np.full((30, skeleton.num_joints, 5), np.nan)  # (F, J, 5): positions in [..., 1:4], not C-contiguous
    rotations = np.full((4, skeleton.num_joints, 30), np.nan).transpose(2, 1, 0)
    returned = kinematics.positions(quats, roots, skeleton, wide[..., 1:4], rotations)
    np.testing.assert_array_equal(wide[..., 1:4], expected)
    np.testing.assert_array_equal(returned, expected)
    np.testing.assert_array_equal(rotations, quats)
    component_major = np.ascontiguousarray(quats.transpose(2, 1, 0))  # what the decoder passes: a transposed view
    np.testing.assert_array_equal(kinematics.positions(component_major.transpose(2, 1, 0), roots, skeleton), expected)


def test_identity_rotations_of_one_frame_give_the_rest_pose():
    skeleton = cmu_like_skeleton()
    quats = np.zeros((1, skeleton.num_joints, 4))
    quats[..., 3] = 1.0
    roots = np.array([[1.0, 2.0, 3.0]])
    rest = kinematics.positions(quats, roots, skeleton)
    offsets = skeleton.offsets.copy()
    offsets[0] = roots[0]
    expected = np.zeros((skeleton.num_joints, 3))
    for joint in range(skeleton.num_joints):  # identity rotations: the sums of the offsets down each path
        expected[joint] = offsets[joint] + (expected[skeleton.parents[joint]] if joint else 0.0)
    np.testing.assert_allclose(rest[0], expected, atol=1e-12)


def test_translation_tracks_step_each_joint_by_its_translation_bit_for_bit():
    """A game rig's translated joint steps from its parent by its translation of the frame, in the kernel as in the
    closed loop's numpy kinematics (the same bits), and as in Motion's forward kinematics (float rounding)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    from game_rig import game_rig_motion

    motion = game_rig_motion(50, seed=4)
    steps = motion.local_translations()
    moving = np.zeros(motion.num_joints, dtype=bool)
    moving[motion.moving_joints()] = True
    expected, _ = forward_kinematics(motion.rotations, motion.root_positions, motion.skeleton, translations=steps)
    placed = kinematics.positions(motion.rotations, motion.root_positions, motion.skeleton, translations=steps,
                                  moving=moving)
    np.testing.assert_array_equal(placed, expected)
    np.testing.assert_allclose(placed, motion.positions(), atol=1e-9)
    still = kinematics.positions(motion.rotations, motion.root_positions, motion.skeleton)
    assert np.abs(still - placed).max() > 100  # the Hips OFFSET is metres from where the pelvis is
