"""quant-pred-zstd, the BD-rate anchor: same decoded positions as quant-delta-zstd, fewer bytes, the right order."""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench.codecs import container, create
from mocapbench.codecs.baselines.codecs import _predict, _reconstruct
from mocapbench.entropy.backend import zstd_pack_ints, zstd_unpack_ints
from mocapbench.motion import Motion, Skeleton


@pytest.mark.parametrize("step, gain", [(0.05, 0.95), (0.5, 0.95), (2.0, 1.0)])
def test_same_positions_as_quant_delta_zstd_in_fewer_bytes(synthetic_motion, step, gain):
    # At 2 cm the synthetic residuals fit one byte: the shuffle has nothing to regroup, only the order helps.
    old, new = create("quant-delta-zstd", step_cm=step), create("quant-pred-zstd", step_cm=step)
    old_data, new_data = old.encode(synthetic_motion), new.encode(synthetic_motion)
    np.testing.assert_array_equal(new.decode(new_data).positions, old.decode(old_data).positions)
    assert len(new_data) < gain * len(old_data), (len(new_data), len(old_data))


@pytest.mark.parametrize("order", [1, 2])
def test_prediction_inverts_exactly(order):
    tracks = np.random.default_rng(order).integers(-(1 << 40), 1 << 40, size=(5, 17))
    np.testing.assert_array_equal(_reconstruct(_predict(tracks, order), order), tracks)
    single = tracks[:, :1]
    np.testing.assert_array_equal(_reconstruct(_predict(single, order), order), single)


def _one_joint(path: np.ndarray) -> Motion:
    skeleton = Skeleton(names=("root",), parents=np.array([-1]), offsets=np.zeros((1, 3)))
    rotations = np.tile([0.0, 0.0, 0.0, 1.0], (len(path), 1, 1))
    return Motion(skeleton, 120.0, path, rotations)


def test_order_is_chosen_per_stream():
    t = np.arange(600)[:, None]
    smooth = _one_joint(np.hstack([0.002 * t**2, 3.0 * t, 50 + 0 * t]).astype(float))  # constant 2nd difference
    walk = _one_joint(np.cumsum(np.random.default_rng(0).normal(size=(600, 3)) * 10, axis=0))  # white 1st difference
    codec = create("quant-pred-zstd", step_cm=0.1)
    orders = {}
    for name, motion in (("smooth", smooth), ("walk", walk)):
        header, payload = container.unpack(codec.encode(motion), "quant-pred-zstd")
        orders[name] = codec.describe_payload(header, payload)["prediction_order"]
        assert codec.last_encode_stats["prediction_order"] == orders[name]
    assert orders == {"smooth": 2, "walk": 1}


def test_byte_shuffle_round_trips_every_width():
    for peak in (100, 30_000, 2_000_000_000, 1 << 61):
        values = np.random.default_rng(peak).integers(-peak, peak, size=1001)
        blob = zstd_pack_ints(values, 3, shuffle=True)
        np.testing.assert_array_equal(zstd_unpack_ints(blob, values.size, shuffle=True), values)


@pytest.mark.parametrize("frames, width", [(10**6, None), (None, 8)])
def test_a_header_or_width_that_disagrees_with_the_zstd_frame_is_refused_before_decoding(synthetic_motion, frames,
                                                                                          width):
    from mocapbench.codecs import BitstreamError

    codec = create("quant-pred-zstd")
    header, payload = container.unpack(codec.encode(synthetic_motion), "quant-pred-zstd")
    payload = bytearray(payload)
    if width is not None:
        from mocapbench.entropy.bitio import ByteReader

        reader = ByteReader(bytes(payload))
        reader.read_bytes(8 + 1, "step and order")
        reader.read_varint("blob length")
        payload[reader.offset] = width  # the blob's first byte: the width of the zigzag codes (1 here)
    stream = container.pack("quant-pred-zstd", frames or header.num_frames, header.num_joints, header.fps,
                            bytes(payload))
    with pytest.raises(BitstreamError, match="expected a zstd frame of"):
        codec.decode(stream)
