"""Generic baselines: what a user would pick instead of a research codec.

* ``raw-zstd``: float32 joint positions through zstd, lossless. The floor every lossy codec must beat.
* ``quant-delta-zstd``: positions uniformly quantized with a step in cm, delta-coded along time, zstd.
  Its step sets the error (per coordinate ≤ step/2, so ≤ step·√3/2 per joint), giving a full RD curve.
* ``quant-pred-zstd``: the strongest generic pipeline, the anchor of the BD-rate tables. The same quantized
  positions as ``quant-delta-zstd``, laid out channel-major (one channel's whole track, then the next), predicted
  along time with order 1 (``q[t] - q[t-1]``) or order 2 (``q[t] - 2 q[t-1] + q[t-2]``), whichever gives the
  smaller stream, then zigzag, narrowest width, **byte shuffle** (Blosc's filter: all low bytes, then all high
  bytes) and zstd. On ``cmu_test`` it is 14-16 % smaller than ``quant-delta-zstd`` at the same step (same
  decoded positions); brotli -q 11 instead of zstd gave 1-3 % less, so zstd stays (no new dependency). A long
  capture's tracks are streamed through zstd one track (and byte plane) at a time, in the same format.
* ``quant-rot-zstd``: local rotations and root translation quantized and zstd-coded, decoded through FK;
  the way game engines store clips. Each quaternion is made scalar-positive (``w >= 0``), its x, y, z are
  range-reduced per joint over the clip and quantized to ``rotation_bits``, ``w`` is rebuilt from the unit
  norm (ACL's "drop W" format, ``quatf_drop_w_variable``). Tracks constant over the clip cost no bits per frame.
  A game rig's translation tracks (joints that move relative to their parent) are quantized with the root's step
  and its scale tracks with ``scale_step``, in a section after the rotations that a motion without them does not
  write (its stream is the bytes it always was; streams written before the section decode as they did).

All three byte-plane the quantized integers per channel (time-major, delta-coded) before zstd, which is
what makes a general-purpose compressor see the temporal coherence.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapbench.codecs.base import Codec, CodecConfig, Header, param
from mocapbench.codecs.registry import register_codec
from mocapbench.codecs.skeleton_blob import pack_skeleton, unpack_skeleton
from mocapbench.entropy.backend import (
    zstd_compress_chunks,
    zstd_decompress_chunks,
    zstd_pack_tracks,
    zstd_unpack_tracks,
)
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.entropy.quantize import quantize
from mocapbench.motion import Motion, OwnedQuaternions

__all__ = ["RawZstdCodec", "QuantDeltaZstdCodec", "QuantPredZstdCodec", "QuantRotZstdCodec"]

_ZSTD_LEVEL_DOC = "zstd compression level (higher: smaller and slower to encode; decode speed barely changes)"


# Frames per block when a long capture is turned into positions or integers block by block.
_BLOCK_FRAMES = 8192


def _block_positions(motion: Motion, start: int) -> np.ndarray:
    """Positions (b, J, 3) cm of frames ``start .. start + _BLOCK_FRAMES`` (forward kinematics of that block)."""
    return motion.slice(start, min(motion.num_frames, start + _BLOCK_FRAMES)).positions()


def _track_codes(values: np.ndarray, channel: int) -> np.ndarray:
    """Zigzag codes of the deltas along time of one channel (the first delta is against 0)."""
    from mocapbench.entropy.bitio import zigzag_encode

    column = values[:, channel].astype(np.int64)
    return zigzag_encode(np.diff(column, prepend=np.int64(0)))


def _pack_int_tracks(values: np.ndarray, level: int) -> bytes:
    """Delta-code integer tracks along time and zstd them channel by channel (the layout of ``zstd_pack_ints`` of the
    channel-major deltas: a width byte, then one zstd frame).

    One channel is coded at a time (two passes: the width, then the bytes), so nothing beside ``values`` is
    F x C sized.

    Parameters
    ----------
    values : ndarray, shape (F, C), integer
        C integer tracks of F samples.
    """
    num_frames, num_channels = values.shape
    peak = max((int(_track_codes(values, c).max()) for c in range(num_channels)), default=0) if num_frames else 0
    width = next(w for w in (1, 2, 4, 8) if peak < 1 << (8 * w))
    chunks = (_track_codes(values, c).astype(f"<u{width}").tobytes() for c in range(num_channels))
    return bytes([width]) + zstd_compress_chunks(chunks, num_frames * num_channels * width, level=level)


def _unpack_int_tracks(blob: bytes, num_frames: int, num_channels: int, sink=None) -> np.ndarray | None:
    """Inverse of :func:`_pack_int_tracks`: ``(F, C)`` int64, or each channel handed to ``sink(channel, values)``.

    With a ``sink``, one channel at a time is held (a long capture is never held as F x C integers).
    """
    from mocapbench.entropy.bitio import zigzag_decode

    blob = memoryview(blob).cast("B")
    if len(blob) < 1 or blob[0] not in (1, 2, 4, 8):
        raise BitstreamError(f"integer tracks: expected a width byte of 1, 2, 4 or 8, found {bytes(blob[:1])!r}")
    width = blob[0]
    out = None
    if sink is None:
        out = np.empty((num_frames, num_channels), dtype=np.int64)

        def sink(channel: int, column: np.ndarray) -> None:
            out[:, channel] = column

    track_bytes = num_frames * width
    pending, channel = bytearray(), 0
    for piece in zstd_decompress_chunks(blob[1:], num_frames * num_channels * width):
        pending += piece
        while len(pending) >= track_bytes and channel < num_channels:
            codes = np.frombuffer(bytes(pending[:track_bytes]), dtype=f"<u{width}").astype(np.uint64)
            del pending[:track_bytes]
            sink(channel, np.cumsum(zigzag_decode(codes).astype(np.int64)))
            channel += 1
    if num_frames == 0:
        for channel in range(num_channels):
            sink(channel, np.zeros(0, dtype=np.int64))
    return out


@register_codec
class RawZstdCodec(Codec):
    """Lossless float32 joint positions through zstd (the floor every lossy codec must beat)."""

    name = "raw-zstd"
    family = "generic"
    # float32 positions: beyond 1 km a float32 step exceeds 0.008 cm and the "lossless" floor stops being one.
    max_coordinate_cm = 1e5
    smoke_max_error_cm = 1e-3  # float32 rounding only

    @dataclass(frozen=True)
    class Config(CodecConfig):
        zstd_level: int = param(19, low=1, high=22, doc=_ZSTD_LEVEL_DOC)

    def encode_payload(self, motion: Motion) -> bytes:
        # Block by block into one zstd frame: a long capture's positions are never held whole.
        chunks = (_block_positions(motion, start).astype("<f4").tobytes()
                  for start in range(0, motion.num_frames, _BLOCK_FRAMES))
        return zstd_compress_chunks(chunks, motion.num_frames * motion.num_joints * 12, level=self.config.zstd_level)

    def decode_payload(self, header: Header, payload: memoryview):
        expected = header.num_frames * header.num_joints * 12
        positions = np.empty((header.num_frames, header.num_joints, 3))
        flat, done, pending = positions.reshape(-1), 0, b""
        for piece in zstd_decompress_chunks(payload, expected):  # straight into the output, no float32 copy
            pending += piece
            usable = len(pending) - len(pending) % 4
            values = np.frombuffer(pending[:usable], dtype="<f4")
            flat[done : done + values.size] = values
            done += values.size
            pending = pending[usable:]
        if done * 4 != expected:
            raise BitstreamError(f"raw-zstd: expected {expected} bytes of positions, found {done * 4}.")
        return positions, None


@register_codec
class QuantDeltaZstdCodec(Codec):
    """Uniformly quantized positions, delta-coded along time, zstd: the generic lossy baseline."""

    name = "quant-delta-zstd"
    family = "generic"
    smoke_params = {"step_cm": 0.1}
    smoke_max_error_cm = 0.1 * 3**0.5 / 2 + 1e-9  # step/2 per coordinate

    @dataclass(frozen=True)
    class Config(CodecConfig):
        step_cm: float = param(0.1, low=1e-4, high=100.0, unit="cm", doc="quantization step of each coordinate")
        zstd_level: int = param(19, low=1, high=22, doc=_ZSTD_LEVEL_DOC)

    def encode_payload(self, motion: Motion) -> bytes:
        step = self.config.step_cm
        indices = np.empty((motion.num_frames, 3 * motion.num_joints), dtype=np.int64)
        for start in range(0, motion.num_frames, _BLOCK_FRAMES):  # positions block by block, never whole
            block = _block_positions(motion, start)
            indices[start : start + len(block)] = quantize(block.reshape(len(block), -1), step)
        writer = ByteWriter()
        writer.write_array(np.array([step]), np.float64)
        writer.write_blob(_pack_int_tracks(indices, self.config.zstd_level))
        return writer.getvalue()

    def decode_payload(self, header: Header, payload: memoryview):
        reader = ByteReader(payload)
        step = float(reader.read_array(1, np.float64, "step")[0])
        if not (step > 0 and np.isfinite(step)):
            raise BitstreamError(f"quant-delta-zstd: expected a positive step, found {step}.")
        blob = reader.read_blob("positions")
        reader.expect_end()
        positions = np.empty((header.num_frames, 3 * header.num_joints))

        def dequantize(channel: int, indices: np.ndarray) -> None:
            positions[:, channel] = indices * step

        _unpack_int_tracks(blob, header.num_frames, header.num_joints * 3, dequantize)
        return positions.reshape(header.num_frames, header.num_joints, 3), None

    def describe_payload(self, header: Header, payload: memoryview):
        return {"step_cm": float(ByteReader(payload).read_array(1, np.float64, "step")[0])}


_MAX_ORDER2_INDEX = 1 << 60  # second differences of larger indices could overflow int64


def _channel_major_indices(motion: Motion, step: float) -> np.ndarray:
    """Quantized positions as channel-major tracks ``(3J, F)``, block by block: int32 while they fit (half the
    memory of the positions array), int64 otherwise."""
    tracks = np.empty((3 * motion.num_joints, motion.num_frames), dtype=np.int32)
    for start in range(0, motion.num_frames, _BLOCK_FRAMES):
        block = _block_positions(motion, start)
        indices = quantize(block.reshape(len(block), -1), step)
        if tracks.dtype == np.int32 and np.abs(indices).max() > np.iinfo(np.int32).max:
            tracks = tracks.astype(np.int64)
        tracks[:, start : start + len(block)] = indices.T
    return tracks


def _predict(indices: np.ndarray, order: int) -> np.ndarray:
    """Residuals of order-1 or order-2 prediction along the last axis (the first samples kept as they are).

    Parameters
    ----------
    indices : ndarray, shape (C, F), int64 (channel-major tracks)
    order : 1 or 2
    """
    residuals = np.diff(indices, axis=1, prepend=np.zeros((indices.shape[0], 1), dtype=np.int64))
    if order == 2:
        residuals[:, 2:] = np.diff(residuals[:, 1:], axis=1)
    return residuals


def _reconstruct(residuals: np.ndarray, order: int) -> np.ndarray:
    """Inverse of :func:`_predict`."""
    firsts = residuals.copy()
    if order == 2:
        firsts[:, 1:] = np.cumsum(residuals[:, 1:], axis=1)
    return np.cumsum(firsts, axis=1)


@register_codec
class QuantPredZstdCodec(Codec):
    """Quantized positions, channel-major, order-1/2 temporal prediction, byte shuffle, zstd: the generic anchor."""

    name = "quant-pred-zstd"
    family = "generic"
    smoke_params = {"step_cm": 0.1}
    smoke_max_error_cm = 0.1 * 3**0.5 / 2 + 1e-9  # step/2 per coordinate

    @dataclass(frozen=True)
    class Config(CodecConfig):
        step_cm: float = param(0.1, low=1e-4, high=100.0, unit="cm", doc="quantization step of each coordinate")
        zstd_level: int = param(19, low=1, high=22, doc=_ZSTD_LEVEL_DOC)

    @property
    def latency_frames(self) -> int:
        return -1  # the order is chosen over the whole clip

    def encode_payload(self, motion: Motion) -> bytes:
        """The channel-major tracks streamed through zstd (:func:`zstd_pack_tracks`): memory is the quantized tracks
        (int32 where they fit: half the positions array) and one track, whatever the length; up to
        :data:`~mocapbench.entropy.backend.ONE_SHOT_VALUES` values the bytes are those of a one-shot zstd."""
        step = self.config.step_cm
        tracks = _channel_major_indices(motion, step)  # (3J, F)
        peak = max(int(tracks.max()), -int(tracks.min())) if tracks.size else 0  # no F-sized temporary
        orders = (1, 2) if peak < _MAX_ORDER2_INDEX else (1,)
        blobs = {order: zstd_pack_tracks(lambda c: _predict(tracks[c : c + 1], order)[0], tracks.shape[0],
                                         tracks.shape[1], self.config.zstd_level, shuffle=True)
                 for order in orders}
        order = min(orders, key=lambda o: len(blobs[o]))
        writer = ByteWriter()
        writer.write_array(np.array([step]), np.float64)
        writer.write_u8(order)
        writer.write_blob(blobs[order])
        self.last_encode_stats = {"prediction_order": order}
        return writer.getvalue()

    def decode_payload(self, header: Header, payload: memoryview):
        """Track by track into the output (:func:`zstd_unpack_tracks`): beside the positions, one track and the
        byte planes below the top one (``width - 1`` bytes per value; none for the usual 1-byte residuals)."""
        reader = ByteReader(payload)
        step = float(reader.read_array(1, np.float64, "step")[0])
        order = reader.read_u8("prediction order")
        if not (step > 0 and np.isfinite(step)) or order not in (1, 2):
            raise BitstreamError(f"quant-pred-zstd: expected a positive step and order 1 or 2, found {step}, {order}.")
        blob = reader.read_blob("positions")
        reader.expect_end()
        channels = 3 * header.num_joints
        positions = None  # allocated once the zstd frame's size has been checked against the header

        def dequantize(channel: int, residuals: np.ndarray) -> None:
            nonlocal positions
            if positions is None:
                positions = np.empty((header.num_frames, channels))
            positions[:, channel] = _reconstruct(residuals[None], order)[0] * step

        zstd_unpack_tracks(blob, channels, header.num_frames, dequantize, "positions", shuffle=True)
        return positions.reshape(header.num_frames, header.num_joints, 3), None

    def describe_payload(self, header: Header, payload: memoryview):
        reader = ByteReader(payload)
        step = float(reader.read_array(1, np.float64, "step")[0])
        return {"step_cm": step, "prediction_order": reader.read_u8("prediction order")}


@register_codec
class QuantRotZstdCodec(Codec):
    """Quantized local rotations (drop-W quaternions) and root translation, zstd, decoded through FK."""

    name = "quant-rot-zstd"
    family = "generic"
    codes_rotations = True
    carries_tracks = ("translations", "scales")
    smoke_params = {"rotation_bits": 12, "translation_step_cm": 0.05}
    smoke_max_error_cm = 0.5

    @dataclass(frozen=True)
    class Config(CodecConfig):
        rotation_bits: int = param(12, low=2, high=24, unit="bits", doc="bits per quaternion x, y, z over its range")
        translation_step_cm: float = param(
            0.05, low=1e-4, high=100.0, unit="cm", doc="step of the root translation and of every translation track"
        )
        scale_step: float = param(1e-4, low=1e-7, high=1.0, doc="step of the scale tracks (unitless)")
        zstd_level: int = param(19, low=1, high=22, doc=_ZSTD_LEVEL_DOC)

    def encode_payload(self, motion: Motion) -> bytes:
        num_frames = motion.num_frames

        def xyz_block(start: int) -> np.ndarray:  # (b, 3J) x, y, z of the quaternions with w >= 0
            quats = motion.rotations[start : start + _BLOCK_FRAMES]
            return (quats * np.where(quats[..., 3:] < 0, -1.0, 1.0))[..., :3].reshape(len(quats), -1)

        blocks = range(0, num_frames, _BLOCK_FRAMES)
        # Bounds rounded to float32 first: the decoder sees exactly the grid the encoder used.
        low = np.min([xyz_block(start).min(axis=0) for start in blocks], axis=0).astype(np.float32).astype(np.float64)
        high = np.max([xyz_block(start).max(axis=0) for start in blocks], axis=0).astype(np.float32).astype(np.float64)
        levels = (1 << self.config.rotation_bits) - 1
        scale = np.where(high > low, (high - low) / levels, 1.0)
        step = self.config.translation_step_cm
        tracks = np.empty((num_frames, 3 + low.size), dtype=np.int64)
        tracks[:, :3] = quantize(motion.root_positions, step)
        for start in blocks:
            tracks[start : start + _BLOCK_FRAMES, 3:] = np.rint((xyz_block(start) - low) / scale)
        writer = ByteWriter()
        writer.write_bytes(pack_skeleton(motion.skeleton))
        writer.write_array(np.array([step]), np.float64)
        writer.write_varint(self.config.rotation_bits)
        writer.write_array(low, np.float32)
        writer.write_array(high, np.float32)
        writer.write_blob(_pack_int_tracks(tracks, self.config.zstd_level))
        if motion.translations is not None or motion.scales is not None:
            self._write_joint_tracks(writer, motion)
        return writer.getvalue()

    def _write_joint_tracks(self, writer: ByteWriter, motion: Motion) -> None:
        """The game-rig section: varint T, varint S, the T translated then the S scaled joints (varints, increasing),
        f64 scale step, then one blob of the 3 T + 3 S integer tracks (translations cm / translation step, scales /
        scale step), coded as the rotations' tracks."""
        moving, scaled = motion.moving_joints(), motion.scaled_joints()
        writer.write_varint(len(moving))
        writer.write_varint(len(scaled))
        writer.write_varints(np.concatenate([moving, scaled]))
        writer.write_array(np.array([self.config.scale_step]), np.float64)
        tracks = np.empty((motion.num_frames, 3 * (len(moving) + len(scaled))), dtype=np.int64)
        if len(moving):
            tracks[:, : 3 * len(moving)] = quantize(motion.translations[:, moving], self.config.translation_step_cm
                                                    ).reshape(motion.num_frames, -1)
        if len(scaled):
            tracks[:, 3 * len(moving) :] = quantize(motion.scales[:, scaled], self.config.scale_step
                                                    ).reshape(motion.num_frames, -1)
        writer.write_blob(_pack_int_tracks(tracks, self.config.zstd_level))

    def decode_payload(self, header: Header, payload: memoryview):
        reader = ByteReader(payload)
        skeleton = unpack_skeleton(reader)
        if skeleton.num_joints != header.num_joints:
            raise BitstreamError(f"quant-rot-zstd: header says {header.num_joints} joints, skeleton has {skeleton.num_joints}.")
        step = float(reader.read_array(1, np.float64, "translation step")[0])
        bits = reader.read_varint("rotation bits")
        if not (step > 0 and np.isfinite(step)) or not 2 <= bits <= 24:
            raise BitstreamError(f"quant-rot-zstd: expected step > 0 and 2..24 bits, found {step}, {bits}.")
        channels = 3 * header.num_joints
        low = reader.read_array(channels, np.float32, "rotation minima").astype(np.float64)
        high = reader.read_array(channels, np.float32, "rotation maxima").astype(np.float64)
        blob = reader.read_blob("tracks")
        joint_tracks = self._read_joint_tracks(reader, header, skeleton, step) if reader.remaining else None
        reader.expect_end()
        scale = np.where(high > low, (high - low) / ((1 << bits) - 1), 1.0)
        num_frames = header.num_frames
        roots = np.empty((num_frames, 3))
        quats = np.empty((num_frames, header.num_joints, 4))

        def dequantize(channel: int, indices: np.ndarray) -> None:  # one track at a time, into the motion's arrays
            if channel < 3:
                roots[:, channel] = indices * step
            else:
                c = channel - 3
                quats[:, c // 3, c % 3] = low[c] + indices * scale[c]

        _unpack_int_tracks(blob, num_frames, 3 + channels, dequantize)
        for start in range(0, num_frames, _BLOCK_FRAMES):
            xyz = quats[start : start + _BLOCK_FRAMES, :, :3]
            quats[start : start + _BLOCK_FRAMES, :, 3] = np.sqrt(np.clip(1.0 - np.sum(xyz**2, axis=-1), 0.0, None))
        translations = scales = None
        if joint_tracks is not None:
            translations, scales = joint_tracks
            translations[:, 0] = roots
        # The quaternions are handed over for keeps: Motion normalizes them in place instead of copying them.
        motion = Motion(skeleton=skeleton, fps=header.fps, root_positions=roots, rotations=OwnedQuaternions(quats),
                        translations=translations, scales=scales)
        return motion.positions(), motion

    def _read_joint_tracks(self, reader: ByteReader, header: Header, skeleton, step: float):
        """(translations (F, J, 3) cm, scales (F, J, 3) or None) of the game-rig section, every field checked."""
        num_joints, num_frames = header.num_joints, header.num_frames
        counts = [reader.read_varint("translated joints"), reader.read_varint("scaled joints")]
        if counts[0] > num_joints - 1 or counts[1] > num_joints or sum(counts) == 0:
            raise BitstreamError(f"quant-rot-zstd: expected at most {num_joints - 1} translated and {num_joints} "
                                 f"scaled joints (some), found {counts[0]} and {counts[1]}.")
        joints = reader.read_varints(sum(counts), "tracked joints").astype(np.int64)
        moving, scaled = joints[: counts[0]], joints[counts[0] :]
        for kind, chosen, first in (("translated", moving, 1), ("scaled", scaled, 0)):
            if len(chosen) and (chosen[0] < first or chosen[-1] >= num_joints or np.any(np.diff(chosen) <= 0)):
                raise BitstreamError(f"quant-rot-zstd: {kind} joints must be increasing in {first}..{num_joints - 1}.")
        scale_step = float(reader.read_array(1, np.float64, "scale step")[0])
        if not (np.isfinite(scale_step) and 0 < scale_step <= 1.0):
            raise BitstreamError(f"quant-rot-zstd: expected a scale step in (0, 1], found {scale_step}.")
        values = _unpack_int_tracks(reader.read_blob("joint tracks"), num_frames, 3 * sum(counts))
        translations = np.broadcast_to(skeleton.offsets, (num_frames, num_joints, 3)).copy()
        translations[:, moving] = values[:, : 3 * len(moving)].reshape(num_frames, -1, 3) * step
        scales = None
        if len(scaled):
            scales = np.ones((num_frames, num_joints, 3))
            scales[:, scaled] = values[:, 3 * len(moving) :].reshape(num_frames, -1, 3) * scale_step
            if np.any(scales <= 0):
                raise BitstreamError("quant-rot-zstd: a decoded scale is <= 0.")
        return translations, scales

    def describe_payload(self, header: Header, payload: memoryview):
        reader = ByteReader(payload)
        skeleton = unpack_skeleton(reader)
        step = float(reader.read_array(1, np.float64, "translation step")[0])
        return {
            "rotation_bits": reader.read_varint("rotation bits"),
            "translation_step_cm": step,
            "skeleton joints": skeleton.num_joints,
        }
