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


def test_job_overhead_is_a_workers_cpu_between_jobs_less_the_codecs_share(tmp_path):
    import json

    import pandas as pd

    from mocapbench.experiments.cost import job_overhead

    rows = []
    # worker 7 runs a, b, c; worker 8 runs d, e. Each job: 2 s + 1 ms per frame beyond its codec's encode + decode.
    plan = [(7, "a", 100, 50.0), (7, "b", 1000, 0.5), (7, "c", 3000, 1.0), (8, "d", 100, 60.0), (8, "e", 2000, 4.0)]
    at = {7: 0.0, 8: 0.0}
    for pid, name, frames, codec_cpu in plan:
        folder = tmp_path / "sweep" / "svd" / name
        folder.mkdir(parents=True)
        at[pid] += codec_cpu + 2.0 + 0.001 * frames
        (folder / "job.json").write_text(json.dumps({"status": "done", "pid": pid, "process_cpu_s": at[pid]}))
        # one row of the job: encode timed 3 times, decode once (the calls count)
        rows.append({"job_dir": str(folder), "frames": frames, "encode_cpu_s": codec_cpu / 4, "encode_repeats": 3,
                     "encode_warmup": 0, "decode_cpu_s": codec_cpu / 4, "decode_repeats": 1, "decode_warmup": 0})
    fit = job_overhead([tmp_path / "sweep"], pd.DataFrame(rows))
    assert fit["overhead_jobs"] == 3  # each worker's first job (imports, first reads) is left out
    assert abs(fit["cpu_s_per_job"] - 2.0) < 1e-6 and abs(fit["cpu_s_per_frame"] - 0.001) < 1e-9
    # jobs of one length: only the constant is fit, the per-frame cost given is kept
    only_b = pd.DataFrame([r for r in rows if r["job_dir"].endswith("/b")] + [rows[0]])
    fit = job_overhead([tmp_path / "sweep"], only_b, per_frame=0.001)
    assert fit["overhead_jobs"] == 1 and abs(fit["cpu_s_per_job"] - 2.0) < 1e-6 and fit["cpu_s_per_frame"] == 0.001


def test_a_datasets_own_costs_replace_the_general_ones_for_its_sweeps_only():
    from mocapbench.experiments.cost import for_dataset

    costs = {**COSTS, "datasets": {"game": {"configs": {"slow/b": {"codec": "slow", "cpu_s_per_frame": 0.5}},
                                            "job": {"cpu_s_per_job": 3.0}}}}
    game = for_dataset(costs, "game")
    assert cpu_cost(game, "slow/b") == (0.5, 0.0) and cpu_cost(game, "cheap/a") == (1e-5, 0.0)
    assert game["job"]["cpu_s_per_job"] == 3.0 and game["job"]["baseline_rss_bytes"] == 1e8
    assert for_dataset(costs, "cmu_test") is costs and cpu_cost(costs, "slow/b") == (1e-2, 0.0)
    # priced per dataset: 1,000 frames of the slow config cost 500 s on the game rig, 10 s elsewhere
    assert estimate(game, ["slow/b"], [1000], 1, max_cpu_s=None).cpu_h * 3600 == pytest.approx(503.0)
    assert estimate(costs, ["slow/b"], [1000], 1, max_cpu_s=None).cpu_h * 3600 == pytest.approx(10.0)


def test_calibrating_per_dataset_keeps_the_general_costs_and_prices_refusals(tmp_path, monkeypatch):
    import pandas as pd

    from mocapbench.experiments import aggregate as aggregate_module
    from mocapbench.experiments.cost import calibrate_from, load_costs

    sweep = tmp_path / "sweep"
    rows = []
    for codec, cpu in (("slow/b", 2.0), ("cheap/a", 0.01)):
        folder = sweep / codec
        folder.mkdir(parents=True)
        (folder / "job.json").write_text(json.dumps({"status": "done", "rows": 1, "cpu_s": cpu}))
        rows.append({"job_dir": str(folder), "dataset": "game", "codec": codec.split("/")[0], "frames": 100,
                     "encode_cpu_s": cpu / 2, "decode_cpu_s": cpu / 2})
    refused = sweep / "rot" / "c"
    refused.mkdir(parents=True)
    (refused / "job.json").write_text(json.dumps({"status": "done", "rows": 0, "cpu_s": 0.25}))
    monkeypatch.setattr(aggregate_module, "aggregate", lambda folders: pd.DataFrame(rows))
    path = tmp_path / "costs.json"
    path.write_text(json.dumps(COSTS))
    calibrate_from([sweep], out=path, per_dataset=True)
    written = load_costs(path)
    assert written["configs"] == COSTS["configs"]  # the general (CMU) entries are untouched
    own = written["datasets"]["game"]["configs"]
    assert own["slow/b"]["cpu_s_per_frame"] == pytest.approx(0.02)
    assert own["cheap/a"]["cpu_s_per_frame"] == pytest.approx(1e-4)
    assert own["rot/c"]["refused"] and own["rot/c"]["cpu_s_per_frame"] == 0.0
    # sweeps of two datasets cannot write one dataset's entries
    rows.append({**rows[0], "dataset": "other"})
    with pytest.raises(RuntimeError, match="one dataset"):
        calibrate_from([sweep], out=path, per_dataset=True)


