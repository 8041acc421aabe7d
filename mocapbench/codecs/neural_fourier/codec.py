"""Neural motion compression with a Fourier-feature MLP: ``fourier-mlp-int`` and ``fourier-mlp-dct``.

Paper: K. Tojo, Y. Chen, N. Umetani, "Neural Motion Compression with Frequency-adaptive Fourier Feature
Network" (Eurographics 2022 short paper; ``../shared/papers/neural-fourier-motion-compression.txt``).

One clip is one network. The pose matrix ``Y`` (F × m, :mod:`.pose_params`, §3) is fitted as a function of the
normalized time ``t ∈ [0, 1]``::

    t ──► x(t; Ω) = [t, sin 2πω₁t, cos 2πω₁t, …, sin 2πω_Kt, cos 2πω_Kt]        (eq. 1)
      ──► W₂ ELU(W₁ ELU(W₀ x + b₀) + b₁) + b₂,   hidden size h = 2 (2K + 1)       (eq. 2)
      ──► ŷ(t) ──► quaternion normalized, axis-angles ──► forward kinematics ──► Motion

trained on the weighted L2 loss of eq. (3), ``Σ ‖(y_i − F(x_i)) ∘ w‖²``.

* ``fourier-mlp-int`` (the paper's "naïve frequency" baseline, §4.1): ``Ω = {1, …, K}``, trained once.
* ``fourier-mlp-dct`` (Algorithm 1, §3.2): start from ``Ω = ∅``; train; stop when the L∞ joint-position error
  is under the threshold; else take the weighted residual ``R ∘ w``, the time history of its first principal
  component, its DCT, and append the peak frequency to Ω (never one already there); grow the network with the old
  weights copied in (warm start) and train again; at most ``K_max`` frequencies.

The stream holds the skeleton (for FK), Ω (float32, angular velocity in cycles per clip), the per-column
normalization (float16), and the network weights ``α`` quantized (float16, or uniform n-bit per tensor with the
range as float32). The time grid ``t_i = i / (F − 1)`` is rebuilt from F in the container header. Decoding is
numpy only (no torch); the encoder evaluates its stopping test on exactly the quantized weights it writes, so the
L∞ that the stream delivers is the one that was checked.

After ``encode``, ``last_encode_stats`` holds ``K``, ``omegas`` (Ω), ``train_s`` (training wall time, s),
``num_parameters`` (|α|), ``paper_compression_ratio`` (F·m / |α|) and ``encoder_max_err_cm`` (the L∞ of the
stream); ``fourier-mlp-dct`` adds ``threshold_cm``, ``threshold_met`` and per round (K = 0, 1, …)
``round_max_err_cm``, ``round_payload_bytes``, ``round_kept_pass`` (which pass of the round it kept, 0: the fit of
eq. (3)) and ``round_train_s`` (cumulative). ``last_training_log`` holds
the loss before every optimizer step and after the last one, one array per training pass (one per round, and
``reweight_passes`` more per round for ``fourier-mlp-dct``, after the one for ``fourier-mlp-int``); ``fourier-mlp-int``
adds ``kept_pass`` (which of its passes the stream holds, 0: the unweighted fit).

Where this departs from the paper, and why
------------------------------------------
* **Angular-velocity convention.** Eq. (1) writes ``sin ω t``, but §4.1 says "angular velocity takes value two
  … when its feature cycles twice throughout the sequence", so a feature is ``sin(2π ω t)`` here with ω in
  cycles per clip. A DCT-II index k of an F-sample signal is ``cos(π k (2n + 1) / 2F)`` = ``k (F − 1) / 2F``
  cycles over ``t ∈ [0, 1]``, which is the ω appended (the phase is irrelevant: both sin and cos are used).
* **Normalization.** ``Y`` is standardized per column (mean and standard deviation, rounded to float16 before
  training so the decoder uses exactly the training values) and the loss weights become ``w · std`` so that the
  loss is still eq. (3) in the original units (``mean`` over entries instead of the sum: a constant factor).
  This only reparameterizes the output layer; it makes training converge on root translations of hundreds of cm.
  The 2m normalization numbers are in the bitstream but not in the paper's parameter count (which counts ``α``).
* **Optimizer** (not given in the paper). With ``optimizer="lbfgs"`` and ``solve_output=True`` (the default of
  both codecs: 100 iterations per round for ``fourier-mlp-int``, 50 + 50 for ``fourier-mlp-dct``) the output
  layer ``[W2 | b2]``, in which the network is linear, is solved by least squares on the hidden activations at
  every evaluation (variable projection: the loss is eq. (3) minimized over the output layer), and the two hidden
  layers are trained by full-batch L-BFGS with a backtracking (Armijo) line search, ``iterations_per_round``
  iterations per round (one loss and gradient each). The network and Algorithm 1 are the paper's; how the
  minimum of eq. (3) is sought differs, and it reaches a lower loss in about a hundredth of Adam's steps
  (README). A line search never accepts a higher loss, so a warm-started round starts from the previous round's
  function (its output layer re-solved with the new units: no higher loss, to the ridge) and never jumps back
  up. For ``fourier-mlp-int`` it gives the same streams at a lower mean L∞ than Adam. The naive
  baseline is trained once with ``iterations_per_round · (K + 1)`` iterations, the budget the adaptive codec
  spends to reach K (its default: 50 + 50 per round, the second pass L∞-weighted), then its own L∞-weighted pass
  (``reweight_passes``, below: one more ``iterations_per_round``). ``rank_tolerance > 0`` (opt-in, off by default) fits the hidden layers to the targets'
  leading principal components only (less arithmetic per step: the products over the outputs are most of it)
  and solves the output layer on all of them at the end; it is off because at a tight bound the left-out
  components are what is missing (README, "Timings", the ``rank_tolerance`` item, has both measurements).
  ``learning_rate`` sets only L-BFGS's first step (no weight moves by more than it).
* **Frame weights** (``reweight_passes``, by default on for ``fourier-mlp-dct``; not in the paper). Plain eq. (3)
  by L-BFGS reaches a lower L2 loss than Adam, but L∞, the stopping test of Algorithm 1, does not follow it, and several clips then
  stop at a larger K (README). So each round is followed by ``reweight_passes`` more passes of
  ``iterations_per_round`` iterations in which each frame's term of eq. (3) is weighted by
  ``(its L∞ error / the clip's mean) ** reweight_power`` (multiplied from pass to pass, mean 1; iteratively
  reweighted least squares toward the minimax fit; the error is measured as the stopping test measures it, on
  the quantized network through FK). Every round starts from the unweighted eq. (3); the residual whose DCT
  peak Algorithm 1 adds is that of the unweighted fit (the weighted fit's residual is shaped by the weights, and
  on a clean two-sinusoid test motion its peaks miss the true frequencies). A pass is not guaranteed to lower
  the L∞, so each round keeps, for its stream and as the next round's start, the pass of lowest L∞ (the fit of
  eq. (3) or one of its weighted passes; every pass is measured anyway, so this costs only copies). The weights of a pass follow the errors of the one before, so a
  difference in the order of floating-point sums (a clip trained alone or beside others) can grow into another
  fit of about the same error, as Adam's tens of thousands of steps do at K = 10 (README). ``reweight_passes=0`` with ``optimizer="adam"``,
  ``solve_output=False`` and ``iterations_per_round=2000`` is the plain schedule below. ``fourier-mlp-int`` has the
  same option (its K is fixed, so a pass can change only the stream's L∞): after its single training,
  ``reweight_passes`` passes of ``iterations_per_round`` iterations, and each clip keeps the network of lowest L∞
  among the unweighted fit and its passes (a pass is not guaranteed to lower the L∞; keeping the best is, at the
  cost of one evaluation per pass).
* **Adam**, ``optimizer="adam"`` with ``solve_output=False`` (opt-in): per round
  ``iterations_per_round`` full-batch Adam steps, learning rate warmed up linearly over the first
  ``warmup_fraction`` of the steps, then cosine-decayed to 5 %; the peak rate of round r is
  ``learning_rate · round_lr_decay**r`` (floor 10 %). A fresh Adam state after a warm start, at full rate, kicks
  the copied near-optimal weights back up (measured: loss 0.006 → 17 on a 900-frame clip); the warmup and the
  per-round decay keep the loss from jumping back. It needs about 2000 steps per round.
* **Stopping.** Each round runs its iterations unless a network's loss has stopped falling: a change of at most
  ``stop_tolerance`` (relative) over the last 200 iterations (for Adam, after the warm-up) ends its round there,
  and so does an L-BFGS line search that can no longer lower the loss in float32.
* **Many clips at once.** :meth:`encode_many` trains the networks of many clips side by side (stacked weights,
  batched matrix products, gradients and the optimizer written out: :mod:`mocapbench.codecs.neural_fourier.training`);
  Algorithm 1 runs in lockstep, round r training every clip still searching. Each network keeps its own
  initialization, schedule and stopping, so a clip's stream is the one it gets alone, up to the order of
  floating-point sums (which L-BFGS's line search and the L-inf passes can grow into another fit of about the
  same error). ``device=cuda`` trains on a GPU when torch sees one (optional; the CPU is the default).
* **Warm start.** New input columns, new hidden units' outgoing weights are zero and the new units' incoming
  weights are drawn like a fresh layer: the grown network computes exactly the old function at its first step.
* **PCA on the residual** centres the weighted residual's columns first (the usual PCA); the DC bin of the DCT
  is excluded (a constant is what the biases fit).
* **Leaf joints' weights** include end sites (see :func:`~mocapbench.codecs.neural_fourier.pose_params.pose_weights`).
* **Bytes, not parameters.** mocapbench's rate is the real stream; ``paper_compression_ratio`` (size of Y divided
  by ``|α|``, the paper's definition) is reported beside it in ``last_encode_stats``.
"""

