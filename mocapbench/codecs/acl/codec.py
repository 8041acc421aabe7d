"""``acl``: the Animation Compression Library 2.1 (Frechette; github.com/nfrechette/acl) as a measured codec.

The production reference for skeletal clips (the codec behind Unreal Engine's ACL plugin). Each joint becomes
one ACL ``qvvf`` transform track: its local rotation, its local translation (the root's position; for every other
joint its translation track where it moves, as a game rig's pelvis, else its bone offset, constant) and its scale
(1 unless the motion has a scale track). ``compress_track_list`` compresses them with the
``qvvf_transform_error_metric`` (ACL's default), a per-track ``precision`` (cm) and ``shell_distance`` (cm)
and ACL's recommended settings (``get_default_compression_settings()``: variable bit rates, loop optimization,
trivial keyframe stripping), with the level, the formats and those two switches exposed as config fields.
``pre_process`` runs ACL's optional ``pre_process_track_list`` on the raw tracks first, as ACL's documentation
recommends after import: its recommended actions (normalize rotations, optimize looping, collapse constant and
default sub-tracks to one sample) under the lossy policy with the same error metric. ACL's optimizer otherwise
spends bits chasing raw values that its constant and default sub-tracks can never reach; with it the tracks it
compresses are themselves within precision of the raw ones, so the error measured against the source is the sum
of both steps (the sweep takes ACL at whichever setting gives the better front).
Every frame is decoded through ACL's ``decompression_context`` (seek to ``frame / fps``, nearest sample,
``decompress_tracks``), the same sampling ACL's own error measurement uses. The decoder rebuilds the full
:class:`Motion` from the decoded local rotations, translations and scales on the skeleton carried in the stream;
positions are its forward kinematics.

Stream payload: the skeleton blob (:mod:`mocapbench.codecs.skeleton_blob`: names, parents, channel orders,
offsets, end sites; a few hundred bytes for CMU's 31 joints) then ACL's compressed buffer (varint length +
bytes, exactly ``compressed_tracks::get_size()`` bytes). A capture of more than
:data:`~mocapbench.codecs.windows.WINDOW_FRAMES` frames (64 s at 120 fps) is compressed as consecutive windows of
that many frames, each its own ACL clip: after the skeleton, the window length (varint, frames), then one buffer
per window. ACL holds a whole clip's raw and lossy tracks while it compresses (and its 32-bit offsets cap a clip
near 4 GiB), so this keeps encode and decode memory to one window beside the motion whatever the length; every
clip up to a window keeps the one-buffer layout, byte for byte. The results row gets ``acl_buffer_bytes`` and
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
from mocapbench.codecs.limits import DecodeLimits, using_limits
from mocapbench.codecs.registry import CodecUnavailableError
from mocapbench.codecs.skeleton_blob import pack_skeleton, unpack_skeleton
from mocapbench.codecs.windows import WINDOW_FRAMES
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.motion import Motion, OwnedQuaternions

__all__ = ["AclCodec"]

# ACL's buffers and offsets are 32-bit: keep the raw track data (10 float32 per joint per frame, ACL's own raw
# size definition) well below 4 GiB so that no size inside ACL can overflow.
MAX_RAW_BYTES = 1 << 31
_FLOAT32_MAX = float(np.finfo(np.float32).max)


def _check_motion(motion: Motion) -> None:
    """One clear line for a motion ACL cannot take (a long capture is checked window by window, as ACL sees it).

    Zero frames and NaN/inf never get here: :class:`Motion` refuses them with one line on construction.
    """
    frames, joints = min(motion.num_frames, WINDOW_FRAMES), motion.num_joints
    if 40 * frames * joints >= MAX_RAW_BYTES:
        raise ValueError(
            f"acl: {frames} frames x {joints} joints is {40 * frames * joints} bytes of raw tracks, over ACL's "
            f"32-bit buffer limit of {MAX_RAW_BYTES} bytes; split the clip."
        )
    tracks = [("root position", motion.root_positions), ("bone offset", motion.skeleton.offsets)]
    if motion.translations is not None:
        tracks.append(("translation", motion.translations))
    if motion.scales is not None:
        tracks.append(("scale", motion.scales))
    for name, values in tracks:
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
    carries_tracks = ("translations", "scales")  # ACL's qvvf tracks: a translation and a scale on every joint
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
        pre_process: bool = param(
            False,
            doc="run ACL's pre_process_track_list first (recommended actions, lossy, the same error metric)",
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
        library = self._library()
        writer = ByteWriter()
        writer.write_bytes(pack_skeleton(motion.skeleton))
        buffer_bytes = 0
        if motion.num_frames <= WINDOW_FRAMES:
            buffer = self._compress(library, motion)
            writer.write_blob(buffer)
            buffer_bytes = len(buffer)
        else:  # one ACL clip per window (module docstring)
            writer.write_varint(WINDOW_FRAMES)
            for start in range(0, motion.num_frames, WINDOW_FRAMES):
                buffer = self._compress(library, motion.slice(start, min(motion.num_frames, start + WINDOW_FRAMES)))
                writer.write_blob(buffer)
                buffer_bytes += len(buffer)
        payload = writer.getvalue()
        header_bytes = len(container.pack(self.name, motion.num_frames, motion.num_joints, motion.fps, b""))
        self.last_encode_stats = {
            "acl_buffer_bytes": buffer_bytes,
            "acl_overhead_bytes": header_bytes + len(payload) - buffer_bytes,  # container + skeleton + lengths
            "acl_version": library.acl_version,
        }
        if motion.num_frames > WINDOW_FRAMES:
            self.last_encode_stats["windows"] = -(-motion.num_frames // WINDOW_FRAMES)
        return payload

    def _compress(self, library, motion: Motion) -> bytes:
        """ACL's compressed buffer of one clip (a whole motion, or one window of a long capture)."""
        config = self.config
        rotations = motion.rotations.astype(np.float32)
        translations = motion.local_translations().astype(np.float32)  # the bone offset where a joint does not move
        scales = None if motion.scales is None else motion.scales.astype(np.float32)
        variable = config.rotation_format.endswith("variable") or config.translation_format.endswith("variable")
        try:
            return library.compress(
                rotations, translations, motion.skeleton.parents.astype(np.int32), motion.fps, scales=scales,
                precision_cm=config.precision_cm, shell_cm=config.shell_cm, level=config.level,
                rotation_format=config.rotation_format, translation_format=config.translation_format,
                optimize_loops=config.optimize_loops,
                # ACL refuses keyframe stripping without a variable format ("no contributing error").
                strip_trivial=config.strip_trivial_keyframes and variable, pre_process=config.pre_process,
            )
        except AclError as error:
            raise ValueError(f"acl: {error}") from error

    def _read(self, header: Header, payload: memoryview):
        """The skeleton, the ACL clips ``[(start, stop, buffer, info), ...]`` in frame order (one per window; each
        buffer validated by ACL, its tracks and samples checked against the header) and the library."""
        reader = ByteReader(payload)
        skeleton = unpack_skeleton(reader)
        if skeleton.num_joints != header.num_joints:
            raise BitstreamError(f"acl: header says {header.num_joints} joints, skeleton has {skeleton.num_joints}.")
        window_frames = header.num_frames
        if header.num_frames > WINDOW_FRAMES:
            window_frames = reader.read_varint("window frames")
            if window_frames < 1:
                raise BitstreamError(f"acl: expected at least 1 frame per window, found {window_frames}.")
        extents = []
        for start in range(0, header.num_frames, window_frames):  # every extent before any buffer is validated
            extents.append((start, min(header.num_frames, start + window_frames), reader.read_blob("ACL buffer")))
        reader.expect_end()
        library = self._library()
        clips = []
        for start, stop, view in extents:
            buffer = bytes(view)
            try:
                info = library.info(buffer)
            except AclError as error:
                raise BitstreamError(f"acl: {error}.") from error
            if info.num_tracks != header.num_joints:
                raise BitstreamError(
                    f"acl: ACL buffer holds {info.num_tracks} tracks, header says {header.num_joints} joints."
                )
            # With loop optimization ACL drops a last frame equal to the first and plays with wrap.
            if info.num_samples not in (stop - start, stop - start - 1) or info.num_samples == 0:
                raise BitstreamError(f"acl: ACL buffer holds {info.num_samples} samples, expected {stop - start} frames.")
            clips.append((start, stop, buffer, info))
        return skeleton, clips, library

    def _decode_range(self, header: Header, payload: memoryview, start: int, stop: int):
        """Positions and Motion of frames ``start:stop`` through ACL's decompression context, clip by clip into the
        motion's arrays (one window's float32 arrays beside them)."""
        skeleton, clips, library = self._read(header, payload)
        rotations = np.empty((stop - start, header.num_joints, 4))
        translations = np.empty((stop - start, header.num_joints, 3))
        scales = np.empty((stop - start, header.num_joints, 3))
        for clip_start, clip_stop, buffer, _ in clips:
            first, last = max(start, clip_start), min(stop, clip_stop)
            if first >= last:
                continue
            try:
                part, moved, scaled = library.decompress(
                    buffer, header.num_joints, first - clip_start, last - clip_start, scales=True
                )
            except AclError as error:
                raise BitstreamError(f"acl: {error}.") from error
            if not (np.all(np.isfinite(part)) and np.all(np.isfinite(moved)) and np.all(np.isfinite(scaled))):
                raise BitstreamError("acl: ACL decoded non-finite values.")
            if np.any(np.einsum("...i,...i->...", part, part) < 0.25):
                raise BitstreamError("acl: ACL decoded a quaternion far from unit length.")
            if np.any(scaled <= 0):
                raise BitstreamError("acl: ACL decoded a scale <= 0.")
            rotations[first - start : last - start] = part
            translations[first - start : last - start] = moved
            scales[first - start : last - start] = scaled
        # A joint that does not move is a constant track of its float32 bone offset, which ACL returns bit for bit
        # (the stored skeleton's offsets are those float32 values), and a joint that does not scale returns 1:
        # Motion stores such tracks as None, so a CMU clip decodes to the rotations-only motion it was.
        motion = Motion(skeleton=skeleton, fps=header.fps, root_positions=translations[:, 0],
                        rotations=OwnedQuaternions(rotations), translations=translations, scales=scales)
        return motion.positions(), motion

    def decode_payload(self, header: Header, payload: memoryview):
        return self._decode_range(header, payload, 0, header.num_frames)

    def decode_frames(self, data: bytes, start: int, stop: int, *, limits: DecodeLimits | None = None) -> Decoded:
        """Frames ``start:stop`` only: ACL seeks each sample directly, nothing else is decompressed.

        Returns a :class:`Decoded` whose positions (``stop - start``, J, 3) and motion cover those frames (the header
        still describes the whole stream). ``limits`` as in :meth:`decode`, applied to the frames asked for.

        Raises
        ------
        ValueError
            If ``start:stop`` is empty or outside the stream's frames.
        BitstreamError
            If the stream is corrupt.
        """
        header, payload = self._unpack_frame_range(data, start, stop)
        with using_limits(limits) as active:
            active.check_header(stop - start, header.num_joints, self.codes_rotations)
            positions, motion = self._decode_range(header, payload, start, stop)
        return Decoded(positions=positions, motion=motion, header=header)

    def describe_payload(self, header: Header, payload: memoryview) -> dict[str, Any]:
        _, clips, library = self._read(header, payload)
        info = clips[0][3]
        windows = {}
        if len(clips) > 1 or header.num_frames > WINDOW_FRAMES:
            windows = {"windows of frames (ACL clips)": f"{len(clips)} x {clips[0][1]} (first shown)"}
        return {
            **windows,
            "acl_version": library.acl_version,
            "acl_buffer_bytes": sum(len(clip[2]) for clip in clips),
            "samples": info.num_samples,
            "sample_rate": info.sample_rate,
            "rotation_format": info.rotation_format,
            "translation_format": info.translation_format,
        }
