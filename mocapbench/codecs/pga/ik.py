"""PGA-based inverse kinematics (Tournier et al. 2008, §3.4 and §3.6).

The map ``f : R^k -> R^{3d}`` sends geodesic coordinates x to the positions of the d end joints in the root's
frame: ``f = g ∘ h`` with ``h(x) = mu · prod_j exp(x_j v_j)`` the pose model (§3.3) and g forward kinematics
with the root at the origin and unrotated. Each frame solves (§3.6)::

    x* = argmin_x ||f(x) - y0||^2 + lambda ||x - x_prev||^2

by Levenberg–Marquardt warm-started from the previous frame's solution.

Jacobian (analytic, chain rule, no finite differences). The paper writes ``dh/dx_j = v_j``; for the product
of exponentials that holds in the frame of the partial product ``mu e^{x_1 v_1} ... e^{x_j v_j}``. In the body
frame of the full local rotation ``R_J = h(x)_J`` it is ``omega_jJ = S_jJ^T v_jJ`` with the suffix product
``S_jJ = exp(x_{j+1} v_{j+1,J}) ... exp(x_k v_kJ)`` (equal to ``v_jJ`` when the later coordinates are zero).
With ``G_J`` the global rotation and ``p_J`` the position of joint J, end joint e moves as
``dp_e/dx_j = sum_{J ancestor of e} (G_J omega_jJ) x (p_e - p_J)``.

Speed: only the joints on the chains from the root to the end joints are evaluated; one evaluation costs a
batched Rodrigues over (k, chain joints), a log2(k)-step parallel suffix scan of 3x3 products, one batched
product per tree depth and a few array operations for the Jacobian: all numpy, no per-joint Python loop.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from mocapbench.lazy_imports import Rotation

from mocapbench.codecs.pga.so3 import skew
from mocapbench.motion import Skeleton

__all__ = ["GeodesicIK", "to_root_frame", "from_root_frame"]


def to_root_frame(root_rotations: np.ndarray, root_positions: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Express global points in the root joint's frame: ``R_root^T (p - root)``.

    Parameters
    ----------
    root_rotations : ndarray, shape (F, 4), quaternions
    root_positions : ndarray, shape (F, 3), cm
    points : ndarray, shape (F, d, 3), cm

    Returns
    -------
    ndarray, shape (F, d, 3), cm
    """
    inverse = Rotation.from_quat(np.asarray(root_rotations)[:, None, :]).inv()
    return inverse.apply(np.asarray(points) - np.asarray(root_positions)[:, None, :])


