"""mcb-rot's translation tracks: the grid keeps every decoded translation within its share of the bound, the header
reads back, second-order differences sum back to the track, hostile headers are BitstreamErrors."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from mocapbench.codecs.mcb_rot.tracks import Tracks, plan_tracks, read_tracks
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from game_rig import game_rig_motion, still_root_rig  # noqa: E402


def _plan(motion, share=0.05):
    return plan_tracks(motion, share, lambda values: int(min(63, np.abs(values).mean())))


def test_the_grid_keeps_every_joint_within_the_tracks_share():
    motion = game_rig_motion(90)
    tracks = _plan(motion)
    assert list(tracks.joints) == [1]
    decoded = tracks.steps_of(motion.skeleton, tracks.q)
    moved = np.sqrt(np.sum((decoded[:, 1] - motion.translations[:, 1]) ** 2, axis=-1)).max()
    assert 0.2 * 0.05 < moved <= tracks.error_cm(motion.skeleton) <= 0.05
    assert np.all(np.sqrt(np.sum(decoded[:, 1] ** 2, axis=-1)) <= tracks.reach[0])
    np.testing.assert_array_equal(decoded[:, 2:], np.broadcast_to(motion.skeleton.offsets[2:], decoded[:, 2:].shape))
    assert tracks.bones_cm(motion.skeleton)[1] == tracks.reach[0]


def test_a_rig_without_translations_has_no_tracks():
    motion = game_rig_motion(30)
    still = type(motion)(motion.skeleton, motion.fps, motion.root_positions, motion.rotations)
    assert _plan(still) is None


def test_header_and_chunk_values_round_trip():
    tracks = _plan(game_rig_motion(90))
    writer = ByteWriter()
    tracks.write(writer)
    read = read_tracks(ByteReader(writer.getvalue()), 22)
    for name in ("joints", "step", "base", "reach", "classes"):
        np.testing.assert_array_equal(getattr(read, name), getattr(tracks, name))
    values = tracks.chunk_values(40, 90)
    np.testing.assert_array_equal(read.q_of_values(values, 50), tracks.q[40:90])
    assert len(tracks.unit_classes(50)) == len(values)


@pytest.mark.parametrize("mutate, match", [
    (lambda b: b[:0] + bytes([0]) + b[1:], "expected 1..21 tracks"),
    (lambda b: b[:1] + bytes([22]) + b[2:], "track's joint must be in 1..21"),
    (lambda b: b[:2] + bytes([1]) + b[3:], "kind 1 is not a translation"),
    (lambda b: b[:3] + np.float32(np.nan).tobytes() + b[7:], "outside the format's range"),
    (lambda b: b[:3] + np.float32(-1).tobytes() + b[7:], "outside the format's range"),
    (lambda b: b[:-1] + bytes([64]), "outside the format's range"),
    (lambda b: b[:-2], "track classes"),
])
def test_a_hostile_header_is_a_bitstream_error(mutate, match):
    writer = ByteWriter()
    _plan(game_rig_motion(30)).write(writer)
    with pytest.raises(BitstreamError, match=match):
        read_tracks(ByteReader(mutate(writer.getvalue())), 22)


@pytest.mark.parametrize("eps", [0.1, 1.0])
def test_a_game_rig_is_within_eps_on_every_joint_and_end_site(eps):
    """The guarantee on a rig whose pelvis moves 1.2 m/s relative to a ground root, with end sites on every chain."""
    from mocapbench.codecs import create

    motion = game_rig_motion(150, seed=6)
    codec = create("mcb-rot", eps_cm=eps)
    data = codec.encode(motion)
    decoded = codec.decode(data)
    joints = np.sqrt(np.sum((decoded.positions - motion.positions()) ** 2, axis=-1))
    ends = np.sqrt(np.sum((decoded.motion.end_site_positions() - motion.end_site_positions()) ** 2, axis=-1))
    assert joints.max() <= eps and ends.max() <= eps
    assert ends.max() > 0.3 * eps  # the end sites are budgeted, not far inside
    assert list(decoded.motion.moving_joints()) == [1]
    moved = np.sqrt(np.sum((decoded.motion.translations[:, 1] - motion.translations[:, 1]) ** 2, axis=-1))
    assert moved.max() <= 0.1 * eps + 1e-9  # the tracks' share of eps
    part = codec.decode_frames(data, 61, 64)
    np.testing.assert_allclose(part.positions, decoded.positions[61:64], atol=1e-9)
    np.testing.assert_allclose(part.motion.translations, decoded.motion.translations[61:64], atol=1e-12)


@pytest.mark.parametrize("rig", [game_rig_motion, still_root_rig], ids=["moving root", "still root"])
def test_a_long_game_rig_capture_is_coded_window_by_window(monkeypatch, rig):
    """Windows of a rig with tracks and of one whose still root is kept apart (flag bit 12): the bound on joints and
    end sites, the whole rig back, parts across a window boundary."""
    from mocapbench.codecs import create
    from mocapbench.codecs.mcb_rot import windowed

    monkeypatch.setattr(windowed, "WINDOW_FRAMES", 128)
    motion = rig(300, seed=7)
    codec = create("mcb-rot", eps_cm=0.5)
    data = codec.encode(motion)
    decoded = codec.decode(data)
    assert np.sqrt(np.sum((decoded.positions - motion.positions()) ** 2, axis=-1)).max() <= 0.5
    ends = decoded.motion.end_site_positions() - motion.end_site_positions()
    assert np.sqrt(np.sum(ends**2, axis=-1)).max() <= 0.5
    assert decoded.motion.skeleton.names == motion.skeleton.names
    part = codec.decode_frames(data, 120, 140)  # across a window boundary
    np.testing.assert_allclose(part.positions, decoded.positions[120:140], atol=1e-9)
    np.testing.assert_allclose(part.motion.translations, decoded.motion.translations[120:140], atol=1e-12)


def test_dropping_the_tracks_would_miss_by_metres():
    """What the checks protect against: the same rotations without the pelvis track put every joint metres away."""
    motion = game_rig_motion(30)
    still = type(motion)(motion.skeleton, motion.fps, motion.root_positions, motion.rotations)
    assert np.sqrt(np.sum((still.positions() - motion.positions())[:, 1:] ** 2, axis=-1)).min() > 100
