"""A game rig's scale tracks in an ``mcb-rot`` stream (payload format 6, settings flag :data:`SCALES`, bit 13).

A rig may scale a joint's frame (:attr:`Motion.scales <mocapbench.motion.Motion.scales>`: local = T R S, so the scale
of joint ``j`` stretches the steps to its children and its end sites, not ``j`` itself). Each scaled joint's track
is coded as a translation track is (:mod:`.tracks`: a :class:`~.tracks.Tracks` of kind 1, ``value = base + step q``
per axis, second-order differences of ``q`` in one rANS unit per chunk, after the translation tracks' unit), its
header after the translation tracks' header::

    header:  varint T | per track: varint joint (0..J-1) | u8 kind (1: scale) | f32 step | 3 x f32 base |
             f32 peak | 3 x u8 class

``peak`` is the largest scale factor the joint takes on any axis and frame, original or decoded (float32, rounded
up). A joint whose scale is 1 on every frame has no track and costs nothing; a stream without scales has no flag and
no section (its bytes are those of a rig without scales).

The bound. Rotations are isometries and ``|diag(s) v| <= max(s) |v|``, so on any frame the linear map of joint
``j``'s parent frame stretches a length by at most ``g_j``, the product of the peaks of ``j``'s proper ancestors
(:func:`frame_factors`), decoded scales or original alike. Every argument of the rigid rig then holds with lengths
measured after that stretch:

* a rotation error ``θ`` at joint ``a`` moves a point ``k`` below it by at most ``θ C(a, k)`` with ``C`` the chain of
  *stretched* bones ``g_c |t_c|`` (and end sites ``g_k peak_k |e|``): :func:`stretched_lengths` gives them to
  :func:`~.budgets.joint_budgets` as bones, so the budgets, the encoder's closed loop and the decoder agree;
* a translation track's error and the stored offsets' discrepancy at joint ``c`` move its subtree by at most
  ``g_c`` times their length (:meth:`.tracks.Tracks.error_cm` and
  :func:`~.budgets.offset_discrepancy_cm` take the factor);
* a scale error ``δ`` (``|δ| <= step / 2`` per axis) at joint ``j`` moves a point ``k`` below it by
  ``|G_parent R_j diag(δ) v| <= g_j (step / 2) |v|`` with ``g_j peak_j |v| <= C(j, k)``: at most
  ``step / 2 · C(j, k) / peak_j`` (:func:`scale_error_cm`, summed over the scaled joints on a path).

The encoder takes the translation and scale errors and twice the discrepancy off the bound its budgets are computed
for (the translation tracks' and scale tracks' steps each follow ``track_share`` of ε), and its closed loop runs forward
kinematics with the decoded scales (matrices: :mod:`.checks`), so its check sees the scale error. The native
runtime reads scale tracks too (``mcbrot_sample_scales``); forward kinematics with them stays in Python. Non-uniform
scales are carried (the bound above does not need a uniform scale). The shell bound (``shell_cm`` > 0) is not
offered on a scaled rig: its vertices are defined on unscaled joint frames.
"""

from __future__ import annotations

import numpy as np

from mocapbench.codecs.mcb_rot.tracks import KIND_SCALE, Tracks, _differences, _f32_above, _f32_below, _path_sums
from mocapbench.motion import Motion, Skeleton

__all__ = ["SCALES", "frame_factors", "stretched_lengths", "scale_error_cm", "plan_scales", "scales_of"]

#: Settings flag of a stream with scale tracks (format 6).
SCALES = 1 << 13
_MAX_STEP = 1.0 / 256  # a scale that moves no checked point (a leaf without end site) is kept within 1/512
_MAX_SCALE = 1e3  # a larger scale factor is refused (the stream's fields allow up to 1e6)
_MAX_Q = 1 << 30


def _peaks(num_joints: int, scales: Tracks | None) -> np.ndarray:
    peaks = np.ones(num_joints)
    if scales is not None:
        peaks[scales.joints] = scales.reach
    return peaks


def frame_factors(skeleton: Skeleton, scales: Tracks | None) -> np.ndarray:
    """(J,) the most the linear map of each joint's parent frame stretches a length on any frame: the product of
    the peaks of the joint's proper ancestors (1 for the root and below unscaled joints)."""
    peaks = _peaks(skeleton.num_joints, scales)
    factors = np.ones(skeleton.num_joints)
    for joint in range(1, skeleton.num_joints):  # parents come before children
        parent = skeleton.parents[joint]
        factors[joint] = factors[parent] * peaks[parent]
    return factors


def stretched_lengths(skeleton: Skeleton, bones: np.ndarray, ends: np.ndarray | None,
                      scales: Tracks | None) -> tuple[np.ndarray, np.ndarray | None]:
    """Bone lengths (J,) and end-site reaches (J,) or None, cm, after the most the scales stretch them: ``bones``
    (each joint's step from its parent: its offset's or translation track's length) times the joint's
    :func:`frame_factors`, ``ends`` (each joint's longest end site) times the joint's factor and peak."""
    factors = frame_factors(skeleton, scales)
    ends = None if ends is None else ends * factors * _peaks(skeleton.num_joints, scales)
    return bones * factors, ends


