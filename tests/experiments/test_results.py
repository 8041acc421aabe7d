"""results.jsonl: rows appended, never rewritten; a line that does not parse is named, never dropped silently."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from mocapbench.experiments.aggregate import aggregate
from mocapbench.experiments.results import (
    CorruptResultsError,
    append_row,
    is_intact,
    read_rows,
    repair,
    scan_rows,
)
from mocapbench.experiments.run import run_job
from mocapbench.experiments.sweeper import is_job_done

REPO = Path(__file__).resolve().parents[2]
THREE_CLIPS = ["codec=quant-delta-zstd", "dataset.clips.seeds=[1,2,3]", "dataset.clips.num_frames=30",
               "dataset.train.clips.num_frames=30"]


def test_rows_are_appended_and_earlier_bytes_never_change(tmp_path):
    path = tmp_path / "results.jsonl"
    append_row(path, {"clip": "a", "x": 1.5})
    first = path.read_bytes()
    append_row(path, {"clip": "b", "x": float("nan")})
    assert path.read_bytes().startswith(first)  # appended, not rewritten
    assert [r["clip"] for r in read_rows(path)] == ["a", "b"]


def test_a_torn_last_line_is_named_with_its_file_and_line(tmp_path):
    path = tmp_path / "results.jsonl"
    append_row(path, {"clip": "a"})
    with open(path, "ab") as handle:
        handle.write(b'{"clip": "b", "max_err')  # a write cut by a kill
    with pytest.raises(CorruptResultsError, match=rf"{path}:2: results line does not parse"):
        read_rows(path)
    assert not is_intact(path)
    append_row(path, {"clip": "c"})  # starts a new line instead of gluing onto the torn one
    rows, bad = scan_rows(path)
    assert [r["clip"] for r in rows] == ["a", "c"] and [line for line, _ in bad] == [2]


def test_repair_keeps_the_damaged_file_and_writes_back_the_good_rows(tmp_path):
    path = tmp_path / "results.jsonl"
    path.write_text('{"clip": "a"}\n[1, 2]\nnot json\n{"clip": "b"}\n')
    rows = repair(path)
    assert [r["clip"] for r in rows] == ["a", "b"]
    assert read_rows(path) == rows
    assert (tmp_path / "results.jsonl.corrupt-1").read_text().count("\n") == 4


def test_corrupt_line_marks_the_job_unfinished_and_resume_redoes_only_its_clip(compose_benchmark, tmp_path,
                                                                             monkeypatch):
    cfg = compose_benchmark(THREE_CLIPS)
    assert run_job(cfg, tmp_path)["status"] == "done" and is_job_done(tmp_path)
    path = tmp_path / "results.jsonl"
    lines = path.read_text().splitlines()
    lines[1] = lines[1][: len(lines[1]) // 2]  # corrupt the row of the second clip
    path.write_text("\n".join(lines) + "\n")
    assert not is_job_done(tmp_path)  # job.json says done, but the sweeper launches it again

    from mocapbench.experiments import evaluate as evaluate_module

    original, seen = evaluate_module.evaluate_with_decoded, []

    def counting(codec, motion, **kwargs):
        seen.append(motion.name)
        return original(codec, motion, **kwargs)

    monkeypatch.setattr(evaluate_module, "evaluate_with_decoded", counting)
    assert run_job(cfg, tmp_path)["status"] == "done"
    assert seen == ["synthetic-seed2"]
    assert sorted(r["clip"] for r in read_rows(path)) == [f"synthetic-seed{i}" for i in (1, 2, 3)]
    assert is_job_done(tmp_path)


def test_aggregate_and_its_command_refuse_a_corrupt_line(tmp_path):
    job = tmp_path / "sweep" / "quant-delta-zstd" / "default"
    append_row(job / "results.jsonl", {"codec": "quant-delta-zstd", "clip": "a"})
    with open(job / "results.jsonl", "a") as handle:
        handle.write("{oops\n")
    with pytest.raises(CorruptResultsError, match="results.jsonl:2"):
        aggregate([tmp_path / "sweep"])
    done = subprocess.run([sys.executable, "-m", "mocapbench.experiments.aggregate", str(tmp_path / "sweep")],
                          cwd=REPO, capture_output=True, text=True)
    assert done.returncode != 0
    assert f"{job / 'results.jsonl'}:2" in done.stderr and "Traceback" not in done.stderr
    assert json.loads((job / "results.jsonl").read_text().splitlines()[0])["clip"] == "a"
    report = subprocess.run([sys.executable, "-m", "mocapbench.experiments.report", str(tmp_path / "sweep"),
                             "--reports-root", str(tmp_path / "reports")], cwd=REPO, capture_output=True, text=True)
    assert report.returncode != 0 and f"{job / 'results.jsonl'}:2" in report.stderr
    assert "Traceback" not in report.stderr and not list((tmp_path / "reports").glob("*/index.html"))
