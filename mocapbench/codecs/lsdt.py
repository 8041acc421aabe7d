"""Low-latency transform codecs of joint positions: Hou, Chau, Magnenat-Thalmann & He, "Low-latency compression
of mocap data using learned spatial decorrelation transform", Computer Aided Geometric Design 43 (2016) 211-225,
and the spatial DCT / DWT baselines it compares against (Kwak & Bajic, ICME 2011, for the frame-based DCT).

One transform-agnostic pipeline, two schemes, three spatial transforms ``B`` (J × J, one per coordinate)::

    frame scheme (§3.1, zero latency)                    clip scheme (§3.2, latency L frames)
    m_1 ──► c_1 = B m_1                  (eq. 1)          clip M~ (J × L) ──► C~ = M~ U_t   temporal DCT (eq. 4)
    m_i ──► r_i = m_i − m^_{i−1}         (eq. 2)                          ──► C  = B C~     spatial      (eq. 5)
        ──► c_i = B r_i                  (eq. 3)
    then, for every coefficient vector (a column of J coefficients):
        hard threshold |c| <= τ·Δ → 0, uniform quantization q = rint(c / Δ)
        count of nonzeros: fixed length (bit_length(J) bits)
        locations (0..J−1) and values of the nonzeros: canonical Huffman (mocapbench.entropy.huffman)
    decoder: ĉ = Δ q, inverse transform with Bᵀ (and U_tᵀ); the frame decoder accumulates m^_i = m^_{i−1} + Bᵀ ĉ_i.

The frame encoder is closed loop (it runs the decoder): every residual is taken against the *reconstructed*
previous frame, so the error of frame i is the quantization error of frame i alone and does not drift with F.
Because ``B`` is orthogonal the loop runs in the coefficient domain (``c_i = B m_i − Δ K_{i−1}``, ``K`` the integer
running sum of the coded indices), which needs no matrix product per frame and vectorizes over time; the decoder
accumulates the integer indices exactly and applies ``Bᵀ`` once (see :func:`_frame_closed_loop`).
The clip scheme codes a final partial clip of ``F mod L`` frames with a DCT of that length.
A capture of more than :data:`~mocapbench.codecs.windows.WINDOW_FRAMES` frames is coded as windows, each this
pipeline on its own frames (see :meth:`_SpatialTransformCodec._encode_windowed`), so that memory stays bounded.

Registered codecs: ``lsdt-frame``, ``lsdt-clip`` (learned ``B``), ``dct-spatial-frame`` (Kwak & Bajic 2011),
``dct-spatial-clip``, ``dwt-spatial-frame``, ``dwt-spatial-clip`` (3-level Haar, see
:func:`mocapbench.transforms.haar_dwt_matrix`).

Departures from the paper (each also in the report of the issue that added this module):

* The rate–distortion knob is the quantization step ``step_cm`` (Δ, cm in the transform domain; the transforms are
  orthonormal, so Δ is also a step in position space) rather than the paper's "quantization bits"; the hard
  threshold is ``threshold_steps`` × Δ, by default 0.5 Δ, i.e. exactly the dead zone of the rounding quantizer.
* ``count_coding="huffman"`` (an option; the default ``"fixed"`` is the paper's fixed-length count) Huffman-codes the
  per-vector counts of nonzeros. At high compression most vectors are empty and the fixed 5-bit counts (15 bits per
  frame for J = 31) become the largest part of the stream.
* The Huffman tables are built over the whole stream and sent in it, so the *bitstream* is written at the end of the
  clip; the coefficient decisions themselves are causal (frame i reads no frame after i, see
  :class:`FrameEncoder`). A deployed streaming coder would use pre-trained tables; the rate would then differ.
* The spatial DWT is a 3-level Haar made square and orthonormal for odd J by carrying the unpaired last sample to
  the next level (PyWavelets' ``wavedec`` returns J + 1 coefficients for odd lengths); the paper does not say how it
  handled J = 31.
* Added to the stream beyond the paper: an 8-byte fingerprint of the LSDT bases (a stream decoded with other bases is
  rejected instead of silently decoded wrong), one byte naming the count coding, the step (float64) and L (varint).
* The LSDT bases are trained on the ``cmu_train`` split (13,063 frames of subjects 13, 124, 135) instead of the
  paper's 86_02, 56_04, 15_05 (40,332 frames), which are not available here.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from typing import Any, ClassVar, Sequence

import numpy as np
import scipy  # scipy.fft loads on first use (see mocapbench.lazy_imports)

from mocapbench.codecs import container
from mocapbench.codecs.base import Codec, CodecConfig, Header, NotFittedError, param
from mocapbench.codecs.registry import register_codec
from mocapbench.codecs.segments import find_cuts, read_cuts, window_lengths, write_cuts
from mocapbench.codecs.windows import WINDOW_FRAMES, encode_frame_windows, split_windows
from mocapbench.entropy.bitio import BitReader, BitWriter, ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.entropy.huffman import decode_symbols, encode_symbols
from mocapbench.entropy.quantize import quantize
from mocapbench.motion import Motion
from mocapbench.transforms.lsdt import train_lsdt_bases
from mocapbench.transforms.spatial import spatial_basis

__all__ = [
    "BASES_FILE",
    "DctSpatialClipCodec",
    "DctSpatialFrameCodec",
    "DwtSpatialClipCodec",
    "DwtSpatialFrameCodec",
    "FrameEncoder",
    "LsdtClipCodec",
    "LsdtFrameCodec",
    "basis_fingerprint",
    "COUNT_CODINGS",
    "code_vectors",
    "decode_vectors",
    "load_committed_bases",
    "quantize_coefficients",
]

#: The committed LSDT bases (package data), made by ``python -m mocapbench.benchmarks.train_lsdt``.
BASES_FILE = "models/lsdt_bases_v1.npz"
#: Largest J of the spatial-transform codecs: a J x J basis (8 MiB at 1024) is built from the header's J, so it
#: is bounded before anything is built (real skeletons have 15-150 joints).
MAX_TRANSFORM_JOINTS = 1024
#: Sparsities P for which the committed file holds bases (§5.1, Fig. 4).
COMMITTED_SPARSITIES = (2, 5, 8, 11)


# ---------------------------------------------------------------------------------------------------------------------
# learned state


@lru_cache(maxsize=1)
def _committed_file() -> dict[str, np.ndarray]:
    path = resources.files("mocapbench").joinpath(BASES_FILE)
    with path.open("rb") as handle, np.load(handle) as data:
        return {key: np.array(data[key]) for key in data.files}


def load_committed_bases(sparsity: int = 8) -> np.ndarray:
    """The committed LSDT bases trained on ``cmu_train`` with sparsity P.

    Parameters
    ----------
    sparsity : int
        P, one of :data:`COMMITTED_SPARSITIES`.

    Returns
    -------
    ndarray, shape (3, 31, 31), float64
        ``B^x, B^y, B^z`` (rows are basis functions).
    """
    key = f"P{sparsity}"
    data = _committed_file()
    if key not in data:
        available = sorted(int(name[1:]) for name in data if name.startswith("P"))
        raise ValueError(f"The committed LSDT bases file {BASES_FILE} has no bases for P={sparsity}; it has P in {available}.")
    return data[key].copy()


def committed_provenance() -> dict[str, Any]:
    """The JSON sidecar of the committed bases (training clips, frames, iterations, objectives)."""
    path = resources.files("mocapbench").joinpath(BASES_FILE.replace(".npz", ".json"))
    return json.loads(path.read_text())


def basis_fingerprint(bases: np.ndarray) -> bytes:
    """First 8 bytes of the SHA-1 of the bases as little-endian float64: names the bases a stream was coded with."""
    return hashlib.sha1(np.ascontiguousarray(bases, dtype="<f8").tobytes()).digest()[:8]


# ---------------------------------------------------------------------------------------------------------------------
# quantization and entropy coding of coefficient vectors (shared by both schemes and all transforms)


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


# ---------------------------------------------------------------------------------------------------------------------
# the frame-based scheme: a causal, closed-loop encoder


class FrameEncoder:
    """Closed-loop frame-by-frame encoder of §3.1: one call to :meth:`push` per frame, no look-ahead.

    Parameters
    ----------
    bases : ndarray, shape (3, J, J)
        ``B^x, B^y, B^z``.
    step : float, cm
        Δ.
    threshold : float, cm
        Hard threshold (>= Δ / 2).

    Notes
    -----
    This is the literal form of §3.1: the residual is taken against the previous *reconstructed* frame
    ``m^_{i−1}``, rebuilt with the inverse transform as the decoder does (eq. 2-3). It keeps only that frame, so by
    construction frame i's coefficients depend on frames 1..i alone: zero latency. The codecs use the equivalent
    vectorized form (:func:`_frame_closed_loop`), which the tests check against this class index for index.
    """

    def __init__(self, bases: np.ndarray, step: float, threshold: float) -> None:
        bases = np.asarray(bases, dtype=np.float64)
        num_joints = bases.shape[-1]
        # Block-diagonal 3J × 3J form: one matrix-vector product per frame covers x, y and z.
        self._block = np.zeros((3 * num_joints, 3 * num_joints))
        for d in range(3):
            self._block[d * num_joints : (d + 1) * num_joints, d * num_joints : (d + 1) * num_joints] = bases[d]
        self._block_t = np.ascontiguousarray(self._block.T)
        self._step = float(step)
        self._threshold = float(threshold)
        self._threshold_active = threshold > 0.5 * step
        self._previous: np.ndarray | None = None  # m^_{i−1}, shape (3J,)
        self.num_joints = num_joints

    @property
    def reconstruction(self) -> np.ndarray | None:
        """The decoder's reconstruction of the last pushed frame, shape (3, J), cm (None before the first)."""
        return None if self._previous is None else self._previous.reshape(3, self.num_joints)

    def push(self, frame: np.ndarray) -> np.ndarray:
        """Code one frame.

        Parameters
        ----------
        frame : ndarray, shape (3, J), float, cm
            ``[m^x_i, m^y_i, m^z_i]``.

        Returns
        -------
        ndarray, shape (3, J), int64
            The quantized coefficient vectors of this frame (intra for the first frame, residual after).
        """
        vector = np.asarray(frame, dtype=np.float64).reshape(-1)
        residual = vector if self._previous is None else vector - self._previous  # eq. (2)
        coefficients = self._block @ residual  # eq. (1) / (3)
        indices = np.rint(coefficients / self._step)
        if self._threshold_active:
            indices[np.abs(coefficients) <= self._threshold] = 0.0
        decoded_residual = self._block_t @ (indices * self._step)  # the decoder's inverse LSDT
        self._previous = decoded_residual if self._previous is None else self._previous + decoded_residual
        return indices.astype(np.int64).reshape(3, self.num_joints)


