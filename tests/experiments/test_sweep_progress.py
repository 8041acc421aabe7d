"""Sweep progress lines and the end-of-sweep summary, from job folders as jobs leave them."""

from __future__ import annotations

import json

from mocapbench.experiments.sweep_progress import JobMonitor, format_summary, summarize


def _job(root, folder, status, errors=()):
    path = root / folder
    path.mkdir(parents=True)
    (path / "job.json").write_text(json.dumps({"status": status, "rows": 2, "errors": len(errors), "seconds": 3.0}))
    if errors:
        (path / "errors.jsonl").write_text("".join(json.dumps({"error": e}) + "\n" for e in errors))


def test_each_finished_job_gets_a_line_with_an_eta(tmp_path):
    lines = []
    monitor = JobMonitor(tmp_path, ["a/1", "a/2", "b/1"], emit=lines.append)
    _job(tmp_path, "a/1", "done")
    monitor.poll()
    _job(tmp_path, "b/1", "failed", ["ValueError: bad"])
    monitor.poll()
    monitor.poll()  # nothing new: no line
    assert len(lines) == 2
    assert lines[0].startswith("[1/3] a/1 done in 3 s; elapsed") and "ETA" in lines[0]
    assert lines[1].startswith("[2/3] b/1 failed in 3 s, 1 error(s)")


def test_summary_groups_failures_by_reason(tmp_path):
    _job(tmp_path, "a/1", "done")
    for i in range(3):
        _job(tmp_path, f"b/{i}", "failed", ["ValueError: step_cm must be in [1e-06, 100] cm, got -1.0.\ntrace"])
    _job(tmp_path, "c/1", "failed", ["KeyError: x"])
    launched = ["a/1", "b/0", "b/1", "b/2", "c/1", "d/1"]  # d/1 never wrote job.json
    summary = summarize(tmp_path, launched, skipped=["z/1"], seconds=125.0)
    assert not summary.ok and summary.done == ["a/1"] and summary.missing == ["d/1"]
    text = format_summary(summary)
    assert text.splitlines()[0] == ("sweep finished in 2.1 min: 1/6 jobs done, 4 failed, 1 without a result, "
                                    "1 skipped (already done)")
    assert "     3  ValueError: step_cm must be in [1e-06, 100] cm, got -1.0." in text
    assert "exit status 1" in text
    assert "exit status 0 (--allow-failures)" in format_summary(summary, allow_failures=True)
    assert summarize(tmp_path, ["a/1"]).ok


def test_eta_from_estimates_scales_the_pending_schedule_by_how_finished_jobs_compared(tmp_path):
    lines = []
    estimates = {"a/1": 1.5, "a/2": 10.0, "b/1": 10.0, "b/2": 4.0}
    monitor = JobMonitor(tmp_path, list(estimates), emit=lines.append, estimates=estimates, workers=2)
    _job(tmp_path, "a/1", "done")  # took 3 s against 1.5 estimated: the machine runs at half the estimated speed
    monitor.poll()
    assert "in 3 s (estimated 2 s)" in lines[0]
    # Pending 10, 10, 4 on 2 workers: 14 s of schedule, times 2.
    assert monitor.eta(elapsed=3.0, done=1) == 28.0
    assert lines[0].endswith("ETA 28 s")
