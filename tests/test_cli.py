"""The mocapbench command line: compress/decompress/inspect, no overwrite without --force, one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench import metrics
from mocapbench.cli import main
from mocapbench.io import read_bvh, write_bvh


@pytest.fixture
def bvh_file(tmp_path, synthetic_motion):
    path = tmp_path / "walk.bvh"
    write_bvh(synthetic_motion, path)
    return path


def test_compress_decompress_bvh_round_trip(tmp_path, bvh_file, capsys):
    stream = tmp_path / "walk.mcb"
    assert main(["compress", str(bvh_file), str(stream), "--codec", "quant-rot-zstd", "--set", "rotation_bits=14"]) == 0
    assert "bytes" in capsys.readouterr().out
    out = tmp_path / "walk_decoded.bvh"
    assert main(["decompress", str(stream), str(out)]) == 0
    original, decoded = read_bvh(bvh_file), read_bvh(out)
    assert metrics.max_joint_error(original.positions(), decoded.positions()) < 0.2


def test_positions_codec_decompresses_to_npy_not_bvh(tmp_path, bvh_file, capsys):
    stream = tmp_path / "walk.mcb"
    assert main(["compress", str(bvh_file), str(stream), "--codec", "mcb-linf", "--set", "eps_cm=0.5"]) == 0
    assert main(["decompress", str(stream), str(tmp_path / "x.bvh")]) == 2
    assert "codes joint positions only" in capsys.readouterr().err
    assert main(["decompress", str(stream), str(tmp_path / "x.npy")]) == 0
    positions = np.load(tmp_path / "x.npy")
    assert metrics.max_joint_error(read_bvh(bvh_file).positions(), positions) <= 0.5


def test_inspect_prints_header_and_sizes(tmp_path, bvh_file, capsys):
    stream = tmp_path / "walk.mcb"
    main(["compress", str(bvh_file), str(stream), "--codec", "quant-delta-zstd", "--set", "step_cm=0.2"])
    capsys.readouterr()
    assert main(["inspect", str(stream)]) == 0
    out = capsys.readouterr().out
    assert "quant-delta-zstd" in out and "frames" in out and "step_cm" in out and "0.2" in out


def test_existing_output_is_never_overwritten_without_force(tmp_path, bvh_file, capsys):
    stream = tmp_path / "walk.mcb"
    stream.write_bytes(b"precious")
    assert main(["compress", str(bvh_file), str(stream), "--codec", "raw-zstd"]) == 2
    assert "exists; pass --force" in capsys.readouterr().err
    assert stream.read_bytes() == b"precious"
    assert main(["compress", str(bvh_file), str(stream), "--codec", "raw-zstd", "--force"]) == 0
    assert stream.read_bytes() != b"precious"


@pytest.mark.parametrize(
    "argv, message",
    [
        (["compress", "missing.bvh", "o.mcb", "--codec", "raw-zstd"], "no such file"),
        (["compress", "{bvh}", "{tmp}/o.mcb", "--codec", "nope"], "registered codecs are"),
        (["compress", "{bvh}", "{tmp}/o.mcb", "--codec", "raw-zstd", "--set", "level=3"], "config fields are"),
        (["compress", "{bvh}", "{tmp}/o.mcb", "--codec", "quant-delta-zstd", "--set", "step_cm=-1"], "step_cm must be"),
        (["compress", "{bvh}", "{tmp}/o.mcb", "--codec", "raw-zstd", "--set", "oops"], "key=value"),
        (["decompress", "{tmp}/garbage.mcb", "{tmp}/o.npy"], "Not a mocapbench bitstream"),
    ],
)
def test_errors_are_one_line_on_stderr(tmp_path, bvh_file, capsys, argv, message):
    (tmp_path / "garbage.mcb").write_bytes(b"this is not a stream")
    argv = [a.format(bvh=bvh_file, tmp=tmp_path) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err


def test_compress_real_cmu_amc(tmp_path, capsys, cmu_fixture_dir):
    amc = cmu_fixture_dir / "asf_amc" / "09" / "09_06.amc"
    stream = tmp_path / "run.mcb"
    assert main(["compress", str(amc), str(stream), "--codec", "quant-delta-zstd", "--set", "step_cm=0.5"]) == 0
    assert "141 frames x 31 joints" in capsys.readouterr().out


def test_inspect_shows_rotation_codec_parameters(tmp_path, bvh_file, capsys):
    stream = tmp_path / "walk.mcb"
    main(["compress", str(bvh_file), str(stream), "--codec", "quant-rot-zstd", "--set", "rotation_bits=9"])
    capsys.readouterr()
    assert main(["inspect", str(stream)]) == 0
    out = capsys.readouterr().out
    assert "rotation_bits" in out and " 9" in out and "skeleton joints" in out
