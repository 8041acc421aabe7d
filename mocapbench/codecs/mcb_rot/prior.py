"""A prior for ``mcb-rot`` streams (payload format 6, settings flag :data:`~.stream.PRIOR`, bit 15): the rigs of
the training clips, so that a stream of one of them names it by index instead of carrying it.

A short clip of a game capture pays a fixed price for its rig: the skeleton part (names, parents, offsets on the
stream's grid) and the still root section, a sizeable share of a fine stream of a few seconds (the README has the
figures). Every clip of one studio's capture shares a handful of rigs (one per
actor), so a prior fit on its training clips (:meth:`Prior.fit`) holds each distinct rig once, and a stream whose
rig is one of them writes, in place of the skeleton part and the still root section::

    u32 the prior's fingerprint (CRC32 of its bytes) | svarint the offsets' grid exponent | varint rig index

and, where no rounding is too close to call (:func:`first_means`), the first segment's quantized means are coded
as differences from those the rig's mean signal predicts (a u8 before the segment means says which): on a game rig
the pelvis height and most joints' mean rotations are much the same from clip to clip. The decoder rebuilds the
skeleton part from the prior's rig at that exponent (:func:`.skeleton6.pack_skeleton_runtime`,
then its reader), so it decodes the very skeleton the stream would have carried, and with it the same budgets and
steps. A rig the prior lacks (another actor, another studio) is
coded as without the prior, byte for byte. Decoding a stream with the flag needs the same prior: another one, or
none, fails in one line naming the fingerprint.

The prior's bytes (what a model file holds and ``model_bytes`` reports)::

    u8 version (1) | varint K rigs | K x rig
    rig: varint J | varint E | varints J - 1 parent steps | varints E end-site parents | (J + E) x 3 f64 offsets cm |
         varint n + n bytes: the J channel-order bytes and the names (varint length + NUL-separated UTF-8) |
         u8 1 and the still root section (:mod:`.static_root`) or u8 0 | (3 + 3 J) f64 the mean coded signal

Offsets are kept as float64, so the rig rounds onto any stream's grid exactly as the clip's own skeleton does. A
prior is untrusted input (a model file may come from anyone): every count is bounded and every field is checked as
a stream's would be; a bad prior raises :class:`ValueError` naming what is wrong.
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mocapbench.codecs.mcb_rot import quaternions as quat
from mocapbench.codecs.mcb_rot.axes import to_axes
from mocapbench.codecs.mcb_rot.skeleton6 import pack_skeleton_runtime, unpack_skeleton_runtime
from mocapbench.codecs.mcb_rot.static_root import StaticRoot, read_static_root, split_static_root
from mocapbench.codecs.skeleton_blob import _ORDERS, STEP_EXPONENTS, skeleton_from_fields
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.motion import Motion, Skeleton

__all__ = ["Prior", "Rig"]

_VERSION = 1
_MAX_RIGS = 4096
_MAX_JOINTS = 4096
_MAX_OFFSET_CM = 1e6


@dataclass(frozen=True, eq=False)
class Rig:
    """One rig of the prior: the skeleton a stream codes (without its still root) and that still root, if any."""

    skeleton: Skeleton
    still: StaticRoot | None
    mean: np.ndarray | None = None  # (3 + 3 J,) the mean coded signal: root position cm, rotation vectors rad

    def write(self, writer: ByteWriter) -> None:
        skeleton = self.skeleton
        writer.write_varint(skeleton.num_joints)
        writer.write_varint(len(skeleton.end_site_parents))
        writer.write_varints(np.arange(1, skeleton.num_joints) - skeleton.parents[1:])
        writer.write_varints(skeleton.end_site_parents)
        writer.write_array(np.concatenate([skeleton.offsets, skeleton.end_site_offsets]).astype(np.float64),
                           np.float64)
        rest = ByteWriter()
        rest.write_array(np.array([_ORDERS.index(o) for o in skeleton.channel_orders]), np.uint8)
        rest.write_blob("\0".join(skeleton.names).encode("utf-8"))
        writer.write_blob(rest.getvalue())
        writer.write_u8(self.still is not None)
        if self.still is not None:
            self.still.write(writer)
        if self.mean is not None:  # (always, but in the key that finds a training clip's rig)
            writer.write_array(self.mean.astype(np.float64), np.float64)

    def stream_part(self, exponent: int) -> bytes:
        """The skeleton part a stream without the prior writes for this rig on the grid ``2^exponent`` cm."""
        return pack_skeleton_runtime(self.skeleton, exponent)

    def same_still(self, still: StaticRoot | None) -> bool:
        """Whether ``still`` is this rig's still root as a stream keeps it (name, order, float32 offset, position)."""
        if self.still is None or still is None:
            return self.still is None and still is None
        return (self.still.name == still.name and self.still.order == still.order
                and np.array_equal(np.float32(self.still.offset), np.float32(still.offset))
                and np.array_equal(np.float32(self.still.position), np.float32(still.position)))


