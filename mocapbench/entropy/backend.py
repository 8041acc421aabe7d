"""General-purpose back ends: zstd and raw LZMA2 over whole byte payloads.

Baseline codecs compress their serialized payload with these; structured codecs may run them over a Huffman blob
when a second pass helps. Both are deterministic (same library version, same level, same input -> same bytes) and
both decoders bound their output (``max_output_size``) and reject truncated, corrupt or trailing data with
:class:`~mocapbench.entropy.errors.BitstreamError`.

Frame layouts
-------------
zstd
    One standard zstd frame (RFC 8878) with the content size in its header and no checksum (the codec container
    carries a CRC32 of the whole bitstream, so 4 more bytes here would be counted twice in the rate).
lzma
    A raw LZMA2 stream (``lzma.FORMAT_RAW``, no .xz/.lzma header: those add 13-60 bytes that every decoder here
    already knows), dictionary size fixed at 16 MiB, terminated by LZMA2's end marker.
"""

from __future__ import annotations

import functools
import lzma

import numpy as np
import zstandard

from mocapbench.entropy.errors import BitstreamError

__all__ = [
    "LZMA_DICT_SIZE",
    "lzma_compress",
    "lzma_decompress",
    "zstd_compress",
    "zstd_decompress",
    "zstd_pack_ints",
    "zstd_pack_tracks",
    "zstd_unpack_ints",
    "zstd_unpack_tracks",
    "zstd_compress_chunks",
    "zstd_decompress_chunks",
]

#: Dictionary size of the raw LZMA2 filter, bytes. Fixed because a raw stream does not record it.
LZMA_DICT_SIZE = 1 << 24
#: Most values :func:`zstd_pack_tracks` packs in one shot (8 MiB as int64), keeping the bytes of
#: :func:`zstd_pack_ints`; more are streamed.
ONE_SHOT_VALUES = 1 << 20


def _check_level(name: str, level, lo: int, hi: int) -> int:
    if isinstance(level, bool) or not isinstance(level, int) or not lo <= level <= hi:
        raise ValueError(f"`{name}` must be an int in [{lo}, {hi}], got {level!r}")
    return level


def _check_max_output_size(max_output_size) -> int:
    if isinstance(max_output_size, bool) or not isinstance(max_output_size, int) or max_output_size < 0:
        raise ValueError(f"`max_output_size` must be a non-negative int (bytes), got {max_output_size!r}")
    return max_output_size


def zstd_compress(data, level: int = 19, dictionary: bytes | None = None) -> bytes:
    """Compress ``data`` into one zstd frame that records its content size.

    Parameters
    ----------
    data : bytes-like
    level : int
        zstd level in [1, 22]; 19 is the highest level that does not need the "ultra" window sizes.
    dictionary : bytes, optional
        Raw-content dictionary (text the data is likely to repeat); the decoder must pass the same one.

    Returns
    -------
    bytes
    """
    level = _check_level("level", level, 1, zstandard.MAX_COMPRESSION_LEVEL)
    compressor = zstandard.ZstdCompressor(
        level=level, write_content_size=True, write_checksum=False, threads=0, dict_data=_raw_dictionary(dictionary)
    )
    return compressor.compress(bytes(data))


@functools.lru_cache(maxsize=8)
def _raw_dictionary(dictionary: bytes | None):
    if dictionary is None:
        return None
    return zstandard.ZstdCompressionDict(dictionary, dict_type=zstandard.DICT_TYPE_RAWCONTENT)


def zstd_decompress(data, max_output_size: int, dictionary: bytes | None = None) -> bytes:
    """Decompress one frame written by :func:`zstd_compress`.

    Parameters
    ----------
    data : bytes-like
        Exactly one zstd frame, nothing after it.
    max_output_size : int
        Largest accepted decompressed size, bytes; checked against the frame header before decompressing.
    dictionary : bytes, optional
        The raw-content dictionary the frame was compressed with.

    Returns
    -------
    bytes

    Raises
    ------
    BitstreamError
        If the frame header is invalid or does not declare its content size, the declared size exceeds
        ``max_output_size``, the data is corrupt or truncated, or bytes follow the frame.
    """
    max_output_size = _check_max_output_size(max_output_size)
    data = bytes(data)
    try:
        params = zstandard.get_frame_parameters(data)
    except zstandard.ZstdError as exc:
        raise BitstreamError(f"expected a zstd frame header in {len(data)} bytes, found none: {exc}") from None
    size = params.content_size
    if size == zstandard.CONTENTSIZE_UNKNOWN:
        raise BitstreamError("expected a zstd frame that declares its content size, found one that does not")
    if size > max_output_size:
        raise BitstreamError(f"expected at most {max_output_size} bytes from zstd, the frame declares {size}")
    decompressor = zstandard.ZstdDecompressor(dict_data=_raw_dictionary(dictionary)).decompressobj()
    try:
        out = decompressor.decompress(data)
    except zstandard.ZstdError as exc:
        raise BitstreamError(f"zstd: corrupt frame: {exc}") from None
    if not decompressor.eof:
        raise BitstreamError(f"zstd: expected a complete frame of {size} bytes, the data ended after {len(out)}")
    if decompressor.unused_data:
        raise BitstreamError(f"zstd: expected the end of data after the frame, found {len(decompressor.unused_data)} "
                             f"more bytes")
    if len(out) != size:
        raise BitstreamError(f"zstd: expected {size} decompressed bytes as declared, found {len(out)}")
    return out


