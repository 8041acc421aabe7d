"""Units and up axes never fail silently: parsed, recorded in the stream, written back, warned about."""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest

from mocapbench import metrics
from mocapbench.cli import main
from mocapbench.codecs import container
from mocapbench.io import read_bvh
from mocapbench.io.formats import read_motion
from mocapbench.io.units import (
    UNITS_CM,
    canonical_unit_cm,
    detect_up_axis,
    parse_units,
    rest_height_cm,
    rest_height_warning,
    unit_label,
)
from mocapbench.synthetic import rig_motion, user_case, write_case_bvh


@pytest.mark.parametrize(
    ("text", "cm"),
    [("cm", 1.0), ("MM", 0.1), ("m", 100.0), ("inch", 2.54), ("in", 2.54), ("cmu", 2.54 / 0.45), ("5.6444", 5.6444),
     (2.0, 2.0)],
)
def test_parse_units(text, cm):
    assert parse_units(text) == pytest.approx(cm)


@pytest.mark.parametrize("text", ["furlong", "0", "-1", "nan", "inf", "", "1e-45", "1e6"])
def test_bad_units_one_line(text):
    with pytest.raises(ValueError, match="--units") as error:
        parse_units(text)
    assert "\n" not in str(error.value)


def test_unit_labels_survive_float32():
    for name, cm in UNITS_CM.items():
        stored = float(np.float32(cm))
        assert canonical_unit_cm(stored) == cm
        assert unit_label(stored).startswith(name)
    assert unit_label(3.5) == "3.5 cm per unit"


@pytest.mark.parametrize("topology", ["biped", "quadruped"])
@pytest.mark.parametrize("up", ["y", "z"])
def test_up_axis_detected_on_walking_rigs(topology, up):
    motion = rig_motion(topology=topology, up_axis=up, num_joints=40, seed=3)
    axis, reason = detect_up_axis(motion)
    assert axis == up, reason
    assert "root travels" in reason


@pytest.mark.parametrize("up", ["y", "z"])
def test_up_axis_detected_from_the_body_when_standing(up):
    standing = rig_motion(up_axis=up, speed_cm_s=0.0, seed=4)
    axis, reason = detect_up_axis(standing)
    assert axis == up and "root-to-Head direction" in reason
    assert 140 < rest_height_cm(standing.skeleton, up) < 200


def test_rest_height_warning_names_the_height_and_likely_unit(tmp_path):
    case = user_case("biped-70-zup-m-yxz")  # a file in metres: 1.8 "cm" tall when read as cm
    path = write_case_bvh(case, tmp_path / "metres.bvh")
    motion, warnings = read_motion(path)
    assert motion.up_axis == "z" and motion.source_unit_cm == 1.0
    assert len(warnings) == 1 and "\n" not in warnings[0]
    assert "rest height is 1.8 cm along z read as cm" in warnings[0]
    assert "likely in m (180.3 cm tall); pass --units m" in warnings[0]
    right, none = read_motion(path, units="m")
    assert none == [] and right.source_unit_cm == 100.0
    np.testing.assert_allclose(right.positions(), case.motion.positions(), atol=1e-3)
    # Given the wrong axis, the height is measured along it and the warning says so.
    assert "along y" in rest_height_warning(right, "y")


