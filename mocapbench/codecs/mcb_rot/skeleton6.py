"""The skeleton of a format 6 stream: what a native sampler needs in plain bits, the rest zstd-compressed.

:func:`~mocapbench.codecs.skeleton_blob.pack_skeleton_compact` compresses the whole skeleton with zstd against a
name dictionary; a decoder in C with nothing beyond the standard library cannot read it. Format 6 splits it::

    svarint grid exponent e (offsets on 2^e cm) | varint J | varint E | varints J - 1 parent steps (j - parent)
    varints E end-site parents
    varint n + n bytes: the offsets of the joints then the end sites, bit-packed (skeleton_blob's layout)
    varint n + n bytes: zstd (name dictionary) of the J channel-order bytes and the names (varint length +
    NUL-separated UTF-8)

The runtime reads the first parts (the error budgets, hence the quantization steps, follow from the bones and, when
the stream's bound covers them, the end sites) and skips the last. The offsets are on the same grid as format 4's, so the stored skeleton is the same.
"""

from __future__ import annotations

import numpy as np

from mocapbench.codecs.skeleton_blob import (
    _MAX_SKELETON_BYTES,
    _ORDERS,
    NAME_DICTIONARY,
    STEP_EXPONENTS,
    _pack_offsets,
    _unpack_offsets,
    skeleton_from_fields,
)
from mocapbench.entropy.backend import zstd_compress, zstd_decompress
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.motion import Skeleton

__all__ = ["pack_skeleton_runtime", "unpack_skeleton_runtime"]

_MAX_JOINTS = 4096


def pack_skeleton_runtime(skeleton: Skeleton, step_exponent: int) -> bytes:
    """The skeleton in format 6's layout, offsets on the grid ``2^step_exponent`` cm (in :data:`STEP_EXPONENTS`)."""
    if step_exponent not in STEP_EXPONENTS:
        raise ValueError(f"Skeleton grid exponent must be in [{STEP_EXPONENTS[0]}, {STEP_EXPONENTS[-1]}], "
                         f"got {step_exponent}.")
    offsets = np.concatenate([skeleton.offsets, skeleton.end_site_offsets])
    writer = ByteWriter()
    writer.write_svarint(int(step_exponent))
    writer.write_varint(skeleton.num_joints)
    writer.write_varint(len(skeleton.end_site_parents))
    writer.write_varints(np.arange(1, skeleton.num_joints) - skeleton.parents[1:])
    writer.write_varints(skeleton.end_site_parents)
    writer.write_blob(_pack_offsets(np.round(offsets / 2.0**step_exponent).astype(np.int64)))
    rest = ByteWriter()
    rest.write_array(np.array([_ORDERS.index(o) for o in skeleton.channel_orders]), np.uint8)
    rest.write_blob("\0".join(skeleton.names).encode("utf-8"))
    writer.write_blob(zstd_compress(rest.getvalue(), dictionary=NAME_DICTIONARY))
    return writer.getvalue()


def unpack_skeleton_runtime(reader: ByteReader) -> Skeleton:
    """Read a skeleton written by :func:`pack_skeleton_runtime` (every count checked)."""
    exponent = reader.read_svarint("offset grid exponent")
    if exponent not in STEP_EXPONENTS:
        raise BitstreamError(f"Skeleton: expected an offset grid exponent in [{STEP_EXPONENTS[0]}, "
                             f"{STEP_EXPONENTS[-1]}], found {exponent}.")
    num_joints = reader.read_varint("joint count")
    num_ends = reader.read_varint("end-site count")
    if not 1 <= num_joints <= _MAX_JOINTS or num_ends > _MAX_JOINTS:
        raise BitstreamError(f"Skeleton: expected 1..{_MAX_JOINTS} joints and <= {_MAX_JOINTS} end sites, found "
                             f"{num_joints}, {num_ends}.")
    steps = reader.read_varints(num_joints - 1, "parents").astype(np.int64)
    parents = np.concatenate([[-1], np.arange(1, num_joints) - steps])
    if np.any(parents[1:] < 0):
        raise BitstreamError("Skeleton: a joint's parent comes after it.")
    end_parents = reader.read_varints(num_ends, "end-site parents").astype(np.int64)
    codes = _unpack_offsets(reader.read_blob("offsets"), num_joints + num_ends)
    step = 2.0**exponent
    if codes.size and np.abs(codes).max() > 1e6 / step + 1:
        raise BitstreamError("Skeleton: an offset exceeds 1e6 cm.")
    offsets = codes.astype(np.float64) * step
    inner = ByteReader(zstd_decompress(reader.read_blob("skeleton names"), _MAX_SKELETON_BYTES,
                                       dictionary=NAME_DICTIONARY))
    order_index = inner.read_array(num_joints, np.uint8, "channel orders")
    if order_index.size and order_index.max() >= len(_ORDERS):
        raise BitstreamError(f"Skeleton: channel order index must be < 6, found {order_index.max()}.")
    return skeleton_from_fields(inner, num_joints, parents, offsets, order_index, end_parents)
