"""compare's engine: models held out or paid for, rows kept as they finish, resumed, Ctrl-C keeps what finished."""

from __future__ import annotations

import io

import numpy as np
import pytest

from mocapbench.experiments import compare_run
from mocapbench.experiments.compare_progress import Progress, duration_text
from mocapbench.experiments.compare_run import (CodecOutcome, CompareInterrupted, RowStore, compare, default_codecs,
                                                estimate_cpu_s, format_codec_times, format_table, setting_text)
from mocapbench.experiments.held_out import FoldModels, models_bytes, plan_folds, skeleton_key
from mocapbench.synthetic import rig_motion


def _clips():
    """Three clips of a 20-joint biped and one of a 16-joint one (short: the tests run every codec's search)."""
    same = [rig_motion(num_joints=20, num_frames=40, fps=30.0, seed=s) for s in (1, 2, 3)]
    alone = rig_motion(num_joints=16, num_frames=40, fps=30.0, seed=4)
    return [*same, alone]


def test_folds_hold_each_clip_out_of_its_own_model():
    clips = _clips()
    folds = plan_folds(clips)
    assert len({skeleton_key(c) for c in clips}) == 2
    tests = sorted(i for fold in folds for i in fold.test)
    assert tests == [0, 1, 2, 3]  # every clip coded once
    for fold in folds:
        assert not set(fold.train) & set(fold.test)
        assert all(skeleton_key(clips[i]) == fold.skeleton for i in fold.train + fold.test)
    assert {fold.scheme for fold in folds} == {"leave-one-out", "no fit"}
    lone = [fold for fold in folds if fold.test == (3,)][0]
    assert lone.train == () and lone.scheme == "no fit"
    # More clips than folds: k-fold, still disjoint.
    many = [rig_motion(num_joints=16, num_frames=5, seed=s) for s in range(7)]
    kfold = plan_folds(many, folds=3)
    assert [len(f.test) for f in kfold] == [3, 2, 2] and {f.scheme for f in kfold} == {"3-fold"}
    assert all(not set(f.train) & set(f.test) and len(f.train) + len(f.test) == 7 for f in kfold)
    insample = plan_folds(clips, "in-sample")
    assert all(set(f.test) <= set(f.train) for f in insample)
    with pytest.raises(ValueError, match="model policy"):
        plan_folds(clips, "peeking")


def test_a_fit_that_changes_nothing_is_reported_as_the_shipped_model():
    clips = [rig_motion(num_joints=31, num_frames=30, seed=s) for s in (1, 2)]
    models = FoldModels("lsdt-frame", clips, plan_folds(clips))
    assert models.fitted(0) is None  # LSDT keeps its committed 31-joint bases
    from mocapbench.codecs import create

    codec = create("lsdt-frame")
    codec.encode(clips[0])
    source = models.source(0, codec)
    assert source.mode == "shipped" and source.model_bytes > 0


def test_learned_codecs_are_fit_out_of_sample_and_their_models_counted():
    clips = _clips()
    outcome = compare(clips, 1.0, ["mcb-linf"])[0]
    assert outcome.rows and not outcome.reason
    sources = {row["clip"]: row for row in outcome.rows}
    for clip in clips[:3]:
        row = sources[clip.name]
        assert row["model_source"] == "out-of-sample" and clip.name not in row["model_train_clips"]
        assert len(row["model_train_clips"]) == 2 and row["model_bytes"] > 0
    assert sources[clips[3].name]["model_source"] == "untrained"  # one clip of its skeleton: no fit
    # One model per skeleton is paid for: the largest fold's.
    fitted = [row["model_bytes"] for row in outcome.rows if row["model_source"] == "out-of-sample"]
    assert outcome.model_bytes == max(fitted)
    assert outcome.ratio == outcome.stream_ratio > outcome.ratio_with_models
    table = format_table([outcome], 1.0)
    assert "out-of-sample" in table and f"{outcome.model_bytes:,} B" in table


