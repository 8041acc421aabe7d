"""Game-rig tracks of a Motion: local translations and scales on any joint, checked against a forward kinematics
written here joint by joint with 4x4 matrices (local = T R S), independent of the vectorized one in motion.py."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from mocapbench.io.units import turn_axes
from mocapbench.motion import Motion, Skeleton


def reference_fk(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Global 4x4 matrices (F, J, 4, 4) and end-site positions (F, E, 3), one joint and one frame at a time."""
    skeleton = motion.skeleton
    num_frames, num_joints = motion.num_frames, motion.num_joints
    glob = np.zeros((num_frames, num_joints, 4, 4))
    for f in range(num_frames):
        for j in range(num_joints):
            local = np.eye(4)
            scale = np.ones(3) if motion.scales is None else motion.scales[f, j]
            local[:3, :3] = Rotation.from_quat(motion.rotations[f, j]).as_matrix() @ np.diag(scale)
            if j == 0:
                local[:3, 3] = motion.root_positions[f]
            elif motion.translations is None:
                local[:3, 3] = skeleton.offsets[j]
            else:
                local[:3, 3] = motion.translations[f, j]
            parent = skeleton.parents[j]
            glob[f, j] = local if parent < 0 else glob[f, parent] @ local
    ends = np.zeros((num_frames, len(skeleton.end_site_parents), 3))
    for e, (joint, offset) in enumerate(zip(skeleton.end_site_parents, skeleton.end_site_offsets)):
        ends[:, e] = (glob[:, joint] @ np.append(offset, 1.0))[:, :3]
    return glob, ends


@st.composite
def game_rigs(draw):
    """A random tree of 1-7 joints with end sites, 1-5 frames, and any mix of translation and scale tracks."""
    num_joints = draw(st.integers(1, 7))
    num_frames = draw(st.integers(1, 5))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    parents = np.array([-1] + [int(rng.integers(0, j)) for j in range(1, num_joints)])
    skeleton = Skeleton(
        names=tuple(f"j{j}" for j in range(num_joints)),
        parents=parents,
        offsets=rng.normal(0, 10, (num_joints, 3)),
        end_site_parents=np.arange(num_joints),
        end_site_offsets=rng.normal(0, 5, (num_joints, 3)),
    )
    translations = scales = None
    if draw(st.booleans()):
        translations = np.broadcast_to(skeleton.offsets, (num_frames, num_joints, 3)).copy()
        moving = rng.random(num_joints) < 0.5
        translations[:, moving] += rng.normal(0, 3, (num_frames, int(moving.sum()), 3))
    if draw(st.booleans()):
        scales = np.exp(rng.normal(0, 0.3, (num_frames, num_joints, 3)))
    return Motion(
        skeleton,
        30.0,
        rng.normal(0, 50, (num_frames, 3)),
        Rotation.random(num_frames * num_joints, random_state=seed).as_quat().reshape(num_frames, num_joints, 4),
        translations=translations,
        scales=scales,
    )


