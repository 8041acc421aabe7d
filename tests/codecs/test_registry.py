"""Every registered codec, through the one interface: round trip, rate, determinism, corrupt streams.

Parametrized over ``CODECS`` so that a codec added later is tested here without touching this file; each codec
declares a fast ``smoke_params`` configuration and the L-inf bound ``smoke_max_error_cm`` it must meet.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapbench import metrics
from mocapbench.codecs import CODECS, BitstreamError, create
from mocapbench.motion import Motion

NAMES = sorted(CODECS)
_CACHE: dict[str, tuple] = {}


def _fitted(name, training_motions):
    codec = create(name, **CODECS[name].smoke_params)
    return codec.fit(training_motions)


@pytest.fixture(scope="module")
def encoded(synthetic_motion, training_motions):
    """(codec, stream) per codec, encoded once per module: some codecs train a network."""

    def get(name):
        if name not in _CACHE:
            codec = _fitted(name, training_motions)
            _CACHE[name] = (codec, codec.encode(synthetic_motion))
        return _CACHE[name]

    return get


def test_registry_is_populated():
    assert {"raw-zstd", "quant-delta-zstd", "quant-rot-zstd"} <= set(CODECS)


@pytest.mark.parametrize("name", NAMES)
def test_round_trip_within_bound_and_smaller_than_raw(name, encoded, synthetic_motion, training_motions):
    codec, data = encoded(name)
    assert isinstance(data, bytes) and len(data) > 0
    raw = metrics.raw_position_bytes(synthetic_motion.num_joints, synthetic_motion.num_frames)
    assert len(data) < raw, f"{name}: {len(data)} bytes is not smaller than the raw {raw}"
    # A fresh codec, fit on the same training motions, decodes from the bytes alone.
    decoded = _fitted(name, training_motions).decode(bytes(data))
    assert decoded.positions.shape == (synthetic_motion.num_frames, synthetic_motion.num_joints, 3)
    error = metrics.max_joint_error(synthetic_motion.positions(), decoded.positions)
    assert error <= CODECS[name].smoke_max_error_cm, f"{name}: L-inf {error:.4f} cm"
    # A codec that returned a constant or its first frame would fail this: the decoded motion moves.
    assert np.ptp(decoded.positions[:, :, 2]) > 10.0
    if CODECS[name].codes_rotations:
        assert isinstance(decoded.motion, Motion)
        np.testing.assert_allclose(decoded.motion.positions(), decoded.positions, atol=1e-9)


@pytest.mark.parametrize("name", NAMES)
def test_decode_frames_returns_the_frames_of_the_whole_decode(name, encoded, training_motions):
    """Every codec answers ``decode_frames`` (random access, or the default: a whole decode, sliced), with the frames
    the whole decode has there; an empty or outside range is a ``ValueError``."""
    codec, data = encoded(name)
    decoder = _fitted(name, training_motions)
    whole = decoder.decode(data)
    frames = whole.positions.shape[0]
    for start, stop in ((0, 1), (frames // 3, frames // 3 + 17), (frames - 5, frames)):
        part = decoder.decode_frames(data, start, stop)
        assert part.positions.shape == (stop - start, *whole.positions.shape[1:])
        np.testing.assert_allclose(part.positions, whole.positions[start:stop], rtol=0, atol=1e-9)
        if whole.motion is not None:
            assert part.motion.num_frames == stop - start
            np.testing.assert_allclose(part.motion.positions(), part.positions, rtol=0, atol=1e-9)
    for start, stop in ((5, 5), (-1, 3), (0, frames + 1)):
        with pytest.raises(ValueError):
            decoder.decode_frames(data, start, stop)


@pytest.mark.parametrize("name", NAMES)
def test_encoding_is_deterministic(name, encoded, synthetic_motion, training_motions):
    _, data = encoded(name)
    assert _fitted(name, training_motions).encode(synthetic_motion) == data


@pytest.mark.parametrize("name", NAMES)
def test_every_truncation_raises_bitstream_error(name, encoded):
    codec, data = encoded(name)
    for length in range(len(data)):
        with pytest.raises(BitstreamError):
            codec.decode(data[:length])


@pytest.mark.parametrize("name", NAMES)
def test_random_bit_flips_raise_bitstream_error(name, encoded):
    codec, data = encoded(name)

    @settings(max_examples=200, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
    @given(st.integers(min_value=0, max_value=8 * len(data) - 1))
    def flip(bit):
        corrupted = bytearray(data)
        corrupted[bit // 8] ^= 1 << (bit % 8)
        with pytest.raises(BitstreamError):
            codec.decode(bytes(corrupted))

    flip()


@pytest.mark.parametrize("name", NAMES)
def test_another_codecs_stream_names_both_codecs(name, encoded):
    other = "raw-zstd" if name != "raw-zstd" else "quant-delta-zstd"
    codec, _ = encoded(name)
    _, foreign = encoded(other)
    with pytest.raises(BitstreamError, match=f"{name}.*{other}"):
        codec.decode(foreign)


def test_unknown_codec_lists_the_known_ones():
    with pytest.raises(KeyError, match="registered codecs are.*raw-zstd"):
        create("no-such-codec")


def test_unknown_parameter_lists_the_config_fields():
    with pytest.raises(TypeError, match="config fields are.*step_cm"):
        create("quant-delta-zstd", stepcm=0.1)


def test_out_of_range_parameter_names_field_range_and_value():
    with pytest.raises(ValueError, match=r"step_cm must be in \[0.0001, 100.0\] cm, got -1.0"):
        create("quant-delta-zstd", step_cm=-1.0)


def test_wrong_parameter_type_is_rejected():
    with pytest.raises(ValueError, match="rotation_bits must be of type int"):
        create("quant-rot-zstd", rotation_bits="twelve")


def test_duplicate_registration_is_an_error():
    from mocapbench.codecs.registry import register_codec

    cls = CODECS["raw-zstd"]
    imposter = type("Imposter", (cls,), {"name": "raw-zstd"})
    with pytest.raises(ValueError, match="already registered"):
        register_codec(imposter)
