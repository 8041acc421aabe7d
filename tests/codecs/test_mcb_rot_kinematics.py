"""mcb-rot forward kinematics: a few frames (summed down whole paths) give the bits of the depth-by-depth loop."""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench.codecs.mcb_rot import kinematics
from mocapbench.codecs.mcb_rot.scratch import Scratch
from mocapbench.synthetic import cmu_like_skeleton, sinusoidal_motion


@pytest.mark.parametrize("count", [1, 2, 7, kinematics._PATH_FRAMES])
def test_few_frames_equal_those_frames_of_a_long_block_bit_for_bit(count):
    motion = sinusoidal_motion(num_frames=200, seed=3)
    quats, roots = motion.rotations, motion.root_positions
    block = kinematics.positions(quats, roots, motion.skeleton)  # > _PATH_FRAMES: the depth-by-depth loop
    for first in (0, 50, 200 - count):
        part = kinematics.positions(quats[first : first + count], roots[first : first + count], motion.skeleton)
        np.testing.assert_array_equal(part, block[first : first + count])
        out = np.empty((count, motion.num_joints, 3))
        kinematics.positions(quats[first : first + count], roots[first : first + count], motion.skeleton, out,
                             Scratch())
        np.testing.assert_array_equal(out, block[first : first + count])
    np.testing.assert_allclose(block, motion.positions(), atol=1e-9)


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
