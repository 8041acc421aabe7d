"""The headline that decides: ranking, winner sentence, rows kept with a reason, synthetic note, formats, verdicts."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from mocapbench.experiments.document import format_column, markdown_table
from mocapbench.experiments.headline import bounds_with, headline_table, synthetic_only_note, winner_sentences
from mocapbench.experiments.reproduction import MIN_REAL_CLIPS, guard_verdicts


def _point(codec, ratio, linf, dataset="cmu_test", **extra):
    return {"dataset": dataset, "codec": codec, "config_hash": f"{codec}-{ratio}", "complete": True, "clips": 12,
            "compression_ratio": ratio, "bits_per_joint_frame": 96.0 / ratio, "max_err_cm": linf,
            "mean_err_cm": linf / 4, "encode_fps": 1000.0, "decode_fps": 5e4, "model_bytes": 0, **extra}


POINTS = pd.DataFrame([
    _point("quant-delta-zstd", 30.0, 0.8, family="generic", codes_rotations=False, latency_frames=-1),
    _point("quant-delta-zstd", 45.0, 2.5, family="generic", codes_rotations=False, latency_frames=-1),
    _point("quant-rot-zstd", 5.0, 0.9, family="generic", codes_rotations=True, latency_frames=-1),
    _point("mcb-linf", 90.0, 0.5, family="mocapbench", codes_rotations=False, needs_model=True, latency_frames=480,
           model_bytes=23064),
    _point("svd", 12.0, 4.0, family="paper", codes_rotations=True, latency_frames=-1),
])
ERRORS = pd.DataFrame([{"dataset": "cmu_test", "codec": "pga-ik", "error": "ValueError: IK diverged\ntrace"}] * 3)


def test_codecs_are_ranked_by_ratio_under_each_bound_and_the_rest_keep_a_reason():
    table = headline_table(POINTS, (1.0, 3.0), errors=ERRORS, unavailable={"acl": "no C++ compiler (apt install g++)"})
    one = table[table["L∞ bound"] == "< 1 cm"]
    assert list(one["codec"]) == ["mcb-linf", "quant-delta-zstd", "quant-rot-zstd", "svd", "pga-ik", "acl"]
    assert list(one["rank"]) == [1, 2, 3, "–", "–", "–"]
    assert list(one["CR"].iloc[:3]) == [90.0, 30.0, 5.0]
    notes = dict(zip(one["codec"], one["config"]))
    assert notes["svd"] == "no config under 1 cm (lowest L∞ 4 cm)"
    assert notes["pga-ik"] == "failed 3x: ValueError: IK diverged"
    assert notes["acl"] == "unavailable here: no C++ compiler (apt install g++)"
    three = table[table["L∞ bound"] == "< 3 cm"]
    assert three.loc[three["codec"] == "quant-delta-zstd", "CR"].item() == 45.0  # its best config under 3 cm
    row = one.iloc[0]
    assert (row["rotations (BVH/glTF)"], row["needs model"], row["model bytes"], row["latency frames"]) == \
        ("no", "yes", 23064, 480)
    assert one.loc[one["codec"] == "quant-rot-zstd", "latency frames"].item() == "whole clip"


def test_a_codec_measured_on_another_dataset_of_the_report_keeps_a_row_where_it_was_not_run():
    points = pd.concat([POINTS, pd.DataFrame([_point("quant-delta-zstd", 20.0, 0.7, dataset="cmu_test_24fps",
                                                     family="generic", codes_rotations=False)])])
    table = headline_table(points, (1.0,), unavailable={})
    low = table[table["dataset"] == "cmu_test_24fps"]
    assert list(low["rank"]) == [1, "–", "–", "–"]
    notes = dict(zip(low["codec"], low["config"]))
    assert set(notes) == {"quant-delta-zstd", "mcb-linf", "quant-rot-zstd", "svd"}
    assert notes["mcb-linf"] == "not run on this dataset (left out of its sweep)"
    full = table[table["dataset"] == "cmu_test"]
    assert "not run" not in " ".join(full["config"])


def test_the_winner_is_stated_with_its_margin_and_the_best_rotation_codec():
    sentences = winner_sentences(headline_table(POINTS, (0.6, 1.0), unavailable={}))
    assert sentences[0].startswith("cmu_test, L∞ < 0.6 cm: mcb-linf wins at 90:1")
    assert "no codec that outputs rotations" in sentences[0]
    # mcb-linf has one point (0.5 cm), quant-delta-zstd none under 0.8 cm: no L∞ at which both were measured.
    assert "the runner-up quant-delta-zstd (30:1) cannot be compared with it at equal L∞" in sentences[1]
    assert "3x" not in sentences[1]
    assert "the best codec that outputs rotations (BVH/glTF) is quant-rot-zstd at 5:1" in sentences[1]
    assert "needs a model" in sentences[1]
    nothing = winner_sentences(headline_table(POINTS, (0.1,), unavailable={}))
    assert nothing == ["cmu_test, L∞ < 0.1 cm: no codec stays under the bound."]


def test_user_bounds_join_1_and_3_cm():
    assert bounds_with([0.5, 3.0]) == (0.5, 1.0, 3.0)
    with pytest.raises(ValueError, match="positive"):
        bounds_with([-1.0])


def test_a_synthetic_only_run_says_so_first():
    synthetic = pd.DataFrame({"dataset": ["synthetic"] * 2, "dataset_desc": ["synthetic sinusoidal, seeds [1]"] * 2})
    assert synthetic_only_note(synthetic).startswith("Synthetic data only")
    mixed = pd.concat([synthetic, pd.DataFrame({"dataset": ["cmu_09_06"], "dataset_desc": ["CMU 09_06"]})])
    assert synthetic_only_note(mixed) is None


def test_a_column_keeps_one_number_format():
    column = pd.Series([97834.0, 1.32e5, 3877.2, 185123.4, 4.852, 0.01274])
    assert format_column(column) == ["97,800", "132,000", "3,880", "185,000", "4.85", "0.0127"]
    assert format_column(pd.Series([23064, 0])) == ["23,064", "0"]
    text = markdown_table(pd.DataFrame({"x": [1.23e-5, 4.0e6, np.nan]}))
    assert "e-" not in text and "e+" not in text and "4,000,000" in text


def test_a_claim_needs_five_real_clips():
    rows = pd.DataFrame({"dataset": ["cmu_09_06"] * 2 + ["cmu_test"] * MIN_REAL_CLIPS + ["synthetic"] * 9,
                         "dataset_desc": ["CMU"] * (2 + MIN_REAL_CLIPS) + ["synthetic sinusoidal"] * 9,
                         "clip": ["09_06", "09_06", *[f"c{i}" for i in range(MIN_REAL_CLIPS)],
                                  *[f"s{i}" for i in range(9)]]})
    claims = pd.DataFrame({"dataset": ["cmu_09_06", "cmu_test", "synthetic", "cmu_09_06"],
                           "holds?": ["yes", "no", "partly (better)", "not run"]})
    guarded = guard_verdicts(claims, rows)["holds?"].tolist()
    assert guarded == ["too few clips (1 real clip; a verdict needs 5)", "no",
                       "too few clips (0 real clips; a verdict needs 5)", "not run"]


def test_the_margin_over_the_runner_up_is_taken_at_equal_error_on_each_curve():
    # Grid points: b's best under 1 cm is 20:1 at 0.8 cm, a's is 10:1 at 0.5 cm (2x apart at two errors).
    # On their curves at exactly 1 cm (log-log): a = 20:1, b = 20 * 1.5 ** (log 1.25 / log 1.5) = 25:1: 1.25x.
    points = pd.DataFrame([_point("a", 10.0, 0.5), _point("a", 40.0, 2.0), _point("b", 20.0, 0.8),
                           _point("b", 30.0, 1.2)])
    table = headline_table(points, (1.0,), unavailable={})
    assert list(table["codec"]) == ["b", "a"]
    assert list(table["CR"]) == [20.0, 10.0]
    assert table["CR at L∞ = bound"].tolist() == pytest.approx([25.0, 20.0])
    assert table["rank 1 ÷ this at equal L∞"].iloc[1] == pytest.approx(1.25)
    assert table["equal L∞ cm"].iloc[1] == 1.0
    sentence = winner_sentences(table)[0]
    assert "at equal L∞ (1 cm, read off each codec's curve) it is 1.25x the runner-up a" in sentence
    assert "2x" not in sentence
    # A bound beyond one curve: compared at the largest L∞ both reach (1.2 cm), never extrapolated.
    wide = headline_table(points, (3.0,), unavailable={})
    assert wide["equal L∞ cm"].iloc[1] == 1.2
    assert np.isnan(wide.loc[wide["codec"] == "b", "CR at L∞ = bound"].item())


def test_a_wider_bound_that_admits_nothing_new_does_not_repeat_the_table():
    points = pd.DataFrame([_point("a", 10.0, 0.5), _point("b", 20.0, 0.8)])
    table = headline_table(points, (1.0, 3.0), unavailable={})
    three = table[table["L∞ bound"] == "< 3 cm"]
    assert len(three) == 1 and three["codec"].item() == ""
    assert "the same codecs and configs as under 1 cm" in three["config"].item()
    sentences = winner_sentences(table)
    assert sentences[1] == ("cmu_test, L∞ < 3 cm: the same codecs and configs as under 1 cm (no codec has a config "
                            "between 1 and 3 cm).")
    # A config that only the wider bound admits gives the wider bound its own table.
    wider = headline_table(pd.concat([points, pd.DataFrame([_point("b", 40.0, 2.0)])]), (1.0, 3.0), unavailable={})
    assert list(wider.loc[wider["L∞ bound"] == "< 3 cm", "codec"]) == ["b", "a"]


def test_a_codec_that_refuses_a_rigs_tracks_shows_its_reason_not_a_failure():
    from mocapbench.experiments.headline import failure_reasons

    message = "TrackRefusal: svd: joint 'Hips' moves relative to its parent (a translation track)"
    errors = pd.DataFrame([{"dataset": "bandai_test", "codec": "svd", "stage": "refused", "error": message,
                            "clip": f"clip{i}"} for i in range(3)]
                          + [{"dataset": "bandai_test", "codec": "pga-ik", "stage": "evaluate", "error": "boom",
                              "clip": "clip0"}])
    reasons = failure_reasons(errors)
    assert reasons[("bandai_test", "svd")] == f"refused 3x: {message}"
    assert reasons[("bandai_test", "pga-ik")] == "failed 1x: boom"


def test_datasets_side_by_side_puts_each_codecs_ratio_and_linf_per_dataset_and_bound():
    import pandas as pd

    from mocapbench.experiments.headline import datasets_side_by_side

    def row(dataset, bound, rank, codec, cr=None, linf=None, config="c", rotations="yes"):
        return {"dataset": dataset, "L∞ bound": bound, "rank": rank, "codec": codec, "config": config, "CR": cr,
                "L∞ cm": linf, "rotations (BVH/glTF)": rotations}

    table = pd.DataFrame([
        row("cmu", "< 1 cm", 1, "b", 20.0, 0.9), row("cmu", "< 1 cm", 2, "a", 10.0, 0.5, rotations="no"),
        row("cmu", "< 3 cm", 1, "b", 40.0, 2.5), row("cmu", "< 3 cm", 2, "a", 12.0, 2.9, rotations="no"),
        row("game", "< 1 cm", 1, "a", 8.0, 0.7, rotations="no"),
        row("game", "< 1 cm", "–", "b", config="refused: a pelvis that moves"),
        row("game", "< 3 cm", "–", "", config="the same codecs and configs as under 1 cm (no config between)"),
    ])
    side = datasets_side_by_side(table)
    assert list(side.columns) == ["codec", "rotations (BVH/glTF)", "cmu CR < 1 cm", "cmu L∞ cm < 1 cm",
                                  "cmu CR < 3 cm", "cmu L∞ cm < 3 cm", "game CR < 1 cm", "game L∞ cm < 1 cm",
                                  "game CR < 3 cm", "game L∞ cm < 3 cm"]
    by_codec = side.set_index("codec")
    assert list(side["codec"]) == ["b", "a"]  # in the order of the first dataset's first bound
    assert by_codec.loc["b", "cmu CR < 3 cm"] == "40:1" and by_codec.loc["b", "cmu L∞ cm < 1 cm"] == "0.900"
    assert by_codec.loc["b", "game CR < 1 cm"] == "–" and by_codec.loc["b", "rotations (BVH/glTF)"] == "yes"
    # "the same as under 1 cm" repeats the 1 cm values
    assert by_codec.loc["a", "game CR < 3 cm"] == "8:1" and by_codec.loc["a", "game L∞ cm < 3 cm"] == "0.700"
    assert by_codec.loc["a", "rotations (BVH/glTF)"] == "no"
    assert datasets_side_by_side(table[table["dataset"] == "cmu"]).shape == (2, 6)
    # an L∞ just under the bound is cut, never rounded up to it
    close = pd.DataFrame([row("cmu", "< 1 cm", 1, "a", 5.0, 0.99996), row("cmu", "< 1 cm", 2, "b", 4.0, 3.08e-5)])
    assert list(datasets_side_by_side(close)["cmu L∞ cm < 1 cm"]) == ["0.999", "0.0000308"]
