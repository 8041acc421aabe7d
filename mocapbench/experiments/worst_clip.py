"""Each job keeps its worst clip, original and decoded, for the report's player (``worst.npz`` in the job folder).

A job measures one codec config over a shard of clips; the clip whose L∞ is the largest so far is written
(replacing the last) as float32 positions with what the player needs to draw and label it. The report takes,
for each codec's headline config, the worst clip over its jobs' rows and reads it from the job that measured it.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from mocapbench.motion import Motion

__all__ = ["WORST_FILE", "save_worst", "load_worst", "worst_error"]

WORST_FILE = "worst.npz"


def save_worst(folder: Path, motion: Motion, reference: np.ndarray, decoded: np.ndarray, row: dict[str, Any]) -> None:
    """Write ``folder/worst.npz`` (atomically) for one clip.

    Parameters
    ----------
    folder : Path
        The job folder.
    motion : Motion
        The original clip (skeleton, fps, up axis, name).
    reference, decoded : ndarray, shape (F, J, 3), float, cm
    row : dict
        The clip's results row (``codec``, ``config_hash``, ``max_err_cm``, ``worst_frame``, ``worst_joint``).
    """
    tmp = Path(folder) / f".{WORST_FILE}.tmp-{os.getpid()}.npz"
    np.savez_compressed(
        tmp,
        original=np.asarray(reference, dtype=np.float32),
        decoded=np.asarray(decoded, dtype=np.float32),
        parents=np.asarray(motion.skeleton.parents),
        names=np.asarray(motion.skeleton.names),
        clip=np.asarray(motion.name),
        fps=np.asarray(motion.fps),
        up_axis=np.asarray(motion.up_axis),
        codec=np.asarray(row["codec"]),
        config_hash=np.asarray(row["config_hash"]),
        max_err_cm=np.asarray(row["max_err_cm"]),
        worst_frame=np.asarray(row["worst_frame"]),
        worst_joint=np.asarray(motion.skeleton.index(row["worst_joint"])),
    )
    os.replace(tmp, Path(folder) / WORST_FILE)


def load_worst(path: Path) -> dict[str, Any]:
    """The arrays and facts of a ``worst.npz`` (strings and numbers as Python values)."""
    with np.load(path, allow_pickle=False) as data:
        out = {key: data[key] for key in data.files}
    for key in ("clip", "up_axis", "codec", "config_hash"):
        out[key] = str(out[key])
    for key in ("fps", "max_err_cm"):
        out[key] = float(out[key])
    for key in ("worst_frame", "worst_joint"):
        out[key] = int(out[key])
    out["names"] = [str(n) for n in out["names"]]
    return out


def worst_error(folder: Path) -> float:
    """L∞ (cm) of the clip in ``folder/worst.npz``; -inf when there is none or it does not load."""
    path = Path(folder) / WORST_FILE
    if not path.exists():
        return float("-inf")
    try:
        with np.load(path, allow_pickle=False) as data:
            return float(data["max_err_cm"])
    except (OSError, ValueError, KeyError):
        return float("-inf")
