"""Learned spatial decorrelation transform (LSDT): Algorithm 1 of Hou, Chau, Magnenat-Thalmann & He,
"Low-latency compression of mocap data using learned spatial decorrelation transform", CAGD 43 (2016).

For one coordinate d, given N training frames ``M`` (J × N, one pose vector per column), LSDT finds an
orthogonal ``B`` (J × J) that makes every ``B m_i`` close to a P-sparse vector (eq. 6)::

    min_{B, {e_i}}  sum_i ||B m_i - e_i||_2^2    s.t.  B B^T = B^T B = I,  ||e_i||_0 <= P

by alternating two exact sub-problem solutions:

* truncation (eq. 7-8): with B fixed, ``e_i`` keeps the P largest-magnitude entries of ``g_i = B m_i``;
* orthogonal step (eq. 9-11): with E fixed, ``M E^T = U S V^T`` (SVD) and ``B = V U^T``.

Each step can only lower the objective, so the recorded objective never increases (up to rounding).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapbench.codecs.lsdt.spatial import dct_matrix, haar_dwt_matrix

__all__ = [
    "LsdtResult",
    "lsdt_objective",
    "orthogonal_step",
    "train_lsdt",
    "train_lsdt_bases",
    "truncate",
]


def _check_sparsity(sparsity: int, num_joints: int) -> int:
    if isinstance(sparsity, bool) or not isinstance(sparsity, (int, np.integer)) or not 1 <= sparsity <= num_joints:
        raise ValueError(f"Expected the sparsity `P` in [1, J={num_joints}], got {sparsity!r}.")
    return int(sparsity)


def _check_frames(frames, name: str = "frames") -> np.ndarray:
    frames = np.asarray(frames, dtype=np.float64)
    if frames.ndim != 2 or frames.shape[0] < 1 or frames.shape[1] < 1:
        raise ValueError(f"Expected `{name}` to have shape (J, N) with J, N >= 1, got {frames.shape}.")
    if not np.all(np.isfinite(frames)):
        raise ValueError(f"`{name}` holds non-finite values.")
    return frames


def truncate(coefficients: np.ndarray, sparsity: int) -> np.ndarray:
    """The truncation operator T of eq. (8): keep the P largest-magnitude entries of every column.

    Parameters
    ----------
    coefficients : ndarray, shape (J, N), float
        ``G = B M``, one coefficient vector per column.
    sparsity : int
        P, in [1, J]. Exactly P entries per column are kept (ties broken by position), the J - P others set to 0.

    Returns
    -------
    ndarray, shape (J, N), float
        ``E``, the solution of eq. (7) for every column.
    """
    coefficients = np.asarray(coefficients, dtype=np.float64)
    if coefficients.ndim != 2:
        raise ValueError(f"Expected `coefficients` to have shape (J, N), got {coefficients.shape}.")
    num_joints = coefficients.shape[0]
    sparsity = _check_sparsity(sparsity, num_joints)
    return _truncate_rows(coefficients.T, sparsity).T


def _truncate_rows(rows: np.ndarray, sparsity: int) -> np.ndarray:
    """:func:`truncate` with one coefficient vector per **row**, shape (N, J)."""
    if sparsity == rows.shape[1]:
        return rows.copy()
    keep = np.argpartition(-np.abs(rows), sparsity - 1, axis=1)[:, :sparsity]
    truncated = np.zeros_like(rows)
    np.put_along_axis(truncated, keep, np.take_along_axis(rows, keep, axis=1), axis=1)
    return truncated


def lsdt_objective(basis: np.ndarray, frames: np.ndarray, sparsity: int) -> float:
    """Objective of eq. (6) at ``basis`` with the optimal sparse vectors, ``||B M - T(B M)||_F^2``.

    Parameters
    ----------
    basis : ndarray, shape (J, J)
    frames : ndarray, shape (J, N), unit U (cm for positions)
    sparsity : int

    Returns
    -------
    float, unit U^2
    """
    coefficients = np.asarray(basis, dtype=np.float64) @ _check_frames(frames)
    residual = coefficients - truncate(coefficients, sparsity)
    return float(np.sum(residual * residual))


def orthogonal_step(frames: np.ndarray, sparse: np.ndarray) -> np.ndarray:
    """Solve eq. (9) for B: ``M E^T = U S V^T`` gives ``B = V U^T`` (eq. 11).

    Parameters
    ----------
    frames : ndarray, shape (J, N)
        ``M``.
    sparse : ndarray, shape (J, N)
        ``E``.

    Returns
    -------
    ndarray, shape (J, J)
        The orthogonal B maximizing ``Tr(B M E^T)`` (eq. 10).
    """
    u, _, vt = np.linalg.svd(frames @ sparse.T)
    return vt.T @ u.T


@dataclass(frozen=True, eq=False)
class LsdtResult:
    """Outcome of :func:`train_lsdt` for one coordinate.

    Attributes
    ----------
    basis : ndarray, shape (J, J), float64
        The learned orthogonal ``B`` (rows are basis functions; coefficients ``c = B m``).
    objective : ndarray, shape (K + 1,), float64, unit U^2
        ``objective[0]`` at the initial basis, ``objective[k]`` after k iterations of Algorithm 1.
    converged : bool
        True when the relative decrease fell below the tolerance before ``max_iterations``.
    """

    basis: np.ndarray
    objective: np.ndarray
    converged: bool

    @property
    def iterations(self) -> int:
        """Number of iterations run."""
        return len(self.objective) - 1


def _initial_basis(init, num_joints: int) -> np.ndarray:
    if isinstance(init, str):
        if init == "dct":
            return dct_matrix(num_joints)
        if init == "dwt":
            return haar_dwt_matrix(num_joints, levels=3)
        raise ValueError(f"Unknown LSDT initialization {init!r}; expected 'dct', 'dwt' or a (J, J) orthogonal matrix.")
    basis = np.array(init, dtype=np.float64)
    if basis.shape != (num_joints, num_joints):
        raise ValueError(f"Expected the initial basis to have shape ({num_joints}, {num_joints}), got {basis.shape}.")
    if np.abs(basis @ basis.T - np.eye(num_joints)).max() > 1e-8:
        raise ValueError("The initial basis must be orthogonal (||B B^T - I|| <= 1e-8).")
    return basis


def train_lsdt(
    frames: np.ndarray,
    sparsity: int,
    *,
    init: str | np.ndarray = "dct",
    max_iterations: int = 500,
    tol: float = 1e-9,
) -> LsdtResult:
    """Algorithm 1: learn the LSDT basis of one coordinate.

    Parameters
    ----------
    frames : ndarray, shape (J, N), float, unit U
        Training pose vectors ``M^d``, one per column.
    sparsity : int
        P, the number of coefficients kept per vector during training, in [1, J].
    init : {"dct", "dwt"} or ndarray, shape (J, J)
        Initial orthogonal basis: the 1-D DCT (the paper's default), the 3-level Haar DWT, or a given matrix.
    max_iterations : int
        K, the iteration cap (>= 0).
    tol : float
        Stop when an iteration lowers the objective by less than ``tol`` times its value (>= 0; 0 runs all K).

    Returns
    -------
    LsdtResult
    """
    frames = _check_frames(frames)
    num_joints = frames.shape[0]
    sparsity = _check_sparsity(sparsity, num_joints)
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, (int, np.integer)) or max_iterations < 0:
        raise ValueError(f"Expected `max_iterations` >= 0, got {max_iterations!r}.")
    if not (np.isfinite(tol) and tol >= 0):
        raise ValueError(f"Expected `tol` >= 0, got {tol!r}.")
    basis = _initial_basis(init, num_joints)
    # Internally one frame per row, so that the per-frame truncation runs along contiguous memory.
    rows = np.ascontiguousarray(frames.T)  # (N, J)
    coefficients = rows @ basis.T  # (B M)^T
    sparse = _truncate_rows(coefficients, sparsity)  # eq. (8)
    objective = [float(np.sum((coefficients - sparse) ** 2))]
    converged = False
    for _ in range(max_iterations):
        basis = orthogonal_step(frames, sparse.T)  # eq. (11)
        coefficients = rows @ basis.T
        sparse = _truncate_rows(coefficients, sparsity)  # eq. (8)
        objective.append(float(np.sum((coefficients - sparse) ** 2)))
        previous, current = objective[-2], objective[-1]
        if previous - current <= tol * previous:
            converged = True
            break
    return LsdtResult(basis=basis, objective=np.array(objective), converged=converged)


def train_lsdt_bases(
    positions: np.ndarray,
    sparsity: int,
    *,
    init: str = "dct",
    max_iterations: int = 500,
    tol: float = 1e-9,
) -> tuple[np.ndarray, list[LsdtResult]]:
    """Learn one LSDT basis per coordinate x, y, z from training frames (§4, §5.1).

    Parameters
    ----------
    positions : ndarray, shape (N, J, 3), float, cm
        Training frames (joint positions); frames of several clips may simply be concatenated.
    sparsity, init, max_iterations, tol
        As in :func:`train_lsdt`.

    Returns
    -------
    bases : ndarray, shape (3, J, J), float64
        ``bases[d]`` is ``B^d``.
    results : list of LsdtResult
        The per-coordinate training records (objective per iteration).
    """
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 3 or positions.shape[2] != 3 or positions.shape[0] < 1:
        raise ValueError(f"Expected `positions` to have shape (N, J, 3) with N >= 1, got {positions.shape}.")
    results = [
        train_lsdt(positions[:, :, d].T, sparsity, init=init, max_iterations=max_iterations, tol=tol)
        for d in range(3)
    ]
    return np.stack([result.basis for result in results]), results
