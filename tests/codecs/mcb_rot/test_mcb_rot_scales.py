"""Scale tracks in ``mcb-rot`` (settings flag bit 13): the bound on every joint and end site of scaled rigs, the
decoded scales, refusals of what the codec cannot carry, hostile scale sections, and the native runtime's answer."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from mocapbench import metrics
from mocapbench.codecs import BitstreamError, container, create
from mocapbench.codecs.base import TrackRefusal
from mocapbench.codecs.mcb_rot import decoder, native, stream
from mocapbench.entropy.bitio import ByteWriter
from mocapbench.motion import Motion
from mocapbench.synthetic.game import game_rig_motion as synthetic_game_rig

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from game_rig import game_rig_motion  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_mcb_rot_native import _full_both  # noqa: E402


def _rescaled(motion: Motion, joint: int, scales) -> Motion:
    """``motion`` with joint ``joint``'s scale track set to ``scales`` (F, 3) (the others' kept)."""
    every = np.ones((motion.num_frames, motion.num_joints, 3)) if motion.scales is None else motion.scales.copy()
    every[:, joint] = scales
    return Motion(motion.skeleton, motion.fps, motion.root_positions, motion.rotations, name=motion.name,
                  translations=motion.translations, scales=every)


def _wave(frames: int, low: float, high: float, axes=(1.0, 1.0, 1.0)) -> np.ndarray:
    t = np.linspace(0.0, 1.0, frames)[:, None]
    return low + (high - low) * (0.5 + 0.5 * np.sin(2 * np.pi * 1.3 * t + np.array(axes)))


def _end_error(original: Motion, decoded: Motion) -> float:
    return float(np.sqrt(np.sum((original.end_site_positions() - decoded.end_site_positions()) ** 2, axis=-1)).max())


RIGS = {
    "forearm stretching (uniform)": lambda: game_rig_motion(90, seed=1, scaled=True),
    "chest squashing (synthetic, with a stretching spine)": lambda: synthetic_game_rig(num_frames=70, seed=2,
                                                                                      scale=1.4, stretch_cm=6.0),
    "root and spine scaled, non-uniform, some below 1": lambda: _rescaled(
        _rescaled(game_rig_motion(80, seed=3), 0, _wave(80, 0.7, 1.6, (0.0, 1.0, 2.0))), 3,
        _wave(80, 0.5, 2.0, (2.0, 0.5, 1.0))),
}


@pytest.mark.parametrize("rig", sorted(RIGS))
@pytest.mark.parametrize("eps", [0.05, 0.5])
def test_scaled_rigs_round_trip_within_the_bound_on_every_joint_and_end_site(rig, eps):
    motion = RIGS[rig]()
    data = create("mcb-rot", eps_cm=eps).encode(motion)
    header, payload = container.unpack(data, "mcb-rot")
    info = stream.read_info(header, payload)
    assert info.settings.scales and info.scales is not None
    assert info.scales.joints.tolist() == motion.scaled_joints().tolist()
    decoded = create("mcb-rot").decode(data)
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= eps
    assert _end_error(motion, decoded.motion) <= eps
    # The decoded motion carries the scales, each within half its track's step of the original.
    steps = np.zeros(motion.num_joints)
    steps[info.scales.joints] = info.scales.step
    assert np.all(np.abs(decoded.motion.scales - motion.scales) <= steps[None, :, None] / 2 * (1 + 1e-9))
    np.testing.assert_allclose(decoded.motion.positions(), decoded.positions, rtol=0, atol=1e-9)
    # A part decodes as the whole.
    part = create("mcb-rot").decode_frames(data, 17, 61)
    np.testing.assert_allclose(part.positions, decoded.positions[17:61], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(part.motion.scales, decoded.motion.scales[17:61])


def test_the_bound_sees_the_scale_error():
    """The closed loop checks positions placed with the decoded scales: on a rig whose scale moves a long chain, the
    stream without the scale's error taken into account would miss (its scales alone move joints by more than a
    third of eps), yet the decoded motion is within eps."""
    motion = _rescaled(game_rig_motion(60, seed=4), 0, _wave(60, 0.9, 1.8))
    data = create("mcb-rot", eps_cm=0.1).encode(motion)
    decoded = create("mcb-rot").decode(data)
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= 0.1
    unscaled = Motion(motion.skeleton, motion.fps, decoded.motion.root_positions, decoded.motion.rotations,
                      translations=decoded.motion.translations, scales=motion.scales)
    # the decoded scales are not the original ones: the error they cause is real, and the loop held it
    assert np.abs(decoded.motion.scales - motion.scales).max() > 0
    assert metrics.max_joint_error(unscaled.positions(), decoded.positions) > 0


def test_a_rig_whose_scales_are_all_one_writes_the_bytes_of_an_unscaled_rig():
    motion = game_rig_motion(40, seed=5)
    ones = Motion(motion.skeleton, motion.fps, motion.root_positions, motion.rotations,
                  translations=motion.translations, scales=np.ones((40, motion.num_joints, 3)))
    assert ones.scales is None  # a track of ones costs nothing
    assert create("mcb-rot", eps_cm=0.5).encode(ones) == create("mcb-rot", eps_cm=0.5).encode(motion)


def test_what_mcb_rot_cannot_carry_is_refused_in_one_line_naming_the_joint():
    motion = game_rig_motion(30, seed=6, scaled=True)
    with pytest.raises(TrackRefusal, match="joint 'LowerArm_L' is scaled.*shell_cm=0"):
        create("mcb-rot", eps_cm=0.5, shell_cm=2.0).encode(motion)
    huge = _rescaled(motion, 8, _wave(30, 1.0, 2000.0))
    with pytest.raises(ValueError, match=r"joint .LowerArm_L. has a scale of 2000 at frame \d+; .* up to 1000"):
        create("mcb-rot", eps_cm=0.5).encode(huge)


@pytest.mark.parametrize("value", [0.0, -1.0, np.nan, np.inf])
def test_a_bad_scale_is_refused_naming_the_joint_and_the_frame(value):
    motion = game_rig_motion(20, seed=7, scaled=True)
    scales = motion.scales.copy()
    scales[13, 8, 1] = value
    with pytest.raises(ValueError, match="LowerArm_L.*frame 13|frame 13.*LowerArm_L") as error:
        Motion(motion.skeleton, motion.fps, motion.root_positions, motion.rotations, translations=motion.translations,
               scales=scales)
    assert "\n" not in str(error.value)


def _scaled_stream():
    motion = game_rig_motion(40, seed=8, scaled=True)
    data = create("mcb-rot", eps_cm=0.5, segment_frames=16, chunk_frames=16).encode(motion)
    header, payload = container.unpack(data, "mcb-rot")
    info = stream.read_info(header, payload)
    writer = ByteWriter()
    info.scales.write(writer)
    section = writer.getvalue()
    at = bytes(payload).find(section)
    assert at > 0 and bytes(payload).find(section, at + 1) < 0
    return header, bytes(payload), at, section


def _pack(header, payload: bytes) -> bytes:
    return container.pack("mcb-rot", header.num_frames, header.num_joints, header.fps, payload)


def _f32(value: float) -> bytes:
    return np.array([value], np.float32).tobytes()


# The section: varint T | varint joint | u8 kind | f32 step | 3 x f32 base | f32 peak | 3 x u8 class (one track).
HOSTILE = {
    "no track": lambda s: b"\x00" + s[1:],
    "too many tracks": lambda s: b"\x17" + s[1:],
    "joint outside the rig": lambda s: s[:1] + b"\x16" + s[2:],
    "kind 0 among the scales": lambda s: s[:2] + b"\x00" + s[3:],
    "zero step": lambda s: s[:3] + _f32(0.0) + s[7:],
    "NaN base": lambda s: s[:7] + _f32(np.nan) + s[11:],
    "zero peak": lambda s: s[:19] + _f32(0.0) + s[23:],
    "peak below the scales": lambda s: s[:19] + _f32(0.5) + s[23:],
    "class 64": lambda s: s[:23] + b"\x40" + s[24:],
}


@pytest.mark.parametrize("case", sorted(HOSTILE))
def test_a_hostile_scale_section_ends_in_a_bitstream_error(case):
    header, payload, at, section = _scaled_stream()
    bad = payload[:at] + HOSTILE[case](section) + payload[at + len(section):]
    data = _pack(header, bad)
    with pytest.raises(BitstreamError) as error:
        create("mcb-rot").decode(data)
    assert "\n" not in str(error.value)


def test_random_corruptions_of_a_scaled_stream_end_in_a_bitstream_error_or_a_finite_motion():
    header, payload, _, _ = _scaled_stream()
    rng = np.random.default_rng(3)
    codec = create("mcb-rot")
    refused = 0
    for _ in range(150):
        bad = bytearray(payload)
        for at in rng.integers(0, len(bad), rng.integers(1, 4)):
            bad[at] = int(rng.integers(0, 256))
        try:
            decoded = codec.decode(_pack(header, bytes(bad)))
        except BitstreamError as error:
            assert "\n" not in str(error)
            refused += 1
            continue
        assert np.all(np.isfinite(decoded.positions)) and np.all(decoded.motion.scales > 0)
    assert refused >= 75


@pytest.mark.parametrize("rig", sorted(RIGS))
def test_the_runtime_decodes_scale_tracks_as_numpy_does(rig, native_runtime):
    motion = RIGS[rig]()
    data = create("mcb-rot", eps_cm=0.2, segment_frames=32, chunk_frames=32).encode(motion)
    for start, stop in ((0, motion.num_frames), (5, 6), (20, 59)):
        (positions, decoded), (ref_positions, ref) = _full_both(data, start, stop)
        np.testing.assert_allclose(positions, ref_positions, rtol=0, atol=1e-6)
        np.testing.assert_allclose(decoded.rotations, ref.rotations, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(decoded.scales, ref.scales)  # the same integers times the same steps
        if ref.translations is not None:
            np.testing.assert_array_equal(decoded.translations[:, 1:], ref.translations[:, 1:])
    decoded = create("mcb-rot").decode(data)  # through the runtime
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= 0.2


def test_hostile_scaled_payloads_are_refused_by_the_runtime_in_one_line(native_runtime):
    lib = native_runtime
    header, payload, at, section = _scaled_stream()
    cases = [payload[:at] + HOSTILE[case](section) + payload[at + len(section):] for case in sorted(HOSTILE)]
    rng = np.random.default_rng(5)
    for _ in range(150):
        bad = bytearray(payload)
        for where in rng.integers(0, len(bad), rng.integers(1, 4)):
            bad[where] = int(rng.integers(0, 256))
        cases.append(bytes(bad))
    refused = []
    for case in cases:
        try:
            clip = native.NativeClip(lib, case, header.num_frames, header.num_joints, header.fps)
            count, joints = header.num_frames, header.num_joints
            clip.poses(0, count, np.empty((count, joints, 3)), np.empty((count, joints, 4)))
            clip.scales(0, count, np.empty((count, joints, 3)))
        except BitstreamError as error:
            assert "\n" not in str(error) and str(error).startswith("mcb-rot")
            refused.append(case)
    assert all(case in refused for case in cases[: len(HOSTILE)])  # every bad section field, as numpy refuses it
    assert len(refused) >= len(cases) // 2


def test_a_decoded_scaled_rig_is_written_by_the_formats_that_hold_scale_and_refused_by_bvh(tmp_path):
    """What mcb-rot now carries, the writers carry too: GLB and FBX read back the decoded scales and positions (float32
    in GLB), BVH refuses in one line naming the joint and the frame."""
    from mocapbench.io.bvh import write_bvh
    from mocapbench.io.fbx import read_fbx
    from mocapbench.io.fbx_ascii import write_fbx_ascii
    from mocapbench.io.gltf import read_gltf, write_gltf

    motion = synthetic_game_rig(num_frames=30, seed=2, scale=1.3, stretch_cm=4.0)
    decoded = create("mcb-rot").decode(create("mcb-rot", eps_cm=0.5).encode(motion)).motion
    for back in (read_gltf(write_gltf(decoded, tmp_path / "rig.glb")),
                 read_fbx(write_fbx_ascii(decoded, tmp_path / "rig.fbx"))):
        np.testing.assert_allclose(back.scales, decoded.scales, rtol=0, atol=1e-6)
        np.testing.assert_allclose(back.positions(), decoded.positions(), rtol=0, atol=1e-3)
    with pytest.raises(ValueError, match="joint 'Spine1' has scale .* at frame 1; BVH has no scale channel") as error:
        write_bvh(decoded, tmp_path / "rig.bvh")
    assert "\n" not in str(error.value)
