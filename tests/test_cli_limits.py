"""The commands' limits: ``compress --limit`` bounds the input read and never throws an encoding away for want of a
limit; ``inspect`` refuses what ``decompress`` refuses; "out of memory" names the limit that applies, or none."""

from __future__ import annotations

import pytest

from mocapbench.cli import main
from mocapbench.codecs import create
from mocapbench.fuzz import edit_header
from mocapbench.io.gltf import write_gltf
from mocapbench.synthetic import rig_motion, sinusoidal_motion


@pytest.fixture
def gltf_file(tmp_path):
    return write_gltf(rig_motion(num_joints=15, num_frames=40), tmp_path / "rig.glb")


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("mocapbench: error: ")
    return err


def test_compress_reads_its_input_under_its_limits(tmp_path, gltf_file, capsys):
    out = tmp_path / "a.mcb"
    assert main(["compress", str(gltf_file), str(out), "--codec", "quant-rot-zstd", "--limit", "frames=39"]) == 2
    assert "over the limit frames=39" in _one_error_line(capsys) and not out.exists()
    assert main(["compress", str(gltf_file), str(out), "--codec", "quant-rot-zstd", "--limit", "frames=40"]) == 0
    other = tmp_path / "b.mcb"
    assert main(["compress", str(gltf_file), str(other), "--codec", "raw-zstd", "--limit", "bogus=1"]) == 2
    assert "unknown decode limit 'bogus'" in _one_error_line(capsys)


@pytest.mark.parametrize("codec", ["quant-rot-zstd", "mcb-linf"])
def test_compress_checks_its_own_stream_under_the_limits_the_capture_needs(tmp_path, gltf_file, capsys, monkeypatch,
                                                                           codec):
    """A reader that did not check (simulated) hands over a capture above the limits: the stream written is
    still decoded back and measured, not thrown away with advice to pass --limit."""
    import mocapbench.cli.compress as compress
    from mocapbench.codecs.limits import DEFAULT_LIMITS, using_limits

    original = compress.load_motion

    def unchecked(args):
        with using_limits(DEFAULT_LIMITS):
            return original(args)

    monkeypatch.setattr(compress, "load_motion", unchecked)
    out = tmp_path / "a.mcb"
    assert main(["compress", str(gltf_file), str(out), "--codec", codec, "--limit", "output_bytes=1000"]) == 0
    assert "40 frames x 15 joints" in capsys.readouterr().out and out.exists()
    # The stream itself is refused by a decoder held to that limit.
    assert main(["decompress", str(out), str(tmp_path / "a.npy"), "--limit", "output_bytes=1000"]) == 2
    assert "decode limit max_output_bytes exceeded" in _one_error_line(capsys)


@pytest.mark.parametrize("codec", ["dct-spatial-clip", "dwt-spatial-frame", "lsdt-clip"])
def test_inspect_refuses_a_transform_larger_than_the_codec_builds_as_decompress_does(tmp_path, capsys, codec):
    data = create(codec).encode(sinusoidal_motion(num_frames=20))
    stream = tmp_path / "wide.mcb"
    stream.write_bytes(edit_header(data, joints=4096))
    assert main(["inspect", str(stream)]) == 2
    inspected = _one_error_line(capsys)
    assert main(["decompress", str(stream), str(tmp_path / "a.npy")]) == 2
    decompressed = _one_error_line(capsys)
    assert "4096 joints; the spatial transforms take at most 1024" in inspected
    assert "4096 joints; the spatial transforms take at most 1024" in decompressed


def test_inspect_takes_the_limits_of_decompress(tmp_path, capsys):
    stream = tmp_path / "a.mcb"
    stream.write_bytes(create("raw-zstd").encode(rig_motion(num_joints=15, num_frames=20)))
    assert main(["inspect", str(stream)]) == 0
    capsys.readouterr()
    assert main(["inspect", str(stream), "--limit", "frames=19"]) == 2
    assert "decode limit max_frames exceeded" in _one_error_line(capsys)


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["decompress", "in.mcb", "out.npy"], "out of memory under the limit output_bytes=2,147,483,648 bytes"),
        (["decompress", "in.mcb", "out.npy", "--limit", "output_bytes=1e6"], "output_bytes=1,000,000 bytes"),
        (["compress", "in.bvh", "out.mcb", "--codec", "raw-zstd"], "out of memory under the limit output_bytes="),
        (["inspect", "in.mcb"], "out of memory under the limit output_bytes="),
        (["codecs"], "out of memory\n"),
        (["fit", "a.bvh", "-o", "m.npz"], "out of memory\n"),
    ],
)
def test_out_of_memory_names_the_limit_that_applies_or_none(capsys, monkeypatch, argv, expected):
    import importlib

    cli_main = importlib.import_module("mocapbench.cli.main")
    parser = cli_main._parser()

    def exhausted(args):
        raise MemoryError

    original = parser.parse_args
    monkeypatch.setattr(cli_main, "_parser", lambda: parser)
    monkeypatch.setattr(parser, "parse_args", lambda argv: setattr(ns := original(argv), "run", exhausted) or ns)
    assert main(argv) == 2
    err = _one_error_line(capsys)
    assert expected in err
    if "--limit" not in argv and "limit" not in expected:
        assert "--limit" not in err
