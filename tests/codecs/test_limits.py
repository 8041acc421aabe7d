"""Decode limits: a stream cannot make a decoder allocate or compute more than the limits allow."""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench.cli import main
from mocapbench.codecs import CODECS, BitstreamError, DecodeLimitError, DecodeLimits, create
from mocapbench.codecs import container
from mocapbench.fuzz import edit_header
from mocapbench.synthetic import sinusoidal_motion

MOTION = sinusoidal_motion(num_frames=24, seed=3)
_STREAMS: dict[str, bytes] = {}


def stream(name: str) -> bytes:
    if name not in _STREAMS:
        _STREAMS[name] = create(name, **CODECS[name].smoke_params).encode(MOTION)
    return _STREAMS[name]


@pytest.mark.parametrize("name", sorted(CODECS))
def test_a_header_frame_count_above_the_output_limit_is_refused_before_decoding(name):
    data = edit_header(stream(name), frames=10_000_000)
    with pytest.raises(DecodeLimitError, match="max_output_bytes") as error:
        create(name, **CODECS[name].smoke_params).decode(data)
    assert error.value.limit == "max_output_bytes" and error.value.value > error.value.allowed
    assert isinstance(error.value, BitstreamError)


@pytest.mark.parametrize("name", sorted(CODECS))
def test_a_header_frame_count_the_payload_cannot_hold_is_refused(name):
    """F edited within the limits (2x, and 1e5): the payload does not match, one BitstreamError."""
    codec = create(name, **CODECS[name].smoke_params)
    for frames in (2 * MOTION.num_frames, 100_000):
        with pytest.raises(BitstreamError):
            codec.decode(edit_header(stream(name), frames=frames))


def test_limits_are_a_setting_of_decode():
    codec = create("raw-zstd")
    data = stream("raw-zstd")
    assert codec.decode(data).positions.shape == (24, 31, 3)
    with pytest.raises(DecodeLimitError, match="max_frames.*23"):
        codec.decode(data, limits=DecodeLimits(max_frames=23))
    with pytest.raises(DecodeLimitError, match="max_joints"):
        codec.decode(data, limits=DecodeLimits(max_joints=30))
    with pytest.raises(DecodeLimitError, match="max_output_bytes"):
        codec.decode(data, limits=DecodeLimits(max_output_bytes=24 * 31 * 24 - 1))


def test_limits_validate_and_parse_settings():
    assert DecodeLimits.from_settings(["output_bytes=8e9", "frames=100"]) == DecodeLimits(
        max_output_bytes=8_000_000_000, max_frames=100
    )
    with pytest.raises(ValueError, match="unknown decode limit 'bytes'"):
        DecodeLimits.from_settings(["bytes=1"])
    with pytest.raises(ValueError, match="NAME=INTEGER"):
        DecodeLimits.from_settings(["frames=1.5"])
    with pytest.raises(ValueError, match="max_frames must be an int >= 1"):
        DecodeLimits(max_frames=0)


def test_pga_ik_iterations_are_capped_in_the_format_and_by_the_limits():
    with pytest.raises(ValueError, match="lm_iterations must be in \\[1, 20\\]"):
        create("pga-ik", lm_iterations=1000)
    data = stream("pga-ik")
    codec = create("pga-ik", **CODECS["pga-ik"].smoke_params)
    with pytest.raises(DecodeLimitError, match="max_ik_iterations"):
        codec.decode(data, limits=DecodeLimits(max_ik_iterations=47))  # 24 frames x 2 iterations = 48


@pytest.mark.parametrize("fps", [5e-324, 1e-4, 1e6, 1e308, float("inf"), float("nan"), -1.0])
def test_the_container_rejects_absurd_fps(fps):
    with pytest.raises(BitstreamError, match="fps"):
        container.read_header(edit_header(stream("raw-zstd"), fps=fps))
    with pytest.raises(ValueError, match="fps must be in"):
        container.pack("raw-zstd", 1, 1, fps, b"")


def test_fixed_transform_streams_carry_a_fingerprint():
    """A DCT stream relabelled as DWT (CRC recomputed) is refused, not decoded to another motion."""
    data = stream("dct-spatial-frame")
    name_at = container._PREFIX.size + 1
    relabelled = bytearray(data)
    relabelled[name_at : name_at + 3] = b"dwt"
    from mocapbench.fuzz import restamp

    with pytest.raises(BitstreamError, match="coded with bases"):
        create("dwt-spatial-frame").decode(restamp(bytes(relabelled)))


def test_spatial_transforms_check_the_joint_count_before_building_a_basis():
    data = edit_header(stream("dct-spatial-clip"), joints=4096)
    with pytest.raises(BitstreamError, match="at most 1024"):
        create("dct-spatial-clip").decode(data)


def test_cli_decode_limit_is_one_line(tmp_path, capsys):
    path = tmp_path / "s.mcb"
    path.write_bytes(stream("raw-zstd"))
    assert main(["decompress", str(path), str(tmp_path / "o.npy"), "--limit", "frames=10"]) == 2
    err = capsys.readouterr().err
    assert "decode limit max_frames exceeded" in err and err.count("\n") == 1
    assert main(["decompress", str(path), str(tmp_path / "o.npy"), "--limit", "frames=24"]) == 0
    assert np.load(tmp_path / "o.npy").shape == (24, 31, 3)
