"""The player page's data and the report's "What animators see" section, without a browser."""

from __future__ import annotations

import base64
import json
import re

import numpy as np
import pandas as pd
import pytest

from mocapbench.codecs import create
from mocapbench.experiments.animator_report import JITTER_LIMIT, SLIDING_LIMIT_CM, animator_flag
from mocapbench.experiments.evaluate import TimingSettings, evaluate_with_decoded
from mocapbench.experiments.player import MAX_PLAYER_FRAMES, PlayerEntry, player_data, player_html
from mocapbench.experiments.report import build_report
from mocapbench.experiments.results import write_rows_atomic
from mocapbench.experiments.worst_clip import save_worst
from mocapbench.synthetic import sinusoidal_motion


def _entry(frames=50, decoded_shift=None, **kw):
    motion = sinusoidal_motion(num_frames=frames, seed=5)
    original = motion.positions()
    decoded = None
    if decoded_shift is not None:
        decoded = original.copy()
        decoded[decoded_shift[0], decoded_shift[1]] += [0.0, 0.0, 1.5]
    return PlayerEntry("clip", motion.skeleton.names, motion.skeleton.parents, motion.fps, "y", original, decoded, **kw)


def _floats(track):
    return np.frombuffer(base64.b64decode(track["positions"]), dtype="<f4")


def test_the_page_data_marks_the_worst_frame_and_joint():
    data = player_data([_entry(decoded_shift=(17, 9))])
    (record,) = data["entries"]
    assert record["worst_frame"] == 17 and record["worst_joint"] == 9
    assert record["max_err_cm"] == pytest.approx(1.5, abs=1e-4) and record["scale_cm"] == record["max_err_cm"]
    original = _floats(data["tracks"][record["original"]]).reshape(50, 31, 3)
    decoded = _floats(data["tracks"][record["decoded"]]).reshape(50, 31, 3)
    assert np.abs(decoded - original).max() == pytest.approx(1.5, abs=1e-4)
    assert record["frame_numbers"] == list(range(50)) and record["fps_shown"] == record["fps"]


def test_one_motion_alone_has_no_error_and_identical_tracks_are_stored_once():
    data = player_data([_entry(), _entry()])
    assert len(data["tracks"]) == 1
    assert data["entries"][0]["decoded"] is None and data["entries"][0]["worst_frame"] is None


def test_a_long_clip_is_decimated_and_keeps_its_worst_frame():
    frames = 2 * MAX_PLAYER_FRAMES + 7
    (record,) = player_data([_entry(frames=frames, decoded_shift=(401, 3))])["entries"]
    assert len(record["frame_numbers"]) <= MAX_PLAYER_FRAMES
    assert record["frame_numbers"][record["worst_frame"]] == 401
    assert record["fps_shown"] == pytest.approx(record["fps"] / 3) and "one frame in 3" in record["note"]


def test_bad_entries_are_refused_in_one_line():
    motion = sinusoidal_motion(num_frames=10, seed=1)
    p = motion.positions()
    with pytest.raises(ValueError, match="do not match"):
        PlayerEntry("x", motion.skeleton.names, motion.skeleton.parents, 120.0, "y", p, p[:5])
    with pytest.raises(ValueError, match="NaN"):
        PlayerEntry("x", motion.skeleton.names, motion.skeleton.parents, 120.0, "y", p * np.nan)
    with pytest.raises(ValueError, match="at least one"):
        player_data([])


def test_the_page_stands_alone_and_its_json_cannot_end_the_script():
    page = player_html("t", [_entry(decoded_shift=(1, 1))], intro=["</script><b>x</b>"])
    assert "<script src=" not in page and "http://" not in page and "https://" not in page
    payload = re.search(r'<script type="application/json" id="player-data">(.*?)</script>', page, re.S).group(1)
    assert json.loads(payload)["entries"][0]["worst_joint"] == 1
    assert "&lt;/script&gt;" in page  # the intro is escaped


def test_flags_follow_the_stated_limits():
    calm = pd.Series({"accel_rms_err_cm_s2": 100.0, "accel_rms_ref_cm_s2": 1000.0, "foot_slide_mean_cm": 3.0,
                      "foot_slide_ref_mean_cm": 2.5})
    assert animator_flag(calm) == ""
    shaky = calm.copy()
    shaky["accel_rms_err_cm_s2"] = 1000.0 * JITTER_LIMIT * 1.5
    assert animator_flag(shaky).startswith("jitter")
    sliding = calm.copy()
    sliding["foot_slide_mean_cm"] = 2.5 + SLIDING_LIMIT_CM + 0.1
    assert animator_flag(sliding).startswith("foot sliding")
    assert animator_flag(pd.Series({"codec": "old row without the columns"})) == ""


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """A report of a positions codec and a rotation codec on 3 synthetic clips, each job keeping its worst clip."""
    root = tmp_path_factory.mktemp("animators")
    motions = [sinusoidal_motion(num_frames=60, seed=seed) for seed in (1, 2, 3)]
    for name, params in (("mcb-linf", {"eps_cm": 0.5}), ("quant-rot-zstd", {"rotation_bits": 10})):
        codec = create(name, **params)
        folder = root / "sweep" / name
        rows = []
        for motion in motions:
            row, decoded = evaluate_with_decoded(codec, motion, timing=TimingSettings(repeats=1, warmup=0))
            rows.append({**row, "dataset": "synthetic", "dataset_desc": "synthetic sinusoidal"})
            if row["max_err_cm"] >= max(r["max_err_cm"] for r in rows):
                folder.mkdir(parents=True, exist_ok=True)
                save_worst(folder, motion, motion.positions(), decoded.positions, row)
        write_rows_atomic(folder / "results.jsonl", rows)
    return build_report([root / "sweep"], name="animators", reports_root=root / "reports", bounds=[])


def test_the_report_shows_what_animators_see(report):
    text = (report / "report.md").read_text()
    assert "## What animators see" in text and "jitter RMS cm/s²" in text and "bone Δ max cm" in text
    assert "[synthetic: play the worst clip" in text
    page = (report / "player_synthetic.html").read_text()
    assert '<script src="player.js">' in page and (report / "player.js").exists()
    data = json.loads(re.search(r'id="player-data">(.*?)</script>', page, re.S).group(1))
    labels = [e["label"] for e in data["entries"]]
    assert len(labels) == 4 and sum("mcb-linf" in label for label in labels) == 2  # 2 codecs x 2 bounds
    headline = text[text.index("## Headline"):text.index("## Rate-distortion")]
    assert "end sites L∞ cm" in headline and "animators" in headline
    assert "Foot sliding: contacts found on the original" in text  # Data and method
