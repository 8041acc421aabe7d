"""mcb-rot's prior (flags bit 15): a stream of a rig the prior holds names it and is shorter, decodes to the same
motion within the bound, needs that prior (none or another fails in one line), a rig the prior lacks codes as
without it byte for byte, and the prior survives a model file; malformed priors are refused."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from mocapbench.codecs import create
from mocapbench.codecs.base import BitstreamError
from mocapbench.codecs.container import unpack
from mocapbench.codecs.mcb_rot.prior import Prior, first_means
from mocapbench.codecs.model_file import ModelFileError, load_model, save_model
from mocapbench.motion import Motion

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from game_rig import game_rig_motion, still_root_rig  # noqa: E402

EPS = 0.5


def _worst(decoded, motion: Motion) -> float:
    joints = np.sqrt(np.sum((decoded.positions - motion.positions()) ** 2, axis=-1)).max()
    ends = np.sqrt(np.sum((decoded.motion.end_site_positions() - motion.end_site_positions()) ** 2, axis=-1)).max()
    return float(max(joints, ends))


@pytest.fixture(scope="module")
def fitted():
    return create("mcb-rot", eps_cm=EPS).fit([still_root_rig(30, seed=1), game_rig_motion(30, seed=2)])


@pytest.mark.parametrize("make", [lambda: still_root_rig(40, seed=5), lambda: game_rig_motion(40, seed=6)])
def test_a_rig_the_prior_holds_is_named_shorter_and_decodes_within_the_bound(fitted, make):
    motion = make()
    plain = create("mcb-rot", eps_cm=EPS).encode(motion)
    named = fitted.encode(motion)
    assert fitted.model_bytes == len(fitted._prior.data) > 0
    # the skeleton part (names, offsets) and the still root are replaced by 6 bytes: far more than 50 saved
    assert len(named) < len(plain) - 50
    decoded = fitted.decode(named)
    assert _worst(decoded, motion) <= EPS
    assert decoded.motion.skeleton.names == motion.skeleton.names
    np.testing.assert_allclose(decoded.motion.skeleton.offsets[2:], motion.skeleton.offsets[2:], atol=0.01)
    np.testing.assert_array_equal(decoded.motion.skeleton.parents, motion.skeleton.parents)
    # one frame (random access) decodes through the same prior
    np.testing.assert_allclose(fitted.decode_frames(named, 7, 8).positions, decoded.positions[7:8], atol=1e-9)


def test_without_the_prior_or_with_another_the_stream_fails_in_one_line(fitted):
    named = fitted.encode(still_root_rig(40, seed=5))
    with pytest.raises(BitstreamError, match="coded against a prior .* holds none") as error:
        create("mcb-rot").decode(named)
    assert "\n" not in str(error.value)
    other = create("mcb-rot").fit([still_root_rig(30, seed=1, position=(0.0, 0.0, 3.0))])
    with pytest.raises(BitstreamError, match="coded against prior [0-9a-f]{8}, this codec holds [0-9a-f]{8}"):
        other.decode(named)


def test_a_rig_the_prior_lacks_is_coded_as_without_it_byte_for_byte(fitted):
    motion = still_root_rig(40, seed=5)
    skeleton = motion.skeleton
    longer = skeleton.offsets.copy()
    longer[8, 0] += 1.0  # another actor's forearm
    moved = Motion(type(skeleton)(skeleton.names, skeleton.parents, longer, skeleton.channel_orders,
                                  skeleton.end_site_parents, skeleton.end_site_offsets),
                   motion.fps, motion.root_positions, motion.rotations, translations=motion.translations)
    assert fitted.encode(moved) == create("mcb-rot", eps_cm=EPS).encode(moved)
    assert fitted.model_bytes == 0
    assert fitted.encode(moved) != create("mcb-rot", eps_cm=EPS).encode(motion)  # (the change is seen)


def test_the_prior_survives_a_model_file(fitted, tmp_path):
    path = save_model(fitted, tmp_path / "prior.npz")
    loaded = load_model(path)
    assert loaded._prior.fingerprint == fitted._prior.fingerprint
    named = fitted.encode(still_root_rig(40, seed=5))
    assert _worst(loaded.decode(named), still_root_rig(40, seed=5)) <= EPS


def test_malformed_priors_are_refused_in_one_line(fitted, tmp_path):
    data = fitted._prior.data
    for bad in (b"", bytes([2]) + data[1:], data[:-3], data + b"\0", bytes([1, 0])):
        with pytest.raises(ValueError, match="mcb-rot: the prior is malformed") as error:
            Prior.from_bytes(bad)
        assert "\n" not in str(error.value)
    state = fitted.model_state()
    state["num_joints"] = np.array(5, dtype=np.int64)
    with pytest.raises(ValueError, match="num_joints says 5"):
        create("mcb-rot").load_model_state(state)
    import zipfile

    path = save_model(fitted, tmp_path / "prior.npz")
    with zipfile.ZipFile(path) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    with zipfile.ZipFile(tmp_path / "bad.npz", "w") as archive:
        for name, content in members.items():
            if name == "state_prior.npy":
                header_end = content.index(b"\n") + 1
                content = content[:header_end] + bytes([9]) + content[header_end + 1:]  # the version byte
            archive.writestr(name, content)
    with pytest.raises(ModelFileError, match="bad.npz: mcb-rot: the prior is malformed: version 9"):
        load_model(tmp_path / "bad.npz")


def test_the_first_means_are_predicted_where_no_rounding_is_close_and_refused_where_one_is():
    axes = np.broadcast_to(np.eye(3), (2, 3, 3))
    mean = np.array([1.0, 2.0, 3.0, 0.1, 0.0, -0.2, 0.0, 0.3, 0.0])
    base = np.full(9, 0.25)
    np.testing.assert_array_equal(first_means(mean, axes, base, 16), np.rint(mean * 4 / 0.25).astype(np.int64))
    assert first_means(mean + np.r_[0.5 / 16, np.zeros(8)], axes, base, 16) is None  # 16.5 steps: too close to call
    assert first_means(np.full(9, 1e6), axes, np.full(9, 1e-9), 16) is None  # beyond 2^40 steps


def test_a_stream_whose_first_means_flag_is_not_0_or_1_is_refused(fitted):
    from mocapbench.codecs.mcb_rot import stream

    data = fitted.encode(still_root_rig(40, seed=5))
    header, payload = unpack(data, "mcb-rot")
    info = stream.read_info(header, payload, fitted._prior)
    assert info.prior_mean is not None
    seen = []
    original = stream.ByteReader.read_u8

    def spy(reader, what="u8"):
        if what == "first means predicted":
            seen.append(reader.offset)
        return original(reader, what)

    stream.ByteReader.read_u8 = spy
    try:
        stream.read_info(header, payload, fitted._prior)
    finally:
        stream.ByteReader.read_u8 = original
    assert len(seen) == 1 and payload[seen[0]] == 1  # predicted on this clip
    bad = bytearray(payload)
    bad[seen[0]] = 2
    with pytest.raises(BitstreamError, match="first-means flag must be 0 or 1, found 2"):
        stream.read_info(header, memoryview(bytes(bad)), fitted._prior)
