"""Clips of a data folder are read once per process and shared, read-only, by the jobs that follow."""

from __future__ import annotations

import os
import shutil

import numpy as np
import pytest

from mocapbench.experiments import clip_cache, datasets
from mocapbench.io.asf_amc import read_amc, read_asf


@pytest.fixture
def cmu_copy(tmp_path, cmu_fixture_dir):
    """A private copy of the CMU fixture folder (a test rewrites a file in it), and an empty cache."""
    shutil.copytree(cmu_fixture_dir, tmp_path / "cmu")
    clip_cache.clear()
    yield tmp_path / "cmu"
    clip_cache.clear()


def _spec(folder, **extra):
    return {"name": "t", "kind": "cmu", "data_dir": str(folder), "clips": ["09_06"], **extra}


def test_a_clip_is_read_once_and_its_values_are_the_files(cmu_copy):
    (first,) = datasets.iter_clips(_spec(cmu_copy))
    (again,) = datasets.iter_clips(_spec(cmu_copy), ["09_06"])
    assert again is first
    fresh = read_amc(cmu_copy / "asf_amc" / "09" / "09_06.amc", read_asf(cmu_copy / "asf_amc" / "09" / "09.asf"),
                     name="09_06", fps=120.0)
    np.testing.assert_array_equal(first.rotations, fresh.rotations)
    np.testing.assert_array_equal(first.positions(), fresh.positions())
    np.testing.assert_array_equal(first.positions(), fresh.positions())  # the second call: the kept kinematics
    with pytest.raises(ValueError, match="read-only"):
        first.rotations[0, 0, 0] = 2.0  # a codec writing into its input fails instead of changing later jobs
    positions = first.positions()
    positions[:] = 0.0  # a caller's copy: what is kept does not change
    np.testing.assert_array_equal(first.positions(), fresh.positions())


def test_another_frame_step_or_a_rewritten_file_is_read_again(cmu_copy):
    (first,) = datasets.iter_clips(_spec(cmu_copy))
    (every_2nd,) = datasets.iter_clips(_spec(cmu_copy, frame_step=2))
    assert every_2nd is not first and every_2nd.num_frames == (first.num_frames + 1) // 2
    amc = cmu_copy / "asf_amc" / "09" / "09_06.amc"
    stat = amc.stat()
    os.utime(amc, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000_000))
    (reread,) = datasets.iter_clips(_spec(cmu_copy))
    assert reread is not first
    np.testing.assert_array_equal(reread.rotations, first.rotations)


def test_no_more_than_max_frames_are_kept(cmu_copy, monkeypatch):
    (first,) = datasets.iter_clips(_spec(cmu_copy))
    monkeypatch.setattr(clip_cache, "MAX_FRAMES", first.num_frames - 1)
    clip_cache.clear()
    (one,) = datasets.iter_clips(_spec(cmu_copy))
    (two,) = datasets.iter_clips(_spec(cmu_copy))
    assert one is not two  # too long to keep: read each time
