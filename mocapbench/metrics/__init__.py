"""Distortion, rate and timing metrics: pure functions with shapes and units in their docstrings."""

from mocapbench.metrics.distortion import (
    joint_errors,
    kg_distortion,
    max_joint_error,
    max_joint_error_percent,
    mean_joint_error,
    p99_joint_error,
    worst_joint_and_frame,
)
from mocapbench.metrics.rate import (
    RAW_BITS_PER_JOINT_FRAME,
    bits_per_joint_frame,
    compression_ratio,
    neural_fourier_pose_parameters,
    pga_raw_numbers,
    raw_position_bytes,
)
from mocapbench.metrics.shell import ACL_SHELL_DISTANCE_CM, motion_shell_errors, shell_errors
from mocapbench.metrics.timing import time_call

__all__ = [
    "joint_errors",
    "kg_distortion",
    "max_joint_error",
    "max_joint_error_percent",
    "mean_joint_error",
    "p99_joint_error",
    "worst_joint_and_frame",
    "RAW_BITS_PER_JOINT_FRAME",
    "bits_per_joint_frame",
    "compression_ratio",
    "neural_fourier_pose_parameters",
    "pga_raw_numbers",
    "raw_position_bytes",
    "time_call",
    "ACL_SHELL_DISTANCE_CM",
    "shell_errors",
    "motion_shell_errors",
]
