"""mcb-rot's rate search: its estimate ranks attempts as their real payload sizes do, and its walk finds the minimum."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from mocapbench.codecs import create
from mocapbench.codecs.mcb_rot.codec import _SEARCH_GRID, _SEARCH_START, _search
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


class _FakeAttempts:
    """Attempts with given sizes per grid index (sloped) and per index (flat), recording what was asked."""

    def __init__(self, sloped, flat, share):
        self.sloped, self.flat, self.share, self.asked = sloped, flat, share, []

    def __call__(self, multiplier, slope=None, budget=np.inf):
        index = _SEARCH_GRID.index(multiplier)
        self.asked.append((index, slope))
        size = float((self.flat if slope == 0.0 else self.sloped)[index])
        if size > budget:
            size = np.inf  # given up, as the encoder does over budget
        return SimpleNamespace(size=size, base=(1.0 - self.share) * size, multiplier=multiplier)


@pytest.mark.parametrize("best", range(len(_SEARCH_GRID)))
@pytest.mark.parametrize("share", [0.02, 0.5])
def test_search_finds_the_minimum_of_a_unimodal_size_whichever_way_it_walks_first(best, share):
    sloped = [1000.0 + 10.0 * (i - best) ** 2 for i in range(len(_SEARCH_GRID))]
    flat = [size + 50.0 for size in sloped]  # flat never wins here
    fake = _FakeAttempts(sloped, flat, share)
    chosen = _search(fake, flat_too=True)
    assert chosen.size == min(sloped)
    assert _SEARCH_GRID.index(chosen.multiplier) == best
    sloped_asked = [index for index, slope in fake.asked if slope is None]
    assert len(sloped_asked) == len(set(sloped_asked))  # no attempt twice
    assert len(sloped_asked) <= abs(best - _SEARCH_START) + 3


def test_search_walks_finer_first_when_corrections_dominate_and_takes_a_winning_flat_step():
    best = _SEARCH_START - 1
    sloped = [1000.0 + 10.0 * (i - best) ** 2 for i in range(len(_SEARCH_GRID))]
    flat = [size - 20.0 if i == best + 1 else size + 100.0 for i, size in enumerate(sloped)]
    fake = _FakeAttempts(sloped, flat, share=0.5)
    chosen = _search(fake, flat_too=True)
    # start, one finer (wins), one finer still (loses): the coarser side is never tried.
    assert [index for index, slope in fake.asked if slope is None] == [_SEARCH_START, best, best - 1]
    assert chosen.size == flat[best + 1]
    coarse = _FakeAttempts(sloped, flat, share=0.02)
    _search(coarse, flat_too=True)
    assert len(coarse.asked) == len(fake.asked) + 1  # the coarse-first walk pays one attempt more


def test_closed_loop_kinematics_match_the_decoders():
    """The encoder's forward kinematics (positions and global rotations) agree with the decoder's and scipy's."""
    from scipy.spatial.transform import Rotation

    from mocapbench.codecs.mcb_rot.checks import forward_kinematics
    from mocapbench.codecs.mcb_rot.kinematics import positions

    motion = sinusoidal_motion(num_frames=40, seed=2, amplitude_deg=60.0, max_frequency_hz=5.0)
    placed, glob = forward_kinematics(motion.rotations, motion.root_positions, motion.skeleton)
    np.testing.assert_allclose(placed, positions(motion.rotations, motion.root_positions, motion.skeleton), atol=1e-9)
    np.testing.assert_allclose(placed, motion.positions(), atol=1e-9)
    matrices, _ = motion.global_transforms()
    np.testing.assert_allclose(Rotation.from_quat(glob.reshape(-1, 4)).as_matrix(), matrices.reshape(-1, 3, 3),
                               atol=1e-12)


@pytest.mark.parametrize("best", [2, _SEARCH_START - 1, _SEARCH_START, _SEARCH_START + 2])
@pytest.mark.parametrize("share", [0.02, 0.5])
@pytest.mark.parametrize("flat_wins", [False, True])
def test_walk_limit_is_the_next_budget_of_the_walk_and_bounds_every_later_one(best, share, flat_wins):
    """Run on the attempts the walk has read so far, _walk_limit returns the budget of its next request (every later
    one is no larger), and -inf once the walk has read all it needs."""
    from mocapbench.codecs.mcb_rot.codec import _walk_limit

    sloped = [1000.0 + 10.0 * (i - best) ** 2 for i in range(len(_SEARCH_GRID))]
    flat = [size - (30.0 if flat_wins and i in (best + 1, best + 2) else -40.0) for i, size in enumerate(sloped)]
    budgets = []

    def recording(multiplier, slope=None, budget=np.inf):
        budgets.append(budget)
        return fake(multiplier, slope, budget)

    fake = _FakeAttempts(sloped, flat, share)
    _search(recording, flat_too=True)
    asked = [(index, slope == 0.0) for index, slope in fake.asked]
    results = [fake(_SEARCH_GRID[index], 0.0 if flat else None, budget)
               for (index, flat), budget in zip(asked, budgets)]
    assert len(asked) >= 3
    for i in range(len(asked)):
        known = dict(zip(asked[:i], results[:i]))
        limit = _walk_limit(known, flat_too=True)
        assert limit == budgets[i]
        assert all(later <= limit for later in budgets[i:])
    assert _walk_limit(dict(zip(asked, results)), flat_too=True) == -np.inf
    assert _walk_limit({}, flat_too=True) == np.inf  # the start, unbudgeted, comes first
