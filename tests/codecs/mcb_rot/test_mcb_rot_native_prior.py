"""The native runtime on streams that name a rig of a prior (flags bit 15): the same output as numpy's given the same
prior, the first segment's means predicted from the rig as numpy predicts them, and the prior checked as Python
checks it (none, another one, a rig index it lacks, hostile prior bytes: an error in one line, never a crash)."""

from __future__ import annotations

import struct
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from mocapbench import metrics
from mocapbench.codecs import BitstreamError, container, create
from mocapbench.codecs.mcb_rot import codec as mcb_rot_codec
from mocapbench.codecs.mcb_rot import decoder, native, stream
from mocapbench.codecs.mcb_rot.prior import Prior
from mocapbench.entropy.bitio import ByteReader

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "tests" / "codecs"))
from game_rig import game_rig_motion, still_root_rig  # noqa: E402
from test_mcb_rot import random_motion  # noqa: E402

sys.path.insert(0, str(ROOT / "tests" / "codecs" / "mcb_rot"))
from test_mcb_rot_native import _full_both  # noqa: E402

EPS = 0.5


@pytest.fixture(scope="module")
def lib(native_runtime):
    return native_runtime


@pytest.fixture(scope="module")
def fitted():
    return create("mcb-rot", eps_cm=EPS).fit([still_root_rig(30, seed=1), game_rig_motion(30, seed=2),
                                              random_motion(3, 5, 20, 0.0, 0.3)])


def _assert_alike(data: bytes, prior: Prior, start: int = 0, stop: int | None = None) -> None:
    (positions, motion), (ref_positions, ref_motion) = _full_both(data, start, stop, prior)
    np.testing.assert_allclose(positions, ref_positions, rtol=0, atol=1e-6)
    np.testing.assert_allclose(motion.rotations, ref_motion.rotations, rtol=0, atol=1e-9)
    np.testing.assert_allclose(motion.root_positions, ref_motion.root_positions, rtol=0, atol=1e-9)
    if ref_motion.translations is not None:
        np.testing.assert_allclose(motion.translations, ref_motion.translations, rtol=0, atol=1e-9)


CASES = {
    "still root, 150 frames": (lambda: still_root_rig(150, seed=5, position=(0.0, 0.0, 0.0)), dict(chunk_frames=64)),
    "still root, 41 frames, cuts of 16": (lambda: still_root_rig(41, seed=6, position=(0.0, 0.0, 0.0)),
                                          dict(segment_frames=16, chunk_frames=16)),
    "game rig, 260 frames": (lambda: game_rig_motion(260, seed=7), dict(static_root=False)),
    "game rig, 1 frame": (lambda: game_rig_motion(1, seed=8), dict(static_root=False)),
    "rigid, 5 joints": (lambda: random_motion(3, 5, 90, 0.0, 0.3), dict(segment_frames=32, chunk_frames=32)),
}


