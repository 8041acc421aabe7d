"""Shards: a codec config's clips cut into contiguous shards of about equal frames, sized to a CPU budget."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from mocapbench.experiments.aggregate import aggregate
from mocapbench.experiments.shards import shard_clips, shard_count, shard_folder, split

REPO = Path(__file__).resolve().parents[2]
FOUR = ["dataset.clips.seeds=[1,2,3,4]", "dataset.clips.num_frames=30", "dataset.train.clips.num_frames=30"]
MEASURED = ["codec", "config_hash", "clip", "frames", "bitstream_bytes", "max_err_cm", "mean_err_cm"]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(1, 5000), min_size=1, max_size=60), st.integers(1, 80))
def test_split_covers_every_clip_once_in_order_with_balanced_shards(frames, count):
    ranges = split(frames, count)
    assert len(ranges) == min(count, len(frames))
    assert [i for r in ranges for i in r] == list(range(len(frames)))
    assert all(len(r) > 0 for r in ranges)
    total = sum(frames)
    # A shard exceeds the equal share by less than the largest clip plus half of another (the midpoint rule).
    assert max(sum(frames[i] for i in r) for r in ranges) <= total / len(ranges) + 1.5 * max(frames)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.integers(1, 5000), min_size=1, max_size=40), st.floats(1e-4, 1e-1), st.floats(1.0, 500.0))
def test_shard_count_keeps_every_shard_under_the_budget_unless_one_clip_is_over_it(frames, per_frame, budget):
    count = shard_count(frames, per_frame, budget)
    shards = split(frames, count)
    worst = max(per_frame * sum(frames[i] for i in r) for r in shards)
    assert worst <= budget or count == len(frames)  # else one shard per clip: a clip is never cut
    if count > 1:  # the fewest shards: one fewer would break the budget
        fewer = split(frames, count - 1)
        assert max(per_frame * sum(frames[i] for i in r) for r in fewer) > budget


def test_shard_clips_and_folders():
    class Ref:
        def __init__(self, name, frames):
            self.name, self.frames = name, frames

    refs = [Ref("a", 100), Ref("b", 100), Ref("c", 100), Ref("d", 100)]
    assert [r.name for r in shard_clips(refs, 1, 2)] == ["c", "d"]
    assert shard_clips(refs, 5, 6) == []  # more shards than clips: the extra ones are empty
    assert shard_folder("svd/codec.rank=2", 0, 1) == "svd/codec.rank=2"
    assert shard_folder("svd/codec.rank=2", 1, 12) == "svd/codec.rank=2/shard-002-of-012"
    assert shard_count([100] * 4, 0.01, None) == 1


def _sweep(folder: Path, *overrides: str) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "mocapbench.experiments.run", "-m", "codec=quant-delta-zstd",
               "codec.step_cm=0.1,1.0", *overrides, *FOUR, f"hydra.sweep.dir={folder}"]
    return subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=300)


def test_a_sharded_sweep_measures_the_same_rows_as_one_job_per_config(tmp_path):
    whole, sharded = tmp_path / "whole", tmp_path / "sharded"
    assert _sweep(whole).returncode == 0
    result = _sweep(sharded, "shard.max_cpu_s=1e-9")  # every clip over the budget: one shard per clip
    assert result.returncode == 0, result.stderr[-2000:]
    plan = json.loads((sharded / "shards.json").read_text())
    assert sorted(plan.values()) == [4, 4]
    folders = sorted(p.parent.relative_to(sharded).as_posix() for p in sharded.rglob("job.json"))
    assert folders == [f"quant-delta-zstd/codec.step_cm={s}/shard-00{i}-of-004" for s in ("0.1", "1.0")
                       for i in range(1, 5)]
    for path in sharded.rglob("results.jsonl"):
        assert len(path.read_text().splitlines()) == 1  # each shard measured its own clip only
    a = aggregate([whole]).sort_values(["config_hash", "clip"])[MEASURED].reset_index(drop=True)
    b = aggregate([sharded]).sort_values(["config_hash", "clip"])[MEASURED].reset_index(drop=True)
    assert a.equals(b) and len(a) == 8

    # Resume keeps the recorded plan, whatever the budget says now; nothing runs again.
    again = _sweep(sharded)
    assert again.returncode == 0 and "8 already done, 0 to run" in again.stdout + again.stderr
