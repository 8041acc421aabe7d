"""Helpers for the experiment tests: the repository's configs folder and Hydra composition."""

from __future__ import annotations

from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra

REPO = Path(__file__).resolve().parents[2]
CONFIGS = REPO / "mocapbench" / "configs"


@pytest.fixture
def compose_benchmark():
    """``compose_benchmark(overrides, hydra=False)``: the composed ``benchmark`` config (GlobalHydra cleared)."""

    def _compose(overrides=(), hydra=False):
        GlobalHydra.instance().clear()
        with initialize_config_dir(version_base="1.3", config_dir=str(CONFIGS)):
            return compose("benchmark", overrides=list(overrides), return_hydra_config=hydra)

    yield _compose
    GlobalHydra.instance().clear()
