"""The README's Python quick start is examples/quick_start.py, word for word, and it runs and gives sane numbers."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "quick_start.py"


def example_code() -> str:
    """The example without its docstring line (what the README shows)."""
    text = EXAMPLE.read_text()
    return text.split('"""\n', 2)[-1].strip() if text.startswith('"""') else text.strip()


def test_readme_shows_the_example_file():
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), flags=re.S)
    assert example_code() in [block.strip() for block in blocks]


def test_example_runs_and_prints_one_row_per_codec():
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    result = subprocess.run([sys.executable, str(EXAMPLE)], cwd=ROOT, env=env, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.strip().splitlines()
    assert lines[0] == ("Motion('09_06', 141 frames at 120 fps = 1.18 s, Skeleton(31 joints, root 'Hips', 7 end sites), "
                        "source unit 5.64444 cm)")  # read in CMU units, no warning line
    assert lines[1].split() == ["codec", "bitstream_bytes", "compression_ratio", "max_err_cm", "mean_err_cm"]
    rows = {cells[0]: [float(x) for x in cells[1:]] for cells in (line.split() for line in lines[2:])}
    assert list(rows) == ["quant-delta-zstd", "quant-rot-zstd", "mcb-linf"]
    assert 0 < rows["mcb-linf"][2] <= 1.0  # its guaranteed bound eps_cm=1
    assert 0 < rows["quant-delta-zstd"][2] <= 0.25 * 3**0.5  # half a 0.5 cm step on each axis
    for size, ratio, max_err, mean_err in rows.values():
        assert size > 100 and ratio > 1.0 and 0 < mean_err <= max_err
