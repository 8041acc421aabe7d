"""The long-capture benchmark's subprocess measures a codec on the synthetic capture; ``--cache`` reads the
capture back instead of rebuilding it, with the same result."""

from __future__ import annotations

import json

from mocapbench.benchmarks import long_captures


def test_cached_capture_gives_the_same_measurement(tmp_path, capsys):
    cache, out = tmp_path / "cache", tmp_path / "rows.jsonl"
    args = ["--frames", "240", "--codecs", "quant-delta-zstd", "--cache", str(cache), "--json", str(out)]
    assert long_captures.main(args) == 0  # builds and keeps the capture
    assert (cache / "sinusoidal-seed7-240.npz").is_file()
    assert long_captures.main(args) == 0  # reads it back
    first, second = (json.loads(line) for line in out.read_text().splitlines())
    assert first["status"] == second["status"] == "ok"
    assert first["bytes"] == second["bytes"] and abs(first["max_err_cm"] - second["max_err_cm"]) < 1e-9
    assert "| quant-delta-zstd | 240 |" in capsys.readouterr().out


def test_set_gives_every_codec_run_a_config_field_and_a_wrong_one_is_one_line(tmp_path, capsys):
    out = tmp_path / "rows.jsonl"
    base = ["--frames", "240", "--codecs", "quant-delta-zstd", "--json", str(out)]
    assert long_captures.main(base) == 0
    assert long_captures.main([*base, "--set", "step_cm=4"]) == 0
    assert long_captures.main([*base, "--set", "no_such_field=1"]) == 0
    default, coarse, wrong = (json.loads(line) for line in out.read_text().splitlines())
    assert coarse["bytes"] < default["bytes"] and coarse["mean_err_cm"] > default["mean_err_cm"]
    assert wrong["status"].startswith("failed:") and "no_such_field" in wrong["status"]
    assert "codec config: {'step_cm': 4}" in capsys.readouterr().out
