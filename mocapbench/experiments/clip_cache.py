"""Parsed clips kept across the jobs of one worker process, their forward kinematics computed once.

A sweep runs every codec config as its own job, and the launcher's worker processes run job after job on the
same dataset: without this cache each job parsed every clip of its shard again (ASF/AMC or BVH text, about 70 ms
of CPU per CMU clip and 0.4 s per ASF) and ran the reference's forward kinematics again (positions, global
transforms for end sites and ACL's shell error), for every one of the ~160 configs of ``sweep=all``.
:func:`mocapbench.experiments.datasets.iter_clips` keeps each clip it reads from a data folder here, keyed by the
dataset spec, the clip name and the files' size and modification time (a file rewritten in place is read again),
as a :func:`~mocapbench.ratesearch.source.known_kinematics` motion: the same arrays and values, its kinematics
computed on first use and handed out as copies.

The cache holds at most :data:`MAX_FRAMES` frames (least recently used clips go first; a clip longer than that
is not kept): about 80 MB for a CMU rig with its kinematics. A motion's arrays are read-only (:class:`Motion`
makes them so) and its kinematics are handed out as copies, so no job can change what a later job reads.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Hashable

from mocapbench.motion import Motion

__all__ = ["MAX_FRAMES", "get", "put", "clear"]

#: Most frames kept per process (all clips together).
MAX_FRAMES = 20_000

_KEPT: "OrderedDict[Hashable, Motion]" = OrderedDict()


def get(key: Hashable) -> Motion | None:
    """The clip kept under ``key``, or None."""
    motion = _KEPT.get(key)
    if motion is not None:
        _KEPT.move_to_end(key)
    return motion


def put(key: Hashable, motion: Motion) -> Motion:
    """Keep ``motion`` under ``key`` unless it is longer than :data:`MAX_FRAMES`; returns the motion to use (the
    kept one, its kinematics computed once)."""
    from mocapbench.ratesearch.source import known_kinematics

    if motion.num_frames > MAX_FRAMES:
        return motion
    if key in _KEPT:
        return get(key)
    kept = known_kinematics(motion)
    frames = sum(m.num_frames for m in _KEPT.values())
    while _KEPT and frames + motion.num_frames > MAX_FRAMES:
        _, old = _KEPT.popitem(last=False)
        frames -= old.num_frames
    _KEPT[key] = kept
    return kept


def clear() -> None:
    """Forget every kept clip."""
    _KEPT.clear()
