"""The closed loop of the ``mcb-rot`` encoder: corrections until every joint (and shell vertex) is within the bound.

The encoder decodes its base layer, runs forward kinematics and, on every frame where a joint misses the bound,
replaces the rotation of over-budget ancestors of the missing joints (and the root translation) by a correction
quantized finely enough to bring it within its budget (:mod:`.budgets`), repeating until nothing misses: a frame
whose every joint is within budget is within the bound in any pose, so the loop ends. :func:`refine` is the loop
(greedy: one correction per missing frame and round, the one :func:`most_helpful` picks), used by the rate search
of :mod:`.codec` on one attempt or several side by side.
"""

from __future__ import annotations

import numpy as np

from mocapbench.codecs.mcb_rot import quaternions as quat
from mocapbench.codecs.mcb_rot.checks import PointTargets
from mocapbench.codecs.mcb_rot.stream import StreamInfo, apply_corrections

__all__ = ["most_helpful", "refine"]


def most_helpful(fix, missing, placed, error, glob, relative, root_error, budgets) -> np.ndarray:
    """``fix`` (n, J + 1) reduced to one slot per row: the candidate whose full correction most reduces a missing
    joint's error (to first order: joint a's correction turns its subtree about ``p_a`` by its rotation error, seen
    in the world frame; the root's moves every joint by its translation error).

    ``placed`` (n, J, 3) decoded positions, ``error`` (n, J, 3) original minus decoded positions, ``glob`` (n, J, 4)
    decoded global rotations, ``relative`` (n, J, 4) the local rotation errors ``conj(decoded) original``,
    ``root_error`` (n, 3).
    """
    rows, joints = np.nonzero(missing)  # the (frame, missing joint) pairs, rows ascending
    miss = error[rows, joints]  # (m, 3)
    size = quat.norm3(miss)
    first = np.flatnonzero(np.concatenate(([True], rows[1:] != rows[:-1])))
    frames_missing = rows[first]
    # Scores: -inf where not a candidate, at least -1e300 where one (a candidate always beats a non-candidate).
    score = np.where(fix, -1e300, -np.inf)
    # Scored only in the columns some row may correct.
    columns = np.flatnonzero(fix[:, 1:].any(axis=0))
    if columns.size:
        # The world-frame turns omega_a = rotate(glob_a, log_map(the short way of relative_a)), component-major (3,
        # n, c) (quat.log_map's and quat.rotate's operations, without stacking).
        qx, qy, qz, qw = np.moveaxis(relative.take(columns, axis=1), -1, 0)
        sign = np.where(qw < 0, -1.0, 1.0)
        qx, qy, qz, qw = qx * sign, qy * sign, qz * sign, qw * sign
        norm = np.sqrt(qx * qx + qy * qy + qz * qz)
        angle = 2.0 * np.arctan2(norm, qw)
        small = norm < 1e-9
        scale = np.where(small, 2.0 / np.where(small, qw, 1.0), angle / np.where(small, 1.0, norm))
        vx, vy, vz = qx * scale, qy * scale, qz * scale
        ux, uy, uz, uw = np.moveaxis(glob.take(columns, axis=1), -1, 0)
        tx, ty, tz = 2.0 * (uy * vz - uz * vy), 2.0 * (uz * vx - ux * vz), 2.0 * (ux * vy - uy * vx)
        omega = np.empty((3,) + ux.shape)
        omega[0] = vx + uw * tx + (uy * tz - uz * ty)
        omega[1] = vy + uw * ty + (uz * tx - ux * tz)
        omega[2] = vz + uw * tz + (ux * ty - uy * tx)
        # |miss - omega_a x (p_k - p_a)| (quat.cross and quat.norm3's operations, component by component) for the
        # (missing joint k, candidate a) pairs only: a an ancestor of k (a mover of it) and a candidate of k's
        # frame; elsewhere the score stays as it is. Each frame's score of a is the best over its missing joints.
        pair, column = np.nonzero(budgets.movers[joints][:, columns] & fix[rows][:, columns + 1])
        if pair.size:
            row, joint, mover = rows[pair], joints[pair], columns[column]
            ox, oy, oz = omega[:, row, column]
            px, py, pz = placed[row, joint].T  # p_k
            cx, cy, cz = placed[row, mover].T  # p_a
            ax, ay, az = px - cx, py - cy, pz - cz
            ex, ey, ez = miss[pair].T
            dx = ex - (oy * az - oz * ay)
            dy = ey - (oz * ax - ox * az)
            dz = ez - (ox * ay - oy * ax)
            np.maximum.at(score, (row, mover + 1), size[pair] - np.sqrt(dx * dx + dy * dy + dz * dz))
    root_gain = size - quat.norm3(miss - root_error[rows])
    root_score = np.full(len(missing), -np.inf)
    root_score[frames_missing] = np.maximum.reduceat(root_gain, first)
    score[:, 0] = np.where(fix[:, 0], np.maximum(root_score, -1e300), -np.inf)
    out = np.zeros_like(fix)
    rows = np.flatnonzero(fix.any(axis=1))
    out[rows, np.argmax(score[rows], axis=1)] = True
    return out


