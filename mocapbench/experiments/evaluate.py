"""One long-format results row per (codec config, clip): every later table and plot is built on it."""

from __future__ import annotations

import platform
from dataclasses import dataclass
from functools import lru_cache
from importlib import metadata
from typing import Any

import numpy as np

from mocapbench import metrics
from mocapbench.codecs.base import Codec, Decoded
from mocapbench.experiments.animator_metrics import animator_columns
from mocapbench.metrics.timing import Timing, measure
from mocapbench.motion import Motion

__all__ = ["evaluate", "evaluate_with_decoded", "package_versions", "codec_traits", "TimingSettings"]

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


@dataclass(frozen=True)
class TimingSettings:
    """How :func:`evaluate` times encode and decode (see :mod:`mocapbench.metrics.timing`).

    repeats: timed calls (median); warmup: untimed calls before them; threads: BLAS/torch threads;
    budget_s: wall seconds after which no further repeat starts (a slower warm-up is itself the one timed call).
    """

    repeats: int = 3
    warmup: int = 1
    threads: int = 1
    budget_s: float = 10.0

    def __post_init__(self) -> None:
        if self.repeats < 1 or self.warmup < 0 or self.threads < 1 or not self.budget_s > 0:
            raise ValueError(f"TimingSettings: repeats >= 1, warmup >= 0, threads >= 1, budget_s > 0; got {self}.")


def codec_traits(codec: Codec) -> dict[str, Any]:
    """What a user choosing a codec needs beside rate and error, from the codec instance (its config included)."""
    return {
        "codes_rotations": bool(codec.codes_rotations),
        "family": str(codec.family),
        "needs_model": bool(codec.needs_model),
        "random_access": bool(codec.random_access),
        "latency_frames": int(codec.latency_frames),
    }


def evaluate(
    codec: Codec,
    motion: Motion,
    *,
    reference_positions: np.ndarray | None = None,
    timing: TimingSettings | None = None,
    encoded: tuple[bytes, dict[str, Any], Timing] | None = None,
) -> dict[str, Any]:
    """The results row of :func:`evaluate_with_decoded`, without the decoded motion."""
    return evaluate_with_decoded(codec, motion, reference_positions=reference_positions, timing=timing,
                                 encoded=encoded)[0]


def evaluate_with_decoded(
    codec: Codec,
    motion: Motion,
    *,
    reference_positions: np.ndarray | None = None,
    timing: TimingSettings | None = None,
    encoded: tuple[bytes, dict[str, Any], Timing] | None = None,
) -> tuple[dict[str, Any], Decoded]:
    """Encode and decode ``motion``, timed as :class:`TimingSettings` says, and measure the result.

    Parameters
    ----------
    codec : Codec
        Fitted if it needs fitting.
    motion : Motion
    reference_positions : ndarray, shape (F, J, 3), float, cm, optional
        ``motion.positions()``, if the caller already has it.
    timing : TimingSettings, optional
        Default: 3 timed repeats after 1 warm-up, one thread, 10 s budget.
    encoded : (bytes, dict, Timing), optional
        The stream, encode stats and encode timing of ``motion`` already made (by
        :meth:`~mocapbench.codecs.base.Codec.encode_many`, which encodes a batch of clips at once and gives each
        its share of the batch's time); then ``motion`` is not encoded again.

    Returns
    -------
    row : dict
        ``codec``, ``param_<field>`` for every config field, ``config_hash``, clip facts (``clip``, ``frames``,
        ``joints``, ``fps``, ``height_cm``), rate (``raw_bytes``, ``bitstream_bytes``, ``model_bytes``,
        ``compression_ratio``, ``bits_per_joint_frame``), distortion (``max_err_cm``, ``max_err_percent_height``,
        ``mean_err_cm``, ``p99_err_cm``, ACL's shell error at 3 cm ``shell_max_err_cm`` and ``shell_p99_err_cm``
        (NaN for codecs that do not return rotations), ``kg_percent``, ``worst_joint``, ``worst_frame``), speed
        (``encode_s``, ``decode_s``: median wall seconds; ``encode_cpu_s``, ``decode_cpu_s``: median CPU seconds
        of the process, which the cost estimator of :mod:`mocapbench.experiments.cost` reads; ``encode_fps``,
        ``decode_fps``: frames per CPU second; ``encode_wall_spread_s``, ``encode_repeats``, ``encode_warmup``,
        ``encode_threads``, ``encode_load_before``, ``encode_load_after`` and the same for decode), the codec's
        traits (:func:`codec_traits`), what animators see (end sites, jitter, foot sliding, bone lengths, joint
        rotations: :mod:`mocapbench.experiments.animator_metrics`) and package versions. KG is NaN for a static
        clip, where it is undefined.
    decoded : Decoded
        What the last timed decode returned (the report's player shows it).
    """
    timing = timing or TimingSettings()
    reference = motion.positions() if reference_positions is None else reference_positions
    knobs = {"repeats": timing.repeats, "warmup": timing.warmup, "threads": timing.threads,
             "budget_s": timing.budget_s}
    if encoded is None:
        encode_timing, data = measure(lambda: codec.encode(motion), **knobs)
        stats = dict(codec.last_encode_stats)
    else:
        data, stats, encode_timing = encoded
    decode_timing, decoded = measure(lambda: codec.decode(data), **knobs)
    encode_s, decode_s = encode_timing.wall_s, decode_timing.wall_s
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
            # Quantiles 0, 1, ..., 100 % of the per-joint, per-frame errors: the share of samples under any
            # bound, for the report's distributions over clips (ACL's "% below threshold").
            "error_quantiles_cm": np.percentile(metrics.joint_errors(reference, positions),
                                                np.arange(101)).round(6).tolist(),
            "worst_joint": motion.skeleton.names[worst_joint],
            "worst_frame": worst_frame,
            "encode_s": encode_s,
            "decode_s": decode_s,
            "encode_fps": encode_timing.per_second(frames),
            "decode_fps": decode_timing.per_second(frames),
            **encode_timing.as_columns("encode"),
            **decode_timing.as_columns("decode"),
            **codec_traits(codec),
            **animator_columns(motion, positions, decoded.motion, reference),
        }
    )
    row.update(stats)
    row.update(package_versions())
    return row, decoded
