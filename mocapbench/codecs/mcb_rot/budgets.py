"""How much rotation error each joint may carry so that every joint stays within ε: lever arms down the hierarchy.

A rotation error of angle θ at joint ``a`` turns the whole subtree of ``a`` about ``a``'s position, so it moves a
descendant ``k`` by at most ``2 |p_k - p_a| sin(θ/2) <= θ C(a, k)``, where ``C(a, k)`` is the sum of the bone lengths on
the chain from ``a`` down to ``k`` (rotations keep bone lengths, so ``|p_k - p_a| <= C(a, k)`` in every pose). A root
translation error ``e`` moves every joint by ``e``. Applying the errors one joint at a time from the root down, the
position error of joint ``k`` is therefore at most::

    e_root + sum over proper ancestors a of k of  θ_a C(a, k)

:func:`joint_budgets` picks angle budgets ``β_a = w / S_a`` (``S_a = max_k C(a, k)``, the joint's *lever arm*: an
error at the hips moves the hands 80 cm away, one at the wrist only the fingers) and the largest ``w`` for which the
sum stays within the bound for every joint. Whenever every joint of a frame is within its budget the frame is within
ε, whatever the pose: the closed-loop refinement of the encoder relies on it. Joints whose rotation moves no joint
(leaves, zero-length subtrees) have no lever; they get the fixed budget ``free_angle_rad``.

With a shell distance ``d > 0`` (ACL's virtual vertices, :mod:`mocapbench.metrics.shell`) the points to keep within ε
are also the three vertices at distance ``d`` along each joint's axes. A vertex of joint ``k`` is a point rigidly
carried by ``k``'s frame, so it is a virtual child of ``k`` with a bone of length ``d``: its chain from an ancestor
``a`` is ``C(a, k) + d``, from ``k`` itself ``d``. The budgets are then computed over joints and vertices alike; every
joint has a lever of at least ``d`` (leaves included: their budget follows the shell distance instead of
``free_angle_rad``).

End sites (the head, finger and toe tips a viewer draws) are points rigidly carried by their joint's frame too: with
``ends_cm`` each joint ``k`` gets a virtual child of length ``max(d, e_k)``, ``e_k`` its longest end-site offset, so
the bound covers every end site and a leaf with an end site has a lever instead of ``free_angle_rad``. A game rig's
translated joint (a pelvis that moves relative to a ground root) has no fixed bone: with ``bones_cm`` its bone length
is the longest its translation gets on any frame, so ``|p_k - p_a| <= C(a, k)`` still holds in every pose; the error
of the translation itself is taken off the bound by the caller.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapbench.motion import Skeleton

__all__ = ["Budgets", "joint_budgets", "offset_discrepancy_cm"]


@dataclass(frozen=True, eq=False)
class Budgets:
    """Error budgets of one skeleton at one bound.

    Attributes
    ----------
    rotation_rad : ndarray, shape (J,), float, radians
        Angle budget β of each joint's local rotation.
    root_cm : float
        Budget of the root translation, cm.
    ancestors : ndarray, shape (J, J), bool
        ``ancestors[k, a]``: the rotation of joint ``a`` moves joint ``k`` (``a`` is a proper ancestor of ``k``).
    has_lever : ndarray, shape (J,), bool
        The joint's rotation moves at least one joint (or, with a shell, its own vertices).
    movers : ndarray, shape (J, J), bool
        ``movers[k, a]``: the rotation of joint ``a`` moves a point checked at joint ``k`` (the joint itself, and its
        shell vertices when ``shell_cm > 0``): the proper ancestors of ``k``, plus ``k`` itself with a shell.
    shell_cm : float
        Shell distance the budgets cover, cm (0: joint positions only).
    base_rad : ndarray, shape (J,), float, radians
        Relative base-layer step of each joint's rotation channels: ``w / W_a`` with ``W_a`` the p-norm of the
        chain lengths from the joint to its descendants (p = ``allocation_power``; p = inf gives the budgets).
    """

    rotation_rad: np.ndarray
    base_rad: np.ndarray
    root_cm: float
    ancestors: np.ndarray
    has_lever: np.ndarray
    movers: np.ndarray
    shell_cm: float = 0.0


def _chains(skeleton: Skeleton, bones: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Chain lengths ``C[a, k]`` (cm, 0 unless ``a`` is a proper ancestor of ``k``) and the ancestor matrix ``[k, a]``.

    ``C[a, k]`` is the sum of the bone lengths of the joints below ``a`` on the path to ``k``, added from the top
    down (``((b_1 + b_2) + b_3) ...``, as the encoder's closed loop relies on these exact floats): one ``cumsum``
    along the paths of every joint for each starting depth, with the bones at or above that depth zeroed (adding
    zeros first changes no bit). The only Python loop builds the paths (J small list operations). ``bones`` (J,) cm
    replaces the offsets' lengths when given.
    """
    num_joints = skeleton.num_joints
    if bones is None:
        bones = np.sqrt(np.sum(skeleton.offsets**2, axis=1))
    parents = skeleton.parents.tolist()
    paths = [[0]]  # paths[k]: the joints from the root down to k
    for k in range(1, num_joints):
        paths.append(paths[parents[k]] + [k])
    depth = np.array([len(path) - 1 for path in paths], dtype=np.int64)
    levels = int(depth.max(initial=0)) + 1
    joint_at = np.zeros((num_joints, levels), dtype=np.int64)  # joint_at[k, d]: k's ancestor at depth d (k at its own)
    along = np.array([joint for path in paths for joint in path], dtype=np.int64)
    rows = np.repeat(np.arange(num_joints), depth + 1)
    first = np.cumsum(depth + 1) - (depth + 1)
    joint_at[rows, np.arange(len(along)) - first[rows]] = along
    steps = np.where(np.arange(levels) <= depth[:, None], bones[joint_at], 0.0)  # (J, D): bone of each path step
    # (D, J, D): from depth s, the sums of the bones of depths s + 1 .. d along each joint's path.
    sums = np.cumsum(np.where(np.arange(levels)[None, None, :] > np.arange(levels)[:, None, None], steps, 0.0), axis=2)
    ancestors = np.zeros((num_joints, num_joints), dtype=bool)
    proper = along != rows
    ancestors[rows[proper], along[proper]] = True
    every = np.arange(num_joints)
    chain = np.where(ancestors.T, sums[depth[:, None], every[None, :], depth[None, :]], 0.0)
    return chain, ancestors


