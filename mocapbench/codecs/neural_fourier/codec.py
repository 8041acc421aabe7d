"""Neural motion compression with a Fourier-feature MLP: ``fourier-mlp-int`` and ``fourier-mlp-dct``.

Paper: K. Tojo, Y. Chen, N. Umetani, "Neural Motion Compression with Frequency-adaptive Fourier Feature
Network" (Eurographics 2022 short paper; ``../shared/papers/neural-fourier-motion-compression.txt``).

One clip is one network. The pose matrix ``Y`` (F × m, :mod:`.pose_params`, §3) is fitted as a function of the
normalized time ``t ∈ [0, 1]``::

    t ──► x(t; Ω) = [t, sin 2πω₁t, cos 2πω₁t, …, sin 2πω_Kt, cos 2πω_Kt]        (eq. 1)
      ──► W₂ ELU(W₁ ELU(W₀ x + b₀) + b₁) + b₂,   hidden size h = 2 (2K + 1)       (eq. 2)
      ──► ŷ(t) ──► quaternion normalized, axis-angles ──► forward kinematics ──► Motion

trained with full-batch Adam on the weighted L2 loss of eq. (3), ``Σ ‖(y_i − F(x_i)) ∘ w‖²``.

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
``round_max_err_cm``, ``round_payload_bytes`` and ``round_train_s`` (cumulative). ``last_training_log`` holds
the loss before every Adam step and after the last one, one array per round.

Where this departs from the paper, and why
------------------------------------------
* **Angular-velocity convention.** Eq. (1) writes ``sin ω t``, but §4.1 says "angular velocity takes value two
  … when its feature cycles twice throughout the sequence", so a feature is ``sin(2π ω t)`` here with ω in
  cycles per clip. A DCT-II index k of an F-sample signal is ``cos(π k (2n + 1) / 2F)`` = ``k (F − 1) / 2F``
  cycles over ``t ∈ [0, 1]``, which is the ω appended (the phase is irrelevant: both sin and cos are used).
* **Normalization.** ``Y`` is standardized per column (mean and standard deviation, rounded to float16 before
  training so the decoder uses exactly the training values) and the loss weights become ``w · std`` so that the
  loss is still eq. (3) in the original units (``mean`` over entries instead of the sum: a constant factor).
  This only reparameterizes the output layer; it makes Adam converge on root translations of hundreds of cm.
  The 2m normalization numbers are in the bitstream but not in the paper's parameter count (which counts ``α``).
* **Training schedule** (not given in the paper): per round, ``iterations_per_round`` full-batch Adam steps,
  learning rate warmed up linearly over the first ``warmup_fraction`` of the steps, then cosine-decayed to 5 %;
  the peak rate of round r is ``learning_rate · round_lr_decay**r`` (floor 10 %). A fresh Adam state after a
  warm start, at full rate, kicks the copied near-optimal weights back up (measured: loss 0.006 → 17 on a
  900-frame clip); the warmup and the per-round decay keep the loss from jumping back. The naive baseline is
  trained once with ``iterations_per_round · (K + 1)`` steps, the budget the adaptive codec spends to reach K.
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
    write_tensor,
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
_LR_FLOOR = 0.1  # the per-round peak learning rate never falls below this fraction of `learning_rate`
_COSINE_END = 0.05  # the cosine decay ends at this fraction of the round's peak rate


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


def network_shapes(num_frequencies: int, num_outputs: int) -> list[tuple[int, ...]]:
    """Shapes of ``α`` for K frequencies and m outputs (h = 2 (2K + 1), §3.1)."""
    inputs = 2 * num_frequencies + 1
    hidden = 2 * inputs
    return [(hidden, inputs), (hidden,), (hidden, hidden), (hidden,), (num_outputs, hidden), (num_outputs,)]


def num_network_parameters(num_frequencies: int, num_outputs: int) -> int:
    """``|α|``, the paper's parameter count."""
    return sum(math.prod(shape) for shape in network_shapes(num_frequencies, num_outputs))


