"""A game rig's translation tracks in an ``mcb-rot`` stream (payload format 6, settings flag :data:`TRACKS`).

A game rig moves joints other than the root relative to their parents (a pelvis under a ground-level root, a
stretching bone): :attr:`Motion.translations <mocapbench.motion.Motion.translations>`. Each moving joint's track is
quantized on a uniform grid, ``value = base + step q`` (``q`` integer, per axis), so every decoded translation is
within ``sqrt(3) / 2 step`` of the original on every frame. The encoder takes the sum of those errors along the worst
chain off the bound the rotation budgets are computed for (a translation error moves the joint's subtree rigidly by
its length), and the budgets take each track's ``reach`` (the longest its decoded translation gets) as the joint's
bone length (:mod:`.budgets`), so the closed loop's guarantee covers the rig as it covers a rigid skeleton: forward
kinematics in the closed loop and in the decoder steps from each parent by the decoded translation of the frame.

Layout (the tracks header after the classes; one unit per chunk after the rotation unit)::

    header:  varint T | per track: varint joint | u8 kind (0: translation) | f32 step cm | 3 x f32 base cm |
             f32 reach cm | 3 x u8 class
    chunk:   one rANS unit (mocapbench.entropy.rans6) of, track by track and axis by axis, the chunk's frames as
             second-order differences of q from zero (two running sums give q back), each with side table
             64 + its axis' class

so any frame decodes from its chunk alone (random access), in the primitives the native runtime reads. A still
track is a run of zeros after its first values, a steady walk too (a pelvis moving at a constant speed has constant
first differences): second differences are the track's accelerations, several bits a value smaller than its
velocities on captured motion. The step follows the bound: the tracks get
:data:`TRACK_SHARE` of it, split evenly among the tracked joints of the longest chain of them.

Scale tracks (kind 1) are coded the same way in a section of their own behind another flag (:mod:`.scales`): a
:class:`Tracks` of kind 1, whose ``reach`` is the largest scale a track's joint takes (its *peak*).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.motion import Motion, Skeleton

__all__ = ["TRACK_SHARE", "Tracks", "plan_tracks", "read_tracks", "SIDE"]

#: Share of the bound given to the translation tracks (the rest goes to the root and the rotations).
TRACK_SHARE = 0.1
#: Class of the side tables in format 6's 128 classes: a track value of class c uses table SIDE + c.
SIDE = 64
_KIND_TRANSLATION = 0
KIND_SCALE = 1
_HALF_DIAGONAL = np.sqrt(3.0) / 2.0  # a cube of side s fits in the ball of radius s sqrt(3) / 2
_MAX_Q = 1 << 30  # |q| of a frame: its first-order differences stay below rans6's 2^31
_MAX_CM = 1e6  # |base| and step of a stream: beyond, a corrupt field (10 km)


@dataclass(frozen=True, eq=False)
class Tracks:
    """The translation tracks of a stream: what the header says (and, at the encoder, the quantized values).

    Attributes
    ----------
    joints : ndarray, shape (T,), int
        The translated joints, increasing, each in 1..J-1.
    step : ndarray, shape (T,), float, cm
        Grid step of each track (float32 values).
    base : ndarray, shape (T, 3), float, cm
        The value of ``q = 0`` (float32 values).
    reach : ndarray, shape (T,), float, cm
        Longest decoded translation of each track over the frames (float32, rounded up): its bone length in the
        budgets.
    classes : ndarray, shape (T, 3), int
        Side class (0..63) of each track's axis.
    q : ndarray, shape (F, T, 3), int, optional
        The quantized values (encoder only).
    kind : int
        0: translation tracks (cm); :data:`KIND_SCALE`: scale tracks (:mod:`.scales`: values and steps are scale
        factors, ``reach`` the largest scale of each track's joint).
    """

    joints: np.ndarray
    step: np.ndarray
    base: np.ndarray
    reach: np.ndarray
    classes: np.ndarray
    q: np.ndarray | None = None
    kind: int = _KIND_TRANSLATION

    @property
    def count(self) -> int:
        return len(self.joints)

    def values(self, q: np.ndarray) -> np.ndarray:
        """Decoded translations (n, T, 3) cm of quantized values ``q`` (n, T, 3)."""
        return self.base[None] + self.step[None, :, None] * q

    def steps_of(self, skeleton: Skeleton, q: np.ndarray) -> np.ndarray:
        """Every joint's step from its parent (n, J, 3) cm on the frames of ``q`` (n, T, 3): the decoded
        translation of a tracked joint, the skeleton offset of the others (column 0 unused)."""
        out = np.empty((len(q), skeleton.num_joints, 3))
        out[:] = skeleton.offsets
        out[:, self.joints] = self.values(q)
        return out

    def moving(self, num_joints: int) -> np.ndarray:
        """(J,) bool: the tracked joints."""
        mask = np.zeros(num_joints, dtype=bool)
        mask[self.joints] = True
        return mask

    def error_cm(self, skeleton: Skeleton, factor: np.ndarray | None = None) -> float:
        """Largest position error the tracks' quantization adds to any joint, cm: the sum of ``sqrt(3) / 2 step``
        over the tracked joints on its path from the root (itself included), each times its ``factor`` (J,) when
        given (a scaled rig: how much its parent's frame may stretch a length, :func:`.scales.frame_factors`)."""
        amounts = _HALF_DIAGONAL * self.step * (1.0 if factor is None else factor[self.joints])
        return float(_path_sums(skeleton, self.joints, amounts).max(initial=0.0))

    def bones_cm(self, skeleton: Skeleton) -> np.ndarray:
        """(J,) bone lengths for the budgets: each offset's length, a tracked joint's reach."""
        bones = np.sqrt(np.sum(skeleton.offsets**2, axis=1))
        bones[self.joints] = self.reach
        return bones

    def write(self, writer: ByteWriter) -> None:
        """The tracks header."""
        writer.write_varint(self.count)
        for t, joint in enumerate(self.joints.tolist()):
            writer.write_varint(joint)
            writer.write_u8(self.kind)
            writer.write_f32(self.step[t])
            for value in self.base[t]:
                writer.write_f32(value)
            writer.write_f32(self.reach[t])
            writer.write_bytes(bytes(int(c) for c in self.classes[t]))

    def unit_classes(self, length: int) -> np.ndarray:
        """(T 3 length,) table of every value of a chunk of ``length`` frames (track, axis, frame order)."""
        return np.repeat(SIDE + self.classes.ravel(), length)

    def chunk_values(self, start: int, stop: int) -> np.ndarray:
        """The values of a chunk's unit (encoder): frames ``start:stop`` of every track and axis as second-order
        differences of q (the first frame's q, then its first difference, then second differences)."""
        return _differences(self.q[start:stop].transpose(1, 2, 0)).ravel()

    def q_of_values(self, values: np.ndarray, length: int) -> np.ndarray:
        """The quantized values (n, T, 3) of a chunk's decoded unit ``values`` (T 3 n,) (decoder): two running
        sums along the frames."""
        q = np.cumsum(np.cumsum(values.reshape(self.count, 3, length), axis=2), axis=2)
        return q.transpose(2, 0, 1)


def _differences(q: np.ndarray) -> np.ndarray:
    """Second-order differences along the last axis, from zero: ``d[0] = q[0]``, ``d[1] = q[1] - 2 q[0]``... so that
    two running sums give ``q`` back (``d[1] = (q[1] - q[0]) - q[0]``: the first difference less the first value)."""
    first = np.diff(q, axis=-1, prepend=0)
    return np.diff(first, axis=-1, prepend=0)


def _path_sums(skeleton: Skeleton, joints: np.ndarray, amounts: np.ndarray) -> np.ndarray:
    """(J,) per joint, the sum of ``amounts`` of the ``joints`` on its path from the root (itself included)."""
    own = np.zeros(skeleton.num_joints)
    own[joints] = amounts
    total = own.copy()
    for joint in range(1, skeleton.num_joints):  # parents come before children
        total[joint] += total[skeleton.parents[joint]]
    return total


def _f32_below(value: np.ndarray) -> np.ndarray:
    rounded = np.asarray(value, dtype=np.float32)
    return np.where(rounded > value, np.nextafter(rounded, np.float32(-np.inf)), rounded).astype(np.float64)


def _f32_above(value: np.ndarray) -> np.ndarray:
    rounded = np.asarray(value, dtype=np.float32)
    return np.where(rounded < value, np.nextafter(rounded, np.float32(np.inf)), rounded).astype(np.float64)


def plan_tracks(motion: Motion, share_cm: float, fit_class) -> Tracks | None:
    """The quantized translation tracks of ``motion`` with at most ``share_cm`` of position error on any joint
    (None when no joint below the root moves).

    ``fit_class(values) -> int`` picks a side class (0..63) for an axis' coded values (the format's side tables).

    Raises
    ------
    ValueError
        A track too long for its step (``|q|`` would exceed 2^30): one line naming the joint.
    """
    if motion.translations is None:
        return None
    joints = motion.moving_joints()
    skeleton = motion.skeleton
    # The tracked joints on the longest chain of them share the budget; every track gets the same step.
    depth = _path_sums(skeleton, joints, np.ones(len(joints))).max()
    step = np.full(len(joints), float(_f32_below(share_cm / depth / _HALF_DIAGONAL)))
    original = motion.translations[:, joints]  # (F, T, 3)
    base = np.asarray(original[0], dtype=np.float32).astype(np.float64)
    q = np.floor((original - base[None]) / step[None, :, None] + 0.5)
    too_far = np.abs(q).max(axis=(0, 2)) >= _MAX_Q
    if too_far.any():
        joint = skeleton.names[int(joints[np.argmax(too_far)])]
        raise ValueError(f"mcb-rot: joint {joint!r} moves {np.ptp(original, axis=0).max():.4g} cm, too far for a step "
                         f"of {step[0]:.3g} cm; raise eps_cm.")
    q = q.astype(np.int64)
    decoded = base[None] + step[None, :, None] * q
    lengths = np.maximum(np.sqrt(np.sum(decoded**2, axis=2)), np.sqrt(np.sum(original**2, axis=2)))
    reach = _f32_above(lengths.max(axis=0))
    coded = _differences(q.transpose(1, 2, 0))  # (T, 3, F): what the units hold (chunk boundaries apart)
    classes = np.array([[fit_class(coded[t, axis]) for axis in range(3)] for t in range(len(joints))], dtype=np.int64)
    return Tracks(joints, step, base, reach, classes, q)


def read_tracks(reader: ByteReader, num_joints: int, kind: int = _KIND_TRANSLATION) -> Tracks:
    """The tracks header of a stream of ``num_joints`` joints, every field checked: translation tracks (joints
    1..J-1), or with ``kind`` :data:`KIND_SCALE` the scale tracks' (joints 0..J-1: the root may be scaled).

    Raises
    ------
    BitstreamError
        A count, joint, kind, step, base, reach or class outside what the format allows.
    """
    first = 0 if kind == KIND_SCALE else 1
    what = "scale" if kind == KIND_SCALE else "translation"
    count = reader.read_varint(f"{what} track count")
    if not 1 <= count <= num_joints - first:
        raise BitstreamError(f"mcb-rot: expected 1..{num_joints - first} {'scale ' if first == 0 else ''}tracks, "
                             f"found {count}.")
    joints, step, base, reach, classes = [], [], [], [], []
    for _ in range(count):
        joint = reader.read_varint("tracked joint")
        if not (joints[-1] + 1 if joints else first) <= joint < num_joints:
            raise BitstreamError(f"mcb-rot: a {what} track's joint must be in {first}..{num_joints - 1}, after the "
                                 f"previous track's, found {joint}.")
        found = reader.read_u8("track kind")
        if found != kind:
            raise BitstreamError(f"mcb-rot: track kind {found} is not a {what} ({kind}).")
        joints.append(joint)
        step.append(reader.read_f32("track step"))
        base.append([reader.read_f32("track base") for _ in range(3)])
        reach.append(reader.read_f32("track reach"))
        classes.append(list(reader.read_bytes(3, "track classes")))
    step, base, reach = np.array(step), np.array(base), np.array(reach)
    classes = np.array(classes, dtype=np.int64)
    least = 0.0 if kind == _KIND_TRANSLATION else np.nextafter(0.0, 1.0)  # a scale's peak is > 0
    if not (np.all((step > 0) & (step <= _MAX_CM)) and np.all(np.abs(base) <= _MAX_CM)
            and np.all((reach >= least) & (reach <= 4 * _MAX_CM)) and classes.max() < SIDE):
        raise BitstreamError(f"mcb-rot: a {what} track's step, base, {'reach' if first else 'peak'} or class is "
                             "outside the format's range.")
    return Tracks(np.array(joints, dtype=np.int64), step, base, reach, classes, kind=kind)

