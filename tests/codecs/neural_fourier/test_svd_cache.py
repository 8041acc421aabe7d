"""svd remembers the decomposition of the last matrices: a rate search's tries slice it; streams do not change."""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench.codecs import create
from mocapbench.codecs.neural_fourier import svd
from mocapbench.synthetic import sinusoidal_motion


@pytest.fixture
def empty_cache(monkeypatch):
    monkeypatch.setattr(svd, "_SVD_CACHE", {})
    return svd._SVD_CACHE


def _fresh_stream(motion, **config) -> bytes:
    svd._SVD_CACHE.clear()
    return create("svd", **config).encode(motion)


def test_a_rank_after_another_gives_the_stream_of_a_fresh_decomposition(empty_cache):
    motion = sinusoidal_motion(num_frames=60, seed=3)
    other = sinusoidal_motion(num_frames=60, seed=4)
    for config in ({}, {"weighted": True}, {"factor_format": "uniform", "factor_bits": 9}):
        fresh = {rank: _fresh_stream(motion, rank=rank, **config) for rank in (3, 17)}
        empty_cache.clear()
        create("svd", rank=40, **config).encode(other)  # another clip in the cache too
        for rank in (17, 3, 17):  # ranks of one search, in any order, slice the one decomposition
            assert create("svd", rank=rank, **config).encode(motion) == fresh[rank]
        assert len(empty_cache) == 2  # this clip's matrix and the other's


def test_one_decomposition_per_matrix_and_at_most_a_few_kept(empty_cache, monkeypatch):
    calls = []
    real = np.linalg.svd

    def counted(matrix, *args, **kwargs):
        calls.append(matrix.shape)
        return real(matrix, *args, **kwargs)

    monkeypatch.setattr(svd.np.linalg, "svd", counted)
    clips = [sinusoidal_motion(num_frames=30, seed=s) for s in range(4)]
    for rank in (2, 5, 9):
        create("svd", rank=rank).encode(clips[0])
    assert len(calls) == 1
    for clip in clips:
        create("svd", rank=4).encode(clip)
    assert len(calls) == 4 and len(empty_cache) == svd._SVD_CACHE_SIZE
    u, s, vt = next(iter(empty_cache.values()))
    assert not (u.flags.writeable or s.flags.writeable or vt.flags.writeable)  # no caller can alter a kept one
    before = len(calls)
    create("svd", rank=4).encode(clips[0])  # fell out of the cache: decomposed again
    assert len(calls) == before + 1