def dct_index_to_omega(index: int, num_frames: int) -> float:
    """Angular velocity (cycles over ``t ∈ [0, 1]``) of DCT-II basis ``index`` on ``num_frames`` samples.

    ``cos(π k (2n + 1) / 2N)`` with ``n = t (N − 1)`` has ``k (N − 1) / 2N`` cycles over ``t ∈ [0, 1]``.
    """
    return index * (num_frames - 1) / (2.0 * num_frames)


def _time_grid(num_frames: int) -> np.ndarray:
    """``t_i = i / (F − 1)``; a single frame sits at t = 0."""
    if num_frames == 1:
        return np.zeros(1)
    return np.arange(num_frames) / (num_frames - 1)


# -- training (torch, imported lazily so that decoding and the rest of mocapbench never load it) ----------------


class _Trainer:
    """Full-batch Adam on eq. (3) for one clip; grows the network with warm start (Algorithm 1, line 11).

    Parameters
    ----------
    targets : ndarray, shape (N, m)
        Normalized pose matrix ``(Y − mean) / std``.
    loss_weights : ndarray, shape (m,)
        ``w · std``: eq. (3)'s weights in the normalized coordinates.
    config : the codec's config (iterations, learning rate, warmup, decay, seed).
    """

    def __init__(self, targets: np.ndarray, loss_weights: np.ndarray, config: Any) -> None:
        import torch

        self.torch = torch
        self.dtype = torch.float32
        self.config = config
        self.generator = torch.Generator().manual_seed(int(config.seed))
        self.targets = torch.tensor(targets, dtype=self.dtype)
        self.loss_weights = torch.tensor(loss_weights, dtype=self.dtype)
        self.t = torch.tensor(_time_grid(targets.shape[0]), dtype=self.dtype)
        self.params: list[Any] | None = None
        self.rounds = 0
        # Per round, the loss before each step and after the last one (iterations + 1 values).
        self.loss_history: list[np.ndarray] = []

    def _uniform(self, shape: tuple[int, ...], fan_in: int):
        bound = 1.0 / math.sqrt(fan_in)
        # Private generator: the global torch RNG is left alone.
        return (self.torch.rand(shape, generator=self.generator, dtype=self.dtype) * 2.0 - 1.0) * bound

    def _grow(self, num_frequencies: int, num_outputs: int) -> None:
        """Build the network for K frequencies; copy the previous (smaller) network into it, function-preserving."""
        shapes = network_shapes(num_frequencies, num_outputs)
        hidden, inputs = shapes[0]
        fresh = [
            self._uniform(shapes[0], inputs),
            self._uniform(shapes[1], inputs),
            self._uniform(shapes[2], hidden),
            self._uniform(shapes[3], hidden),
            self._uniform(shapes[4], hidden),
            self._uniform(shapes[5], hidden),
        ]
        if self.params is not None:
            w0, b0, w1, b1, w2, b2 = (p.detach() for p in self.params)
            old_hidden, old_inputs = w0.shape
            fresh[0][:old_hidden, :old_inputs] = w0
            fresh[0][:old_hidden, old_inputs:] = 0.0  # old units ignore the new features
            fresh[1][:old_hidden] = b0
            fresh[2][:old_hidden, :old_hidden] = w1
            fresh[2][:old_hidden, old_hidden:] = 0.0  # old units ignore the new units
            fresh[3][:old_hidden] = b1
            fresh[4][:, :old_hidden] = w2
            fresh[4][:, old_hidden:] = 0.0  # new units do not reach the output yet
            fresh[5][:] = b2
        self.params = [p.requires_grad_(True) for p in fresh]

    def features(self, omegas: list[float]):
        torch = self.torch
        t = self.t[:, None]
        columns = [t]
        for omega in omegas:
            phase = (2.0 * math.pi * float(omega)) * t
            columns += [torch.sin(phase), torch.cos(phase)]
        return torch.cat(columns, dim=1)

    def train_round(self, omegas: list[float], iterations: int) -> None:
        """Grow to ``len(omegas)`` frequencies (warm start) and run one round of Adam."""
        torch = self.torch
        self._grow(len(omegas), self.targets.shape[1])
        features = self.features(omegas)
        config = self.config
        peak = config.learning_rate * max(config.round_lr_decay**self.rounds, _LR_FLOOR)
        warmup = max(1, int(round(config.warmup_fraction * iterations))) if config.warmup_fraction > 0 else 0
        optimizer = torch.optim.Adam(self.params, lr=peak, fused=True)
        functional = torch.nn.functional
        elu, linear = functional.elu, functional.linear
        w0, b0, w1, b1, w2, b2 = self.params
        weighted_targets = self.targets * self.loss_weights
        losses = np.empty(iterations + 1)
        for step in range(iterations):
            if step < warmup:
                rate = peak * (step + 1) / warmup
            else:
                progress = (step - warmup) / max(1, iterations - warmup)
                rate = peak * (_COSINE_END + (1 - _COSINE_END) * 0.5 * (1.0 + math.cos(math.pi * progress)))
            for group in optimizer.param_groups:
                group["lr"] = rate
            optimizer.zero_grad(set_to_none=True)
            output = linear(elu(linear(elu(linear(features, w0, b0)), w1, b1)), w2, b2)  # eq. (2)
            # eq. (3) up to a constant factor: mean over entries of ((y - F(x)) o w)^2 (fewer torch ops this way).
            loss = functional.mse_loss(output * self.loss_weights, weighted_targets)
            loss.backward()
            optimizer.step()
            losses[step] = float(loss.detach())
        with torch.no_grad():  # the loss of the weights this round ends with (the last step's is one step behind)
            output = linear(elu(linear(elu(linear(features, w0, b0)), w1, b1)), w2, b2)
            losses[iterations] = float(functional.mse_loss(output * self.loss_weights, weighted_targets))
        self.rounds += 1
        self.loss_history.append(losses)

    def weights(self) -> list[np.ndarray]:
        """The current network ``[W0, b0, W1, b1, W2, b2]`` as float64 numpy arrays."""
        return [p.detach().numpy().astype(np.float64) for p in self.params]


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


