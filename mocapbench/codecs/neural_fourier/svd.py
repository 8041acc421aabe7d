"""``svd``: low-rank approximation of the pose matrix Y, the neural Fourier paper's baseline (§4.1).

Paper: K. Tojo, Y. Chen, N. Umetani, "Neural Motion Compression with Frequency-adaptive Fourier Feature
Network" (Eurographics 2022 short paper), §4.1: "We decompose the matrix Y and compute its low-rank
approximation using SVD", compared in its Figure 3 for "various numbers of nonzero singular values".

Y (F × m) is the pose parameterization of §3 (:mod:`mocapbench.codecs.neural_fourier.pose_params`: root translation,
sign-continuous root quaternion, axis-angles). With the column means μ::

    Y − μ ≈ U_r S_r V_rᵀ = A Bᵀ,    A = U_r S_r  (F × r),   B = V_r  (m × r)

The stream holds the skeleton (for FK), r, μ (float32), A and B quantized (float16, or uniform n-bit with a
float32 range per column of A, i.e. per component, and per row of B, i.e. per pose parameter). Decoding is ``μ + A Bᵀ`` → normalized quaternion, axis-angles → FK.

Departures from the paper, and why
----------------------------------
* The columns are centred first (μ stored, m numbers) — the paper does not say; a low-rank fit of an
  uncentred Y spends its first component on the mean pose.
* ``weighted=True`` (not the default, not in the paper) takes the SVD of ``(Y − μ) ∘ w`` with the loss weights
  of eq. (3) and unweights B, so that the rank is spent in cm as the network's loss does; plain Y mixes cm of
  root translation with radians, so the translation dominates. Both variants are measured in the benchmark.
* Parameter count for the paper's ratio: ``r (F + m) + m`` numbers (A, B and μ).
"""

from __future__ import annotations

import hashlib
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np

from mocapbench.codecs.base import Codec, CodecConfig, Header, param
from mocapbench.codecs.neural_fourier.pose_params import (
    TENSOR_FORMATS,
    motion_from_pose_blocks,
    num_pose_parameters,
    pose_matrix,
    pose_weights,
    quantize_tensor,
    read_tensor,
    read_tensor_format,
    write_tensor,
)
from mocapbench.codecs.limits import check_payload_holds
from mocapbench.codecs.registry import register_codec
from mocapbench.codecs.skeleton_blob import pack_skeleton, unpack_skeleton
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.motion import Motion

__all__ = ["SvdCodec", "low_rank_factors"]

_FORMAT_CODES = {name: code for code, name in enumerate(TENSOR_FORMATS)}