def from_root_frame(root_rotations: np.ndarray, root_positions: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_root_frame`: ``R_root p + root``, shapes as there."""
    rotation = Rotation.from_quat(np.asarray(root_rotations)[:, None, :])
    return rotation.apply(np.asarray(points)) + np.asarray(root_positions)[:, None, :]


class GeodesicIK:
    """IK on the k principal geodesics of a pose model, for d end joints.

    Parameters
    ----------
    skeleton : Skeleton
        J joints; joint 0 is the root, joints 1..J-1 are the modelled inner joints (n = J - 1).
    mean : ndarray, shape (n, 4)
        Intrinsic mean of the inner joints' local rotations (quaternions).
    directions : ndarray, shape (k, n, 3)
        Principal geodesic directions ``v_j`` per inner joint, rad per unit coordinate.
    end_joints : sequence of int, length d
        Skeleton indices of the constrained end joints (distinct, not the root).
    """

    def __init__(self, skeleton: Skeleton, mean: np.ndarray, directions: np.ndarray, end_joints: Sequence[int]):
        mean, directions, ends = _checked_model(skeleton, mean, directions, end_joints)
        parents = skeleton.parents
        self.skeleton = skeleton
        self.end_joints = tuple(ends)
        self.num_geodesics = directions.shape[0]
        # Joints whose rotation moves an end joint: the strict ancestors of the ends, the root excepted.
        ancestors_of = _end_chains(parents, ends)
        rotating = sorted({j for chain in ancestors_of.values() for j in chain})
        nodes = sorted({0, *rotating, *ends})  # the joints the IK evaluates, parents before children
        compact = {j: c for c, j in enumerate(nodes)}
        node_parent = np.array([0] + [compact[int(parents[j])] for j in nodes[1:]], dtype=np.int64)
        self._end_compact = np.array([compact[e] for e in ends], dtype=np.int64)
        self._node_parent = node_parent
        self._offsets = np.ascontiguousarray(skeleton.offsets[nodes].T)  # (3, c), cm
        self._set_tree(node_parent)
        self._set_pairs(ends, ancestors_of, compact)
        self._set_model(nodes, rotating, mean, directions)

    def _set_tree(self, node_parent: np.ndarray) -> None:
        """The pointer-jumping steps and the ancestor matrix of the evaluated nodes."""
        num_nodes = len(node_parent)
        # Global rotations by pointer jumping: after step s a node holds the product of the locals of itself and
        # its 2^s - 1 nearest ancestors; ceil(log2(depth + 1)) steps reach the root for every node.
        depth = np.zeros(num_nodes, dtype=np.int64)
        ancestors = np.eye(num_nodes)
        for c in range(1, num_nodes):
            depth[c] = depth[node_parent[c]] + 1
            ancestors[c] += ancestors[node_parent[c]]
        self._jumps = []
        pointer = node_parent.copy()
        for _ in range(int(depth.max()).bit_length()):
            self._jumps.append(pointer.copy())
            pointer = pointer[pointer]
        ancestors[:, 0] = 0.0  # the root's step is the root position, 0 in the root frame
        self._ancestors_t = np.ascontiguousarray(ancestors.T)  # pos = steps @ ancestors^T

    def _set_pairs(self, ends: list[int], ancestors_of: dict[int, list[int]], compact: dict[int, int]) -> None:
        """(end, rotating ancestor) pairs for the Jacobian, and the (pairs, d) summing matrix."""
        pairs = [(i, compact[j]) for i, e in enumerate(ends) for j in ancestors_of[e]]
        self._pair_end = np.array([self._end_compact[i] for i, _ in pairs], dtype=np.int64)
        self._pair_joint = np.array([c for _, c in pairs], dtype=np.int64)
        self._pair_sum_t = np.zeros((len(pairs), len(ends)))
        for p, (i, _) in enumerate(pairs):
            self._pair_sum_t[p, i] = 1.0

    def _set_model(self, nodes: list[int], rotating: list[int], mean: np.ndarray, directions: np.ndarray) -> None:
        """The mean rotations and the geodesics' Rodrigues terms on every evaluated node."""
        num_nodes = len(nodes)
        # The model on every evaluated node, component-major ((3, 3, ...) and (3, ...): at these sizes explicit
        # 3x3 products over contiguous component arrays are ~3x faster than batched matmul). Nodes whose
        # rotation moves no end joint (the root, leaf end joints) get the identity and zero directions.
        moving = np.array([j in set(rotating) for j in nodes])
        inner = np.array(nodes) - 1
        mean_matrices = np.tile(np.eye(3), (num_nodes, 1, 1))
        if moving.any():
            mean_matrices[moving] = Rotation.from_quat(mean[inner[moving]]).as_matrix()
        self._mean = np.ascontiguousarray(mean_matrices.transpose(1, 2, 0))  # (3, 3, c)
        v = np.zeros((self.num_geodesics, num_nodes, 3))
        v[:, moving] = directions[:, inner[moving]]
        self._theta = np.linalg.norm(v, axis=-1)  # (k, c)
        axes = v / np.where(self._theta > 0, self._theta, 1.0)[..., None]
        k1 = skew(axes)
        self._k1 = np.ascontiguousarray(k1.transpose(2, 3, 0, 1))  # (3, 3, k, c)
        self._k2 = np.ascontiguousarray((k1 @ k1).transpose(2, 3, 0, 1))
        self._v = np.ascontiguousarray(v.transpose(2, 0, 1))  # (3, k, c)
        self._eye = np.eye(3)[:, :, None, None]

    # -- forward model ------------------------------------------------------------------------------
    @staticmethod
    def _mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """3x3 products of component-major stacks: ``(3, 3, ...) x (3, 3, ...)``."""
        return a[:, 0:1] * b[0:1] + a[:, 1:2] * b[1:2] + a[:, 2:3] * b[2:3]

    def _evaluate(self, x: np.ndarray, with_jacobian: bool):
        k = self.num_geodesics
        mul = self._mul
        angles = x[:, None] * self._theta
        # E_j = exp(x_j v_jJ) by Rodrigues, (3, 3, k, c)
        suffix = self._eye + np.sin(angles) * self._k1 + (1.0 - np.cos(angles)) * self._k2
        step = 1
        while step < k:  # Hillis–Steele inclusive suffix scan: suffix[j] = E_j E_{j+1} ... E_k
            suffix[:, :, : k - step] = mul(suffix[:, :, : k - step], suffix[:, :, step:])
            step *= 2
        glob = mul(self._mean, suffix[:, :, 0])  # local R_J = mu_J E_1 ... E_k, (3, 3, c)
        for pointer in self._jumps:
            glob = mul(glob[:, :, pointer], glob)
        g = glob[:, :, self._node_parent]  # parent's global rotation applied to the offsets
        o = self._offsets
        steps = g[:, 0] * o[0] + g[:, 1] * o[1] + g[:, 2] * o[2]  # (3, c)
        pos = steps @ self._ancestors_t
        ends = pos[:, self._end_compact].T
        if not with_jacobian:
            return ends, None
        # Body-frame angular velocity of R_J along x_j: S_j^T v_j, S_j = suffix[j + 1] (identity for j = k).
        v = self._v
        omega = v.copy()
        if k > 1:
            s = suffix[:, :, 1:]
            omega[:, :-1] = s[0] * v[0:1, :-1] + s[1] * v[1:2, :-1] + s[2] * v[2:3, :-1]
        g = glob[:, :, None, self._pair_joint]  # (3, 3, 1, pairs)
        om = omega[:, :, self._pair_joint]  # (3, k, pairs)
        w = g[:, 0] * om[0] + g[:, 1] * om[1] + g[:, 2] * om[2]  # G_J omega_jJ in the root frame
        lever = (pos[:, self._pair_end] - pos[:, self._pair_joint])[:, None, :]  # (3, 1, pairs)
        cross = np.stack(
            [
                w[1] * lever[2] - w[2] * lever[1],
                w[2] * lever[0] - w[0] * lever[2],
                w[0] * lever[1] - w[1] * lever[0],
            ]
        )  # (3, k, pairs)
        jacobian = (cross @ self._pair_sum_t).transpose(2, 0, 1).reshape(-1, k)  # (3d, k)
        return ends, jacobian

    def forward(self, x: np.ndarray) -> np.ndarray:
        """End-joint positions in the root frame for geodesic coordinates ``x`` (k,): ``(d, 3)`` cm."""
        return self._evaluate(np.asarray(x, dtype=np.float64), False)[0]

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """Analytic Jacobian ``df/dx`` at ``x``: ``(3d, k)``, cm per unit coordinate (rows: end, then x/y/z)."""
        return self._evaluate(np.asarray(x, dtype=np.float64), True)[1]

    # -- solver -------------------------------------------------------------------------------------
    def solve(
        self,
        target: np.ndarray,
        x_prev: np.ndarray,
        lam: float,
        iterations: int,
        *,
        tol: float = 1e-5,
        start: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """One frame: Levenberg–Marquardt on ``||f(x) - y0||^2 + lam ||x - x_prev||^2`` from ``x_prev``.

        Parameters
        ----------
        target : ndarray, shape (d, 3), cm
            End-joint positions y0 in the root frame.
        x_prev : ndarray, shape (k,)
            Previous frame's coordinates: the starting point and the anchor of the smoothness term.
        lam : float, cm^2 per unit coordinate^2
            Weight of the smoothness term (the paper uses 1).
        iterations : int
            Maximum LM iterations (each costs one evaluation of f and its Jacobian).
        tol : float
            Stop once an accepted step is shorter than this (max-norm, units of x).
        start : (ends (d, 3), jacobian (3d, k)), optional
            f and its Jacobian at ``x_prev`` if known (the previous frame's result): saves one evaluation.

        Returns
        -------
        x : ndarray, shape (k,)
        state : (ends, jacobian) at x, to pass as ``start`` to the next frame.
        """
        y0 = np.asarray(target, dtype=np.float64).reshape(-1)
        anchor = np.asarray(x_prev, dtype=np.float64)
        x = anchor.copy()
        ends, jac = self._evaluate(x, True) if start is None else start
        residual = ends.reshape(-1) - y0
        cost = residual @ residual  # x = x_prev: the smoothness term is 0
        damping = 1e-3
        # (+1e-9: keeps the system solvable when lam = 0 and a direction moves no end joint)
        regularizer = (lam + 1e-9) * np.eye(self.num_geodesics)
        for _ in range(iterations):
            hessian = jac.T @ jac + regularizer
            gradient = jac.T @ residual + lam * (x - anchor)
            step = np.linalg.solve(hessian + damping * np.diag(np.diag(hessian)), -gradient)
            trial = x + step
            trial_ends, trial_jac = self._evaluate(trial, True)
            trial_residual = trial_ends.reshape(-1) - y0
            delta = trial - anchor
            trial_cost = trial_residual @ trial_residual + lam * (delta @ delta)
            if trial_cost < cost:
                x, ends, jac, residual, cost = trial, trial_ends, trial_jac, trial_residual, trial_cost
                damping = max(damping * 0.3, 1e-9)
                if np.max(np.abs(step)) < tol:
                    break
            else:
                damping *= 10.0
        return x, (ends, jac)

    def solve_sequence(
        self, targets: np.ndarray, lam: float, iterations: int, first_iterations: int | None = None
    ) -> np.ndarray:
        """Every frame in order, each warm-started from the previous solution (the first from x = 0, the mean pose).

        Frame 0 has no previous frame: it starts from the mean pose with a weak anchor there (``1e-3 lam``,
        enough to keep the problem well posed when k > 3d, too weak to bias the solution).

        Parameters
        ----------
        targets : ndarray, shape (F, d, 3), cm, in the root frame
        lam : float
        iterations : int
            LM iterations per frame.
        first_iterations : int, optional
            LM iterations for frame 0, which starts from the mean pose (default ``10 * iterations``).

        Returns
        -------
        ndarray, shape (F, k)
        """
        targets = np.asarray(targets, dtype=np.float64)
        if targets.ndim != 3 or targets.shape[1:] != (len(self.end_joints), 3):
            raise ValueError(f"Expected `targets` of shape (F, {len(self.end_joints)}, 3), got {targets.shape}.")
        out = np.zeros((targets.shape[0], self.num_geodesics))
        x = np.zeros(self.num_geodesics)
        state = None
        first = 10 * iterations if first_iterations is None else first_iterations
        for frame in range(targets.shape[0]):
            if frame == 0:
                x, state = self.solve(targets[0], x, 1e-3 * lam, first)
            else:
                x, state = self.solve(targets[frame], x, lam, iterations, start=state)
            out[frame] = x
        return out


def _checked_model(skeleton: Skeleton, mean, directions, end_joints: Sequence[int]):
    """``mean`` (J - 1, 4) and ``directions`` (k >= 1, J - 1, 3) as float64, and the end joints as a list of
    distinct indices in 1..J-1; anything else is a ``ValueError`` naming the argument."""
    num_inner = skeleton.num_joints - 1
    mean = np.asarray(mean, dtype=np.float64)
    directions = np.asarray(directions, dtype=np.float64)
    if mean.shape != (num_inner, 4):
        raise ValueError(f"Expected `mean` of shape ({num_inner}, 4), got {mean.shape}.")
    if directions.ndim != 3 or directions.shape[1:] != (num_inner, 3) or directions.shape[0] < 1:
        raise ValueError(f"Expected `directions` of shape (k >= 1, {num_inner}, 3), got {directions.shape}.")
    ends = [int(e) for e in end_joints]
    if not ends or len(set(ends)) != len(ends) or min(ends) < 1 or max(ends) >= skeleton.num_joints:
        raise ValueError(
            f"`end_joints` must be distinct joint indices in 1..{skeleton.num_joints - 1}, got {ends}."
        )
    return mean, directions, ends


def _end_chains(parents: np.ndarray, ends: list[int]) -> dict[int, list[int]]:
    """For each end joint, its strict ancestors below the root, nearest first."""
    chains = {}
    for e in ends:
        chain, j = [], int(parents[e])
        while j > 0:
            chain.append(j)
            j = int(parents[j])
        chains[e] = chain
    return chains