@pytest.mark.parametrize("case", list(CASES))
def test_the_runtime_decodes_prior_streams_as_numpy_does(lib, case):
    make, settings = CASES[case]
    codec = create("mcb-rot", eps_cm=EPS, **settings).fit([still_root_rig(30, seed=1), game_rig_motion(30, seed=2),
                                                           random_motion(3, 5, 20, 0.0, 0.3)])
    motion = make()
    data = codec.encode(motion)
    header, payload = container.unpack(data, "mcb-rot")
    info = stream.read_info(header, payload, codec._prior)
    assert info.settings.prior and info.prior_data == codec._prior.data
    _assert_alike(data, codec._prior)
    frames = header.num_frames
    _assert_alike(data, codec._prior, frames // 3, max(frames // 3 + 1, frames // 2))
    decoded = codec.decode(data)  # through the runtime
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= EPS


def test_the_first_means_predicted_from_the_rig_are_used_and_read_alike(lib, fitted):
    """The streams above predict their first segment's means from the rig (the flag 1): the path is exercised."""
    predicted = 0
    for make, _ in CASES.values():
        data = fitted.encode(make())
        header, payload = container.unpack(data, "mcb-rot")
        info = stream.read_info(header, payload, fitted._prior)
        predicted += stream._first_means(info) is not None
        _assert_alike(data, fitted._prior)
    assert predicted >= 3


def _reference_at(payload: bytes) -> int:
    """Byte offset of the prior's fingerprint in a payload with flags bit 15."""
    reader = ByteReader(payload)
    version = reader.read_u8()
    stream.Settings.read(reader, version)
    return reader.offset


def _with_fingerprint(payload: bytes, prior_bytes: bytes) -> bytes:
    at = _reference_at(payload)
    return payload[:at] + struct.pack("<I", zlib.crc32(prior_bytes)) + payload[at + 4:]


def _open(lib, payload: bytes, header, prior_bytes: bytes | None):
    return native.NativeClip(lib, payload, header.num_frames, header.num_joints, header.fps, prior_bytes)


def test_a_prior_stream_without_its_prior_or_with_another_is_refused_in_one_line(lib, fitted):
    data = fitted.encode(still_root_rig(40, seed=5))
    header, payload = container.unpack(data, "mcb-rot")
    payload = bytes(payload)
    with pytest.raises(BitstreamError, match=r"coded against a prior \(model [0-9a-f]{8}\) and none was given"):
        _open(lib, payload, header, None)
    other = create("mcb-rot").fit([still_root_rig(30, seed=1, position=(0.0, 0.0, 3.0))])._prior.data
    with pytest.raises(BitstreamError, match="coded against prior [0-9a-f]{8}, the prior given is [0-9a-f]{8}") as error:
        _open(lib, payload, header, other)
    assert "\n" not in str(error.value)
    _open(lib, payload, header, fitted._prior.data)  # (its own opens)


def test_a_rig_index_the_prior_lacks_is_refused_by_the_runtime_and_by_numpy(lib, fitted):
    data = fitted.encode(still_root_rig(40, seed=5))
    header, payload = container.unpack(data, "mcb-rot")
    payload = bytes(payload)
    reader = ByteReader(payload[_reference_at(payload) + 4:])
    reader.read_svarint()
    at = _reference_at(payload) + 4 + reader.offset  # the rig index (one byte: the prior holds 3 rigs)
    bad = payload[:at] + bytes([7]) + payload[at + 1:]
    with pytest.raises(BitstreamError, match="names rig 7 of the prior, which holds 3"):
        _open(lib, bad, header, fitted._prior.data)
    with pytest.raises(BitstreamError, match="names rig 7 of the prior, which holds 3"):
        stream.read_info(header, memoryview(bad), fitted._prior)


def _hostile_priors(data: bytes) -> list[bytes]:
    """Variants of a prior's bytes: every field's first bytes flipped, cut short, a byte added, a wrong version,
    no rigs, a NaN offset."""
    rng = np.random.default_rng(5)
    cases = [data[:cut] for cut in range(0, len(data), 1 + len(data) // 40)]
    cases += [data + b"\0", bytes([2]) + data[1:], bytes([1, 0]) + data[2:]]
    for at in list(range(0, 40)) + sorted(rng.choice(len(data), 60, replace=False).tolist()):
        for mask in (0x01, 0x80, 0xff):
            flipped = bytearray(data)
            flipped[at] ^= mask
            cases.append(bytes(flipped))
    nan = bytearray(data)
    nan[-8:] = struct.pack("<d", float("nan"))  # the last rig's mean signal
    cases.append(bytes(nan))
    return cases


def test_hostile_prior_bytes_are_refused_as_python_refuses_them(lib, fitted):
    """Each hostile prior, with the stream's fingerprint set to its CRC32 (so that the prior's parser reads it): where
    Python's Prior refuses it, the runtime refuses it (one line naming the prior); where Python takes it, the
    runtime either opens the stream and decodes what numpy decodes with that prior, or refuses the stream (the rig
    no longer fits it) as numpy does. Python alone checks that the joint names differ (the runtime never reads them)."""
    motion = still_root_rig(24, seed=5, position=(0.0, 0.0, 0.0))
    data = fitted.encode(motion)
    header, payload = container.unpack(data, "mcb-rot")
    payload = bytes(payload)
    refused = decoded = 0
    for bad in _hostile_priors(fitted._prior.data):
        patched = _with_fingerprint(payload, bad)
        try:
            prior = Prior.from_bytes(bad)
        except ValueError as error:
            if "unique" in str(error):
                continue
            with pytest.raises(BitstreamError, match="the prior is malformed") as native_error:
                _open(lib, patched, header, bad)
            assert "\n" not in str(native_error.value)
            refused += 1
            continue
        try:
            numpy_info = stream.read_info(header, memoryview(patched), prior)
        except BitstreamError:
            with pytest.raises(BitstreamError):
                _open(lib, patched, header, bad)
            continue
        numpy_out = mcb_rot_codec._decode_frames(numpy_info, memoryview(patched), 0, header.num_frames, header.fps)
        clip_info = stream.read_info(header, memoryview(patched), prior)
        assert decoder.native_clip(clip_info, memoryview(patched)) is not None
        native_out = mcb_rot_codec._decode_frames(clip_info, memoryview(patched), 0, header.num_frames, header.fps)
        np.testing.assert_allclose(native_out[0], numpy_out[0], rtol=0, atol=1e-6)
        decoded += 1
    assert refused >= 100 and decoded >= 5


def test_a_bandai_clip_named_in_a_prior_decodes_alike_through_the_runtime(lib, bandai_dir):
    """A real game-studio clip (the first of the test split, at most 150 frames) coded against a prior fit on the
    first 30 frames of three test clips: its rig named, native = numpy, the bound held."""
    from mocapbench.datasets.bandai import clip_files
    from mocapbench.io.bvh import read_bvh

    clips = clip_files("bandai_test", bandai_dir)
    codec = create("mcb-rot", eps_cm=EPS).fit([read_bvh(path).slice(0, 30) for _, _, path in clips[:3]])
    name, _, path = clips[0]
    motion = read_bvh(path)
    motion = motion.slice(0, min(150, motion.num_frames))
    data = codec.encode(motion)
    header, payload = container.unpack(data, "mcb-rot")
    assert stream.read_info(header, payload, codec._prior).settings.prior, name
    _assert_alike(data, codec._prior)
    _assert_alike(data, codec._prior, 31, 97)
    assert metrics.max_joint_error(motion.positions(), codec.decode(data).positions) <= EPS
