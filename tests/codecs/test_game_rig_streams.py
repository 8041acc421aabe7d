"""Hostile streams with the game-rig tracks (translation and scale sections): every mutation of a valid stream of
a codec that carries the tracks decodes to finite positions or raises BitstreamError, within the decode limits and a
few seconds, never another exception (the fuzz harness's mutations, :func:`mocapbench.fuzz.mutations`)."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mocapbench.codecs import CODECS, BitstreamError, DecodeLimits, create
from mocapbench.fuzz import mutations

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from game_rig import game_rig_motion  # noqa: E402

CARRIERS = sorted(name for name in CODECS if "translations" in CODECS[name].carries_tracks)
LIMITS = DecodeLimits(max_frames=10_000, max_joints=256, max_output_bytes=64 << 20)


def test_the_codecs_that_carry_tracks():
    assert "quant-rot-zstd" in CARRIERS


@pytest.mark.parametrize("name", CARRIERS)
def test_mutated_game_rig_streams_end_in_bitstream_error_or_decode(name):
    codec = create(name, **CODECS[name].smoke_params)
    scaled = "scales" in CODECS[name].carries_tracks
    stream = codec.encode(game_rig_motion(40, seed=2, scaled=scaled))
    decoded = 0
    for kind, data in mutations(stream, 300, seed=5):
        started = time.perf_counter()
        try:
            result = codec.decode(data, limits=LIMITS)
        except BitstreamError:
            pass
        else:
            assert np.all(np.isfinite(result.positions)), kind
            decoded += 1
        assert time.perf_counter() - started < 5.0, kind
    assert decoded < 300  # the mutations reach the parsers


def test_every_byte_of_quant_rot_zstds_track_section_is_checked():
    """The section after the rotations (counts, joints, scale step, the tracks' blob): each truncation inside it is a
    BitstreamError; each byte changed (CRC restamped) decodes or is a BitstreamError."""
    from mocapbench.fuzz import restamp

    codec = create("quant-rot-zstd")
    motion = game_rig_motion(30, seed=3, scaled=True)
    stream = codec.encode(motion)
    plain = create("quant-rot-zstd").encode(type(motion)(motion.skeleton, motion.fps, motion.root_positions,
                                                          motion.rotations))
    section = len(stream) - len(plain)  # the rotations' part is the same bytes (cut there: a stream without tracks)
    assert section > 20
    for cut in range(len(stream) - section + 1, len(stream)):
        with pytest.raises(BitstreamError):
            codec.decode(restamp(stream[:cut]))
    for offset in range(len(stream) - section, len(stream)):
        for value in (0, 1, 0x7F, 0xFF):
            data = bytearray(stream)
            data[offset] = value
            try:
                result = codec.decode(restamp(bytes(data)), limits=LIMITS)
            except BitstreamError:
                continue
            assert np.all(np.isfinite(result.positions))


def test_every_byte_of_mcb_rots_tracks_header_is_checked():
    """mcb-rot's tracks header (format 6, flags bit 10; located by its bytes in the stream): each byte changed (CRC
    restamped) decodes to finite positions or is a BitstreamError, never another exception."""
    from mocapbench.codecs.mcb_rot.classes import fit_single
    from mocapbench.codecs.mcb_rot.tracks import plan_tracks
    from mocapbench.entropy.bitio import ByteWriter
    from mocapbench.fuzz import restamp

    motion = game_rig_motion(40, seed=8)
    codec = create("mcb-rot", eps_cm=0.5)
    stream = codec.encode(motion)
    writer = ByteWriter()
    plan_tracks(motion, 0.1 * 0.5, lambda values: fit_single(values, 0.5)).write(writer)
    header = writer.getvalue()
    start = stream.find(header)
    assert start > 0 and stream.count(header) == 1
    for offset in range(start, start + len(header)):
        for value in (0, 1, 0x40, 0x7F, 0xFF):
            data = bytearray(stream)
            data[offset] = value
            try:
                result = codec.decode(restamp(bytes(data)), limits=LIMITS)
            except BitstreamError:
                continue
            assert np.all(np.isfinite(result.positions))
