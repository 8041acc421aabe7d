"""Figures: fixed codec styles whatever the subset, family line styles, lossless off the log axes, 10 px text."""

from __future__ import annotations

import pandas as pd

from mocapbench.experiments import plots


def test_a_codec_keeps_its_colour_and_marker_in_every_subset():
    assert plots.codec_style("mcb-linf") == plots.codec_style("mcb-linf")
    assert plots.codec_style("quant-delta-zstd")["color"] != plots.codec_style("quant-rot-zstd")["color"]
    later = plots.codec_style("some-future-codec")
    assert later == plots.codec_style("some-future-codec") and later["color"].startswith("#")


def test_line_style_tells_the_family():
    styles = {f: plots.family_linestyle(f) for f in ("paper", "generic", "production", "mocapbench")}
    assert len(set(styles.values())) == 4
    assert plots.codec_style("quant-delta-zstd")["linestyle"] == "--"  # generic, from the registry


def test_rd_figure_keeps_lossless_points_off_the_axis_and_text_readable(tmp_path):
    points = pd.DataFrame({"codec": ["raw-zstd", "quant-delta-zstd", "quant-delta-zstd"],
                           "bits_per_joint_frame": [70.0, 10.0, 4.0], "max_err_cm": [1e-5, 0.1, 0.9],
                           "family": ["generic"] * 3})
    path = plots.rd_metric_figure(points, "demo", "max_err_cm", tmp_path / "rd.png", bounds=(1.0, 3.0))
    svg = path.with_suffix(".svg").read_text()
    assert "raw-zstd (generic): lossless, 70 bits" in svg and "3 cm" in svg
    assert plots.rd_metric_figure(points, "demo", "shell_max_err_cm", tmp_path / "none.png") is None

    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(30, 4))
    ax.set_title("tiny", fontsize=8)
    assert plots.smallest_text_px(fig) < 10  # the check that _save applies can fail
    plt.close(fig)


def test_the_text_check_after_a_save_reads_what_a_draw_of_its_own_reads(tmp_path, caplog):
    import io
    import logging

    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(30, 4), layout="constrained")
    ax.set_title("tiny", fontsize=8)
    ax.legend(handles=ax.plot([0, 1], label="a long label " * 8), loc="upper left")
    fig.savefig(io.BytesIO(), format="png", dpi=plots.DPI, bbox_inches="tight")
    after_save = plots.smallest_text_px(fig, draw=False)
    assert abs(after_save - plots.smallest_text_px(fig)) < 1e-6 * after_save and after_save < 10
    with caplog.at_level(logging.WARNING, logger=plots.__name__):
        plots._save(fig, tmp_path / "tiny.png")  # warns from the layout of the save, without its own draw
    assert "smallest text" in caplog.text and (tmp_path / "tiny.svg").exists()
