"""The frame-based scheme of Hou et al. 2016, §3.1: a causal, closed-loop encoder (zero latency).

``c_1 = B m_1`` (eq. 1), ``r_i = m_i − m^_{i−1}`` (eq. 2), ``c_i = B r_i`` (eq. 3). Because ``B`` is orthogonal the
loop runs in the coefficient domain (see :func:`frame_closed_loop`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["FrameEncoder", "frame_closed_loop", "frame_reconstruct", "spatial_forward"]


class FrameEncoder:
    """Closed-loop frame-by-frame encoder of §3.1: one call to :meth:`push` per frame, no look-ahead.

    Parameters
    ----------
    bases : ndarray, shape (3, J, J)
        ``B^x, B^y, B^z``.
    step : float, cm
        Δ.
    threshold : float, cm
        Hard threshold (>= Δ / 2).

    Notes
    -----
    This is the literal form of §3.1: the residual is taken against the previous *reconstructed* frame
    ``m^_{i−1}``, rebuilt with the inverse transform as the decoder does (eq. 2-3). It keeps only that frame, so by
    construction frame i's coefficients depend on frames 1..i alone: zero latency. The codecs use the equivalent
    vectorized form (:func:`frame_closed_loop`), which the tests check against this class index for index.
    """

    def __init__(self, bases: np.ndarray, step: float, threshold: float) -> None:
        bases = np.asarray(bases, dtype=np.float64)
        num_joints = bases.shape[-1]
        # Block-diagonal 3J × 3J form: one matrix-vector product per frame covers x, y and z.
        self._block = np.zeros((3 * num_joints, 3 * num_joints))
        for d in range(3):
            self._block[d * num_joints : (d + 1) * num_joints, d * num_joints : (d + 1) * num_joints] = bases[d]
        self._block_t = np.ascontiguousarray(self._block.T)
        self._step = float(step)
        self._threshold = float(threshold)
        self._threshold_active = threshold > 0.5 * step
        self._previous: np.ndarray | None = None  # m^_{i−1}, shape (3J,)
        self.num_joints = num_joints

    @property
    def reconstruction(self) -> np.ndarray | None:
        """The decoder's reconstruction of the last pushed frame, shape (3, J), cm (None before the first)."""
        return None if self._previous is None else self._previous.reshape(3, self.num_joints)

    def push(self, frame: np.ndarray) -> np.ndarray:
        """Code one frame.

        Parameters
        ----------
        frame : ndarray, shape (3, J), float, cm
            ``[m^x_i, m^y_i, m^z_i]``.

        Returns
        -------
        ndarray, shape (3, J), int64
            The quantized coefficient vectors of this frame (intra for the first frame, residual after).
        """
        vector = np.asarray(frame, dtype=np.float64).reshape(-1)
        residual = vector if self._previous is None else vector - self._previous  # eq. (2)
        coefficients = self._block @ residual  # eq. (1) / (3)
        indices = np.rint(coefficients / self._step)
        if self._threshold_active:
            indices[np.abs(coefficients) <= self._threshold] = 0.0
        decoded_residual = self._block_t @ (indices * self._step)  # the decoder's inverse LSDT
        self._previous = decoded_residual if self._previous is None else self._previous + decoded_residual
        return indices.astype(np.int64).reshape(3, self.num_joints)


def spatial_forward(frames: np.ndarray, bases: np.ndarray) -> np.ndarray:
    """``g_i = B^d m^d_i`` for every frame and coordinate at once: ``(F, 3, J)`` to ``(F, 3, J)``."""
    return np.matmul(frames.transpose(1, 0, 2), bases.transpose(0, 2, 1)).transpose(1, 0, 2)


def frame_closed_loop(frames: np.ndarray, bases: np.ndarray, step: float, threshold: float) -> np.ndarray:
    """The closed-loop predictive coder of §3.1 for a whole motion, in the coefficient domain.

    With ``m^_{i−1} = Bᵀ Δ K_{i−1}`` (``K`` the running sum of the coded indices, integers), the residual coefficients
    of eq. (2)-(3) are ``c_i = B (m_i − m^_{i−1}) = g_i − Δ K_{i−1}`` with ``g_i = B m_i``, because ``B Bᵀ = I``.
    So the loop needs no matrix product per frame, and frame i still reads only ``g_i`` and the past. With the plain
    rounding dead zone (threshold = Δ/2) the recurrence ``K_i = K_{i−1} + rint(g_i/Δ − K_{i−1})`` is
    ``K_i = rint(g_i/Δ)`` (up to ties), which vectorizes over time; a wider hard threshold keeps the per-frame loop.

    Parameters
    ----------
    frames : ndarray, shape (F, 3, J), cm
    bases : ndarray, shape (3, J, J)
    step, threshold : float, cm

    Returns
    -------
    ndarray, shape (F, 3, J), int64
        The coded indices: intra for frame 0 (eq. 1), residual after.
    """
    scaled = spatial_forward(frames, bases) / step  # g_i / Δ
    if threshold <= 0.5 * step:
        levels = np.rint(scaled).astype(np.int64)  # K_i
        indices = levels.copy()
        indices[1:] -= levels[:-1]
        return indices
    ratio = threshold / step
    indices = np.empty(scaled.shape, dtype=np.int64)
    state = np.zeros(scaled.shape[1:])  # K_{i−1}, integer-valued floats
    residual = np.empty(scaled.shape[1:])
    for i in range(scaled.shape[0]):
        np.subtract(scaled[i], state, out=residual)  # c_i / Δ
        coded = np.rint(residual)
        coded[np.abs(residual) <= ratio] = 0.0  # hard threshold
        state += coded
        indices[i] = coded
    return indices


def frame_reconstruct(indices: np.ndarray, bases: np.ndarray, step: float) -> np.ndarray:
    """Decoder of the frame scheme: ``m^_i = m^_{i−1} + Bᵀ ĉ_i = Bᵀ Δ K_i`` with ``K_i = Σ_{k<=i} q_k`` (integers).

    Parameters
    ----------
    indices : ndarray, shape (F, 3, J), int64
    bases : ndarray, shape (3, J, J)
    step : float, cm

    Returns
    -------
    ndarray, shape (F, J, 3), float64, cm
    """
    levels = np.cumsum(indices, axis=0)  # exact: integer accumulation, so nothing drifts
    return np.matmul(levels.transpose(1, 0, 2) * step, bases).transpose(1, 2, 0)