@settings(max_examples=60, deadline=None)
@given(game_rigs())
def test_forward_kinematics_matches_a_joint_by_joint_reference(motion):
    glob, ends = reference_fk(motion)
    matrices, positions = motion.global_transforms()
    np.testing.assert_allclose(positions, glob[..., :3, 3], atol=1e-9)
    np.testing.assert_allclose(matrices, glob[..., :3, :3], atol=1e-12)
    np.testing.assert_allclose(motion.positions(), glob[..., :3, 3], atol=1e-9)
    np.testing.assert_allclose(motion.end_site_positions(), ends, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(game_rigs(), st.data())
def test_slice_and_every_carry_the_tracks(motion, data):
    start = data.draw(st.integers(0, motion.num_frames - 1))
    stop = data.draw(st.integers(start + 1, motion.num_frames))
    step = data.draw(st.integers(1, 3))
    positions = motion.positions()
    part = motion.slice(start, stop)
    np.testing.assert_allclose(part.positions(), positions[start:stop], atol=1e-9)
    np.testing.assert_allclose(motion.every(step).positions(), positions[::step], atol=1e-9)
    for track in ("translations", "scales"):
        whole = getattr(motion, track)
        assert (getattr(part, track) is None) == (whole is None or np.all(whole[start:stop] == _still(motion, track)[start:stop]))


def _still(motion: Motion, track: str) -> np.ndarray:
    """What ``track`` holds for a joint that does not move (offsets; root positions in column 0) or scale (1)."""
    if track == "scales":
        return np.ones((motion.num_frames, motion.num_joints, 3))
    still = np.broadcast_to(motion.skeleton.offsets, (motion.num_frames, motion.num_joints, 3)).copy()
    still[:, 0] = motion.root_positions
    return still


def rig(num_frames=4):
    """A ground root, a translated pelvis under it and a leg: the shape of a game rig."""
    skeleton = Skeleton(
        names=("Root", "Hips", "Leg", "Foot"),
        parents=np.array([-1, 0, 1, 2]),
        offsets=np.array([[0, 0, 0], [0, 90.0, 0], [10.0, -40, 0], [0, -45.0, 0]]),
        end_site_parents=np.array([3]),
        end_site_offsets=np.array([[0, 0, 12.0]]),
    )
    rotations = np.tile([0, 0, 0, 1.0], (num_frames, 4, 1))
    return skeleton, rotations


def test_a_translation_equal_to_the_offset_costs_nothing():
    skeleton, rotations = rig()
    roots = np.arange(12.0).reshape(4, 3)
    still = np.broadcast_to(skeleton.offsets, (4, 4, 3)).copy()
    still[:, 0] = [5.0, 6, 7]  # column 0 is replaced by the root positions
    motion = Motion(skeleton, 30, roots, rotations, translations=still, scales=np.ones((4, 4, 3)))
    assert motion.translations is None and motion.scales is None
    assert motion.moving_joints().size == 0 and motion.scaled_joints().size == 0
    np.testing.assert_allclose(motion.positions(), Motion(skeleton, 30, roots, rotations).positions(), atol=0)
    np.testing.assert_array_equal(motion.local_translations(), np.concatenate([roots[:, None], still[:, 1:]], axis=1))


def test_a_moving_pelvis_and_a_scaled_leg_move_what_they_should():
    skeleton, rotations = rig()
    translations = np.broadcast_to(skeleton.offsets, (4, 4, 3)).copy()
    translations[:, 1, 1] = [90.0, 85, 80, 95]  # the pelvis bobs
    scales = np.ones((4, 4, 3))
    scales[2, 2] = [1.0, 2.0, 1.0]  # the leg doubles along its Y at frame 2: the foot moves, the leg does not
    motion = Motion(skeleton, 30, np.zeros((4, 3)), rotations, translations=translations, scales=scales)
    np.testing.assert_array_equal(motion.moving_joints(), [1])
    np.testing.assert_array_equal(motion.scaled_joints(), [2])
    np.testing.assert_array_equal(motion.translations[:, 0], motion.root_positions)
    positions = motion.positions()
    np.testing.assert_allclose(positions[:, 1, 1], [90, 85, 80, 95])
    np.testing.assert_allclose(positions[:, 2, 1], [50, 45, 40, 55])
    np.testing.assert_allclose(positions[:, 3, 1], [5, 0, 40 - 90, 10])
    np.testing.assert_allclose(motion.end_site_positions()[:, 0], positions[:, 3] + [0, 0, 12])
    assert repr(motion).endswith("1 translated joints, 1 scaled joints)")
    assert not motion.translations.flags.writeable and not motion.scales.flags.writeable


@pytest.mark.parametrize(
    "track, value, message",
    [
        ("translations", np.nan, r"Non-finite value .* `translations` at frame 2, joint 'Leg' \(2\)"),
        ("translations", np.inf, r"Non-finite value .* `translations` at frame 2, joint 'Leg' \(2\)"),
        ("scales", np.nan, r"Non-finite value .* `scales` at frame 2, joint 'Leg' \(2\)"),
        ("scales", 0.0, r"<= 0 in `scales` at frame 2, joint 'Leg' \(2\); a scale must be > 0"),
        ("scales", -1.0, r"<= 0 in `scales` at frame 2, joint 'Leg' \(2\)"),
    ],
)
def test_bad_tracks_are_refused_naming_the_joint_and_the_frame(track, value, message):
    skeleton, rotations = rig()
    array = np.ones((4, 4, 3)) if track == "scales" else np.broadcast_to(skeleton.offsets, (4, 4, 3)).copy()
    array[2, 2, 1] = value
    with pytest.raises(ValueError, match=message):
        Motion(skeleton, 30, np.zeros((4, 3)), rotations, **{track: array})


def test_a_track_of_the_wrong_shape_is_refused():
    skeleton, rotations = rig()
    with pytest.raises(ValueError, match=r"`translations` to have shape \(4, 4, 3\) \(frames, joints, xyz\), got \(3, 4, 3\)"):
        Motion(skeleton, 30, np.zeros((4, 3)), rotations, translations=np.zeros((3, 4, 3)))
    with pytest.raises(ValueError, match=r"`scales` to have shape"):
        Motion(skeleton, 30, np.zeros((4, 3)), rotations, scales=np.ones((4, 4)))


def test_a_decoder_passes_its_tracks_through():
    skeleton, rotations = rig()
    translations = np.broadcast_to(skeleton.offsets, (4, 4, 3)).copy()
    translations[1, 1, 0] = 3.0
    scales = np.full((4, 4, 3), 2.0)
    motion = Motion.from_decoder(skeleton, 30.0, np.zeros((4, 3)), rotations.copy(), translations, scales)
    assert motion.translations is translations and motion.scales is scales and not scales.flags.writeable
    reference = Motion(skeleton, 30, np.zeros((4, 3)), rotations, translations=translations, scales=scales)
    np.testing.assert_allclose(motion.positions(), reference.positions(), atol=1e-12)
    with pytest.raises(ValueError, match="from_decoder: expected `scales`"):
        Motion.from_decoder(skeleton, 30.0, np.zeros((4, 3)), rotations.copy(), None, scales[:, :2].copy())


def test_replacing_the_root_positions_keeps_the_root_column_of_translations():
    skeleton, rotations = rig()
    translations = np.broadcast_to(skeleton.offsets, (4, 4, 3)).copy()
    translations[:, 1, 2] = 1.0
    motion = Motion(skeleton, 30, np.zeros((4, 3)), rotations, translations=translations)
    moved = dataclasses.replace(motion, root_positions=np.ones((4, 3)))
    np.testing.assert_array_equal(moved.translations[:, 0], 1.0)
    np.testing.assert_allclose(moved.positions(), motion.positions() + 1.0, atol=1e-12)


def test_turning_the_axes_turns_the_tracks():
    skeleton, rotations = rig()
    rng = np.random.default_rng(0)
    translations = np.broadcast_to(skeleton.offsets, (4, 4, 3)) + rng.normal(0, 2, (4, 4, 3))
    scales = np.exp(rng.normal(0, 0.2, (4, 4, 3)))
    rotations = Rotation.random(16, random_state=1).as_quat().reshape(4, 4, 4)
    motion = Motion(skeleton, 30, rng.normal(0, 9, (4, 3)), rotations, translations=translations, scales=scales)
    turn = Rotation.from_euler("x", 90, degrees=True)
    turned = turn_axes(motion, turn, "z")
    np.testing.assert_allclose(turned.positions(), turn.apply(motion.positions().reshape(-1, 3)).reshape(4, 4, 3),
                               atol=1e-9)
    np.testing.assert_allclose(turned.end_site_positions()[:, 0], turn.apply(motion.end_site_positions()[:, 0]),
                               atol=1e-9)
    with pytest.raises(ValueError, match="shear"):
        turn_axes(motion, Rotation.from_euler("x", 30, degrees=True), "z")
