"""The size of an ``mcb-rot`` payload estimated without entropy coding it: what the rate search compares.

The rate search (``codec._search``) tries several step multipliers per stream and keeps the smallest stream. Writing
each attempt's payload (choosing the entropy classes of the whole stream, then ANS coding every chunk) was a sixth
of the encoding time at 120 fps and a fifth at 24 fps; the search only needs to *rank* the attempts, so it ranks them
by this estimate and writes the winner alone.

The estimate is the ideal code length of what :func:`mocapbench.codecs.mcb_rot.stream.write_payload` codes, in bytes:

* AC coefficients (the dominant part): those up to each channel's last nonzero one, as the stream codes them, each
  (channel, band) cell under the class (token distribution of :mod:`.classes`) that codes it best, plus their raw
  bits (escape low bits and signs). The stream's classes are separable (a channel scale plus a band tilt, fitted
  by coordinate descent), so the stream costs a little more than this per-cell optimum, by a similar share in every
  attempt of one stream;
* segment means and significance counts (each as differences along the segments),
  correction gaps and correction values: each stream under its best single class, plus raw bits.

Header bytes common to all attempts of a stream (skeleton, cuts, axes, class bytes) are left out: the estimate
compares attempts of one stream, it is not a stream size. ``tests/codecs/mcb_rot/test_mcb_rot_rate.py`` checks that it
ranks attempts as their real sizes do.
"""

from __future__ import annotations

import numpy as np

from mocapbench.codecs.mcb_rot import classes as model
from mocapbench.codecs.mcb_rot.stream import RUNTIME_ROUNDING, StreamInfo
from mocapbench.entropy.ans import TOKEN_COUNT, tokenize

__all__ = ["base_bytes", "base_bytes_many", "corrections_bytes", "estimate_bytes"]

_NEAREST = 0.5  # rounding of the tables every side stream is coded with


def _single_class_bits(values: np.ndarray) -> float:
    """Ideal bits of ``values`` under the one side class that codes them best, raw bits included."""
    if values.size == 0:
        return 0.0
    tokens, _, widths = tokenize(values)
    histogram = np.bincount(tokens, minlength=TOKEN_COUNT).astype(np.float64)
    tokens_bits = float(np.min(-(model.tables(_NEAREST).log2_probabilities @ histogram)))
    return tokens_bits + float(widths.sum() + np.count_nonzero(values))


def base_bytes(info: StreamInfo, coefficients: dict[int, np.ndarray]) -> float:
    """Estimated bytes of the base layer of a stream whose ``info.dc`` is set, with AC coefficients
    ``coefficients`` (segment -> (n - 1, C) int): AC coefficients, segment means and significance counts
    (:func:`base_bytes_many` of the one attempt)."""
    layout = info.layout
    quantized = np.zeros((layout.num_frames, 1, info.channels), dtype=np.int64)
    for segment, (start, length) in enumerate(zip(layout.starts.tolist(), layout.lengths.tolist())):
        quantized[start, 0] = info.dc[segment]
        quantized[start + 1 : start + length, 0] = coefficients[segment]
    return base_bytes_many([info], quantized)[0]


