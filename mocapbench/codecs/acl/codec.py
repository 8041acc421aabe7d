"""``acl``: the Animation Compression Library 2.1 (Frechette; github.com/nfrechette/acl) as a measured codec.

The production reference for skeletal clips (the codec behind Unreal Engine's ACL plugin). Each joint becomes
one ACL ``qvvf`` transform track: its local rotation, its local translation (the root's position; the bone
offset, constant, for every other joint) and a unit scale. ``compress_track_list`` compresses them with the
``qvvf_transform_error_metric`` (ACL's default), a per-track ``precision`` (cm) and ``shell_distance`` (cm)
and ACL's recommended settings (``get_default_compression_settings()``: variable bit rates, loop optimization,
trivial keyframe stripping), with the level, the formats and those two switches exposed as config fields.
Every frame is decoded through ACL's ``decompression_context`` (seek to ``frame / fps``, nearest sample,
``decompress_tracks``), the same sampling ACL's own error measurement uses. The decoder rebuilds the full
:class:`Motion` from the decoded local rotations and root translation on the skeleton carried in the stream;
positions are its forward kinematics.

Stream payload: the skeleton blob (:mod:`mocapbench.codecs.skeleton_blob`: names, parents, channel orders,
offsets, end sites; a few hundred bytes for CMU's 31 joints) then ACL's compressed buffer (varint length +
bytes, exactly ``compressed_tracks::get_size()`` bytes). The results row gets ``acl_buffer_bytes`` and
``acl_overhead_bytes`` (container header + skeleton + lengths) so that ACL's own ratio can be recovered.
The buffer is validated by ACL's ``is_valid(check_hash=true)`` (size, tag, version, hash) before a
decompression context touches it; anything wrong is a :class:`BitstreamError`.

Departures: none from ACL itself (unmodified 2.1.0 headers). What is ours: the mapping of a :class:`Motion` to
tracks (bone offsets as constant translation tracks, which ACL stores losslessly as constants) and the decoded
positions, computed by mocapbench's forward kinematics from ACL's decoded rotations and root translation.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from mocapbench.codecs.acl.binding import LEVELS, ROTATION_FORMATS, TRANSLATION_FORMATS, AclError, load_library
from mocapbench.codecs.acl.build import AclSetupError
from mocapbench.codecs import container
from mocapbench.codecs.base import Codec, CodecConfig, Decoded, Header, param
from mocapbench.codecs.registry import CodecUnavailableError
from mocapbench.codecs.skeleton_blob import pack_skeleton, unpack_skeleton
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.motion import Motion

__all__ = ["AclCodec"]

# ACL's buffers and offsets are 32-bit: keep the raw track data (10 float32 per joint per frame, ACL's own raw
# size definition) well below 4 GiB so that no size inside ACL can overflow.
MAX_RAW_BYTES = 1 << 31
_FLOAT32_MAX = float(np.finfo(np.float32).max)


def _check_motion(motion: Motion) -> None:
    """One clear line for a motion ACL cannot take.

    Zero frames and NaN/inf never get here: :class:`Motion` refuses them with one line on construction.
    """
    frames, joints = motion.num_frames, motion.num_joints
    if 40 * frames * joints >= MAX_RAW_BYTES:
        raise ValueError(
            f"acl: {frames} frames x {joints} joints is {40 * frames * joints} bytes of raw tracks, over ACL's "
            f"32-bit buffer limit of {MAX_RAW_BYTES} bytes; split the clip."
        )
    for name, values in (("root position", motion.root_positions), ("bone offset", motion.skeleton.offsets)):
        too_big = np.abs(values) > _FLOAT32_MAX / 2
        if too_big.any():
            index = tuple(int(i) for i in np.argwhere(too_big)[0])
            raise ValueError(f"acl: {name} at {index} is {values[index]} cm, outside ACL's float32 range.")
    if not np.isfinite(motion.fps) or not 0 < motion.fps < 1e6:
        raise ValueError(f"acl: fps must be in (0, 1e6) for ACL's float32 sample rate, got {motion.fps}.")


class AclCodec(Codec):
    """ACL 2.1 through a compiled C++ shim: local rotations + translations, qvvf error metric, shell distance."""

    name = "acl"
    codes_rotations = True
    family = "production"
    random_access = True  # ACL seeks any sample directly: decode_frames decompresses only the frames asked for
    smoke_params = {"precision_cm": 0.01, "shell_cm": 3.0}
    smoke_max_error_cm = 0.05

    @dataclass(frozen=True)
    class Config(CodecConfig):
        precision_cm: float = param(
            0.01, low=1e-5, high=100.0, unit="cm",
            doc="ACL's per-track precision: target of the shell error of every joint (ACL's default 0.01 cm)",
        )
        shell_cm: float = param(
            3.0, low=0.0, high=1000.0, unit="cm",
            doc="ACL's shell distance: the virtual vertices where the error is measured (0: on the joints themselves)",
        )
        level: str = param("highest", choices=tuple(LEVELS), doc="ACL's compression level (how hard it searches bit rates)")
        rotation_format: str = param(
            "quatf_drop_w_variable", choices=tuple(ROTATION_FORMATS), doc="ACL's rotation format"
        )
        translation_format: str = param(
            "vector3f_variable", choices=tuple(TRANSLATION_FORMATS), doc="ACL's translation format"
        )
        optimize_loops: bool = param(True, doc="drop a last frame equal to the first and play with wrap (ACL default)")
        strip_trivial_keyframes: bool = param(
            True, doc="remove keyframes rebuilt within precision by interpolation (ACL default; variable formats only)"
        )
        acl_dir: str = param(
            "", doc="folder with ACL 2.1 + rtm headers (empty: $MOCAPBENCH_ACL_DIR, else ../shared/third_party/acl-2.1.0)"
        )

    @property
    def latency_frames(self) -> int:
        return -1  # ACL compresses a whole clip

    def _library(self):
        try:
            return load_library(self.config.acl_dir or None)
        except AclSetupError as error:
            raise CodecUnavailableError(f"codec 'acl' is unavailable here: {error}") from error

    def encode_payload(self, motion: Motion) -> bytes:
        _check_motion(motion)
        config = self.config
        library = self._library()
        rotations = motion.rotations.astype(np.float32)
        translations = np.empty((motion.num_frames, motion.num_joints, 3), dtype=np.float32)
        translations[:, 0] = motion.root_positions
        translations[:, 1:] = motion.skeleton.offsets[1:]
        variable = config.rotation_format.endswith("variable") or config.translation_format.endswith("variable")
        try:
            buffer = library.compress(
                rotations, translations, motion.skeleton.parents.astype(np.int32), motion.fps,
                precision_cm=config.precision_cm, shell_cm=config.shell_cm, level=config.level,
                rotation_format=config.rotation_format, translation_format=config.translation_format,
                optimize_loops=config.optimize_loops,
                # ACL refuses keyframe stripping without a variable format ("no contributing error").
                strip_trivial=config.strip_trivial_keyframes and variable,
            )
        except AclError as error:
            raise ValueError(f"acl: {error}") from error
        writer = ByteWriter()
        writer.write_bytes(pack_skeleton(motion.skeleton))
        writer.write_blob(buffer)
        payload = writer.getvalue()
        header_bytes = len(container.pack(self.name, motion.num_frames, motion.num_joints, motion.fps, b""))
        self.last_encode_stats = {
            "acl_buffer_bytes": len(buffer),
            "acl_overhead_bytes": header_bytes + len(payload) - len(buffer),  # container + skeleton + length
            "acl_version": library.acl_version,
        }
        return payload

    def _read(self, header: Header, payload: memoryview):
        reader = ByteReader(payload)
        skeleton = unpack_skeleton(reader)
        if skeleton.num_joints != header.num_joints:
            raise BitstreamError(f"acl: header says {header.num_joints} joints, skeleton has {skeleton.num_joints}.")
        buffer = bytes(reader.read_blob("ACL buffer"))
        reader.expect_end()
        library = self._library()
        try:
            info = library.info(buffer)
        except AclError as error:
            raise BitstreamError(f"acl: {error}.") from error
        if info.num_tracks != header.num_joints:
            raise BitstreamError(f"acl: ACL buffer holds {info.num_tracks} tracks, header says {header.num_joints} joints.")
        # With loop optimization ACL drops a last frame equal to the first and plays with wrap.
        if info.num_samples not in (header.num_frames, header.num_frames - 1) or info.num_samples == 0:
            raise BitstreamError(f"acl: ACL buffer holds {info.num_samples} samples, header says {header.num_frames} frames.")
        return skeleton, buffer, info, library

    def _decode_range(self, header: Header, payload: memoryview, start: int, stop: int):
        """Positions and Motion of frames ``start:stop`` through ACL's decompression context."""
        skeleton, buffer, _, library = self._read(header, payload)
        try:
            rotations, translations = library.decompress(buffer, header.num_joints, start, stop)
        except AclError as error:
            raise BitstreamError(f"acl: {error}.") from error
        rotations = rotations.astype(np.float64)
        if not (np.all(np.isfinite(rotations)) and np.all(np.isfinite(translations))):
            raise BitstreamError("acl: ACL decoded non-finite values.")
        if np.any(np.linalg.norm(rotations, axis=-1) < 0.5):
            raise BitstreamError("acl: ACL decoded a quaternion far from unit length.")
        motion = Motion(skeleton=skeleton, fps=header.fps, root_positions=translations[:, 0].astype(np.float64),
                        rotations=rotations)
        return motion.positions(), motion

    def decode_payload(self, header: Header, payload: memoryview):
        return self._decode_range(header, payload, 0, header.num_frames)

    def decode_frames(self, data: bytes, start: int, stop: int) -> Decoded:
        """Frames ``start:stop`` only: ACL seeks each sample directly, nothing else is decompressed.

        Returns a :class:`Decoded` whose positions (``stop - start``, J, 3) and motion cover those frames (the header
        still describes the whole stream).

        Raises
        ------
        ValueError
            If ``start:stop`` is empty or outside the stream's frames.
        BitstreamError
            If the stream is corrupt.
        """
        header, payload = self._unpack_frame_range(data, start, stop)
        positions, motion = self._decode_range(header, payload, start, stop)
        return Decoded(positions=positions, motion=motion, header=header)

    def describe_payload(self, header: Header, payload: memoryview) -> dict[str, Any]:
        _, buffer, info, library = self._read(header, payload)
        return {
            "acl_version": library.acl_version,
            "acl_buffer_bytes": len(buffer),
            "samples": info.num_samples,
            "sample_rate": info.sample_rate,
            "rotation_format": info.rotation_format,
            "translation_format": info.translation_format,
        }
