"""Forward kinematics on quaternions, component-major: the decoder's hot loop.

Equal to :meth:`mocapbench.motion.Motion.positions` up to float rounding (~1e-13 cm), several times faster. Two
steps on (4, J, F) arrays whose components are contiguous:

1. the global rotations of the joints that have children, one quaternion product per tree depth (a leaf's global
   rotation moves nothing: it is never computed);
2. every bone's offset turned by its parent's global rotation, all bones in one vectorized step, then the
   positions a depth at a time: each joint's is its parent's plus its turned offset (elementwise, so the result
   does not depend on how many frames are decoded together, as a BLAS product's summation order may).

The encoder verifies its bound on these positions, so the guarantee is about exactly what the decoder returns.
"""

from __future__ import annotations

import numpy as np

from mocapbench.codecs.mcb_rot.scratch import Scratch
from mocapbench.motion import Skeleton

__all__ = ["compose", "positions"]


_PLANS: dict[tuple[bytes, bytes], tuple] = {}  # plans of recent skeletons
_R1, _R2 = [1, 2, 0], [2, 0, 1]  # (y, z, x) and (z, x, y): a x b = a[_R1] b[_R2] - a[_R2] b[_R1]
#: Components gathered for a product, in this order (10 rows): x y z w, then x y z by _R1, then by _R2.
_ROWS = np.array([0, 1, 2, 3] + _R1 + _R2)
#: Up to this many frames, the positions are summed down each joint's whole path at once (D times the additions of
#: the depth-by-depth loop, D the tree depth, but 4 numpy calls instead of 3 D).
_PATH_FRAMES = 16


def _plan(parents: np.ndarray, offsets: np.ndarray) -> tuple:
    """The levels, bones and chain matrix of a skeleton (cached by tree and offsets).

    Returns ``(levels, bone_rows, v, v2a, v2b, depths, paths)``: ``levels`` lists, per tree depth 1, 2, ..., the joints
    with children at that depth, their parents, and the rows of the flattened (4 J, F) arrays to gather for a
    product (:data:`_ROWS`: the parents' rows of the global rotations, the joints' rows of the local ones);
    ``bone_rows`` those rows of the parents of joints 1..J-1; ``v`` (3, J - 1, 1) their offsets, cm, with ``2 v``
    rotated for the cross products; ``depths`` lists, per tree depth, all its joints and their parents; ``paths``
    is (D + 1, the (J, D + 1) root-first path of every joint flattened, where each joint's running sum ends).
    """
    key = (np.asarray(parents, dtype=np.int64).tobytes(), np.asarray(offsets).tobytes())
    if key not in _PLANS:
        if len(_PLANS) > 64:
            _PLANS.clear()
        num_joints = len(parents)
        depth = np.zeros(num_joints, dtype=np.int64)
        for j in range(1, num_joints):  # parents come before their children
            depth[j] = depth[parents[j]] + 1
        has_children = np.zeros(num_joints, dtype=bool)
        has_children[parents[1:]] = True
        levels, depths = [], []
        for d in range(1, int(depth.max(initial=0)) + 1):
            inner = np.flatnonzero((depth == d) & has_children)
            if inner.size:  # rows of the flattened (4 J, F) arrays: components x y z w, then _R1, then _R2
                rows = _ROWS[:, None] * num_joints
                levels.append((inner, parents[inner], (rows + parents[inner]).ravel(), (rows + inner).ravel()))
            joints = np.flatnonzero(depth == d)
            depths.append((joints, parents[joints]))
        rows = _ROWS[:, None] * num_joints
        bone_rows = (rows + np.asarray(parents[1:], dtype=np.int64)).ravel()  # (10 (J - 1),) rows of (4 J, F)
        v = np.asarray(offsets[1:], dtype=np.float64).T[:, :, None]  # (3, J - 1, 1)
        v2 = 2.0 * v
        # Each joint's path from the root (its joints' indices, padded with 0 past the joint's depth) and where its
        # sum of the path's terms ends in the flattened (J, D + 1) array of running sums.
        paths = [[0]]
        for j in range(1, num_joints):
            paths.append(paths[parents[j]] + [j])
        span = int(depth.max(initial=0)) + 1
        path_joints = np.array([path + [0] * (span - len(path)) for path in paths], dtype=np.int64).ravel()
        path_ends = np.arange(num_joints) * span + depth
        _PLANS[key] = (levels, bone_rows, v, v2[_R2], v2[_R1], depths, (span, path_joints, path_ends))
    return _PLANS[key]


