"""mcb-rot payload formats 4 and 5: the lean header's pieces round-trip exactly, and bad bytes are one BitstreamError."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapbench.codecs import BitstreamError, container, create
from mocapbench.codecs.mcb_rot import stream
from mocapbench.codecs.mcb_rot.budgets import offset_discrepancy_cm
from mocapbench.codecs.mcb_rot.stream import Settings, read_small_ints, skeleton_step_exponent, write_small_ints
from mocapbench.codecs.skeleton_blob import _pack_offsets, _unpack_offsets, pack_skeleton_compact, unpack_skeleton_compact
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.motion import Skeleton
from mocapbench.synthetic import sinusoidal_motion

DEFAULTS = Settings.create(0.05, 0.0499, 2.0**3.5, 1.0, 0.45, 0.05, np.deg2rad(1.0), 0.0, 128, 128, 0.0)


def _round_trip(settings: Settings) -> tuple[Settings, int]:
    writer = ByteWriter()
    settings.write(writer)
    data = writer.getvalue()
    reader = ByteReader(data)
    assert reader.read_u8() == stream.FORMAT == 6
    back = Settings.read(reader, stream.FORMAT)
    reader.expect_end("settings")
    return back, len(data)


def test_default_settings_take_eleven_bytes_and_read_back_exactly():
    back, size = _round_trip(DEFAULTS)
    assert back == DEFAULTS
    assert size == 11  # format, eps, bound, flags, multiplier code (format 3 wrote 45)


@pytest.mark.parametrize("change", [
    {"slope": 0.0}, {"slope": 0.5}, {"multiplier": stream._f32(3.3)}, {"shell_cm": 3.0}, {"segment_frames": 64},
    {"chunk_frames": 512}, {"rounding": 0.5}, {"root_share": stream._f32(0.2)}, {"free_angle_rad": stream._f32(0.1)},
    {"allocation_power": 2.0}, {"slope": 0.0, "shell_cm": 3.0, "multiplier": 1.0, "chunk_frames": 1 << 20},
])
def test_settings_that_differ_from_the_defaults_read_back_exactly(change):
    settings = dataclasses.replace(DEFAULTS, **change)
    back, size = _round_trip(settings)
    assert back == settings
    assert size <= 11 + 4 * len(change) + 3


def test_a_format_4_header_reads_its_own_defaults():
    """Formats 4 and 6 leave out chunks of 128 frames (their default), format 5 leaves out 256: the same flags read
    back as each format's default, and a format 4 header written before format 5 (by hand here: flags 0) reads 128."""
    writer = ByteWriter()
    writer.write_f32(0.05)
    writer.write_f32(0.0499)
    writer.write_varint(0)  # every setting at its default
    writer.write_u8(71)  # multiplier code: 2^3.5
    for version, chunk in ((4, 128), (5, 256), (6, 128)):
        back = Settings.read(ByteReader(writer.getvalue()), version)
        assert (back.chunk_frames, back.segment_frames, back.multiplier) == (chunk, 128, stream._f32(2.0**3.5))
    five = dataclasses.replace(DEFAULTS, chunk_frames=256)
    back, size = _round_trip(five)  # written as format 6: chunks of 256 are not its default
    assert back == five and size == 13


def test_the_bound_is_rounded_down_to_float32():
    bound = 0.049908099359818166
    settings = Settings.create(0.05, bound, 1.0, 1.0, 0.45, 0.05, 0.01, 0.0, 128, 128)
    assert settings.bound_cm <= bound and settings.bound_cm == float(np.float32(settings.bound_cm))
    assert bound - settings.bound_cm < 1e-8


def test_unknown_settings_flags_are_one_bitstream_error():
    writer = ByteWriter()
    writer.write_f32(0.05)
    writer.write_f32(0.0499)
    writer.write_varint(1 << 12)  # a flag past the known settings
    writer.write_bytes(bytes(64))
    with pytest.raises(BitstreamError, match="unknown settings flags"):
        Settings.read(ByteReader(writer.getvalue()), 4)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.lists(st.integers(0, 127), min_size=1, max_size=200))
def test_small_ints_round_trip(values):
    values = np.array(values)
    writer = ByteWriter()
    write_small_ints(writer, values)
    data = writer.getvalue()
    reader = ByteReader(data)
    np.testing.assert_array_equal(read_small_ints(reader, len(values), 128, "test"), values)
    reader.expect_end("small ints")
    spread = int(values[values != 0].max() - values[values != 0].min()).bit_length() if values.any() else 0
    assert len(data) <= (len(values) + 7) // 8 + 2 + (np.count_nonzero(values) * spread + 7) // 8


def test_small_ints_beyond_their_limit_or_cut_short_are_one_bitstream_error():
    writer = ByteWriter()
    write_small_ints(writer, np.array([0, 100, 127, 3]))
    data = writer.getvalue()
    with pytest.raises(BitstreamError, match="below 100"):
        read_small_ints(ByteReader(data), 4, 100, "test")
    with pytest.raises(BitstreamError):
        read_small_ints(ByteReader(data[:-1]), 4, 128, "test")
    with pytest.raises(BitstreamError, match="width"):
        read_small_ints(ByteReader(data[:1] + bytes([5, 9]) + bytes(8)), 4, 128, "test")


def _rig(repeat: bool = True) -> Skeleton:
    motion = sinusoidal_motion(num_frames=2, seed=3)
    skeleton = motion.skeleton
    offsets = skeleton.offsets.copy()
    if repeat:
        offsets[7] = offsets[4]  # an exact repeat, as an ASF rig's clavicles
    return dataclasses.replace(skeleton, offsets=offsets)


