"""Acceleration error: how much high-frequency motion (jitter) a codec adds or removes. Pure functions, no I/O.

A joint's acceleration at frame ``t`` is its second difference over one frame step, scaled to seconds::

    a[t] = (p[t + 1] - 2 p[t] + p[t - 1]) * fps**2        (cm/s^2, frames 1 .. F - 2)

and the error is ``|| a_decoded[t, j] - a_reference[t, j] ||`` for every inner frame and joint. Dividing by the
frame step in seconds (not in frames) puts 24 fps and 120 fps clips on one scale: the same physical motion has
the same acceleration at either rate. The same position noise, however, is 25 times larger in cm/s^2 at 120 fps
than at 24 fps, because it changes direction 5 times as often: that is the jitter an animator sees at that rate.
"""

from __future__ import annotations

import numpy as np

from mocapbench.metrics.distortion import joint_errors

__all__ = ["accelerations", "acceleration_errors", "acceleration_error"]


def _check_fps(fps: float) -> float:
    fps = float(fps)
    if not np.isfinite(fps) or fps <= 0:
        raise ValueError(f"`fps` must be a finite number > 0, got {fps}.")
    return fps


def accelerations(positions, fps: float) -> np.ndarray:
    """Second differences of joint positions, scaled to cm/s^2.

    Parameters
    ----------
    positions : array_like, shape (F, J, 3), float, cm
    fps : float
        Frames per second, > 0.

    Returns
    -------
    ndarray, shape (max(F - 2, 0), J, 3), float, cm/s^2
        Acceleration at the inner frames 1 .. F - 2.
    """
    positions = np.asarray(positions, dtype=np.float64)
    fps = _check_fps(fps)
    return (positions[2:] - 2.0 * positions[1:-1] + positions[:-2]) * fps**2


def acceleration_errors(reference, decoded, fps: float) -> np.ndarray:
    """Euclidean acceleration error of every joint at every inner frame.

    Parameters
    ----------
    reference, decoded : array_like, shape (F, J, 3), float, cm
    fps : float
        Frames per second of both, > 0.

    Returns
    -------
    ndarray, shape (max(F - 2, 0), J), float, cm/s^2
    """
    errors = joint_errors(reference, decoded)  # validates shapes and finiteness
    if errors.shape[0] < 3:
        return np.zeros((0, errors.shape[1]))
    return np.linalg.norm(accelerations(decoded, fps) - accelerations(reference, fps), axis=-1)


def acceleration_error(reference, decoded, fps: float) -> tuple[float, float]:
    """RMS and maximum of :func:`acceleration_errors` over every joint and inner frame.

    Returns
    -------
    (rms, max) : tuple of float, cm/s^2
        Both NaN for a clip of fewer than 3 frames (no second difference exists).
    """
    errors = acceleration_errors(reference, decoded, fps)
    if errors.size == 0:
        return float("nan"), float("nan")
    return float(np.sqrt(np.mean(errors**2))), float(errors.max())
