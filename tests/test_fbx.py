"""FBX in (ufbx): ASCII FBX files of the synthetic rigs read back with the same joint positions, unit and up axis."""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench.io.fbx_ascii import write_fbx_ascii
from mocapbench import metrics
from mocapbench.cli import main
from mocapbench.io import read_bvh
from mocapbench.io.fbx import read_fbx
from mocapbench.io.formats import read_motion
from mocapbench.motion import MotionFormatError
from mocapbench.synthetic import rig_motion, user_case
from mocapbench.synthetic.game import game_rig_motion


@pytest.mark.parametrize("case", ["biped-22-zup-mm-xyz", "biped-52-yup-inch-mixed", "random-33-yup-cmu-yzx"])
def test_fbx_reads_positions_unit_and_axis(tmp_path, case):
    motion = user_case(case).motion
    path = write_fbx_ascii(motion, tmp_path / "rig.fbx", unit_cm=motion.source_unit_cm)
    back = read_fbx(path)
    assert (back.num_frames, back.num_joints, back.fps) == (motion.num_frames, motion.num_joints, motion.fps)
    assert back.skeleton.names == motion.skeleton.names
    assert back.source_unit_cm == pytest.approx(motion.source_unit_cm) and back.up_axis == motion.up_axis
    assert np.abs(back.positions() - motion.positions()).max() < 1e-4  # cm
    np.testing.assert_allclose(back.skeleton.offsets[1:], motion.skeleton.offsets[1:], atol=1e-5)
    # --units overrides the file's unit (lengths scale), and read_motion passes the file's unit and axis on.
    halved = read_fbx(path, length_unit_cm=motion.source_unit_cm / 2)
    np.testing.assert_allclose(halved.positions(), motion.positions() / 2, atol=1e-4)
    read, warnings = read_motion(path)
    assert read.up_axis == motion.up_axis and warnings == [] or "rest height" in warnings[0]


def test_a_moving_bone_is_the_joints_translation(tmp_path):
    motion = rig_motion(num_joints=15, num_frames=10)
    back = read_fbx(write_fbx_ascii(motion, tmp_path / "moving.fbx", moving_joint=4))
    np.testing.assert_array_equal(back.moving_joints(), [4])
    np.testing.assert_allclose(back.translations[:, 4, 0] - motion.skeleton.offsets[4, 0], np.linspace(0, 5, 10),
                               atol=1e-5)


def test_a_game_rig_reads_with_its_tracks(tmp_path):
    """Translated pelvis, stretching spine, scaled chest: the same joint positions and tracks, evaluated with the
    baked keys; they agree with ufbx's own per-frame evaluation of the same nodes."""
    motion = game_rig_motion(num_frames=30, stretch_cm=3.0, scale=1.4, seed=3)
    path = write_fbx_ascii(motion, tmp_path / "game.fbx")
    back = read_fbx(path)
    assert back.fps == 30.0 and back.skeleton.names == motion.skeleton.names
    np.testing.assert_array_equal(back.moving_joints(), motion.moving_joints())
    np.testing.assert_array_equal(back.scaled_joints(), motion.scaled_joints())
    assert np.abs(back.positions() - motion.positions()).max() < 1e-4
    ufbx = pytest.importorskip("ufbx")
    scene = ufbx.load_file(str(path))
    nodes, stacks = list(scene.nodes), list(scene.anim_stacks)  # ufbx 0.0.5: items live while their list lives
    anim = stacks[0].anim
    chest = [node for node in nodes if node.name == motion.skeleton.names[3]][0]
    for frame in (0, 7, 29):
        transform = ufbx.evaluate_transform(anim, chest, frame / 30.0)
        np.testing.assert_allclose(back.scales[frame, 3], list(transform.scale), atol=1e-6)


def test_the_rest_pose_is_the_bind_pose_not_the_saved_frame(tmp_path):
    """Blender saves the current frame as the bones' static transforms; the bind pose is the rest."""
    motion = rig_motion(num_joints=19, num_frames=12, seed=2)
    saved = write_fbx_ascii(motion, tmp_path / "saved.fbx", saved_frame=6)
    bound = write_fbx_ascii(motion, tmp_path / "bound.fbx", saved_frame=6, bind_pose=True)
    for path in (saved, bound):
        np.testing.assert_allclose(read_fbx(path).positions(), motion.positions(), atol=1e-4)
    np.testing.assert_allclose(read_fbx(bound).skeleton.rest_positions(), motion.skeleton.rest_positions(), atol=1e-5)
    assert np.abs(read_fbx(saved).skeleton.rest_positions() - motion.skeleton.rest_positions()).max() > 1.0


def test_a_frame_rate_a_rounding_away_from_an_integer_snaps(tmp_path):
    motion = rig_motion(num_joints=15, num_frames=20, fps=120.0)
    assert read_fbx(write_fbx_ascii(motion, tmp_path / "r.fbx", declared_fps=120.0048)).fps == 120.0
    assert read_fbx(write_fbx_ascii(motion, tmp_path / "n.fbx", declared_fps=119.88)).fps == pytest.approx(119.88)


