"""The sweeper composes one job of each shape before launching, and launches the longest estimated jobs first."""

from __future__ import annotations

from types import SimpleNamespace

from mocapbench.experiments.sweeper import RdSweeper


def _sweeper(composed):
    sweeper = RdSweeper()
    repository = SimpleNamespace(group_exists=lambda name: name in {"sweep", "codec", "dataset", "hydra/launcher"})
    loader = SimpleNamespace(repository=repository,
                             load_sweep_config=lambda master_config, sweep_overrides: composed.append(sweep_overrides))
    sweeper.hydra_context = SimpleNamespace(config_loader=loader)
    sweeper.config = object()
    return sweeper


def test_one_job_of_each_shape_is_composed():
    composed = []
    batch = [["sweep=rd_acl", "dataset=cmu_test", f"codec.precision_cm={p}", f"hydra.sweep.subdir=acl/{p}"]
             for p in (0.1, 0.2, 0.5)]
    batch += [["sweep=rd_svd", "dataset=cmu_test", f"codec.rank={r}", "data_dir=/a"] for r in (2, 4)]
    batch += [["sweep=rd_svd", "dataset=cmu_test_24fps", "codec.rank=2", "data_dir=/a"],
              ["sweep=rd_svd", "dataset=cmu_test", "codec.rank=2", "codec.weighted=true", "data_dir=/a"]]
    _sweeper(composed).validate_batch_is_legal(batch)
    # acl once, svd once per dataset (a group: its value picks a file), once more for the extra key
    assert composed == [batch[0], batch[3], batch[5], batch[6]]


def test_jobs_are_launched_longest_estimate_first():
    from mocapbench.experiments.sweeper import longest_first

    folders = ["acl/a", "fourier-mlp-int/k2", "svd/r2", "fourier-mlp-int/k10", "svd/r4"]
    estimates = {"acl/a": 3.0, "fourier-mlp-int/k2": 40.0, "svd/r2": 1.0, "fourier-mlp-int/k10": 200.0, "svd/r4": 1.0}
    assert [folders[i] for i in longest_first(folders, estimates)] == [
        "fourier-mlp-int/k10", "fourier-mlp-int/k2", "acl/a", "svd/r2", "svd/r4"]
    assert longest_first(["x", "y"], {}) == [0, 1]