@pytest.mark.parametrize("exponent", [-20, -14, -9, 0])
def test_stepped_skeleton_blob_keeps_offsets_within_half_a_grid_step(exponent):
    skeleton = _rig()
    blob = pack_skeleton_compact(skeleton, exponent)
    reader = ByteReader(blob)
    back = unpack_skeleton_compact(reader, stepped=True)
    reader.expect_end("skeleton")
    step = 2.0**exponent
    assert np.abs(back.offsets - skeleton.offsets).max() <= step / 2 + 1e-12
    assert np.abs(back.end_site_offsets - skeleton.end_site_offsets).max() <= step / 2 + 1e-12
    np.testing.assert_array_equal(back.offsets[7], back.offsets[4])
    assert back.names == skeleton.names and back.channel_orders == skeleton.channel_orders
    np.testing.assert_array_equal(back.parents, skeleton.parents)
    if exponent >= -16:  # no finer than the fixed 2^-16 cm varint layout: smaller than it
        assert len(blob) < len(pack_skeleton_compact(skeleton))


def test_a_repeat_that_names_a_later_offset_is_one_bitstream_error():
    codes = np.array([[0, 0, 0], [5, -3, 0], [5, -3, 0]])
    packed = bytearray(_pack_offsets(codes))
    np.testing.assert_array_equal(_unpack_offsets(bytes(packed), 3), codes)
    # bits after the width byte: repeat flags 0 1, then the source of vector 2 in 2 bits: 01 -> 11 (vector 3)
    packed[1] |= 0b00110000
    with pytest.raises(BitstreamError, match="repeated offset"):
        _unpack_offsets(bytes(packed), 3)
    with pytest.raises(BitstreamError):
        _unpack_offsets(bytes(packed[:1]), 3)
    with pytest.raises(BitstreamError, match="follow"):
        _unpack_offsets(_pack_offsets(codes) + bytes(1), 3)


@pytest.mark.parametrize("eps", [0.001, 0.05, 0.5, 1.0, 10.0])
def test_the_skeleton_grid_costs_at_most_a_third_of_eps(eps):
    skeleton = _rig(repeat=False)
    exponent = skeleton_step_exponent(eps, skeleton)
    chain = dataclasses.replace(  # a 30-bone chain: the worst case grows with the depth, so must the grid's fineness
        skeleton, parents=np.arange(-1, 30), offsets=np.full((31, 3), 0.37))
    assert skeleton_step_exponent(eps, chain) < exponent
    stored = unpack_skeleton_compact(ByteReader(pack_skeleton_compact(skeleton, exponent)), stepped=True)
    assert 2 * offset_discrepancy_cm(skeleton, stored) <= eps / 3  # the encoder refuses at eps / 2
    assert skeleton_step_exponent(2 * eps, skeleton) >= exponent  # a coarser bound, a grid no finer


def test_a_format_6_stream_reads_its_counts_from_the_header(synthetic_motion):
    codec = create("mcb-rot", eps_cm=0.5, segment_frames=32, chunk_frames=64)
    data = codec.encode(synthetic_motion)
    header, payload = container.unpack(data, "mcb-rot")
    assert payload[0] == 6
    info = stream.read_info(header, payload)
    assert info.counts.shape == (info.layout.num_segments, info.channels)
    assert np.all(info.counts <= (info.layout.lengths - 1)[:, None])
    whole = codec.decode(data)
    part = codec.decode_frames(data, 70, 170)
    np.testing.assert_array_equal(part.positions, whole.positions[70:170])


@pytest.mark.parametrize("skip, count", [(0, 1), (5, 1), (31, 2), (20, 30), (0, 64)])
def test_assemble_on_some_frames_of_segments_equals_those_frames_of_the_whole(synthetic_motion, skip, count):
    """Random access maps only the frames asked for to quaternions (re-references included): bit for bit what the
    whole segments give at those frames."""
    codec = create("mcb-rot", eps_cm=0.5, segment_frames=32, chunk_frames=64)
    header, payload = container.unpack(codec.encode(synthetic_motion), "mcb-rot")
    info = stream.read_info(header, payload)
    turn = np.array([0.6, 0.0, 0.8, 0.0])  # a unit quaternion (x, y, z, w)
    info = info.replace(overrides={(1, 2): turn, (2, 0): turn[[1, 2, 3, 0]]})
    segments = np.array([1, 2])
    coefficients = {s: np.random.default_rng(s).integers(-3, 4, size=(int(info.layout.lengths[s]) - 1, info.channels))
                    for s in segments.tolist()}
    roots, quats = stream.assemble(info, segments, stream.base_signal(info, segments, coefficients))
    part = stream.base_signal(info, segments, coefficients)[:, skip : skip + count]
    part_roots, part_quats = stream.assemble(info, segments, part, skip=skip)
    np.testing.assert_array_equal(part_roots, roots[skip : skip + count])
    np.testing.assert_array_equal(part_quats, quats[skip : skip + count])


@pytest.mark.parametrize("nominal", [1, 16, 30, 64, 100, 128, 256, 1000, 4096])
def test_the_integer_bands_are_the_float_formula_s(nominal):
    """Format 6's classes must not depend on a ``log2``: the integer bands equal the float formula formats 2-5
    were written with, on every segment length up to the nominal one."""
    from mocapbench.codecs.mcb_rot.classes import NUM_BANDS, band_of

    for length in range(1, nominal + 1):
        k = np.arange(1, length)
        expected = np.minimum(NUM_BANDS - 1, 1 + np.floor(2 * np.log2(np.maximum(1.0, k * (nominal / length)))))
        np.testing.assert_array_equal(band_of(k, length, nominal), expected.astype(np.int64))
