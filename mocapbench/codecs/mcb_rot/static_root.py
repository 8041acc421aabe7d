"""A game rig's still ground root in an ``mcb-rot`` stream (payload format 6, settings flag :data:`STATIC_ROOT`).

Game rigs often hang the whole body under a root that never moves (Bandai Namco's ``joint_Root`` sits at the origin
with the identity rotation on every frame) while its one child, the pelvis, carries the trajectory as a local
translation. Coded as it stands, the pelvis pays for that trajectory on the uniform grid of the translation tracks
(:mod:`.tracks`: lossless on a fine step, each frame's acceleration a symbol) while the stream's root channels, the
ones with a DCT, a rate search and the closed loop behind them, code a constant. With the flag the stream codes the
motion *without* the still root: the pelvis becomes the coded root, its global position the root channels (the
still root has the identity rotation, so that position is the root's position plus the pelvis' local translation),
and the still root itself is a few bytes after the skeleton part::

    static root:  varint n + n bytes UTF-8 name | u8 channel order index | 3 x f32 offset cm | 3 x f32 position cm

The decoder decodes the J - 1 joints as any stream, then puts the still root back as joint 0 (its position on every
frame, the identity rotation) and gives joint 1 the local translation ``decoded root - position``. Joint 0 is exact
and the other joints' world positions are those the J - 1 joint stream guarantees, so the bound is unchanged.

:func:`split_static_root` writes the flag only where it is exact: joint 0 with the identity rotation and one
float32 position on every frame, exactly one child (joint 1), no end site, a float32 offset, and joint 1 moving.
Every other rig is coded as before.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapbench.codecs.skeleton_blob import _ORDERS
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.motion import Motion, Skeleton

__all__ = ["StaticRoot", "split_static_root", "read_static_root"]

_MAX_NAME_BYTES = 255
_MAX_CM = 1e6  # |offset| and |position| of a stream: beyond, a corrupt field (10 km)


@dataclass(frozen=True, eq=False)
class StaticRoot:
    """The still root joint of a rig: what the stream keeps of it.

    Attributes
    ----------
    name : str
        The joint's name.
    order : str
        Its channel order (``"ZXY"``...).
    offset : ndarray, shape (3,), float, cm
        Its skeleton offset (float32 values).
    position : ndarray, shape (3,), float, cm
        Its position on every frame (float32 values).
    """

    name: str
    order: str
    offset: np.ndarray
    position: np.ndarray

    def write(self, writer: ByteWriter) -> None:
        """The static root section."""
        writer.write_blob(self.name.encode("utf-8"))
        writer.write_u8(_ORDERS.index(self.order))
        writer.write_array(self.offset.astype(np.float32), np.float32)
        writer.write_array(self.position.astype(np.float32), np.float32)

    def skeleton(self, inner: Skeleton) -> Skeleton:
        """The decoded motion's skeleton: the still root above the stream's skeleton ``inner`` (J - 1 joints)."""
        return Skeleton(
            (self.name,) + tuple(inner.names),
            np.concatenate([[-1], inner.parents + 1]).astype(np.int64),
            np.concatenate([self.offset[None], inner.offsets]),
            (self.order,) + tuple(inner.channel_orders),
            inner.end_site_parents + 1,
            inner.end_site_offsets,
        )

    def expand(self, positions: np.ndarray, roots: np.ndarray, quats: np.ndarray, translations: np.ndarray | None,
               offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The decoded motion's positions (n, J, 3), root positions (n, 3), rotations (n, J, 4) and translations
        (n, J, 3) from the stream's (J - 1 joints: positions, roots, rotations, translations or None where the stream
        has no tracks); ``offsets`` (J - 1, 3) are the stream skeleton's."""
        count, inner_joints = len(roots), quats.shape[1]
        full_positions = np.empty((count, inner_joints + 1, 3))
        full_positions[:, 0] = self.position
        full_positions[:, 1:] = positions
        full_quats = np.zeros((count, inner_joints + 1, 4))
        full_quats[:, 0, 3] = 1.0
        full_quats[:, 1:] = quats
        full_translations = np.empty((count, inner_joints + 1, 3))
        full_translations[:, 0] = self.position
        if translations is None:
            full_translations[:, 1:] = offsets
        else:
            full_translations[:, 1:] = translations
        full_translations[:, 1] = roots - self.position
        return full_positions, np.repeat(self.position[None], count, axis=0), full_quats, full_translations


