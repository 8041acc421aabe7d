"""The PGA paper reproduction's report on synthetic clips standing in for CMU's: every section, in order, printed as
it comes and written to pga.md."""

from __future__ import annotations

import pytest

from mocapbench.benchmarks.pga import paper
from mocapbench.motion import Motion
from mocapbench.synthetic import sinusoidal_motion

pytestmark = pytest.mark.slow


@pytest.fixture
def synthetic_clips(monkeypatch):
    """Every clip name reads a synthetic motion of that name; every split lists two of them."""

    def load_clip(name: str, data_dir=None) -> Motion:
        motion = sinusoidal_motion(num_frames=64, seed=sum(map(ord, name)))
        return Motion(motion.skeleton, motion.fps, motion.root_positions, motion.rotations, name)

    monkeypatch.setattr(paper, "load_clip", load_clip)
    monkeypatch.setattr(paper, "clip_names", lambda split, data_dir=None: ["s1", "s2"])


def test_quick_report_has_every_section_and_is_written(synthetic_clips, tmp_path, capsys):
    paper.main(["--quick", "--repeats", "1", "--out", str(tmp_path)])
    printed = capsys.readouterr().out
    report = (tmp_path / "pga.md").read_text()
    assert report.rstrip("\n") in printed
    headings = [line for line in report.splitlines() if line.startswith("## ")]
    assert headings == ["## 1. Table 2, clip 1: 09_06 (running, 141 frames)", "## 2. The same protocol over cmu_test",
                        "## 3. The paper's other rows' settings on similar clips",
                        "## 4. Fig. 3: geodesics reaching 95 % / 99 % of the tangent variance",
                        "## 5. Speed (one thread)"]
    rows = [line for line in report.splitlines() if line.startswith("| ") and "---" not in line]
    settings = [row for row in rows if row.startswith(("| paper setting", "| k = 6, ", "| k = 12, ", "| k = 9"))]
    assert len(settings) == 6 + 8  # section 1's variants, section 2's totals
    assert sum(row.startswith("| walk (17_08) | 02_01 |") for row in rows) == 1  # --quick: one clip per paper row
    assert "Over 2 clips:" in report
    assert sum(row.startswith(("| 1 | 09_06", "| 2 | 09_06", "| 5 | 09_06")) for row in rows) == 9  # k x iterations


def test_the_totals_pool_sizes_and_take_the_worst_error():
    rows = [{"frames": 10, "joints": 2, "paper_ratio": 4.0, "bytes": 60, "K": 3, "kg": 1.0, "linf": 0.5, "mean": 0.1,
             "end_linf": 0.2, "decode_ms": 1.0, "decode_cpu_ms": 1.0, "encode_s": 1.0},
            {"frames": 30, "joints": 2, "paper_ratio": 2.0, "bytes": 180, "K": 5, "kg": 3.0, "linf": 2.0, "mean": 0.3,
             "end_linf": 0.1, "decode_ms": 3.0, "decode_cpu_ms": 2.0, "encode_s": 2.0}]
    total = paper.total_row(rows, "both")
    assert total["K"] == "3-5" and total["frames"] == 40 and total["linf"] == 2.0 and total["kg"] == 2.0
    assert total["real_ratio"] == pytest.approx(12 * 2 * 40 / 240)
    assert total["paper_ratio"] == pytest.approx(240 / (60 / 4 + 180 / 2))
    assert total["mean"] == pytest.approx((0.1 * 10 + 0.3 * 30) / 40)
