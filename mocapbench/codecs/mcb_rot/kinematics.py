"""Forward kinematics on quaternions, component-major: the decoder's hot loop, compiled with numba.

One pass over the joints in tree order (parents come before their children), each over all frames: the joint's
offset turned by its parent's global rotation and added to its parent's position, then its own global rotation,
the parent's times its local one. The arithmetic is the closed loop's (:func:`.checks.forward_kinematics`, numpy on
component-major arrays) operation for operation: ``t = 2 q x v``, ``v + w t + q x t`` summed in that order, the
products as :func:`compose`; numba compiles IEEE operations one for one (no fused multiply-adds, no reassociation
without ``fastmath``), so the decoder's positions are bit-identical to the ones the encoder's closed loop scores
(a test checks it), and equal to :meth:`mocapbench.motion.Motion.positions` up to float rounding (~1e-13 cm).

Why compiled: in numpy the same steps are about 100 calls per block on arrays of one tree depth's joints (a few
thousand values), where call overhead, not arithmetic, sets the time: 1.0 ms of a 465-frame, 31-joint clip's
4.5 ms decode against 0.1 ms compiled (cmu_test, one thread; :mod:`.codec`'s design notes). The kernel also writes
the decoded rotations (F, J, 4) out of the component-major (4, J, F) ones, the transpose the decoder would otherwise
do in two numpy copies.

numba is imported and the kernel compiled on the first call (``cache=True``: later processes load the compiled code
from ``__pycache__``; the first compile takes about a second), so ``import mocapbench`` does not pay for it.
"""

from __future__ import annotations

from functools import cache

import numpy as np

from mocapbench.motion import Skeleton

__all__ = ["compose", "positions"]

_R1, _R2 = [1, 2, 0], [2, 0, 1]  # (y, z, x) and (z, x, y): a x b = a[_R1] b[_R2] - a[_R2] b[_R1]


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


def _forward(local, roots, parents, offsets, positions, rotations, translations,
             moving):  # pragma: no cover (runs compiled)
    """The kernel: ``local`` (4, J, F) unit quaternions x y z w, ``roots`` (F, 3) cm, ``parents`` (J,) int with
    ``0 <= parents[j] < j`` for j >= 1, ``offsets`` (J, 3) cm; writes ``positions`` (F, J, 3) cm and, unless it has
    no frames, ``rotations`` (F, J, 4) (``local`` transposed). ``translations`` (F, J, 3) cm replaces the offset of
    every joint ``j`` with ``moving[j]`` (a translated joint of a game rig), frame by frame, in the same arithmetic;
    with no joint moving it may have no frames. Loops over frames innermost: the component-major reads are
    contiguous."""
    num_joints, num_frames = local.shape[1], local.shape[2]
    glob = np.empty((4, num_joints, num_frames))
    copy_rotations = rotations.shape[0] > 0
    for f in range(num_frames):
        for c in range(4):
            glob[c, 0, f] = local[c, 0, f]
        for c in range(3):
            positions[f, 0, c] = roots[f, c]
    for j in range(1, num_joints):
        p = parents[j]
        vx, vy, vz = offsets[j, 0], offsets[j, 1], offsets[j, 2]
        vx2, vy2, vz2 = 2.0 * vx, 2.0 * vy, 2.0 * vz
        moves = moving[j]
        for f in range(num_frames):
            if moves:
                vx, vy, vz = translations[f, j, 0], translations[f, j, 1], translations[f, j, 2]
                vx2, vy2, vz2 = 2.0 * vx, 2.0 * vy, 2.0 * vz
            px, py, pz, pw = glob[0, p, f], glob[1, p, f], glob[2, p, f], glob[3, p, f]
            tx = py * vz2 - pz * vy2  # t = 2 q x v
            ty = pz * vx2 - px * vz2
            tz = px * vy2 - py * vx2
            ux = py * tz - pz * ty  # q x t
            uy = pz * tx - px * tz
            uz = px * ty - py * tx
            positions[f, j, 0] = positions[f, p, 0] + ((ux + pw * tx) + vx)  # parent + (q x t + w t + v)
            positions[f, j, 1] = positions[f, p, 1] + ((uy + pw * ty) + vy)
            positions[f, j, 2] = positions[f, p, 2] + ((uz + pw * tz) + vz)
            bx, by, bz, bw = local[0, j, f], local[1, j, f], local[2, j, f], local[3, j, f]
            glob[0, j, f] = ((py * bz - pz * by) + pw * bx) + bw * px  # compose's order
            glob[1, j, f] = ((pz * bx - px * bz) + pw * by) + bw * py
            glob[2, j, f] = ((px * by - py * bx) + pw * bz) + bw * pz
            glob[3, j, f] = pw * bw - ((px * bx + py * by) + pz * bz)
    if copy_rotations:
        for f in range(num_frames):
            for j in range(num_joints):
                for c in range(4):
                    rotations[f, j, c] = local[c, j, f]


_NO_TRANSLATIONS = np.zeros((0, 0, 3))


@cache
def _kernel():
    """:func:`_forward` compiled (numba imported here, on first use)."""
    import numba

    return numba.njit(cache=True, nogil=True)(_forward)


def positions(
    quats: np.ndarray, roots: np.ndarray, skeleton: Skeleton, out: np.ndarray | None = None,
    rotations_out: np.ndarray | None = None, translations: np.ndarray | None = None,
    moving: np.ndarray | None = None,
) -> np.ndarray:
    """Global joint positions (F, J, 3) cm of local rotations ``quats`` (F, J, 4), unit, and ``roots`` (F, 3) cm.

    ``translations`` (F, J, 3) cm with ``moving`` (J,) bool: the joints whose step from their parent is their
    translation of the frame instead of their skeleton offset (a stream's translation tracks; default none).

    Written into ``out`` (F, J, 3) when given (and returned); ``rotations_out`` (F, J, 4), when given, receives
    ``quats``. ``quats`` laid out as a transposed (4, J, F) C-contiguous array (what :func:`.stream.assemble`
    returns) is read without a copy; outputs that are not C-contiguous float64 are filled through a temporary.
    """
    num_frames, num_joints, _ = quats.shape
    local = np.ascontiguousarray(quats.transpose(2, 1, 0), dtype=np.float64)  # (4, J, F)
    roots = np.ascontiguousarray(roots, dtype=np.float64)
    direct = out is not None and out.flags.c_contiguous and out.dtype == np.float64
    result = out if direct else np.empty((num_frames, num_joints, 3))
    rotations_direct = rotations_out is None or (rotations_out.flags.c_contiguous and rotations_out.dtype == np.float64)
    rotations = (np.empty((0, num_joints, 4)) if rotations_out is None
                 else rotations_out if rotations_direct else np.empty((num_frames, num_joints, 4)))
    # A Skeleton guarantees 0 <= parents[j] < j (checked when it was built): the kernel indexes without bounds checks.
    if translations is None:
        translations, moving = _NO_TRANSLATIONS, np.zeros(num_joints, dtype=np.bool_)
    _kernel()(local, roots, np.asarray(skeleton.parents, dtype=np.int64),
              np.ascontiguousarray(skeleton.offsets, dtype=np.float64), result, rotations,
              np.ascontiguousarray(translations, dtype=np.float64), np.asarray(moving, dtype=np.bool_))
    if not rotations_direct:
        rotations_out[...] = rotations
    if out is None or direct:
        return result
    out[...] = result
    return out
