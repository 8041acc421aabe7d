"""mcb-linf: the L-infinity bound holds on every joint of every frame, whatever the motion."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapbench import metrics
from mocapbench.codecs import create
from mocapbench.codecs.mcb_linf import bcc_quantize
from mocapbench.synthetic import sinusoidal_motion


@settings(max_examples=25, deadline=None, derandomize=True)
@given(
    seed=st.integers(0, 10_000),
    frames=st.integers(1, 400),
    eps=st.sampled_from([0.05, 0.3, 1.0, 2.5, 7.0]),
    clip=st.sampled_from([4, 17, 120]),
    representation=st.sampled_from(["bone", "absolute"]),
    amplitude=st.floats(0.0, 60.0),
)
def test_bound_holds_on_random_synthetic_motions(seed, frames, eps, clip, representation, amplitude):
    motion = sinusoidal_motion(num_frames=frames, seed=seed, amplitude_deg=amplitude, max_frequency_hz=6.0)
    codec = create("mcb-linf", eps_cm=eps, clip_frames=clip, representation=representation)
    decoded = create("mcb-linf").decode(codec.encode(motion))  # a fresh codec: nothing beside the bytes
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= eps


def test_bound_is_used_not_wasted(synthetic_motion):
    """The error is close to eps (a codec that codes losslessly would also meet the bound, at a high rate)."""
    codec = create("mcb-linf", eps_cm=1.0)
    data = codec.encode(synthetic_motion)
    error = metrics.max_joint_error(synthetic_motion.positions(), codec.decode(data).positions)
    assert 0.5 < error <= 1.0
    baseline = create("quant-delta-zstd", step_cm=2 / np.sqrt(3)).encode(synthetic_motion)
    assert len(data) < len(baseline), "mcb-linf should beat the generic baseline at equal L-inf"


def test_rate_falls_as_the_bound_grows(synthetic_motion):
    sizes = [len(create("mcb-linf", eps_cm=eps).encode(synthetic_motion)) for eps in (0.1, 0.5, 2.0, 8.0)]
    assert sizes == sorted(sizes, reverse=True) and sizes[0] > 2 * sizes[-1]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-50, 50), min_size=3, max_size=3), st.floats(0.01, 10.0))
def test_bcc_lattice_covers_within_radius(point, radius):
    coords, half_cell = bcc_quantize(np.array([point]), radius)
    assert np.all(coords % 2 == coords[0, 0] % 2)  # all even or all odd
    assert np.linalg.norm(coords[0] * half_cell - point) <= radius * (1 + 1e-12)


def test_static_motion_and_single_frame(synthetic_motion):
    still = synthetic_motion.slice(0, 1)
    codec = create("mcb-linf", eps_cm=0.2)
    decoded = codec.decode(codec.encode(still))
    assert metrics.max_joint_error(still.positions(), decoded.positions) <= 0.2


def test_bad_config_values_are_rejected():
    with pytest.raises(ValueError, match=r"eps_cm must be in \[0.001, 100.0\] cm, got 0.0"):
        create("mcb-linf", eps_cm=0.0)
    with pytest.raises(ValueError, match="representation must be one of"):
        create("mcb-linf", representation="quaternion")