def zstd_compress_chunks(chunks, content_size: int, level: int = 19) -> bytes:
    """:func:`zstd_compress` of the concatenation of ``chunks``, without ever holding the concatenation.

    The frame declares ``content_size`` (what :func:`zstd_decompress` needs); the chunks must add up to it.

    Raises
    ------
    ValueError
        If the chunks do not add up to ``content_size``.
    """
    level = _check_level("level", level, 1, zstandard.MAX_COMPRESSION_LEVEL)
    compressor = zstandard.ZstdCompressor(level=level, write_content_size=True, write_checksum=False, threads=0)
    stream = compressor.compressobj(size=int(content_size))
    parts, total = [], 0
    for chunk in chunks:
        total += len(memoryview(chunk).cast("B"))
        parts.append(stream.compress(chunk))
    if total != content_size:
        raise ValueError(f"zstd: the chunks hold {total} bytes, {content_size} were declared")
    parts.append(stream.flush())
    return b"".join(parts)


def zstd_decompress_chunks(data, expected_size: int, input_chunk: int = 1 << 16):
    """The content of one frame written by :func:`zstd_compress` (or :func:`zstd_compress_chunks`), in pieces.

    Yields bytes objects whose concatenation is the content; memory is one piece at a time, not the content.
    The frame must declare exactly ``expected_size`` bytes (checked before anything is decompressed).

    Raises
    ------
    BitstreamError
        As :func:`zstd_decompress`, and if the frame declares another size than ``expected_size``.
    """
    data = memoryview(data).cast("B")
    _check_frame_size(data, expected_size)
    decompressor = zstandard.ZstdDecompressor().decompressobj()
    produced = 0
    for start in range(0, len(data), input_chunk):
        if decompressor.eof:
            break
        try:
            piece = decompressor.decompress(bytes(data[start : start + input_chunk]))
        except zstandard.ZstdError as exc:
            raise BitstreamError(f"zstd: corrupt frame: {exc}") from None
        produced += len(piece)
        if produced > expected_size:
            raise BitstreamError(f"zstd: the frame holds more than the {expected_size} bytes it declares")
        if piece:
            yield piece
    if not decompressor.eof:
        raise BitstreamError(f"zstd: expected a complete frame of {expected_size} bytes, the data ended after {produced}")
    if decompressor.unused_data or start + input_chunk < len(data):
        raise BitstreamError("zstd: expected the end of data after the frame, found more bytes")
    if produced != expected_size:
        raise BitstreamError(f"zstd: expected {expected_size} decompressed bytes as declared, found {produced}")


def _check_frame_size(data: memoryview, expected_size: int) -> None:
    """:class:`BitstreamError` unless ``data`` starts with a zstd frame header declaring ``expected_size`` bytes."""
    try:
        params = zstandard.get_frame_parameters(bytes(data[:18]))
    except zstandard.ZstdError as exc:
        raise BitstreamError(f"expected a zstd frame header in {len(data)} bytes, found none: {exc}") from None
    if params.content_size != expected_size:
        raise BitstreamError(f"expected a zstd frame of {expected_size} bytes, the frame declares {params.content_size}")


def _lzma_filters(preset: int | None = None) -> list[dict]:
    spec = {"id": lzma.FILTER_LZMA2, "dict_size": LZMA_DICT_SIZE}
    if preset is not None:
        spec["preset"] = preset
    return [spec]


def lzma_compress(data, preset: int = 9) -> bytes:
    """Compress ``data`` into a raw LZMA2 stream (layout in the module docstring).

    Parameters
    ----------
    data : bytes-like
    preset : int
        LZMA preset in [0, 9]; the dictionary size stays :data:`LZMA_DICT_SIZE` whatever the preset.
    """
    preset = _check_level("preset", preset, 0, 9)
    return lzma.compress(bytes(data), format=lzma.FORMAT_RAW, filters=_lzma_filters(preset))


