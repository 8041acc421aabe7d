"""Fixed orthonormal spatial transforms of a pose vector: the 1-D DCT and the 3-level Haar DWT.

Both are returned as ``(J, J)`` matrices ``B`` with the convention of the LSDT paper (Hou et al., CAGD 2016,
eq. 1): coefficients ``c = B @ m`` for a pose vector ``m`` (one coordinate of the J joints of one frame), so the
**rows** of ``B`` are the basis functions and the inverse is ``B.T``. Applying a transform as a matrix product
lets the codecs batch it over frames, clips and coordinates.
"""

from __future__ import annotations

import numpy as np
import scipy  # scipy.fft loads on first use (see mocapbench.lazy_imports)

from mocapbench.lazy_imports import pywt

__all__ = ["dct_matrix", "haar_dwt_matrix", "is_orthogonal", "spatial_basis"]


def _check_length(n: int) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"Expected a transform length `n` >= 1, got {n!r}.")
    return int(n)


def dct_matrix(n: int) -> np.ndarray:
    """Orthonormal DCT-II matrix.

    Parameters
    ----------
    n : int
        Signal length (J for the spatial transform, L for the temporal one), >= 1.

    Returns
    -------
    ndarray, shape (n, n), float64
        ``D`` with ``D @ x == scipy.fft.dct(x, norm="ortho")``; row ``k`` is the k-th cosine, ``D @ D.T == I``.
    """
    n = _check_length(n)
    return scipy.fft.dct(np.eye(n), norm="ortho", axis=0)


def haar_dwt_matrix(n: int, levels: int = 3) -> np.ndarray:
    """Orthonormal multi-level Haar DWT matrix, computed with PyWavelets.

    Each level splits the current approximation with ``pywt.dwt(..., "haar", mode="periodization")``. For an odd
    length the last sample has no partner; it is carried unchanged into the next level's approximation. This keeps
    the transform square and orthonormal for any ``n`` (PyWavelets' own ``wavedec`` on an odd length returns
    ``n + 1`` coefficients with any extension mode, i.e. a frame, not a basis). For even lengths at every level
    (e.g. ``n = 32``) the result equals ``pywt.wavedec(x, "haar", mode="periodization", level=levels)``.

    Parameters
    ----------
    n : int
        Signal length, >= 1.
    levels : int
        Decomposition levels, >= 0 (stops early when the approximation has a single sample).

    Returns
    -------
    ndarray, shape (n, n), float64
        ``W`` with coefficients ``W @ x`` ordered ``[cA_levels, cD_levels, ..., cD_1]`` (wavedec's order).
    """
    n = _check_length(n)
    if isinstance(levels, bool) or not isinstance(levels, (int, np.integer)) or levels < 0:
        raise ValueError(f"Expected `levels` >= 0, got {levels!r}.")
    approx = np.eye(n)  # columns: the transform of each unit vector, built level by level
    details: list[np.ndarray] = []
    for _ in range(levels):
        length = approx.shape[0]
        if length < 2:
            break
        even = length - length % 2
        c_a, c_d = pywt.dwt(approx[:even], "haar", mode="periodization", axis=0)
        if even < length:
            c_a = np.concatenate([c_a, approx[even:]], axis=0)
        details.insert(0, c_d)
        approx = c_a
    return np.concatenate([approx, *details], axis=0)


def is_orthogonal(matrix: np.ndarray, tol: float = 1e-10) -> bool:
    """True when ``matrix`` is square and ``||B B^T - I||_max < tol``."""
    matrix = np.asarray(matrix, dtype=np.float64)
    if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1]:
        return False
    return bool(np.abs(matrix @ matrix.T - np.eye(matrix.shape[0])).max() < tol)


def spatial_basis(kind: str, num_joints: int) -> np.ndarray:
    """The fixed spatial transform ``kind`` for J joints, one copy per coordinate.

    Parameters
    ----------
    kind : {"dct", "dwt"}
        ``"dct"``: 1-D DCT-II over the joint index (Kwak & Bajic 2011); ``"dwt"``: 3-level Haar DWT.
    num_joints : int
        J.

    Returns
    -------
    ndarray, shape (3, J, J), float64
        ``B[d]`` for the x, y, z coordinates (identical for fixed transforms).
    """
    if kind == "dct":
        single = dct_matrix(num_joints)
    elif kind == "dwt":
        single = haar_dwt_matrix(num_joints, levels=3)
    else:
        raise ValueError(f"Unknown spatial transform {kind!r}; expected 'dct' or 'dwt'.")
    return np.repeat(single[None], 3, axis=0)