def test_in_sample_models_are_paid_for_in_the_ranked_ratio():
    clips = _clips()
    outcome = compare(clips, 1.0, ["mcb-linf"], policy="in-sample")[0]
    assert {row["model_source"] for row in outcome.rows} == {"in-sample"}
    assert outcome.in_sample and outcome.ratio == outcome.ratio_with_models < outcome.stream_ratio
    assert "(models in)" in format_table([outcome], 1.0)


def test_rows_are_kept_as_they_finish_and_a_second_run_resumes(tmp_path):
    clips = _clips()
    store = RowStore(tmp_path)
    first = compare(clips, 1.0, ["quant-delta-zstd", "svd"], store=store)
    assert (tmp_path / "svd" / "results.jsonl").exists()
    again = compare(clips, 1.0, ["quant-delta-zstd", "svd"], store=store)
    assert [o.resumed for o in again] == [4, 4]
    assert [o.stream_ratio for o in again] == [o.stream_ratio for o in first]
    # Another bound is another measurement.
    other = compare(clips, 2.0, ["quant-delta-zstd"], store=store)
    assert other[0].resumed == 0


def test_a_failed_codec_is_remembered_with_its_reason(tmp_path, monkeypatch):
    clips = _clips()[:1]
    store = RowStore(tmp_path)
    calls = []

    def broken(name, motion, bound, **kwargs):
        calls.append(name)
        raise RuntimeError("boom\nsecond line")

    monkeypatch.setattr("mocapbench.ratesearch.search", broken)
    outcome = compare(clips, 1.0, ["svd"], store=store)[0]
    assert outcome.reason == "RuntimeError: boom second line" and not outcome.rows
    assert compare(clips, 1.0, ["svd"], store=store)[0].reason == outcome.reason
    assert calls == ["svd"]  # the second run took the reason from the store


def test_ctrl_c_keeps_the_finished_codecs_and_rows(tmp_path, monkeypatch):
    clips = _clips()[:2]
    store = RowStore(tmp_path)
    real = compare_run._compare_codec

    def interrupting(name, *args):
        if name == "svd":
            raise KeyboardInterrupt
        return real(name, *args)

    monkeypatch.setattr(compare_run, "_compare_codec", interrupting)
    with pytest.raises(CompareInterrupted) as caught:
        compare(clips, 1.0, ["quant-delta-zstd", "svd", "raw-zstd"], store=store)
    assert [o.codec for o in caught.value.outcomes] == ["quant-delta-zstd"] and caught.value.current == "svd"
    assert (tmp_path / "quant-delta-zstd" / "results.jsonl").exists()


def test_the_default_set_leaves_the_neural_codecs_on_request():
    names = default_codecs()
    assert "fourier-mlp-int" not in names and "fourier-mlp-dct" not in names and "mcb-rot" in names
    clips = _clips()
    # A network trained per rate-search try: still an order of magnitude above a quantizer's search (costs.json).
    assert estimate_cpu_s("fourier-mlp-int", clips) > 10 * estimate_cpu_s("quant-delta-zstd", clips)


def test_settings_print_rounded():
    assert setting_text([{"step_cm": 1.1547005372245511}]) == "step_cm=1.15"
    assert setting_text([{"rank": 3}, {"rank": 9}]) == "rank=3..9"
    assert setting_text([{}]) == "-"


def test_unranked_rows_keep_their_reason():
    table = format_table([CodecOutcome("acl", [], reason="unavailable here: no compiler")], 1.0)
    assert "unavailable here: no compiler" in table


def test_progress_lines_say_what_is_left():
    out = io.StringIO()
    progress = Progress(4, stream=out, bar=False)
    progress.clip_start("svd", "a")
    progress.try_started()
    progress.try_started()
    progress.clip_done("svd", "a")
    progress.clip_done("svd", "b", resumed=True)
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("[1/4] svd on a: 2 tries,") and "left" in lines[0]
    assert lines[1].startswith("[2/4] svd on b: kept from the last run")
    assert progress.done_in("svd") == 2
    assert duration_text(125) == "2 min 5 s"


