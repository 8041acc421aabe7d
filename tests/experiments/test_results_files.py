"""Machine-readable results in the report folder, read back by ``mocapbench plot``, which overlays two reports."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from mocapbench.cli import main as cli
from mocapbench.codecs import create
from mocapbench.experiments.aggregate import curve_points
from mocapbench.experiments.evaluate import TimingSettings, evaluate
from mocapbench.experiments.results_files import ResultsFileError, load, load_many, write_results
from mocapbench.synthetic import sinusoidal_motion

FAST = TimingSettings(repeats=1, warmup=0)


@pytest.fixture(scope="module")
def rows():
    motions = [sinusoidal_motion(num_frames=40, seed=seed) for seed in (1, 2)]
    out = []
    for name, params in [("quant-delta-zstd", {"step_cm": 0.2}), ("quant-delta-zstd", {"step_cm": 2.0}),
                         ("raw-zstd", {})]:
        codec = create(name, **params)
        for motion in motions:
            out.append({**evaluate(codec, motion, timing=FAST), "dataset": "synthetic", "dataset_desc": "synthetic"})
    return pd.DataFrame(out)


def _report(folder, rows):
    folder.mkdir()
    return write_results(folder, rows, curve_points(rows))


def test_one_json_per_codec_and_dataset_and_one_csv(rows, tmp_path):
    written = _report(tmp_path / "r", rows)
    assert [p.relative_to(tmp_path / "r").as_posix() for p in written] == [
        "results/synthetic/quant-delta-zstd.json", "results/synthetic/raw-zstd.json", "results/rows.csv"]
    document = json.loads(written[0].read_text())
    assert document["name"] == "quant-delta-zstd" and document["family"] == "generic" and document["description"]
    assert [c["params"]["step_cm"] for c in document["configs"]] == [2.0, 0.2]  # by increasing rate
    for metric in ("compression_ratio", "bits_per_joint_frame", "max_err_cm", "mean_err_cm", "p99_err_cm",
                   "kg_percent", "encode_fps", "decode_fps"):
        assert len(document["results"][metric]) == 2, metric
    assert document["results"]["bits_per_joint_frame"][0] < document["results"]["bits_per_joint_frame"][1]
    csv = pd.read_csv(written[-1])
    assert len(csv) == len(rows) and {"codec", "clip", "encode_cpu_s", "encode_wall_s"} <= set(csv.columns)
    back = load(written[0])
    assert back["bits_per_joint_frame"].tolist() == document["results"]["bits_per_joint_frame"]
    assert back["param_step_cm"].tolist() == [2.0, 0.2]


def test_bad_results_files_get_one_clear_line(tmp_path):
    (tmp_path / "a.json").write_text("{not json")
    (tmp_path / "b.json").write_text(json.dumps({"name": "x"}))
    with pytest.raises(ResultsFileError, match="a.json: not JSON"):
        load(tmp_path / "a.json")
    with pytest.raises(ResultsFileError, match="not a mocapbench results file"):
        load(tmp_path / "b.json")
    with pytest.raises(ResultsFileError, match="no such file"):
        load_many([tmp_path / "missing"])


def test_mocapbench_plot_overlays_two_report_folders(rows, tmp_path, capsys):
    _report(tmp_path / "run-a", rows)
    _report(tmp_path / "run-b", rows)
    out = tmp_path / "plots"
    assert cli(["plot", str(tmp_path / "run-a"), str(tmp_path / "run-b"), "-o", str(out)]) == 0
    for metric in ("max_err_cm", "mean_err_cm", "kg_percent"):
        assert (out / f"rd_{metric}.png").stat().st_size > 5000 and (out / f"rd_{metric}.svg").exists()
    svg = (out / "rd_max_err_cm.svg").read_text()
    assert "quant-delta-zstd [run-a]" in svg and "quant-delta-zstd [run-b]" in svg  # two runs told apart
    assert "raw-zstd [run-a] (generic): lossless" in svg  # kept off the log axis, noted at the edge
    assert "neural Fourier" in svg  # a published point
    assert cli(["plot", str(tmp_path / "run-a"), "-o", str(out)]) == 2  # never over existing figures
    assert "exists; pass --force" in capsys.readouterr().err
    assert cli(["plot", str(tmp_path / "nothing-here"), "-o", str(out)]) == 2


def test_mocapbench_plot_draws_one_figure_per_dataset_and_grows_with_its_legend(rows, tmp_path):
    import matplotlib.image

    # Two datasets, 20 codec curves per source, two sources: 40 legend lines on each figure.
    many = pd.concat([rows.assign(dataset=dataset, codec=rows["codec"] + f"-{copy}")
                      for dataset in ("synthetic", "synthetic_24fps") for copy in range(10)], ignore_index=True)
    _report(tmp_path / "run-a", many)
    _report(tmp_path / "run-b", many)
    out = tmp_path / "plots"
    assert cli(["plot", str(tmp_path / "run-a"), str(tmp_path / "run-b"), "-o", str(out)]) == 0
    assert not (out / "rd_max_err_cm.png").exists()
    for dataset in ("synthetic", "synthetic_24fps"):
        svg = (out / f"rd_max_err_cm_{dataset}.svg").read_text()
        assert f"{dataset}: bits/joint/frame" in svg and "quant-delta-zstd-9 [run-b]" in svg
        height, width = matplotlib.image.imread(out / f"rd_max_err_cm_{dataset}.png").shape[:2]
        assert height > 0.8 * width  # 40 legend lines: taller than the 10 x 6 in default, the axes keep their size


def test_curve_points_of_a_sweep_with_many_settings_warns_nothing(rows):
    """A sweep over every codec has a column per setting of any codec (over a hundred): pooling it must not make
    pandas warn (a PerformanceWarning per derived column was printed by every ``make run``)."""
    import warnings

    wide = pd.concat([rows, pd.DataFrame({f"param_setting_{i}": [float(i)] * len(rows) for i in range(150)},
                                         index=rows.index)], axis=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", pd.errors.PerformanceWarning)
        points = curve_points(wide)
    assert len(points) == 3 and (points["param_setting_149"] == 149.0).all()