from __future__ import annotations

import importlib.util
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy  # scipy.fft loads on first use (see mocapbench.lazy_imports)

from mocapbench.codecs.base import Codec, CodecConfig, Header, param
from mocapbench.codecs.neural_fourier.pose_params import (
    TENSOR_FORMATS,
    motion_from_pose_blocks,
    motion_from_pose_matrix,
    num_pose_parameters,
    pose_matrix,
    pose_weights,
    quantize_tensor,
    read_tensor,
    read_tensor_format,
    write_tensor,
)
from mocapbench.codecs.neural_fourier.training import (
    Network,
    TrainingSettings,
    network_shapes,
    time_grid as _time_grid,
    train_round,
)
from mocapbench.codecs.registry import register_codec, register_unavailable
from mocapbench.codecs.skeleton_blob import pack_skeleton, unpack_skeleton
from mocapbench.entropy.bitio import ByteReader, ByteWriter
from mocapbench.entropy.errors import BitstreamError
from mocapbench.motion import Motion

__all__ = [
    "FourierMlpIntCodec",
    "FourierMlpDctCodec",
    "fourier_features",
    "mlp_forward",
    "dct_index_to_omega",
    "network_shapes",
    "num_network_parameters",
]

MAX_FREQUENCIES = 256  # decoder's limit on K
_FORMAT_CODES = {name: code for code, name in enumerate(TENSOR_FORMATS)}
_MIN_STD = 1e-3  # a column with a smaller standard deviation is scaled by 1 (constant channels of CMU data)