def test_calls_under_follows_the_timing_of_measure(monkeypatch):
    import types

    from mocapbench.experiments.cost import calls_under
    from mocapbench.metrics import timing

    assert calls_under(0.01, 3, 0, 0.25) == 3 and calls_under(0.2, 3, 0, 0.25) == 2
    assert calls_under(0.3, 3, 0, 0.25) == 1 and calls_under(0.3, 3, 0, None) == 3
    clock = [0.0]  # a clock that only the measured calls advance, so the count cannot depend on the machine
    monkeypatch.setattr(timing, "time", types.SimpleNamespace(perf_counter=lambda: clock[0],
                                                              process_time=lambda: clock[0]))
    for wall in (0.01, 0.1, 0.2, 0.26, 0.3, 2.0):
        for warmup in (0, 1, 2):
            calls = []

            def call():
                calls.append(1)
                clock[0] += wall

            timing.measure(call, repeats=3, warmup=warmup, budget_s=0.25)
            assert len(calls) == calls_under(wall, 3, warmup, 0.25), (wall, warmup)


def test_calibrating_prices_the_calls_the_current_timing_makes_for_the_named_codecs(tmp_path, monkeypatch):
    import pandas as pd

    from mocapbench.experiments import aggregate as aggregate_module
    from mocapbench.experiments import cost as cost_module

    sweep = tmp_path / "sweep"
    rows = []
    # one codec timed three times under an older, larger budget, one whose calls stay short
    for codec, wall in (("slow/b", 0.6), ("cheap/a", 0.01)):
        (sweep / codec).mkdir(parents=True)
        rows.append({"job_dir": str(sweep / codec), "dataset": "cmu_test", "codec": codec.split("/")[0],
                     "frames": 100, "encode_cpu_s": wall, "encode_wall_s": wall, "encode_repeats": 3,
                     "encode_warmup": 0, "decode_cpu_s": wall / 10, "decode_wall_s": wall / 10,
                     "decode_repeats": 3, "decode_warmup": 0})
    monkeypatch.setattr(aggregate_module, "aggregate", lambda folders: pd.DataFrame(rows))
    monkeypatch.setattr(cost_module, "benchmark_timing", lambda: {"repeats": 3, "warmup": 0, "budget_s": 0.25})
    path = tmp_path / "costs.json"
    path.write_text(json.dumps(COSTS))
    cost_module.calibrate_from([sweep], out=path, codecs=["slow"], scale=0.5)
    written = cost_module.load_costs(path)
    # halved by the scale: a 0.3 s encode is timed once, a 0.03 s decode three times, over 100 frames
    assert written["configs"]["slow/b"]["cpu_s_per_frame"] == pytest.approx(0.5 * (0.6 + 3 * 0.06) / 100)
    assert written["configs"]["cheap/a"] == COSTS["configs"]["cheap/a"] and written["job"] == COSTS["job"]
    with pytest.raises(RuntimeError, match="no rows of them"):
        cost_module.calibrate_from([sweep], out=path, codecs=["acl"])


def test_calibrating_replaces_the_costs_file_and_never_writes_through_a_link(tmp_path, monkeypatch):
    import pandas as pd

    from mocapbench.experiments import aggregate as aggregate_module
    from mocapbench.experiments import cost as cost_module

    sweep = tmp_path / "sweep"
    (sweep / "slow" / "b").mkdir(parents=True)
    rows = [{"job_dir": str(sweep / "slow" / "b"), "dataset": "cmu_test", "codec": "slow", "frames": 100,
             "encode_cpu_s": 0.6, "decode_cpu_s": 0.06}]
    monkeypatch.setattr(aggregate_module, "aggregate", lambda folders: pd.DataFrame(rows))
    elsewhere = tmp_path / "elsewhere.json"
    elsewhere.write_text(json.dumps(COSTS))
    link = tmp_path / "costs.json"
    link.symlink_to(elsewhere)
    cost_module.calibrate_from([sweep], out=link, codecs=["slow"])
    assert json.loads(elsewhere.read_text()) == COSTS  # the file the link named is untouched
    assert not link.is_symlink()
    assert cost_module.load_costs(link)["configs"]["slow/b"]["cpu_s_per_frame"] == pytest.approx(0.66 / 100)


def test_calibrating_from_a_missing_folder_or_with_a_bad_scale_is_one_line(tmp_path, capsys):
    from mocapbench.experiments.cost import main

    costs = tmp_path / "costs.json"
    costs.write_text(json.dumps(COSTS))
    assert main(["--calibrate-from", str(tmp_path / "no_such_sweep"), "--costs", str(costs)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("cost --calibrate-from: ") and "no_such_sweep" in err and len(err.strip().splitlines()) == 1
    for scale in ("0", "inf", "nan"):
        with pytest.raises(SystemExit) as stop:
            main(["--calibrate-from", str(tmp_path), "--costs", str(costs), "--scale", scale])
        assert stop.value.code == 2 and "--scale must be a finite number > 0" in capsys.readouterr().err
    assert json.loads(costs.read_text()) == COSTS
