"""zstd and raw LZMA2 back ends: round trips, determinism, output bounds, corrupt and truncated input."""

from __future__ import annotations

import numpy as np
import pytest
import zstandard
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapbench.entropy import BitstreamError, lzma_compress, lzma_decompress, zstd_compress, zstd_decompress

PAYLOADS = {
    "empty": b"",
    "one-byte": b"\x07",
    "compressible": b"mocap " * 2000,
    "random": np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8).tobytes(),
}
BACKENDS = {
    "zstd": (zstd_compress, zstd_decompress),
    "lzma": (lzma_compress, lzma_decompress),
}


@pytest.mark.parametrize("backend", sorted(BACKENDS))
@pytest.mark.parametrize("name", sorted(PAYLOADS))
def test_round_trip(backend, name):
    compress, decompress = BACKENDS[backend]
    data = PAYLOADS[name]
    packed = compress(data)
    assert isinstance(packed, bytes)
    assert decompress(packed, max_output_size=len(data)) == data
    assert decompress(bytearray(packed), max_output_size=len(data) + 10) == data


@pytest.mark.parametrize("backend", sorted(BACKENDS))
def test_compresses_redundant_data_and_is_deterministic(backend):
    compress, _ = BACKENDS[backend]
    data = PAYLOADS["compressible"]
    packed = compress(data)
    assert len(packed) < len(data) // 50
    assert compress(bytes(bytearray(data))) == packed


@pytest.mark.parametrize("backend", sorted(BACKENDS))
def test_every_truncation_raises(backend):
    compress, decompress = BACKENDS[backend]
    data = PAYLOADS["random"][:300] + PAYLOADS["compressible"][:300]
    packed = compress(data)
    for cut in range(len(packed)):
        with pytest.raises(BitstreamError):
            decompress(packed[:cut], max_output_size=len(data))


@pytest.mark.parametrize("backend", sorted(BACKENDS))
def test_trailing_bytes_raise(backend):
    compress, decompress = BACKENDS[backend]
    packed = compress(b"abc" * 10)
    with pytest.raises(BitstreamError, match=r"expected the end of data after the (frame|stream), found 4 more bytes"):
        decompress(packed + b"junk", max_output_size=100)


@pytest.mark.parametrize("backend", sorted(BACKENDS))
def test_single_byte_corruption_raises_or_keeps_the_size(backend):
    # Without a checksum a flipped literal decodes to other bytes; the container's CRC32 catches that.
    compress, decompress = BACKENDS[backend]
    data = PAYLOADS["compressible"][:2000]
    packed = bytearray(compress(data))
    errors = 0
    for i in range(len(packed)):
        packed[i] ^= 0x5A
        try:
            out = decompress(bytes(packed), max_output_size=len(data))
        except BitstreamError:
            errors += 1
        else:
            assert len(out) <= len(data)
        packed[i] ^= 0x5A
    assert errors > len(packed) // 2


@pytest.mark.parametrize("backend", sorted(BACKENDS))
def test_output_is_bounded(backend):
    compress, decompress = BACKENDS[backend]
    packed = compress(bytes(1000))
    with pytest.raises(BitstreamError, match=r"expected at most 999 bytes from (zstd|lzma)"):
        decompress(packed, max_output_size=999)


@pytest.mark.parametrize("backend", sorted(BACKENDS))
def test_garbage_raises(backend):
    _, decompress = BACKENDS[backend]
    with pytest.raises(BitstreamError, match=backend):
        decompress(b"this is not compressed data at all", max_output_size=1000)


def test_zstd_messages():
    with pytest.raises(BitstreamError, match=r"expected a zstd frame header in 0 bytes, found none"):
        zstd_decompress(b"", max_output_size=10)
    no_size = zstandard.ZstdCompressor(write_content_size=False).compressobj()
    frame = no_size.compress(b"abc") + no_size.flush()
    with pytest.raises(BitstreamError, match=r"expected a zstd frame that declares its content size"):
        zstd_decompress(frame, max_output_size=10)


@pytest.mark.parametrize(("compress", "name", "level"),
                         [(zstd_compress, "level", 0), (zstd_compress, "level", 23), (lzma_compress, "preset", 10),
                          (lzma_compress, "preset", -1), (zstd_compress, "level", 3.0)])
