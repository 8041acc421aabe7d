"""The container: self-describing header, checked before any payload is read."""

from __future__ import annotations

import struct
import zlib

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapbench.codecs import container
from mocapbench.codecs.container import BitstreamError


def _stream(payload=b"payload-bytes", codec="test-codec"):
    return container.pack(codec, 120, 31, 120.0, payload)


def test_header_round_trip():
    header, payload = container.read_header(_stream())
    assert (header.codec, header.num_frames, header.num_joints, header.fps) == ("test-codec", 120, 31, 120.0)
    assert bytes(payload) == b"payload-bytes"
    assert header.header_bytes + header.payload_bytes == len(_stream())


def test_wrong_magic():
    data = b"XXXX" + _stream()[4:]
    with pytest.raises(BitstreamError, match=r"expected magic b'MCB\\x00', found b'XXXX'"):
        container.read_header(data)


def test_unknown_version():
    data = bytearray(_stream())
    data[4] = 99
    with pytest.raises(BitstreamError, match=r"expected one of \[1, 2\], found 99"):
        container.read_header(bytes(data))


def test_other_codec_names_both():
    with pytest.raises(BitstreamError, match="'mine' decoder was given a stream written by 'test-codec'"):
        container.unpack(_stream(), "mine")


@given(st.binary(max_size=64))
@settings(max_examples=100, deadline=None)
def test_every_truncation_raises(payload):
    data = _stream(payload)
    for length in range(len(data)):
        with pytest.raises(BitstreamError):
            container.read_header(data[:length])


def test_trailing_bytes_rejected():
    with pytest.raises(BitstreamError, match="longer than its header says"):
        container.read_header(_stream() + b"\x00")


def test_flipped_payload_bit_fails_crc():
    data = bytearray(_stream())
    data[-1] ^= 0x10
    with pytest.raises(BitstreamError, match="CRC32"):
        container.read_header(bytes(data))


def test_payload_length_claiming_more_than_present_is_caught_before_allocation():
    name = b"c"
    body = bytes([len(name)]) + name + struct.pack("<IHdI", 10, 3, 30.0, 2**31 - 1) + b"abc"
    data = container.MAGIC + bytes([1]) + struct.pack("<I", zlib.crc32(body)) + body
    with pytest.raises(BitstreamError, match=r"declares a 2147483647-byte payload, found 3"):
        container.read_header(data)


def test_size_fields_out_of_range_rejected():
    name = b"c"
    body = bytes([len(name)]) + name + struct.pack("<IHdI", 0, 3, 30.0, 0)
    data = container.MAGIC + bytes([1]) + struct.pack("<I", zlib.crc32(body)) + body
    with pytest.raises(BitstreamError, match="found F=0"):
        container.read_header(data)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"codec": ""}, "Codec name"),
        ({"num_frames": 0}, "num_frames"),
        ({"num_joints": 5000}, "num_joints"),
        ({"fps": float("nan")}, "fps"),
    ],
)
def test_pack_rejects_bad_fields(kwargs, message):
    args = {"codec": "c", "num_frames": 1, "num_joints": 1, "fps": 30.0, "payload": b""} | kwargs
    with pytest.raises(ValueError, match=message):
        container.pack(**args)


def test_not_bytes():
    with pytest.raises(BitstreamError, match="as bytes, got str"):
        container.read_header("MCB")


def test_source_unit_and_up_axis_round_trip():
    data = container.pack("c", 5, 2, 30.0, b"xy", source_unit_cm=0.1, up_axis="z")
    header, payload = container.read_header(data)
    assert header.version == 2 and header.up_axis == "z" and bytes(payload) == b"xy"
    assert header.source_unit_cm == pytest.approx(0.1, rel=1e-7)
    # Defaults: cm, unknown axis; the two fields cost 5 bytes.
    plain, _ = container.read_header(container.pack("c", 5, 2, 30.0, b"xy"))
    assert (plain.source_unit_cm, plain.up_axis) == (1.0, "?")
    assert header.header_bytes == plain.header_bytes == 4 + 1 + 4 + 1 + 1 + 4 + 2 + 8 + 4 + 1 + 4


def test_version_1_streams_still_read():
    name = b"c"
    body = bytes([len(name)]) + name + struct.pack("<IHdI", 10, 3, 30.0, 2) + b"ab"
    data = container.MAGIC + bytes([1]) + struct.pack("<I", zlib.crc32(body)) + body
    header, payload = container.read_header(data)
    assert (header.version, header.num_frames, header.source_unit_cm, header.up_axis) == (1, 10, 1.0, "?")
    assert bytes(payload) == b"ab"


@pytest.mark.parametrize(
    ("unit", "axis"),
    [(0.0, b"y"), (-1.0, b"y"), (float("nan"), b"y"), (2e6, b"y"), (1e6, b"y"), (1e-45, b"y"), (5e-5, b"y"),
     (1.0, b"w")],
)
def test_corrupt_unit_or_axis_rejected(unit, axis):
    name = b"c"
    body = bytes([len(name)]) + name + struct.pack("<IHdfcI", 10, 3, 30.0, unit, axis, 0)
    data = container.MAGIC + bytes([2]) + struct.pack("<I", zlib.crc32(body)) + body
    with pytest.raises(BitstreamError, match="Corrupt header: expected a source unit"):
        container.read_header(data)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [({"source_unit_cm": 0.0}, "source_unit_cm"), ({"source_unit_cm": 1e-45}, r"source_unit_cm must be in \[0.0001"),
     ({"source_unit_cm": 1e6}, r"100000\] cm, got 1000000.0"), ({"up_axis": "up"}, "up_axis")],
)
def test_pack_refuses_bad_unit_or_axis(kwargs, message):
    with pytest.raises(ValueError, match=message):
        container.pack("c", 5, 2, 30.0, b"", **kwargs)


@pytest.mark.parametrize("unit", [container.MIN_UNIT_CM, 0.1, 2.54, 100.0, container.MAX_UNIT_CM])
def test_units_at_the_ends_of_the_range_round_trip_through_float32(unit):
    header, _ = container.read_header(container.pack("c", 5, 2, 30.0, b"", source_unit_cm=unit))
    assert header.source_unit_cm == pytest.approx(unit, rel=1e-7)