def compose(p: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quaternion products ``p b`` of component-major arrays ``p``, ``b`` (4, ...) (x, y, z, w first): returns the
    vector parts (3, ...) and the scalar parts (...). ``p`` must be a copy (a fancy-indexed gather): it is reused."""
    pv, pw = p[:3], p[3]
    bv, bw = b[:3], b[3]
    xyz = pv[_R1] * bv[_R2]
    xyz -= pv[_R2] * bv[_R1]
    xyz += pw * bv
    xyz += bw * pv
    pv *= bv
    return xyz, pw * bw - pv.sum(axis=0)


def positions(
    quats: np.ndarray, roots: np.ndarray, skeleton: Skeleton, out: np.ndarray | None = None, scratch: Scratch | None = None
) -> np.ndarray:
    """Global joint positions (F, J, 3) cm of local rotations ``quats`` (F, J, 4), unit, and ``roots`` (F, 3) cm.

    Written into ``out`` (F, J, 3) when given (and returned); ``scratch`` then holds the work arrays. ``quats`` laid
    out as a transposed (4, J, F) array (what :func:`.stream.assemble` returns) is read without a copy. The x, y, z
    components go through each step as one (3, n, F) array (cross products by rolling the component axis).
    """
    num_frames, num_joints, _ = quats.shape
    local = np.ascontiguousarray(quats.transpose(2, 1, 0))  # (4, J, F)
    reuse = scratch is not None and out is not None
    levels, bone_rows, v, v2a, v2b, depths, (span, path_joints, path_ends) = _plan(skeleton.parents, skeleton.offsets)
    glob = scratch.take("glob", local.shape) if reuse else np.empty_like(local)
    glob[:, 0] = local[:, 0]
    flat_glob, flat_local = glob.reshape(-1, num_frames), local.reshape(-1, num_frames)
    for inner, parents, parent_rows, inner_rows in levels:  # global rotations of the joints with children, by depth
        # Each factor gathered once into a C-contiguous (10, n, F) array: its components and the two rotations of
        # its vector part that the cross product reads (compose's fancy-index copies, as views).
        width = len(inner)
        p = np.take(flat_glob, parent_rows, axis=0).reshape(10, width, num_frames)
        b = np.take(flat_local, inner_rows, axis=0).reshape(10, width, num_frames)
        xyz = p[4:7] * b[7:10]  # as compose: p[_R1] b[_R2] - p[_R2] b[_R1] + pw bv + bw pv
        xyz -= p[7:10] * b[4:7]
        xyz += p[3] * b[:3]
        xyz += b[3] * p[:3]
        glob[:3, inner] = xyz
        glob[3, inner] = p[3] * b[3] - np.add.reduce(p[:3] * b[:3], axis=0)
    result = scratch.take("fk", (3, num_joints, num_frames)) if reuse else np.empty((3, num_joints, num_frames))
    if num_joints > 1:  # (leaves only the root, whose position is ``roots``)
        # Bone-sized temporaries (a few hundred KB on a 465-frame clip) would be mapped and page-faulted afresh on
        # every call: with ``scratch`` they are its reused buffers.
        shape = (3, num_joints - 1, num_frames)
        work = (lambda name: scratch.take(name, shape)) if reuse else (lambda name: np.empty(shape))
        rows = (10, num_joints - 1, num_frames)  # components x y z w, then x y z by _R1, then by _R2
        p = np.take(glob.reshape(-1, num_frames), bone_rows, axis=0, mode="clip",
                    out=scratch.take("bone parents", (10 * (num_joints - 1), num_frames)) if reuse else None).reshape(rows)
        p1, p2, pw = p[4:7], p[7:10], p[3]
        rolled = scratch.take("t", (5,) + shape[1:]) if reuse else np.empty((5,) + shape[1:])
        t, turned, other = rolled[:3], work("turned"), work("other")
        np.multiply(p1, v2a, out=t)
        t -= np.multiply(p2, v2b, out=other)  # t = 2 q x v
        rolled[3:] = t[:2]  # t rolled by _R1 is rolled[1:4], by _R2 rolled[2:5]
        np.multiply(p1, rolled[2:5], out=turned)
        turned -= np.multiply(p2, rolled[1:4], out=other)  # q x t
        t *= pw
        turned += t
        turned += v  # v + w t + q x t: each bone's offset turned into the world frame
    result[:, 0] = roots.T
    if num_joints > 1 and num_frames <= _PATH_FRAMES:
        # A few frames (random access): every joint's root + turned offsets down its path as one running sum,
        # the same additions in the same order as the loop below, in 4 calls instead of 3 per tree depth.
        terms = np.concatenate([result[:, :1], turned], axis=1)  # (3, J, F): the root, then each joint's offset
        sums = np.take(terms, path_joints, axis=1).reshape(3, num_joints, span, num_frames)
        np.cumsum(sums, axis=2, out=sums)
        np.take(sums.reshape(3, num_joints * span, num_frames), path_ends, axis=1, out=result)
    else:
        for joints, parents in depths:  # each joint: its parent's position plus its turned offset
            result[:, joints] = np.take(result, parents, axis=1) + np.take(turned, joints - 1, axis=1)
    if out is None:
        return result.transpose(2, 1, 0)
    out[...] = result.transpose(2, 1, 0)
    return out
