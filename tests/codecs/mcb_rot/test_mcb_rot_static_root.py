"""mcb-rot's still root (flags bit 12): a rig whose root never moves codes its pelvis as the root, the bound holds on
every joint and end site, the whole rig decodes back (names, offsets, the still root), hostile sections and flags
are BitstreamErrors."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from mocapbench.codecs import create
from mocapbench.codecs.base import Header
from mocapbench.codecs.container import unpack
from mocapbench.codecs.mcb_rot.static_root import read_static_root, split_static_root
from mocapbench.codecs.mcb_rot.stream import Settings, read_info
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.motion import Motion

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from game_rig import game_rig_motion, still_root_rig  # noqa: E402


def _errors(decoded, motion):
    joints = np.sqrt(np.sum((decoded.positions - motion.positions()) ** 2, axis=-1))
    ends = np.sqrt(np.sum((decoded.motion.end_site_positions() - motion.end_site_positions()) ** 2, axis=-1))
    return joints, ends


def test_the_split_keeps_every_joint_but_the_root():
    motion = still_root_rig(40, position=(1.5, 0.0, -2.25))
    still, inner = split_static_root(motion)
    assert still.name == "joint_Root" and inner.num_joints == motion.num_joints - 1
    np.testing.assert_array_equal(still.position, [1.5, 0.0, -2.25])
    np.testing.assert_allclose(inner.positions(), motion.positions()[:, 1:], atol=1e-9)
    np.testing.assert_allclose(inner.end_site_positions(), motion.end_site_positions(), atol=1e-9)
    assert inner.translations is None  # the pelvis is the root now: no joint below it moves


@pytest.mark.parametrize("change", ["moving root", "turning root", "still pelvis", "off-grid position"])
def test_a_root_that_is_not_still_is_coded_as_before(change):
    motion = still_root_rig(30)
    roots, rotations, translations = motion.root_positions.copy(), motion.rotations.copy(), motion.translations
    if change == "moving root":
        roots[5, 0] += 0.25
    elif change == "turning root":
        rotations[:, 0] = (0.0, np.sin(0.05), 0.0, np.cos(0.05))
    elif change == "still pelvis":
        translations = None
    else:
        roots[:] = 0.1  # not a float32 value
    assert split_static_root(Motion(motion.skeleton, motion.fps, roots, rotations, translations=translations)) is None


@pytest.mark.parametrize("eps", [0.1, 1.0])
def test_a_still_root_rig_is_within_eps_and_decodes_whole(eps):
    motion = still_root_rig(150, position=(0.0, 0.0, 3.0))
    codec = create("mcb-rot", eps_cm=eps)
    data = codec.encode(motion)
    header, payload = unpack(data, "mcb-rot")
    info = read_info(header, payload)
    assert info.settings.static_root and info.tracks is None and info.skeleton.num_joints == motion.num_joints - 1
    decoded = codec.decode(data)
    joints, ends = _errors(decoded, motion)
    assert joints.max() <= eps and ends.max() <= eps
    assert joints.max() > 0.3 * eps  # the bound is used, not far inside
    assert joints[:, 0].max() == 0.0  # the still root is exact
    skeleton = decoded.motion.skeleton
    assert skeleton.names == motion.skeleton.names and skeleton.channel_orders == motion.skeleton.channel_orders
    np.testing.assert_array_equal(skeleton.parents, motion.skeleton.parents)
    np.testing.assert_array_equal(skeleton.end_site_parents, motion.skeleton.end_site_parents)
    np.testing.assert_array_equal(decoded.motion.root_positions, motion.root_positions)
    np.testing.assert_array_equal(decoded.motion.rotations[:, 0], np.broadcast_to([0, 0, 0, 1.0], (150, 4)))
    assert list(decoded.motion.moving_joints()) == [1]
    pelvis = np.sqrt(np.sum((decoded.motion.translations[:, 1] - motion.translations[:, 1]) ** 2, axis=-1))
    assert pelvis.max() <= eps
    part = codec.decode_frames(data, 61, 64)
    np.testing.assert_allclose(part.positions, decoded.positions[61:64], atol=1e-9)
    np.testing.assert_allclose(part.motion.translations, decoded.motion.translations[61:64], atol=1e-12)


def test_without_the_flag_the_rig_is_coded_with_tracks_and_the_same_bound():
    motion = still_root_rig(90)
    codec = create("mcb-rot", eps_cm=0.5, static_root=False)
    data = codec.encode(motion)
    header, payload = unpack(data, "mcb-rot")
    info = read_info(header, payload)
    assert not info.settings.static_root and list(info.tracks.joints) == [1]
    joints, ends = _errors(codec.decode(data), motion)
    assert joints.max() <= 0.5 and ends.max() <= 0.5


def _section() -> bytes:
    still, _ = split_static_root(still_root_rig(10))
    writer = ByteWriter()
    still.write(writer)
    return writer.getvalue()


def test_the_section_reads_back():
    still = read_static_root(ByteReader(_section()))
    assert still.name == "joint_Root" and still.order == game_rig_motion(2).skeleton.channel_orders[0]
    np.testing.assert_array_equal(still.position, 0.0)


@pytest.mark.parametrize("mutate, match", [
    (lambda b: bytes([0]) + b[11:], "1..255 bytes"),
    (lambda b: bytes([200]) + b[1:], "static root name"),
    (lambda b: b[:1] + b"joint\0Root" + b[11:], "without NUL"),
    (lambda b: b[:1] + b"\xff" + b[2:], "not UTF-8"),
    (lambda b: b[:11] + bytes([6]) + b[12:], "channel order index must be < 6"),
    (lambda b: b[:12] + np.float32(np.nan).tobytes() + b[16:], "not finite or beyond"),
    (lambda b: b[:-4] + np.float32(3e7).tobytes(), "not finite or beyond"),
    (lambda b: b[:-2], "static root position"),
])
def test_a_hostile_section_is_a_bitstream_error(mutate, match):
    with pytest.raises(BitstreamError, match=match):
        read_static_root(ByteReader(mutate(_section())))


def test_the_flag_on_a_stream_without_the_section_is_a_bitstream_error():
    """Bit 12 set on an ordinary stream: the section is read from the cuts' bytes, and whatever it finds, the joint
    counts, a field or a later count disagree: one BitstreamError from decode."""
    motion = game_rig_motion(60)
    codec = create("mcb-rot", eps_cm=0.5, static_root=False)
    data = codec.encode(motion)
    header, payload = unpack(data, "mcb-rot")
    reader = ByteReader(payload)
    reader.read_u8("format")
    settings = Settings.read(reader, 6)
    writer = ByteWriter()
    dataclasses.replace(settings, static_root=True).write(writer)
    hostile = writer.getvalue() + bytes(payload[reader.offset:])
    with pytest.raises(BitstreamError):
        codec.decode_payload(Header("mcb-rot", motion.num_frames, motion.num_joints, motion.fps), memoryview(hostile))


def test_unknown_flags_past_the_scale_tracks_are_refused():
    writer = ByteWriter()
    writer.write_f32(0.05)
    writer.write_f32(0.0499)
    writer.write_varint(1 << 14)  # (bit 13: scale tracks, mocapbench.codecs.mcb_rot.scales)
    writer.write_bytes(bytes(64))
    with pytest.raises(BitstreamError, match="settings flags"):  # (a third varint byte is refused first)
        Settings.read(ByteReader(writer.getvalue()), 6)