# -- the network (numpy: what the decoder runs) -------------------------------------------------------------------


def fourier_features(t: np.ndarray, omegas: np.ndarray) -> np.ndarray:
    """The Fourier feature of eq. (1), ω in cycles per clip.

    Parameters
    ----------
    t : ndarray, shape (N,), float
        Normalized time in ``[0, 1]``.
    omegas : ndarray, shape (K,), float
        Angular velocities, cycles over ``t ∈ [0, 1]``.

    Returns
    -------
    ndarray, shape (N, 2K + 1), float64
        ``[t, sin 2πω₁t, cos 2πω₁t, …]``.
    """
    t = np.asarray(t, dtype=np.float64)[:, None]
    phase = 2.0 * np.pi * t * np.asarray(omegas, dtype=np.float64)[None, :]
    out = np.empty((t.shape[0], 1 + 2 * phase.shape[1]))
    out[:, :1] = t
    out[:, 1::2] = np.sin(phase)
    out[:, 2::2] = np.cos(phase)
    return out


def _elu(x: np.ndarray) -> np.ndarray:
    return np.where(x > 0, x, np.expm1(np.minimum(x, 0.0)))


def mlp_forward(x: np.ndarray, weights: list[np.ndarray]) -> np.ndarray:
    """The three-layer ELU network of eq. (2).

    Parameters
    ----------
    x : ndarray, shape (N, 2K + 1)
    weights : list of ndarray
        ``[W0 (h, 2K+1), b0 (h,), W1 (h, h), b1 (h,), W2 (m, h), b2 (m,)]``.

    Returns
    -------
    ndarray, shape (N, m), float64
    """
    w0, b0, w1, b1, w2, b2 = weights
    hidden = _elu(x @ w0.T + b0)
    hidden = _elu(hidden @ w1.T + b1)
    return hidden @ w2.T + b2


def num_network_parameters(num_frequencies: int, num_outputs: int) -> int:
    """``|α|``, the paper's parameter count."""
    return sum(math.prod(shape) for shape in network_shapes(num_frequencies, num_outputs))


def dct_index_to_omega(index: int, num_frames: int) -> float:
    """Angular velocity (cycles over ``t ∈ [0, 1]``) of DCT-II basis ``index`` on ``num_frames`` samples.

    ``cos(π k (2n + 1) / 2N)`` with ``n = t (N − 1)`` has ``k (N − 1) / 2N`` cycles over ``t ∈ [0, 1]``.
    """
    return index * (num_frames - 1) / (2.0 * num_frames)


# -- training (torch, imported lazily so that decoding and the rest of mocapbench never load it) ----------------
# The networks are trained by mocapbench.codecs.neural_fourier.training, many clips side by side.


