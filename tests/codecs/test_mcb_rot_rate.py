"""mcb-rot's rate estimate (what the rate search ranks attempts by) ranks them as their real payload sizes do."""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench.codecs import create
from mocapbench.codecs.mcb_rot.codec import _SEARCH_GRID
from mocapbench.synthetic import sinusoidal_motion


def _real_and_estimated(motion, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """Payload bytes and estimated bytes of the stream at every multiplier of the search grid, both slopes."""
    real, estimated = [], []
    for multiplier in _SEARCH_GRID:
        for slope in (1.0, 0.0):
            codec = create("mcb-rot", eps_cm=eps, step_rel=multiplier, frequency_slope=slope)
            real.append(len(codec.encode(motion)))
            estimated.append(codec.last_encode_stats["estimated_bytes"])
    return np.array(real), np.array(estimated)


@pytest.mark.parametrize(
    "motion, eps",
    [
        (sinusoidal_motion(num_frames=300, seed=3, amplitude_deg=40.0, max_frequency_hz=3.0), 0.1),
        (sinusoidal_motion(num_frames=200, seed=5, amplitude_deg=20.0, max_frequency_hz=6.0), 1.0),
    ],
)
def test_estimate_picks_the_multiplier_real_sizes_pick(motion, eps):
    real, estimated = _real_and_estimated(motion, eps)
    # The attempt the estimate ranks first is the smallest real stream, or within 0.5 % of it.
    assert real[np.argmin(estimated)] <= 1.005 * real.min()
    # The estimate leaves out the header common to all attempts: real - estimate is about one constant, to 2 % of
    # the stream among the attempts that contend (within 20 % of the best).
    offset = real - estimated
    assert offset.min() > 0
    near = offset[real <= 1.2 * real.min()]
    assert near.max() - near.min() < 0.02 * real.min()
    assert np.corrcoef(real, estimated)[0, 1] > 0.999


def test_estimate_counts_the_corrections():
    """Two attempts that differ only by their corrections: the one with more corrections is estimated larger."""
    motion = sinusoidal_motion(num_frames=150, seed=11, amplitude_deg=30.0, max_frequency_hz=4.0)
    coarse = create("mcb-rot", eps_cm=0.1, step_rel=16.0)
    coarse.encode(motion)
    plain = create("mcb-rot", eps_cm=0.1, step_rel=16.0, greedy_corrections=False)
    plain.encode(motion)
    assert plain.last_encode_stats["corrections"] > coarse.last_encode_stats["corrections"] > 0
    assert plain.last_encode_stats["estimated_bytes"] > coarse.last_encode_stats["estimated_bytes"]