def test_models_bytes_counts_one_model_per_skeleton_and_shipped_once():
    rows = [{"model_key": "sk1/0", "model_bytes": 100}, {"model_key": "sk1/1", "model_bytes": 120},
            {"model_key": "shipped/31", "model_bytes": 50}, {"model_key": "shipped/31", "model_bytes": 50},
            {"model_key": "", "model_bytes": 0}]
    assert models_bytes(rows) == 170


def test_the_report_pools_what_the_table_pools():
    from mocapbench.experiments.aggregate import curve_points
    from mocapbench.experiments.compare_report import pooled_rows

    import pandas as pd

    clips = _clips()
    outcomes = compare(clips, 1.0, ["svd", "quant-delta-zstd"])
    pooled = pooled_rows(outcomes, 1.0)
    rows = pd.DataFrame([row for codec_rows in pooled.values() for row in codec_rows])
    points = curve_points(rows)
    assert len(points) == 2 and points["complete"].all()  # one configuration per codec, over every clip
    svd = points[points["codec"] == "svd"].iloc[0]
    outcome = [o for o in outcomes if o.codec == "svd"][0]
    assert svd["compression_ratio"] == pytest.approx(outcome.stream_ratio)
    ranks = sorted({s["rank"] for s in outcome.settings})
    expected = f"{ranks[0]}..{ranks[-1]} (rate search per clip)" if len(ranks) > 1 else str(ranks[0])
    assert svd["param_rank"] == expected
    # Fields at their default are not printed: svd's factor format stays at its default.
    assert "param_factor_format" not in pooled["svd"][0]


def test_the_papers_cmu_claims_are_left_out_on_a_users_clips():
    import pandas as pd

    from mocapbench.experiments.document import Document
    from mocapbench.experiments.report import _reproduction_section

    pooled = compare(_clips()[:2], 1.0, ["quant-delta-zstd"], dataset="studio")
    rows = pd.DataFrame(pooled[0].rows)
    doc = Document("t")
    _reproduction_section(doc, rows)
    assert "Reproduction" not in doc.markdown()
    rows["cmu_data"] = True
    _reproduction_section(doc, rows)
    assert "Reproduction of the papers' claims" in doc.markdown()


@pytest.mark.parametrize("name", ["quant-delta-zstd", "svd"])
def test_each_clip_is_encoded_only_by_its_search_and_the_row_is_the_chosen_stream(name, monkeypatch):
    from mocapbench.codecs import create
    from mocapbench.codecs.base import Codec

    clips = _clips()
    encodes = []
    real = Codec.encode

    def counted(self, motion, *args, **kwargs):
        encodes.append(motion.name)
        return real(self, motion, *args, **kwargs)

    monkeypatch.setattr(Codec, "encode", counted)
    outcome = compare(clips, 1.0, [name])[0]
    assert not outcome.reason and len(outcome.rows) == len(clips)
    assert len(encodes) == sum(row["rate_search_tries"] for row in outcome.rows)  # no encode beside the tries
    monkeypatch.setattr(Codec, "encode", real)
    for clip, row, settings in zip(clips, outcome.rows, outcome.settings):
        fresh = create(name, **settings)
        data = fresh.encode(clip)
        assert row["bitstream_bytes"] == len(data) and row["clip"] == clip.name
        assert row["encode_repeats"] == 1 and row["encode_threads"] == 1 and row["encode_cpu_s"] >= 0
        assert row["max_err_cm"] == pytest.approx(float(np.max(np.linalg.norm(
            fresh.decode(data).positions - clip.positions(), axis=-1))), rel=1e-9)