class _TorchThreads:
    """Run torch on one thread inside the block (deterministic, and polite on a shared machine)."""

    def __enter__(self):
        import torch

        self.torch = torch
        self.previous = torch.get_num_threads()
        torch.set_num_threads(1)
        return self

    def __exit__(self, *exc):
        self.torch.set_num_threads(self.previous)
        return False


# -- the codecs -------------------------------------------------------------------------------------------------


_ITERATIONS_DOC = "optimizer iterations per training round (the naive codec trains once for (K + 1) times this)"
_OPTIMIZER_DOC = ("adam (warm-up and cosine schedule) or lbfgs (full-batch L-BFGS with a backtracking line search; "
                  "about 100 iterations per round suffice)")
_RANK_DOC = ("with solve_output: fit the hidden layers to the fewest leading components of the targets that leave out "
             "at most this fraction of their energy, the output layer solved on all of them at the end (0: all)")
_SOLVE_OUTPUT_DOC = "solve the output layer by least squares at every step instead of stepping it (variable projection)"
_REWEIGHT_PASSES_DOC = ("training passes of iterations_per_round iterations after the first, each with eq. (3)'s frames "
                        "weighted by their L-inf error (0: the paper's loss alone)")
_REWEIGHT_POWER_DOC = "a pass multiplies a frame's loss weight by (its L-inf error / the mean) ** this"


@dataclass(frozen=True)
class _TrainingConfig(CodecConfig):
    """Fields shared by both Fourier-MLP codecs."""

    iterations_per_round: int = param(2000, low=1, high=1_000_000, doc=_ITERATIONS_DOC)
    learning_rate: float = param(3e-3, low=1e-6, high=1.0, doc="Adam: peak learning rate of the first round; L-BFGS: the most a weight moves in the first iteration")
    warmup_fraction: float = param(0.2, low=0.0, high=0.9, doc="Adam: fraction of each round's steps with a linear LR warmup")
    round_lr_decay: float = param(0.8, low=0.1, high=1.0, doc="Adam: peak LR of round r is learning_rate * decay**r (floor 0.1)")
    weight_format: str = param("float16", choices=TENSOR_FORMATS, doc="storage of the weights: float16 or uniform n-bit per tensor")
    weight_bits: int = param(12, low=2, high=16, unit="bits", doc="bits per weight for the uniform format")
    seed: int = param(0, low=0, high=2**31 - 1, doc="seed of the weight initialization")
    stop_tolerance: float = param(1e-4, low=0.0, high=1.0, doc="a network whose loss changed by at most this fraction over the last 200 steps (after the warm-up) stops; 0: never")
    optimizer: str = param("adam", choices=("adam", "lbfgs"), doc=_OPTIMIZER_DOC)
    solve_output: bool = param(False, doc=_SOLVE_OUTPUT_DOC)
    device: str = param("cpu", choices=("cpu", "cuda"), doc="where the networks train: cpu, or cuda when torch sees a GPU (optional)")
    rank_tolerance: float = param(0.0, low=0.0, high=1e-2, doc=_RANK_DOC)


