"""The one exception raised for coded data that cannot be decoded.

Every reader in :mod:`mocapbench.entropy` (bit and byte readers, varints, Huffman tables and payloads, the
zstd/lzma back ends) raises :class:`BitstreamError` for truncated, corrupt or otherwise invalid input, never an
``IndexError`` from numpy or a ``ValueError`` from bitarray. The codec container
(``mocapbench/codecs/container.py``) imports it from here, so a caller catches a single type for "these bytes are
not a valid bitstream".
"""

from __future__ import annotations

__all__ = ["BitstreamError"]


class BitstreamError(ValueError):
    """Truncated, corrupt or invalid coded data.

    The message names what the reader expected and what it found, for example
    ``"expected 4 bytes for frame count, found 1"``.

    It derives from :class:`ValueError` so that code written against "bad input raises ValueError" keeps working,
    while callers that must tell a damaged bitstream from a bad argument can catch this subclass alone.
    """
