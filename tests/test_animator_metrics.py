"""What animators see, as pure metrics: acceleration error, bone lengths, local rotations, foot sliding."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from mocapbench.metrics.acceleration import acceleration_error, acceleration_errors
from mocapbench.metrics.bones import bone_length_deviation, bone_lengths
from mocapbench.metrics.foot_sliding import (ContactSettings, Contact, contact_travel, find_contacts, foot_joints,
                                             foot_sliding)
from mocapbench.metrics.rotation_error import local_rotation_error, local_rotation_errors

finite = st.floats(min_value=-300, max_value=300, allow_nan=False, allow_infinity=False)


def test_acceleration_error_of_one_displaced_sample():
    reference = np.zeros((5, 2, 3))
    decoded = reference.copy()
    decoded[2, 1, 0] = 0.5  # one joint off by 0.5 cm in the middle frame
    errors = acceleration_errors(reference, decoded, fps=10.0)
    assert errors.shape == (3, 2)
    # second differences at frames 1, 2, 3: +d, -2d, +d, times fps^2 = 100
    np.testing.assert_allclose(errors[:, 1], [50.0, 100.0, 50.0])
    np.testing.assert_allclose(errors[:, 0], 0.0)
    rms, worst = acceleration_error(reference, decoded, fps=10.0)
    assert worst == pytest.approx(100.0)
    assert rms == pytest.approx(np.sqrt((50**2 * 2 + 100**2) / 6))


def test_acceleration_error_is_in_cm_per_s2_at_any_frame_rate():
    """The same per-frame displacement is fps^2 larger in cm/s^2: 25 times from 24 to 120 fps."""
    reference = np.zeros((6, 1, 3))
    decoded = reference.copy()
    decoded[3, 0, 1] = 1.0
    assert acceleration_error(reference, decoded, 120.0)[1] == pytest.approx(25 * acceleration_error(
        reference, decoded, 24.0)[1])


@settings(max_examples=40)
@given(arrays(np.float64, (7, 3, 3), elements=finite), st.tuples(finite, finite, finite),
       st.tuples(finite, finite, finite))
def test_an_offset_moving_at_constant_velocity_adds_no_acceleration(reference, start, velocity):
    frames = np.arange(7)[:, None, None]
    decoded = reference + np.asarray(start) + frames * np.asarray(velocity) / 50.0
    assert acceleration_error(reference, decoded, 30.0)[1] < 1e-6 * 900 * (1 + np.abs(decoded).max())


def test_acceleration_error_of_a_short_clip_is_nan_and_bad_fps_is_refused():
    assert np.isnan(acceleration_error(np.zeros((2, 1, 3)), np.ones((2, 1, 3)), 30.0)).all()
    with pytest.raises(ValueError, match="fps"):
        acceleration_error(np.zeros((4, 1, 3)), np.ones((4, 1, 3)), 0.0)
    with pytest.raises(ValueError, match="shape"):
        acceleration_error(np.zeros((4, 1, 3)), np.ones((4, 2, 3)), 30.0)


def test_bone_lengths_and_one_stretched_bone():
    parents = np.array([-1, 0, 1])
    reference = np.array([[[0, 0, 0], [0, 10, 0], [0, 10, 5]]], dtype=float).repeat(3, axis=0)
    np.testing.assert_allclose(bone_lengths(reference, parents), [[10, 5]] * 3)
    decoded = reference.copy()
    decoded[1, 2, 2] += 2.0  # the second bone 2 cm longer in frame 1
    worst, mean = bone_length_deviation(reference, decoded, parents)
    assert worst == pytest.approx(2.0) and mean == pytest.approx(2.0 / 6)


@settings(max_examples=40)
@given(arrays(np.float64, (4, 5, 3), elements=finite), st.tuples(finite, finite, finite))
def test_a_rigid_translation_keeps_every_bone(reference, shift):
    parents = np.array([-1, 0, 1, 1, 3])
    worst, _ = bone_length_deviation(reference, reference + np.asarray(shift), parents)
    assert worst < 1e-9 * (1 + np.abs(reference).max() + np.abs(shift).max())


def test_bone_lengths_refuse_bad_parents():
    with pytest.raises(ValueError, match="parents"):
        bone_lengths(np.zeros((1, 3, 3)), [0, 0, 1])
    with pytest.raises(ValueError, match="parents"):
        bone_lengths(np.zeros((1, 3, 3)), [-1, 2, 1])


def test_local_rotation_error_of_known_rotations():
    reference = Rotation.from_euler("z", [[0], [30], [45], [90]], degrees=True).as_quat().reshape(2, 2, 4)
    decoded = Rotation.from_euler("z", [[10], [30], [45], [89.5]], degrees=True).as_quat().reshape(2, 2, 4)
    np.testing.assert_allclose(local_rotation_errors(reference, decoded), [[10, 0], [0, 0.5]], atol=1e-9)
    np.testing.assert_allclose(local_rotation_errors(reference, -reference), 0.0, atol=1e-9)  # q and -q agree
    worst, mean = local_rotation_error(reference, decoded)
    assert worst == pytest.approx(10.0) and mean == pytest.approx(10.5 / 4)
    tiny = Rotation.from_euler("x", [[1e-6]], degrees=True).as_quat().reshape(1, 1, 4)
    assert local_rotation_errors(Rotation.identity(1).as_quat().reshape(1, 1, 4), tiny)[0, 0] == pytest.approx(1e-6, rel=1e-6)


def test_local_rotation_error_refuses_bad_shapes():
    with pytest.raises(ValueError, match=r"\(F, J, 4\)"):
        local_rotation_errors(np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="shape of `reference`"):
        local_rotation_errors(np.ones((2, 3, 4)), np.ones((2, 2, 4)))


def _walker(fps=30.0, frames=90):
    """Hips, and one leg per side: ankle and toe; the left foot is planted for frames 0-44, then swings."""
    names = ("Hips", "LeftFoot", "LeftToeBase", "RightFoot", "RightToeBase")
    parents = np.array([-1, 0, 1, 0, 3])
    positions = np.zeros((frames, 5, 3))
    positions[:, 0] = [0, 90, 0]
    positions[:, 1] = [10, 8, 0]
    positions[:, 2] = [10, 2, 12]
    positions[:, 3] = [-10, 8, 0]
    positions[:, 4] = [-10, 2, 12]
    swing = np.arange(frames - 45) / fps
    positions[45:, 1:3, 1] += 20 * np.sin(np.pi * swing / swing[-1])[:, None]  # up in the air
    positions[45:, 1:3, 2] += 100 * swing[:, None]  # forward at 1 m/s
    return names, parents, positions


def test_foot_contacts_are_found_on_known_joint_names():
    names, parents, positions = _walker()
    assert foot_joints(names, parents, positions, "y") == [1, 2, 3, 4]
    contacts = find_contacts(positions, 30.0, [1, 2, 3, 4], "y")
    left = [c for c in contacts if c.joint == 1]
    assert len(left) == 1 and left[0].start == 0 and 44 <= left[0].stop <= 46
    assert [c for c in contacts if c.joint == 3] == [Contact(3, 0, 90)]  # the right foot never moves


def test_foot_sliding_measures_the_decoded_horizontal_travel():
    names, parents, positions = _walker()
    decoded = positions.copy()
    decoded[:45, 1, 0] += np.linspace(0.0, 3.0, 45)  # the planted left ankle slides 3 cm sideways
    decoded[:, 3, 1] += 0.5  # the right ankle lifted 0.5 cm: vertical, not sliding
    sliding = foot_sliding(positions, decoded, 30.0, names, parents, "y")
    travel = dict(zip([c.joint for c in sliding.contacts], sliding.decoded_cm))
    assert travel[1] == pytest.approx(3.0 * min(c.stop for c in sliding.contacts if c.joint == 1) / 45, rel=0.05)
    assert travel[3] == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(sliding.reference_cm, 0.0, atol=1e-9)
    np.testing.assert_allclose(sliding.added_cm, sliding.decoded_cm)


def test_foot_sliding_uses_the_up_axis():
    """The same walker z-up: the 3 cm slide along x is horizontal in both readings."""
    names, parents, positions = _walker()
    z_up = positions[..., [0, 2, 1]]
    decoded = z_up.copy()
    decoded[:45, 1, 0] += np.linspace(0.0, 3.0, 45)
    y_reading = foot_sliding(positions, positions + (decoded - z_up)[..., [0, 2, 1]], 30.0, names, parents, "y")
    z_reading = foot_sliding(z_up, decoded, 30.0, names, parents, "z")
    np.testing.assert_allclose(z_reading.decoded_cm, y_reading.decoded_cm)
    assert len(z_reading.contacts) == len(y_reading.contacts) > 0


def test_foot_joints_fall_back_to_the_lowest_leaves():
    names, parents, positions = _walker()
    renamed = ("root", "a", "b", "c", "d")
    assert foot_joints(renamed, parents, positions, "y") == [1, 2, 3, 4]
    with pytest.raises(ValueError, match="up_axis"):
        foot_joints(renamed, parents, positions, "w")


def test_contact_settings_are_checked_and_change_the_contacts():
    with pytest.raises(ValueError, match="speed_cm_s"):
        ContactSettings(speed_cm_s=0.0)
    with pytest.raises(ValueError, match="floor_percentile"):
        ContactSettings(floor_percentile=80.0)
    names, parents, positions = _walker()
    long_only = find_contacts(positions, 30.0, [1], "y", ContactSettings(min_duration_s=2.0))
    assert long_only == []
    assert contact_travel(positions, [], "y").shape == (0,)
