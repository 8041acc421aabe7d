"""One long-format results row per (codec config, clip): every later table and plot is built on it."""

from __future__ import annotations

import platform
import time
from functools import lru_cache
from importlib import metadata
from typing import Any

import numpy as np

from mocapbench import metrics
from mocapbench.codecs.base import Codec
from mocapbench.motion import Motion

__all__ = ["evaluate", "package_versions"]

_PACKAGES = ("mocapbench", "numpy", "scipy", "torch", "PyWavelets", "zstandard", "bitarray")


@lru_cache(maxsize=1)
def package_versions() -> dict[str, str]:
    """Versions of the packages that can change a result, as ``version_<name>`` columns."""
    versions = {"version_python": platform.python_version()}
    for package in _PACKAGES:
        try:
            versions[f"version_{package}"] = metadata.version(package)
        except metadata.PackageNotFoundError:
            versions[f"version_{package}"] = "absent"
    return versions


def evaluate(codec: Codec, motion: Motion, *, reference_positions: np.ndarray | None = None) -> dict[str, Any]:
    """Encode and decode ``motion`` once and measure it.

    Parameters
    ----------
    codec : Codec
        Fitted if it needs fitting.
    motion : Motion
    reference_positions : ndarray, shape (F, J, 3), float, cm, optional
        ``motion.positions()``, if the caller already has it.

    Returns
    -------
    dict
        ``codec``, ``param_<field>`` for every config field, ``config_hash``, clip facts (``clip``, ``frames``,
        ``joints``, ``fps``, ``height_cm``), rate (``raw_bytes``, ``bitstream_bytes``, ``model_bytes``,
        ``compression_ratio``, ``bits_per_joint_frame``), distortion (``max_err_cm``, ``max_err_percent_height``,
        ``mean_err_cm``, ``p99_err_cm``, ACL's shell error at 3 cm ``shell_max_err_cm`` and ``shell_p99_err_cm``
        (NaN for codecs that do not return rotations), ``kg_percent``, ``worst_joint``, ``worst_frame``), speed
        (``encode_s``, ``decode_s`` wall; ``encode_cpu_s``, ``decode_cpu_s`` CPU of the process, which the cost
        estimator of :mod:`mocapbench.experiments.cost` reads; ``encode_fps``, ``decode_fps``) and package versions. KG is NaN for a
        static clip, where it is undefined.
    """
    reference = motion.positions() if reference_positions is None else reference_positions
    start, cpu = time.perf_counter(), time.process_time()
    data = codec.encode(motion)
    encode_s, encode_cpu_s = time.perf_counter() - start, time.process_time() - cpu
    start, cpu = time.perf_counter(), time.process_time()
    decoded = codec.decode(data)
    decode_s, decode_cpu_s = time.perf_counter() - start, time.process_time() - cpu
    positions = decoded.positions
    frames, joints = motion.num_frames, motion.num_joints
    raw = metrics.raw_position_bytes(joints, frames)
    height = motion.skeleton.rest_height()
    try:
        kg = metrics.kg_distortion(reference, positions)
    except ValueError:
        kg = float("nan")
    worst_joint, worst_frame = metrics.worst_joint_and_frame(reference, positions)
    # ACL's own error (virtual vertices 3 cm from each joint) needs rotations: NaN for position-only codecs.
    shell = (
        metrics.motion_shell_errors(motion, decoded.motion, metrics.ACL_SHELL_DISTANCE_CM)
        if decoded.motion is not None
        else np.full(1, np.nan)
    )
    row: dict[str, Any] = {"codec": codec.name}
    row.update({f"param_{key}": value for key, value in codec.config.as_dict().items()})
    row.update(
        {
            "config_hash": codec.config.config_hash(),
            "clip": motion.name,
            "frames": frames,
            "joints": joints,
            "fps": motion.fps,
            "height_cm": height,
            "raw_bytes": raw,
            "bitstream_bytes": len(data),
            "model_bytes": codec.model_bytes,
            "compression_ratio": metrics.compression_ratio(raw, len(data)),
            "bits_per_joint_frame": metrics.bits_per_joint_frame(len(data), joints, frames),
            "max_err_cm": metrics.max_joint_error(reference, positions),
            "max_err_percent_height": metrics.max_joint_error_percent(reference, positions, height),
            "mean_err_cm": metrics.mean_joint_error(reference, positions),
            "p99_err_cm": metrics.p99_joint_error(reference, positions),
            "shell_max_err_cm": float(shell.max()),
            "shell_p99_err_cm": float(np.percentile(shell, 99)),
            "kg_percent": kg,
            "worst_joint": motion.skeleton.names[worst_joint],
            "worst_frame": worst_frame,
            "encode_s": encode_s,
            "decode_s": decode_s,
            "encode_cpu_s": encode_cpu_s,
            "decode_cpu_s": decode_cpu_s,
            "encode_fps": frames / encode_s if encode_s > 0 else float("inf"),
            "decode_fps": frames / decode_s if decode_s > 0 else float("inf"),
        }
    )
    row.update(codec.last_encode_stats)
    row.update(package_versions())
    return row
