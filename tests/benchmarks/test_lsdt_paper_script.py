"""The LSDT paper reproduction's Figs. 6/7 on a synthetic clip: every curve in the CSV and the plots, the RD points
as printed, and a line per claim."""

from __future__ import annotations

import csv

import pytest

from mocapbench.benchmarks.lsdt import paper
from mocapbench.synthetic import sinusoidal_motion

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def fig67_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("lsdt")
    text = paper.fig67([sinusoidal_motion(num_frames=120, seed=5)], out)
    return text, out


def test_every_curve_is_written_plotted_and_printed(fig67_run):
    text, out = fig67_run
    with (out / "fig67_rd.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == len(paper.FIG67_CONFIGS) * len(paper.STEPS_CM)
    assert (out / "fig6_frame_based.png").stat().st_size > 0 and (out / "fig7_clip_based.png").stat().st_size > 0
    printed = [line for line in text.splitlines() if line.startswith("| ") and not line.startswith("| codec")]
    for row in rows:  # each CSV row is one printed RD point, with its ratio and distortion
        line = (f"| {row['label']} | {float(row['step_cm']):g} | {float(row['cr']):.2f} | "
                f"{float(row['distortion_cm']):.4f} |")
        assert any(p.startswith(line) for p in printed), line
    assert all(float(row["cr"]) == pytest.approx(12 * 31 * 120 / int(row["bytes"])) for row in rows)


def test_every_claim_has_its_line(fig67_run):
    text, _ = fig67_run
    claims = text.split("**Claims**", 1)[1]
    for start in ("LSDT vs DCT, frame-based", "lsdt-clip L=120 vs lsdt-frame", "L=60 → L=120", "L=120 → L=240",
                  "lsdt-clip L=120 vs dct-spatial-clip L=120", "lsdt-clip L=120 vs dwt-spatial-clip L=120",
                  "lsdt-frame vs dwt-spatial-frame", "lsdt-frame with Huffman-coded counts",
                  "lsdt-clip L=120 with Huffman-coded counts"):
        assert sum(line.startswith(start) for line in claims.splitlines()) == 1, start
    huffman = next(line for line in claims.splitlines() if line.startswith("lsdt-frame with Huffman"))
    assert huffman.count("step ") == len(paper.STEPS_CM)


def test_reductions_are_taken_where_the_other_curve_reaches():
    curve = [{"cr": 2.0, "distortion_cm": 1.0}, {"cr": 50.0, "distortion_cm": 4.0}]
    other = [{"cr": 1.0, "distortion_cm": 0.5}, {"cr": 4.0, "distortion_cm": 0.5}]
    assert paper._reductions(curve, other) == [(2.0, 50.0)]
