"""Keyed animation tracks evaluated at many times at once (numpy, no Python call per sample).

The interpolations of glTF 2.0 (LINEAR with slerp for rotations, STEP, CUBICSPLINE); the FBX reader uses LINEAR on
the keys ufbx bakes at the sampling rate.
"""

from __future__ import annotations

import numpy as np

__all__ = ["sample_keys", "KEY_TIME_TOLERANCE_S"]

#: Key times are float32 in glTF: a sample time within this many seconds of a STEP key takes that key.
KEY_TIME_TOLERANCE_S = 1e-5


def sample_keys(times: np.ndarray, values: np.ndarray, interpolation: str, at: np.ndarray, rotation: bool) -> np.ndarray:
    """Evaluate a keyed track at times ``at`` (s), all at once.

    Parameters
    ----------
    times : ndarray, shape (K,), float, s
        Key times, strictly increasing.
    values : ndarray, shape (K, W) or, for ``"CUBICSPLINE"``, (3K, W) in-tangent, value, out-tangent per key
        Key values; for a rotation, scalar-last quaternions (W = 4).
    interpolation : str
        ``"LINEAR"`` (lerp, slerp for rotations), ``"STEP"`` or ``"CUBICSPLINE"`` (Hermite), as glTF 2.0 defines
        them. Before the first key and after the last the track holds its end value.
    at : ndarray, shape (F,), float, s
    rotation : bool
        Values are quaternions: slerp along the short arc, results normalized.

    Returns
    -------
    ndarray, shape (F, W), float
    """
    cubic = interpolation == "CUBICSPLINE"
    keys = values.reshape(len(times), 3, -1)[:, 1] if cubic else values
    if len(times) == 1:
        return np.broadcast_to(keys[0], (len(at), keys.shape[1])).copy()
    index = np.clip(np.searchsorted(times, at, side="right") - 1, 0, len(times) - 2)
    span = times[index + 1] - times[index]
    u = np.clip((at - times[index]) / span, 0.0, 1.0)[:, None]
    if interpolation == "STEP":
        # Key times are float32 in the file: a sample time within 10 us of a key takes that key.
        result = keys[np.clip(np.searchsorted(times, at + KEY_TIME_TOLERANCE_S, side="right") - 1, 0, len(times) - 1)]
    elif cubic:
        tangents = values.reshape(len(times), 3, -1)
        out_tangent, in_tangent = tangents[index, 2], tangents[index + 1, 0]
        u2, u3 = u * u, u * u * u
        result = ((2 * u3 - 3 * u2 + 1) * keys[index] + (u3 - 2 * u2 + u) * span[:, None] * out_tangent
                  + (-2 * u3 + 3 * u2) * keys[index + 1] + (u3 - u2) * span[:, None] * in_tangent)
    elif rotation:
        q0, q1 = keys[index], keys[index + 1].copy()
        q1[np.sum(q0 * q1, axis=1) < 0] *= -1
        dot = np.clip(np.sum(q0 * q1, axis=1, keepdims=True), -1.0, 1.0)
        angle = np.arccos(dot)
        small = angle[:, 0] < 1e-6
        sin = np.where(small[:, None], 1.0, np.sin(angle))
        w0 = np.where(small[:, None], 1 - u, np.sin((1 - u) * angle) / sin)
        w1 = np.where(small[:, None], u, np.sin(u * angle) / sin)
        result = w0 * q0 + w1 * q1
    else:
        result = (1 - u) * keys[index] + u * keys[index + 1]
    if rotation:
        norms = np.linalg.norm(result, axis=1, keepdims=True)
        result = result / np.where(norms < 1e-12, 1.0, norms)
    return result
