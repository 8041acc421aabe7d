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
from mocapbench.entropy.bitio import ByteReader, ByteWriter, zigzag_decode, zigzag_encode
from mocapbench.entropy.errors import BitstreamError
from mocapbench.motion import Skeleton

__all__ = ["pack_skeleton", "unpack_skeleton", "pack_skeleton_compact", "unpack_skeleton_compact"]

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
            channel_orders=tuple([_ORDERS[i] for i in order_index.tolist()]),
            end_site_parents=end_parents,
            end_site_offsets=end_offsets.astype(np.float64),
        )
    except ValueError as error:
        raise BitstreamError(f"Skeleton in the stream is invalid: {error}") from error


# -- compact layout (mcb-rot) ------------------------------------------------------------------------------------
# Joint names most skeletons share, as zstd's raw-content dictionary: the CMU ASF and BVH trees (what the benchmark
# codes), then common names of other rigs. A stream whose names match costs a few bytes for them instead of ~200.
# Part of the format: BE CAREFUL WHEN CHANGING (old streams decode only with the same text).
NAME_DICTIONARY = "\0".join(
    [
        "Hips", "Spine", "Spine1", "Spine2", "Spine3", "Chest", "UpperChest", "Neck", "Neck1", "Head", "HeadTop_End",
        "LeftShoulder", "LeftArm", "LeftUpperArm", "LeftForeArm", "LeftLowerArm", "LeftHand", "LeftHandThumb1",
        "LeftHandIndex1", "LeftHandMiddle1", "LeftUpLeg", "LeftUpperLeg", "LeftLeg", "LeftLowerLeg", "LeftFoot",
        "LeftToeBase", "LeftToe_End", "RightShoulder", "RightArm", "RightUpperArm", "RightForeArm", "RightLowerArm",
        "RightHand", "RightHandThumb1", "RightHandIndex1", "RightHandMiddle1", "RightUpLeg", "RightUpperLeg",
        "RightLeg", "RightLowerLeg", "RightFoot", "RightToeBase", "RightToe_End", "pelvis", "spine_01", "neck_01",
        "head", "clavicle_l", "upperarm_l", "lowerarm_l", "hand_l", "thigh_l", "calf_l", "foot_l", "ball_l",
        "mixamorig:",
        # CMU ASF, then CMU BVH, in file order (the longest matches come last: zstd looks back from the end).
        "root", "lhipjoint", "lfemur", "ltibia", "lfoot", "ltoes", "rhipjoint", "rfemur", "rtibia", "rfoot", "rtoes",
        "lowerback", "upperback", "thorax", "lowerneck", "upperneck", "head", "lclavicle", "lhumerus", "lradius",
        "lwrist", "lhand", "lfingers", "lthumb", "rclavicle", "rhumerus", "rradius", "rwrist", "rhand", "rfingers",
        "rthumb",
        "Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "RHipJoint", "RightUpLeg",
        "RightLeg", "RightFoot", "RightToeBase", "LowerBack", "Spine", "Spine1", "Neck", "Neck1", "Head",
        "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "LeftFingerBase", "LeftHandIndex1", "LThumb",
        "RightShoulder", "RightArm", "RightForeArm", "RightHand", "RightFingerBase", "RightHandIndex1", "RThumb",
    ]
).encode()
#: Grid of the compact layout's offsets, cm, unless the blob names its own (2^-16: 1.5e-5 cm; the codec takes the
#: change off its error bound).
OFFSET_STEP_CM = 2.0**-16
_MAX_OFFSET_CM = 1e6
#: Grid exponents a blob may name: offsets on 2^e cm.
STEP_EXPONENTS = range(-40, 11)


