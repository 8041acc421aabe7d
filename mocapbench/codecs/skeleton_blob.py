"""Serialize a skeleton into a codec payload, for codecs whose decoder runs forward kinematics.

A rotation codec's decoder needs the bone offsets, so they travel in its stream and count in its rate:
nothing needed to decode may travel beside the bytes. Layout (then zstd-compressed as one blob): J, E
(varints); parents as J bytes+1 offset; channel orders as one byte each (index into the 6 permutations of
XYZ); offsets and end-site offsets as float32 cm; names as a NUL-separated ASCII/UTF-8 string.
"""

from __future__ import annotations

from itertools import permutations

import numpy as np

from mocapbench.entropy.backend import zstd_compress, zstd_decompress
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.motion import Skeleton

__all__ = ["pack_skeleton", "unpack_skeleton"]

_ORDERS = ["".join(p) for p in permutations("XYZ")]
_MAX_SKELETON_BYTES = 1 << 20


def pack_skeleton(skeleton: Skeleton) -> bytes:
    """The skeleton as a compact, self-delimiting blob (length-prefixed zstd)."""
    writer = ByteWriter()
    writer.write_varint(skeleton.num_joints)
    writer.write_varint(len(skeleton.end_site_parents))
    writer.write_array(skeleton.parents + 1, np.uint16)
    writer.write_array(np.array([_ORDERS.index(o) for o in skeleton.channel_orders]), np.uint8)
    writer.write_array(skeleton.offsets, np.float32)
    writer.write_array(skeleton.end_site_parents, np.uint16)
    writer.write_array(skeleton.end_site_offsets, np.float32)
    writer.write_blob("\0".join(skeleton.names).encode("utf-8"))
    outer = ByteWriter()
    outer.write_blob(zstd_compress(writer.getvalue()))
    return outer.getvalue()


def unpack_skeleton(reader: ByteReader) -> Skeleton:
    """Read a skeleton written by :func:`pack_skeleton` from ``reader``."""
    inner = ByteReader(zstd_decompress(reader.read_blob("skeleton"), _MAX_SKELETON_BYTES))
    num_joints = inner.read_varint("joint count")
    num_ends = inner.read_varint("end-site count")
    if not 1 <= num_joints <= 4096 or num_ends > 4096:
        raise BitstreamError(f"Skeleton: expected 1..4096 joints and <= 4096 end sites, found {num_joints}, {num_ends}.")
    parents = inner.read_array(num_joints, np.uint16, "parents").astype(np.int64) - 1
    order_index = inner.read_array(num_joints, np.uint8, "channel orders")
    if order_index.size and order_index.max() >= len(_ORDERS):
        raise BitstreamError(f"Skeleton: channel order index must be < 6, found {order_index.max()}.")
    offsets = inner.read_array(num_joints * 3, np.float32, "offsets").reshape(num_joints, 3)
    end_parents = inner.read_array(num_ends, np.uint16, "end-site parents").astype(np.int64)
    end_offsets = inner.read_array(num_ends * 3, np.float32, "end-site offsets").reshape(num_ends, 3)
    names = bytes(inner.read_blob("joint names")).decode("utf-8", errors="strict").split("\0")
    try:
        return Skeleton(
            names=tuple(names),
            parents=parents,
            offsets=offsets.astype(np.float64),
            channel_orders=tuple(_ORDERS[i] for i in order_index),
            end_site_parents=end_parents,
            end_site_offsets=end_offsets.astype(np.float64),
        )
    except ValueError as error:
        raise BitstreamError(f"Skeleton in the stream is invalid: {error}") from error