def test_cli_records_unit_and_axis_and_decompress_writes_them_back(tmp_path, capsys):
    case = user_case("biped-22-zup-mm-xyz")
    source = write_case_bvh(case, tmp_path / "mm.bvh")
    stream = tmp_path / "mm.mcb"
    assert main(["compress", str(source), str(stream), "--codec", "quant-rot-zstd", "--units", "mm"]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and "source unit mm, z up" in captured.out
    header, _ = container.read_header(stream.read_bytes())
    assert (header.up_axis, canonical_unit_cm(header.source_unit_cm)) == ("z", 0.1)
    assert main(["inspect", str(stream)]) == 0
    out = capsys.readouterr().out
    assert "source unit" in out and "mm" in out and "up axis" in out
    # Default: the BVH is written in mm, as the source.
    back = tmp_path / "back.bvh"
    assert main(["decompress", str(stream), str(back)]) == 0
    assert "lengths in mm" in capsys.readouterr().out
    source_first = np.array(source.read_text().split("Frame Time:")[1].splitlines()[1].split()[:3], float)
    back_first = np.array(back.read_text().split("Frame Time:")[1].splitlines()[1].split()[:3], float)
    np.testing.assert_allclose(back_first, source_first, atol=0.5)  # mm
    error = metrics.max_joint_error(case.motion.positions(), read_bvh(back, length_unit_cm=0.1).positions())
    assert error < 1.0  # cm of the real body
    # --units cm writes cm (10x smaller numbers), .npy positions follow the same rule.
    assert main(["decompress", str(stream), str(tmp_path / "cm.bvh"), "--units", "cm"]) == 0
    cm_first = np.array((tmp_path / "cm.bvh").read_text().split("Frame Time:")[1].splitlines()[1].split()[:3], float)
    np.testing.assert_allclose(cm_first * 10, source_first, atol=0.5)
    assert main(["decompress", str(stream), str(tmp_path / "mm.npy")]) == 0
    np.testing.assert_allclose(np.load(tmp_path / "mm.npy") * 0.1, case.motion.positions(), atol=1.0)


def test_cli_warns_once_per_file_without_units_and_length_unit_cm_still_works(tmp_path, capsys):
    case = user_case("random-33-yup-cmu-yzx")
    source = write_case_bvh(case, tmp_path / "cmu.bvh")
    stream = tmp_path / "cmu.mcb"
    assert main(["compress", str(source), str(stream), "--codec", "raw-zstd"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mocapbench: warning:") and "--units cmu" in err[0]
    assert main(["compress", str(source), str(stream), "--codec", "raw-zstd", "--length-unit-cm", "5.644444444444445",
                 "--force"]) == 0
    assert capsys.readouterr().err == ""
    header, _ = container.read_header(stream.read_bytes())
    assert canonical_unit_cm(header.source_unit_cm) == UNITS_CM["cmu"]


def test_cli_inspect_motion_file_reports_axis_and_height(tmp_path, capsys):
    source = write_case_bvh(user_case("quadruped-40-zup-mm-zxy"), tmp_path / "dog.bvh")
    assert main(["inspect", str(source), "--units", "mm"]) == 0
    out = capsys.readouterr().out
    assert "up axis      z (detected: the root travels" in out
    assert "rest height  86.6 cm" in out
    assert main(["inspect", str(source), "--units", "mm", "--up", "y"]) == 0
    assert "up axis      y (given)" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--units", "parsec"], "--units 'parsec': expected one of cm, mm, m, inch, cmu"),
        (["--units", "-3"], "--units '-3': a number of cm per unit must be in [0.0001, 100000]"),
    ],
)
def test_cli_bad_units_one_line(tmp_path, capsys, argv, message):
    source = write_case_bvh(user_case("biped-15-yup-cm-zyx"), tmp_path / "a.bvh")
    assert main(["compress", str(source), str(tmp_path / "a.mcb"), "--codec", "raw-zstd", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_version_1_stream_decompresses_in_cm(tmp_path, capsys):
    motion = rig_motion(num_joints=15, num_frames=10, unit="mm")
    from mocapbench.codecs import create

    codec = create("quant-rot-zstd")
    header, payload = container.read_header(codec.encode(motion))
    # The same payload in a version 1 container (no unit, no axis), as streams written before version 2.
    name = header.codec.encode()
    fields = struct.pack("<IHdI", header.num_frames, header.num_joints, header.fps, len(payload))
    body = bytes([len(name)]) + name + fields + bytes(payload)
    old = tmp_path / "old.mcb"
    old.write_bytes(container.MAGIC + bytes([1]) + struct.pack("<I", zlib.crc32(body)) + body)
    assert main(["decompress", str(old), str(tmp_path / "old.bvh")]) == 0
    assert "lengths in cm" in capsys.readouterr().out
    assert main(["inspect", str(old)]) == 0
    assert "cm (format version 1)" in capsys.readouterr().out
