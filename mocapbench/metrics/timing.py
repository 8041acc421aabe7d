"""Timing helpers for benchmark scripts (never asserted in tests: these machines are shared and noisy)."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from typing import Any

__all__ = ["time_call"]


def time_call(function: Callable[[], Any], *, repeats: int = 5, warmup: int = 1) -> tuple[float, Any]:
    """Median wall time of ``function()`` over ``repeats`` runs after ``warmup`` runs.

    Returns
    -------
    (seconds, result) : the median time in s (``time.perf_counter``) and the last call's result.
    """
    if repeats < 1 or warmup < 0:
        raise ValueError(f"`repeats` must be >= 1 and `warmup` >= 0, got {repeats} and {warmup}.")
    result = None
    for _ in range(warmup):
        result = function()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result