def joint_budgets(
    skeleton: Skeleton,
    bound_cm: float,
    root_share: float,
    free_angle_rad: float,
    allocation_power: float = 0.0,
    shell_cm: float = 0.0,
    *,
    ends_cm: np.ndarray | None = None,
    bones_cm: np.ndarray | None = None,
) -> Budgets:
    """Angle budgets of every joint and the root translation budget for an L-inf bound of ``bound_cm``.

    Parameters
    ----------
    skeleton : Skeleton
    bound_cm : float, > 0
        The position bound the budgets must respect, cm.
    root_share : float, in (0, 1)
        Share of the bound given to the root translation.
    free_angle_rad : float, > 0
        Budget of the joints without a lever arm.
    allocation_power : float, >= 0
        p of the p-norm lever of the base-layer steps (0 stands for infinity: the steps follow the budgets). The
        budgets guard the worst case, where every ancestor's error points the same way; the base layer's errors are
        closer to independent, and a finite p lets a joint that moves many joints take a finer step.
    shell_cm : float, >= 0
        Distance of the virtual vertices that must also stay within the bound, cm (0: joints only).
    ends_cm : ndarray, shape (J,), float, cm, optional, keyword-only
        Each joint's longest end-site offset (0 where it has none): its end sites must stay within the bound too.
    bones_cm : ndarray, shape (J,), float, cm, optional, keyword-only
        Each joint's bone length (default: its offset's): the longest translation of a translated joint.
    """
    chain, ancestors = _chains(skeleton, bones_cm)
    movers = ancestors.copy()
    reach = np.full(skeleton.num_joints, float(shell_cm))
    if ends_cm is not None:
        reach = np.maximum(reach, ends_cm)
    if reach.max(initial=0.0) > 0:
        # The vertices and end sites of joint k: a virtual child of k at distance reach[k] (columns J..2J-1 of the
        # chain matrix; a joint with neither has a column equal to its own, which changes no sum's maximum).
        vertices = np.where(ancestors.T, chain + reach[None, :], 0.0)
        np.fill_diagonal(vertices, reach)
        chain = np.concatenate([chain, vertices], axis=1)
        movers[np.diag_indices_from(movers)] = reach > 0
    lever = chain.max(axis=1)  # S_a
    has_lever = lever > 0
    relative = np.divide(chain, lever[:, None], out=np.zeros_like(chain), where=has_lever[:, None])
    worst = float(relative.sum(axis=0).max())  # max over k of sum over a of C(a, k) / S_a
    rotation_share = bound_cm * (1.0 - root_share)
    weight = rotation_share / worst if worst > 0 else 0.0
    rotation = np.where(has_lever, weight / np.where(has_lever, lever, 1.0), free_angle_rad)
    if allocation_power > 0:
        norm = np.sum(chain**allocation_power, axis=1) ** (1.0 / allocation_power)
        base = np.where(has_lever, weight / np.where(has_lever, norm, 1.0), free_angle_rad)
    else:
        base = rotation
    return Budgets(
        rotation_rad=rotation, base_rad=base, root_cm=bound_cm * root_share, ancestors=ancestors, has_lever=has_lever,
        movers=movers, shell_cm=float(shell_cm),
    )


def offset_discrepancy_cm(original: Skeleton, stored: Skeleton, ends: bool = False,
                          stretch: tuple[np.ndarray, np.ndarray] | None = None) -> float:
    """Largest position change of any joint, in any pose, from replacing ``original``'s offsets by ``stored``'s, cm.

    The stream keeps offsets as float32; this bound (the sum of offset changes along the worst chain, to a joint or,
    with ``ends``, an end site) is taken off the error budget so that the guarantee holds against the caller's float64 skeleton.
    ``stretch`` (a scaled rig): each joint's frame factor and its own peak scale (J,) each (:mod:`.scales`): a
    joint's offset change counts times its factor, an end site's times its joint's factor and peak.
    """
    factor, peak = (np.ones(original.num_joints), np.ones(original.num_joints)) if stretch is None else stretch
    change = np.sqrt(np.sum((original.offsets - stored.offsets) ** 2, axis=1)) * factor
    change[0] = 0.0
    total = np.zeros(original.num_joints)
    for k in range(1, original.num_joints):
        total[k] = total[original.parents[k]] + change[k]
    tips = np.zeros(0)
    if ends and len(original.end_site_parents) == len(stored.end_site_parents) > 0:  # one offset further
        parents = original.end_site_parents
        tips = total[parents] + np.sqrt(np.sum((original.end_site_offsets - stored.end_site_offsets) ** 2, axis=1)) * (
            factor[parents] * peak[parents])
    return float(max(total.max(), tips.max(initial=0.0)))
