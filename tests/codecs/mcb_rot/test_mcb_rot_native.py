"""The native runtime (``runtime/``) against the numpy decoder: the same output on the streams the suite makes,
the bound on its output, and hostile payloads refused with one line (never a crash)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapbench import metrics
from mocapbench.codecs import BitstreamError, container, create
from mocapbench.codecs.mcb_rot import codec as mcb_rot_codec
from mocapbench.codecs.mcb_rot import decoder, native, stream
from mocapbench.codecs.mcb_rot.skeleton6 import unpack_skeleton_runtime
from mocapbench.codecs.mcb_rot.static_root import read_static_root
from mocapbench.entropy.bitio import ByteReader
from mocapbench.motion import Motion
from mocapbench.synthetic import sinusoidal_motion
from mocapbench.synthetic.game import game_rig_motion as synthetic_game_rig

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "tests" / "codecs"))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "tests" / "fixtures" / "golden_decode"))
from game_rig import game_rig_motion, still_root_rig  # noqa: E402
from make_golden import spinning  # noqa: E402
from test_mcb_rot import random_motion  # noqa: E402

GOLDEN = sorted((ROOT / "tests" / "fixtures" / "golden_decode").glob("mcb-rot6-*.mcb"))


@pytest.fixture(scope="module")
def lib(native_runtime):
    return native_runtime


def _both(data: bytes, start: int = 0, stop: int | None = None):
    """(native, numpy) positions, roots, rotations and, on a stream with tracks, every joint's translation (n, J, 3)
    (else None) of frames start:stop of a one-window stream."""
    header, payload = container.unpack(data, "mcb-rot")
    stop = header.num_frames if stop is None else stop
    results = []
    for use_native in (True, False):
        info = stream.read_info(header, payload)
        if not use_native:
            info._cache["native"] = None
        else:
            assert decoder.native_clip(info, payload) is not None
        count, joints = stop - start, header.num_joints
        steps = None if info.tracks is None else np.full((count, joints, 3), np.nan)
        out = (np.empty((count, joints, 3)), np.empty((count, 3)), np.empty((count, joints, 4)))
        results.append(decoder.decode_range(info, payload, start, stop, out + (() if steps is None else (steps,)))
                       + (steps,))
    return results


def _assert_same(data: bytes, start: int = 0, stop: int | None = None) -> None:
    (positions, roots, quats, steps), (ref_positions, ref_roots, ref_quats, ref_steps) = _both(data, start, stop)
    np.testing.assert_allclose(positions, ref_positions, rtol=0, atol=1e-6)
    np.testing.assert_allclose(roots, ref_roots, rtol=0, atol=1e-6)
    np.testing.assert_allclose(quats, ref_quats, rtol=0, atol=1e-9)
    if steps is not None:  # tracks: the same integers times the same steps
        np.testing.assert_array_equal(steps[:, 1:], ref_steps[:, 1:])
        np.testing.assert_allclose(steps[:, 0], ref_roots, rtol=0, atol=1e-6)


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(
    seed=st.integers(0, 10_000),
    joints=st.integers(1, 20),
    frames=st.integers(1, 400),
    eps=st.sampled_from([0.05, 0.5, 2.0]),
    zero_bones=st.sampled_from([0.0, 0.3, 1.0]),
    speed=st.sampled_from([0.0, 0.02, 0.3]),
    segment=st.sampled_from([1, 7, 32, 128]),
    chunk=st.sampled_from([1, 100, 128, 300]),
    shell=st.sampled_from([0.0, 2.0]),
    power=st.sampled_from([0.0, 2.0]),
    slope=st.sampled_from([0.0, 1.0]),
)
def test_the_runtime_decodes_what_numpy_decodes_and_holds_the_bound(lib, seed, joints, frames, eps, zero_bones, speed,
                                                                    segment, chunk, shell, power, slope):
    motion = random_motion(seed, joints, frames, zero_bones, speed)
    data = create("mcb-rot", eps_cm=eps, segment_frames=segment, chunk_frames=chunk, shell_cm=shell,
                  allocation_power=power, frequency_slope=slope, high_rate_segment_frames=0).encode(motion)
    _assert_same(data)
    decoded = create("mcb-rot").decode(data)  # through the runtime
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= eps


@settings(max_examples=10, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(
    seed=st.integers(0, 10_000),
    frames=st.integers(1, 260),
    eps=st.sampled_from([0.1, 0.5, 2.0]),
    rig=st.sampled_from(["bandai-like", "synthetic biped", "stretching spine"]),
    chunk=st.sampled_from([32, 128, 300]),
    part=st.tuples(st.floats(0, 1), st.floats(0, 1)),
)
def test_the_runtime_decodes_game_rigs_translation_tracks_as_numpy_does(lib, seed, frames, eps, rig, chunk, part):
    """Streams with translation tracks (flags bit 10): the runtime gives numpy's rotations and tracks, on the whole
    clip and on a part of it, and the bound holds on its output."""
    if rig == "bandai-like":
        motion = game_rig_motion(frames, seed=seed)
    else:
        motion = synthetic_game_rig(num_frames=frames, seed=seed, stretch_cm=8.0 if rig == "stretching spine" else 0.0)
    data = create("mcb-rot", eps_cm=eps, segment_frames=min(chunk, 128), chunk_frames=chunk,
                  static_root=False).encode(motion)  # (a still root would be kept apart: bit 12, numpy)
    header, payload = container.unpack(data, "mcb-rot")
    assert stream.read_info(header, payload).tracks is not None
    _assert_same(data)
    low, high = sorted(int(f * frames) for f in part)
    _assert_same(data, low, max(high, low + 1) if low < frames else frames)
    decoded = create("mcb-rot").decode(data)  # through the runtime
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= eps


@pytest.mark.parametrize("path", GOLDEN, ids=lambda p: p.stem)
def test_the_golden_format_6_streams_decode_alike(lib, path):
    _assert_same(path.read_bytes())


def test_cuts_spins_and_parts_decode_alike(lib):
    motion = spinning(sinusoidal_motion(num_frames=700, seed=5))
    data = create("mcb-rot", eps_cm=0.1).encode(motion)
    _assert_same(data)
    codec = create("mcb-rot")
    whole = codec.decode(data)
    for start, stop in ((0, 1), (127, 129), (300, 700), (699, 700)):
        part = codec.decode_frames(data, start, stop)
        np.testing.assert_allclose(part.positions, whole.positions[start:stop], rtol=0, atol=1e-9)


def _hostile_cases(payload: bytes, every: int, seed: int) -> list[bytes]:
    """The payload cut after every ``every``-th byte, and 300 copies with 1-3 random bytes overwritten."""
    rng = np.random.default_rng(seed)
    cases = [payload[:n] for n in range(0, len(payload), every)]
    for _ in range(300):
        bad = bytearray(payload)
        for at in rng.integers(0, len(bad), rng.integers(1, 4)):
            bad[at] = int(rng.integers(0, 256))
        cases.append(bytes(bad))
    return cases


def test_hostile_payloads_are_refused_with_one_line_never_a_crash(lib):
    data = GOLDEN[0].read_bytes()
    header, payload = container.unpack(data, "mcb-rot")
    payload = bytes(payload)
    cases = _hostile_cases(payload, every=7, seed=7)
    refused = 0
    for case in cases:
        try:
            clip = native.NativeClip(lib, case, header.num_frames, header.num_joints, header.fps)
            count = header.num_frames
            clip.frames(0, count, np.empty((count, 3)), np.empty((count, header.num_joints, 4)))
        except BitstreamError as error:
            assert "\n" not in str(error) and str(error).startswith("mcb-rot")
            refused += 1
    assert refused >= len(cases) // 2


def _full_both(data: bytes, start: int = 0, stop: int | None = None, prior=None):
    """(native, numpy) positions (n, J, 3) and motion of frames start:stop of a one-window stream, the whole rig (a
    still root kept apart put back in front); ``prior``: the one a stream with flags bit 15 names."""
    header, payload = container.unpack(data, "mcb-rot")
    stop = header.num_frames if stop is None else stop
    results = []
    for use_native in (True, False):
        info = stream.read_info(header, payload, prior)
        if not use_native:
            info._cache["native"] = None
        else:
            assert decoder.native_clip(info, payload) is not None
        results.append(mcb_rot_codec._decode_frames(info, payload, start, stop, header.fps))
    return results


def _still(motion, position):
    """``motion`` with its joint 0 held still at ``position`` with the identity rotation (the Bandai Namco files'
    ``joint_Root``): the translations of the other joints unchanged, so joint 1 carries the trajectory."""
    rotations = motion.rotations.copy()
    rotations[:, 0] = (0.0, 0.0, 0.0, 1.0)
    roots = np.broadcast_to(np.asarray(position, dtype=np.float32).astype(np.float64), motion.root_positions.shape)
    return Motion(motion.skeleton, motion.fps, roots.copy(), rotations, name="still", translations=motion.translations)


def _assert_whole_rig_alike(data: bytes, start: int = 0, stop: int | None = None) -> None:
    (positions, motion), (ref_positions, ref_motion) = _full_both(data, start, stop)
    np.testing.assert_allclose(positions, ref_positions, rtol=0, atol=1e-6)
    np.testing.assert_allclose(motion.rotations, ref_motion.rotations, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(motion.root_positions, ref_motion.root_positions)  # the still root: exact
    np.testing.assert_allclose(motion.translations, ref_motion.translations, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(motion.rotations[:, 0], np.broadcast_to([0.0, 0.0, 0.0, 1.0], (len(positions), 4)))


@settings(max_examples=10, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(
    seed=st.integers(0, 10_000),
    frames=st.integers(1, 260),
    eps=st.sampled_from([0.1, 0.5, 2.0]),
    rig=st.sampled_from(["bandai-like", "synthetic biped", "stretching spine"]),
    chunk=st.sampled_from([32, 128, 300]),
    position=st.sampled_from([(0.0, 0.0, 0.0), (3.5, -0.25, 120.0)]),
    part=st.tuples(st.floats(0, 1), st.floats(0, 1)),
)
def test_the_runtime_decodes_a_still_root_kept_apart_as_numpy_does(lib, seed, frames, eps, rig, chunk, position, part):
    """Game rigs whose ground root never moves (flags bit 12, with and without other translation tracks): the
    runtime gives the whole rig (the still root in front) as numpy does, on the clip and on a part of it, and the
    bound holds on its output, end sites included."""
    if rig == "bandai-like":
        motion = still_root_rig(frames, seed=seed, position=position)
    else:
        motion = _still(synthetic_game_rig(num_frames=frames, seed=seed,
                                           stretch_cm=8.0 if rig == "stretching spine" else 0.0), position)
    data = create("mcb-rot", eps_cm=eps, segment_frames=min(chunk, 128), chunk_frames=chunk).encode(motion)
    header, payload = container.unpack(data, "mcb-rot")
    info = stream.read_info(header, payload)
    assert info.static_root is not None and (info.tracks is not None) == (rig == "stretching spine")
    _assert_whole_rig_alike(data)
    low, high = sorted(int(f * frames) for f in part)
    _assert_whole_rig_alike(data, low, max(high, low + 1) if low < frames else frames)
    decoded = create("mcb-rot").decode(data)  # through the runtime
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= eps
    ends = np.sqrt(np.sum((decoded.motion.end_site_positions() - motion.end_site_positions()) ** 2, axis=-1))
    assert ends.max() <= eps


def test_the_runtime_gives_a_still_roots_whole_rig_in_its_own_calls(lib):
    """The clip opened by the runtime has the whole rig's joints, the still root's parent -1 and offset, and its
    child listed among the tracked joints."""
    motion = still_root_rig(40, position=(1.5, 0.0, -2.0))
    data = create("mcb-rot", eps_cm=0.5).encode(motion)
    header, payload = container.unpack(data, "mcb-rot")
    clip = native.NativeClip(lib, bytes(payload), header.num_frames, header.num_joints, header.fps)
    steps, rotations = np.empty((40, 22, 3)), np.empty((40, 22, 4))
    clip.poses(0, 40, steps, rotations)
    np.testing.assert_array_equal(steps[:, 0], np.broadcast_to([1.5, 0.0, -2.0], (40, 3)))
    np.testing.assert_allclose(steps[:, 1], motion.translations[:, 1], rtol=0, atol=0.5)
    offsets = create("mcb-rot").decode(data).motion.skeleton.offsets  # (on the stream's grid)
    np.testing.assert_array_equal(steps[:, 2:], np.broadcast_to(offsets[2:], (40, 20, 3)))
    with pytest.raises(BitstreamError, match="the skeleton has 21 joints and a still root, the header says 21"):
        native.NativeClip(lib, bytes(payload), header.num_frames, header.num_joints - 1, header.fps)


def _still_root_section(payload: bytes) -> int:
    """Where the still root section of a format 6 payload starts (after the skeleton part)."""
    reader = ByteReader(memoryview(payload))
    reader.read_u8("format")
    stream.Settings.read(reader, 6)
    unpack_skeleton_runtime(reader)
    return reader.offset


@pytest.mark.parametrize("name, section", [
    ("empty name", b"\x00"),
    ("name too long", b"\x80\x02" + b"a" * 256),
    ("NUL in the name", b"\x03a\x00b"),
    ("not UTF-8", b"\x02\xc3\x28"),
    ("overlong UTF-8", b"\x02\xc0\xaf"),
    ("surrogate", b"\x03\xed\xa0\x80"),
    ("channel order", b"\x01r\x06"),
    ("NaN offset", b"\x01r\x00" + np.array([np.nan, 0, 0, 0, 0, 0], np.float32).tobytes()),
    ("position beyond 1e6 cm", b"\x01r\x00" + np.array([0, 0, 0, 0, 2e6, 0], np.float32).tobytes()),
    ("infinite position", b"\x01r\x00" + np.array([0, 0, 0, 0, 0, np.inf], np.float32).tobytes()),
    ("truncated", b"\x01r\x00" + np.zeros(5, np.float32).tobytes()),
])
def test_a_hostile_still_root_section_is_refused_by_the_runtime_and_by_numpy(lib, name, section):
    """The still root section rewritten with a bad field: both decoders refuse it with one line (never a crash)."""
    motion = still_root_rig(20)
    data = create("mcb-rot", eps_cm=0.5).encode(motion)
    header, payload = container.unpack(data, "mcb-rot")
    payload = bytes(payload)
    at = _still_root_section(payload)
    reader = ByteReader(memoryview(payload), at)
    read_static_root(reader)
    bad = payload[:at] + section + payload[reader.offset:]
    with pytest.raises(BitstreamError) as native_error:
        native.NativeClip(lib, bad, header.num_frames, header.num_joints, header.fps)
    with pytest.raises(BitstreamError) as numpy_error:
        stream.read_info(header, memoryview(bad))
    for error in (native_error.value, numpy_error.value):
        assert "\n" not in str(error)
    if name != "truncated":  # (the section then reads into the cuts: any field may be the first to fail)
        assert "static root" in str(native_error.value) and "static root" in str(numpy_error.value)


def test_hostile_still_root_payloads_are_refused_with_one_line_never_a_crash(lib):
    data = create("mcb-rot", eps_cm=0.5, segment_frames=16, chunk_frames=16).encode(still_root_rig(40))
    header, payload = container.unpack(data, "mcb-rot")
    payload = bytes(payload)
    cases = _hostile_cases(payload, every=5, seed=11)
    refused = 0
    for case in cases:
        try:
            clip = native.NativeClip(lib, case, header.num_frames, header.num_joints, header.fps)
            count = header.num_frames
            clip.poses(0, count, np.empty((count, header.num_joints, 3)), np.empty((count, header.num_joints, 4)))
        except BitstreamError as error:
            assert "\n" not in str(error) and str(error).startswith("mcb-rot")
            refused += 1
    assert refused >= len(cases) // 2


def test_a_bandai_clip_decodes_alike_through_the_runtime(lib, bandai_dir):
    """A real game-studio clip (the first of the test split, at most 150 frames): a still root kept apart, native =
    numpy, the bound held."""
    from mocapbench.datasets.bandai import clip_files
    from mocapbench.io.bvh import read_bvh

    name, _, path = clip_files("bandai_test", bandai_dir)[0]
    motion = read_bvh(path)
    motion = motion.slice(0, min(150, motion.num_frames))
    data = create("mcb-rot", eps_cm=0.5).encode(motion)
    header, payload = container.unpack(data, "mcb-rot")
    assert stream.read_info(header, payload).static_root is not None, name
    _assert_whole_rig_alike(data)
    _assert_whole_rig_alike(data, 31, 97)
    decoded = create("mcb-rot").decode(data)
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= 0.5


def test_another_format_is_refused_by_the_runtime(lib):
    header, payload = container.unpack(GOLDEN[0].read_bytes(), "mcb-rot")
    newer = bytes([7]) + bytes(payload)[1:]
    with pytest.raises(BitstreamError, match="payload format 7"):
        native.NativeClip(lib, newer, header.num_frames, header.num_joints, header.fps)


def test_the_c_tables_are_the_python_tables():
    result = subprocess.run([sys.executable, str(ROOT / "runtime" / "tools" / "gen_tables.py"), "--check"],
                            capture_output=True, text=True, cwd=ROOT, env={"PYTHONPATH": str(ROOT)})
    assert result.returncode == 0, result.stderr


def test_the_runtime_decodes_the_default_high_rate_streams_as_numpy_does(lib):
    """At 120 fps the encoder's default segments and chunks are 80 frames (``high_rate_segment_frames``): the
    runtime gives numpy's output on the whole clip and on ranges that start and end inside chunks or straddle them."""
    motion = sinusoidal_motion(num_frames=333, seed=5)
    assert motion.fps >= 60
    data = create("mcb-rot", eps_cm=0.3).encode(motion)
    header, payload = container.unpack(data, "mcb-rot")
    settings = stream.read_info(header, payload).settings
    assert (settings.segment_frames, settings.chunk_frames) == (80, 80)
    _assert_same(data)
    for start, stop in ((0, 1), (79, 81), (100, 250), (320, 333)):
        _assert_same(data, start, stop)
    decoded = create("mcb-rot").decode(data)  # through the runtime
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= 0.3