def test_levels_are_validated(compress, name, level):
    with pytest.raises(ValueError, match=rf"`{name}` must be an int in"):
        compress(b"x", level) if name == "level" else compress(b"x", preset=level)


@pytest.mark.parametrize("decompress", [zstd_decompress, lzma_decompress])
def test_max_output_size_is_validated(decompress):
    with pytest.raises(ValueError, match=r"`max_output_size` must be a non-negative int \(bytes\), got -1"):
        decompress(b"", max_output_size=-1)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.integers(min_value=-(2**62), max_value=2**62), max_size=200))
def test_zstd_pack_ints_round_trips_and_picks_narrow_width(values):
    from mocapbench.entropy.backend import zstd_pack_ints, zstd_unpack_ints

    blob = zstd_pack_ints(np.array(values, dtype=np.int64))
    np.testing.assert_array_equal(zstd_unpack_ints(blob, len(values)), np.array(values, dtype=np.int64))
    if values and max(abs(v) for v in values) < 64:
        assert blob[0] == 1


def test_zstd_unpack_ints_rejects_wrong_count_and_bad_width():
    from mocapbench.entropy.backend import zstd_pack_ints, zstd_unpack_ints

    blob = zstd_pack_ints(np.arange(10))
    with pytest.raises(BitstreamError, match="expected 11 bytes"):
        zstd_unpack_ints(blob, 11, "tracks")
    with pytest.raises(BitstreamError, match="width byte"):
        zstd_unpack_ints(b"\x03" + blob[1:], 10, "tracks")


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 6), st.integers(0, 300), st.sampled_from([3, 2**10, 2**20, 2**40, 2**62]), st.booleans(),
       st.booleans(), st.integers(0, 2**32 - 1))
def test_zstd_pack_tracks_is_zstd_pack_ints_without_the_array(num_tracks, length, scale, shuffle, stream, seed):
    """One shot (small inputs): the bytes of zstd_pack_ints. Streamed (as a long capture is): a frame that
    zstd_unpack_ints reads to the same values. zstd_unpack_tracks hands every track back, in order."""
    from mocapbench.entropy import backend

    values = np.random.default_rng(seed).integers(-scale, scale, size=(num_tracks, length), dtype=np.int64)
    if stream:
        original, backend.ONE_SHOT_VALUES = backend.ONE_SHOT_VALUES, 0
    try:
        blob = backend.zstd_pack_tracks(lambda i: values[i], num_tracks, length, 5, shuffle=shuffle)
    finally:
        if stream:
            backend.ONE_SHOT_VALUES = original
    if not stream:
        assert blob == backend.zstd_pack_ints(values, 5, shuffle=shuffle)
    unpacked = backend.zstd_unpack_ints(blob, values.size, shuffle=shuffle)
    np.testing.assert_array_equal(unpacked.reshape(values.shape), values)
    seen = []
    backend.zstd_unpack_tracks(blob, num_tracks, length, lambda i, row: seen.append((i, row.copy())), shuffle=shuffle)
    assert [i for i, _ in seen] == list(range(num_tracks))
    for i, row in seen:
        np.testing.assert_array_equal(row, values[i])


def test_zstd_unpack_tracks_rejects_a_wrong_size_and_bad_width():
    from mocapbench.entropy.backend import zstd_pack_tracks, zstd_unpack_tracks

    values = np.arange(30).reshape(3, 10)
    blob = zstd_pack_tracks(lambda i: values[i], 3, 10, shuffle=True)
    with pytest.raises(BitstreamError, match="expected a zstd frame of 33 bytes"):
        zstd_unpack_tracks(blob, 3, 11, lambda i, row: None, "tracks", shuffle=True)
    with pytest.raises(BitstreamError, match="width byte"):
        zstd_unpack_tracks(b"\x03" + blob[1:], 3, 10, lambda i, row: None, "tracks", shuffle=True)
    with pytest.raises(ValueError, match=r"track 1 has shape \(9,\), expected \(10,\)"):
        zstd_pack_tracks(lambda i: values[i, : 10 - i], 3, 10)
