"""Report generation from a small fixture results file: tables, figures, BD-rate, reproduction, no overwrite."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mocapbench.codecs import create
from mocapbench.experiments.aggregate import AggregateError, aggregate, curve_points
from mocapbench.experiments.bdrate import bd_rate_percent, pareto_front
from mocapbench.experiments.evaluate import TimingSettings, evaluate
from mocapbench.experiments.reproduction import compare_at_equal_rate, neural_fourier_tables, pga_tables
from mocapbench.experiments.report import CMU_ACKNOWLEDGEMENT, build_report, headline_table
from mocapbench.experiments.run import write_rows_atomic
from mocapbench.synthetic import sinusoidal_motion

ONCE = TimingSettings(repeats=1, warmup=0)  # speeds are not checked here
STEPS = (0.05, 0.2, 0.8, 3.0)
BITS = (6, 8, 10)


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory):
    """A sweep-like folder: quant-pred-zstd (4 steps) and quant-rot-zstd (3 bit depths) on 2 short clips."""
    root = tmp_path_factory.mktemp("sweep")
    motions = [sinusoidal_motion(num_frames=60, seed=seed) for seed in (1, 2)]
    jobs = [("quant-pred-zstd", {"step_cm": s}) for s in STEPS] + [("quant-rot-zstd", {"rotation_bits": b}) for b in BITS]
    for name, params in jobs:
        codec = create(name, **params)
        folder = root / name / ",".join(f"codec.{k}={v}" for k, v in params.items())
        rows = []
        for motion in motions:
            row = evaluate(codec, motion, timing=ONCE)
            row.update({"dataset": "synthetic", "train_set": "synthetic seeds 11-13", "cmu_data": False})
            rows.append(row)
        write_rows_atomic(folder / "results.jsonl", rows)
        reference = motions[0].positions()
        np.savez_compressed(folder / "example.npz", original=reference.astype(np.float32),
                            decoded=codec.decode(codec.encode(motions[0])).positions.astype(np.float32),
                            parents=np.asarray(motions[0].skeleton.parents),
                            names=np.asarray(motions[0].skeleton.names), clip=np.asarray(motions[0].name),
                            fps=np.asarray(motions[0].fps))
    (root / "quant-rot-zstd" / "codec.rotation_bits=6" / "errors.jsonl").write_text(
        json.dumps({"codec": "quant-rot-zstd", "clip": "synthetic-seed9", "stage": "evaluate", "error": "boom"}) + "\n")
    return root


def test_aggregate_reads_every_row(sweep_dir):
    data = aggregate([sweep_dir])
    assert len(data) == (len(STEPS) + len(BITS)) * 2
    assert set(data["codec"]) == {"quant-pred-zstd", "quant-rot-zstd"}
    assert (data["sweep_dir"] == str(sweep_dir)).all()
    assert len(aggregate([sweep_dir, sweep_dir])) == len(data)  # the same rows twice are kept once


def test_aggregate_of_nothing_is_a_clear_error(tmp_path):
    with pytest.raises(AggregateError, match="no results.jsonl rows"):
        aggregate([tmp_path])
    with pytest.raises(AggregateError, match="no such sweep folder"):
        aggregate([tmp_path / "missing"])


def test_curve_points_pool_clips(sweep_dir):
    data = aggregate([sweep_dir])
    points = curve_points(data)
    assert len(points) == len(STEPS) + len(BITS)
    one = points[(points["codec"] == "quant-pred-zstd") & (points["param_step_cm"] == 0.8)].iloc[0]
    rows = data[(data["codec"] == "quant-pred-zstd") & (data["param_step_cm"] == 0.8)]
    assert one["clips"] == 2
    assert one["bitstream_bytes"] == rows["bitstream_bytes"].sum()
    assert one["max_err_cm"] == rows["max_err_cm"].max()
    assert one["compression_ratio"] == pytest.approx(rows["raw_bytes"].sum() / rows["bitstream_bytes"].sum())


def test_headline_picks_the_highest_ratio_under_each_bound(sweep_dir):
    points = curve_points(aggregate([sweep_dir]))
    table = headline_table(points, unavailable={})
    assert set(table["L∞ bound"]) == {"< 1 cm", "< 3 cm"}
    assert len(table) == 2 * 2  # 2 codecs x 2 bounds
    for _, row in table.iterrows():
        if row["rank"] == "–":
            continue
        bound = float(row["L∞ bound"].split()[1])
        assert row["L∞ cm"] < bound
        candidates = points[(points["codec"] == row["codec"]) & (points["max_err_cm"] < bound)]
        assert row["CR"] == pytest.approx(candidates["compression_ratio"].max())


def test_report_writes_tables_and_figures_and_never_overwrites(sweep_dir, tmp_path):
    first = build_report([sweep_dir], name="fixture", reports_root=tmp_path)
    second = build_report([sweep_dir], name="fixture", reports_root=tmp_path)
    assert first != second and first.exists() and second.exists()
    markdown = (first / "report.md").read_text()
    html = (first / "index.html").read_text()
    for text in ("Headline", "ACL 2.1 [quoted, not measured here]", "BD-rate against quant-pred-zstd",
                 "Neural Fourier", "LSDT", "PGA", "Data and method", "12·J·F bytes", "Failed jobs", "boom"):
        assert text in markdown, text
        assert text in html or text.replace("·", "&middot;") in html, text
    assert "not run" in markdown  # the paper codecs are absent from this fixture
    assert CMU_ACKNOWLEDGEMENT not in markdown  # no CMU clip was used
    figures = sorted(p.name for p in (first / "figures").glob("*.png"))
    assert figures == ["animators_synthetic_1cm.png", "animators_synthetic_3cm.png", "clips_synthetic_1cm.png", "clips_synthetic_3cm.png", "heatmap_synthetic.png",
                       "overlay_synthetic.png", "rd_kg_percent_synthetic.png", "rd_max_err_cm_synthetic.png",
                       "rd_mean_err_cm_synthetic.png", "rd_per_clip_synthetic.png",
                       "rd_shell_max_err_cm_synthetic.png"]  # ACL's shell error: quant-rot-zstd returns rotations
    for name in figures:
        assert f"figures/{name}" in markdown and f"figures/{name}" in html
        assert (first / "figures" / name).stat().st_size > 5000
        svg = (first / "figures" / name).with_suffix(".svg")
        assert svg.read_text().lstrip().startswith("<?xml") and f"figures/{svg.name}" in html
    assert markdown.startswith("# mocapbench report: fixture\n\n**Synthetic data only")
    assert 'id="headline-which-codec-to-pick"' in html and 'href="#headline-which-codec-to-pick"' in html
    assert html.count("<table>") == html.count('<div class="table-scroll"><table>')


def test_report_carries_the_cmu_acknowledgement_when_cmu_was_used(tmp_path):
    codec = create("quant-pred-zstd", step_cm=0.5)
    motion = sinusoidal_motion(num_frames=30, seed=3)
    row = {**evaluate(codec, motion, timing=ONCE), "dataset": "cmu_test", "cmu_data": True, "train_set": "CMU cmu_train"}
    write_rows_atomic(tmp_path / "sweep" / "job" / "results.jsonl", [row])
    report = build_report([tmp_path / "sweep"], reports_root=tmp_path / "reports")
    assert CMU_ACKNOWLEDGEMENT in (report / "report.md").read_text()


def test_bd_rate_of_half_the_rate_is_minus_50_percent():
    rate = np.array([1.0, 2.0, 4.0, 8.0])
    error = np.array([4.0, 2.0, 1.0, 0.5])
    value, note = bd_rate_percent(rate, error, rate / 2, error)
    assert value == pytest.approx(-50.0, abs=1e-6)
    value, _ = bd_rate_percent(rate, error, rate * 1.1, error)
    assert value == pytest.approx(10.0, abs=1e-6)


def test_bd_rate_says_why_it_cannot_be_computed():
    value, note = bd_rate_percent([1.0, 2.0], [2.0, 1.0], [3.0], [0.0])
    assert np.isnan(value) and "Pareto" in note
    value, note = bd_rate_percent([1.0, 2.0], [2.0, 1.0], [1.0, 2.0], [20.0, 10.0])
    assert np.isnan(value) and "overlap" in note


def test_pareto_front_drops_dominated_and_lossless_points():
    rate, error = pareto_front([1, 2, 3, 4, 5], [3.0, 3.5, 1.0, 0.0, 0.5])
    assert rate.tolist() == [1, 3, 5] and error.tolist() == [3.0, 1.0, 0.5]


def _rows(codec, clip, rates, errors, **extra):
    return pd.DataFrame({"codec": codec, "clip": clip, "bits_per_joint_frame": rates, "mean_err_cm": errors,
                         "max_err_cm": errors, **extra})


def test_compare_at_equal_rate_measures_the_reduction():
    rates = np.array([1.0, 2.0, 4.0])
    test = _rows("a", "c1", rates, np.array([2.0, 1.0, 0.5]))
    ref = _rows("b", "c1", rates, np.array([4.0, 2.0, 1.0]))
    table = compare_at_equal_rate(test, ref)
    assert len(table) == 1
    assert table["mean_reduction_percent"].iloc[0] == pytest.approx(50.0)
    assert bool(table["test_better"].iloc[0])
    assert not compare_at_equal_rate(ref, test)["test_better"].iloc[0]


def test_neural_fourier_table_uses_the_paper_ratio_and_two_percent_of_height():
    rows = pd.concat([
        _rows("fourier-mlp-dct", "c1", [1.0, 2.0], [5.0, 2.0], max_err_percent_height=[3.0, 1.2],
              compression_ratio=[30.0, 12.0], paper_compression_ratio=[9.0, 4.0], param_K=[2, 5]),
        _rows("fourier-mlp-dct", "c2", [1.0, 2.0], [5.0, 2.0], max_err_percent_height=[2.5, 1.9],
              compression_ratio=[30.0, 12.0], paper_compression_ratio=[9.0, 1.5], param_K=[2, 5]),
        _rows("fourier-mlp-dct", "c3", [1.0, 2.0], [5.0, 2.0], max_err_percent_height=[1.0, 0.5],
              compression_ratio=[30.0, 12.0], paper_compression_ratio=[9.0, 4.0], param_K=[2, 5]),
    ])
    detail, claims = neural_fourier_tables(rows)
    first = claims.iloc[0]
    assert "2/3" in first["measured here"] and first["holds?"] == "yes"
    assert claims.iloc[1]["holds?"] == "not run"  # fourier-mlp-int absent
    assert detail.loc[detail["clip"] == "c3", "CR (paper's raw)"].iloc[0] == 9.0


def test_naive_frequency_claim_names_each_arms_trainer_and_keeps_its_computed_verdict():
    rates = [1.0, 2.0, 4.0]
    rows = pd.concat([
        _rows("fourier-mlp-dct", clip, rates, [4.0, 2.0, 1.0], max_err_percent_height=[3.0, 2.0, 1.0],
              compression_ratio=[30.0, 15.0, 8.0], param_optimizer="lbfgs")
        for clip in ("c1", "c2", "c3")] + [
        _rows("fourier-mlp-int", clip, rates, [3.0, 1.5, 0.8], max_err_percent_height=[3.0, 2.0, 1.0],
              compression_ratio=[30.0, 15.0, 8.0], param_optimizer="adam" if clip == "c1" else "lbfgs")
        for clip in ("c1", "c2", "c3")])
    claims = neural_fourier_tables(rows)[1]
    naive = claims[claims["claim (published)"].str.contains("naive")].iloc[0]
    assert naive["holds?"] == "no"  # the naive curve is lower on every clip: the notice does not change the verdict
    assert "0/3" in naive["measured here"]
    assert "fourier-mlp-dct lbfgs, fourier-mlp-int adam/lbfgs" in naive["measured here"]
    without = neural_fourier_tables(rows.drop(columns="param_optimizer"))[1]
    assert "trained by" not in without[without["claim (published)"].str.contains("naive")].iloc[0]["measured here"]


def test_pga_table_compares_09_06_at_the_paper_distortion():
    rows = _rows("pga-ik", "09_06", [1.0, 2.0], [3.0, 1.0], kg_percent=[0.5, 0.3],
                 compression_ratio=[40.0, 20.0], paper_compression_ratio=[45.0, 25.0], decode_fps=[100.0, 100.0],
                 param_num_geodesics=[6, 12])
    table = pga_tables(rows)
    first = table[table["clip"] == "09_06"].iloc[0]
    assert first["ours"] == "yes"  # 1:25 (paper's raw) at 0.3 % <= 0.36 %, better than 1:18
    assert first["ours: ratio (paper's raw)"] == "1:25"
    assert "not available" in table[table["clip"] == "17_08"].iloc[0]["ours"]
    assert "not run" in pga_tables(rows.iloc[:0])["ours"].iloc[0]


def test_figures_drawn_elsewhere_land_in_the_documents_order(tmp_path):
    import math
    from concurrent.futures import Future

    from mocapbench.experiments.document import Document, image_fill
    from mocapbench.experiments.plots import FigurePool

    doc = Document("t")
    first, second = Future(), Future()
    doc.heading("a")
    doc.later(first, image_fill(tmp_path, "one"))
    doc.paragraph("middle")
    doc.later(second, image_fill(tmp_path, "two", "nothing to draw"))
    second.set_result(None)  # the results come in any order
    first.set_result(tmp_path / "figures" / "x.png")
    doc.resolve()
    assert [kind for kind, _ in doc.blocks] == ["heading", "image", "paragraph", "paragraph"]
    assert doc.blocks[1][1] == ("figures/x.png", "one") and doc.blocks[3][1] == ("nothing to draw", False)
    with FigurePool(2) as pool, FigurePool(1) as here:
        assert pool.draw(math.sqrt, 6.25).result() == here.draw(math.sqrt, 6.25).result() == 2.5


def test_a_document_rendered_before_it_is_resolved_keeps_its_figures(tmp_path):
    from concurrent.futures import Future

    from mocapbench.experiments.document import Document, image_fill

    drawn = Future()
    drawn.set_result(tmp_path / "figures" / "rd.png")
    for render in (Document.markdown, Document.html):
        doc = Document("t")
        doc.later(drawn, image_fill(tmp_path, "the rate-distortion figure"))
        assert "figures/rd.png" in render(doc) and "the rate-distortion figure" in render(doc)


def test_figure_workers_leave_ctrl_c_to_the_report():
    """SIGINT reaches every process of the terminal's group: the figure workers ignore it, the report handles it."""
    import signal

    from mocapbench.experiments.plots import FigurePool

    with FigurePool(2) as pool:
        assert pool.draw(signal.getsignal, signal.SIGINT).result() == signal.SIG_IGN
