"""Shards: a codec config's clips packed into shards sized to a CPU budget (balanced, or contiguous runs)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapbench.experiments.aggregate import aggregate
from mocapbench.experiments.shards import PACKINGS, pack, shard_clips, shard_count, shard_folder, split

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


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(1, 5000), min_size=1, max_size=60), st.integers(1, 80), st.sampled_from(PACKINGS))
def test_pack_puts_every_clip_in_one_shard(frames, count, packing):
    shards = pack(frames, count, packing)
    assert len(shards) == min(count, len(frames)) and all(shards)
    assert sorted(i for shard in shards for i in shard) == list(range(len(frames)))
    assert all(shard == sorted(shard) for shard in shards)  # each shard lists its clips in catalogue order
    assert pack(list(frames), count, packing) == shards  # the same catalogue gives the same shards
    if packing == "balanced":  # LPT: a shard's last clip went to the emptiest shard, at most the mean then
        assert max(sum(frames[i] for i in s) for s in shards) <= sum(frames) / len(shards) + max(frames)
    else:
        assert [i for shard in shards for i in shard] == list(range(len(frames)))  # contiguous runs, in order


@settings(max_examples=100, deadline=None)
@given(st.lists(st.integers(1, 5000), min_size=1, max_size=40), st.floats(1e-4, 1e-1), st.floats(1.0, 500.0),
       st.sampled_from(PACKINGS))
def test_shard_count_keeps_every_shard_under_the_budget_unless_one_clip_is_over_it(frames, per_frame, budget,
                                                                                    packing):
    def over(shards):
        return [s for s in shards if len(s) > 1 and per_frame * sum(frames[i] for i in s) > budget]

    count = shard_count(frames, per_frame, budget, packing=packing)
    assert not over(pack(frames, count, packing))  # a clip is never cut: only a shard of one clip may be over
    alone = sum(1 for f in frames if per_frame * f > budget)
    bound = alone + math.ceil(sum(per_frame * f for f in frames if per_frame * f <= budget) / budget - 1e-9)
    if count > max(1, bound):  # the fewest: one fewer breaks the budget (fewer than the bound cannot fit)
        assert over(pack(frames, count - 1, packing))


def test_one_long_clip_gets_a_shard_of_its_own_and_the_rest_stay_full():
    frames = [100] * 50 + [2000] + [100] * 50  # 1 CPU s per frame, 1000 CPU s budget: the long clip is over it
    balanced = shard_count(frames, 1.0, 1000.0)
    assert balanced == 11  # the long clip alone, then 10,000 frames in 10 full shards
    shards = pack(frames, balanced)
    assert [50] in shards and sorted(sum(frames[i] for i in s) for s in shards if s != [50]) == [1000] * 10
    assert shard_count(frames, 1.0, 1000.0, packing="contiguous") == 12  # equal runs around the long clip


def test_shard_clips_and_folders():
    class Ref:
        def __init__(self, name, frames):
            self.name, self.frames = name, frames

    refs = [Ref("a", 100), Ref("b", 100), Ref("c", 100), Ref("d", 100)]
    assert [r.name for r in shard_clips(refs, 1, 2)] == ["b", "d"]
    assert [r.name for r in shard_clips(refs, 1, 2, "contiguous")] == ["c", "d"]
    assert shard_clips(refs, 5, 6) == []  # more shards than clips: the extra ones are empty
    assert shard_folder("svd/codec.rank=2", 0, 1) == "svd/codec.rank=2"
    assert shard_folder("svd/codec.rank=2", 1, 12) == "svd/codec.rank=2/shard-002-of-012"
    assert shard_count([100] * 4, 0.01, None) == 1
    with pytest.raises(ValueError, match="shard.packing must be one of balanced, contiguous, got 'lpt'"):
        shard_clips(refs, 0, 2, "lpt")


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
    assert plan["packing"] == "balanced" and sorted(plan["counts"].values()) == [4, 4]
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


def test_a_sweep_whose_shards_file_predates_balanced_packing_resumes_with_contiguous_shards(tmp_path):
    folders = [f"quant-delta-zstd/codec.step_cm={s}" for s in ("0.1", "1.0")]
    tmp_path.mkdir(exist_ok=True)
    (tmp_path / "shards.json").write_text(json.dumps({folder: 2 for folder in folders}))  # the older format
    result = _sweep(tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    for folder in folders:
        clips = [[json.loads(line)["clip"] for line in (tmp_path / folder / f"shard-00{i}-of-002" /
                                                         "results.jsonl").read_text().splitlines()] for i in (1, 2)]
        assert [len(c) for c in clips] == [2, 2] and sorted(clips[0])[-1] < sorted(clips[1])[0]  # runs, in order
    plan = json.loads((tmp_path / "shards.json").read_text())
    assert plan == {"packing": "contiguous", "counts": {folder: 2 for folder in folders}}
