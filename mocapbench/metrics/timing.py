"""The one way mocapbench times code: warm-up, repeats, median, CPU time of the process beside wall time, load.

Used by the benchmark jobs (:func:`mocapbench.experiments.evaluate.evaluate`) and by every benchmark script
(``mocapbench.benchmarks.*``), so that every speed in a report or a script's output is taken the same way:

* ``warmup`` untimed calls first (caches, lazy imports, JIT-like first-call costs);
* then ``repeats`` timed calls (at least 3 by default), each measured twice: wall time
  (``time.perf_counter``) and CPU time of the whole process, user + system (``time.process_time``); on a shared,
  loaded machine the CPU time is the figure that does not depend on what the neighbours do;
* the medians of both are reported, with the spread (max - min of the wall times, s) and the 1-minute load
  average before and after (``os.getloadavg``), so a reader can tell a quiet measurement from a noisy one;
* BLAS/OpenMP (threadpoolctl) and torch are limited to ``threads`` (default 1) during the calls.

``budget_s`` bounds the cost of slow calls (a neural codec trains a network in ``encode``): a warm-up call that
alone exceeds it becomes the one timed call (``warmup`` then reads 0 and ``repeats`` 1), and once the calls so far
exceed it no further repeat is started; the :class:`Timing` always says how many ran.
Timings are never asserted in tests: these machines are shared and noisy.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from typing import Any, Iterator

__all__ = ["Timing", "measure", "time_call", "load_average", "usable_cores", "single_thread", "METHOD"]

# One sentence for reports and script footers: how every speed was taken.
METHOD = ("median of {repeats} timed runs after {warmup} warm-up run(s), {threads} thread(s); CPU time of the "
          "process (user + system, time.process_time) beside wall time (time.perf_counter); spread = max - min of "
          "the wall times; 1-minute load average recorded before and after")


@dataclass(frozen=True)
class Timing:
    """One timed measurement.

    Attributes
    ----------
    wall_s, cpu_s : float, s
        Medians over the timed repeats of wall time and of CPU time of the process (user + system).
    wall_spread_s : float, s
        Max - min of the timed wall times (0 with one repeat).
    repeats, warmup, threads : int
        Timed calls that ran, untimed calls before them, and the thread limit in force.
    load_before, load_after : float
        1-minute load average of the machine before the warm-up and after the last repeat (NaN if unknown).
    """

    wall_s: float
    cpu_s: float
    wall_spread_s: float
    repeats: int
    warmup: int
    threads: int
    load_before: float
    load_after: float

    def per_second(self, items: float, *, cpu: bool = True) -> float:
        """``items`` per second of CPU time (``cpu=True``) or of wall time; inf for a zero time."""
        seconds = self.cpu_s if cpu else self.wall_s
        return items / seconds if seconds > 0 else float("inf")

    def as_columns(self, prefix: str) -> dict[str, float | int]:
        """Flat ``<prefix>_<field>`` columns for a results row (e.g. ``encode_wall_s``, ``encode_repeats``)."""
        return {f"{prefix}_{key}": value for key, value in asdict(self).items()}


def load_average() -> float:
    """The machine's 1-minute load average (NaN where the OS does not report it)."""
    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):
        return float("nan")


def usable_cores() -> int:
    """The cores this process may run on: its CPU affinity (a job's share of a machine), else the machine's count."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


#: ``(modules loaded when it was made, ThreadpoolController)`` of this process (:func:`_controller`).
_CONTROLLER: list[Any] = []


def _controller() -> Any:
    """The process's ``threadpoolctl.ThreadpoolController``, made again when a module was imported since.

    Making one reads ``/proc/self/maps`` and inspects every loaded shared library (a cost paid at every
    timed call otherwise: README, "Timings"); a BLAS or OpenMP library is loaded with the extension module
    that links it, so while no module was imported the libraries it found are still all there are.
    """
    from threadpoolctl import ThreadpoolController

    if not _CONTROLLER or _CONTROLLER[0] != len(sys.modules):
        _CONTROLLER[:] = [len(sys.modules), ThreadpoolController()]
    return _CONTROLLER[1]


@contextmanager
def single_thread(threads: int = 1) -> Iterator[None]:
    """Limit BLAS/OpenMP pools and, if it is loaded, torch to ``threads`` threads inside the block."""
    torch = sys.modules.get("torch")
    before = torch.get_num_threads() if torch is not None else None
    try:
        if torch is not None:
            torch.set_num_threads(threads)
        with _controller().limit(limits=threads):
            yield
    finally:
        if torch is not None and before is not None:
            torch.set_num_threads(before)


def measure(
    function: Callable[[], Any],
    *,
    repeats: int = 3,
    warmup: int = 1,
    threads: int = 1,
    budget_s: float | None = None,
) -> tuple[Timing, Any]:
    """Time ``function()`` as described in the module docstring.

    Parameters
    ----------
    function : callable with no arguments
    repeats : int
        Timed calls (>= 1; 3 or more for a median worth the name).
    warmup : int
        Untimed calls before them (>= 0).
    threads : int
        Thread limit for BLAS/OpenMP and torch during the calls (>= 1).
    budget_s : float, optional
        Wall seconds after which no further timed call is started (at least one always runs).

    Returns
    -------
    (Timing, result)
        The timing and the last call's result.
    """
    if repeats < 1 or warmup < 0 or threads < 1:
        raise ValueError(f"`repeats` and `threads` must be >= 1 and `warmup` >= 0, got {repeats}, {threads}, {warmup}.")
    result = None
    walls: list[float] = []
    cpus: list[float] = []
    load_before = load_average()
    start_all = time.perf_counter()
    with single_thread(threads):
        for index in range(warmup):
            cpu = time.process_time()
            wall = time.perf_counter()
            result = function()
            wall = time.perf_counter() - wall
            if budget_s is not None and wall > budget_s and index == warmup - 1:
                # Too slow to repeat: this call is the measurement.
                walls.append(wall)
                cpus.append(time.process_time() - cpu)
                warmup -= 1
                break
        for _ in range(repeats):
            if walls and budget_s is not None and time.perf_counter() - start_all > budget_s:
                break
            cpu = time.process_time()
            wall = time.perf_counter()
            result = function()
            walls.append(time.perf_counter() - wall)
            cpus.append(time.process_time() - cpu)
    timing = Timing(
        wall_s=statistics.median(walls),
        cpu_s=statistics.median(cpus),
        wall_spread_s=max(walls) - min(walls),
        repeats=len(walls),
        warmup=warmup,
        threads=threads,
        load_before=load_before,
        load_after=load_average(),
    )
    return timing, result


def time_call(function: Callable[[], Any], *, repeats: int = 5, warmup: int = 1,
              clock: str = "cpu") -> tuple[float, Any]:
    """:func:`measure` reduced to one number: the median CPU time of the process (``clock="cpu"``, default) or
    wall time (``clock="wall"``) of ``function()`` in s, and its last result."""
    if clock not in ("cpu", "wall"):
        raise ValueError(f"`clock` must be 'cpu' or 'wall', got {clock!r}.")
    timing, result = measure(function, repeats=repeats, warmup=warmup)
    return (timing.cpu_s if clock == "cpu" else timing.wall_s), result
