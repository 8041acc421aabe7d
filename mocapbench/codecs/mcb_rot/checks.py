"""What the ``mcb-rot`` encoder checks on every frame: joint position errors, end-site errors and, with a shell,
ACL's vertex errors.

The shell error of joint ``k`` is :mod:`mocapbench.metrics.shell`'s: the largest displacement of the three virtual
vertices at distance ``d`` along ``k``'s global axes, ``|d (R_ref - R_dec) e_i + (p_ref - p_dec)|``. The encoder's
closed loop keeps ``max(joint error, shell error)`` within the bound; the final check of the encoder is the metric
itself on the decoded :class:`~mocapbench.motion.Motion`.

End sites (the tips a viewer draws: head top, fingers, toes) are carried by their joint's frame: an end site's error
counts as its joint's, so a joint misses when one of its end sites does, and the closed loop corrects the rotations
that move it (the joint's own among them, :mod:`.budgets`). A game rig's translated joints step from their parent by
their decoded translation of the frame instead of their offset, in forward kinematics as in the decoder. A scaled
rig's joints (:mod:`.scales`) are placed with the decoded scales, by the matrix forward kinematics of
:class:`~mocapbench.motion.Motion` (the decoder's for such a stream), so the loop sees the scale error too.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from mocapbench.codecs.mcb_rot import quaternions as quat
from mocapbench.codecs.mcb_rot.kinematics import compose
from mocapbench.motion import Skeleton, _forward_kinematics, _tree_levels

__all__ = ["PointTargets", "forward_kinematics", "global_quaternions", "tree_levels"]


def tree_levels(parents: np.ndarray) -> list[np.ndarray]:
    """The joints at tree depth 0 (the root), 1, 2, ... of a parent array (J,) (parents before children).

    Cached per tree (the closed loop asks for them every round); the arrays returned are shared: do not modify them.
    """
    return _levels(np.asarray(parents, dtype=np.int64).tobytes())


@lru_cache(maxsize=64)
def _levels(key: bytes) -> list[np.ndarray]:
    parents = np.frombuffer(key, dtype=np.int64)
    depth = np.zeros(len(parents), dtype=np.int64)
    for joint in range(1, len(parents)):
        depth[joint] = depth[parents[joint]] + 1
    levels = [np.flatnonzero(depth == d) for d in range(int(depth.max(initial=0)) + 1)]
    for level in levels:
        level.setflags(write=False)
    return levels


def global_quaternions(quats: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Global rotations (F, J, 4) of local rotations ``quats`` (F, J, 4), one product per tree depth."""
    glob = np.array(quats, dtype=np.float64)
    for joints in tree_levels(parents)[1:]:
        glob[:, joints] = quat.multiply(glob[:, parents[joints]], quats[:, joints])
    return glob


_ROLL1, _ROLL2 = [1, 2, 0], [2, 0, 1]  # a x b = a[_ROLL1] b[_ROLL2] - a[_ROLL2] b[_ROLL1] on component-major arrays


def _plan(parents: np.ndarray) -> tuple[list, list]:
    """Per tree depth 1, 2, ...: (joints, their parents) of every joint and of the joints with children (cached)."""
    key = np.asarray(parents, dtype=np.int64).tobytes()
    if key not in _PLANS:
        has_children = np.zeros(len(parents), dtype=bool)
        has_children[parents[1:]] = True
        every, inner = [], []
        for joints in tree_levels(parents)[1:]:
            every.append((joints, parents[joints]))
            if has_children[joints].any():
                inner.append((joints[has_children[joints]], parents[joints[has_children[joints]]]))
        _PLANS[key] = (every, inner)
    return _PLANS[key]


_PLANS: dict = {}