def lzma_decompress(data, max_output_size: int) -> bytes:
    """Decompress a stream written by :func:`lzma_compress`.

    Raises
    ------
    BitstreamError
        If the stream is corrupt or truncated, decompresses to more than ``max_output_size`` bytes, or bytes follow
        its end marker.
    """
    max_output_size = _check_max_output_size(max_output_size)
    decompressor = lzma.LZMADecompressor(format=lzma.FORMAT_RAW, filters=_lzma_filters())
    try:
        out = decompressor.decompress(bytes(data), max_length=max_output_size + 1)
    except lzma.LZMAError as exc:
        raise BitstreamError(f"lzma: corrupt stream: {exc}") from None
    if len(out) > max_output_size:
        raise BitstreamError(f"expected at most {max_output_size} bytes from lzma, the stream holds more")
    if not decompressor.eof:
        raise BitstreamError(f"lzma: expected the stream's end marker, the data ended after {len(out)} output bytes")
    if decompressor.unused_data:
        raise BitstreamError(f"lzma: expected the end of data after the stream, found "
                             f"{len(decompressor.unused_data)} more bytes")
    return out


def zstd_pack_ints(values, level: int = 19, *, shuffle: bool = False) -> bytes:
    """Integers through zstd: zigzag, the narrowest little-endian width (1, 2, 4 or 8 bytes), one zstd frame.

    Layout: one byte holding the width, then the zstd frame. The element order is kept, so callers put values
    that resemble each other next to each other (channel-major tracks, coefficient bands) before packing.
    With ``shuffle`` the bytes are regrouped by significance before zstd (all lowest bytes, then all next bytes,
    ...: Blosc's byte shuffle), so the mostly-constant high bytes of small residuals form long runs.

    Parameters
    ----------
    values : array_like of int, any shape (flattened in C order)
    level : int
        zstd level, 1..22.
    shuffle : bool
        Byte-shuffle before zstd (the decoder must be told: :func:`zstd_unpack_ints` ``shuffle``).
    """
    from mocapbench.entropy.bitio import zigzag_encode

    codes = zigzag_encode(np.asarray(values).ravel())
    peak = int(codes.max()) if codes.size else 0
    width = next(w for w in (1, 2, 4, 8) if peak < 1 << (8 * w))
    raw = codes.astype(f"<u{width}")
    if shuffle:
        raw = raw.view(np.uint8).reshape(-1, width).T
    return bytes([width]) + zstd_compress(np.ascontiguousarray(raw).tobytes(), level=level)


def zstd_unpack_ints(blob, count: int, what: str = "integers", *, shuffle: bool = False) -> np.ndarray:
    """Inverse of :func:`zstd_pack_ints` (same ``shuffle``): exactly ``count`` int64 values, or
    :class:`BitstreamError`."""
    from mocapbench.entropy.bitio import zigzag_decode

    blob = bytes(blob)
    if len(blob) < 1 or blob[0] not in (1, 2, 4, 8):
        raise BitstreamError(f"{what}: expected a width byte of 1, 2, 4 or 8, found {blob[:1]!r}")
    width = blob[0]
    raw = zstd_decompress(blob[1:], count * width)
    if len(raw) != count * width:
        raise BitstreamError(f"{what}: expected {count * width} bytes after zstd, found {len(raw)}")
    planes = np.frombuffer(raw, dtype=np.uint8)
    if shuffle:
        planes = np.ascontiguousarray(planes.reshape(width, count).T)
    return zigzag_decode(planes.view(f"<u{width}").reshape(-1).astype(np.uint64)).astype(np.int64)


