"""Shared fixtures: synthetic sinusoidal skeletons (no files needed) and the CMU clips.

Two sources of real CMU data:

* ``tests/fixtures/cmu/``: clip 09_06 (ASF/AMC and BVH, 0.23 MB) shipped with the tests in the layout of the data
  folder, so the quick real-data tests run on every clone (:func:`cmu_fixture_dir`, :func:`cmu_09_06`).
* the full 63-clip folder (``../shared/data/cmu`` or ``$MOCAPBENCH_CMU_DIR``, :func:`cmu_full_dir`): tests that
  need it skip with the reason when it is missing, except under ``CI=true``, where they fail (CI always has it).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from mocapbench.synthetic import sinusoidal_motion

pytest_plugins = ["pytester"]  # test_cmu_dataset runs the skip-or-fail rule of cmu_full_dir in an inner session

CMU_FIXTURE_DIR = Path(__file__).parent / "fixtures" / "cmu"
"""Clip 09_06 of the CMU database in the data folder's layout (see its README.md for source and terms)."""


@pytest.fixture(scope="session")
def synthetic_motion():
    """The test motion: 240 frames at 120 fps, 31 joints, seed 1."""
    return sinusoidal_motion(num_frames=240, seed=1)


@pytest.fixture(scope="session")
def training_motions():
    """Training motions for codecs that learn shared state: other seeds than the test motion."""
    return [sinusoidal_motion(num_frames=300, seed=seed) for seed in (11, 12, 13)]


@pytest.fixture(scope="session")
def cmu_fixture_dir() -> Path:
    """``tests/fixtures/cmu``: a CMU data folder holding clip 09_06 only (``asf_amc/09/``, ``bvh/09_06.bvh``)."""
    return CMU_FIXTURE_DIR


@pytest.fixture(scope="session")
def cmu_09_06(cmu_fixture_dir):
    """The real 141-frame CMU run 09_06 from ASF/AMC (shipped in tests/fixtures/cmu, always present)."""
    from mocapbench.datasets.cmu import load_clip

    return load_clip("09_06", data_dir=cmu_fixture_dir)


def running_in_ci() -> bool:
    """True when ``$CI`` is ``true`` (any case) or ``1``, as CI services set it."""
    return os.environ.get("CI", "").strip().lower() in ("true", "1")


@pytest.fixture(scope="session")
def cmu_full_dir() -> Path:
    """The full CMU data folder (63 clips, ``manifest.csv``), found as :func:`mocapbench.datasets.cmu.cmu_data_dir`.

    When it is missing the test is skipped with the reason (where it looked, how to point at it); under
    ``CI=true`` the ``DataNotFoundError`` is raised instead, so CI never passes by skipping real-data tests.
    """
    from mocapbench.datasets.cmu import DataNotFoundError, cmu_data_dir

    try:
        return cmu_data_dir()
    except DataNotFoundError as error:
        if running_in_ci():
            raise
        pytest.skip(f"needs the full CMU data folder (63 clips; CI=true makes this a failure): {error}")


@pytest.fixture(scope="session")
def bandai_dir() -> Path:
    """The Bandai Namco data folder (``manifest.csv``, ``bvh/``), found as
    :func:`mocapbench.datasets.bandai.bandai_data_dir`: skipped with where it looked when missing, a failure under
    ``CI=true``."""
    from mocapbench.datasets.bandai import bandai_data_dir
    from mocapbench.datasets.cmu import DataNotFoundError

    try:
        return bandai_data_dir()
    except DataNotFoundError as error:
        if running_in_ci():
            raise
        pytest.skip(f"needs the Bandai Namco data folder (CI=true makes this a failure): {error}")


@pytest.fixture(scope="session")
def acl_codec():
    """``create("acl", **params)``. Where ACL's headers or a C++ compiler are missing the test is skipped with the
    registry's one-line reason, except under ``CI=true`` (CI has ../shared), where it fails."""
    from mocapbench.codecs import CODECS, UNAVAILABLE, create

    if "acl" not in CODECS:
        message = f"acl is unavailable here: {UNAVAILABLE.get('acl')}"
        if running_in_ci():
            pytest.fail(message)
        pytest.skip(message)
    return lambda **params: create("acl", **params)


@pytest.fixture(scope="session")
def native_runtime():
    """The native mcb-rot runtime's library (compiled on first use). Without a C compiler the test is skipped, except
    under ``CI=true`` (CI installs clang), where it fails."""
    from mocapbench.codecs.mcb_rot import native

    found = native.library()
    if found is None:
        if running_in_ci():
            pytest.fail("the native runtime did not build (CI has a C compiler)")
        pytest.skip("the native runtime is not available (no C compiler?)")
    return found


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    """Tests marked ``torch`` (the neural codecs) skip with the registry's one-line reason when PyTorch is missing.

    Under ``CI=true`` they run anyway and fail: the Makefile always installs torch, so its absence there is a bug.
    """
    if item.get_closest_marker("torch") is None or running_in_ci():
        return
    from mocapbench.codecs import CODECS, UNAVAILABLE

    missing = sorted(name for name in ("fourier-mlp-int", "fourier-mlp-dct") if name not in CODECS)
    if missing:
        pytest.skip(f"{', '.join(missing)}: {UNAVAILABLE.get(missing[0], 'not registered')}")