def _read_rig(reader: ByteReader) -> Rig:
    num_joints = reader.read_varint("joint count")
    num_ends = reader.read_varint("end-site count")
    if not 1 <= num_joints <= _MAX_JOINTS or num_ends > _MAX_JOINTS:
        raise BitstreamError(f"expected 1..{_MAX_JOINTS} joints and <= {_MAX_JOINTS} end sites, found {num_joints}, "
                             f"{num_ends}")
    steps = reader.read_varints(num_joints - 1, "parents").astype(np.int64)
    parents = np.concatenate([[-1], np.arange(1, num_joints) - steps])
    if np.any(parents[1:] < 0):
        raise BitstreamError("a joint's parent comes after it")
    end_parents = reader.read_varints(num_ends, "end-site parents").astype(np.int64)
    offsets = reader.read_array(3 * (num_joints + num_ends), np.float64, "offsets").reshape(-1, 3)
    if not np.all(np.abs(offsets) <= _MAX_OFFSET_CM):
        raise BitstreamError("an offset is not finite or beyond 1e6 cm")
    inner = ByteReader(reader.read_blob("names", 1 << 20))
    order_index = inner.read_array(num_joints, np.uint8, "channel orders")
    if order_index.size and order_index.max() >= len(_ORDERS):
        raise BitstreamError(f"channel order index must be < {len(_ORDERS)}, found {order_index.max()}")
    skeleton = skeleton_from_fields(inner, num_joints, parents, offsets, order_index, end_parents)
    has_still = reader.read_u8("still root flag")
    if has_still > 1:
        raise BitstreamError(f"the still root flag must be 0 or 1, found {has_still}")
    still = read_static_root(reader) if has_still else None
    mean = reader.read_array(3 + 3 * num_joints, np.float64, "mean signal")
    if not np.all(np.abs(mean) <= _MAX_OFFSET_CM):
        raise BitstreamError("a mean of the signal is not finite or beyond 1e6")
    return Rig(skeleton, still, mean)


@dataclass(frozen=True, eq=False)
class Prior:
    """The distinct rigs of the training clips (module docstring), with the bytes they are stored as."""

    rigs: tuple[Rig, ...]
    data: bytes  # the prior's bytes (module docstring): what a model file holds and model_bytes counts

    @property
    def fingerprint(self) -> int:
        """CRC32 of :attr:`data`: a stream coded against this prior carries it."""
        return zlib.crc32(self.data)

    @property
    def main_joints(self) -> int:
        """Joint count of the first rig (the whole rig, its still root included): a model file's joint count."""
        rig = self.rigs[0]
        return rig.skeleton.num_joints + (rig.still is not None)

    @classmethod
    def of_rigs(cls, rigs: Sequence[Rig]) -> "Prior":
        if not 1 <= len(rigs) <= _MAX_RIGS:
            raise ValueError(f"mcb-rot: a prior holds 1..{_MAX_RIGS} rigs, got {len(rigs)}.")
        writer = ByteWriter()
        writer.write_u8(_VERSION)
        writer.write_varint(len(rigs))
        for rig in rigs:
            rig.write(writer)
        return cls(tuple(rigs), writer.getvalue())

    @classmethod
    def fit(cls, motions: Sequence[Motion], static_root: bool = True) -> "Prior":
        """The distinct rigs of ``motions`` (each kept once, in the order first met), each split from its still root
        as the encoder splits it (``static_root``: the codec's setting)."""
        if not motions:
            raise ValueError("mcb-rot: fitting a prior needs at least one training motion, got none.")
        rigs: dict[bytes, tuple[Rig, np.ndarray, int]] = {}  # rig key -> (rig, signal sum, frames)
        for motion in motions:
            split = split_static_root(motion) if static_root else None
            coded = motion if split is None else split[1]
            rig = Rig(coded.skeleton, None if split is None else split[0])
            buffer = ByteWriter()
            rig.write(buffer)
            signal = _signal(coded)
            known, total, frames = rigs.get(buffer.getvalue(), (rig, 0.0, 0))
            rigs[buffer.getvalue()] = (known, total + signal.sum(axis=0), frames + len(signal))
        with_means = [Rig(rig.skeleton, rig.still, total / frames) for rig, total, frames in rigs.values()]
        return cls.from_bytes(cls.of_rigs(with_means).data)  # the rigs as a decoder reads them (float32 still roots)

    @classmethod
    def from_bytes(cls, data: bytes) -> "Prior":
        """The prior stored as ``data``; :class:`ValueError` naming the first field that is wrong."""
        data = bytes(data)
        reader = ByteReader(data)
        try:
            version = reader.read_u8("prior version")
            if version != _VERSION:
                raise BitstreamError(f"version {version}, this mocapbench reads {_VERSION}")
            count = reader.read_varint("rig count")
            if not 1 <= count <= _MAX_RIGS:
                raise BitstreamError(f"expected 1..{_MAX_RIGS} rigs, found {count}")
            rigs = tuple(_read_rig(reader) for _ in range(count))
            reader.expect_end("the prior")
        except BitstreamError as error:
            raise ValueError(f"mcb-rot: the prior is malformed: {error}".rstrip(".") + ".") from None
        return cls(rigs, data)

    def match(self, skeleton: Skeleton, still: StaticRoot | None, exponent: int) -> int | None:
        """Index of the rig whose stream part on the grid ``2^exponent`` equals ``skeleton``'s and whose still
        root is ``still``; None when there is none (the stream then carries its rig)."""
        part = pack_skeleton_runtime(skeleton, exponent)
        for index, rig in enumerate(self.rigs):
            same_rig = rig.skeleton.num_joints == skeleton.num_joints and rig.stream_part(exponent) == part
            if same_rig and rig.same_still(still):
                return index
        return None

    def write_reference(self, writer: ByteWriter, exponent: int, index: int) -> None:
        """The stream's reference to rig ``index`` (module docstring)."""
        writer.write_u32(self.fingerprint)
        writer.write_svarint(exponent)
        writer.write_varint(index)