def low_rank_factors(y: np.ndarray, rank: int, weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Column means and the rank-r factors of a (weighted) SVD of the centred matrix.

    Parameters
    ----------
    y : ndarray, shape (F, m)
    rank : int
        r >= 1; clipped to ``min(F, m)``.
    weights : ndarray, shape (m,), optional
        If given, the SVD is of ``(y − μ) ∘ weights`` and B is unweighted afterwards (zero weights count as 1).

    Returns
    -------
    mean : ndarray, shape (m,)
    a : ndarray, shape (F, r')
        ``U_r S_r``.
    b : ndarray, shape (m, r')
        ``V_r`` (divided by the weights if any), so that ``y ≈ mean + a @ b.T``; ``r' = min(r, F, m)``.
    """
    if rank < 1:
        raise ValueError(f"`rank` must be >= 1, got {rank}.")
    mean = y.mean(axis=0)
    scale = np.ones(y.shape[1]) if weights is None else np.where(weights > 0, weights, 1.0)
    num_frames, m = y.shape
    if num_frames <= _DIRECT_SVD_FRAMES:
        u, s, vt = _centred_svd((y - mean) * scale)
        r = min(rank, len(s))
        return mean, u[:, :r] * s[:r], vt[:r].T / scale[:, None]
    # A long capture: the right singular vectors are the eigenvectors of the m x m Gram matrix, accumulated block
    # by block, and U S = (Y - mean) V block by block, so no F x m temporary beside Y is ever made.
    gram = np.zeros((m, m))
    for start in range(0, num_frames, _BLOCK_FRAMES):
        block = (y[start : start + _BLOCK_FRAMES] - mean) * scale
        gram += block.T @ block
    eigenvalues, vectors = np.linalg.eigh(gram)
    r = min(rank, m)
    v = vectors[:, ::-1][:, :r]
    a = np.empty((num_frames, r))
    for start in range(0, num_frames, _BLOCK_FRAMES):
        a[start : start + _BLOCK_FRAMES] = ((y[start : start + _BLOCK_FRAMES] - mean) * scale) @ v
    return mean, a, v / scale[:, None]


def _centred_svd(centred: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The thin SVD of ``centred`` (F, m), remembered for the last few matrices (read-only arrays).

    A rate search encodes one clip at rank after rank: the decomposition is the same every time and only its
    truncation differs, so it is computed once per matrix (found again by a hash of its bytes, shape and dtype)
    and each rank slices it: the same factors, bit for bit, as a fresh SVD. At most :data:`_SVD_CACHE_SIZE`
    decompositions are kept, each of a matrix of at most :data:`_DIRECT_SVD_FRAMES` rows.
    """
    digest = hashlib.blake2b(np.ascontiguousarray(centred).data, digest_size=20)
    digest.update(repr((centred.shape, centred.dtype.str)).encode())
    key = digest.digest()
    with _SVD_CACHE_LOCK:
        found = _SVD_CACHE.pop(key, None)
    if found is None:
        found = np.linalg.svd(centred, full_matrices=False)
        for array in found:
            array.setflags(write=False)
    with _SVD_CACHE_LOCK:
        _SVD_CACHE[key] = found  # most recently used last
        while len(_SVD_CACHE) > _SVD_CACHE_SIZE:
            _SVD_CACHE.pop(next(iter(_SVD_CACHE)))
    return found


# Decompositions kept by _centred_svd, least recently used first: a rate search needs one (a sweep that
# alternates plain and weighted needs two).
_SVD_CACHE: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
_SVD_CACHE_SIZE = 2
_SVD_CACHE_LOCK = threading.Lock()

# Up to this many frames the factors come from one SVD of the centred matrix; beyond, from the Gram matrix in
# blocks of _BLOCK_FRAMES (same subspace, bounded memory). Every CMU clip of the benchmark is under it.
_DIRECT_SVD_FRAMES = 30_000
_BLOCK_FRAMES = 8192


@register_codec
class SvdCodec(Codec):
    """Low-rank SVD of the pose matrix Y, decoded through FK (Tojo et al. 2022, §4.1 baseline).

    See the module docstring for the stream and the departures from the paper.
    """

    name = "svd"
    min_joints = 2  # the pose parameters (axis-angles of non-root joints) need a joint below the root
    codes_rotations = True
    smoke_params = {"rank": 16}
    smoke_max_error_cm = 1.0  # measured 0.26 cm

    @dataclass(frozen=True)
    class Config(CodecConfig):
        rank: int = param(8, low=1, high=4096, doc="kept singular values r (clipped to min(F, m) per clip)")
        weighted: bool = param(False, doc="SVD of (Y - mean) * w (eq. 3 weights) instead of plain Y (the paper)")
        factor_format: str = param("float16", choices=TENSOR_FORMATS, doc="storage of the factors: float16, or uniform n-bit per column of U*S and per row of V")
        factor_bits: int = param(12, low=2, high=16, unit="bits", doc="bits per factor entry for the uniform format")

    def encode_payload(self, motion: Motion) -> bytes:
        config = self.config
        y = pose_matrix(motion)
        weights = pose_weights(motion) if config.weighted else None
        mean, a, b = low_rank_factors(y, config.rank, weights)
        mean = mean.astype(np.float32).astype(np.float64)
        rank, m = a.shape[1], y.shape[1]
        writer = ByteWriter()
        writer.write_bytes(pack_skeleton(motion.skeleton))
        writer.write_varint(rank)
        writer.write_u8(_FORMAT_CODES[config.factor_format])
        writer.write_u8(config.factor_bits if config.factor_format == "uniform" else 0)
        writer.write_array(mean, np.float32)
        # Uniform format: one range per column of A (the components' scales differ by orders of magnitude) and per
        # row of B (one pose parameter: cm of translation and radians have nothing in common).
        for column in range(rank):
            write_tensor(writer, a[:, column], config.factor_format, config.factor_bits)
        for row in range(m):
            write_tensor(writer, b[row], config.factor_format, config.factor_bits)
        num_params = rank * (motion.num_frames + m) + m
        fmt, bits = config.factor_format, config.factor_bits
        a_stored = np.stack([quantize_tensor(a[:, k], fmt, bits) for k in range(rank)], axis=1)
        b_stored = np.stack([quantize_tensor(b[j], fmt, bits) for j in range(m)], axis=0)
        pose_w = pose_weights(motion)
        squared = 0.0
        for start in range(0, motion.num_frames, _BLOCK_FRAMES):  # block by block: no F x m temporaries
            block = slice(start, start + _BLOCK_FRAMES)
            squared += float(np.sum(((y[block] - mean - a_stored[block] @ b_stored.T) * pose_w) ** 2))
        self.last_encode_stats = {
            "rank": rank,
            "num_parameters": num_params,
            "paper_compression_ratio": y.size / num_params,
            "pose_rmse_weighted": float(np.sqrt(squared / y.size)),
        }
        return writer.getvalue()

    def _read(self, header: Header, payload: memoryview) -> dict[str, Any]:
        reader = ByteReader(payload)
        skeleton = unpack_skeleton(reader)
        if skeleton.num_joints != header.num_joints:
            raise BitstreamError(
                f"svd: the header says {header.num_joints} joints, the skeleton in the stream has {skeleton.num_joints}."
            )
        m = num_pose_parameters(skeleton.num_joints)
        rank = reader.read_varint("rank")
        if not 1 <= rank <= min(header.num_frames, m):
            raise BitstreamError(f"svd: expected a rank in [1, {min(header.num_frames, m)}], found {rank}.")
        fmt, bits = read_tensor_format(reader, "svd", "factor")
        mean = reader.read_array(m, np.float32, "column means").astype(np.float64)
        if not np.all(np.isfinite(mean)):
            raise BitstreamError("svd: the column means hold non-finite values.")
        # The factors' bytes are fixed by F, m, r and the format: refuse a payload too short for them before
        # allocating A (F x r), so that a header F edited to 1e8 costs nothing.
        if fmt == "float16":
            needed = 2 * rank * (header.num_frames + m)
        else:
            needed = rank * (header.num_frames * bits + 7) // 8 + m * (rank * bits + 7) // 8
        check_payload_holds(reader.remaining, needed, f"factors of rank {rank}", self.name)
        a = np.empty((header.num_frames, rank))
        b = np.empty((m, rank))
        for column in range(rank):
            a[:, column] = read_tensor(reader, (header.num_frames,), fmt, bits, f"temporal factor U*S, column {column}")
        for row in range(m):
            b[row] = read_tensor(reader, (rank,), fmt, bits, f"pose factor V, row {row}")
        reader.expect_end()
        return {"skeleton": skeleton, "rank": rank, "format": fmt, "bits": bits, "mean": mean, "a": a, "b": b}

    def decode_payload(self, header: Header, payload: memoryview):
        parts = self._read(header, payload)
        mean, a, b = parts["mean"], parts["a"], parts["b"]
        # Y-hat one block of rows at a time: memory is the motion's arrays, A (F x r) and one block, never F x m.
        motion = motion_from_pose_blocks(
            header.num_frames, lambda start, stop: mean + a[start:stop] @ b.T, parts["skeleton"], header.fps
        )
        del parts, a
        return motion.positions(), motion

    def describe_payload(self, header: Header, payload: memoryview) -> dict[str, Any]:
        parts = self._read(header, payload)
        m = num_pose_parameters(header.num_joints)
        num_params = parts["rank"] * (header.num_frames + m) + m
        return {
            "rank": parts["rank"],
            "factor_format": parts["format"] + (f"/{parts['bits']} bits" if parts["format"] == "uniform" else ""),
            "num_parameters": num_params,
            "paper_compression_ratio": header.num_frames * m / num_params,
        }
