"""The cost of a sweep before it runs: per-frame costs x frames, shards on workers, peak memory per worker."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from mocapbench.experiments.cost import cpu_cost, estimate

REPO = Path(__file__).resolve().parents[2]
COSTS = {
    "configs": {"cheap/a": {"codec": "cheap", "cpu_s_per_frame": 1e-5},
                "slow/b": {"codec": "slow", "cpu_s_per_frame": 1e-2}},
    "memory": {"cheap": {"peak_bytes_per_frame": 1000.0}, "slow": {"peak_bytes_per_frame": 20000.0}},
    "job": {"cpu_s_per_clip": 0.0, "cpu_s_per_frame": 0.0, "baseline_rss_bytes": 1e8, "motion_bytes_per_frame": 2000.0},
    "old_layout": {"rewrite_s_per_clip_squared": 1e-5, "resident_bytes_per_frame": 2000.0},
}


def test_costs_fall_back_to_the_codec_then_to_a_default():
    assert cpu_cost(COSTS, "slow/b") == (1e-2, 0.0)
    assert cpu_cost(COSTS, "slow/other-config") == (1e-2, 0.0)
    assert cpu_cost(COSTS, "unknown/x")[0] == pytest.approx(1e-3)


def test_shards_spread_a_slow_config_over_the_workers():
    frames = [1000] * 100  # 100,000 frames
    sharded = estimate(COSTS, ["cheap/a", "slow/b"], frames, workers=10, max_cpu_s=100.0)
    whole = estimate(COSTS, ["cheap/a", "slow/b"], frames, workers=10, max_cpu_s=None)
    assert sharded.cpu_h == pytest.approx(whole.cpu_h) == pytest.approx((1e-5 + 1e-2) * 1e5 / 3600)
    slow = next(r for r in sharded.rows if r["codec"] == "slow")
    assert slow["jobs"] == 10 and slow["longest_job_h"] == pytest.approx(100 / 3600)
    assert whole.wall_h == pytest.approx(1000 / 3600)  # one job per config: the slow one is the wall time
    assert sharded.wall_h < 0.12 * whole.wall_h
    # One clip in memory at a time: baseline + (motion + codec) bytes per frame of the longest clip.
    assert sharded.peak_gb == pytest.approx((1e8 + (2000 + 20000) * 1000) / 1e9)


def test_the_layout_before_shards_holds_the_dataset_and_rewrites_its_results():
    frames = [1000] * 100
    old = estimate(COSTS, ["cheap/a"], frames, workers=1, layout="config")
    new = estimate(COSTS, ["cheap/a"], frames, workers=1)
    assert old.cpu_h * 3600 == pytest.approx(new.cpu_h * 3600 + 1e-5 * 100**2)
    assert old.peak_gb > new.peak_gb + 2000 * 99_000 / 1e9 * 0.99


def test_the_command_prints_an_estimate_for_a_dataset_size(tmp_path):
    costs = tmp_path / "costs.json"
    costs.write_text(json.dumps(COSTS))
    done = subprocess.run([sys.executable, "-m", "mocapbench.experiments.cost", "--sweep", "rd_raw-zstd",
                           "--frames", "1000000", "--clips", "500", "--workers", "4", "--costs", str(costs)],
                          cwd=REPO, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "| raw-zstd | 1 | 1 |" in done.stdout and "wall" in done.stdout and "CPU h" in done.stdout
    missing = subprocess.run([sys.executable, "-m", "mocapbench.experiments.cost", "--frames", "10", "--clips", "1",
                              "--costs", str(tmp_path / "none.json")], cwd=REPO, capture_output=True, text=True)
    assert missing.returncode == 2 and "--calibrate" in missing.stderr
