"""The mcb-rot benchmark's rate-distortion section on a synthetic clip: every table, with the reference ACL table
standing in for ACL (as on a machine without ACL 2.1) and one sweep curve joining the comparison."""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench.benchmarks.mcb_rot import rd
from mocapbench.codecs import CODECS
from mocapbench.synthetic import sinusoidal_motion


def _tables(text: str) -> dict[str, list[list[str]]]:
    """Each '### ' heading's markdown table, as rows of cells (header and rule left out)."""
    tables, heading = {}, None
    for line in text.splitlines():
        if line.startswith("### "):
            heading = line[4:]
            tables[heading] = []
        elif line.startswith("| ") and heading is not None:
            tables[heading].append([cell.strip() for cell in line.strip("|").split("|")])
    return {name: rows[1:] for name, rows in tables.items()}


@pytest.fixture
def section_text(monkeypatch, capsys) -> str:
    monkeypatch.setattr(rd, "CODECS", {name: codec for name, codec in CODECS.items() if name != "acl"})
    motions = [sinusoidal_motion(num_frames=96, seed=3)]
    sweep = [{"codec": "other", "ratio": ratio, "linf_cm": linf} for ratio, linf in ((4.0, 0.05), (40.0, 3.0))]
    rd._rd_section(motions, "synthetic", sweep, epsilons=(0.5, 1.0), others_too=False)
    return capsys.readouterr().out


def test_the_bound_table_holds_the_bound_at_every_eps(section_text):
    bound = next(rows for name, rows in _tables(section_text).items() if name.startswith("mcb-rot: rate"))
    assert [float(row[0]) for row in bound] == [0.5, 1.0]
    for eps, ratio, linf, _mean, _shell, margin, model_bytes, ratio_paid in bound:
        assert float(ratio) > 1 and 0 < float(linf) <= float(eps) and float(margin) <= 0
        assert int(model_bytes) == 0 and float(ratio_paid) == pytest.approx(float(ratio), rel=1e-3)  # no prior here


def test_the_comparison_tables_hold_acl_and_the_sweep_curve(section_text):
    tables = _tables(section_text)
    assert "Against ACL (ACL: the reference run's table (BVH, not measured here))" in tables
    assert len(tables["Against ACL (ACL: the reference run's table (BVH, not measured here))"]) == 2
    assert not any(name.startswith("On ACL's metric") for name in tables)  # the reference table has no shell errors
    header = next(line for line in section_text.splitlines() if line.startswith("| eps cm | mcb-rot ratio | acl"))
    assert header == "| eps cm | mcb-rot ratio | acl (best shell) | other |"
    anchors = [row[0] for row in tables["BD-rate of mcb-rot (L-inf axis; negative: fewer bits than the anchor at "
                                       "equal L-inf)"]]
    assert anchors == ["acl (best shell)", "other"]


def test_the_ratio_over_another_codec_is_taken_at_equal_linf(section_text):
    tables = _tables(section_text)
    bound = next(rows for name, rows in tables.items() if name.startswith("mcb-rot: rate"))
    over = next(rows for name, rows in tables.items() if name.startswith("mcb-rot's ratio over each codec's"))
    sweep = [{"ratio": 4.0, "linf_cm": 0.05}, {"ratio": 40.0, "linf_cm": 3.0}]
    for ours, row in zip(bound, over):
        expected = float(ours[1]) / rd.ratio_at(sweep, "linf_cm", float(ours[2]))
        assert float(row[3]) == pytest.approx(expected, rel=1e-3)


def test_the_shell_target_verdict():
    assert rd._shell_verdict(3.0, 1.0) == "met"
    assert rd._shell_verdict(1.0, 1.0) == "not met"
    assert rd._shell_verdict(1.0, float("nan")) == "-"
    assert np.isnan(rd.ratio_at([{"ratio": 4.0, "linf_cm": 1.0}], "linf_cm", 2.0))
