"""BVH reading and writing: hand-computed FK, round trips, every malformed input named by file and line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapbench.io import MotionFileNotFoundError
from mocapbench.io.asf_amc import CMU_CM_PER_UNIT
from mocapbench.io.bvh import read_bvh, write_bvh
from mocapbench.motion import Motion, MotionFormatError
from mocapbench.synthetic import sinusoidal_motion

FIXTURES = Path(__file__).parent / "fixtures"
CHAIN = FIXTURES / "chain3.bvh"  # 3 joints A > B > C, an end site, 2 frames; see the file for line numbers


def variant(tmp_path: Path, old: str, new: str, *, source: Path = CHAIN) -> Path:
    """A copy of ``source`` in ``tmp_path`` with the first ``old`` replaced by ``new``."""
    text = source.read_text()
    assert old in text, f"fixture text {old!r} not found"
    path = tmp_path / source.name
    path.write_text(text.replace(old, new, 1))
    return path


# --- hand-computed forward kinematics -------------------------------------------------------------------


def test_chain_positions_by_hand():
    motion = read_bvh(CHAIN)
    assert motion.skeleton.names == ("A", "B", "C")
    assert motion.skeleton.parents.tolist() == [-1, 0, 1]
    assert motion.num_frames == 2
    assert motion.fps == 30.0  # "Frame Time: 0.0333333" is 1/30 printed with 7 decimals
    expected = np.array(
        [
            # frame 0: root at (1, 2, 3) turned 90 deg about Z (x -> y, y -> -x)
            [[1, 2, 3], [-9, 2, 3], [-9, 7, 3]],
            # frame 1: B = Rz(90) @ Rx(90) (listed order = multiplication order): C's offset (5, 0, 0) -> (0, 5, 0)
            [[0, 0, 0], [0, 10, 0], [0, 15, 0]],
        ],
        dtype=float,
    )
    np.testing.assert_allclose(motion.positions(), expected, atol=1e-9)
    np.testing.assert_allclose(motion.end_site_positions(), [[[-11, 7, 3]], [[0, 15, 2]]], atol=1e-9)


def test_chain_rotation_is_intrinsic_in_listed_order():
    motion = read_bvh(CHAIN)
    rz, rx = Rotation.from_euler("z", 90, degrees=True), Rotation.from_euler("x", 90, degrees=True)
    local_b = Rotation.from_quat(motion.rotations[1, 1])
    assert (local_b * (rz * rx).inv()).magnitude() < 1e-12
    assert (local_b * (rx * rz).inv()).magnitude() > 1.0  # the other order is a different rotation


def test_length_unit_scales_offsets_and_root_but_not_angles():
    plain, scaled = read_bvh(CHAIN), read_bvh(CHAIN, length_unit_cm=2.5)
    np.testing.assert_allclose(scaled.skeleton.offsets, 2.5 * plain.skeleton.offsets)
    np.testing.assert_allclose(scaled.skeleton.end_site_offsets, 2.5 * plain.skeleton.end_site_offsets)
    np.testing.assert_allclose(scaled.positions(), 2.5 * plain.positions(), atol=1e-12)
    np.testing.assert_array_equal(scaled.rotations, plain.rotations)


def test_any_channel_order_and_root_position_order(tmp_path):
    path = variant(
        tmp_path,
        "CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation ",
        "CHANNELS 6 Zposition Xposition Yposition Xrotation Zrotation Yrotation",
    )
    motion = read_bvh(path)
    assert motion.skeleton.channel_orders == ("XZY", "ZYX", "ZYX")
    # frame 0 values "1 2 3 90 0 0" now mean z=1, x=2, y=3, Rx(90) @ Rz(0) @ Ry(0)
    np.testing.assert_allclose(motion.root_positions[0], [2, 3, 1])
    expected = Rotation.from_euler("XZY", [90, 0, 0], degrees=True)
    assert (Rotation.from_quat(motion.rotations[0, 0]) * expected.inv()).magnitude() < 1e-12
    written = write_bvh(motion, tmp_path / "out.bvh")
    assert "CHANNELS 6 Xposition Yposition Zposition Xrotation Zrotation Yrotation" in written.read_text()
    np.testing.assert_allclose(read_bvh(written).positions(), motion.positions(), atol=1e-6)


def test_root_without_position_channels_stays_at_its_offset(tmp_path):
    path = variant(tmp_path, "OFFSET 0 0 0\n\tCHANNELS 6 Xposition Yposition Zposition", "OFFSET 4 5 6\n\tCHANNELS 3")
    path.write_text(path.read_text().replace("1 2 3 90 0 0 0", "90 0 0 0").replace("0 0 0 0 0 0 90", "0 0 0 90"))
    motion = read_bvh(path)
    np.testing.assert_allclose(motion.root_positions, [[4, 5, 6], [4, 5, 6]])


def test_crlf_line_endings(tmp_path):
    path = tmp_path / "crlf.bvh"
    path.write_bytes(CHAIN.read_text().replace("\n", "\r\n").encode())
    np.testing.assert_allclose(read_bvh(path).positions(), read_bvh(CHAIN).positions(), atol=1e-12)
    path.write_bytes(CHAIN.read_text().replace("\n", "\r\n").replace("90 0 90 0 0 0", "90 0 90 0 x 0").encode())
    with pytest.raises(MotionFormatError, match=r"line 25: expected a number, got 'x'"):
        read_bvh(path)


def test_drop_first_frame_and_name(tmp_path):
    motion = read_bvh(CHAIN, drop_first_frame=True, name="clip")
    assert motion.num_frames == 1 and motion.name == "clip"
    np.testing.assert_allclose(motion.positions()[0, 2], [0, 15, 0], atol=1e-9)
    assert read_bvh(CHAIN).name == "chain3"


# --- writing and round trips ------------------------------------------------------------------------------


def test_synthetic_round_trip(tmp_path):
    motion = sinusoidal_motion(num_frames=200, amplitude_deg=60)
    path = write_bvh(motion, tmp_path / "synthetic.bvh")
    back = read_bvh(path)
    assert back.skeleton.names == motion.skeleton.names
    assert np.array_equal(back.skeleton.parents, motion.skeleton.parents)
    assert back.skeleton.channel_orders == motion.skeleton.channel_orders
    np.testing.assert_array_equal(back.skeleton.end_site_parents, motion.skeleton.end_site_parents)
    np.testing.assert_allclose(back.skeleton.end_site_offsets, motion.skeleton.end_site_offsets, atol=1e-6)
    assert back.fps == motion.fps and back.num_frames == motion.num_frames
    assert np.abs(back.positions() - motion.positions()).max() < 1e-3
    assert np.abs(back.end_site_positions() - motion.end_site_positions()).max() < 1e-3


def test_round_trip_in_other_units(tmp_path):
    motion = sinusoidal_motion(num_frames=50)
    path = write_bvh(motion, tmp_path / "inches.bvh", length_unit_cm=2.54)
    first_offset = path.read_text().split("OFFSET", 3)[3].split()[:3]  # third joint: LeftUpLeg (9, -8, 0) cm
    np.testing.assert_allclose([float(v) for v in first_offset], np.array([9.0, -8.0, 0.0]) / 2.54, atol=1e-6)
    back = read_bvh(path, length_unit_cm=2.54)
    assert np.abs(back.positions() - motion.positions()).max() < 1e-3


def test_round_trip_through_gimbal_lock(tmp_path):
    motion = sinusoidal_motion(num_frames=4)
    rotations = motion.rotations.copy()
    rotations[:, 3] = Rotation.from_euler("ZYX", [30, 90, -20], degrees=True).as_quat()  # Y = 90: gimbal lock
    locked = Motion(motion.skeleton, motion.fps, motion.root_positions, rotations, motion.name)
    back = read_bvh(write_bvh(locked, tmp_path / "lock.bvh"))
    assert np.abs(back.positions() - locked.positions()).max() < 1e-3


def test_writer_refuses_to_overwrite(tmp_path):
    motion = sinusoidal_motion(num_frames=3)
    path = write_bvh(motion, tmp_path / "out.bvh")
    before = path.read_text()
    with pytest.raises(FileExistsError, match="out.bvh exists"):
        write_bvh(sinusoidal_motion(num_frames=5), path)
    assert path.read_text() == before
    write_bvh(sinusoidal_motion(num_frames=5), path, overwrite=True)
    assert read_bvh(path).num_frames == 5


def test_real_clip_round_trip(cmu_fixture_dir, tmp_path):
    motion = read_bvh(cmu_fixture_dir / "bvh" / "09_06.bvh", length_unit_cm=CMU_CM_PER_UNIT)
    back = read_bvh(
        write_bvh(motion, tmp_path / "09_06.bvh", length_unit_cm=CMU_CM_PER_UNIT), length_unit_cm=CMU_CM_PER_UNIT
    )
    assert back.skeleton.names == motion.skeleton.names and back.num_frames == motion.num_frames == 142
    assert np.abs(back.positions() - motion.positions()).max() < 1e-3
    assert np.abs(back.end_site_positions() - motion.end_site_positions()).max() < 1e-3


def test_real_clip_layout(cmu_fixture_dir):
    """The CMU file: trailing space after the root CHANNELS, 31 joints, 7 end sites, 120 fps, frame 0 a T pose."""
    full = read_bvh(cmu_fixture_dir / "bvh" / "09_06.bvh")
    dropped = read_bvh(cmu_fixture_dir / "bvh" / "09_06.bvh", drop_first_frame=True)
    assert full.num_joints == 31 and len(full.skeleton.end_site_parents) == 7
    assert full.fps == 120.0 and full.num_frames == 142 and dropped.num_frames == 141
    assert set(full.skeleton.channel_orders) == {"ZYX"}
    np.testing.assert_array_equal(dropped.rotations, full.rotations[1:])
    assert full.name == "09_06"
    assert full.translations is None and full.scales is None  # position channels on the root only: no track


# --- malformed input -------------------------------------------------------------------------------------


def test_missing_file(tmp_path):
    with pytest.raises(MotionFormatError, match=r"nothing\.bvh: BVH file does not exist"):
        read_bvh(tmp_path / "nothing.bvh")
    with pytest.raises(FileNotFoundError):  # the same error is a FileNotFoundError too
        read_bvh(tmp_path / "nothing.bvh")
    assert issubclass(MotionFileNotFoundError, MotionFormatError)


def test_empty_file(tmp_path):
    (tmp_path / "empty.bvh").write_text("  \n\n")
    with pytest.raises(MotionFormatError, match=r"empty\.bvh: the BVH file is empty"):
        read_bvh(tmp_path / "empty.bvh")


def test_no_hierarchy(tmp_path):
    path = variant(tmp_path, "HIERARCHY\n", "")
    with pytest.raises(MotionFormatError, match=r"chain3\.bvh: line 1: expected 'HIERARCHY'.*got 'ROOT'"):
        read_bvh(path)


def test_no_motion_section(tmp_path):
    path = tmp_path / "chain3.bvh"
    path.write_text(CHAIN.read_text().split("MOTION")[0])
    with pytest.raises(MotionFormatError, match=r"chain3\.bvh: no MOTION section"):
        read_bvh(path)


@pytest.mark.parametrize(
    ("frames", "message"),
    [
        ("3", r"line 22: 'Frames: 3' but the MOTION section has 2 data lines \(lines 24-25\)"),
        ("1", r"line 22: 'Frames: 1' but the MOTION section has 2 data lines"),
    ],
)
def test_frames_count_disagrees(tmp_path, frames, message):
    path = variant(tmp_path, "Frames: 2", f"Frames: {frames}")
    with pytest.raises(MotionFormatError, match=message):
        read_bvh(path)


def test_truncated_data_is_not_silently_shortened(tmp_path):
    path = tmp_path / "chain3.bvh"
    path.write_text(CHAIN.read_text().rsplit("0 0 0 0 0 0 90", 1)[0])  # last line lost
    with pytest.raises(MotionFormatError, match=r"line 22: 'Frames: 2' but the MOTION section has 1 data lines"):
        read_bvh(path)


def test_zero_frames(tmp_path):
    path = tmp_path / "chain3.bvh"
    path.write_text(CHAIN.read_text().split("Frames:")[0] + "Frames: 0\nFrame Time: 0.0333333\n")
    with pytest.raises(MotionFormatError, match=r"line 22: 'Frames: 0'; a motion needs at least one frame"):
        read_bvh(path)


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("1 2 3 90 0 0 0 0 0 0 0", r"line 24: expected 12 values \(the channels of the HIERARCHY\), got 11"),
        ("1 2 3 90 0 0 0 0 0 0 0 0 7", r"line 24: expected 12 values .*got 13"),
    ],
)
def test_wrong_value_count_names_the_line(tmp_path, line, message):
    path = variant(tmp_path, "1 2 3 90 0 0 0 0 0 0 0 0", line)
    with pytest.raises(MotionFormatError, match=message):
        read_bvh(path)


@pytest.mark.parametrize("token", ["abc", "0x1A", "1.5d", "1,5", "1_0", "--1", "1e"])
def test_non_numeric_token_names_the_line(tmp_path, token):
    path = variant(tmp_path, "0 0 0 0 0 0 90 0 90 0 0 0", f"0 0 0 0 0 0 90 {token} 90 0 0 0")
    with pytest.raises(MotionFormatError, match=rf"line 25: expected a number, got '{token}'"):
        read_bvh(path)


@pytest.mark.parametrize("token", ["nan", "NaN", "inf", "-inf"])
def test_non_finite_value_names_the_line(tmp_path, token):
    path = variant(tmp_path, "0 0 0 0 0 0 90 0 90 0 0 0", f"0 0 0 0 0 0 90 0 90 0 {token} 0")
    with pytest.raises(MotionFormatError, match=r"line 25: expected finite numbers, got .*\(value 11 of 12\)"):
        read_bvh(path)


def test_unknown_channel_name(tmp_path):
    path = variant(tmp_path, "CHANNELS 3 Zrotation Yrotation Xrotation", "CHANNELS 3 Zrotation Wrotation Xrotation")
    with pytest.raises(MotionFormatError, match=r"line 9: unknown channel name 'Wrotation' in joint 'B'"):
        read_bvh(path)


def test_channel_count_disagrees_with_names(tmp_path):
    path = variant(tmp_path, "CHANNELS 3 Zrotation Yrotation Xrotation", "CHANNELS 3 Zrotation Yrotation")
    with pytest.raises(MotionFormatError, match=r"line 9: CHANNELS announces 3 channels for joint 'B' but names 2"):
        read_bvh(path)


def test_a_moving_position_channel_below_the_root_is_the_joints_translation(tmp_path):
    # B's OFFSET x is 0; its new Xposition channel takes the old Zrotation column: 0 on frame 0, 90 on frame 1.
    path = variant(tmp_path, "CHANNELS 3 Zrotation Yrotation Xrotation", "CHANNELS 3 Xposition Yrotation Xrotation")
    motion = read_bvh(path)
    np.testing.assert_array_equal(motion.moving_joints(), [1])
    np.testing.assert_allclose(motion.translations[:, 1], [[0, 10, 0], [90, 10, 0]])  # Y, Z from the OFFSET
    # Frame 1: B at (90, 10, 0) turned Rx(90): C's offset (5, 0, 0) stays along x, the end site's (0, 2, 0) -> +z.
    np.testing.assert_allclose(motion.positions(), [[[1, 2, 3], [-9, 2, 3], [-9, 7, 3]],
                                                    [[0, 0, 0], [90, 10, 0], [95, 10, 0]]], atol=1e-9)
    np.testing.assert_allclose(motion.end_site_positions()[:, 0], [[-11, 7, 3], [95, 10, 2]], atol=1e-9)
    again = read_bvh(write_bvh(motion, tmp_path / "again.bvh"))
    assert again.skeleton.channel_orders == motion.skeleton.channel_orders
    np.testing.assert_allclose(again.translations, motion.translations, atol=1e-6)
    np.testing.assert_allclose(again.positions(), motion.positions(), atol=1e-5)


def test_a_motion_bvh_cannot_hold_is_refused_naming_joint_and_frame(tmp_path):
    motion = read_bvh(variant(tmp_path, "CHANNELS 3 Zrotation Yrotation Xrotation",
                              "CHANNELS 3 Xposition Yrotation Xrotation"))
    with pytest.raises(MotionFormatError, match=r"root.bvh: joint 'B' moves \(translation \[90.0, 10.0, 0.0\] cm at "
                                                r"frame 1, .*position_channels='root' cannot hold it"):
        write_bvh(motion, tmp_path / "root.bvh", position_channels="root")
    scales = np.ones((2, 3, 3))
    scales[1, 2] = [1, 1, 0.5]
    scaled = Motion(motion.skeleton, motion.fps, motion.root_positions, motion.rotations, scales=scales)
    with pytest.raises(MotionFormatError, match=r"scaled.bvh: joint 'C' has scale \[1.0, 1.0, 0.5\] at frame 1; "
                                                "BVH has no scale channel"):
        write_bvh(scaled, tmp_path / "scaled.bvh")
    assert not (tmp_path / "scaled.bvh").exists() and not (tmp_path / "root.bvh").exists()


def test_position_channels_that_stay_at_the_offset_are_folded_away(tmp_path):
    path = variant(tmp_path, "CHANNELS 3 Zrotation Yrotation Xrotation\n\t\tJOINT C",
                   "CHANNELS 5 Yposition Zrotation Xposition Yrotation Xrotation\n\t\tJOINT C")
    text = path.read_text().replace("1 2 3 90 0 0 0 0 0", "1 2 3 90 0 0 10.00001 0 0 0 0").replace(
        "0 0 0 0 0 0 90 0 90", "0 0 0 0 0 0 10 90 0 0 90")
    path.write_text(text)
    folded = read_bvh(path)
    reference = read_bvh(CHAIN)
    assert folded.translations is None
    np.testing.assert_allclose(folded.positions(), reference.positions(), atol=1e-9)
    assert folded.skeleton.channel_orders == reference.skeleton.channel_orders


def test_every_joint_with_position_channels_round_trips(tmp_path):
    motion = sinusoidal_motion(num_frames=30, seed=2)
    path = write_bvh(motion, tmp_path / "mobu.bvh", position_channels="all")
    assert path.read_text().count("CHANNELS 6") == motion.num_joints
    back = read_bvh(path)
    np.testing.assert_allclose(back.positions(), motion.positions(), atol=1e-3)


def test_a_hierarchy_thousands_deep_reads_and_writes_without_recursion(tmp_path):
    depth = 3000
    lines = ["HIERARCHY"] + [f"{'ROOT' if j == 0 else 'JOINT'} j{j}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Yrotation "
                              f"Xrotation" for j in range(depth)] + ["}"] * depth
    values = " ".join(["1"] * (3 * depth))
    (tmp_path / "deep.bvh").write_text("\n".join(lines) + f"\nMOTION\nFrames: 2\nFrame Time: 0.01\n{values}\n{values}\n")
    motion = read_bvh(tmp_path / "deep.bvh")
    assert motion.num_joints == depth and motion.skeleton.parents[-1] == depth - 2
    again = read_bvh(write_bvh(motion, tmp_path / "again.bvh"))
    np.testing.assert_allclose(again.positions(), motion.positions(), atol=1e-3)


def test_more_joints_than_the_limit_is_one_line(tmp_path):
    lines = ["HIERARCHY", "ROOT r", "{", "OFFSET 0 0 0", "CHANNELS 3 Zrotation Yrotation Xrotation"]
    lines += [f"JOINT j{j}\n{{\nOFFSET 0 1 0\n}}" for j in range(4096)] + ["}", "MOTION", "Frames: 1",
                                                                         "Frame Time: 0.01", "0 0 0"]
    (tmp_path / "wide.bvh").write_text("\n".join(lines) + "\n")
    with pytest.raises(MotionFormatError, match=r"more than 4096 joints"):
        read_bvh(tmp_path / "wide.bvh")


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        *[("Frame Time: 0.0333333", f"Frame Time: {t}", rf"line 23: expected a frame time in \[1e-05, 1000\] s .*{t}")
          for t in ("5e-324", "1e-6", "1e308", "2000")],
        # A frame count the file's bytes cannot hold allocates nothing big and names the real count.
        ("Frames: 2", "Frames: 1000000000000", r"'Frames: 1000000000000' but the MOTION section has 2 data lines"),
    ],
)
def test_absurd_motion_header_values_are_one_line(tmp_path, old, new, message):
    with pytest.raises(MotionFormatError, match=message):
        read_bvh(variant(tmp_path, old, new))


def test_bytes_that_are_not_text_in_the_hierarchy(tmp_path):
    path = tmp_path / "binary.bvh"
    path.write_bytes(CHAIN.read_bytes().replace(b"ROOT A", b"ROOT \xff\xfe"))
    with pytest.raises(MotionFormatError, match=r"line 2 \(invalid start byte\)"):
        read_bvh(path)


def test_missing_closing_brace(tmp_path):
    path = variant(tmp_path, "\t\t\t}\n\t\t}\n", "\t\t\t}\n")  # C's block never closes
    with pytest.raises(MotionFormatError, match=r"line 20: expected '}' closing joint 'A' \(opened at line 3\)"):
        read_bvh(path)


def test_extra_closing_brace(tmp_path):
    path = variant(tmp_path, "}\nMOTION", "}\n}\nMOTION")
    with pytest.raises(MotionFormatError, match=r"line 21: unbalanced braces: this '}' closes nothing"):
        read_bvh(path)


def test_missing_offset(tmp_path):
    path = variant(tmp_path, "\t\tOFFSET 0 10 0\n", "")
    with pytest.raises(MotionFormatError, match=r"line 6: joint 'B' has no OFFSET"):
        read_bvh(path)


def test_bad_offset(tmp_path):
    path = variant(tmp_path, "OFFSET 0 10 0", "OFFSET 0 ten 0")
    with pytest.raises(MotionFormatError, match=r"line 8: expected 3 numbers after OFFSET"):
        read_bvh(path)


def test_bad_frame_time(tmp_path):
    path = variant(tmp_path, "Frame Time: 0.0333333", "Frame Time: 0")
    with pytest.raises(MotionFormatError, match=r"line 23: expected a frame time in seconds > 0, got '0'"):
        read_bvh(path)


def test_missing_frames_line(tmp_path):
    path = variant(tmp_path, "Frames: 2\n", "")
    with pytest.raises(MotionFormatError, match=r"line 22: expected 'Frames: <number>', got 'Frame Time: 0.0333333'"):
        read_bvh(path)


def test_drop_first_frame_needs_two_frames(tmp_path):
    path = tmp_path / "one.bvh"
    path.write_text(CHAIN.read_text().replace("Frames: 2", "Frames: 1").rsplit("0 0 0 0 0 0 90", 1)[0])
    assert read_bvh(path).num_frames == 1
    with pytest.raises(MotionFormatError, match=r"line 22: drop_first_frame needs 2 frames or more"):
        read_bvh(path, drop_first_frame=True)


def test_bad_length_unit():
    with pytest.raises(ValueError, match="`length_unit_cm` must be a finite number > 0, got 0"):
        read_bvh(CHAIN, length_unit_cm=0)


def test_frames_times_joints_over_the_decode_limits_is_one_line(tmp_path):
    """The reader checks the motion it would build against the current decode limits before allocating it."""
    from mocapbench.codecs.limits import DecodeLimits, using_limits

    path = write_bvh(sinusoidal_motion(num_frames=50, seed=1), tmp_path / "m.bvh")
    with using_limits(DecodeLimits(max_output_bytes=50 * 31 * 56 - 1)):
        with pytest.raises(MotionFormatError, match=r"m.bvh: line \d+: the file asks for 50 frames x 31 joints, .* over "
                                                    r"the limit output_bytes=.*--limit output_bytes=N"):
            read_bvh(path)
    with using_limits(DecodeLimits(max_output_bytes=50 * 31 * 56 + 24 * 50)):
        assert read_bvh(path).num_frames == 50