def _spatial_forward(frames: np.ndarray, bases: np.ndarray) -> np.ndarray:
    """``g_i = B^d m^d_i`` for every frame and coordinate at once: ``(F, 3, J)`` to ``(F, 3, J)``."""
    return np.matmul(frames.transpose(1, 0, 2), bases.transpose(0, 2, 1)).transpose(1, 0, 2)


def _frame_closed_loop(frames: np.ndarray, bases: np.ndarray, step: float, threshold: float) -> np.ndarray:
    """The closed-loop predictive coder of §3.1 for a whole motion, in the coefficient domain.

    With ``m^_{i−1} = Bᵀ Δ K_{i−1}`` (``K`` the running sum of the coded indices, integers), the residual coefficients
    of eq. (2)-(3) are ``c_i = B (m_i − m^_{i−1}) = g_i − Δ K_{i−1}`` with ``g_i = B m_i``, because ``B Bᵀ = I``.
    So the loop needs no matrix product per frame, and frame i still reads only ``g_i`` and the past. With the plain
    rounding dead zone (threshold = Δ/2) the recurrence ``K_i = K_{i−1} + rint(g_i/Δ − K_{i−1})`` is
    ``K_i = rint(g_i/Δ)`` (up to ties), which vectorizes over time; a wider hard threshold keeps the per-frame loop.

    Parameters
    ----------
    frames : ndarray, shape (F, 3, J), cm
    bases : ndarray, shape (3, J, J)
    step, threshold : float, cm

    Returns
    -------
    ndarray, shape (F, 3, J), int64
        The coded indices: intra for frame 0 (eq. 1), residual after.
    """
    scaled = _spatial_forward(frames, bases) / step  # g_i / Δ
    if threshold <= 0.5 * step:
        levels = np.rint(scaled).astype(np.int64)  # K_i
        indices = levels.copy()
        indices[1:] -= levels[:-1]
        return indices
    ratio = threshold / step
    indices = np.empty(scaled.shape, dtype=np.int64)
    state = np.zeros(scaled.shape[1:])  # K_{i−1}, integer-valued floats
    residual = np.empty(scaled.shape[1:])
    for i in range(scaled.shape[0]):
        np.subtract(scaled[i], state, out=residual)  # c_i / Δ
        coded = np.rint(residual)
        coded[np.abs(residual) <= ratio] = 0.0  # hard threshold
        state += coded
        indices[i] = coded
    return indices