def base_bytes_many(infos: list[StreamInfo], quantized: np.ndarray) -> list[float]:
    """:func:`base_bytes` of several attempts of one stream (the same bits), from their quantized base layers laid
    side by side: ``quantized`` (F, K, C) int, row ``start`` of each segment its mean, the next rows its AC
    coefficients (:meth:`.compensate.Compensator.quantize_many`), and ``infos`` (K) with their ``dc`` set.

    AC coefficients: those up to each channel's last nonzero one (the significance counts the stream writes), each
    (channel, band) cell under its best class, plus their raw bits; one histogram for all the attempts (each
    attempt's cells apart), only the cells and tokens that occur (a short clip fills a few of the 12 C cells, small
    tokens only). Segment means and significance counts: differences along the segments under their best single
    class."""
    first = infos[0]
    layout, settings = first.layout, first.settings
    count, channels = len(infos), first.channels
    log2p = model.tables(RUNTIME_ROUNDING).log2_probabilities  # (K, T): the format's tables, whatever the rounding
    histogram = np.zeros((count, channels * model.NUM_BANDS, TOKEN_COUNT))
    raw = np.zeros(count)
    counts = np.zeros((layout.num_segments, count, channels), dtype=np.int64)
    cell_of = (np.arange(count)[:, None] * channels + np.arange(channels)[None, :]) * model.NUM_BANDS  # (K, C)
    for length, segments in layout.groups.items():
        if length < 2:
            continue
        stacked = quantized[layout.starts[segments, None] + 1 + np.arange(length - 1)]  # (S_g, n - 1, K, C)
        nonzero = stacked != 0
        last = np.where(nonzero.any(axis=1), length - 1 - np.argmax(nonzero[:, ::-1], axis=1), 0)  # (S_g, K, C)
        counts[segments] = last
        coded = np.arange(length - 1)[None, :, None, None] < last[:, None]  # (S_g, n - 1, K, C)
        values = stacked[coded]
        bands = model.band_of(np.arange(1, length), length, settings.segment_frames)  # (n - 1,)
        cells = np.broadcast_to(cell_of[None, None] + bands[None, :, None, None], stacked.shape)[coded]
        tokens, _, widths = tokenize(values)
        histogram += np.bincount(cells * TOKEN_COUNT + tokens, minlength=histogram.size).reshape(histogram.shape)
        attempt = np.broadcast_to(np.arange(count)[None, None, :, None], stacked.shape)[coded]
        raw += np.bincount(attempt, weights=widths + (values != 0), minlength=count)
    sizes = []
    for k, info in enumerate(infos):
        used = histogram[k][histogram[k].any(axis=1)]
        tokens_used = int(np.flatnonzero(used.any(axis=0)).max(initial=-1)) + 1
        cost = used[:, :tokens_used] @ -log2p[:, :tokens_used].T  # (used cells, K)
        bits = (float(cost.min(axis=1).sum()) if len(cost) else 0.0) + float(raw[k])
        bits += _single_class_bits(np.diff(info.dc, axis=0, prepend=0).ravel())
        count_diffs = np.diff(counts[:, k], axis=0, prepend=0)
        sizes.append((bits + _single_class_bits(count_diffs.ravel())) / 8.0)
    return sizes


def corrections_bytes(info: StreamInfo, flat: np.ndarray, values: np.ndarray) -> float:
    """Estimated bytes of corrections at sorted ``flat`` indices (N,) with ``values`` (N, 3): each chunk codes the
    gaps between its corrected slots and their values."""
    layout = info.layout
    slots = len(info.correction_steps)
    chunk_first = layout.starts[layout.chunk_starts[:-1]] * slots
    chunk_of = np.searchsorted(chunk_first, flat, side="right") - 1
    within = flat - chunk_first[chunk_of]  # each chunk codes its gaps from its own first slot
    first_of_chunk = np.diff(chunk_of, prepend=-1) != 0
    gaps = within - np.where(first_of_chunk, -1, np.concatenate([[-1], within[:-1]])) - 1
    return (_single_class_bits(gaps) + _single_class_bits(np.asarray(values).ravel())) / 8.0


def estimate_bytes(info: StreamInfo, coefficients: dict[int, np.ndarray], corrections) -> float:
    """Estimated payload bytes (less the header common to every attempt) of a stream whose ``info.dc`` is set,
    with AC coefficients ``coefficients`` (segment -> (n - 1, C) int) and ``corrections`` (flat indices (N,),
    values (N, 3)), as :func:`~mocapbench.codecs.mcb_rot.stream.write_payload` would write it: the sum of
    :func:`base_bytes` and :func:`corrections_bytes`."""
    return base_bytes(info, coefficients) + corrections_bytes(info, *corrections)