def zstd_pack_tracks(track, num_tracks: int, length: int, level: int = 19, *, shuffle: bool = False) -> bytes:
    """:func:`zstd_pack_ints` of the ``(num_tracks, length)`` array whose row ``i`` is ``track(i)``, never held whole.

    Up to :data:`ONE_SHOT_VALUES` values the tracks are stacked and packed by :func:`zstd_pack_ints` (the same
    bytes). Beyond, one pass over the tracks finds the width, then each track's bytes (with ``shuffle``: each byte
    plane of each track, plane by plane) go through zstd's streaming compressor: the same layout and frame format,
    which :func:`zstd_unpack_ints` reads, though not always the same bytes (zstd's one-shot and streaming
    compressors can differ by a few bytes on the same input). Memory: one track and the compressor's tables.
    ``track`` may be called several times per track (``1 + width`` times with ``shuffle``) and must return the same
    values each time.

    Parameters
    ----------
    track : callable, int -> ndarray, shape (length,), integer
    num_tracks, length : int
    level : int
        zstd level, 1..22.
    shuffle : bool
        Byte-shuffle as :func:`zstd_pack_ints` does (all lowest bytes of every value, then all next bytes, ...).
    """
    from mocapbench.entropy.bitio import zigzag_encode

    def values(i: int) -> np.ndarray:
        row = np.asarray(track(i))
        if row.shape != (length,):
            raise ValueError(f"track {i} has shape {row.shape}, expected ({length},)")
        return row

    def codes(i: int) -> np.ndarray:
        return zigzag_encode(values(i))

    if num_tracks * length <= ONE_SHOT_VALUES:  # small: zstd's one-shot compressor, the bytes of zstd_pack_ints
        stacked = np.empty((num_tracks, length), dtype=np.int64)
        for i in range(num_tracks):
            stacked[i] = values(i)
        return zstd_pack_ints(stacked, level, shuffle=shuffle)
    peak = max((int(codes(i).max()) for i in range(num_tracks)), default=0) if length else 0
    width = next(w for w in (1, 2, 4, 8) if peak < 1 << (8 * w))
    if shuffle:
        chunks = ((codes(i) >> np.uint64(8 * plane)).astype(np.uint8).tobytes()
                  for plane in range(width) for i in range(num_tracks))
    else:
        chunks = (codes(i).astype(f"<u{width}").tobytes() for i in range(num_tracks))
    return bytes([width]) + zstd_compress_chunks(chunks, num_tracks * length * width, level=level)


def zstd_unpack_tracks(blob, num_tracks: int, length: int, sink, what: str = "integers", *,
                       shuffle: bool = False) -> None:
    """Inverse of :func:`zstd_pack_tracks` (same ``shuffle``): ``sink(i, values)`` for every track in order, values
    an int64 array of ``length``; :class:`BitstreamError` on any inconsistency.

    Memory beside the sink: one track, and with ``shuffle`` the byte planes below the highest one
    (``(width - 1) * num_tracks * length`` bytes: a track's top byte comes after every lower byte of every track).
    """
    from mocapbench.entropy.bitio import zigzag_decode

    blob = memoryview(blob).cast("B")
    if len(blob) < 1 or blob[0] not in (1, 2, 4, 8):
        raise BitstreamError(f"{what}: expected a width byte of 1, 2, 4 or 8, found {bytes(blob[:1])!r}")
    width = blob[0]
    planes = width if shuffle else 1
    track_bytes = length * (1 if shuffle else width)  # bytes of one track in one plane
    _check_frame_size(blob[1:], planes * num_tracks * track_bytes)  # before anything sized by the header
    held = np.empty(((planes - 1) * num_tracks * track_bytes,), dtype=np.uint8)  # the planes below the top
    filled, pending, index = 0, bytearray(), 0

    def emit(top) -> None:  # track ``index``'s top plane (its only plane without shuffle) is complete in ``top``
        if not shuffle:
            sink(index, zigzag_decode(np.frombuffer(top, dtype=f"<u{width}").astype(np.uint64)))
            return
        codes = np.frombuffer(top, dtype=np.uint8).astype(np.uint64) << np.uint64(8 * (planes - 1))
        for plane in range(planes - 1):
            start = (plane * num_tracks + index) * track_bytes
            codes |= held[start : start + track_bytes].astype(np.uint64) << np.uint64(8 * plane)
        sink(index, zigzag_decode(codes))

    for piece in zstd_decompress_chunks(blob[1:], planes * num_tracks * track_bytes):
        view, at = memoryview(piece), 0
        if filled < held.size:  # the lower planes come first, straight into their buffer
            at = min(held.size - filled, len(view))
            held[filled : filled + at] = np.frombuffer(view[:at], dtype=np.uint8)
            filled += at
        while at < len(view):  # whole tracks from the piece itself, the rest through ``pending``
            if not pending and len(view) - at >= track_bytes:
                emit(view[at : at + track_bytes])
                at += track_bytes
            else:
                take = min(track_bytes - len(pending), len(view) - at)
                pending += view[at : at + take]
                at += take
                if len(pending) < track_bytes:
                    continue
                emit(pending)
                pending = bytearray()
            index += 1
    for index in range(index, num_tracks):  # zero-length tracks: nothing was decompressed for them
        sink(index, np.zeros(0, dtype=np.int64))
