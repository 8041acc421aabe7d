"""Shared fixtures: synthetic sinusoidal skeletons (no files needed) and the CMU data folder."""

from __future__ import annotations

import pytest

from mocapbench.synthetic import sinusoidal_motion


@pytest.fixture(scope="session")
def synthetic_motion():
    """The test motion: 240 frames at 120 fps, 31 joints, seed 1."""
    return sinusoidal_motion(num_frames=240, seed=1)


@pytest.fixture(scope="session")
def training_motions():
    """Training motions for codecs that learn shared state: other seeds than the test motion."""
    return [sinusoidal_motion(num_frames=300, seed=seed) for seed in (11, 12, 13)]


@pytest.fixture(scope="session")
def cmu_09_06():
    """The real 141-frame CMU run 09_06 from ASF/AMC.

    Fails (DataNotFoundError saying where it looked) rather than skips when ../shared/data/cmu is missing:
    CI always has the data beside the clone, and a silently skipped real-data test proves nothing.
    """
    from mocapbench.datasets.cmu import load_clip

    return load_clip("09_06")
