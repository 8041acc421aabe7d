"""Long captures are coded through windows of frames (bounded memory): the windowed streams keep every codec's
guarantees. The windows are made small here (monkeypatched) so the tests stay fast."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapbench.codecs import container, create
from mocapbench.codecs.base import BitstreamError
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.synthetic import sinusoidal_motion


def _error(codec, motion, stream):
    return np.linalg.norm(codec.decode(stream).positions - motion.positions(), axis=-1)


def test_mcb_linf_codes_a_long_capture_window_by_window_and_keeps_its_bound(monkeypatch):
    from mocapbench.codecs.mcb_linf import codec as mcb_linf

    motion = sinusoidal_motion(num_frames=1000, seed=4)
    whole = create("mcb-linf", eps_cm=0.5).encode(motion)
    monkeypatch.setattr(mcb_linf, "WINDOW_FRAMES", 480)
    codec = create("mcb-linf", eps_cm=0.5)
    stream = codec.encode(motion)
    assert codec.last_encode_stats["windows"] == 3
    assert _error(codec, motion, stream).max() <= 0.5  # the guarantee, on every frame of every window
    assert len(stream) <= 1.1 * len(whole)  # the windows' own settings and rate search cost little
    header, payload = container.unpack(stream, "mcb-linf")
    assert codec.describe_payload(header, payload)["windows of frames"] == "3 x 480 (first shown)"
    payload = bytearray(stream)
    with pytest.raises(BitstreamError):
        codec.decode(bytes(payload[:-7]))  # truncated: a window runs past the end


@settings(max_examples=300, deadline=None)
@given(st.integers(7681, 2_000_000), st.sampled_from([2, 257, 1025, 1000, 2049, 7681]), st.integers(0, 10))
def test_pga_ik_windows_of_a_long_capture_end_on_a_kept_trajectory_sample(num_frames, window_frames, dropped):
    from mocapbench.codecs.pga.codec import _long_extents

    grid = 1 << dropped
    extents = _long_extents(num_frames, window_frames, grid)
    assert extents[0][0] == 0 and extents[-1][1] == num_frames
    assert all(stop - start == window_frames for start, stop in extents[:-1])
    assert all(a[1] == b[0] for a, b in zip(extents[:-2], extents[1:-1]))  # back to back
    start, stop = extents[-1]
    if len(extents) > 1:  # the last one is lengthened backwards, never past the start of the one before
        assert extents[-2][0] <= start <= extents[-2][1]
    assert 1 <= stop - start <= window_frames
    if (window_frames - 1) % grid == 0:  # full windows end on the grid, and so does the last
        assert (stop - start - 1) % grid == 0


def test_pga_ik_codes_each_window_of_a_long_capture_as_a_clip_of_its_own(monkeypatch):
    from mocapbench.codecs.pga import codec as pga
    from mocapbench.codecs.windows import encode_windows, split_windows

    motion = sinusoidal_motion(num_frames=600, seed=4)
    codec = create("pga-ik", root_levels_dropped=2, end_levels_dropped=2, window_frames=257)
    whole = _error(codec, motion, codec.encode(motion))  # 600 frames: one clip, one pose model
    monkeypatch.setattr(pga, "WINDOW_FRAMES", 256)
    stream = codec.encode(motion)
    header, payload = container.unpack(stream, "pga-ik")
    assert bytes(payload[:4]) == bytes([0, 1, 0x81, 0x02]) and payload[4] == 4  # marker, version, 257, grid 2^2
    extents = pga._long_extents(600, 257, 4)
    assert extents == [(0, 257), (257, 514), (511, 600)]  # the last: 1 + 22 x 4 frames, its end on the grid
    for start, stop, part in split_windows(payload[5:], 600, 257, extents):
        assert bytes(part) == codec._encode_window(motion.slice(start, stop))  # the window is that clip's stream
    windowed = _error(codec, motion, stream)
    assert windowed.mean() < 0.8 * whole.mean()  # a pose model per window holds its poses better than one for all
    # A stream written before the marker (back-to-back windows of WINDOW_FRAMES) still decodes.
    old, _ = encode_windows(motion, pga.WINDOW_FRAMES, lambda part: (codec._encode_window(part), {}))
    old_error = _error(codec, motion, container.pack("pga-ik", 600, motion.num_joints, motion.fps, old))
    assert old_error.mean() < 0.8 * whole.mean()
    for index, value, message in ((1, 7, "layout version 7"), (2, 1, "window of 2..257 frames.*found 1 and 2")):
        bad = bytearray(payload)
        bad[index] = value
        with pytest.raises(BitstreamError, match=message):
            codec.decode(container.pack("pga-ik", 600, motion.num_joints, motion.fps, bytes(bad)))


def test_pga_ik_fits_one_pose_model_per_window(monkeypatch):
    from mocapbench.codecs.pga import codec as pga

    motion = sinusoidal_motion(num_frames=600, seed=4)
    codec = create("pga-ik", num_geodesics=12, root_levels_dropped=0, end_levels_dropped=0, window_frames=257)
    whole = _error(codec, motion, codec.encode(motion)).max()  # 12.2 cm: IK on this seed's poses
    monkeypatch.setattr(pga, "WINDOW_FRAMES", 256)
    stream = codec.encode(motion)
    assert codec.last_encode_stats["windows"] == 3
    decoded = codec.decode(stream)
    assert decoded.motion.num_frames == 600 and np.allclose(decoded.motion.positions(), decoded.positions)
    assert _error(codec, motion, stream).max() <= whole  # a model per window fits its poses no worse
    header, payload = container.unpack(stream, "pga-ik")
    assert codec.describe_payload(header, payload)["num_geodesics"] == 12
    with pytest.raises(BitstreamError):
        codec.decode(stream[:-5])
    # The IK work limit holds for the whole stream, not per window (each window alone is under it).
    from mocapbench.codecs.limits import DecodeLimitError, DecodeLimits

    with pytest.raises(DecodeLimitError, match="max_ik_iterations"):
        codec.decode(stream, limits=DecodeLimits(max_ik_iterations=600 * 2 - 1))


def test_svd_of_a_long_capture_uses_the_gram_matrix_with_the_same_result(monkeypatch):
    from mocapbench.codecs.neural_fourier import svd

    motion = sinusoidal_motion(num_frames=900, seed=4)
    direct = create("svd", rank=16)
    reference = _error(direct, motion, direct.encode(motion))
    monkeypatch.setattr(svd, "_DIRECT_SVD_FRAMES", 100)
    monkeypatch.setattr(svd, "_BLOCK_FRAMES", 128)

    def no_direct_svd(*args, **kwargs):
        raise AssertionError("a long capture must not take the F x m SVD")

    monkeypatch.setattr(svd.np.linalg, "svd", no_direct_svd)
    blocked = create("svd", rank=16)
    error = _error(blocked, motion, blocked.encode(motion))
    assert abs(error.max() - reference.max()) < 1e-3 and abs(error.mean() - reference.mean()) < 1e-4


SPATIAL_TRANSFORM_CODECS = ["lsdt-frame", "lsdt-clip", "dct-spatial-frame", "dct-spatial-clip", "dwt-spatial-frame",
                            "dwt-spatial-clip"]


@pytest.mark.parametrize("name", SPATIAL_TRANSFORM_CODECS)
def test_spatial_transform_codecs_code_a_long_capture_window_by_window(name, monkeypatch):
    from mocapbench.codecs.lsdt import pipeline as lsdt

    motion = sinusoidal_motion(num_frames=1100, seed=4)
    short = motion.slice(0, 300)
    short_stream = create(name).encode(short)
    whole = create(name).encode(motion)  # one window: the paper's pipeline over the whole capture
    whole_decoded = create(name).decode(whole).positions
    monkeypatch.setattr(lsdt, "WINDOW_FRAMES", 480)  # 1,100 frames: windows of 480, 480, 140
    codec = create(name)
    assert codec.encode(short) == short_stream  # up to a window: the same bytes as before windows existed
    stream = codec.encode(motion)
    assert codec.last_encode_stats["windows"] == 3
    header, payload = container.unpack(stream, name)
    assert codec.describe_payload(header, payload)["windows of frames"] == "3 x 480 (first shown)"
    assert len(stream) <= 1.05 * len(whole)  # a window's own Huffman tables (and intra frame) cost little
    # With the paper's dead zone (threshold 0.5 step) the coefficients of every frame (frame scheme: K_i = rint(g_i/Δ))
    # or every clip of L frames (clip scheme, windows of whole clips) do not depend on the windows: the same integer
    # indices. The inverse transform of a window is a matrix product of another shape, which the BLAS kernel may
    # round differently in the last bits (it does with OPENBLAS_CORETYPE=Haswell): equal within float rounding of
    # positions of a few metres, while one index off would move a joint by a whole step (0.5 cm).
    np.testing.assert_allclose(codec.decode(stream).positions, whole_decoded, rtol=0, atol=1e-9)
    assert _error(codec, motion, stream).max() < 3 * 0.5  # a few steps (step 0.5 cm)
    with pytest.raises(BitstreamError):
        codec.decode(stream[:-9])  # truncated: a window runs past the end


@pytest.mark.parametrize("name", ["lsdt-frame", "dct-spatial-frame"])
def test_frame_codecs_restart_their_closed_loop_per_window_within_the_bound(name, monkeypatch):
    from mocapbench.codecs.lsdt import pipeline as lsdt

    motion = sinusoidal_motion(num_frames=1000, seed=8)
    config = {"step_cm": 0.5, "threshold_steps": 2.0}  # a hard threshold wider than the dead zone: the loop matters
    whole = create(name, **config)
    whole_error = _error(whole, motion, whole.encode(motion))  # decoded before the windows are made small
    monkeypatch.setattr(lsdt, "WINDOW_FRAMES", 256)
    codec = create(name, **config)
    windowed_error = _error(codec, motion, codec.encode(motion))
    # Closed loop: every frame's error is its own quantization error (at most sqrt(3J) x threshold), with or
    # without windows, and it does not grow along the capture.
    bound = (3 * motion.num_joints) ** 0.5 * 2.0 * 0.5
    assert whole_error.max() <= bound and windowed_error.max() <= bound
    assert abs(windowed_error.mean() - whole_error.mean()) < 0.05 * whole_error.mean()
    assert windowed_error[-256:].mean() < 1.5 * windowed_error[:256].mean()


def test_clip_codec_windows_are_whole_clips_of_any_length(monkeypatch):
    from mocapbench.codecs.lsdt import pipeline as lsdt

    motion = sinusoidal_motion(num_frames=1000, seed=2)
    codec = create("lsdt-clip", clip_length=100)
    whole = codec.decode(codec.encode(motion)).positions
    monkeypatch.setattr(lsdt, "WINDOW_FRAMES", 256)  # windows of 200 frames: two clips of 100
    stream = codec.encode(motion)
    assert codec.last_encode_stats["windows"] == 5
    # The same clips and indices; the inverse transforms run over other shapes (rounding of the BLAS kernel).
    np.testing.assert_allclose(codec.decode(stream).positions, whole, rtol=0, atol=1e-9)
    monkeypatch.setattr(lsdt, "WINDOW_FRAMES", 64)  # a clip longer than the window: windows of one clip
    assert create("lsdt-clip", clip_length=100).describe_payload(
        *container.unpack(create("lsdt-clip", clip_length=100).encode(motion), "lsdt-clip"))[
        "windows of frames"] == "10 x 100 (first shown)"


def test_windowed_spatial_stream_with_a_hostile_window_length_is_refused(monkeypatch):
    from mocapbench.codecs.lsdt import pipeline as lsdt

    motion = sinusoidal_motion(num_frames=600, seed=1)
    monkeypatch.setattr(lsdt, "WINDOW_FRAMES", 256)
    codec = create("dct-spatial-clip")
    header, payload = container.unpack(codec.encode(motion), "dct-spatial-clip")
    for window_frames in (0, 7):
        writer = ByteWriter()
        writer.write_varint(window_frames)
        edited = writer.getvalue() + bytes(payload)[2:]  # replaces the 2-byte varint of 240
        stream = container.pack("dct-spatial-clip", 600, motion.num_joints, motion.fps, edited)
        with pytest.raises(BitstreamError):
            codec.decode(stream)


def test_quant_pred_zstd_streams_a_long_capture_to_the_same_positions(monkeypatch):
    from mocapbench.entropy import backend

    motion = sinusoidal_motion(num_frames=1500, seed=6)
    codec = create("quant-pred-zstd", step_cm=0.1)
    one_shot = codec.encode(motion)  # 1,500 x 93 values: under ONE_SHOT_VALUES, the bytes it always had
    monkeypatch.setattr(backend, "ONE_SHOT_VALUES", 1000)  # as a long capture: track by track, streaming zstd
    streamed = codec.encode(motion)
    assert abs(len(streamed) - len(one_shot)) <= 0.001 * len(one_shot)  # zstd's streaming mode: a few bytes apart
    decoded = codec.decode(streamed).positions
    assert np.array_equal(decoded, codec.decode(one_shot).positions)
    assert _error(codec, motion, streamed).max() <= 0.1 * 3**0.5 / 2 + 1e-9  # step / 2 per coordinate
    with pytest.raises(BitstreamError):
        codec.decode(streamed[:-9])


def test_acl_compresses_a_long_capture_as_one_acl_clip_per_window(acl_codec, monkeypatch):
    from mocapbench.codecs.acl import codec as acl_module

    motion = sinusoidal_motion(num_frames=1000, seed=5)
    codec = acl_codec(precision_cm=0.1, shell_cm=0.0)
    short_stream = codec.encode(motion.slice(0, 300))
    whole = codec.encode(motion)
    whole_decoded = codec.decode(whole)
    monkeypatch.setattr(acl_module, "WINDOW_FRAMES", 400)  # 1,000 frames: ACL clips of 400, 400, 200
    assert codec.encode(motion.slice(0, 300)) == short_stream  # up to a window: one ACL clip, the same bytes
    stream = codec.encode(motion)
    assert codec.last_encode_stats["windows"] == 3
    assert codec.last_encode_stats["acl_overhead_bytes"] < codec.last_encode_stats["acl_buffer_bytes"]
    assert len(stream) <= 1.2 * len(whole)  # each ACL clip has its own header and constant tracks
    decoded = codec.decode(stream)
    assert decoded.motion.num_frames == 1000 and np.allclose(decoded.motion.positions(), decoded.positions)
    error = _error(codec, motion, stream)
    assert error.max() <= 1.5 * 0.1  # ACL's precision (shell 0), window by window as over the whole clip
    assert np.abs(decoded.positions - whole_decoded.positions).max() <= 2 * 1.5 * 0.1
    # Random access across a window boundary decodes the same frames as the full decode.
    part = codec.decode_frames(stream, 350, 850)
    np.testing.assert_allclose(part.positions, decoded.positions[350:850], rtol=0, atol=1e-9)  # FK blocks differ
    header, payload = container.unpack(stream, "acl")
    assert codec.describe_payload(header, payload)["windows of frames (ACL clips)"] == "3 x 400 (first shown)"
    with pytest.raises(BitstreamError):
        codec.decode(stream[:-9])
    # The stream carries its window length: another WINDOW_FRAMES in the decoder reads it the same.
    monkeypatch.setattr(acl_module, "WINDOW_FRAMES", 300)
    np.testing.assert_array_equal(codec.decode(stream).positions, decoded.positions)
    # A window length edited to 300 asks for 4 clips where the payload holds 3 of 400 frames: refused.
    from mocapbench.codecs.skeleton_blob import unpack_skeleton

    reader = ByteReader(payload)
    unpack_skeleton(reader)
    skeleton_end = reader.offset
    assert reader.read_varint("window frames") == 400
    edited = ByteWriter()
    edited.write_varint(300)
    hostile = bytes(payload[:skeleton_end]) + edited.getvalue() + bytes(payload[reader.offset :])
    with pytest.raises(BitstreamError):
        codec.decode(container.pack("acl", 1000, motion.num_joints, motion.fps, hostile))


def _mcb_rot_windows(monkeypatch, window_frames: int):
    """The mcb-rot codec module and its window module, with windows of ``window_frames`` frames."""
    from mocapbench.codecs.mcb_rot import codec as module
    from mocapbench.codecs.mcb_rot import windowed

    monkeypatch.setattr(windowed, "WINDOW_FRAMES", window_frames)
    return module, windowed


def test_mcb_rot_codes_a_long_capture_window_by_window_within_eps(monkeypatch):
    from mocapbench.codecs.windows import split_windows

    motion = sinusoidal_motion(num_frames=768, seed=4)
    short = motion.slice(0, 200)
    codec = create("mcb-rot", eps_cm=0.5, high_rate_segment_frames=0)  # 128-frame segments at 120 fps, as below
    short_stream, whole = codec.encode(short), codec.encode(motion)
    module, windowed = _mcb_rot_windows(monkeypatch, 300)  # 768 frames: 3 windows, made equal: 256 frames each
    assert codec.encode(short) == short_stream  # up to a window: the bytes it always had
    assert container.unpack(short_stream, "mcb-rot")[1][0] != windowed.MARKER
    stream = codec.encode(motion)
    assert codec.last_encode_stats["windows"] == 3
    assert codec.last_encode_stats["segments"] == 3 * 2  # segments of 128 frames restart at every window
    header, payload = container.unpack(stream, "mcb-rot")
    assert bytes(payload[:4]) == bytes([windowed.MARKER, windowed.LAYOUT_VERSION, 0x80, 0x02])  # varint 256
    parts = split_windows(payload[4:], 768, 256)
    assert [(first, end) for first, end, _ in parts] == [(0, 256), (256, 512), (512, 768)]
    assert bytes(parts[-1][2]) == codec._encode_window(motion.slice(512, 768))  # each window is that clip's stream
    decoded = codec.decode(stream)
    assert _error(codec, motion, stream).max() <= 0.5  # the guarantee, on every frame of every window
    assert decoded.motion.num_frames == 768 and np.allclose(decoded.motion.positions(), decoded.positions)
    # Each window's header, rate search and entropy classes cost little (here +20 % on windows of a 2 KB stream;
    # -0.7 % to +0.8 % on a 20,000-frame capture in windows of 6,784 frames).
    assert len(stream) <= 1.3 * len(whole)
    assert codec.describe_payload(header, payload)["windows of frames"] == "3 x 256 (first shown)"
    # A long stream written before windows existed (one payload) still decodes, whatever the window length.
    assert np.array_equal(codec.decode(whole).positions, create("mcb-rot").decode(whole).positions)
    assert _error(codec, motion, whole).max() <= 0.5


def test_mcb_rot_random_access_decodes_only_the_windows_holding_the_frames(monkeypatch):
    motion = sinusoidal_motion(num_frames=1000, seed=5)
    module, _ = _mcb_rot_windows(monkeypatch, 400)  # 1,000 frames: windows of 384, 384, 232 (whole segments)
    codec = create("mcb-rot", eps_cm=1.0, high_rate_segment_frames=0)  # segments of 128 frames at 120 fps
    stream = codec.encode(motion)
    decoded = codec.decode(stream)
    for start, stop in ((350, 850), (383, 385), (384, 768), (0, 1000), (999, 1000), (0, 1)):
        part = codec.decode_frames(stream, start, stop)
        assert np.array_equal(part.positions, decoded.positions[start:stop]), (start, stop)
        assert np.array_equal(part.motion.rotations, decoded.motion.rotations[start:stop])
        assert np.array_equal(part.motion.root_positions, decoded.motion.root_positions[start:stop])
    calls = []
    decode_range = module.decode_range

    def spy(info, payload, start, stop, out=None):
        calls.append((info.layout.num_frames, start, stop))
        assert out is not None and out[0].base is not None  # straight into (views of) the outputs: no copy
        return decode_range(info, payload, start, stop, out)

    monkeypatch.setattr(module, "decode_range", spy)
    codec.decode_frames(stream, 450, 500)
    assert calls == [(384, 66, 116)]  # the second window only, frames 66:116 of it
    calls.clear()
    codec.decode_frames(stream, 760, 780)
    assert calls == [(384, 376, 384), (232, 0, 12)]
    calls.clear()
    assert np.array_equal(codec.decode(stream).positions, decoded.positions)
    assert calls == [(384, 0, 384), (384, 0, 384), (232, 0, 232)]
    with pytest.raises(ValueError, match="outside"):
        codec.decode_frames(stream, 990, 1001)


def test_mcb_rot_windowed_stream_with_hostile_window_lengths_is_refused(monkeypatch):
    from mocapbench.codecs.mcb_rot.stream import read_info

    motion = sinusoidal_motion(num_frames=600, seed=1)
    _, windowed = _mcb_rot_windows(monkeypatch, 256)  # 600 frames: windows of 256, 256, 88
    codec = create("mcb-rot", eps_cm=1.0, high_rate_segment_frames=0)  # segments of 128 frames at 120 fps
    header, payload = container.unpack(codec.encode(motion), "mcb-rot")
    body = bytes(payload[4:])  # after the marker, the version and the 2-byte varint of 256

    def stream(head: list[int], rest: bytes = body) -> bytes:
        writer = ByteWriter()
        writer.write_u8(windowed.MARKER)
        writer.write_varints(head)
        return container.pack("mcb-rot", 600, motion.num_joints, motion.fps, writer.getvalue() + rest)

    assert codec.decode(stream([1, 256])).positions.shape == (600, motion.num_joints, 3)  # the unedited stream
    for head, message in (([2, 256], "window layout version 1, found 2"), ([1, 0], "windows of 1..599 frames.*found 0"),
                          ([1, 600], "found 600"), ([1, 1], "windows of 1 frames"),
                          ([1, 128], "windows of 128 frames")):  # 5 windows asked for, the payload holds 3
        with pytest.raises(BitstreamError, match=message):
            codec.decode(stream(head))
    with pytest.raises(BitstreamError, match="600 windows, more than the 10 bytes left"):
        codec.decode(stream([1, 1], bytes(10)))  # refused before reading 600 window sizes
    first = ByteReader(body).read_varint("window size")
    edited = ByteWriter()
    edited.write_varint(first + 1)  # the first window's size one byte too long: the windows no longer add up
    rest = edited.getvalue() + body[len(edited.getvalue()) :]
    with pytest.raises(BitstreamError, match="mcb-rot"):
        codec.decode(stream([1, 256], rest))
    with pytest.raises(BitstreamError):
        codec.decode(stream([1, 256])[:-9])  # truncated
    with pytest.raises(BitstreamError, match="mcb-rot"):  # the marker is no one-window format
        read_info(header, memoryview(bytes([windowed.MARKER])))


def test_mcb_rot_encoder_memory_does_not_grow_with_the_capture(monkeypatch):
    """Traced (tracemalloc counts numpy's arrays): windows of 128 frames, a capture 4 times longer, the same peak.
    Without windows the peak grows with the capture (about 16x its positions array: 14 MB at 1,200 frames)."""
    import tracemalloc

    _mcb_rot_windows(monkeypatch, 128)
    codec = create("mcb-rot", eps_cm=1.0, step_rel=8.0)  # one attempt, no rate search: fast, the same arrays
    codec.encode(sinusoidal_motion(num_frames=64, seed=3))  # lazy imports and tables, not the capture's cost
    peaks = []
    for frames in (300, 1200):
        motion = sinusoidal_motion(num_frames=frames, seed=3)
        tracemalloc.start()
        try:
            codec.encode(motion)
            peaks.append(tracemalloc.get_traced_memory()[1])
        finally:
            tracemalloc.stop()
    assert peaks[1] <= 1.2 * peaks[0], f"encode peaks {peaks[0] / 2**20:.1f} MB, then {peaks[1] / 2**20:.1f} MB"
    assert codec.last_encode_stats["windows"] == 10


@settings(max_examples=300, deadline=None)
@given(st.integers(7681, 10_000_000), st.sampled_from([1, 3, 100, 128, 1000, 4096]))
def test_mcb_rot_windows_of_a_long_capture_are_about_equal(num_frames, segment_frames):
    from mocapbench.codecs.mcb_rot.windowed import WINDOW_FRAMES, window_length

    window = window_length(num_frames, segment_frames)
    count = -(-num_frames // window)
    assert 1 <= window < num_frames
    assert count == -(-num_frames // WINDOW_FRAMES)  # as many windows as windows of WINDOW_FRAMES need
    assert window <= -(-num_frames // count) + segment_frames - 1  # no longer than an equal share, in segments
    if WINDOW_FRAMES % segment_frames == 0:
        assert window % segment_frames == 0 and window <= WINDOW_FRAMES


def test_mcb_rot_windowed_stream_mutated_decodes_or_is_one_bitstream_error(monkeypatch):
    """The fuzzer's mutations (header fields, byte edits, truncations; CRC restamped) of a windowed stream: every
    decode and random-access decode returns or raises BitstreamError, never anything else."""
    from mocapbench.fuzz import mutations

    _mcb_rot_windows(monkeypatch, 128)  # 300 frames: windows of 128, 128, 44
    codec = create("mcb-rot", eps_cm=1.0, step_rel=8.0)
    stream = codec.encode(sinusoidal_motion(num_frames=300, seed=2))
    refused = 0
    def frames_of(data: bytes):  # a range inside the frames the (maybe edited) header says
        frames = container.read_header(data)[0].num_frames
        return codec.decode_frames(data, frames // 3, max(frames // 3 + 1, 2 * frames // 3))

    for kind, data in mutations(stream, 200, seed=11):
        for decode in (lambda: codec.decode(data), lambda: frames_of(data)):
            try:
                decoded = decode()
            except BitstreamError:
                refused += 1
                continue
            assert np.all(np.isfinite(decoded.positions)), kind
    assert refused > 200  # most edits are caught (the rest edit a value the stream allows)