def refine(info: StreamInfo, true_quats: np.ndarray, true_roots: np.ndarray, roots, quats, points: PointTargets,
            check_cm: float, greedy: bool, give_up=None, prune=None):
    """Closed-loop corrections (in place on ``roots``, ``quats``): returns (flat indices, values (N, 3)) sorted, or
    None when ``give_up(flat, values)`` (asked after every round with the corrections so far) returns True.

    On every frame where a joint (or, with a shell, one of its vertices) misses ``check_cm``, the over-budget joints
    that move the missing points (and the root translation when it is over budget) are corrected to within budget;
    repeated until nothing misses. With ``greedy``, only one of them per frame and round: the one whose correction
    most reduces a missing joint's error (a miss is usually by a little, and one correction often ends it). A frame
    whose every joint and root is within budget cannot miss (:mod:`.budgets`), and every round corrects a new slot
    of every frame still missing, so the loop ends.
    """
    if greedy:
        return _refine_greedy(info, true_quats, true_roots, roots, quats, points, check_cm, give_up, prune)
    budgets = info.budgets
    steps = info.correction_steps
    slots = len(steps)
    num_frames = len(roots)
    movers = budgets.movers.astype(np.float64)
    corrected = np.zeros((num_frames, slots), dtype=bool)
    values = np.zeros((num_frames, slots, 3), dtype=np.int64)
    everything = np.arange(num_frames)
    errors, placed, glob = points.evaluate(everything, quats, roots)  # (F, J), (F, J, 3), (F, J, 4)
    still = np.any(errors > check_cm, axis=1)
    frames, errors, placed, glob = everything[still], errors[still], placed[still], glob[still]
    for _ in range(slots + 1):
        if frames.size and prune is not None:
            keep = prune(corrected, values, frames)
            frames, errors, placed, glob = frames[keep], errors[keep], placed[keep], glob[keep]
        if frames.size == 0:
            break
        missing = errors > check_cm
        moves_missing = (missing.astype(np.float64) @ movers) > 0  # (n, J): joint a moves a missing point
        relative = quat.multiply(quat.conjugate(quats[frames]), true_quats[frames])
        over = quat.angle(relative) > budgets.rotation_rad
        root_over = quat.norm3(true_roots[frames] - roots[frames]) > budgets.root_cm
        fix = np.concatenate([(root_over & missing.any(axis=1))[:, None], moves_missing & over], axis=1)
        fix &= ~corrected[frames]
        stuck = ~fix.any(axis=1)
        if stuck.any():  # cannot happen by the budget argument; fix every over-budget slot to be sure
            fix[stuck] = np.concatenate([root_over[:, None], over], axis=1)[stuck] & ~corrected[frames[stuck]]
        if greedy:
            fix = most_helpful(fix, missing, placed, points.positions[frames] - placed, glob, relative,
                                true_roots[frames] - roots[frames], budgets)
        rows, slot = np.nonzero(fix)
        if rows.size == 0:
            raise RuntimeError("mcb-rot: refinement made no progress; the error budgets are inconsistent.")
        at = frames[rows]
        root = slot == 0
        step_root = steps[0]
        delta = np.floor((true_roots[at[root]] - roots[at[root]]) / step_root + 0.5).astype(np.int64)
        values[at[root], 0] = delta
        joint = slot[~root] - 1
        rel = relative[rows[~root], joint]
        rel = rel * np.where(rel[:, 3] < 0, -1.0, 1.0)[:, None]
        delta_rot = np.floor(quat.log_map(rel) / steps[slot[~root]][:, None] + 0.5).astype(np.int64)
        values[at[~root], slot[~root]] = delta_rot
        corrected[at, slot] = True
        if give_up is not None:
            so_far = np.flatnonzero(corrected.ravel())
            if give_up(so_far, values.reshape(-1, 3)[so_far]):
                return None
        flat = at * slots + slot
        apply_corrections(info, roots, quats, flat, values[at, slot])
        errors, placed, glob = points.evaluate(frames, quats[frames], roots[frames])
        still = np.any(errors > check_cm, axis=1)
        frames, errors, placed, glob = frames[still], errors[still], placed[still], glob[still]
    if frames.size:
        raise RuntimeError("mcb-rot: refinement did not converge; not writing.")
    flat = np.flatnonzero(corrected.ravel())
    return flat, values.reshape(-1, 3)[flat]




