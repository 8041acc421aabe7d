"""FBX in (ufbx): ASCII FBX files of the synthetic rigs read back with the same joint positions, unit and up axis."""

from __future__ import annotations

import numpy as np
import pytest

from fbx_ascii import write_fbx_ascii
from mocapbench import metrics
from mocapbench.cli import main
from mocapbench.io import read_bvh
from mocapbench.io.fbx import read_fbx
from mocapbench.io.formats import read_motion
from mocapbench.motion import MotionFormatError
from mocapbench.synthetic import rig_motion, user_case


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


def test_moving_bone_is_refused_in_one_line(tmp_path):
    path = write_fbx_ascii(rig_motion(num_joints=15, num_frames=10), tmp_path / "moving.fbx", moving_joint=4)
    with pytest.raises(MotionFormatError, match=r"joint '.*' has an animated translation that moves 5 cm") as error:
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
    assert "z (from the file)" in capsys.readouterr().out