def forward_kinematics(quats: np.ndarray, roots: np.ndarray, skeleton: Skeleton,
                       leaves: bool = True, translations: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Joint positions (n, J, 3) cm and global rotations (n, J, 4) of local rotations ``quats`` (n, J, 4) and root
    positions ``roots`` (n, 3) cm, one tree depth at a time; without ``leaves`` the global rotations of the joints
    without children are left at zero (they move no joint: only the shell reads them).

    The closed loop's forward kinematics: it needs the global rotations of every joint too (to score corrections
    and for the shell), which the decoder's :func:`.kinematics.positions` does not keep. Component-major (4, J, n)
    arrays with x, y, z stacked, as there (a few numpy calls per depth; the loop runs on few frames, where the calls
    cost more than the arithmetic). Its positions are the decoder's bit for bit (the same operations in the same
    order; a test checks it), and the encoder's final check decodes with the decoder's. The results are transposed
    views. ``translations`` (n, J, 3) cm: every joint's step from its parent on each frame (the offsets for the joints
    that do not move, so each joint's arithmetic is the decoder's with its offset or its translation).
    """
    parents, offsets = skeleton.parents, skeleton.offsets
    every, inner = _plan(parents)
    local = np.ascontiguousarray(np.moveaxis(quats, -1, 0).swapaxes(1, 2))  # (4, J, n)
    glob = np.empty(local.shape) if leaves else np.zeros(local.shape)
    glob[:, 0] = local[:, 0]
    for joints, above in every if leaves else inner:  # global rotations, a depth at a time
        glob[:3, joints], glob[3, joints] = compose(np.take(glob, above, axis=1), np.take(local, joints, axis=1))
    positions = np.empty((3,) + local.shape[1:])
    positions[:, 0] = roots.T
    if len(parents) > 1:  # every bone's offset turned into the world frame by its parent, in one step
        p = np.take(glob, parents[1:], axis=1)
        pv, pw = p[:3], p[3]
        p1, p2 = pv[_ROLL1], pv[_ROLL2]
        if translations is None:
            v = offsets[1:].T[:, :, None]  # (3, J - 1, 1)
        else:
            v = np.ascontiguousarray(translations[:, 1:].transpose(2, 1, 0))  # (3, J - 1, n)
        t = p1 * (2.0 * v[_ROLL2])
        t -= p2 * (2.0 * v[_ROLL1])  # 2 u x v
        turned = p1 * t[_ROLL2]
        turned -= p2 * t[_ROLL1]  # u x t
        t *= pw
        turned += t
        turned += v
        for joints, above in every:
            positions[:, joints] = np.take(positions, above, axis=1) + np.take(turned, joints - 1, axis=1)
    return positions.transpose(2, 1, 0), glob.transpose(2, 1, 0)


class PointTargets:
    """The original motion's checked points: joint positions (F, J, 3) cm, with ``ends`` its end-site positions
    (F, E, 3) cm, and with a shell of ``shell_cm`` > 0 its vertices' offsets from their joints, ``d R e_i`` as
    (F, J, 3, 3) (column i: vertex i). ``translations`` (F, J, 3) cm: the decoded steps of every joint from its parent
    (the stream's translation tracks; None: the skeleton's offsets), with which the decoded points are placed.
    ``scales`` (F, J, 3): the decoded scale of every joint (the stream's scale tracks; None: unscaled); no shell
    then."""

    def __init__(self, positions: np.ndarray, rotations: np.ndarray, skeleton: Skeleton, shell_cm: float,
                 ends: np.ndarray | None = None, translations: np.ndarray | None = None,
                 scales: np.ndarray | None = None) -> None:
        self.positions = positions
        self.skeleton = skeleton
        self.shell_cm = float(shell_cm)
        self.vertices = None
        if self.shell_cm > 0:
            self.vertices = self.shell_cm * quat.as_matrix(global_quaternions(rotations, skeleton.parents))
        self.ends = None if ends is None or len(skeleton.end_site_parents) == 0 else ends
        self.translations = translations
        self.scales = scales
        if scales is not None and self.shell_cm > 0:
            raise ValueError("PointTargets: no shell on a scaled rig.")

    def tiled(self, count: int) -> "PointTargets":
        """The same targets repeated ``count`` times along the frames (frame ``f`` of copy ``k`` is ``k F + f``): what
        the closed loop checks when it refines several attempts of one motion side by side."""
        tiled = object.__new__(PointTargets)
        tiled.skeleton, tiled.shell_cm = self.skeleton, self.shell_cm
        tiled.positions = np.tile(self.positions, (count, 1, 1))
        tiled.vertices = None if self.vertices is None else np.tile(self.vertices, (count, 1, 1, 1))
        tiled.ends = None if self.ends is None else np.tile(self.ends, (count, 1, 1))
        tiled.translations = None if self.translations is None else np.tile(self.translations, (count, 1, 1))
        tiled.scales = None if self.scales is None else np.tile(self.scales, (count, 1, 1))
        return tiled

    def errors(self, frames: np.ndarray, quats: np.ndarray, roots: np.ndarray) -> np.ndarray:
        """(n, J) error of every joint at ``frames`` (cm) for decoded ``quats`` (n, J, 4), ``roots`` (n, 3): the joint's
        position error, or with a shell the larger of it and its vertices' errors."""
        return self.evaluate(frames, quats, roots)[0]

    def evaluate(self, frames: np.ndarray, quats: np.ndarray, roots: np.ndarray) -> tuple[np.ndarray, ...]:
        """:meth:`errors`, the decoded joint positions (n, J, 3) cm and global rotations (n, J, 4)."""
        translations = None if self.translations is None else self.translations[frames]
        if self.scales is not None:
            return self._evaluate_scaled(frames, quats, roots, translations)
        decoded, glob = forward_kinematics(quats, roots, self.skeleton,
                                           leaves=self.vertices is not None or self.ends is not None,
                                           translations=translations)
        return self.errors_of(frames, decoded, glob), decoded, glob

    def _evaluate_scaled(self, frames: np.ndarray, quats: np.ndarray, roots: np.ndarray,
                         translations: np.ndarray | None) -> tuple[np.ndarray, ...]:
        """:meth:`evaluate` with the decoded scales: positions and end sites by the matrix forward kinematics
        (:class:`~mocapbench.motion.Motion`'s); the global rotations returned are the products of the local rotations
        (what the closed loop scores corrections with, to first order)."""
        skeleton = self.skeleton
        levels, ancestors = _tree_levels(skeleton.parents)
        matrices, decoded = _forward_kinematics(quats, roots, skeleton, levels, ancestors, translations=translations,
                                                scales=self.scales[frames])
        squared = np.sum((self.positions[frames] - decoded) ** 2, axis=-1)
        if self.ends is not None:
            parents = skeleton.end_site_parents
            placed = decoded[:, parents] + np.einsum("fejk,ek->fej", matrices[:, parents], skeleton.end_site_offsets)
            np.maximum.at(squared.T, parents, np.sum((self.ends[frames] - placed) ** 2, axis=-1).T)
        return np.sqrt(squared), decoded, global_quaternions(quats, skeleton.parents)

    def errors_of(self, frames: np.ndarray, decoded: np.ndarray, glob: np.ndarray) -> np.ndarray:
        """:meth:`errors` from the decoded joint positions (n, J, 3) cm and global rotations (n, J, 4)."""
        moved = self.positions[frames] - decoded  # (n, J, 3)
        x, y, z = moved[..., 0], moved[..., 1], moved[..., 2]
        squared = x * x + y * y + z * z
        if self.vertices is not None:
            axes = self.shell_cm * quat.as_matrix(glob)
            displacement = self.vertices[frames] - axes + moved[..., :, None]  # (n, J, 3 coords, 3 vertices)
            squared = np.maximum(squared, np.sum(displacement**2, axis=-2).max(axis=-1))
        if self.ends is not None:  # an end site's error is its joint's
            parents = self.skeleton.end_site_parents
            placed = decoded[:, parents] + quat.rotate(glob[:, parents], self.skeleton.end_site_offsets)
            missed = self.ends[frames] - placed
            np.maximum.at(squared.T, parents, np.sum(missed**2, axis=-1).T)
        return np.sqrt(squared)