class _FourierMlpCodec(Codec):
    """What both Fourier-MLP codecs share: the stream, the decoder, the quantized evaluation."""

    codes_rotations = True
    # The stream stores the pose parameters' mean and scale as float16 (largest 65504): the root translation in
    # cm must stay well inside it.
    max_coordinate_cm = 5e4
    min_joints = 2  # the pose parameters (axis-angles of non-root joints) need a joint below the root

    # -- helpers used by encode_payload -------------------------------------------------------------------
    def _prepare(self, motion: Motion) -> dict[str, Any]:
        y = pose_matrix(motion)
        w = pose_weights(motion)
        # Rounded to float16 before training: the decoder uses exactly the values the network was trained with.
        mean = y.mean(axis=0).astype(np.float16).astype(np.float64)
        std = y.std(axis=0)
        std = np.where(std < _MIN_STD, 1.0, std).astype(np.float16).astype(np.float64)
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(std))):
            raise ValueError(f"{self.name}: the pose parameters of {motion.name!r} overflow float16 (|y| > 65504).")
        return {"y": y, "w": w, "mean": mean, "std": std, "reference": motion.positions()}

    def _evaluate(self, prep: dict[str, Any], motion: Motion, weights: list[np.ndarray], omegas: list[float]):
        """Quantize the weights as the stream will, decode, and measure the L∞ error (cm)."""
        config = self.config
        stored = [quantize_tensor(wt, config.weight_format, config.weight_bits) for wt in weights]
        omegas32 = np.asarray(omegas, dtype=np.float32).astype(np.float64)
        y_hat = prep["mean"] + prep["std"] * mlp_forward(fourier_features(_time_grid(motion.num_frames), omegas32), stored)
        decoded = motion_from_pose_matrix(y_hat, motion.skeleton, motion.fps)
        frame_errors = np.linalg.norm(decoded.positions() - prep["reference"], axis=-1).max(axis=1)
        self._last_frame_errors = frame_errors  # per frame, the largest joint error (cm), shape (F,)
        return stored, y_hat, float(frame_errors.max())

    def _train_many(self, motions: list[Motion], preps: list[dict[str, Any]]) -> list[tuple]:
        """Train one network per motion, side by side; per motion (Ω, stored weights, L∞ cm, extra stats)."""
        raise NotImplementedError

    def _networks(self, preps: list[dict[str, Any]]) -> list[Network]:
        return [Network((p["y"] - p["mean"]) / p["std"], p["w"] * p["std"], int(self.config.seed)) for p in preps]

    def _serialize(self, motion: Motion, prep: dict[str, Any], omegas: list[float], stored: list[np.ndarray]) -> bytes:
        """The payload for network ``stored`` (already quantized) with frequencies ``omegas``."""
        config = self.config
        writer = ByteWriter()
        writer.write_bytes(pack_skeleton(motion.skeleton))
        # F again: the network is a function of time, so nothing else in the payload pins the frame count, and a
        # header F edited to 1e7 would make the decoder evaluate the network 1e7 times.
        writer.write_varint(motion.num_frames)
        writer.write_varint(len(omegas))
        writer.write_array(np.asarray(omegas, dtype=np.float32), np.float32)
        writer.write_u8(_FORMAT_CODES[config.weight_format])
        writer.write_u8(config.weight_bits if config.weight_format == "uniform" else 0)
        writer.write_array(prep["mean"], np.float16)
        writer.write_array(prep["std"], np.float16)
        for tensor in stored:
            write_tensor(writer, tensor, config.weight_format, config.weight_bits)
        return writer.getvalue()

    encodes_many = True

    def encode_payload(self, motion: Motion) -> bytes:
        [(payload, stats)] = self._encode_payloads([motion], [self._prepare(motion)])
        self.last_encode_stats = stats
        self.last_training_log = self.last_training_logs[0]
        return payload

    def encode_many(self, motions) -> list[tuple[bytes | Exception, dict[str, Any]]]:
        """Encode every motion, their networks trained side by side (one batched computation per group of clips
        of similar length); per motion its stream, or the error that refused it, and its encode stats.

        Each stream is the one :meth:`encode` writes for the motion alone, up to the order of floating-point sums.
        ``train_s`` and ``round_train_s`` are then the batch's times. ``last_training_logs`` holds each motion's
        loss log (see the module docstring).
        """
        results: list[Any] = [None] * len(motions)
        ready = []
        for index, motion in enumerate(motions):
            try:
                if not isinstance(motion, Motion):
                    raise TypeError(f"{self.name}: encode expects a Motion, got {type(motion).__name__}.")
                self.check_motion_fits(motion)
                ready.append((index, motion, self._prepare(motion)))
            except Exception as error:  # noqa: BLE001 - handed back per motion
                results[index] = (error, {})
        if ready:
            encoded = self._encode_payloads([m for _, m, _ in ready], [p for _, _, p in ready])
            for (index, motion, _), (payload, stats) in zip(ready, encoded):
                results[index] = (self.pack_stream(motion, payload), stats)
        return results

    def _encode_payloads(self, motions: list[Motion], preps: list[dict[str, Any]]) -> list[tuple[bytes, dict]]:
        """Train the motions' networks together and write each one's payload and stats."""
        self._start = time.perf_counter()
        trained = self._train_many(motions, preps)
        train_s = time.perf_counter() - self._start
        out = []
        for motion, prep, (omegas, stored, error, extra) in zip(motions, preps, trained):
            payload = self._serialize(motion, prep, omegas, stored)
            m = num_pose_parameters(motion.num_joints)
            num_params = num_network_parameters(len(omegas), m)
            stats = {
                "K": len(omegas),
                "omegas": [round(float(o), 4) for o in omegas],
                "train_s": train_s,
                "num_parameters": num_params,
                "paper_compression_ratio": motion.num_frames * m / num_params,
                "encoder_max_err_cm": error,
                **extra,
            }
            out.append((payload, stats))
        return out

    # -- decoding -----------------------------------------------------------------------------------------
    def _read(self, header: Header, payload: memoryview) -> dict[str, Any]:
        reader = ByteReader(payload)
        skeleton = unpack_skeleton(reader)
        if skeleton.num_joints != header.num_joints:
            raise BitstreamError(
                f"{self.name}: the header says {header.num_joints} joints, the skeleton in the stream has "
                f"{skeleton.num_joints}."
            )
        num_frames = reader.read_varint("frame count")
        if num_frames != header.num_frames:
            raise BitstreamError(f"{self.name}: the header says {header.num_frames} frames, the payload {num_frames}.")
        num_frequencies = reader.read_varint("frequency count")
        if num_frequencies > MAX_FREQUENCIES:
            raise BitstreamError(f"{self.name}: expected at most {MAX_FREQUENCIES} frequencies, found {num_frequencies}.")
        omegas = reader.read_array(num_frequencies, np.float32, "frequencies").astype(np.float64)
        if not np.all(np.isfinite(omegas)):
            raise BitstreamError(f"{self.name}: the frequencies hold non-finite values.")
        fmt, bits = read_tensor_format(reader, self.name, "weight")
        m = num_pose_parameters(skeleton.num_joints)
        mean = reader.read_array(m, np.float16, "column means").astype(np.float64)
        std = reader.read_array(m, np.float16, "column scales").astype(np.float64)
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(std)) and np.all(std > 0)):
            raise BitstreamError(f"{self.name}: the normalization holds non-finite or non-positive values.")
        weights = [
            read_tensor(reader, shape, fmt, bits, f"network tensor {i}")
            for i, shape in enumerate(network_shapes(num_frequencies, m))
        ]
        reader.expect_end()
        return {"skeleton": skeleton, "omegas": omegas, "format": fmt, "bits": bits, "mean": mean, "std": std,
                "weights": weights}

    def decode_payload(self, header: Header, payload: memoryview):
        parts = self._read(header, payload)
        num_frames, omegas, weights, std, mean = (
            header.num_frames, parts["omegas"], parts["weights"], parts["std"], parts["mean"])

        def rows(start: int, stop: int) -> np.ndarray:
            # One block of frames at a time: the hidden layers (2 x 2(2K+1) per frame) and Y-hat never exist for
            # the whole clip; t_i = i / (F - 1) as in _time_grid.
            times = np.arange(start, stop) / (num_frames - 1) if num_frames > 1 else np.zeros(1)
            with np.errstate(over="raise", invalid="raise"):
                try:
                    y_hat = mlp_forward(fourier_features(times, omegas), weights)
                except FloatingPointError as error:
                    raise BitstreamError(f"{self.name}: the network overflows on this stream: {error}") from error
            y_hat *= std
            y_hat += mean
            return y_hat

        motion = motion_from_pose_blocks(num_frames, rows, parts["skeleton"], header.fps)
        return motion.positions(), motion


    def describe_payload(self, header: Header, payload: memoryview) -> dict[str, Any]:
        parts = self._read(header, payload)
        m = num_pose_parameters(header.num_joints)
        num_params = num_network_parameters(len(parts["omegas"]), m)
        return {
            "K": len(parts["omegas"]),
            "omegas_cycles_per_clip": [round(float(o), 4) for o in parts["omegas"]],
            "weight_format": parts["format"] + (f"/{parts['bits']} bits" if parts["format"] == "uniform" else ""),
            "num_parameters": num_params,
            "paper_compression_ratio": header.num_frames * m / num_params,
        }