def pack_skeleton_compact(skeleton: Skeleton, step_exponent: int | None = None) -> bytes:
    """The skeleton as a smaller self-delimiting blob than :func:`pack_skeleton`, for codecs that bound the error.

    Offsets are rounded to a grid and written as zigzag varints (exact zeros and short bones cost a byte or two, not
    four), parents as ``j - parent``, names compressed against :data:`NAME_DICTIONARY`. The unpacked skeleton's
    offsets differ from the original's by at most half a grid step per coordinate. The grid is
    :data:`OFFSET_STEP_CM`, or with ``step_exponent`` (in :data:`STEP_EXPONENTS`) ``2^step_exponent`` cm, written
    first in the blob (read it back with ``unpack_skeleton_compact(reader, stepped=True)``): a codec whose bound is
    coarse keeps coarser offsets, in fewer bytes; the offsets are then bit-packed (:func:`_pack_offsets`), 12 %
    smaller than zstd over varints on the CMU rig.

    Raises
    ------
    ValueError
        If an offset exceeds 1e6 cm, or the exponent is outside :data:`STEP_EXPONENTS`.
    """
    offsets = np.concatenate([skeleton.offsets, skeleton.end_site_offsets]).ravel()
    if offsets.size and np.abs(offsets).max() > _MAX_OFFSET_CM:
        raise ValueError(f"Skeleton offsets must be within {_MAX_OFFSET_CM:g} cm, got {np.abs(offsets).max():g} cm.")
    step = OFFSET_STEP_CM
    writer = ByteWriter()
    if step_exponent is not None:
        if step_exponent not in STEP_EXPONENTS:
            raise ValueError(f"Skeleton grid exponent must be in [{STEP_EXPONENTS[0]}, {STEP_EXPONENTS[-1]}], "
                             f"got {step_exponent}.")
        writer.write_svarint(int(step_exponent))
        step = 2.0 ** int(step_exponent)
    writer.write_varint(skeleton.num_joints)
    writer.write_varint(len(skeleton.end_site_parents))
    writer.write_varints(np.arange(1, skeleton.num_joints) - skeleton.parents[1:])
    writer.write_array(np.array([_ORDERS.index(o) for o in skeleton.channel_orders]), np.uint8)
    codes = np.round(offsets / step).astype(np.int64)
    if step_exponent is None:
        writer.write_varints(zigzag_encode(codes))
    else:
        writer.write_blob(_pack_offsets(codes.reshape(-1, 3)))
    writer.write_varints(skeleton.end_site_parents)
    writer.write_blob("\0".join(skeleton.names).encode("utf-8"))
    outer = ByteWriter()
    outer.write_blob(zstd_compress(writer.getvalue(), dictionary=NAME_DICTIONARY))
    return outer.getvalue()


def unpack_skeleton_compact(reader: ByteReader, stepped: bool = False) -> Skeleton:
    """Read a skeleton written by :func:`pack_skeleton_compact` from ``reader`` (``stepped``: with a ``step_exponent``)."""
    inner = ByteReader(zstd_decompress(reader.read_blob("skeleton"), _MAX_SKELETON_BYTES, dictionary=NAME_DICTIONARY))
    step = OFFSET_STEP_CM
    if stepped:
        exponent = inner.read_svarint("offset grid exponent")
        if exponent not in STEP_EXPONENTS:
            raise BitstreamError(f"Skeleton: expected an offset grid exponent in [{STEP_EXPONENTS[0]}, "
                                 f"{STEP_EXPONENTS[-1]}], found {exponent}.")
        step = 2.0**exponent
    num_joints = inner.read_varint("joint count")
    num_ends = inner.read_varint("end-site count")
    if not 1 <= num_joints <= 4096 or num_ends > 4096:
        raise BitstreamError(f"Skeleton: expected 1..4096 joints and <= 4096 end sites, found {num_joints}, {num_ends}.")
    steps = inner.read_varints(num_joints - 1, "parents").astype(np.int64)
    parents = np.concatenate([[-1], np.arange(1, num_joints) - steps])
    order_index = inner.read_array(num_joints, np.uint8, "channel orders")
    if order_index.size and order_index.max() >= len(_ORDERS):
        raise BitstreamError(f"Skeleton: channel order index must be < 6, found {order_index.max()}.")
    if stepped:
        codes = _unpack_offsets(inner.read_blob("offsets"), num_joints + num_ends)
        if codes.size and np.abs(codes).max() > _MAX_OFFSET_CM / step + 1:
            raise BitstreamError("Skeleton: an offset exceeds 1e6 cm.")
    else:
        codes = inner.read_varints(3 * (num_joints + num_ends), "offsets")
        if codes.size and codes.max() > 2 * _MAX_OFFSET_CM / step + 2:
            raise BitstreamError("Skeleton: an offset exceeds 1e6 cm.")
        codes = zigzag_decode(codes.astype(np.int64))
    offsets = codes.astype(np.float64).reshape(-1, 3) * step
    end_parents = inner.read_varints(num_ends, "end-site parents").astype(np.int64)
    return skeleton_from_fields(inner, num_joints, parents, offsets, order_index, end_parents)


