"""Shards: the job unit of a sweep is one codec config over a list of clips, sized to a CPU budget.

One job per codec config over a whole database does not fit a cluster (a neural Fourier config over the full CMU
database is 15-119 CPU-hours against a 2-hour SLURM limit). The sweeper cuts each config's clips into
``count`` shards of contiguous clips with about equal frames (:func:`split`), ``count`` being the smallest that
keeps every shard's estimated CPU time (measured per-frame cost of the config, :mod:`mocapbench.experiments.cost`)
under ``shard.max_cpu_s`` (:func:`shard_count`). A job reads only its shard's clips, one at a time, so its memory is
that of one clip, whatever the size of the database. The partition depends only on the dataset's catalogue (names
and frame counts, in order) and ``count``, so every process computes the same shard from ``shard.index`` and
``shard.count``; the sweeper records each job's ``count`` in ``<sweep dir>/shards.json`` and reuses it on resume.
"""

from __future__ import annotations

import math
from typing import Sequence, TypeVar

__all__ = ["split", "shard_clips", "shard_count", "shard_folder"]

T = TypeVar("T")


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


def shard_clips(clips: Sequence[T], index: int, count: int) -> list[T]:
    """The clips of shard ``index`` of ``count`` (clips carry ``frames``; see :func:`split`).

    Raises
    ------
    ValueError
        ``index`` outside ``0 .. count - 1`` or ``count`` < 1.
    """
    if count < 1 or not 0 <= index < count:
        raise ValueError(f"shard.index must be in 0..shard.count-1 and shard.count >= 1, got {index} of {count}.")
    ranges = split([clip.frames for clip in clips], count)
    if index >= len(ranges):  # more shards than clips: the extra shards are empty
        return []
    return [clips[i] for i in ranges[index]]


def shard_count(frames: Sequence[int], cpu_s_per_frame: float, max_cpu_s: float | None,
                cpu_s_per_clip: float = 0.0) -> int:
    """The fewest shards that keep each shard's estimated CPU time under ``max_cpu_s`` (1 if no budget).

    A shard's estimate is ``cpu_s_per_frame * frames + cpu_s_per_clip * clips``; a clip is never cut, so a clip
    alone over the budget gets a shard of its own.
    """
    if not frames:
        return 1
    if not max_cpu_s or max_cpu_s <= 0:
        return 1
    cost = [cpu_s_per_frame * f + cpu_s_per_clip for f in frames]
    count = max(1, min(len(frames), math.ceil(sum(cost) / max_cpu_s)))
    while count < len(frames):
        ranges = split(frames, count)
        if max(sum(cost[i] for i in r) for r in ranges) <= max_cpu_s:
            break
        count += 1
    return count


def shard_folder(folder: str, index: int, count: int) -> str:
    """The job folder of shard ``index`` of ``count`` below a config's folder (the folder itself if ``count == 1``)."""
    if count == 1:
        return folder
    width = max(3, len(str(count)))
    return f"{folder}/shard-{index + 1:0{width}d}-of-{count:0{width}d}"