def _frame_reconstruct(indices: np.ndarray, bases: np.ndarray, step: float) -> np.ndarray:
    """Decoder of the frame scheme: ``m^_i = m^_{i−1} + Bᵀ ĉ_i = Bᵀ Δ K_i`` with ``K_i = Σ_{k<=i} q_k`` (integers).

    Parameters
    ----------
    indices : ndarray, shape (F, 3, J), int64
    bases : ndarray, shape (3, J, J)
    step : float, cm

    Returns
    -------
    ndarray, shape (F, J, 3), float64, cm
    """
    levels = np.cumsum(indices, axis=0)  # exact: integer accumulation, so nothing drifts
    return np.matmul(levels.transpose(1, 0, 2) * step, bases).transpose(1, 2, 0)


# ---------------------------------------------------------------------------------------------------------------------
# the clip-based scheme: temporal DCT then spatial transform, batched over clips


def _clip_lengths(num_frames: int, clip_length: int) -> list[int]:
    """Full clips of L frames, then the partial clip of ``F mod L`` frames if any."""
    lengths = [clip_length] * (num_frames // clip_length)
    if num_frames % clip_length:
        lengths.append(num_frames % clip_length)
    return lengths


def _clip_forward(frames: np.ndarray, bases: np.ndarray) -> np.ndarray:
    """eq. (4)-(5) for a batch of clips of one length L.

    Parameters
    ----------
    frames : ndarray, shape (n, L, 3, J), cm
    bases : ndarray, shape (3, J, J)

    Returns
    -------
    ndarray, shape (n, 3, L, J)
        ``C^d`` of each clip, one coefficient vector (a column of C, over the J joints) per temporal frequency k.

    Notes
    -----
    ``C~ = M~ U_t`` (eq. 4) with the orthonormal DCT-II matrix is ``scipy.fft.dct(..., norm="ortho")`` along time:
    O(L log L) per trajectory and no L × L matrix, so any clip length fits in memory.
    """
    n, length, _, num_joints = frames.shape
    spectra = scipy.fft.dct(frames, type=2, norm="ortho", axis=1)  # eq. (4), (n, L, 3, J)
    rows = spectra.transpose(2, 0, 1, 3).reshape(3, n * length, num_joints)
    coefficients = np.matmul(rows, bases.transpose(0, 2, 1))  # eq. (5) in row form: (B C~)ᵀ = C~ᵀ Bᵀ
    return coefficients.reshape(3, n, length, num_joints).transpose(1, 0, 2, 3)


def _clip_inverse(coefficients: np.ndarray, bases: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_clip_forward`: ``(n, 3, L, J)`` coefficients to ``(n, L, 3, J)`` frames, cm."""
    n, _, length, num_joints = coefficients.shape
    rows = np.matmul(coefficients.transpose(1, 0, 2, 3).reshape(3, n * length, num_joints), bases)  # Bᵀ C
    spectra = rows.reshape(3, n, length, num_joints).transpose(1, 2, 0, 3)  # (n, L, 3, J)
    return scipy.fft.idct(spectra, type=2, norm="ortho", axis=1)


# ---------------------------------------------------------------------------------------------------------------------
# codecs


def _check_joints(name: str, bases: np.ndarray, num_joints: int) -> None:
    if bases.shape[-1] != num_joints:
        raise NotFittedError(
            f"{name}: the spatial bases are {bases.shape[-1]} x {bases.shape[-1]} but the motion has {num_joints} "
            f"joints; LSDT bases are learned per skeleton: fit them on clips of this skeleton "
            f"(`mocapbench fit CLIPS... -o MODEL --codec {name}`, then `--model MODEL`)."
        )


#: Set on the count-coding byte when a cut list follows it (clip scheme; streams without cuts are unchanged).
_CUTS_FLAG = 0x80


class _SpatialTransformCodec(Codec):
    """The pipeline shared by the six codecs; subclasses choose the scheme and the spatial transform."""

    scheme: ClassVar[str]  # "frame" or "clip"
    random_access = False  # the coefficient vectors are entropy-coded as one sequence
    smoke_params = {"step_cm": 0.05}
    # Per-coordinate error <= ||c - ĉ||_2 <= sqrt(J) Δ/2 in the worst case; in practice a few Δ at most.
    smoke_max_error_cm = 0.5

    # -- the spatial transform -------------------------------------------------------------------------
    @property
    def latency_frames(self) -> int:
        """Frame-based: 0 (closed-loop prediction, frame by frame); clip-based: the clip length L."""
        return 0 if self.scheme == "frame" else int(self.config.clip_length)

    def _bases(self, num_joints: int) -> np.ndarray:
        """``(3, J, J)`` bases for J joints."""
        raise NotImplementedError

    def _fingerprint(self, num_joints: int) -> bytes:
        """Bytes written in the stream to name the bases (8 bytes of SHA-1 of the bases)."""
        raise NotImplementedError

    def _check_joint_count(self, num_joints: int, error: type[Exception]) -> None:
        """Refuse J above :data:`MAX_TRANSFORM_JOINTS` before any J x J basis is built."""
        if num_joints > MAX_TRANSFORM_JOINTS:
            raise error(
                f"{self.name}: {num_joints} joints; the spatial transforms take at most {MAX_TRANSFORM_JOINTS} "
                f"(a J x J basis per coordinate)."
            )

    # -- payload ---------------------------------------------------------------------------------------
    def encode_positions(self, positions: np.ndarray, fps: float = 120.0) -> bytes:
        """Encode joint positions directly (the paper's input), without a skeleton or forward kinematics.

        Parameters
        ----------
        positions : ndarray, shape (F, J, 3), float, cm
        fps : float
            Stored in the container header.

        Returns
        -------
        bytes
            A stream :meth:`decode` reads, identical to ``encode(motion)`` for a motion with these positions.
        """
        positions = np.asarray(positions, dtype=np.float64)
        if positions.ndim != 3 or positions.shape[2] != 3 or positions.shape[0] < 1 or positions.shape[1] < 1:
            raise ValueError(f"{self.name}: expected `positions` of shape (F, J, 3) with F, J >= 1, got {positions.shape}.")

        def window(start: int, stop: int) -> np.ndarray:  # checked window by window: no F-sized temporary
            part = positions[start:stop]
            if not np.all(np.isfinite(part)):
                raise ValueError(f"{self.name}: `positions` holds non-finite values.")
            reach = max(-float(part.min()), float(part.max()))
            if reach > self.max_coordinate_cm:
                raise ValueError(
                    f"{self.name}: a joint lies {reach:.3g} cm from the origin; this codec's numeric range "
                    f"is ±{self.max_coordinate_cm:g} cm (re-centre the motion or check its length unit)."
                )
            return part

        self.last_encode_stats = {}
        payload = self._encode_windowed(positions.shape[0], positions.shape[1], window)
        return container.pack(self.name, positions.shape[0], positions.shape[1], float(fps), payload)

    def encode_payload(self, motion: Motion) -> bytes:
        if motion.num_frames <= WINDOW_FRAMES:
            return self._encode_windowed(motion.num_frames, motion.num_joints, lambda start, stop: motion.positions())
        return self._encode_windowed(
            motion.num_frames, motion.num_joints, lambda start, stop: motion.slice(start, stop).positions()
        )

    def _window_frames(self) -> int:
        """Frames per window of a long capture: :data:`WINDOW_FRAMES` (frame scheme), rounded down to whole clips of
        L for the clip scheme (at least one clip), so that the windows keep the clip grid of an unwindowed stream."""
        if self.scheme == "frame":
            return WINDOW_FRAMES
        return max(1, WINDOW_FRAMES // self.config.clip_length) * self.config.clip_length

    def _encode_windowed(self, num_frames: int, num_joints: int, window_positions) -> bytes:
        """One payload (every capture up to :data:`WINDOW_FRAMES` frames), else a sequence of windows.

        A longer capture is coded as the window length (varint, frames) then length-prefixed windows
        (:mod:`mocapbench.codecs.windows`), each a payload of its own: the paper's pipeline, unchanged, on the window's
        frames (its own Huffman tables; the frame scheme restarts its closed loop with an intra frame, eq. 1; the
        clip scheme keeps the clip grid of L frames, :meth:`_window_frames`, and finds the cuts within the window).
        So the encoder holds one window's positions and temporaries and the decoder one window's temporaries beside
        its output. ``window_positions(start, stop)`` gives frames ``start:stop`` as an ``(n, J, 3)`` array, cm.
        """
        if num_frames <= WINDOW_FRAMES:
            return self._encode_positions(window_positions(0, num_frames))
        window_frames = self._window_frames()

        def encode_window(start: int, stop: int) -> tuple[bytes, dict]:
            return self._encode_positions(window_positions(start, stop)), self.last_encode_stats

        windows, stats = encode_frame_windows(num_frames, window_frames, encode_window)
        writer = ByteWriter()
        writer.write_varint(window_frames)
        payload = writer.getvalue() + windows
        nonzero = sum(window["nonzero_coefficients"] for window in stats)
        self.last_encode_stats = {
            "windows": len(stats),
            "nonzero_coefficients": nonzero,
            "nonzero_percent": 100.0 * nonzero / (3 * num_frames * num_joints),  # one coefficient per coordinate
            "cuts": sum(window["cuts"] for window in stats),
        }
        return payload

    def _encode_positions(self, positions: np.ndarray) -> bytes:
        num_frames, num_joints = positions.shape[:2]
        self._check_joint_count(num_joints, ValueError)
        bases = self._bases(num_joints)
        _check_joints(self.name, bases, num_joints)
        step = self.config.step_cm
        threshold = self.config.threshold_steps * step
        frames = np.ascontiguousarray(positions.transpose(0, 2, 1))  # (F, 3, J): the columns m^d_i
        cuts = np.zeros(0, dtype=np.int64)
        if self.scheme == "frame":
            vectors = _frame_closed_loop(frames, bases, step, threshold).reshape(-1, num_joints)
        else:
            if self.config.cut_detection:
                cuts = find_cuts(positions)
            blocks = []
            start = 0
            for length, count in self._clip_groups(num_frames, cuts=cuts):
                stop = start + length * count
                batch = frames[start:stop].reshape(count, length, 3, num_joints)
                coefficients = _clip_forward(batch, bases)
                blocks.append(quantize_coefficients(coefficients, step, threshold).reshape(-1, num_joints))
                start = stop
            vectors = np.concatenate(blocks)
        writer = ByteWriter()
        writer.write_bytes(self._fingerprint(num_joints))
        writer.write_u8(COUNT_CODINGS.index(self.config.count_coding) | (_CUTS_FLAG if len(cuts) else 0))
        writer.write_f64(step)
        if self.scheme == "clip":
            writer.write_varint(self.config.clip_length)
            if len(cuts):
                write_cuts(writer, cuts)
        writer.write_bytes(code_vectors(vectors, self.config.count_coding))
        nonzero = int(np.count_nonzero(vectors))
        self.last_encode_stats = {
            "nonzero_coefficients": nonzero,
            "nonzero_percent": 100.0 * nonzero / vectors.size,
            "cuts": len(cuts),
        }
        return writer.getvalue()

    def decode_payload(self, header: Header, payload: memoryview):
        """One window's payload (every stream up to :data:`WINDOW_FRAMES` frames), else a sequence of windows, each
        decoded into its frames of the output: a window's temporaries beside the output, whatever the length."""
        num_frames, num_joints = header.num_frames, header.num_joints
        self._check_joint_count(num_joints, BitstreamError)
        if num_frames <= WINDOW_FRAMES:
            return self._decode_window(header, payload), None
        reader = ByteReader(payload)
        window_frames = reader.read_varint("window frames")
        if window_frames < 1:
            raise BitstreamError(f"{self.name}: expected at least 1 frame per window, found {window_frames}.")
        # Every extent is checked before anything is decoded.
        windows = split_windows(payload[reader.offset :], num_frames, window_frames)
        positions = np.empty((num_frames, num_joints, 3))
        for start, stop, part in windows:
            positions[start:stop] = self._decode_window(Header(header.codec, stop - start, num_joints, header.fps), part)
        return positions, None

    def _decode_window(self, header: Header, payload: memoryview) -> np.ndarray:
        """Positions (F, J, 3) cm of one window's payload (a whole stream up to :data:`WINDOW_FRAMES` frames)."""
        num_frames, num_joints = header.num_frames, header.num_joints
        reader = ByteReader(payload)
        expected = self._fingerprint(num_joints)
        if expected:
            found = reader.read_bytes(len(expected), "bases fingerprint")
            if found != expected:
                raise BitstreamError(
                    f"{self.name}: the stream was coded with bases {found.hex()}, this codec holds {expected.hex()} "
                    f"(another transform, another sparsity P, another training set, or another basis file)"
                )
        bases = self._bases(num_joints)
        if bases.shape[-1] != num_joints:
            raise BitstreamError(f"{self.name}: the stream has {num_joints} joints, the bases {bases.shape[-1]}.")
        coding = reader.read_u8("count coding")
        has_cuts = bool(coding & _CUTS_FLAG) and self.scheme == "clip"
        coding &= ~_CUTS_FLAG if self.scheme == "clip" else 0xFF
        if coding >= len(COUNT_CODINGS):
            raise BitstreamError(f"{self.name}: expected a count coding in 0..{len(COUNT_CODINGS) - 1}, found {coding}.")
        step = reader.read_f64("quantization step")
        if not (np.isfinite(step) and step > 0):
            raise BitstreamError(f"{self.name}: expected a positive quantization step, found {step!r}.")
        if self.scheme == "clip":
            clip_length = reader.read_varint("clip length")
            if not 1 <= clip_length <= 1 << 20:
                raise BitstreamError(f"{self.name}: expected a clip length in [1, 2**20], found {clip_length}.")
            cuts = read_cuts(reader, num_frames, self.name) if has_cuts else ()
        else:
            clip_length, cuts = 0, ()
        vectors = decode_vectors(reader.read_bytes(reader.remaining, "coefficient streams"), 3 * num_frames,
                                 num_joints, COUNT_CODINGS[coding])
        if self.scheme == "frame":
            positions = _frame_reconstruct(vectors.reshape(num_frames, 3, num_joints), bases, step)
        else:
            parts = []
            start = 0
            for length, count in self._clip_groups(num_frames, clip_length, cuts):
                stop = start + count * 3 * length
                coefficients = vectors[start:stop].reshape(count, 3, length, num_joints) * step
                parts.append(_clip_inverse(coefficients, bases).reshape(count * length, 3, num_joints))
                start = stop
            positions = np.concatenate(parts).transpose(0, 2, 1)
        return positions

    # -- stream layout ---------------------------------------------------------------------------------
    def _clip_groups(self, num_frames: int, clip_length: int | None = None, cuts=()) -> list[tuple[int, int]]:
        """``(length, number of clips)`` runs in stream (time) order: each segment's full clips, then its remainder.

        Segments are the frames between ``cuts`` (:mod:`mocapbench.codecs.segments`); without cuts: the full clips,
        then the partial one.
        """
        clip_length = self.config.clip_length if clip_length is None else clip_length
        groups: list[tuple[int, int]] = []
        for length in window_lengths(num_frames, clip_length, cuts):
            if groups and groups[-1][0] == length:
                groups[-1] = (length, groups[-1][1] + 1)
            else:
                groups.append((length, 1))
        return groups

    def describe_payload(self, header: Header, payload: memoryview) -> dict[str, Any]:
        info: dict[str, Any] = {"scheme": self.scheme}
        reader = ByteReader(payload)
        num_frames = header.num_frames
        if num_frames > WINDOW_FRAMES:  # a sequence of windows: describe the first
            window_frames = reader.read_varint("window frames")
            reader.read_varint("window length")
            count = -(-num_frames // max(window_frames, 1))
            info["windows of frames"] = f"{count} x {window_frames} (first shown)"
            num_frames = min(num_frames, window_frames)
        reader.read_bytes(len(self._fingerprint(header.num_joints)), "bases fingerprint")
        coding = reader.read_u8("count coding")
        info["count_coding"] = COUNT_CODINGS[(coding & ~_CUTS_FLAG) % len(COUNT_CODINGS)]
        info["step_cm"] = reader.read_f64("quantization step")
        if self.scheme == "clip":
            info["clip_length"] = reader.read_varint("clip length")
            cuts = read_cuts(reader, num_frames, self.name) if coding & _CUTS_FLAG else ()
            info["cuts (frames starting a segment)"] = [int(cut) for cut in cuts]
        return info


# -- configs ---------------------------------------------------------------------------------------------


_STEP_DOC = "uniform quantization step Δ of the transform coefficients (the rate-distortion knob)"
_THRESHOLD_DOC = (
    "hard threshold in units of Δ: coefficients with |c| <= threshold_steps·Δ are zeroed; 0.5 = the dead zone of "
    "the rounding quantizer itself"
)
_COUNT_DOC = (
    "coding of the number of nonzeros per coefficient vector: 'fixed' = bit_length(J) bits each (the paper), "
    "'huffman' = canonical Huffman (an option, not in the paper)"
)
_CLIP_DOC = "clip length L (the latency); the paper uses 60, 120, 240 at 120 fps"


@dataclass(frozen=True)
class _FrameConfig(CodecConfig):
    step_cm: float = param(0.5, low=1e-4, high=1000.0, unit="cm", doc=_STEP_DOC)
    threshold_steps: float = param(0.5, low=0.5, high=100.0, unit="steps", doc=_THRESHOLD_DOC)
    count_coding: str = param("fixed", choices=COUNT_CODINGS, doc=_COUNT_DOC)


_CUT_DOC = (
    "split the clips at discontinuities (a T-pose frame, a cut between takes, a teleport; "
    "mocapbench.codecs.segments): not in the paper, which codes fixed clips of L frames"
)


@dataclass(frozen=True)
class _ClipConfig(_FrameConfig):
    clip_length: int = param(120, low=1, high=1 << 20, unit="frames", doc=_CLIP_DOC)
    cut_detection: bool = param(True, doc=_CUT_DOC)


_SPARSITY_DOC = "P, nonzeros per training vector in LSDT training (eq. 6); committed bases exist for 2, 5, 8, 11"
_BASIS_DOC = "'cmu-v1': the committed bases trained on cmu_train (fit() is a no-op); 'fit': train in fit()"
_ITER_DOC = "maximum iterations K of Algorithm 1 when basis='fit'"


@dataclass(frozen=True)
class _LsdtFrameConfig(_FrameConfig):
    sparsity: int = param(8, low=1, high=4096, doc=_SPARSITY_DOC)
    basis: str = param("cmu-v1", choices=("cmu-v1", "fit"), doc=_BASIS_DOC)
    train_iterations: int = param(300, low=1, high=100_000, doc=_ITER_DOC)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.basis == "cmu-v1" and self.sparsity not in COMMITTED_SPARSITIES:
            raise ValueError(
                f"sparsity={self.sparsity} has no committed bases (they exist for P in {list(COMMITTED_SPARSITIES)}); "
                f"use basis='fit' to train bases with this P."
            )


@dataclass(frozen=True)
class _LsdtClipConfig(_LsdtFrameConfig):
    clip_length: int = param(120, low=1, high=1 << 20, unit="frames", doc=_CLIP_DOC)
    cut_detection: bool = param(True, doc=_CUT_DOC)


class _LsdtBases:
    """Mixin: the learned bases (committed, or trained in :meth:`fit`)."""

    # The bases are learned for one skeleton (31 CMU joints committed; basis='fit' for another).
    needs_model = True
    _trained: np.ndarray | None = None  # the main learned bases (the skeleton with the most training frames)
    _trained_by_joints: dict[int, np.ndarray] = {}  # every learned basis set, by joint count (replaced in fit)

    def fit(self, motions: Sequence[Motion]):
        """Run Algorithm 1 on the frames of ``motions`` (DCT init) with ``basis='fit'``, or with ``basis='cmu-v1'``
        for the motions whose skeleton is not the committed bases' (31 joints); otherwise do nothing.

        Motions of several joint counts get one basis set each. The committed bases (``basis='cmu-v1'``) were
        produced from ``cmu_train`` by ``python -m mocapbench.benchmarks.train_lsdt``; refitting on the CMU
        training motions of a run would only repeat that. Any number of motions of any length (1 frame) fits.
        """
        if not motions:
            raise ValueError(f"{self.name}: fit() needs at least one training motion.")
        groups: dict[int, list[Motion]] = {}
        for motion in motions:
            groups.setdefault(motion.num_joints, []).append(motion)
        committed = None if self.config.basis == "fit" else load_committed_bases(self.config.sparsity).shape[-1]
        trained, frames = {}, {}
        self.training_objective = []
        for num_joints, group in groups.items():
            if num_joints == committed:
                continue
            if self.config.sparsity > num_joints:
                raise ValueError(
                    f"{self.name}: sparsity={self.config.sparsity} exceeds the {num_joints} joints of the motions."
                )
            positions = np.concatenate([motion.positions() for motion in group])
            trained[num_joints], results = train_lsdt_bases(
                positions, self.config.sparsity, init="dct", max_iterations=self.config.train_iterations
            )
            frames[num_joints] = len(positions)
            self.training_objective += [result.objective for result in results]
        self._trained_by_joints = trained
        self._trained = trained[max(frames, key=frames.get)] if trained else None
        return self

    def set_bases(self, bases: np.ndarray):
        """Use given bases as the learned state, e.g. bases trained once for many configs or read from a model file.

        With ``basis='cmu-v1'`` only bases of another joint count than the committed ones are accepted (the
        committed file serves its own skeleton).

        Parameters
        ----------
        bases : ndarray, shape (3, J, J), float
            Orthogonal ``B^x, B^y, B^z`` (``||B Bᵀ − I|| < 1e-10``).
        """
        committed = None if self.config.basis == "fit" else load_committed_bases(self.config.sparsity).shape[-1]
        if committed is not None and np.shape(bases)[-1] == committed:
            raise ValueError(f"{self.name}: set_bases needs basis='fit'; basis={self.config.basis!r} uses the committed file.")
        bases = np.array(bases, dtype=np.float64)
        if bases.ndim != 3 or bases.shape[0] != 3 or bases.shape[1] != bases.shape[2]:
            raise ValueError(f"{self.name}: expected bases of shape (3, J, J), got {bases.shape}.")
        identity = np.eye(bases.shape[1])
        if max(np.abs(b @ b.T - identity).max() for b in bases) >= 1e-10:
            raise ValueError(f"{self.name}: the bases must be orthogonal (||B Bᵀ − I|| < 1e-10).")
        self._trained = bases
        self._trained_by_joints = {**self._trained_by_joints, bases.shape[-1]: bases}
        return self

    def model_state(self) -> dict[str, np.ndarray]:
        """The learned bases as arrays, for a model file or a sweep's shared state (:mod:`.model_file`).

        Empty when nothing was learned (``basis='cmu-v1'`` fit on the committed skeleton); bases of other
        skeletons than the main one under ``j<joints>__`` keys.
        """
        from mocapbench.codecs.model_file import join_states

        if self._trained is None:
            return {}
        others = {joints: {"bases": bases} for joints, bases in self._trained_by_joints.items()
                  if bases is not self._trained}
        return join_states({"bases": self._trained}, others)

    def load_model_state(self, arrays):
        """Hold the bases stored by :meth:`model_state` (nothing for an empty state)."""
        from mocapbench.codecs.model_file import split_states

        main, others = split_states(arrays)
        if not main:
            self._trained, self._trained_by_joints = None, {}
            return self
        self.set_bases(main["bases"])
        for state in others.values():
            self.set_bases(state["bases"])
        self._trained = np.array(main["bases"], dtype=np.float64)
        self._trained_by_joints = {**self._trained_by_joints, self._trained.shape[-1]: self._trained}
        return self

    def _bases(self, num_joints: int) -> np.ndarray:
        self._used_joints = num_joints
        if num_joints in self._trained_by_joints:
            return self._trained_by_joints[num_joints]
        if self._trained is not None and (self.config.basis == "fit" or self._trained.shape[-1] == num_joints):
            return self._trained
        if self.config.basis == "fit":
            raise NotFittedError(f"{self.name}: basis='fit' needs fit(motions) before encoding or decoding.")
        return load_committed_bases(self.config.sparsity)

    def _fingerprint(self, num_joints: int) -> bytes:
        return basis_fingerprint(self._bases(num_joints))

    @property
    def model_bytes(self) -> int:
        """Bytes of the three J × J float64 bases a decoder needs beside the stream (31 joints: 23,064).

        With bases for several skeletons: those of the last coded motion's skeleton.
        """
        joints = getattr(self, "_used_joints", None)
        try:
            bases = self._bases(joints) if joints is not None else self._trained
        except NotFittedError:
            bases = None
        if bases is None and self.config.basis != "fit":
            bases = load_committed_bases(self.config.sparsity)
        return 0 if bases is None else int(bases.nbytes)


class _FixedBases:
    """Mixin: a data-independent spatial transform (nothing to store)."""

    transform: ClassVar[str]

    def _bases(self, num_joints: int) -> np.ndarray:
        return _fixed_bases(self.transform, num_joints)[0]

    def _fingerprint(self, num_joints: int) -> bytes:
        # As the LSDT streams do: a DCT stream relabelled as a DWT one (CRC recomputed) is refused, not decoded
        # to another motion.
        return _fixed_bases(self.transform, num_joints)[1]


@lru_cache(maxsize=16)
def _fixed_bases(kind: str, num_joints: int) -> tuple[np.ndarray, bytes]:
    """The fixed bases for J joints and their fingerprint (callers check J <= MAX_TRANSFORM_JOINTS first)."""
    bases = spatial_basis(kind, num_joints)
    bases.flags.writeable = False
    return bases, basis_fingerprint(bases)


@register_codec
class LsdtFrameCodec(_LsdtBases, _SpatialTransformCodec):
    """LSDT frame-based codec (Hou et al. 2016, §3.1): zero latency, closed-loop prediction, learned B."""

    name = "lsdt-frame"
    scheme = "frame"

    @dataclass(frozen=True)
    class Config(_LsdtFrameConfig):
        """Fields: see the module docstring and ``describe_fields()``."""


@register_codec
class LsdtClipCodec(_LsdtBases, _SpatialTransformCodec):
    """LSDT clip-based codec (Hou et al. 2016, §3.2): temporal DCT over clips of L frames, then learned B."""

    name = "lsdt-clip"
    scheme = "clip"

    @dataclass(frozen=True)
    class Config(_LsdtClipConfig):
        """Fields: see the module docstring and ``describe_fields()``."""


@register_codec
class DctSpatialFrameCodec(_FixedBases, _SpatialTransformCodec):
    """Frame-based codec with the spatial 1-D DCT (Kwak & Bajic, ICME 2011, as compared in Hou et al. 2016)."""

    name = "dct-spatial-frame"
    scheme = "frame"
    transform = "dct"

    @dataclass(frozen=True)
    class Config(_FrameConfig):
        """Fields: see the module docstring and ``describe_fields()``."""


@register_codec
class DctSpatialClipCodec(_FixedBases, _SpatialTransformCodec):
    """Clip-based pipeline of Hou et al. 2016 with the spatial 1-D DCT in place of the LSDT."""

    name = "dct-spatial-clip"
    scheme = "clip"
    transform = "dct"

    @dataclass(frozen=True)
    class Config(_ClipConfig):
        """Fields: see the module docstring and ``describe_fields()``."""


@register_codec
class DwtSpatialFrameCodec(_FixedBases, _SpatialTransformCodec):
    """Frame-based pipeline of Hou et al. 2016 with a 3-level Haar DWT (PyWavelets) in place of the LSDT."""

    name = "dwt-spatial-frame"
    scheme = "frame"
    transform = "dwt"

    @dataclass(frozen=True)
    class Config(_FrameConfig):
        """Fields: see the module docstring and ``describe_fields()``."""


@register_codec
class DwtSpatialClipCodec(_FixedBases, _SpatialTransformCodec):
    """Clip-based pipeline of Hou et al. 2016 with a 3-level Haar DWT (PyWavelets) in place of the LSDT."""

    name = "dwt-spatial-clip"
    scheme = "clip"
    transform = "dwt"

    @dataclass(frozen=True)
    class Config(_ClipConfig):
        """Fields: see the module docstring and ``describe_fields()``."""