def _pack_offsets(codes: np.ndarray) -> bytes:
    """Offsets on the grid, (V, 3) int64, bit-packed: u8 ``W`` (bit length of the largest magnitude), then the bits
    (MSB first, byte-padded) of: V - 1 flags "vector v repeats an earlier one" (an ASF rig repeats its clavicle and
    thumb offsets); each repeat's first occurrence in ``bit_length(V - 1)`` bits; a nonzero flag per coordinate of
    the other vectors; a sign bit and ``W`` magnitude bits per nonzero coordinate."""
    first = {}
    source = np.full(len(codes), -1, dtype=np.int64)
    for index, vector in enumerate(map(tuple, codes.tolist())):
        if vector in first and any(vector):
            source[index] = first[vector]
        first.setdefault(vector, index)
    repeated = source >= 0
    fresh = codes[~repeated].ravel()
    nonzero = fresh[fresh != 0]
    width = int(np.abs(nonzero).max()).bit_length() if nonzero.size else 0
    index_bits = max(len(codes) - 1, 0).bit_length()
    parts = [repeated[1:].astype(np.int64), _bits(source[repeated], index_bits), (fresh != 0).astype(np.int64),
             (nonzero < 0).astype(np.int64), _bits(np.abs(nonzero), width)]
    return bytes([width]) + np.packbits(np.concatenate(parts).astype(np.uint8)).tobytes()


def _bits(values: np.ndarray, width: int) -> np.ndarray:
    """The ``width`` low bits of each of ``values`` (N,), MSB first, flattened (N * width,)."""
    return ((values[:, None] >> np.arange(width - 1, -1, -1)) & 1).ravel()


def _unpack_offsets(data: bytes, count: int) -> np.ndarray:
    """Inverse of :func:`_pack_offsets` for ``count`` vectors: (count, 3) int64, checked."""
    if len(data) == 0 or data[0] > 62:
        raise BitstreamError(f"Skeleton: expected offsets of at most 62 bits, found {data[:1]!r}.")
    width = data[0]
    bits = np.unpackbits(np.frombuffer(data, np.uint8)[1:]).astype(np.int64)
    index_bits = max(count - 1, 0).bit_length()
    at = 0

    def take(n: int, what: str) -> np.ndarray:
        nonlocal at
        if at + n > len(bits):
            raise BitstreamError(f"Skeleton: the offsets end inside their {what}.")
        at += n
        return bits[at - n : at]

    repeated = np.concatenate([[False], take(max(count - 1, 0), "repeat flags").astype(bool)])[:count]
    source = _values(take(int(repeated.sum()) * index_bits, "repeat sources"), index_bits)
    fresh = take(3 * int(count - repeated.sum()), "zero flags").astype(bool)
    signs = take(int(fresh.sum()), "signs")
    magnitudes = _values(take(int(fresh.sum()) * width, "magnitudes"), width)
    values = np.zeros(fresh.size, dtype=np.int64)
    values[fresh] = np.where(signs == 1, -magnitudes, magnitudes)
    codes = np.zeros((count, 3), dtype=np.int64)
    codes[~repeated] = values.reshape(-1, 3)
    targets = np.flatnonzero(repeated)
    if np.any(source >= targets) or np.any(repeated[source]):
        raise BitstreamError("Skeleton: a repeated offset names a later or repeated one.")
    codes[targets] = codes[source]
    if len(bits) - at >= 8:
        raise BitstreamError(f"Skeleton: {(len(bits) - at) // 8} bytes follow the offsets.")
    return codes


def _values(bits: np.ndarray, width: int) -> np.ndarray:
    """Inverse of :func:`_bits`."""
    if width == 0:
        return np.zeros(len(bits), dtype=np.int64)
    return bits.reshape(-1, width) @ (np.int64(1) << np.arange(width - 1, -1, -1))


def skeleton_from_fields(inner, num_joints: int, parents: np.ndarray, offsets: np.ndarray, order_index: np.ndarray,
                         end_parents: np.ndarray) -> Skeleton:
    """The last step of reading a skeleton blob (formats of :mod:`skeleton_blob` and mcb-rot format 6 alike): the
    joint names, the end of the blob, and the :class:`Skeleton` built from the fields read before.

    ``offsets``: (J + E, 3) float, cm, the joints' then the end sites'. A field the skeleton refuses (a parent after
    its child, names not UTF-8, ...) raises :class:`BitstreamError`.
    """
    names = bytes(inner.read_blob("joint names")).decode("utf-8", errors="strict").split("\0")
    inner.expect_end("skeleton")
    try:
        return Skeleton(
            names=tuple(names),
            parents=parents,
            offsets=offsets[:num_joints],
            channel_orders=tuple([_ORDERS[i] for i in order_index.tolist()]),
            end_site_parents=end_parents,
            end_site_offsets=offsets[num_joints:],
        )
    except (ValueError, UnicodeDecodeError) as error:
        raise BitstreamError(f"Skeleton in the stream is invalid: {error}") from error