TORCH_MISSING = "needs PyTorch, which is not installed: pip install 'mocapbench[neural]'"
"""Why the two codecs are unavailable without torch (the one line ``mocapbench codecs`` prints)."""


def _register_if_torch(cls: type[Codec]) -> type[Codec]:
    """``register_codec`` when torch can be imported, else ``register_unavailable`` (torch is the ``[neural]`` extra).

    Only the presence of torch is checked here (``find_spec``, no import), so listing codecs stays fast.
    """
    try:
        missing = importlib.util.find_spec("torch") is None
    except ImportError:  # a finder that refuses torch outright (as test_neural_fourier.py simulates)
        missing = True
    if missing:
        register_unavailable(cls.name, TORCH_MISSING)
        return cls
    return register_codec(cls)


@_register_if_torch
class FourierMlpIntCodec(_FourierMlpCodec):
    """The paper's naïve baseline: Fourier features at the integer angular velocities ``Ω = {1, …, K}`` (§4.1).

    Tojo, Chen, Umetani 2022 (see the module docstring for the network, the stream and every departure).
    """

    name = "fourier-mlp-int"
    smoke_params = {"K": 4, "iterations_per_round": 200, "learning_rate": 0.01}
    smoke_max_error_cm = 25.0

    @dataclass(frozen=True)
    class Config(_TrainingConfig):
        # The default trainer is L-BFGS with the output layer solved (module docstring, "Optimizer"): the same
        # network and loss at a lower loss and L-inf in a twentieth of Adam's CPU time (README, "Timings").
        iterations_per_round: int = param(100, low=1, high=1_000_000, doc=_ITERATIONS_DOC)
        optimizer: str = param("lbfgs", choices=("adam", "lbfgs"), doc=_OPTIMIZER_DOC)
        solve_output: bool = param(True, doc=_SOLVE_OUTPUT_DOC)
        K: int = param(10, low=0, high=MAX_FREQUENCIES, doc="number of frequencies, Ω = {1, ..., K} cycles per clip")
        # One L-inf weighted pass after the training (module docstring, "Frame weights"): the same bytes at a lower
        # L-inf for one more pass of iterations_per_round (README, "Timings").
        reweight_passes: int = param(1, low=0, high=16, doc=_REWEIGHT_PASSES_DOC)
        reweight_power: float = param(2.0, low=0.0, high=8.0, doc=_REWEIGHT_POWER_DOC)

    def _train_many(self, motions: list[Motion], preps: list[dict[str, Any]]):
        """Train every network once; then ``reweight_passes`` L-inf weighted passes, each clip keeping the network
        of lowest L∞ among its passes (K is fixed here, so the L∞ of the stream is all a pass can change)."""
        config = self.config
        settings = TrainingSettings.from_config(config)
        omegas = [float(k) for k in range(1, config.K + 1)]
        all_omegas = [omegas] * len(motions)
        networks = self._networks(preps)
        best = [None] * len(motions)  # per clip (L∞ cm, stored weights, pass index) of its best pass so far
        with _TorchThreads():
            train_round(networks, all_omegas, config.iterations_per_round * (config.K + 1), settings)
            for reweighting in range(config.reweight_passes + 1):
                if reweighting:
                    train_round(networks, all_omegas, config.iterations_per_round, settings, same_round=True)
                for i, (motion, prep, network) in enumerate(zip(motions, preps, networks)):
                    stored, _, error = self._evaluate(prep, motion, network.weights64(), omegas)
                    if best[i] is None or error < best[i][0]:
                        best[i] = (error, stored, reweighting)
                    if reweighting < config.reweight_passes:
                        network.reweight_frames(self._last_frame_errors, config.reweight_power)
        self.last_training_logs = [network.loss_history for network in networks]
        return [(omegas, stored, error, {"kept_pass": kept}) for error, stored, kept in best]


