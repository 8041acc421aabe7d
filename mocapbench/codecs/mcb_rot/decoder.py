"""The ``mcb-rot`` decoder: chunks read a block at a time into preallocated outputs.

A stream is a list of chunks (256 frames by default since payload format 5, 128 before), each an ANS stream of its
coefficients and corrections (the significance counts are in the payload header since format 4; :mod:`.stream`).
Decoding chunk by chunk would pay numpy's per-call overhead on arrays of a few thousand values, and decoding the
whole clip at once would hold every temporary of the clip. So consecutive chunks are decoded in *blocks* of at
least :data:`BLOCK_FRAMES` frames:

1. entropy, in two passes over the block's chunks: the ANS calls (one per class present, runs of 6 or more small
   classes in one call) stream by stream, then signs, raw bits, significance masks, classes and the sort that
   orders each stream by class, once for the block (:func:`mocapbench.entropy.ans.read_tokens`,
   :func:`~mocapbench.entropy.ans.values_of_tokens`); the sort keys are built chunk by chunk from per-length class
   rows gathered from a (channel, band) table;
2. synthesis: dequantization and one batched inverse DCT per segment length, rotation vectors off their principal
   axes and the exponential map (sin and cos of the half angle from one SIMD tan), the re-referenced segments and
   the corrections (:func:`.stream.segment_signal`, :func:`.stream.assemble`, :func:`.stream.apply_corrections`:
   the functions the encoder's closed loop uses, so its bound check sees bit-identical rotations);
3. forward kinematics of the block (:mod:`.kinematics`, compiled), which also writes the rotations into the
   output arrays, and the motion built without re-validating what the decoder made
   (:meth:`mocapbench.motion.Motion.from_decoder`).

Peak memory is the outputs (positions, rotations, roots) plus one block's temporaries, whatever the length of the
stream; :func:`decode_range` decodes only the blocks holding the frames asked for, synthesizes only their segments
holding those frames (a chunk is entropy decoded whole, one frame costs one 128-frame segment's inverse DCT), and
maps to quaternions, corrects and runs forward kinematics only on those frames.

Speed (cmu_test, 12 clips, 5,587 frames at 120 fps, one thread, CPU time, the benchmark's decode of every clip):
see :mod:`.codec`'s design notes.
"""

from __future__ import annotations

import numpy as np

from mocapbench.codecs.mcb_rot import kinematics, native
from mocapbench.codecs.mcb_rot.classes import NUM_CLASSES, band_of
from mocapbench.codecs.mcb_rot.scales import scales_of
from mocapbench.codecs.mcb_rot.scratch import Scratch, thread_scratch
from mocapbench.codecs.mcb_rot.stream import (
    StreamInfo,
    apply_corrections,
    assemble,
    runtime_tables,
    segment_signal,
    tables,
)
from mocapbench.entropy.rans6 import decode_unit
from mocapbench.entropy.ans import class_groups, read_tokens, values_of_tokens
from mocapbench.entropy.bitio import ByteReader
from mocapbench.entropy.errors import BitstreamError
from mocapbench.motion import _forward_kinematics, _tree_levels

__all__ = ["BLOCK_FRAMES", "decode_range", "decode_block"]

#: Frames decoded together (whole chunks, at least this many, unless the stream ends): large enough that numpy's
#: per-call costs are small against the work, small enough that the block's temporaries (about 1 KB per frame on a
#: 31-joint skeleton) stay in cache-sized pieces.
BLOCK_FRAMES = 2048
_SIDE = NUM_CLASSES  # classes >= this are the side tables (as in .stream)
_KEY_STRIDE = 2 * NUM_CLASSES  # classes of one stream lie in [0, 128)


