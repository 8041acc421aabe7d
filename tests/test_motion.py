"""Skeleton/Motion: forward kinematics on hand-computed chains, validation, synthetic determinism."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapbench.motion import Motion, Skeleton
from mocapbench.synthetic import SyntheticConfig, cmu_like_skeleton, sinusoidal_motion


def chain(offsets):
    n = len(offsets)
    return Skeleton(names=tuple(f"j{i}" for i in range(n)), parents=np.arange(n) - 1, offsets=np.array(offsets))


def test_fk_two_joint_chain_by_hand():
    skeleton = chain([[0, 0, 0], [10.0, 0, 0]])
    rotations = Rotation.from_euler("z", np.array([[0.0, 0.0], [90.0, 0.0]])[..., None], degrees=True)  # (F=2, J=2)
    motion = Motion(skeleton, 30.0, np.array([[1.0, 2, 3], [0, 0, 0]]), rotations)
    positions = motion.positions()
    np.testing.assert_allclose(positions[0], [[1, 2, 3], [11, 2, 3]], atol=1e-12)
    # Root turned 90 degrees about Z: the child's x offset now points along +Y.
    np.testing.assert_allclose(positions[1], [[0, 0, 0], [0, 10, 0]], atol=1e-12)


def test_fk_three_joint_chain_composes_rotations():
    skeleton = chain([[0, 0, 0], [0, 10.0, 0], [0, 5.0, 0]])
    quats = Rotation.from_euler("x", np.array([[0.0, 90.0, 90.0]])[..., None], degrees=True)
    motion = Motion(skeleton, 30.0, np.zeros((1, 3)), quats)
    # Joint 1 sits 10 up; joint 1 rotated 90 deg about X turns joint 2's +Y offset into +Z.
    np.testing.assert_allclose(motion.positions()[0], [[0, 0, 0], [0, 10, 0], [0, 10, 5]], atol=1e-12)
    matrices, _ = motion.global_transforms()
    np.testing.assert_allclose(matrices[0, 2], Rotation.from_euler("x", 180, degrees=True).as_matrix(), atol=1e-12)


def test_motion_rejects_bad_input():
    skeleton = chain([[0, 0, 0], [1, 0, 0]])
    good = np.tile([0, 0, 0, 1.0], (3, 2, 1))
    with pytest.raises(ValueError, match=r"`rotations` to have shape \(\*, 2, 4\), got \(3, 3, 4\)"):
        Motion(skeleton, 30, np.zeros((3, 3)), np.tile([0, 0, 0, 1.0], (3, 3, 1)))
    with pytest.raises(ValueError, match="at least one frame"):
        Motion(skeleton, 30, np.zeros((0, 3)), np.zeros((0, 2, 4)))
    bad = good.copy()
    bad[1, 1, 0] = np.nan
    with pytest.raises(ValueError, match=r"non-finite value .* at index \(1, 1, 0\)"):
        Motion(skeleton, 30, np.zeros((3, 3)), bad)
    with pytest.raises(ValueError, match="fps"):
        Motion(skeleton, 0, np.zeros((3, 3)), good)
    with pytest.raises(ValueError, match=r"root_positions` to have shape \(3, 3\)"):
        Motion(skeleton, 30, np.zeros((2, 3)), good)
    with pytest.raises(ValueError, match="zero-norm quaternion .* frame 0, joint 1"):
        Motion(skeleton, 30, np.zeros((3, 3)), np.concatenate([good[:, :1], np.zeros((3, 1, 4))], axis=1))


def test_skeleton_rejects_bad_trees():
    with pytest.raises(ValueError, match="Parents must come before children"):
        Skeleton(names=("a", "b"), parents=np.array([-1, 1]), offsets=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="unique"):
        Skeleton(names=("a", "a"), parents=np.array([-1, 0]), offsets=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="permutation of 'XYZ'"):
        Skeleton(names=("a",), parents=np.array([-1]), offsets=np.zeros((1, 3)), channel_orders=("XXY",))


def test_cmu_like_skeleton_is_human_sized():
    skeleton = cmu_like_skeleton()
    assert skeleton.num_joints == 31
    assert 150 < skeleton.rest_height() < 200
    assert skeleton.descendants(skeleton.index("LeftArm")) == [
        skeleton.index(n) for n in ("LeftForeArm", "LeftHand", "LeftFingerBase", "LeftHandIndex1", "LThumb")
    ]


def test_synthetic_is_deterministic_and_seed_dependent():
    a = sinusoidal_motion(num_frames=50, seed=3)
    b = sinusoidal_motion(SyntheticConfig(num_frames=50, seed=3))
    c = sinusoidal_motion(num_frames=50, seed=4)
    np.testing.assert_array_equal(a.rotations, b.rotations)
    np.testing.assert_array_equal(a.root_positions, b.root_positions)
    assert not np.allclose(a.rotations, c.rotations)


def test_synthetic_moves_forward_and_feet_stay_near_floor():
    motion = sinusoidal_motion(num_frames=240, fps=120.0, speed_cm_s=100.0, seed=0)
    assert motion.root_positions[-1, 2] == pytest.approx(100.0 * 239 / 120)
    positions = motion.positions()
    feet = positions[:, [motion.skeleton.index("LeftFoot"), motion.skeleton.index("RightFoot")], 1]
    assert feet.min() > -20 and feet.max() < 60


def test_synthetic_config_rejects_bad_values():
    with pytest.raises(ValueError, match=r"num_frames must be in \[1, 1000000\], got 0"):
        sinusoidal_motion(num_frames=0)


def test_every_keeps_every_kth_frame_at_the_lower_rate_and_refuses_a_bad_step():
    motion = sinusoidal_motion(num_frames=11, seed=3)
    sub = motion.every(5)
    assert sub.num_frames == 3 and sub.fps == pytest.approx(motion.fps / 5)
    np.testing.assert_allclose(sub.positions(), motion.positions()[[0, 5, 10]], atol=1e-5)
    assert sub.source_unit_cm == motion.source_unit_cm and sub.up_axis == motion.up_axis
    assert motion.every(1) is motion
    for step in (0, -1, 2.0, True):
        with pytest.raises(ValueError, match="Frame step must be a positive integer"):
            motion.every(step)


def test_a_decoders_motion_skips_the_checks_but_keeps_its_arrays_read_only():
    """Motion.from_decoder (decoders only) takes the arrays as they are, read-only, and equals a validated motion
    of the same unit quaternions; it refuses arrays of the wrong shape or dtype and a bad fps (a decoder bug)."""
    reference = sinusoidal_motion(num_frames=30, seed=5)
    rotations, roots = reference.rotations.copy(), reference.root_positions.copy()
    motion = Motion.from_decoder(reference.skeleton, reference.fps, roots, rotations)
    assert motion.rotations is rotations and motion.root_positions is roots
    assert not rotations.flags.writeable and not roots.flags.writeable
    np.testing.assert_array_equal(motion.positions(), reference.positions())
    assert (motion.name, motion.source_unit_cm, motion.up_axis, motion.num_frames) == ("", 1.0, "y", 30)
    for bad in (dict(rotations=rotations[:, :-1]), dict(rotations=rotations.astype(np.float32)),
                dict(roots=roots[:-1]), dict(fps=0.0), dict(fps=np.inf), dict(rotations=rotations[:0], roots=roots[:0])):
        args = dict(rotations=rotations, roots=roots, fps=30.0) | bad
        with pytest.raises(ValueError, match="from_decoder"):
            Motion.from_decoder(reference.skeleton, args["fps"], args["roots"], args["rotations"])