def _refine_greedy(info: StreamInfo, true_quats: np.ndarray, true_roots: np.ndarray, roots, quats,
                   points: PointTargets, check_cm: float, give_up=None, prune=None):
    """:func:`refine` with ``greedy`` (one correction per missing frame and round), on the missing frames' own
    copies (``roots``, ``quats`` are left as they are), compacted every round to the frames still missing.

    After the first forward kinematics the loop does not run it again: a frame's correction of joint ``a`` turns
    ``a``'s subtree about ``p_a`` by the change of ``a``'s global rotation (the root's moves every joint), so the
    positions and global rotations are updated in place, a few numpy calls instead of one product per tree depth.
    They drift from forward kinematics by float rounding only (~1e-13 cm after every round a frame can take, far
    inside the safety margin; a scaled rig's frames run forward kinematics again instead, :mod:`.scales`); the
    corrected rotations themselves are computed as :func:`.stream.apply_corrections` computes them (the same bits as
    the decoder's), and the encoder's final check decodes the stream.
    """
    budgets = info.budgets
    steps = info.correction_steps
    slots = len(steps)
    num_frames = len(roots)
    parents = info.skeleton.parents
    movers = budgets.movers.astype(np.float64)
    subtree = budgets.ancestors.T | np.eye(len(parents), dtype=bool)  # [a, k]: k is a or below it
    corrected = np.zeros((num_frames, slots), dtype=bool)
    values = np.zeros((num_frames, slots, 3), dtype=np.int64)
    everything = np.arange(num_frames)
    errors, placed, glob = points.evaluate(everything, quats, roots)  # (F, J), (F, J, 3), (F, J, 4)
    still = np.flatnonzero(np.any(errors > check_cm, axis=1))
    frames, errors, placed, glob = everything[still], errors[still], placed[still], glob[still]
    local, root = quats[frames], roots[frames]  # copies (fancy indexing)
    true_local, true_root = true_quats[frames], true_roots[frames]
    relative = quat.multiply(quat.conjugate(local), true_local)
    over = quat.angle(relative) > budgets.rotation_rad
    root_error = true_root - root
    root_over = quat.norm3(root_error) > budgets.root_cm
    done = np.zeros((len(frames), slots), dtype=bool)

    def keep_only(keep):
        nonlocal frames, errors, placed, glob, local, root, true_local, true_root, relative, over, root_error
        nonlocal root_over, done
        frames, errors, placed, glob = frames[keep], errors[keep], placed[keep], glob[keep]
        local, root = local[keep], root[keep]
        true_local, true_root, relative, over = true_local[keep], true_root[keep], relative[keep], over[keep]
        root_error, root_over, done = root_error[keep], root_over[keep], done[keep]

    for _ in range(slots + 1):
        if frames.size and prune is not None:
            keep = prune(corrected, values, frames)
            if not keep.all():
                keep_only(keep)
        if frames.size == 0:
            break
        missing = errors > check_cm
        moves_missing = (missing.astype(np.float64) @ movers) > 0  # (n, J): joint a moves a missing point
        fix = np.concatenate([(root_over & missing.any(axis=1))[:, None], moves_missing & over], axis=1)
        fix &= ~done
        stuck = ~fix.any(axis=1)
        if stuck.any():  # cannot happen by the budget argument; fix every over-budget slot to be sure
            fix[stuck] = np.concatenate([root_over[:, None], over], axis=1)[stuck] & ~done[stuck]
        fix = most_helpful(fix, missing, placed, points.positions[frames] - placed, glob, relative, root_error,
                            budgets)
        rows, slot = np.nonzero(fix)
        if rows.size == 0:
            raise RuntimeError("mcb-rot: refinement made no progress; the error budgets are inconsistent.")
        at = frames[rows]
        is_root = slot == 0
        root_rows, joint_rows = rows[is_root], rows[~is_root]
        joint_slot = slot[~is_root]
        joint = joint_slot - 1
        delta = np.floor(root_error[root_rows] / steps[0] + 0.5).astype(np.int64)
        values[at[is_root], 0] = delta
        rel = relative[joint_rows, joint]
        rel = rel * np.where(rel[:, 3] < 0, -1.0, 1.0)[:, None]
        delta_rot = np.floor(quat.log_map(rel) / steps[joint_slot][:, None] + 0.5).astype(np.int64)
        values[at[~is_root], joint_slot] = delta_rot
        corrected[at, slot] = True
        done[rows, slot] = True
        if give_up is not None:
            so_far = np.flatnonzero(corrected.ravel())
            if give_up(so_far, values.reshape(-1, 3)[so_far]):
                return None
        # The corrections, as apply_corrections computes them.
        if root_rows.size:
            moved = root[root_rows]
            root[root_rows] += delta * steps[slot[is_root]][:, None]
            placed[root_rows] += (root[root_rows] - moved)[:, None, :]
            root_error[root_rows] = true_root[root_rows] - root[root_rows]
            root_over[root_rows] = quat.norm3(root_error[root_rows]) > budgets.root_cm
        if joint_rows.size:
            turned = quat.multiply(local[joint_rows, joint], quat.exp_map(delta_rot * steps[joint_slot][:, None]))
            local[joint_rows, joint] = turned
            relative[joint_rows, joint] = quat.multiply(quat.conjugate(turned), true_local[joint_rows, joint])
            over[joint_rows, joint] = quat.angle(relative[joint_rows, joint]) > budgets.rotation_rad[joint]
            # The subtree of each corrected joint turns about it by the change of its global rotation.
            above = parents[joint]
            new_global = quat.multiply(glob[joint_rows, np.maximum(above, 0)], turned)
            new_global[above < 0] = turned[above < 0]
            change = quat.multiply(new_global, quat.conjugate(glob[joint_rows, joint]))  # (r, 4)
            pair, below = np.nonzero(subtree[joint])  # (corrected row, joint in its subtree) pairs
            row = joint_rows[pair]
            centre = placed[joint_rows, joint][pair]
            glob[row, below] = quat.multiply(change[pair], glob[row, below])
            glob[joint_rows, joint] = new_global
            placed[row, below] = centre + quat.rotate(change[pair], placed[row, below] - centre)
        if points.scales is None:
            errors = points.errors_of(frames, placed, glob)
        else:  # a scaled subtree does not turn rigidly with its joint: forward kinematics again (the frames missing)
            errors, placed, glob = points.evaluate(frames, local, root)
        keep = np.any(errors > check_cm, axis=1)
        if not keep.all():
            keep_only(keep)
    if frames.size:
        raise RuntimeError("mcb-rot: refinement did not converge; not writing.")
    flat = np.flatnonzero(corrected.ravel())
    return flat, values.reshape(-1, 3)[flat]