_ITERATIONS_DOC = "full-batch Adam steps per training round (the naive codec trains once for (K + 1) times this)"


@dataclass(frozen=True)
class _TrainingConfig(CodecConfig):
    """Fields shared by both Fourier-MLP codecs."""

    iterations_per_round: int = param(2000, low=1, high=1_000_000, doc=_ITERATIONS_DOC)
    learning_rate: float = param(3e-3, low=1e-6, high=1.0, doc="peak Adam learning rate of the first round")
    warmup_fraction: float = param(0.2, low=0.0, high=0.9, doc="fraction of each round's steps with a linear LR warmup")
    round_lr_decay: float = param(0.8, low=0.1, high=1.0, doc="peak LR of round r is learning_rate * decay**r (floor 0.1)")
    weight_format: str = param("float16", choices=TENSOR_FORMATS, doc="storage of the weights: float16 or uniform n-bit per tensor")
    weight_bits: int = param(12, low=2, high=16, unit="bits", doc="bits per weight for the uniform format")
    seed: int = param(0, low=0, high=2**31 - 1, doc="seed of the weight initialization")


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
        error = float(np.linalg.norm(decoded.positions() - prep["reference"], axis=-1).max())
        return stored, y_hat, error

    def _train(self, motion: Motion, prep: dict[str, Any]) -> tuple[list[float], list[np.ndarray], float, dict[str, Any]]:
        """Train on ``prep`` (from :meth:`_prepare`); return (Ω, stored weights, L∞ cm, extra stats)."""
        raise NotImplementedError

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

    def encode_payload(self, motion: Motion) -> bytes:
        start = time.perf_counter()
        self._start = start
        prep = self._prepare(motion)
        omegas, stored, error, extra = self._train(motion, prep)
        payload = self._serialize(motion, prep, omegas, stored)
        train_s = time.perf_counter() - start
        m = num_pose_parameters(motion.num_joints)
        num_params = num_network_parameters(len(omegas), m)
        self.last_encode_stats = {
            "K": len(omegas),
            "omegas": [round(float(o), 4) for o in omegas],
            "train_s": train_s,
            "num_parameters": num_params,
            "paper_compression_ratio": motion.num_frames * m / num_params,
            "encoder_max_err_cm": error,
            **extra,
        }
        return payload

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
        code = reader.read_u8("weight format")
        if code >= len(TENSOR_FORMATS):
            raise BitstreamError(f"{self.name}: weight format code must be < {len(TENSOR_FORMATS)}, found {code}.")
        fmt = TENSOR_FORMATS[code]
        bits = reader.read_u8("weight bits")
        if (fmt == "uniform") != (2 <= bits <= 16) or (fmt == "float16" and bits != 0):
            raise BitstreamError(f"{self.name}: weight bits {bits} do not fit the {fmt} format.")
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
        K: int = param(10, low=0, high=MAX_FREQUENCIES, doc="number of frequencies, Ω = {1, ..., K} cycles per clip")

    def _train(self, motion: Motion, prep: dict[str, Any]):
        config = self.config
        omegas = [float(k) for k in range(1, config.K + 1)]
        with _TorchThreads():
            trainer = _Trainer((prep["y"] - prep["mean"]) / prep["std"], prep["w"] * prep["std"], config)
            trainer.train_round(omegas, config.iterations_per_round * (config.K + 1))
        self.last_training_log = trainer.loss_history
        stored, _, error = self._evaluate(prep, motion, trainer.weights(), omegas)
        return omegas, stored, error, {}


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

    def threshold_cm(self, motion: Motion) -> float:
        """The stopping threshold in cm for ``motion`` (``% × Skeleton.rest_height()`` or cm as configured)."""
        if self.config.threshold_unit == "cm":
            return self.config.threshold
        return self.config.threshold / 100.0 * motion.skeleton.rest_height()

    def _train(self, motion: Motion, prep: dict[str, Any]):
        config = self.config
        limit = self.threshold_cm(motion)
        num_frames = motion.num_frames
        omegas: list[float] = []
        used: set[int] = set()
        errors: list[float] = []
        round_bytes: list[int] = []
        round_seconds: list[float] = []
        with _TorchThreads():
            trainer = _Trainer((prep["y"] - prep["mean"]) / prep["std"], prep["w"] * prep["std"], config)
            while True:
                trainer.train_round(omegas, config.iterations_per_round)  # Algorithm 1, lines 3-4
                stored, y_hat, error = self._evaluate(prep, motion, trainer.weights(), omegas)
                errors.append(error)
                # What the stream would be if Algorithm 1 stopped here (a larger threshold stops exactly here:
                # training does not depend on the threshold), for rate-distortion curves from a single run.
                round_bytes.append(len(self._serialize(motion, prep, omegas, stored)))
                round_seconds.append(time.perf_counter() - self._start)
                if error <= limit or len(omegas) >= config.K_max:  # line 5
                    break
                index = _dominant_dct_index(prep["y"] - y_hat, prep["w"], used)  # lines 7-9
                if index is None:
                    break
                used.add(index)
                omegas.append(dct_index_to_omega(index, num_frames))  # line 10 (line 11 in train_round)
        self.last_training_log = trainer.loss_history
        extra = {
            "threshold_cm": limit,
            "threshold_met": bool(errors[-1] <= limit),
            "round_max_err_cm": [round(e, 4) for e in errors],
            "round_payload_bytes": round_bytes,
            "round_train_s": [round(t, 3) for t in round_seconds],
        }
        return omegas, stored, error, extra


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
