"""Shards: the job unit of a sweep is one codec config over a list of clips, sized to a CPU budget.

One job per codec config over a whole database does not fit a cluster (a neural Fourier config over the full CMU
database is 15-119 CPU-hours against a 2-hour SLURM limit). The sweeper packs each config's clips into ``count``
shards (:func:`pack`), ``count`` being the smallest that keeps every shard's estimated CPU time (measured per-frame
cost of the config, :mod:`mocapbench.experiments.cost`) under ``shard.max_cpu_s`` (:func:`shard_count`); a clip is
never cut, so a clip alone over the budget is a shard of its own and the other shards stay full.

Packing (``shard.packing``):

* ``balanced`` (the default): longest clip first, each to the shard with the fewest frames so far (the LPT rule
  of scheduling; ties go to the lower shard number), so a shard's time (the sum of its clips) stays near the
  equal share and the longest clips are spread one per shard. A job holds one clip at a time, so its memory is set
  by the longest clip of its shard: the packing cannot lower that, but it keeps the longest clips apart, so only
  their shards need the larger memory.
* ``contiguous``: contiguous runs of clips of about equal frames (:func:`split`), the packing of sweeps started
  before ``balanced`` existed (one long clip made every shard as thin as that clip: 8,903 jobs for ``sweep=all``
  over the full CMU database instead of 1,939 without it). A ``shards.json`` without a ``packing`` entry is one
  of those, and its sweep resumes with it.

Either packing depends only on the dataset's catalogue (names and frame counts, in order) and ``count``, so every
process computes the same shard from ``shard.index`` and ``shard.count`` (and the same on every machine: the
weights are integer frame counts); the sweeper records each job's ``count`` in ``<sweep dir>/shards.json`` and
reuses it on resume. A shard lists its clips in catalogue order.
"""

from __future__ import annotations

import heapq
import math
from typing import Sequence, TypeVar

__all__ = ["PACKINGS", "split", "pack", "shard_clips", "shard_count", "shard_folder"]

T = TypeVar("T")

#: The packings :func:`pack` knows; the first is the default of new sweeps.
PACKINGS = ("balanced", "contiguous")


def split(frames: Sequence[int], count: int) -> list[range]:
    """Cut ``len(frames)`` items into ``count`` contiguous ranges of about equal total frames.

    Range ``i`` ends where the cumulative frames are nearest to ``(i + 1) / count`` of the total (an item goes to
    the range holding its midpoint); every range holds at least one item, ``count`` is capped at the number of items.

    Returns
    -------
    list of range
        ``count`` (or fewer, when there are fewer items) non-empty ranges covering ``0 .. len(frames)`` in order.
    """
    items = len(frames)
    if items == 0:
        return []
    count = max(1, min(int(count), items))
    weights = [max(1, int(f)) for f in frames]
    total = sum(weights)
    bounds, cumulative, item = [0], 0, 0
    for shard in range(1, count):
        target = total * shard / count
        first = bounds[-1] + 1  # at least one item in this range
        last = items - (count - shard)  # and one for each range after it
        # Take items while their midpoint is under the target: the cut lands nearest to the equal share.
        while item < last and (item < first or cumulative + weights[item] / 2 <= target):
            cumulative += weights[item]
            item += 1
        bounds.append(item)
    bounds.append(items)
    return [range(a, b) for a, b in zip(bounds, bounds[1:])]


def pack(frames: Sequence[int], count: int, packing: str = "balanced") -> list[list[int]]:
    """The item indices of each of ``count`` shards (``count`` capped at the number of items; none empty).

    ``balanced``: items by decreasing frames (ties: catalogue order), each to the shard with the fewest frames so
    far (ties: the lower shard); ``contiguous``: :func:`split`. Each shard's indices are in increasing order.

    Raises
    ------
    ValueError
        An unknown ``packing``.
    """
    if packing == "contiguous":
        return [list(r) for r in split(frames, count)]
    if packing != "balanced":
        raise ValueError(f"shard.packing must be one of {', '.join(PACKINGS)}, got {packing!r}.")
    items = len(frames)
    if items == 0:
        return []
    count = max(1, min(int(count), items))
    weights = [max(1, int(f)) for f in frames]
    order = sorted(range(items), key=lambda i: (-weights[i], i))
    bins: list[list[int]] = [[] for _ in range(count)]
    loads = [(0, shard) for shard in range(count)]  # a heap of (frames so far, shard): both ints, so exact
    for item in order:
        load, shard = heapq.heappop(loads)
        bins[shard].append(item)
        heapq.heappush(loads, (load + weights[item], shard))
    return [sorted(b) for b in bins]


def shard_clips(clips: Sequence[T], index: int, count: int, packing: str = "balanced") -> list[T]:
    """The clips of shard ``index`` of ``count`` (clips carry ``frames``; see :func:`pack`).

    Raises
    ------
    ValueError
        ``index`` outside ``0 .. count - 1``, ``count`` < 1 or an unknown ``packing``.
    """
    if count < 1 or not 0 <= index < count:
        raise ValueError(f"shard.index must be in 0..shard.count-1 and shard.count >= 1, got {index} of {count}.")
    shards = pack([clip.frames for clip in clips], count, packing)
    if index >= len(shards):  # more shards than clips: the extra shards are empty
        return []
    return [clips[i] for i in shards[index]]


def shard_count(frames: Sequence[int], cpu_s_per_frame: float, max_cpu_s: float | None,
                cpu_s_per_clip: float = 0.0, packing: str = "balanced") -> int:
    """The fewest shards (of ``packing``) that keep each shard's estimated CPU time under ``max_cpu_s``.

    1 if there is no budget. A shard's estimate is ``cpu_s_per_frame * frames + cpu_s_per_clip * clips``; a clip
    is never cut, so a shard of one clip may be over the budget (that clip alone is). The search starts at the
    bound no packing can beat (one shard per clip over the budget, plus the rest's total over the budget) and
    stops at the first count whose shards of two or more clips all fit.
    """
    if not frames or not max_cpu_s or max_cpu_s <= 0:
        return 1
    cost = [cpu_s_per_frame * f + cpu_s_per_clip for f in frames]
    over = sum(1 for c in cost if c > max_cpu_s)
    rest = sum(c for c in cost if c <= max_cpu_s)
    count = max(1, min(len(frames), over + math.ceil(rest / max_cpu_s - 1e-9)))

    def fits(shard: list[int]) -> bool:
        return len(shard) == 1 or sum(cost[i] for i in shard) <= max_cpu_s

    while count < len(frames) and not all(fits(shard) for shard in pack(frames, count, packing)):
        count += 1
    return count


def shard_folder(folder: str, index: int, count: int) -> str:
    """The job folder of shard ``index`` of ``count`` below a config's folder (the folder itself if ``count == 1``)."""
    if count == 1:
        return folder
    width = max(3, len(str(count)))
    return f"{folder}/shard-{index + 1:0{width}d}-of-{count:0{width}d}"
