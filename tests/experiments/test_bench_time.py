"""make bench's time per codec (from job.json) and its estimate line."""

from __future__ import annotations

import json
import math

from mocapbench.experiments.bench_time import BenchEstimate, codec_times, format_codec_times, format_estimate


def _job(root, folder, seconds, cpu=None):
    path = root / folder
    path.mkdir(parents=True)
    record = {"status": "done", "seconds": seconds}
    if cpu is not None:
        record["cpu_s"] = cpu
    (path / "job.json").write_text(json.dumps(record))


def test_codec_times_sum_each_codecs_jobs_over_sweeps_and_shards(tmp_path):
    _job(tmp_path / "s1", "svd/codec.rank=2", 10.0, 8.0)
    _job(tmp_path / "s1", "fourier-mlp-int/codec.K=2/shard-001-of-002", 100.0, 90.0)
    _job(tmp_path / "s1", "fourier-mlp-int/codec.K=2/shard-002-of-002", 50.0, 45.0)
    _job(tmp_path / "s2", "svd/codec.rank=4", 5.0)  # written before job.json held cpu_s
    rows = codec_times([tmp_path / "s1", tmp_path / "s2"])
    assert [r["codec"] for r in rows] == ["fourier-mlp-int", "svd"]
    assert rows[0]["jobs"] == 2 and rows[0]["wall_s"] == 150.0 and rows[0]["cpu_s"] == 135.0
    assert rows[1]["wall_s"] == 15.0 and math.isnan(rows[1]["cpu_s"])
    table = format_codec_times(rows)
    assert "| fourier-mlp-int | 2 | 2.5 min | 2.2 min |" in table
    assert table.splitlines()[-1].startswith("| all | 4 |")


def test_estimate_line_names_the_time_and_the_costliest_codecs():
    estimate = BenchEstimate(wall_s=600.0, cpu_s=1100.0, jobs=90,
                             codec_cpu_s={"a": 500.0, "b": 400.0, "c": 1.0}, measured="2026-12-02 on here")
    line = format_estimate(estimate, workers=2, top=2)
    assert line.startswith("estimated 10.0 min wall on 2 workers (sweeps 0 s, report 0 s, this estimate 0 s) "
                           "(18.3 min CPU, 90 jobs; most CPU: a 8.3 min, b 6.7 min)")
    assert "c " not in line and line.endswith("measured 2026-12-02 on here")


def test_progress_line_scales_the_time_left_by_the_sweeps_so_far():
    from mocapbench.experiments.bench_time import format_progress

    estimate = BenchEstimate(wall_s=600.0, cpu_s=1100.0, jobs=90, codec_cpu_s={}, measured="here",
                             sweep_wall_s=(300.0, 200.0, 100.0))
    # the first sweep took twice its estimate: the 300 s estimated for the rest read as 10 minutes
    line = format_progress(1, 600.0, estimate)
    assert line == "make bench: 1 sweep(s) done, 10.0 min elapsed (estimated 5.0 min); 1/3 sweeps, about 10.0 min left"
    assert format_progress(3, 500.0, estimate).endswith("3/3 sweeps, about 0 s left")
    assert format_progress(2, 10.0, None) == "make bench: 2 sweep(s) done, 10 s elapsed"


def test_estimate_table_lists_each_sweep_and_each_codecs_cpu_per_sweep():
    from mocapbench.experiments.bench_time import format_estimate_table

    estimate = BenchEstimate(wall_s=450.0, cpu_s=900.0, jobs=7, codec_cpu_s={"a": 120.0, "b": 780.0},
                             measured="here", sweep_wall_s=(400.0, 50.0), sweep_cpu_s=(800.0, 100.0),
                             sweep_jobs=(5, 2), labels=("s1", "s2"),
                             sweep_codec_cpu_s=({"a": 20.0, "b": 780.0}, {"a": 100.0}), report_s=30.0,
                             prepare_s=12.0)
    lines = format_estimate_table(estimate).splitlines()
    assert lines[2:7] == ["| s1 | 5 | 800 | 400 |", "| s2 | 2 | 100 | 50 |", "| report | | 30 | 30 |",
                          "| the estimate's dry runs (measured) | | | 12 |", "| all | 7 | 930 | 450 |"]
    assert lines[8] == "| codec CPU s | s1 | s2 | all |"
    # costliest codec first; a codec a sweep does not run reads "-"
    assert lines[10:] == ["| b | 780 | - | 780 |", "| a | 20 | 100 | 120 |"]


def test_the_report_costs_a_constant_a_share_per_dataset_and_per_job():
    from mocapbench.experiments.bench_time import report_cost

    costs = {"report": {"cpu_s": 5.0, "cpu_s_per_dataset": 10.0, "cpu_s_per_job": 0.1}}
    assert report_cost(costs, datasets=3, jobs=200) == 55.0
    assert report_cost({}, datasets=3, jobs=200) == 0.0


def test_a_sweep_that_cannot_be_priced_is_named_and_the_others_are_priced():
    from mocapbench.experiments.bench_time import SweepPlan, estimate_run

    plans = [SweepPlan("bad", "no_such_sweep", "synthetic"), SweepPlan("raw", "rd_raw-zstd", "synthetic")]
    estimate = estimate_run(plans, workers=2)
    assert len(estimate.unpriced) == 1 and estimate.unpriced[0].startswith("bad (")
    assert estimate.sweep_jobs[0] == 0 and estimate.sweep_jobs[1] >= 1 and estimate.sweep_cpu_s[1] > 0
    assert estimate.labels == ("bad", "raw") and estimate.prepare_s > 0
    assert estimate.wall_s >= estimate.sweep_wall_s[1] + estimate.report_s
