"""The command starts fast: which heavy packages each command imports, ``--version``, ``python -m mocapbench``.

Timings live in ``mocapbench.benchmarks.cli_startup``; these tests check the cause (imported modules), which does
not depend on the machine's load.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import mocapbench
from mocapbench.io import write_bvh
from mocapbench.lazy_imports import Lazy, Rotation
from mocapbench.synthetic import sinusoidal_motion

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("pywt", "torch", "pandas", "matplotlib", "hydra", "omegaconf")
"""Packages the listing must not import; also every public scipy submodule (``import scipy`` alone is cheap)."""

PROBE = """
import json, sys
from mocapbench.cli import main
try:
    code = main(sys.argv[1:])
except SystemExit as exit:
    code = exit.code
print(json.dumps({"code": code, "modules": sorted(sys.modules)}))
"""


def loaded_modules(tmp_path: Path, *args: str) -> tuple[int, set[str]]:
    """Run ``mocapbench ARGS`` in a fresh interpreter; return (exit code, every module it imported)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    result = subprocess.run(
        [sys.executable, "-c", PROBE, *args], cwd=tmp_path, env=env, capture_output=True, text=True, check=True
    )
    report = json.loads(result.stdout.strip().splitlines()[-1])
    return report["code"], set(report["modules"])


def heavy(modules: set[str]) -> set[str]:
    def is_heavy(name: str) -> bool:
        if name.startswith("scipy."):
            return not name.split(".")[1].startswith("_") and name not in ("scipy.version",)
        return any(name == package or name.startswith(package + ".") for package in HEAVY)

    return {name for name in modules if is_heavy(name)}


def test_help_imports_no_third_party_package(tmp_path):
    code, modules = loaded_modules(tmp_path, "--help")
    assert code == 0
    assert not {name.split(".")[0] for name in modules} & {"numpy", "scipy", "zstandard", "bitarray", "constriction"}


def test_codecs_listing_imports_no_scipy_submodule_torch_pandas_matplotlib_or_hydra(tmp_path):
    code, modules = loaded_modules(tmp_path, "codecs")
    assert code == 0 and "mocapbench.codecs.pga.codec" in modules  # every codec module was imported ...
    assert heavy(modules) == set(), (  # ... and none of them pulled a heavy package in
        "a codec module imports a heavy package at the top: take Rotation/pywt from mocapbench.lazy_imports, "
        "write `import scipy` and use scipy.fft.* (loaded on first use), import torch/pandas/... in the function"
    )


def test_compress_imports_only_what_it_uses(tmp_path):
    path = write_bvh(sinusoidal_motion(num_frames=30), tmp_path / "walk.bvh")
    code, modules = loaded_modules(tmp_path, "compress", str(path), str(tmp_path / "walk.mcb"), "--codec",
                                   "quant-delta-zstd")  # fmt: skip
    assert code == 0 and (tmp_path / "walk.mcb").stat().st_size > 0
    assert "scipy.spatial.transform" in modules  # reading BVH Euler angles does use scipy's Rotation
    rotation_only = subprocess.run(
        [sys.executable, "-c", "import json, sys, scipy.spatial.transform; print(json.dumps(sorted(sys.modules)))"],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    assert heavy(modules) - set(json.loads(rotation_only.stdout)) == set()  # no scipy.fft, pywt, torch, ...


@pytest.mark.parametrize("module", [["-m", "mocapbench"], ["-m", "mocapbench.cli"]])
def test_version_from_python_dash_m(module):
    result = subprocess.run([sys.executable, *module, "--version"], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0
    assert result.stdout.startswith(f"mocapbench {mocapbench.__version__} (Python 3.")
    assert mocapbench.__version__.count(".") == 2 and all(part.isdigit() for part in mocapbench.__version__.split("."))


def test_python_dash_m_mocapbench_runs_a_command_and_reports_errors_in_one_line(tmp_path):
    result = subprocess.run([sys.executable, "-m", "mocapbench", "inspect", str(tmp_path / "missing.mcb")],
                            cwd=ROOT, capture_output=True, text=True)  # fmt: skip
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "missing.mcb" in result.stderr


def test_lazy_stand_in_behaves_like_the_class():
    quaternion = Rotation.from_rotvec([0.0, 0.0, 0.5]).as_quat()
    assert isinstance(Rotation.from_quat(quaternion), Rotation)
    assert not isinstance(quaternion, Rotation)
    assert Rotation.resolve().__name__ == "Rotation" and "imported" in repr(Rotation)
    missing = Lazy("json", "no_such_name")
    assert "not imported yet" in repr(missing)
    with pytest.raises(AttributeError, match="no_such_name"):
        missing.resolve()
