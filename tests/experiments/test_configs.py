"""Every codec config composes and instantiates; every registered codec has its codec and sweep yaml; launchers."""

from __future__ import annotations

import dataclasses
import importlib
from pathlib import Path

import pytest
from hydra.utils import instantiate

from mocapbench.codecs import CODECS, UNAVAILABLE, Codec, codec_names
from mocapbench.experiments.sweeper import _evenly, job_folder

CONFIGS = Path(__file__).resolve().parents[2] / "mocapbench" / "configs"

ALL_CODEC_YAMLS = sorted(p.stem for p in (CONFIGS / "codec").glob("*.yaml"))
# A codec that cannot run here (e.g. `acl` without ACL's headers) is listed in UNAVAILABLE instead of CODECS.
CODEC_YAMLS = [name for name in ALL_CODEC_YAMLS if name not in UNAVAILABLE]


def test_every_codec_yaml_names_a_registered_or_unavailable_codec():
    for name in ALL_CODEC_YAMLS:
        assert name in CODECS or name in UNAVAILABLE, f"configs/codec/{name}.yaml names no known codec"


@pytest.mark.parametrize("name", codec_names())
def test_every_registered_codec_has_codec_and_sweep_yaml(name):
    assert (CONFIGS / "codec" / f"{name}.yaml").is_file(), f"configs/codec/{name}.yaml is missing"
    assert (CONFIGS / "sweep" / f"rd_{name}.yaml").is_file(), f"configs/sweep/rd_{name}.yaml is missing"


@pytest.mark.parametrize("name", CODEC_YAMLS)
def test_codec_yaml_composes_and_instantiates_the_registered_class(compose_benchmark, name):
    cfg = compose_benchmark([f"codec={name}"])
    codec = instantiate(cfg.codec)
    assert isinstance(codec, Codec)
    assert type(codec) is CODECS[name]  # exact type: the yaml's name selects this class, not a look-alike
    fields = {f.name for f in dataclasses.fields(CODECS[name].Config)}
    listed = set(cfg.codec) - {"_target_", "_convert_", "name"}
    assert listed == fields, f"configs/codec/{name}.yaml should list every Config field with its default"
    defaults = dataclasses.asdict(CODECS[name].Config())
    for field in sorted(fields):
        value = cfg.codec[field]
        value = tuple(value) if isinstance(defaults[field], tuple) else value
        # a sweep (which composes the yaml) must measure the codec a user gets from create(name) or the CLI
        assert value == defaults[field], f"configs/codec/{name}.yaml: {field} is {value!r}, the default {defaults[field]!r}"


@pytest.mark.parametrize("name", [n for n in CODEC_YAMLS if (CONFIGS / "sweep" / f"rd_{n}.yaml").exists()])
def test_rd_sweep_selects_its_codec_and_sweeps_its_fields(compose_benchmark, name):
    cfg = compose_benchmark([f"sweep=rd_{name}"], hydra=True)
    assert cfg.codec.name == name
    assert cfg.hydra.mode.name == "MULTIRUN"
    params = cfg.hydra.sweeper.params
    assert params, f"rd_{name}.yaml sweeps nothing"
    fields = {f.name for f in dataclasses.fields(CODECS[name].Config)}
    for key in params:
        assert key.startswith("codec.") and key[len("codec."):] in fields, f"rd_{name}.yaml sweeps unknown {key}"


@pytest.mark.parametrize("sweep", ["all", "small"])
def test_union_sweeps_select_the_mocapbench_sweeper(compose_benchmark, monkeypatch, sweep):
    monkeypatch.syspath_prepend(str(CONFIGS.parents[1]))  # the checkout's hydra_plugins/, as run.py ensures
    cfg = compose_benchmark([f"sweep={sweep}", "dataset=cmu_test"], hydra=True)
    assert cfg.hydra.sweeper._target_ == "hydra_plugins.mocapbench_sweeper.MocapbenchSweeper"
    assert cfg.hydra.sweeper.union is True
    assert cfg.hydra.mode.name == "MULTIRUN"
    module, cls = cfg.hydra.sweeper._target_.rsplit(".", 1)
    assert getattr(importlib.import_module(module), cls)


def test_local_launcher_is_joblib_with_two_jobs(compose_benchmark):
    cfg = compose_benchmark([], hydra=True)
    assert cfg.hydra.launcher._target_.endswith("joblib_launcher.JoblibLauncher")
    assert cfg.hydra.launcher.n_jobs == 2


def test_slurm_launcher_composes(compose_benchmark):
    cfg = compose_benchmark(["sweep=all", "hydra/launcher=slurm", "hydra.launcher.partition=cpu"], hydra=True)
    launcher = cfg.hydra.launcher
    assert launcher._target_ == "hydra_plugins.hydra_submitit_launcher.submitit_launcher.SlurmLauncher"
    assert launcher.partition == "cpu"
    # One job = one process with threads_per_job BLAS/torch threads: one CPU per thread, none idle.
    assert launcher.cpus_per_task == cfg.threads_per_job == 1 and launcher.timeout_min > 0
    assert any("OMP_NUM_THREADS=1" in line for line in launcher.setup)
    # A shard's CPU budget fits the time limit with room for a slower node.
    assert cfg.shard.max_cpu_s * 2 <= launcher.timeout_min * 60
    module, cls = launcher._target_.rsplit(".", 1)
    assert getattr(importlib.import_module(module), cls)


@pytest.mark.parametrize("dataset", ["synthetic", "cmu_train", "cmu_test", "cmu_test_24fps", "cmu_all", "cmu_09_06",
                                     "cmu_full", "folder"])
def test_dataset_configs_compose(compose_benchmark, dataset):
    cfg = compose_benchmark([f"dataset={dataset}"])
    assert cfg.dataset.name == dataset
    assert cfg.dataset.kind in ("synthetic", "cmu", "folder", "cmu_tree")
    if cfg.dataset.kind == "cmu":
        assert cfg.dataset.data_dir == "../shared/data/cmu"
        assert compose_benchmark([f"dataset={dataset}", "data_dir=/elsewhere"]).dataset.data_dir == "/elsewhere"


def test_cmu_test_trains_on_cmu_train(compose_benchmark):
    cfg = compose_benchmark(["dataset=cmu_test"])
    assert cfg.dataset.split == "cmu_test" and cfg.dataset.train.split == "cmu_train"


def test_job_folder_is_stable_readable_and_distinct():
    assert job_folder("svd", ["codec.rank=4"]) == "svd/codec.rank=4"
    assert job_folder("svd", []) == "svd/default"
    assert job_folder("svd", ["b=1", "a=2"]) == job_folder("svd", ["a=2", "b=1"])
    long_a = job_folder("x", [f"codec.p{i}=1" for i in range(40)])
    long_b = job_folder("x", [f"codec.p{i}=2" for i in range(40)])
    assert long_a != long_b and len(long_a) < 120
    assert "/" not in job_folder("x", ["data_dir=/a/b"]).split("/", 1)[1]


def test_evenly_keeps_the_ends():
    assert _evenly(list(range(9)), 3) == [0, 4, 8]
    assert _evenly([1, 2], 3) == [1, 2]
    assert _evenly(list(range(5)), None) == list(range(5))
