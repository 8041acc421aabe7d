"""mcb-rot's encode CPU benchmark script: bad input and a missing data folder are one line each, never a traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from mocapbench.benchmarks.mcb_rot import encode_cpu

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("argv, message", [
    (["--datasets", "no_such_set"], "invalid choice: 'no_such_set'"),
    (["--eps", "0"], "expected a finite length in cm > 0, got '0'"),
    (["--shell", "-1"], "expected a finite length in cm >= 0, got '-1'"),
    (["--eps", "nan"], "got 'nan'"),
])
def test_bad_arguments_are_one_usage_line(argv, message, capsys):
    with pytest.raises(SystemExit) as stop:
        encode_cpu.main(argv)
    assert stop.value.code == 2 and message in capsys.readouterr().err


def test_a_missing_data_folder_is_one_line(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    done = subprocess.run([sys.executable, "-m", "mocapbench.benchmarks.mcb_rot.encode_cpu", "--datasets", "cmu_test",
                           "--data-dir", str(tmp_path / "nowhere")], capture_output=True, text=True, env=env,
                          timeout=120)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "nowhere" in done.stderr