def test_the_time_of_every_codec_that_ran_is_told():
    ran = [CodecOutcome("svd", [], seconds=3.0, cpu_seconds=2.5), CodecOutcome("acl", [], seconds=9.0, cpu_seconds=8.0),
           CodecOutcome("unknown-codec", [], reason="unknown codec")]
    assert format_codec_times(ran) == "time per codec (wall / CPU): acl 9.0 / 8.0 s, svd 3.0 / 2.5 s"
    assert format_codec_times(ran[2:]) == ""
    outcome = compare(_clips()[:1], 1.0, ["raw-zstd"])[0]
    assert outcome.seconds > 0 and outcome.cpu_seconds > 0


def test_a_codec_that_encodes_many_at_once_is_searched_on_every_clip_in_lockstep(monkeypatch):
    from mocapbench.codecs import CODECS
    from mocapbench.codecs.base import Codec

    clips = _clips()
    alone = compare(clips, 1.0, ["svd"])[0]
    batches = []
    real = Codec.encode_many

    def counted(self, motions):
        batches.append(len(motions))
        return real(self, motions)

    monkeypatch.setattr(Codec, "encode_many", counted)
    monkeypatch.setattr(CODECS["svd"], "encodes_many", True)  # as the neural codecs, which train side by side
    progress = Progress(len(clips), stream=io.StringIO(), bar=False)
    together = compare(clips, 1.0, ["svd"], progress=progress)[0]
    assert max(batches) == len(clips)  # the first try (rank 1) of every clip in one call
    assert sum(batches) == sum(row["rate_search_tries"] for row in together.rows)
    keys = ("clip", "bitstream_bytes", "max_err_cm", "mean_err_cm", "rate_search_settings", "rate_search_tries")
    assert [{k: r[k] for k in keys} for r in together.rows] == [{k: r[k] for k in keys} for r in alone.rows]
    assert progress.finished == len(clips) and progress.measured == len(clips)


_TIMING = ("encode_s", "decode_s", "encode_fps", "decode_fps")


def _without_timing(row):
    """A row without what depends on the machine's speed at the time (the timings and load), as JSON text (NaN
    columns then compare equal)."""
    import json

    return json.dumps({key: value for key, value in row.items()
                       if key not in _TIMING and not key.startswith(("encode_wall", "encode_cpu", "encode_load",
                                                                     "decode_wall", "decode_cpu", "decode_load"))},
                      sort_keys=True, default=str)


@pytest.mark.slow
def test_codecs_run_side_by_side_give_the_rows_they_give_one_after_another(tmp_path):
    clips = _clips()
    names = ["svd", "mcb-linf", "quant-delta-zstd", "raw-zstd", "no-such-codec"]
    alone = compare(clips, 1.0, names, store=RowStore(tmp_path / "alone"))
    out = io.StringIO()
    progress = Progress(len(names) * len(clips), stream=out, bar=False, workers=2)
    together = compare(clips, 1.0, names, store=RowStore(tmp_path / "together"), progress=progress, workers=2)
    assert [o.codec for o in together] == [o.codec for o in alone]
    for one, other in zip(alone, together):
        assert one.reason == other.reason and len(one.rows) == len(other.rows)
        assert [_without_timing(r) for r in one.rows] == [_without_timing(r) for r in other.rows]
        stored = RowStore(tmp_path / "together")._rows(other.codec, "results.jsonl")
        assert [_without_timing(r) for r in stored] == [_without_timing(r) for r in other.rows]
    assert all(o.cpu_seconds > 0 for o in together if o.rows)  # measured in the worker that ran the codec
    lines = out.getvalue().splitlines()
    assert len(lines) == 4 * len(clips) and progress.finished == len(names) * len(clips)
    assert {line.split(" on ")[0].split("] ")[1] for line in lines} == {"svd", "mcb-linf", "quant-delta-zstd",
                                                                      "raw-zstd"}
    with pytest.raises(ValueError, match="workers must be >= 1"):
        compare(clips, 1.0, names, workers=0)