def test_a_scale_of_zero_is_refused_naming_bone_and_frame(tmp_path):
    motion = game_rig_motion(num_frames=10, scale=1.4, seed=1)
    text = write_fbx_ascii(motion, tmp_path / "zero.fbx").read_text()
    path = tmp_path / "zero.fbx"
    # The chest's Y scale curve: its key 4 set to 0.
    curve = text.split('"AnimCurveNode::S"')[1].split("KeyValueFloat: *10 {\n\t\t\ta: ")[2]
    values = curve.split("\n")[0].split(",")
    values[4] = "0"
    path.write_text(text.replace(curve.split("\n")[0], ",".join(values), 1))
    with pytest.raises(MotionFormatError, match=r"zero.fbx: bone 'Spine1' has scale \[.*, 0.0, .*\] at frame 4; a scale "
                                                "must be > 0") as error:
        read_fbx(path)
    assert "\n" not in str(error.value)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (b"Kaydara FBX Binary  \x00\x1a\x00garbage", "not a readable FBX file"),
        (b"; FBX 7.4.0 project file\nFBXHeaderExtension:  {\n\tFBXHeaderVersion: 1003\n\tFBXVersion: 7400\n}\n",
         "has no skeleton"),
    ],
)
def test_bad_fbx_one_line(tmp_path, data, message):
    path = tmp_path / "bad.fbx"
    path.write_bytes(data)
    with pytest.raises(MotionFormatError, match=message):
        read_fbx(path)


def test_truncated_fbx_never_crashes(tmp_path):
    data = write_fbx_ascii(rig_motion(num_joints=15, num_frames=6), tmp_path / "full.fbx").read_bytes()
    for cut in (10, len(data) // 3, len(data) // 2):
        path = tmp_path / f"cut{cut}.fbx"
        path.write_bytes(data[:cut])
        with pytest.raises(MotionFormatError):
            read_fbx(path)


def test_cli_compresses_fbx(tmp_path, capsys):
    case = user_case("quadruped-40-zup-mm-zxy")
    source = write_fbx_ascii(case.motion, tmp_path / "dog.fbx", unit_cm=0.1)
    stream = tmp_path / "dog.mcb"
    assert main(["compress", str(source), str(stream), "--codec", "quant-rot-zstd"]) == 0
    out = capsys.readouterr().out
    assert "source unit mm, z up" in out
    assert main(["decompress", str(stream), str(tmp_path / "dog.bvh")]) == 0
    back = read_bvh(tmp_path / "dog.bvh", length_unit_cm=0.1)
    assert metrics.max_joint_error(case.motion.positions(), back.positions()) < 1.0
    assert main(["inspect", str(source)]) == 0
    out = capsys.readouterr().out
    assert "z (from the file)" in out and "mm (declared by the file's UnitScaleFactor)" in out


def test_frames_times_bones_over_the_decode_limits_is_refused_before_baking(tmp_path):
    """Key times stretched 10,000 times ask for 10,000x the frames: checked as frames x bones against the decode
    limits before ufbx bakes anything."""
    from mocapbench.codecs.limits import DecodeLimits, using_limits

    path = write_fbx_ascii(rig_motion(num_joints=15, num_frames=6, fps=30.0), tmp_path / "long.fbx")
    head, *curves = path.read_text().split("KeyTime: ")
    rebuilt = head
    for curve in curves:
        count, rest = curve.split(" {\n\t\t\ta: ", 1)
        numbers, tail = rest.split("\n", 1)
        rebuilt += f"KeyTime: {count} {{\n\t\t\ta: " + ",".join(str(int(v) * 10_000) for v in numbers.split(","))
        rebuilt += "\n" + tail
    stop = 5 * 46_186_158_000 // 30
    path.write_text(rebuilt.replace(f'"",{stop}\n', f'"",{stop * 10_000}\n'))
    with using_limits(DecodeLimits(max_output_bytes=10_000_000)):
        with pytest.raises(MotionFormatError, match=r"long.fbx: the file asks for 50,001 frames at 30 fps x 15 joints, "
                                                    r".* over the limit output_bytes=10,000,000"):
            read_fbx(path)
    assert read_fbx(path).num_frames == 50_001  # within the default limits: read, at a cost per frame and bone


@pytest.mark.parametrize("value", ["inf", "nan"])
def test_a_non_finite_key_is_refused_naming_bone_and_frame(tmp_path, value):
    motion = rig_motion(num_joints=15, num_frames=10, fps=30.0)
    text = write_fbx_ascii(motion, tmp_path / "bad.fbx").read_text()
    # Curves in file order: joint 0's rotation (3) and translation (3), then joint 1's rotation: key 4 of its X
    # curve becomes ``value``.
    curves = text.split("KeyValueFloat: *10 {\n\t\t\ta: ")
    index = 1 + 3 * 2
    values = curves[index].split("\n", 1)[0].split(",")
    values[4] = value
    curves[index] = ",".join(values) + "\n" + curves[index].split("\n", 1)[1]
    path = tmp_path / "bad.fbx"
    path.write_text("KeyValueFloat: *10 {\n\t\t\ta: ".join(curves))
    with pytest.raises(MotionFormatError, match=r"bad.fbx: bone '.*' has the rotation \[nan, nan, nan, nan\] at frame 4; "
                                                r"expected a rotation") as error:
        read_fbx(path)
    assert "\n" not in str(error.value)
