"""The clip-based scheme of Hou et al. 2016, §3.2: temporal DCT, then the spatial transform, batched over clips."""

from __future__ import annotations

import numpy as np
import scipy  # scipy.fft loads on first use (see mocapbench.lazy_imports)

__all__ = ["clip_forward", "clip_inverse", "clip_lengths"]


def clip_lengths(num_frames: int, clip_length: int) -> list[int]:
    """Full clips of L frames, then the partial clip of ``F mod L`` frames if any."""
    lengths = [clip_length] * (num_frames // clip_length)
    if num_frames % clip_length:
        lengths.append(num_frames % clip_length)
    return lengths


def clip_forward(frames: np.ndarray, bases: np.ndarray) -> np.ndarray:
    """eq. (4)-(5) for a batch of clips of one length L.

    Parameters
    ----------
    frames : ndarray, shape (n, L, 3, J), cm
    bases : ndarray, shape (3, J, J)

    Returns
    -------
    ndarray, shape (n, 3, L, J)
        ``C^d`` of each clip, one coefficient vector (a column of C, over the J joints) per temporal frequency k.

    Notes
    -----
    ``C~ = M~ U_t`` (eq. 4) with the orthonormal DCT-II matrix is ``scipy.fft.dct(..., norm="ortho")`` along time:
    O(L log L) per trajectory and no L × L matrix, so any clip length fits in memory.
    """
    n, length, _, num_joints = frames.shape
    spectra = scipy.fft.dct(frames, type=2, norm="ortho", axis=1)  # eq. (4), (n, L, 3, J)
    rows = spectra.transpose(2, 0, 1, 3).reshape(3, n * length, num_joints)
    coefficients = np.matmul(rows, bases.transpose(0, 2, 1))  # eq. (5) in row form: (B C~)ᵀ = C~ᵀ Bᵀ
    return coefficients.reshape(3, n, length, num_joints).transpose(1, 0, 2, 3)


def clip_inverse(coefficients: np.ndarray, bases: np.ndarray) -> np.ndarray:
    """Inverse of :func:`clip_forward`: ``(n, 3, L, J)`` coefficients to ``(n, L, 3, J)`` frames, cm."""
    n, _, length, num_joints = coefficients.shape
    rows = np.matmul(coefficients.transpose(1, 0, 2, 3).reshape(3, n * length, num_joints), bases)  # Bᵀ C
    spectra = rows.reshape(3, n, length, num_joints).transpose(1, 2, 0, 3)  # (n, L, 3, J)
    return scipy.fft.idct(spectra, type=2, norm="ortho", axis=1)