def _signal(motion: Motion) -> np.ndarray:
    """(F, 3 + 3 J) the signal a stream codes: root position cm, then each joint's rotation vector rad (the
    quaternion's sign chosen per frame for w >= 0; the encoder chooses it per segment, which the mean hardly sees)."""
    quats = motion.rotations * np.where(motion.rotations[..., 3:] < 0, -1.0, 1.0)
    rotvecs = quat.log_map(quats).reshape(motion.num_frames, -1)
    return np.concatenate([motion.root_positions, rotvecs], axis=1)


def first_means(prior_mean: np.ndarray, axes: np.ndarray, base_steps: np.ndarray, segment_frames: int):
    """(C,) int: the quantized means of a stream's first segment predicted from its rig's mean signal, or None.

    ``prior_mean`` (3 + 3 J,) the rig's mean (root cm, rotation vectors rad), turned onto the stream's principal
    ``axes`` (J, 3, 3); ``base_steps`` (C,) the stream's base steps (multiplier x channel steps). The orthonormal
    DCT's DC of a segment of n frames is sqrt(n) times its mean and its step is ``base sqrt(n / segment_frames)``,
    so the quantized mean is ``mean sqrt(segment_frames) / base``, rounded. Floating point decides a rounding here,
    so a value within 1e-6 of a rounding boundary (where a decoder on another machine, its last bits different,
    could round the other way) makes the prediction None: the stream then says so (a byte) and codes the means as
    without a prior.
    """
    num_joints = len(axes)
    values = np.concatenate([prior_mean[:3], to_axes(prior_mean[3:].reshape(num_joints, 3), axes).ravel()])
    scaled = values * np.sqrt(float(segment_frames)) / base_steps
    if not np.all(np.abs(scaled) < 2.0**40):
        return None
    fraction = scaled - np.floor(scaled)
    if np.any(np.abs(fraction - 0.5) < 1e-6):
        return None
    return np.floor(scaled + 0.5).astype(np.int64)


def read_reference(reader: ByteReader, prior: Prior | None) -> tuple[Skeleton, StaticRoot | None, np.ndarray]:
    """The skeleton, still root and mean signal of the rig a stream with the prior flag names, from ``prior``.

    Raises
    ------
    BitstreamError
        No prior held, another prior (fingerprints differ), an exponent outside the grid's, or a rig index the
        prior lacks.
    """
    fingerprint = reader.read_u32("prior fingerprint")
    if prior is None:
        raise BitstreamError(f"mcb-rot: the stream was coded against a prior (model {fingerprint:08x}) and this codec "
                             "holds none; decode it with that model (--model).")
    if prior.fingerprint != fingerprint:
        raise BitstreamError(f"mcb-rot: the stream was coded against prior {fingerprint:08x}, this codec holds "
                             f"{prior.fingerprint:08x}; decode it with the model it was coded with.")
    exponent = reader.read_svarint("offset grid exponent")
    if exponent not in STEP_EXPONENTS:
        raise BitstreamError(f"mcb-rot: expected an offset grid exponent in [{STEP_EXPONENTS[0]}, "
                             f"{STEP_EXPONENTS[-1]}], found {exponent}.")
    index = reader.read_varint("prior rig index")
    if index >= len(prior.rigs):
        raise BitstreamError(f"mcb-rot: the stream names rig {index} of the prior, which holds {len(prior.rigs)}.")
    rig = prior.rigs[index]
    return unpack_skeleton_runtime(ByteReader(rig.stream_part(exponent))), rig.still, rig.mean