def _levers(skeleton: Skeleton, bones: np.ndarray, ends: np.ndarray | None) -> np.ndarray:
    """(J,) the longest chain of ``bones`` from each joint down to a joint or (with ``ends``) an end site of its
    subtree, cm (0 for a leaf without end site)."""
    down = np.zeros(skeleton.num_joints) if ends is None else np.array(ends, dtype=np.float64)
    for joint in range(skeleton.num_joints - 1, 0, -1):  # children after parents: walk back up
        parent = skeleton.parents[joint]
        down[parent] = max(down[parent], bones[joint] + down[joint])
    return down


def scale_error_cm(skeleton: Skeleton, scales: Tracks, bones: np.ndarray, ends: np.ndarray | None) -> float:
    """Largest position error the scale tracks' quantization adds to any joint (or end site, with ``ends``), cm:
    over the paths from the root, the sum of ``step / 2 · lever / peak`` of the scaled joints on it (module
    docstring); ``bones`` and ``ends`` as :func:`stretched_lengths` takes them (unstretched)."""
    stretched, stretched_ends = stretched_lengths(skeleton, bones, ends, scales)
    lever = _levers(skeleton, stretched, stretched_ends)[scales.joints]
    return float(_path_sums(skeleton, scales.joints, 0.5 * scales.step * lever / scales.reach).max(initial=0.0))


def scales_of(tracks: Tracks, num_joints: int, q: np.ndarray) -> np.ndarray:
    """Every joint's scale (n, J, 3) on the frames of ``q`` (n, T, 3): a scaled joint's decoded track, 1 elsewhere."""
    out = np.ones((len(q), num_joints, 3))
    out[:, tracks.joints] = tracks.values(q)
    return out


def plan_scales(motion: Motion, skeleton: Skeleton, bones: np.ndarray, ends: np.ndarray | None, share_cm: float,
                fit_class) -> Tracks | None:
    """The quantized scale tracks of ``motion`` (None when no joint is scaled): each track's step gives its joint
    ``share_cm`` split evenly among the scaled joints of the longest chain of them, as :func:`scale_error_cm` counts
    it (with the original scales' peaks; the error of the tracks as coded, with the decoded peaks, is taken off the
    bound by the caller). ``skeleton`` is the stored one, ``bones`` (J,) and ``ends`` (J,) or None its unstretched
    lengths (:func:`stretched_lengths`), ``fit_class`` as in :func:`.tracks.plan_tracks`.

    Raises
    ------
    ValueError
        A scale above 1000, or one too far from its first frame for its step: one line naming the joint and frame.
    """
    if motion.scales is None:
        return None
    joints = motion.scaled_joints()
    original = motion.scales[:, joints]  # (F, T, 3)
    names = motion.skeleton.names
    if original.max() > _MAX_SCALE:
        frame, track = np.unravel_index(int(np.argmax(original.max(axis=2))), original.shape[:2])
        raise ValueError(f"mcb-rot: joint {names[joints[track]]!r} has a scale of {original[frame, track].max():.4g} "
                         f"at frame {frame}; mcb-rot carries scales up to {_MAX_SCALE:g}.")
    peak = _f32_above(original.max(axis=(0, 2)))
    first = Tracks(joints, np.ones(len(joints)), np.zeros((len(joints), 3)), peak, np.zeros((len(joints), 3), np.int64),
                   kind=KIND_SCALE)
    stretched, stretched_ends = stretched_lengths(skeleton, bones, ends, first)
    lever = _levers(skeleton, stretched, stretched_ends)[joints] / peak
    depth = _path_sums(skeleton, joints, np.ones(len(joints))).max()
    per_joint = share_cm / depth
    step = _f32_below(np.where(lever > 0, 2.0 * per_joint / np.where(lever > 0, lever, 1.0), _MAX_STEP))
    step = np.minimum(step, _MAX_STEP)
    base = np.asarray(original[0], dtype=np.float32).astype(np.float64)
    q = np.floor((original - base[None]) / step[None, :, None] + 0.5)
    decoded = base[None] + step[None, :, None] * q
    bad = (np.abs(q) >= _MAX_Q) | (decoded <= 0)
    if bad.any():
        frame, track, _ = np.argwhere(bad)[0]
        raise ValueError(f"mcb-rot: joint {names[joints[track]]!r} at frame {frame}: its scale "
                         f"{original[frame, track].tolist()} is too far from its first frame's for a step of "
                         f"{step[track]:.3g}; raise eps_cm.")
    q = q.astype(np.int64)
    peak = _f32_above(np.maximum(original.max(axis=(0, 2)), decoded.max(axis=(0, 2))))
    coded = _differences(q.transpose(1, 2, 0))  # (T, 3, F)
    classes = np.array([[fit_class(coded[t, axis]) for axis in range(3)] for t in range(len(joints))], dtype=np.int64)
    return Tracks(joints, step, base, peak, classes, q, kind=KIND_SCALE)