class _DyingStore(RowStore):
    """Rows stored as usual, but the worker process of codec ``victim`` kills itself when it looks for its rows (as
    the kernel kills a process out of memory): only in a worker, never in the test's own process."""

    def __init__(self, folder, victim: str) -> None:
        super().__init__(folder)
        self.victim = victim

    def find_failure(self, codec, key):
        import multiprocessing
        import os
        import signal

        if codec == self.victim:
            if multiprocessing.parent_process() is None:
                raise RuntimeError("_DyingStore kills worker processes only")
            os.kill(os.getpid(), signal.SIGKILL)
        return super().find_failure(codec, key)


@pytest.mark.slow
def test_a_worker_killed_mid_run_gives_its_codec_a_reason_and_the_others_their_rows(tmp_path):
    """A worker that dies without an outcome (killed, a crash in native code) is seen: its codec gets a row with the
    reason, the other codecs their rows, and compare returns (it does not wait for an outcome that never comes)."""
    import threading

    clips = _clips()
    names = ["raw-zstd", "svd", "quant-delta-zstd"]
    progress = Progress(len(names) * len(clips), stream=io.StringIO(), bar=False, workers=2)
    returned = []
    run = threading.Thread(target=lambda: returned.append(
        compare(clips, 1.0, names, store=_DyingStore(tmp_path, "svd"), progress=progress, workers=2)), daemon=True)
    run.start()
    run.join(timeout=300)
    assert returned, "compare did not return after a worker was killed"
    outcomes = {outcome.codec: outcome for outcome in returned[0]}
    assert outcomes["svd"].rows == [] and "ended without a result (killed by SIGKILL)" in outcomes["svd"].reason
    assert len(outcomes["raw-zstd"].rows) == len(outcomes["quant-delta-zstd"].rows) == len(clips)
    assert progress.finished == len(names) * len(clips)  # the killed codec's clips are counted as skipped


@pytest.mark.slow
def test_a_codec_named_twice_runs_once(tmp_path):
    clips = _clips()[:2]
    outcomes = compare(clips, 1.0, ["raw-zstd", "quant-delta-zstd", "raw-zstd"], store=RowStore(tmp_path), workers=2)
    assert sorted(o.codec for o in outcomes) == ["quant-delta-zstd", "raw-zstd"]
    rows = RowStore(tmp_path)._rows("raw-zstd", "results.jsonl")
    assert [row["clip"] for row in rows] == [clip.name for clip in clips]  # each clip's row written once


def test_the_command_counts_a_codec_named_twice_once():
    from mocapbench.cli.compare import _codec_names

    assert _codec_names("svd, raw-zstd,svd,,raw-zstd") == ["svd", "raw-zstd"]


class _BrokenStore(RowStore):
    """A store that fails for codec ``victim`` outside the codec's own try (an error compare does not turn into a
    row: it stops the run, in a worker as in this process)."""

    def __init__(self, folder, victim: str) -> None:
        super().__init__(folder)
        self.victim = victim

    def find_failure(self, codec, key):
        if codec == self.victim:
            raise OSError(f"cannot read the rows of {codec}")
        return super().find_failure(codec, key)


@pytest.mark.parametrize("workers", [1, 2])
def test_an_error_outside_a_codec_stops_the_run_in_a_worker_as_in_this_process(tmp_path, workers):
    with pytest.raises(OSError, match="cannot read the rows of svd"):
        compare(_clips()[:2], 1.0, ["raw-zstd", "svd"], store=_BrokenStore(tmp_path, "svd"), workers=workers)


def test_a_ctrl_c_while_a_worker_starts_is_noted_not_lost():
    import os
    import signal
    import time

    class Starting:  # a process whose start takes a Ctrl-C (a spawned worker's start takes a second)
        def start(self):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)

    # Python's own handler, as in a terminal (a run started in the background inherits SIGINT ignored, and then
    # there is no Ctrl-C to note).
    outside = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        assert compare_run._start_worker(Starting()) is True
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, outside)

