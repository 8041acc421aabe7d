"""Quantization and entropy coding of coefficient vectors, shared by both schemes and every spatial transform.

For every coefficient vector (a column of J coefficients): hard threshold and uniform quantization
(:func:`quantize_coefficients`), the count of nonzeros (fixed length, or canonical Huffman), then the locations and
values of the nonzeros (canonical Huffman, :mod:`mocapbench.entropy.huffman`).
"""

from __future__ import annotations

import numpy as np

from mocapbench.entropy.bitio import BitReader, BitWriter, ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.entropy.huffman import decode_symbols, encode_symbols
from mocapbench.entropy.quantize import quantize

__all__ = ["COUNT_CODINGS", "code_vectors", "decode_vectors", "quantize_coefficients"]


def quantize_coefficients(coefficients: np.ndarray, step: float, threshold: float) -> np.ndarray:
    """Hard thresholding then uniform quantization (§3.1).

    Parameters
    ----------
    coefficients : ndarray, any shape, float, cm
    step : float, cm
        Δ, the quantization step.
    threshold : float, cm
        Coefficients with ``|c| <= threshold`` become 0; ``threshold >= step / 2``.

    Returns
    -------
    ndarray, same shape, int64
        ``rint(c / Δ)`` where ``|c| > threshold``, else 0.
    """
    indices = quantize(coefficients, step)
    if threshold > 0.5 * step:
        indices[np.abs(coefficients) <= threshold] = 0
    return indices


def _count_width(num_joints: int) -> int:
    """Bits of the fixed-length count of nonzeros per vector: counts go from 0 to J."""
    return int(num_joints).bit_length()


#: Ways to code the count of nonzeros per vector: the paper's fixed-length field, or canonical Huffman (an option).
COUNT_CODINGS = ("fixed", "huffman")


def code_vectors(indices: np.ndarray, count_coding: str = "fixed") -> bytes:
    """Entropy-code quantized coefficient vectors (§3.1): counts, then locations and values with Huffman codes.

    Parameters
    ----------
    indices : ndarray, shape (V, J), int64
        One quantized coefficient vector per row, in stream order.
    count_coding : {"fixed", "huffman"}
        "fixed": the count of nonzeros of every vector in ``bit_length(J)`` bits (the paper); "huffman": the counts
        through the same canonical Huffman coder (not in the paper; most high temporal frequencies have none).

    Returns
    -------
    bytes
        The counts (a length-prefixed bit block, or a Huffman blob), then two Huffman blobs: the locations
        (0..J−1, ascending within each vector) and the values of the nonzero coefficients.
    """
    if count_coding not in COUNT_CODINGS:
        raise ValueError(f"Unknown count coding {count_coding!r}; expected one of {list(COUNT_CODINGS)}.")
    counts = np.count_nonzero(indices, axis=1)
    rows, locations = np.nonzero(indices)  # row-major: vector by vector, locations ascending
    writer = ByteWriter()
    if count_coding == "fixed":
        counts_writer = BitWriter()
        counts_writer.write_array(counts, _count_width(indices.shape[1]))
        writer.write_blob(counts_writer.getvalue())
    else:
        writer.write_bytes(encode_symbols(counts))
    writer.write_bytes(encode_symbols(locations))
    writer.write_bytes(encode_symbols(indices[rows, locations]))
    return writer.getvalue()


def decode_vectors(data, num_vectors: int, num_joints: int, count_coding: str = "fixed") -> np.ndarray:
    """Inverse of :func:`code_vectors`, checking every count, location and value.

    Parameters
    ----------
    data : bytes-like
        Exactly what :func:`code_vectors` returned (trailing bytes are an error).
    num_vectors, num_joints : int
        V and J, known to the decoder from the container header.
    count_coding : {"fixed", "huffman"}

    Returns
    -------
    ndarray, shape (V, J), int64

    Raises
    ------
    BitstreamError
        On any inconsistency (counts above J, locations out of range or not ascending, zero values, sizes).
    """
    data = bytes(data)
    if count_coding == "fixed":
        reader = ByteReader(data)
        counts_blob = reader.read_blob("nonzero counts")
        width = _count_width(num_joints)
        if len(counts_blob) != (num_vectors * width + 7) // 8:
            raise BitstreamError(
                f"expected {(num_vectors * width + 7) // 8} bytes of {width}-bit nonzero counts for {num_vectors} "
                f"vectors, found {len(counts_blob)}"
            )
        counts = BitReader(counts_blob).read_array(num_vectors, width, "nonzero counts").astype(np.int64)
        offset = reader.offset
    elif count_coding == "huffman":
        counts, offset = decode_symbols(data, 0, expected_count=num_vectors)
        if counts.size and counts.min() < 0:
            raise BitstreamError(f"expected nonnegative nonzero counts, found {int(counts.min())}")
    else:
        raise BitstreamError(f"unknown count coding {count_coding!r}")
    if counts.size and counts.max() > num_joints:
        raise BitstreamError(f"expected at most J={num_joints} nonzeros per vector, found {int(counts.max())}")
    total = int(counts.sum())
    locations, offset = decode_symbols(data, offset, expected_count=total)
    values, offset = decode_symbols(data, offset, expected_count=total)
    if offset != len(data):
        raise BitstreamError(f"expected the payload to end after the value stream, found {len(data) - offset} more bytes")
    rows = np.repeat(np.arange(num_vectors), counts)
    if total:
        if locations.min() < 0 or locations.max() >= num_joints:
            raise BitstreamError(
                f"expected coefficient locations in [0, {num_joints - 1}], found "
                f"[{int(locations.min())}, {int(locations.max())}]"
            )
        if np.any((rows[1:] == rows[:-1]) & (locations[1:] <= locations[:-1])):
            raise BitstreamError("expected strictly increasing coefficient locations within each vector")
        if np.any(values == 0):
            raise BitstreamError("expected only nonzero coefficient values, found a zero")
    indices = np.zeros((num_vectors, num_joints), dtype=np.int64)
    indices[rows, locations] = values
    return indices
