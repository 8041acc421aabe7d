"""The shared timing helper: warm-up, repeats, median of wall and CPU time, budget, load average."""

from __future__ import annotations

import time

import pytest

from mocapbench.experiments.evaluate import TimingSettings
from mocapbench.metrics.timing import measure, time_call


def test_measure_runs_warmup_then_repeats_and_reports_medians():
    calls = []
    timing, result = measure(lambda: calls.append(1) or len(calls), repeats=3, warmup=2)
    assert len(calls) == 5 and result == 5
    assert (timing.repeats, timing.warmup, timing.threads) == (3, 2, 1)
    assert timing.wall_s >= 0 and timing.cpu_s >= 0 and timing.wall_spread_s >= 0
    assert timing.as_columns("encode")["encode_repeats"] == 3


def test_cpu_time_excludes_sleeping():
    timing, _ = measure(lambda: time.sleep(0.05), repeats=3, warmup=0)
    assert timing.wall_s >= 0.045 and timing.cpu_s < 0.02


def test_a_call_over_the_budget_is_timed_once():
    calls = []
    timing, _ = measure(lambda: calls.append(time.sleep(0.03)), repeats=3, warmup=1, budget_s=0.01)
    assert len(calls) == 1 and (timing.repeats, timing.warmup) == (1, 0)


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="repeats"):
        measure(lambda: None, repeats=0)
    with pytest.raises(ValueError, match="TimingSettings"):
        TimingSettings(repeats=0)
    seconds, value = time_call(lambda: 7, repeats=2)
    assert value == 7 and seconds >= 0


def test_single_thread_limits_the_pools_and_restores_them(monkeypatch):
    import sys
    import types

    from threadpoolctl import threadpool_info, threadpool_limits

    from mocapbench.metrics import timing

    # Two threads first, so that the limit and the restore each change something whatever the environment sets
    # (the Makefile and CI run the tests with one BLAS / OpenMP thread).
    with threadpool_limits(limits=2):
        before = [(pool["filepath"], pool["num_threads"]) for pool in threadpool_info()]
        assert all(threads == 2 for _, threads in before)
        with timing.single_thread(1):
            assert all(pool["num_threads"] == 1 for pool in threadpool_info())
        assert [(pool["filepath"], pool["num_threads"]) for pool in threadpool_info()] == before
    first = timing._controller()
    assert timing._controller() is first  # the loaded libraries are listed once while no module is imported
    monkeypatch.setitem(sys.modules, "_a_module_imported_later", types.ModuleType("_a_module_imported_later"))
    assert timing._controller() is not first


def test_usable_cores_are_the_affinity_of_the_process():
    import os

    from mocapbench.metrics.timing import usable_cores

    assert 1 <= usable_cores() <= (os.cpu_count() or 1)
    if hasattr(os, "sched_getaffinity"):
        assert usable_cores() == len(os.sched_getaffinity(0))
