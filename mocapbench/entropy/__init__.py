"""Entropy-coding layer shared by every codec: quantizers, bit/byte I/O, canonical Huffman, zstd/lzma back ends.

Codecs turn motion into integers (or bytes) and hand them to this package; they never lay out bits themselves.
Every decoder here raises :class:`BitstreamError` (a ``ValueError``) for truncated or corrupt input.

- :mod:`.quantize`: :func:`quantize` / :func:`dequantize` (step-based), :class:`RangeQuantizer`,
  :func:`quantize_range` / :func:`dequantize_range` (1-24 bits over ``[lo, hi]``).
- :mod:`.bitio`: :class:`BitWriter` / :class:`BitReader` (fixed-width fields, vectorized arrays),
  :class:`ByteWriter` / :class:`ByteReader` (little-endian fields, LEB128 varints, arrays, blobs), zigzag.
- :mod:`.huffman`: :func:`encode_symbols` / :func:`decode_symbols` (self-contained canonical Huffman blobs).
- :mod:`.backend`: :func:`zstd_compress` / :func:`zstd_decompress`, :func:`lzma_compress` / :func:`lzma_decompress`.
"""

from mocapbench.entropy.backend import (
    lzma_compress,
    lzma_decompress,
    zstd_compress,
    zstd_decompress,
    zstd_pack_ints,
    zstd_unpack_ints,
)
from mocapbench.entropy.bitio import (
    BitReader,
    BitWriter,
    ByteReader,
    ByteWriter,
    decode_varint,
    decode_varints,
    encode_varint,
    encode_varints,
    zigzag_decode,
    zigzag_encode,
)
from mocapbench.entropy.errors import BitstreamError
from mocapbench.entropy.huffman import (
    decode_symbols,
    encode_symbols,
    huffman_code_lengths,
    huffman_payload_bits,
)
from mocapbench.entropy.quantize import (
    RangeQuantizer,
    dequantize,
    dequantize_range,
    quantize,
    quantize_range,
)

__all__ = [
    "BitstreamError",
    "quantize",
    "dequantize",
    "RangeQuantizer",
    "quantize_range",
    "dequantize_range",
    "BitWriter",
    "BitReader",
    "ByteWriter",
    "ByteReader",
    "encode_varint",
    "decode_varint",
    "encode_varints",
    "decode_varints",
    "zigzag_encode",
    "zigzag_decode",
    "encode_symbols",
    "decode_symbols",
    "zstd_pack_ints",
    "zstd_unpack_ints",
    "huffman_code_lengths",
    "huffman_payload_bits",
    "zstd_compress",
    "zstd_decompress",
    "lzma_compress",
    "lzma_decompress",
]
