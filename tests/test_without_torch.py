"""Without PyTorch (no ``[neural]`` extra) the two neural codecs are listed as unavailable and everything else works.

Each test runs a fresh interpreter in which a meta-path finder refuses ``torch``, as on an install without it.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NEURAL = ("fourier-mlp-dct", "fourier-mlp-int")

HIDE_TORCH = """
import importlib.abc, sys

class NoTorch(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "torch" or name.startswith("torch."):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None

sys.meta_path.insert(0, NoTorch())
"""


def run_without_torch(tmp_path: Path, code: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-c", HIDE_TORCH + code], cwd=tmp_path, env=env, capture_output=True,
                          text=True)  # fmt: skip


def test_listing_names_each_neural_codec_unavailable_in_one_line(tmp_path):
    result = run_without_torch(tmp_path, "from mocapbench.cli import main; sys.exit(main(['codecs']))")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    for name in NEURAL:
        (line,) = [line for line in lines if line.startswith(f"{name}:")]
        assert line == f"{name}: unavailable here: needs PyTorch, which is not installed: pip install 'mocapbench[neural]'"
    assert any(line.startswith("mcb-linf: ") for line in lines) and any(line.startswith("svd: ") for line in lines)


def test_registry_refuses_the_neural_codecs_and_runs_the_others(tmp_path):
    code = """
import numpy as np
from mocapbench import metrics
from mocapbench.codecs import CODECS, UNAVAILABLE, CodecUnavailableError, create
from mocapbench.synthetic import sinusoidal_motion

assert not set(CODECS) & {"fourier-mlp-dct", "fourier-mlp-int"}, sorted(CODECS)
assert set(UNAVAILABLE) >= {"fourier-mlp-dct", "fourier-mlp-int"}
try:
    create("fourier-mlp-dct")
except CodecUnavailableError as error:
    print("refused:", error)
motion = sinusoidal_motion(num_frames=40, seed=3)
for name in ("svd", "quant-rot-zstd"):
    codec = create(name)
    decoded = codec.decode(codec.encode(motion))
    print(name, metrics.max_joint_error(motion.positions(), decoded.positions))
assert "torch" not in sys.modules
"""
    result = run_without_torch(tmp_path, code)
    assert result.returncode == 0, result.stderr
    out = result.stdout.splitlines()
    assert out[0] == ("refused: codec 'fourier-mlp-dct' is unavailable here: needs PyTorch, which is not installed: "
                      "pip install 'mocapbench[neural]'")  # fmt: skip
    errors = {line.split()[0]: float(line.split()[1]) for line in out[1:]}
    assert set(errors) == {"svd", "quant-rot-zstd"} and all(0.0 <= e < 5.0 for e in errors.values()), errors


def test_compress_with_a_neural_codec_is_one_line_error(tmp_path):
    code = f"""
from mocapbench.cli import main
from mocapbench.io import write_bvh
from mocapbench.synthetic import sinusoidal_motion
write_bvh(sinusoidal_motion(num_frames=20), "walk.bvh")
sys.exit(main(["compress", "walk.bvh", "walk.mcb", "--codec", "{NEURAL[0]}"]))
"""
    result = run_without_torch(tmp_path, code)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "needs PyTorch" in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "walk.mcb").exists()
