"""Long captures are coded through windows of frames (bounded memory): the windowed streams keep every codec's
guarantees. The windows are made small here (monkeypatched) so the tests stay fast."""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench.codecs import container, create
from mocapbench.codecs.base import BitstreamError
from mocapbench.synthetic import sinusoidal_motion


def _error(codec, motion, stream):
    return np.linalg.norm(codec.decode(stream).positions - motion.positions(), axis=-1)


def test_mcb_linf_codes_a_long_capture_window_by_window_and_keeps_its_bound(monkeypatch):
    from mocapbench.codecs import mcb_linf

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


def test_pga_ik_fits_one_pose_model_per_window(monkeypatch):
    from mocapbench.codecs import pga

    motion = sinusoidal_motion(num_frames=600, seed=4)
    codec = create("pga-ik", num_geodesics=12, root_levels_dropped=0, end_levels_dropped=0)
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
    from mocapbench.codecs import svd

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
