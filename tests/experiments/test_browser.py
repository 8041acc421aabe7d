"""The report as a browser shows it: headless Chromium loads index.html, every image loads, nothing overflows.

Marked ``browser`` (excluded from the default run; ``.ci/run`` installs Chromium when it is missing and runs
``make test-browser``). Without Chromium this test fails with the line that says how to install it.
"""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench.codecs import create
from mocapbench.experiments.browser_check import check_report
from mocapbench.experiments.evaluate import TimingSettings, evaluate
from mocapbench.experiments.report import build_report
from mocapbench.experiments.run import write_rows_atomic
from mocapbench.synthetic import sinusoidal_motion

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """A report of four codecs (a lossless one, a rotation codec, a wide table of configs) on 3 synthetic clips."""
    root = tmp_path_factory.mktemp("browser")
    motions = [sinusoidal_motion(num_frames=60, seed=seed) for seed in (1, 2, 3)]
    jobs = [("quant-delta-zstd", {"step_cm": s}) for s in (0.05, 0.4, 2.0)] + \
        [("quant-rot-zstd", {"rotation_bits": b}) for b in (8, 12)] + [("raw-zstd", {})] + \
        [("mcb-linf", {"eps_cm": e}) for e in (0.2, 1.0)]
    for name, params in jobs:
        codec = create(name, **params)
        folder = root / "sweep" / name / (",".join(f"{k}={v}" for k, v in params.items()) or "default")
        rows = [{**evaluate(codec, m, timing=TimingSettings(repeats=1, warmup=0)), "dataset": "synthetic",
                 "dataset_desc": "synthetic sinusoidal", "train_set": "synthetic", "cmu_data": False}
                for m in motions]
        write_rows_atomic(folder / "results.jsonl", rows)
        np.savez_compressed(folder / "example.npz", original=motions[0].positions().astype(np.float32),
                            decoded=codec.decode(codec.encode(motions[0])).positions.astype(np.float32),
                            parents=np.asarray(motions[0].skeleton.parents),
                            names=np.asarray(motions[0].skeleton.names), clip=np.asarray(motions[0].name),
                            fps=np.asarray(motions[0].fps))
    return build_report([root / "sweep"], name="browser", reports_root=root / "reports", bounds=[0.5])


def test_every_image_loads_and_nothing_overflows_the_page(report, tmp_path):
    check = check_report(report, tmp_path / "shots", widths=(1280, 1024))
    assert check.ok, "\n".join(check.failures)
    assert len(check.findings) == 2 and "all loaded: True" in check.findings[0]
    names = sorted(p.name for p in check.screenshots)
    assert "top.png" in names and "headline-which-codec-to-pick.png" in names and "pictures.png" in names
    for path in check.screenshots:
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000


def test_a_broken_image_is_found(report, tmp_path):
    index = report / "index.html"
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "index.html").write_text(index.read_text().replace("figures/", "missing/", 1) +
                                       "<div style='width:3000px'>wide</div>")
    check = check_report(broken, tmp_path / "shots2", widths=(1280,))
    assert any("image did not load: missing/" in f for f in check.failures), check.failures
    assert any("overflows the page" in f or "px wide in a" in f for f in check.failures), check.failures