@_register_if_torch
class FourierMlpDctCodec(_FourierMlpCodec):
    """Frequency-adaptive Fourier features (Algorithm 1, §3.2): add the residual's dominant DCT frequency until
    the L∞ joint-position error is under the threshold.

    Tojo, Chen, Umetani 2022 (see the module docstring for the network, the stream and every departure).
    The threshold is tested on the decoded (quantized) network through FK, so the stream meets it when
    ``threshold_met`` is true in ``last_encode_stats``; when ``K_max`` frequencies are not enough, the last
    network is written anyway and ``threshold_met`` is false.
    """

    name = "fourier-mlp-dct"
    smoke_params = {"K_max": 4, "iterations_per_round": 200, "learning_rate": 0.01, "threshold": 1.0, "threshold_unit": "cm"}
    smoke_max_error_cm = 25.0

    @dataclass(frozen=True)
    class Config(_TrainingConfig):
        threshold: float = param(2.0, low=1e-6, high=1e6, doc="stopping L-inf joint-position error (unit: threshold_unit)")
        threshold_unit: str = param("percent_height", choices=("percent_height", "cm"), doc="percent of the rest height, or cm")
        K_max: int = param(10, low=0, high=MAX_FREQUENCIES, doc="largest number of frequencies tried")
        # The default trainer: per round 50 L-BFGS iterations with the output layer solved, then 50 more with the
        # frames weighted by their L-inf error (module docstring, "Optimizer" and "Frame weights"; README).
        iterations_per_round: int = param(50, low=1, high=1_000_000, doc=_ITERATIONS_DOC)
        optimizer: str = param("lbfgs", choices=("adam", "lbfgs"), doc=_OPTIMIZER_DOC)
        solve_output: bool = param(True, doc=_SOLVE_OUTPUT_DOC)
        reweight_passes: int = param(1, low=0, high=16, doc=_REWEIGHT_PASSES_DOC)
        reweight_power: float = param(2.0, low=0.0, high=8.0, doc=_REWEIGHT_POWER_DOC)

    def threshold_cm(self, motion: Motion) -> float:
        """The stopping threshold in cm for ``motion`` (``% × Skeleton.rest_height()`` or cm as configured)."""
        if self.config.threshold_unit == "cm":
            return self.config.threshold
        return self.config.threshold / 100.0 * motion.skeleton.rest_height()

    def _train_many(self, motions: list[Motion], preps: list[dict[str, Any]]):
        """Algorithm 1 for every motion, in lockstep: round r trains every clip still searching (all with r
        frequencies, so of one width) side by side; a clip leaves when it meets its threshold or K_max."""
        config = self.config
        settings = TrainingSettings.from_config(config)
        networks = self._networks(preps)
        state = [{"limit": self.threshold_cm(motion), "omegas": [], "used": set(), "errors": [], "kept": [],
                  "bytes": [], "seconds": [], "stored": None} for motion in motions]
        searching = list(range(len(motions)))
        with _TorchThreads():
            while searching:
                # Algorithm 1, lines 3-4 (line 11, the warm start, in train_round)
                group, group_omegas = [networks[i] for i in searching], [state[i]["omegas"] for i in searching]
                for network in group:
                    network.frame_weights = None  # every round starts from eq. (3) itself
                train_round(group, group_omegas, config.iterations_per_round, settings)
                plain_fit = {}  # the fit of eq. (3) itself, before the L-inf passes: its residual picks the frequency
                best = {}  # per clip, (L-inf cm, stored weights, float32 weights, pass) of the round's best pass so far
                for reweighting in range(config.reweight_passes + 1):
                    if reweighting:
                        train_round(group, group_omegas, config.iterations_per_round, settings, same_round=True)
                    for i in searching:
                        network, omegas = networks[i], state[i]["omegas"]
                        stored, fit, error = self._evaluate(preps[i], motions[i], network.weights64(), omegas)
                        if reweighting == 0:
                            plain_fit[i] = fit
                        if i not in best or error < best[i][0]:
                            best[i] = (error, stored, [w.copy() for w in network.weights], reweighting)
                        if reweighting < config.reweight_passes:
                            network.reweight_frames(self._last_frame_errors, config.reweight_power)
                still = []
                for i in searching:
                    motion, prep, clip = motions[i], preps[i], state[i]
                    error, stored, weights, kept = best[i]
                    networks[i].weights = weights  # the round's best pass: the stream, and the next round's start
                    clip["stored"] = stored
                    clip["errors"].append(error)
                    clip["kept"].append(kept)
                    # What the stream would be if Algorithm 1 stopped here (a larger threshold stops exactly here:
                    # training does not depend on the threshold), for rate-distortion curves from a single run.
                    clip["bytes"].append(len(self._serialize(motion, prep, clip["omegas"], stored)))
                    clip["seconds"].append(time.perf_counter() - self._start)
                    if error <= clip["limit"] or len(clip["omegas"]) >= config.K_max:  # line 5
                        continue
                    index = _dominant_dct_index(prep["y"] - plain_fit[i], prep["w"], clip["used"])  # 7-9
                    if index is None:
                        continue
                    clip["used"].add(index)
                    clip["omegas"].append(dct_index_to_omega(index, motion.num_frames))  # line 10
                    still.append(i)
                searching = still
        self.last_training_logs = [network.loss_history for network in networks]
        out = []
        for clip in state:
            extra = {
                "threshold_cm": clip["limit"],
                "threshold_met": bool(clip["errors"][-1] <= clip["limit"]),
                "round_max_err_cm": [round(e, 4) for e in clip["errors"]],
                "round_payload_bytes": clip["bytes"],
                "round_kept_pass": clip["kept"],
                "round_train_s": [round(t, 3) for t in clip["seconds"]],
            }
            out.append((clip["omegas"], clip["stored"], clip["errors"][-1], extra))
        return out


def _dominant_dct_index(residual: np.ndarray, weights: np.ndarray, used: set[int]) -> int | None:
    """DCT index of the dominant frequency of the weighted residual's first principal component (§3.2).

    Parameters
    ----------
    residual : ndarray, shape (N, m)
        ``Y − F(X)``.
    weights : ndarray, shape (m,)
        ``w`` of eq. (3).
    used : set of int
        DCT indices already in Ω (never added twice).

    Returns
    -------
    int or None
        The index ``k ≥ 1`` with the largest ``|DCT|`` not in ``used``; None if there is none left.
    """
    weighted = residual * weights
    weighted = weighted - weighted.mean(axis=0)
    if weighted.shape[0] < 2:
        return None
    # First principal direction p from the m x m covariance (cheaper than an SVD of the N x m matrix).
    _, vectors = np.linalg.eigh(weighted.T @ weighted)
    history = weighted @ vectors[:, -1]  # time history of the first principal component
    spectrum = np.abs(scipy.fft.dct(history, type=2, norm="ortho"))
    spectrum[0] = -1.0  # DC: the biases fit a constant
    for index in sorted(used):
        spectrum[index] = -1.0
    best = int(np.argmax(spectrum))
    return None if spectrum[best] < 0 else best