def _is_f32(values: np.ndarray) -> bool:
    return bool(np.all(values.astype(np.float32).astype(np.float64) == values))


def split_static_root(motion: Motion) -> tuple[StaticRoot, Motion] | None:
    """The still root of ``motion`` and the motion of the other joints (joint 1 as their root, its global position
    the root trajectory), or None when the rig has no still root the stream can keep exactly (module docstring)."""
    skeleton = motion.skeleton
    if motion.num_joints < 2 or motion.translations is None or skeleton.names[0].encode("utf-8") == b"":
        return None
    root_rotation = motion.rotations[:, 0]
    position = motion.root_positions[0]
    if (skeleton.parents[1] != 0 or np.any(skeleton.parents[2:] == 0) or np.any(skeleton.end_site_parents == 0)
            or np.any(root_rotation[:, :3] != 0.0) or np.any(np.abs(root_rotation[:, 3]) != 1.0)
            or np.any(motion.root_positions != position) or not _is_f32(position) or not _is_f32(skeleton.offsets[0])
            or len(skeleton.names[0].encode("utf-8")) > _MAX_NAME_BYTES or "\0" in skeleton.names[0]
            or 1 not in motion.moving_joints().tolist() or motion.scales is not None):
        return None
    inner = Skeleton(
        tuple(skeleton.names[1:]),
        np.concatenate([[-1], skeleton.parents[2:] - 1]).astype(np.int64),
        skeleton.offsets[1:],
        tuple(skeleton.channel_orders[1:]),
        skeleton.end_site_parents - 1,
        skeleton.end_site_offsets,
    )
    roots = position + motion.translations[:, 1]  # the root's rotation is the identity
    translations = motion.translations[:, 1:].copy()
    translations[:, 0] = roots
    still = StaticRoot(skeleton.names[0], skeleton.channel_orders[0], skeleton.offsets[0].copy(), position.copy())
    return still, Motion(inner, motion.fps, roots, motion.rotations[:, 1:], name=motion.name,
                         source_unit_cm=motion.source_unit_cm, up_axis=motion.up_axis, translations=translations)


def read_static_root(reader: ByteReader) -> StaticRoot:
    """The static root section, every field checked.

    Raises
    ------
    BitstreamError
        A name that is empty, too long, not UTF-8 or holds a NUL; a channel order index above 5; an offset or
        position that is not finite or beyond 1e6 cm.
    """
    raw = reader.read_blob("static root name", _MAX_NAME_BYTES)
    if not 1 <= len(raw) <= _MAX_NAME_BYTES or b"\0" in raw:
        raise BitstreamError(f"mcb-rot: the static root's name must be 1..{_MAX_NAME_BYTES} bytes without NUL, "
                             f"found {len(raw)} bytes.")
    try:
        name = bytes(raw).decode("utf-8")
    except UnicodeDecodeError as error:
        raise BitstreamError("mcb-rot: the static root's name is not UTF-8.") from error
    order = reader.read_u8("static root channel order")
    if order >= len(_ORDERS):
        raise BitstreamError(f"mcb-rot: the static root's channel order index must be < {len(_ORDERS)}, found {order}.")
    offset = reader.read_array(3, np.float32, "static root offset").astype(np.float64)
    position = reader.read_array(3, np.float32, "static root position").astype(np.float64)
    if not (np.all(np.abs(offset) <= _MAX_CM) and np.all(np.abs(position) <= _MAX_CM)):
        raise BitstreamError("mcb-rot: the static root's offset or position is not finite or beyond 1e6 cm.")
    return StaticRoot(name, _ORDERS[order], offset, position)