def decode_range(
    info: StreamInfo, payload: memoryview, start: int, stop: int,
    out: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (n, J, 3) cm, roots (n, 3) cm and rotations (n, J, 4) of frames ``start:stop`` (n = stop - start).

    Decodes the blocks of chunks that hold those frames, each into the preallocated outputs (``out``, C-contiguous
    arrays of those shapes, when given: a window of a long capture decodes straight into the motion's arrays). The
    rotations are the decoded quaternions as forward kinematics used them (unit up to float rounding).

    Raises
    ------
    BitstreamError
        If a chunk is corrupt or inconsistent with the payload header.
    """
    layout = info.layout
    num_joints = info.skeleton.num_joints
    count = stop - start
    if out is None:
        out = np.empty((count, num_joints, 3)), np.empty((count, 3)), np.empty((count, num_joints, 4))
    positions, roots, quats = out[:3]
    translations = out[3] if len(out) > 3 else None  # (n, J, 3): the joints' steps, filled when the stream has tracks
    scales = out[4] if len(out) > 4 else None  # (n, J, 3): the joints' scales, filled when the stream has scale tracks
    if info.scales is not None:
        return _decode_scaled(info, payload, start, stop, (positions, roots, quats, translations, scales))
    moving = None if info.tracks is None else info.tracks.moving(num_joints)
    clip = native_clip(info, payload)
    if clip is not None and info.static_root is not None:
        return _native_inner(info, clip, start, stop, (positions, roots, quats, translations), moving)
    if clip is not None:  # the runtime samples the rotations (and tracks); forward kinematics here, as below
        into = quats if quats.flags.c_contiguous else np.empty(quats.shape)
        if info.tracks is None:
            roots_into = roots if roots.flags.c_contiguous else np.empty(roots.shape)
            clip.frames(start, stop, roots_into, into)
            roots[...] = roots_into
            kinematics.positions(into, roots_into, info.skeleton, positions, quats)
            return positions, roots, quats
        steps = translations if translations is not None and translations.flags.c_contiguous else np.empty(
            (count, num_joints, 3))
        clip.poses(start, stop, steps, into)
        roots[...] = steps[:, 0]
        if translations is not None and translations is not steps:
            translations[...] = steps
        kinematics.positions(into, roots, info.skeleton, positions, quats, translations=steps, moving=moving)
        return positions, roots, quats
    scratch = thread_scratch()
    first_segment = int(np.searchsorted(layout.starts, start, side="right")) - 1  # the segment holding ``start``
    for chunks in _blocks(info, layout.chunks_of_frames(start, stop)):
        # The block's chunks are entropy decoded whole; only its segments holding frames of start:stop are
        # synthesized (a chunk of several segments, when one frame is asked for).
        first = max(int(layout.starts[max(int(layout.chunk_starts[chunks[0]]), first_segment)]), start)
        block_roots, block_quats, block_steps, _ = decode_block(info, payload, chunks, scratch, (start, stop))
        low, high = max(first, start), min(first + len(block_roots), stop)
        inside, out = slice(low - first, high - first), slice(low - start, high - start)
        roots[out] = block_roots[inside]
        steps = None if block_steps is None else block_steps[inside]
        if steps is not None and translations is not None:
            translations[out] = steps
            translations[out, 0] = block_roots[inside]
        # The rotations (n, J, 4) are written by the forward kinematics kernel, out of the component-major block.
        kinematics.positions(block_quats[inside], block_roots[inside], info.skeleton, positions[out], quats[out],
                             translations=steps, moving=moving)
    scratch.trim()
    return positions, roots, quats


def _decode_scaled(info: StreamInfo, payload: memoryview, start: int, stop: int, out: tuple) -> tuple:
    """:func:`decode_range` of a stream with scale tracks (:mod:`.scales`; the runtime's rotations, translations and
    scales when it is built, else numpy's): positions by the matrix forward kinematics of
    :class:`~mocapbench.motion.Motion` with the decoded scales, the closed loop's (:class:`.checks.PointTargets`).
    ``out``: positions, roots, rotations, translations and scales (the last two (n, J, 3) or None)."""
    positions, roots, quats, translations, scales = out
    count, skeleton = stop - start, info.skeleton
    steps = np.empty((count, skeleton.num_joints, 3)) if translations is None else translations
    steps[:] = skeleton.offsets
    every = np.empty((count, skeleton.num_joints, 3)) if scales is None else scales
    layout = info.layout
    first_segment = int(np.searchsorted(layout.starts, start, side="right")) - 1
    clip = native_clip(info, payload)
    if clip is not None:
        contiguous = all(a.flags.c_contiguous for a in (steps, every, quats))
        into = (steps, every, quats) if contiguous else tuple(np.empty(a.shape) for a in (steps, every, quats))
        clip.poses(start, stop, into[0], into[2])
        clip.scales(start, stop, into[1])
        if not contiguous:
            steps[...], every[...], quats[...] = into
        roots[...] = steps[:, 0]
    for chunks in () if clip is not None else _blocks(info, layout.chunks_of_frames(start, stop)):
        first = max(int(layout.starts[max(int(layout.chunk_starts[chunks[0]]), first_segment)]), start)
        block_roots, block_quats, block_steps, block_scales = decode_block(info, payload, chunks, None, (start, stop))
        low, high = max(first, start), min(first + len(block_roots), stop)
        inside, into = slice(low - first, high - first), slice(low - start, high - start)
        roots[into] = block_roots[inside]
        quats[into] = block_quats[inside]
        if block_steps is not None:
            steps[into] = block_steps[inside]
        every[into] = block_scales[inside]
    steps[:, 0] = roots
    levels, ancestors = _tree_levels(skeleton.parents)
    positions[...] = _forward_kinematics(quats, roots, skeleton, levels, ancestors,
                                         translations=None if info.tracks is None else steps, scales=every)[1]
    return positions, roots, quats


def _native_inner(info: StreamInfo, clip, start: int, stop: int, out: tuple, moving) -> tuple:
    """:func:`decode_range`'s outputs (``out``: positions, roots, rotations, translations or None) of a stream with a
    still root kept apart (:mod:`.static_root`), from the runtime: it gives the whole rig (the still root as joint
    0, the stream's root as joint 1 with its translation from the still root), of which the stream's joints are
    kept here (the root's position added back), as the numpy path decodes them."""
    positions, roots, quats, translations = out
    count, num_joints = stop - start, info.skeleton.num_joints
    steps, rotations = np.empty((count, num_joints + 1, 3)), np.empty((count, num_joints + 1, 4))
    clip.poses(start, stop, steps, rotations)
    steps = steps[:, 1:]
    steps[:, 0] += info.static_root.position
    roots[...] = steps[:, 0]
    if translations is not None:
        translations[...] = steps
    kinematics.positions(rotations[:, 1:], roots, info.skeleton, positions, quats,
                         translations=None if moving is None else steps, moving=moving)
    return positions, roots, quats


def native_clip(info: StreamInfo, payload: memoryview):
    """The runtime's opened clip of a format 6 payload (kept in ``info``'s cache), or None: an older format, the
    runtime not built, or ``MOCAPBENCH_NATIVE=0``. A stream named against a prior (flag bit 15) opens with the
    prior's bytes ``read_info`` kept. The clip has the whole rig's joints (a still root kept apart, :mod:`.static_root`, is
    one more than the stream's skeleton)."""
    if info.version < 6:
        return None
    if "native" not in info._cache:
        lib = native.library()
        # fps 1: frames are asked for by index, the runtime's time-based sampling is not used here
        info._cache["native"] = None if lib is None else native.NativeClip(
            lib, payload, info.layout.num_frames, info.skeleton.num_joints + (info.static_root is not None), 1.0,
            info.prior_data)
    return info._cache["native"]


def _blocks(info: StreamInfo, chunks: np.ndarray) -> list[np.ndarray]:
    """``chunks`` (consecutive) cut into runs of at least :data:`BLOCK_FRAMES` frames (the last may hold fewer)."""
    layout = info.layout
    frames = layout.starts[layout.chunk_starts[chunks + 1] - 1] + layout.lengths[layout.chunk_starts[chunks + 1] - 1]
    frames = frames - layout.starts[layout.chunk_starts[chunks]]  # frames of each chunk
    blocks, begin, held = [], 0, 0
    for i, held_here in enumerate(frames.tolist()):
        held += held_here
        if held >= BLOCK_FRAMES:
            blocks.append(chunks[begin : i + 1])
            begin, held = i + 1, 0
    if begin < len(chunks):
        blocks.append(chunks[begin:])
    return blocks


def decode_block(
    info: StreamInfo, payload: memoryview, chunks: np.ndarray, scratch: Scratch | None = None,
    frames: tuple[int, int] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Roots (n, 3) cm, rotations (n, J, 4) (a view of a component-major array) of the consecutive ``chunks``,
    corrections applied, every joint's step from its parent (n, J, 3) cm when the stream has translation tracks
    (else None) and every joint's scale (n, J, 3) when it has scale tracks (else None). With ``scratch`` the rotations are a scratch view (valid until its next use).

    With ``frames`` (start, stop: frames of the stream), only the chunks' segments holding some of those frames
    are synthesized (the entropy decoding is the chunks' whole, the inverse DCT per segment), and only the frames
    asked for (those of ``start:stop`` in the chunks) go through the exponential map, the re-references and the
    corrections, and are returned: one frame costs its segment's inverse DCT, not its segment's quaternions.
    """
    layout = info.layout
    segments = np.arange(layout.chunk_starts[chunks[0]], layout.chunk_starts[chunks[-1] + 1])
    ac, flat, values, track_q, scale_q = read_chunks(info, payload, chunks, scratch)
    skip, returned = 0, 0  # frames of the block before those returned (counted from its first frame)
    if frames is None:
        signal = segment_signal(info, segments, ac, scratch)
    else:
        ends = layout.starts[segments] + layout.lengths[segments]
        low = int(np.searchsorted(ends, frames[0], side="right"))  # the first segment ending after start
        high = int(np.searchsorted(layout.starts[segments], frames[1], side="left"))  # past the last starting before stop
        begin = int(layout.starts[segments[low]])
        skip = max(frames[0] - begin, 0)  # frames of the first segment before start
        returned = begin + skip - int(layout.starts[segments[0]])
        held = min(frames[1], int(ends[high - 1])) - begin - skip  # frames returned
        if low > 0 or high < len(segments) or skip or held < int(ends[-1] - begin):
            slots = len(info.correction_steps)
            local = flat - (begin - int(layout.starts[segments[0]]) + skip) * slots
            keep = (local >= 0) & (local < held * slots)
            ac, flat, values, segments = ac[low:high], local[keep], values[keep], segments[low:high]
        signal = segment_signal(info, segments, ac, scratch)[:, skip : skip + held]
    roots, quats = assemble(info, segments, signal, scratch, skip)
    apply_corrections(info, roots, quats, flat, values)
    steps = scales = None
    if track_q is not None:
        steps = info.tracks.steps_of(info.skeleton, track_q[returned : returned + len(roots)])
    if scale_q is not None:
        scales = scales_of(info.scales, info.skeleton.num_joints, scale_q[returned : returned + len(roots)])
    return roots, quats, steps, scales


def _count_groups(info: StreamInfo, num_segments: int) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Sort order and class groups of the significance counts of a chunk of ``num_segments`` segments (cached)."""
    key = ("count groups", num_segments)
    if key not in info._cache:
        info._cache[key] = class_groups(info.count_classes(num_segments))
    return info._cache[key]


def read_chunks(
    info: StreamInfo, payload: memoryview, chunks: np.ndarray, scratch: Scratch | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Entropy-decode consecutive ``chunks`` (with ``scratch``, ``ac`` is a scratch view).

    Returns
    -------
    ac : ndarray, shape (S, C, P), float
        Quantized AC coefficients of the chunks' S segments, channel-major, zero-padded to ``P = max n_s - 1``.
    flat : ndarray, shape (N,), int
        Corrections as ``frame * (J + 1) + slot``, frames counted from the first frame of the chunks.
    values : ndarray, shape (N, 3), int
        The corrections' quantized values.
    track_q : ndarray, shape (n, T, 3), int, or None
        The quantized translation tracks of the chunks' frames (format 6 with tracks; else None).
    scale_q : ndarray, shape (n, T', 3), int, or None
        The quantized scale tracks of the chunks' frames (format 6 with scale tracks; else None).

    Raises
    ------
    BitstreamError
        If a chunk is corrupt: ANS words that do not decode, counts outside their segments, corrections past the
        chunk's end, bytes left over.
    """
    if info.version >= 6:
        return _read_units(info, payload, chunks, scratch)
    layout = info.layout
    coder_tables = tables(info.settings.rounding)
    channels = info.channels
    slots = len(info.correction_steps)
    first_segment = layout.chunk_starts[chunks]
    per_chunk = layout.chunk_starts[chunks + 1] - first_segment  # segments of each chunk
    segments = np.arange(first_segment[0], first_segment[-1] + per_chunk[-1])
    lengths = layout.lengths[segments]
    local_first = first_segment - first_segment[0]  # first segment of each chunk, within the block
    chunk_frames = np.add.reduceat(lengths, local_first)
    # Pass 1: the correction count of every chunk and (before format 4) its significance counts' ANS stream.
    readers, count_runs, corrections = [], [], []
    offsets = info.chunk_offsets
    for chunk, held, frames in zip(chunks.tolist(), per_chunk.tolist(), chunk_frames.tolist()):
        reader = ByteReader(payload[: offsets[chunk + 1]], int(offsets[chunk]))
        count = reader.read_varint("correction count")
        if count > frames * slots:
            raise BitstreamError(f"mcb-rot: chunk {chunk}: expected at most {frames * slots} corrections, found {count}.")
        if info.counts is None:
            count_runs.append(read_tokens(reader, _count_groups(info, held)[1], coder_tables, f"mcb-rot: chunk {chunk}"))
        readers.append(reader)
        corrections.append(count)
    if info.counts is not None:  # format 4: in the payload header, checked there
        counts = info.counts[segments[0] : segments[-1] + 1]
    else:
        counts = _chunk_counts(info, chunks, count_runs, per_chunk, local_first, lengths)
    # Pass 2: the coefficients and corrections, one ANS stream per chunk, classes found for the whole block: the
    # values are numbered stream by stream (each: coefficients, correction gaps, correction values), so that a
    # stable sort by (chunk, class) gives each stream's coding order.
    padded = max(int(lengths.max()) - 1, 0)
    shape = (len(segments), channels, padded)
    mask = np.empty(shape, dtype=bool) if scratch is None else scratch.take("mask", shape, bool)
    np.less(np.arange(padded), counts[:, :, None], out=mask)  # (S, C, P): the coded coefficients
    key_type = np.uint16 if len(chunks) * _KEY_STRIDE <= 1 << 16 else np.int64  # (uint16 sorts by radix)
    segment_key = np.repeat(np.arange(len(chunks), dtype=np.int64), per_chunk) * _KEY_STRIDE
    coefficient_keys = _coefficient_keys(info, lengths, segment_key, mask, key_type)
    coded = np.add.reduceat(counts.sum(axis=1), local_first).tolist()  # coefficients of each chunk
    parts, at = [], 0
    for i, (held, count) in enumerate(zip(coded, corrections)):
        key = i * _KEY_STRIDE + _SIDE
        parts += [coefficient_keys[at : at + held], np.full(count, key + info.gap_class, key_type),
                  np.full(3 * count, key + info.value_class, key_type)]
        at += held
    keys = np.concatenate(parts) if len(parts) > 3 or corrections[0] else coefficient_keys
    order = np.argsort(keys, kind="stable")  # by chunk, then by class (as each stream was coded)
    histogram = np.bincount(keys, minlength=len(chunks) * _KEY_STRIDE).reshape(len(chunks), _KEY_STRIDE)
    group_chunk, group_class = np.nonzero(histogram)
    groups = list(zip(group_class.tolist(), histogram[group_chunk, group_class].tolist()))
    bounds = np.searchsorted(group_chunk, np.arange(len(chunks) + 1)).tolist()
    runs = []
    for i, (chunk, reader) in enumerate(zip(chunks.tolist(), readers)):
        runs.append(read_tokens(reader, groups[bounds[i] : bounds[i + 1]], coder_tables, f"mcb-rot: chunk {chunk}"))
        reader.expect_end(f"chunk {chunk}")
    decoded = values_of_tokens(runs, order, None if scratch is None else scratch.take("values", order.shape, np.int64))
    ac = np.empty(shape) if scratch is None else scratch.take("ac", shape)
    ac.fill(0.0)
    sizes = np.array(coded) + 4 * np.array(corrections, dtype=np.int64)
    starts = (np.cumsum(sizes) - sizes).tolist()
    if len(chunks) == 1:
        ac[mask] = decoded[: coded[0]]
        gaps, values = decoded[coded[0] : coded[0] + corrections[0]], decoded[coded[0] + corrections[0] :]
    else:
        ac[mask] = np.concatenate([decoded[at : at + held] for at, held in zip(starts, coded)])
        gaps = np.concatenate([decoded[at + held : at + held + n] for at, held, n in zip(starts, coded, corrections)])
        values = np.concatenate([decoded[at + held + n : at + held + 4 * n]
                                 for at, held, n in zip(starts, coded, corrections)])
    corrections = np.array(corrections, dtype=np.int64)
    if gaps.size and gaps.min() < 0:
        raise BitstreamError(f"mcb-rot: chunks {chunks[0]}-{chunks[-1]}: a correction gap is negative.")
    steps = np.cumsum(gaps + 1)
    local = steps - 1 - np.repeat((np.concatenate([[0], steps]))[np.cumsum(corrections) - corrections], corrections)
    ends = np.repeat(chunk_frames * slots, corrections)
    if np.any(local >= ends):
        raise BitstreamError(f"mcb-rot: chunks {chunks[0]}-{chunks[-1]}: corrections run past their chunk's end.")
    chunk_offset = (np.cumsum(chunk_frames) - chunk_frames) * slots
    flat = local + np.repeat(chunk_offset, corrections)
    return ac, flat, values.reshape(-1, 3), None, None


def _read_units(
    info: StreamInfo, payload: memoryview, chunks: np.ndarray, scratch: Scratch | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`read_chunks` of a format 6 stream: each chunk one rANS unit in natural order (its coefficients segment
    by segment, channel by channel, then the correction gaps and values), decoded value after value."""
    layout = info.layout
    channels = info.channels
    slots = len(info.correction_steps)
    first_segment = layout.chunk_starts[chunks]
    segments = np.arange(first_segment[0], layout.chunk_starts[chunks[-1] + 1])
    lengths = layout.lengths[segments]
    counts = info.counts[segments[0] : segments[-1] + 1]
    padded = max(int(lengths.max()) - 1, 0)
    shape = (len(segments), channels, padded)
    mask = np.empty(shape, dtype=bool) if scratch is None else scratch.take("mask", shape, bool)
    np.less(np.arange(padded), counts[:, :, None], out=mask)
    ac = np.empty(shape) if scratch is None else scratch.take("ac", shape)
    ac.fill(0.0)
    side = _SIDE + np.array([info.gap_class, info.value_class])
    flats, values, frame_at, track_q, scale_q = [], [], 0, [], []
    unit_tables = runtime_tables()
    for chunk in chunks.tolist():
        reader = ByteReader(payload[: info.chunk_offsets[chunk + 1]], int(info.chunk_offsets[chunk]))
        mine = np.arange(layout.chunk_starts[chunk], layout.chunk_starts[chunk + 1]) - segments[0]
        frames = int(lengths[mine].sum())
        count = reader.read_varint("correction count")
        if count > frames * slots:
            raise BitstreamError(f"mcb-rot: chunk {chunk}: expected at most {frames * slots} corrections, found {count}.")
        coded = [_class_rows(info, int(lengths[i]))[mask[i, :, : lengths[i] - 1]] for i in mine.tolist()]
        classes = np.concatenate(coded + [np.repeat(side, [count, 3 * count])])
        if len(classes) > info.unit_values:
            raise BitstreamError(f"mcb-rot: chunk {chunk}: {len(classes)} values, the header says at most "
                                 f"{info.unit_values}.")
        decoded = decode_unit(reader, classes, unit_tables, f"mcb-rot: chunk {chunk}")
        if info.tracks is not None:  # the chunk's translation tracks (:mod:`.tracks`): two running sums
            unit = decode_unit(reader, info.tracks.unit_classes(frames), unit_tables, f"mcb-rot: chunk {chunk} tracks")
            track_q.append(info.tracks.q_of_values(unit, frames))
        if info.scales is not None:  # the chunk's scale tracks (:mod:`.scales`), each value checked
            unit = decode_unit(reader, info.scales.unit_classes(frames), unit_tables, f"mcb-rot: chunk {chunk} scales")
            scale_q.append(_checked_scales(info, info.scales.q_of_values(unit, frames), chunk))
        reader.expect_end(f"chunk {chunk}")
        held = len(classes) - 4 * count
        ac_values = decoded[:held]
        gaps = decoded[held : held + count]
        if gaps.size and gaps.min() < 0:
            raise BitstreamError(f"mcb-rot: chunk {chunk}: a correction gap is negative.")
        local = np.cumsum(gaps + 1) - 1
        if local.size and local[-1] >= frames * slots:
            raise BitstreamError(f"mcb-rot: chunk {chunk}: corrections run past the chunk's end.")
        flats.append(local + frame_at * slots)
        values.append(decoded[held + count :].reshape(-1, 3))
        ac[mine[0] : mine[-1] + 1][mask[mine[0] : mine[-1] + 1]] = ac_values
        frame_at += frames
    return (ac, np.concatenate(flats), np.concatenate(values), np.concatenate(track_q) if track_q else None,
            np.concatenate(scale_q) if scale_q else None)


def _checked_scales(info: StreamInfo, q: np.ndarray, chunk: int) -> np.ndarray:
    """``q`` (n, T, 3) of a chunk's scale tracks, refused unless every decoded scale lies in (0, peak]."""
    with np.errstate(all="ignore"):
        values = info.scales.values(q)
    if not np.all((values > 0) & (values <= info.scales.reach[None, :, None])):
        raise BitstreamError(f"mcb-rot: chunk {chunk}: a decoded scale is not in (0, its track's peak].")
    return q


def _coefficient_keys(info: StreamInfo, lengths: np.ndarray, segment_key: np.ndarray, mask: np.ndarray,
                      key_type) -> np.ndarray:
    """``class + segment_key[s]`` (``key_type``) of the coded AC coefficients of segments of ``lengths``, in stream
    order (segment, channel, k): ``mask`` (S, C, P) marks them."""
    keys = np.zeros(mask.shape, dtype=key_type)
    for i, (length, key) in enumerate(zip(lengths.tolist(), segment_key.tolist())):
        if length > 1:
            np.add(_class_rows(info, length), key, out=keys[i, :, : length - 1])
    return keys[mask]


def _class_rows(info: StreamInfo, length: int) -> np.ndarray:
    """(C, n - 1) uint16 classes of the AC coefficients of a segment of ``length`` frames, channel-major (cached)."""
    key = ("class rows", length)
    if key not in info._cache:  # info.class_matrix(length).T, computed in this layout
        if "class table" not in info._cache:  # (C, NUM_BANDS): the class of every channel in every band
            table = info.scale[:, None] + info.tilt[None, :]
            info._cache["class table"] = np.clip(table, 0, NUM_CLASSES - 1, out=table).astype(np.uint16)
        bands = band_of(np.arange(1, length), length, info.settings.segment_frames)
        info._cache[key] = np.take(info._cache["class table"], bands, axis=1)
    return info._cache[key]


def _chunk_counts(info: StreamInfo, chunks: np.ndarray, count_runs: list, per_chunk: np.ndarray,
                  local_first: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """(S, C) significance counts of the ``chunks`` of a stream before format 4, from their count streams
    (differences from the previous segment of the same chunk), checked against the segment lengths."""
    channels = info.channels
    if np.all(per_chunk == per_chunk[0]):
        order = _count_groups(info, int(per_chunk[0]))[0]
        order = (order[None, :] + len(order) * np.arange(len(chunks))[:, None]).ravel()
    else:
        sizes = per_chunk * channels
        order = np.concatenate([_count_groups(info, int(n))[0] + at for n, at in zip(per_chunk, np.cumsum(sizes) - sizes)])
    counts = values_of_tokens(count_runs, order).reshape(len(lengths), channels)
    if len(lengths) > len(chunks):  # differences from the previous segment of the same chunk
        counts = np.cumsum(counts, axis=0)
        before = np.concatenate([np.zeros((1, channels), dtype=np.int64), counts])[local_first]
        counts -= np.repeat(before, per_chunk, axis=0)
    bad = (counts < 0) | (counts > (lengths - 1)[:, None])
    if bad.any():
        chunk = chunks[np.searchsorted(local_first, int(np.argmax(bad.any(axis=1))), side="right") - 1]
        raise BitstreamError(f"mcb-rot: chunk {chunk}: significance counts outside their segments.")
    return counts
