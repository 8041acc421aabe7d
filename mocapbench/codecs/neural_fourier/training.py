"""Training of the neural Fourier codecs' networks, many at once (torch, imported only by the encoders).

Tojo, Chen, Umetani 2022 train one small network per clip: ``h = 2 (2K + 1)`` hidden units, a few thousand
weights. One such network costs little arithmetic per Adam step and a fixed overhead of dozens of tensor
operations, and it takes tens of thousands of steps; trained one at a time through autograd and ``torch.optim``,
the overhead is most of the time. Here every network of a call is trained side by side:

* **Stacked weights.** The B networks of a group live in one flat parameter tensor ``P`` (B × |α|), viewed as
  ``W0 (B, h, 2K+1)``, ``b0 (B, h)``, ``W1 (B, h, h)``, ``b1``, ``W2 (B, m, h)``, ``b2 (B, m)``; the forward pass of
  eq. (2) is three batched matrix products (``baddbmm``) over the group's frames.
* **Gradients by hand.** The loss of eq. (3) and its gradient through the two ELU layers are written out (five
  more batched products), so no autograd graph is built. ELU is computed as ``max(z, e − 1)`` with
  ``e = exp(min(z, 0))``, and ``e`` is also ELU's derivative (1 where ``z > 0``), so one exponential serves both.
* **Adam by hand**, on the flat tensor: the update of ``torch.optim.Adam`` (β = 0.9, 0.999, ε = 1e-8, bias
  corrections), each network with its own moments. All networks of a group take the same step number and rate, so
  each one follows exactly the schedule it would follow alone.
* **Padding that changes nothing.** Clips of different lengths are padded with frames whose loss weight is 0, and
  skeletons with fewer pose parameters with outputs whose loss weight is 0: the padded rows add 0 to every
  gradient. Padding costs arithmetic, so the networks are cut into groups of similar length
  (:func:`frame_groups`) and the groups are trained one after another.
* **Stopping.** A network whose loss has stopped falling (relative decrease over the last ``stop_window`` steps at
  most ``stop_tolerance``, tested after the warm-up) is frozen there; the round ends when all are. The benchmark's
  schedules fall the whole way down (see the README), so this guards against wasted steps on easy clips and
  changes nothing on the others.

Each network draws its initial weights from its own generator seeded with the codec's seed, in the order one
network trained alone draws them, so a network's result does not depend on which others share its batch, up to the
order of floating-point sums (the batched products add in another order than one product per network).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

__all__ = ["Network", "TrainingSettings", "train_round", "frame_groups", "resolve_device", "network_shapes", "time_grid"]

_LR_FLOOR = 0.1  # the per-round peak learning rate never falls below this fraction of `learning_rate`
_COSINE_END = 0.05  # the cosine decay ends at this fraction of the round's peak rate
_ADAM_BETAS = (0.9, 0.999)
_ADAM_EPS = 1e-8
# A group of networks costs about (networks × longest clip) frames of arithmetic per step plus a fixed overhead of
# tensor operations, worth this many frames on one CPU core; frame_groups balances the two.
_STEP_OVERHEAD_FRAMES = 200
# The most padded frames in one group (bounds the group's activations: about 2.5 kB per frame at K = 16).
_MAX_GROUP_FRAMES = 65_536


def network_shapes(num_frequencies: int, num_outputs: int) -> list[tuple[int, ...]]:
    """Shapes of ``α`` for K frequencies and m outputs (h = 2 (2K + 1), §3.1)."""
    inputs = 2 * num_frequencies + 1
    hidden = 2 * inputs
    return [(hidden, inputs), (hidden,), (hidden, hidden), (hidden,), (num_outputs, hidden), (num_outputs,)]


def time_grid(num_frames: int) -> np.ndarray:
    """``t_i = i / (F − 1)``; a single frame sits at t = 0."""
    if num_frames == 1:
        return np.zeros(1)
    return np.arange(num_frames) / (num_frames - 1)


@dataclass(frozen=True)
class TrainingSettings:
    """What training needs from the codec's config (see ``_TrainingConfig`` in the codec module)."""

    learning_rate: float
    warmup_fraction: float
    round_lr_decay: float
    seed: int
    stop_tolerance: float = 0.0
    stop_window: int = 200
    device: str = "cpu"

    @classmethod
    def from_config(cls, config: Any) -> "TrainingSettings":
        return cls(
            learning_rate=float(config.learning_rate),
            warmup_fraction=float(config.warmup_fraction),
            round_lr_decay=float(config.round_lr_decay),
            seed=int(config.seed),
            stop_tolerance=float(getattr(config, "stop_tolerance", 0.0)),
            stop_window=int(getattr(config, "stop_window", 200)),
            device=str(getattr(config, "device", "cpu")),
        )


def resolve_device(name: str):
    """The torch device ``name`` (``cpu`` or ``cuda``); a ValueError in one line when CUDA is asked for and absent."""
    import torch

    if name == "cpu":
        return torch.device("cpu")
    if name == "cuda":
        if not torch.cuda.is_available():
            raise ValueError("device=cuda was asked for, but torch sees no CUDA device here; use device=cpu.")
        return torch.device("cuda")
    raise ValueError(f"device must be 'cpu' or 'cuda', got {name!r}.")


@dataclass
class Network:
    """One clip's network between training rounds (Algorithm 1 grows it round by round).

    Parameters
    ----------
    targets : ndarray, shape (N, m)
        Normalized pose matrix ``(Y − mean) / std``.
    loss_weights : ndarray, shape (m,)
        ``w · std``: eq. (3)'s weights in the normalized coordinates.
    seed : int
        Seed of this network's own generator (initial weights and the units added at each growth).
    """

    targets: np.ndarray
    loss_weights: np.ndarray
    seed: int
    weights: list[np.ndarray] | None = None  # [W0, b0, W1, b1, W2, b2], float32
    rounds: int = 0
    # Per round, the loss before each step and after the last one (steps + 1 values).
    loss_history: list[np.ndarray] = field(default_factory=list)
    _generator: Any = None

    @property
    def num_frames(self) -> int:
        return int(self.targets.shape[0])

    @property
    def num_outputs(self) -> int:
        return int(self.targets.shape[1])

    def _uniform(self, shape: tuple[int, ...], fan_in: int) -> np.ndarray:
        import torch

        if self._generator is None:
            # Private generator: the global torch RNG is left alone.
            self._generator = torch.Generator().manual_seed(int(self.seed))
        bound = 1.0 / math.sqrt(fan_in)
        return ((torch.rand(shape, generator=self._generator, dtype=torch.float32) * 2.0 - 1.0) * bound).numpy()

    def grow(self, num_frequencies: int) -> None:
        """Build the network for K frequencies; copy the previous (smaller) one in, function-preserving.

        Algorithm 1, line 11 (warm start): new input columns and the new hidden units' outgoing weights are zero,
        the new units' incoming weights are drawn like a fresh layer, so the grown network computes exactly the
        old function at its first step.
        """

        shapes = network_shapes(num_frequencies, self.num_outputs)
        hidden, inputs = shapes[0]
        fresh = [
            self._uniform(shapes[0], inputs),
            self._uniform(shapes[1], inputs),
            self._uniform(shapes[2], hidden),
            self._uniform(shapes[3], hidden),
            self._uniform(shapes[4], hidden),
            self._uniform(shapes[5], hidden),
        ]
        if self.weights is not None:
            w0, b0, w1, b1, w2, b2 = self.weights
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
        self.weights = fresh

    def weights64(self) -> list[np.ndarray]:
        """The current network ``[W0, b0, W1, b1, W2, b2]`` as float64 arrays."""
        return [w.astype(np.float64) for w in self.weights]


def learning_rate(step: int, iterations: int, warmup: int, peak: float) -> float:
    """The rate of ``step``: linear warm-up over ``warmup`` steps, then cosine decay to 5 % of ``peak``."""
    if step < warmup:
        return peak * (step + 1) / warmup
    progress = (step - warmup) / max(1, iterations - warmup)
    return peak * (_COSINE_END + (1 - _COSINE_END) * 0.5 * (1.0 + math.cos(math.pi * progress)))


def frame_groups(frames: Sequence[int], overhead_frames: int = _STEP_OVERHEAD_FRAMES,
                 max_group_frames: int = _MAX_GROUP_FRAMES) -> list[list[int]]:
    """Cut networks into groups trained together: least padded frames plus per-group overhead.

    Parameters
    ----------
    frames : sequence of int
        Frames of each network's clip.
    overhead_frames : int
        The fixed cost of one more group, in frames of arithmetic.
    max_group_frames : int
        A group's padded frames (networks × its longest clip) stay at most this (a longer clip is alone).

    Returns
    -------
    list of list of int
        Indices into ``frames``; every index once; a group's clips are consecutive in length order.
    """
    order = sorted(range(len(frames)), key=lambda i: -frames[i])
    n = len(order)
    best = [0.0] + [math.inf] * n  # best[i]: cost of the first i networks (longest first)
    cut = [0] * (n + 1)
    for end in range(1, n + 1):
        for start in range(end - 1, -1, -1):
            padded = (end - start) * frames[order[start]]  # the longest clip of the group is its first
            if padded > max_group_frames and end - start > 1:
                break
            cost = best[start] + padded + overhead_frames
            if cost < best[end]:
                best[end], cut[end] = cost, start
    groups, end = [], n
    while end > 0:
        groups.append(order[cut[end]:end])
        end = cut[end]
    return groups[::-1]


def train_round(networks: Sequence[Network], omegas: Sequence[Sequence[float]], iterations: int,
                settings: TrainingSettings) -> None:
    """Grow every network to ``len(omegas[i])`` frequencies (warm start) and run one round of Adam on each.

    Parameters
    ----------
    networks : sequence of Network
    omegas : sequence of sequence of float
        Each network's Ω (cycles per clip); networks with the same number of frequencies and rounds so far are
        trained together.
    iterations : int
        Adam steps of the round.
    settings : TrainingSettings
    """
    for network, frequencies in zip(networks, omegas):
        network.grow(len(frequencies))
    by_shape: dict[tuple[int, int], list[int]] = {}
    for index, (network, frequencies) in enumerate(zip(networks, omegas)):
        by_shape.setdefault((len(frequencies), network.rounds), []).append(index)
    for members in by_shape.values():
        for group in frame_groups([networks[i].num_frames for i in members]):
            chosen = [members[i] for i in group]
            _train_group([networks[i] for i in chosen], [omegas[i] for i in chosen], iterations, settings)


def _features(torch, t, omegas: Sequence[float]):
    """Eq. (1) for one network: ``[t, sin 2πω₁t, cos 2πω₁t, …]``, shape (N, 2K + 1)."""
    t = t[:, None]
    columns = [t]
    for omega in omegas:
        phase = (2.0 * math.pi * float(omega)) * t
        columns += [torch.sin(phase), torch.cos(phase)]
    return torch.cat(columns, dim=1)


def _train_group(networks: Sequence[Network], omegas: Sequence[Sequence[float]], iterations: int,
                 settings: TrainingSettings) -> None:
    """One round for networks of the same width: lockstep full-batch Adam on stacked weights."""
    import torch


    device = resolve_device(settings.device)
    dtype = torch.float32
    count = len(networks)
    frames = max(n.num_frames for n in networks)
    outputs = max(n.num_outputs for n in networks)
    shapes = [w.shape for w in networks[0].weights]
    # Networks with fewer outputs than the widest one: pad W2 and b2 with zero rows (zero loss weight keeps them 0).
    shapes[4], shapes[5] = (outputs, shapes[4][1]), (outputs,)
    sizes = [math.prod(s) for s in shapes]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    params = torch.zeros(count, int(offsets[-1]), dtype=dtype)
    features = torch.zeros(count, frames, shapes[0][1], dtype=dtype)
    targets = torch.zeros(count, frames, outputs, dtype=dtype)
    # eq. (3) as the mean over the clip's entries (the single-network codec's loss), per network: with
    # s = w · std · sqrt(2 / (N m)) per output (0 on padded outputs), loss = |(F(x) − y) ∘ s|² / 2 and
    # d loss / d output = (F(x) − y) ∘ s². The scaled residual (F(x) − y) ∘ s is one batched product:
    # [a2, 1] [s ∘ W2, s ∘ b2]ᵀ − y ∘ s, and padded frames give 0 in it (their [a2, 1] row is set to 0).
    scale = torch.zeros(count, 1, outputs, dtype=dtype)
    row_mask = torch.zeros(count, frames, 1, dtype=dtype)
    for b, (network, frequencies) in enumerate(zip(networks, omegas)):
        n, m = network.targets.shape
        packed = []
        for i, w in enumerate(network.weights):
            padded = np.zeros(shapes[i], dtype=np.float32)
            padded[tuple(slice(0, s) for s in w.shape)] = w
            packed.append(padded.ravel())
        params[b] = torch.from_numpy(np.concatenate(packed))
        t = torch.tensor(time_grid(n), dtype=dtype)
        features[b, :n] = _features(torch, t, frequencies)
        scale[b, 0, :m] = torch.from_numpy(np.asarray(network.loss_weights, dtype=np.float32)) * math.sqrt(2.0 / (n * m))
        targets[b, :n, :m] = torch.from_numpy(np.asarray(network.targets, dtype=np.float32)) * scale[b, 0, :m]
        row_mask[b, :n] = 1.0
    padded_rows = bool((row_mask == 0).any())
    params, features, targets, scale, row_mask = (x.to(device) for x in (params, features, targets, scale, row_mask))
    hidden = shapes[2][0]
    # [a2, 1] of every frame (0 on padded frames), the left factor of the output layer's product.
    a2_ones = row_mask.expand(count, frames, 1).repeat(1, 1, hidden + 1)
    a2 = a2_ones[:, :, :hidden]
    column_scale = scale.transpose(1, 2)  # (B, m, 1)
    w0, b0, w1, b1, w2, b2 = (params[:, offsets[i]:offsets[i + 1]].unflatten(1, tuple(shapes[i])) for i in range(6))
    first_moment = torch.zeros_like(params)
    second_moment = torch.zeros_like(params)
    beta1, beta2 = _ADAM_BETAS
    rounds = networks[0].rounds
    peak = settings.learning_rate * max(settings.round_lr_decay**rounds, _LR_FLOOR)
    warmup = max(1, int(round(settings.warmup_fraction * iterations))) if settings.warmup_fraction > 0 else 0
    losses = torch.empty(iterations + 1, count, dtype=dtype, device=device)
    stopping = settings.stop_tolerance > 0 and settings.stop_window > 0
    active = torch.ones(count, 1, dtype=dtype, device=device)
    stopped = np.full(count, iterations)
    for step in range(iterations + 1):
        # eq. (2): W2 ELU(W1 ELU(W0 x + b0) + b1) + b2, ELU(z) = max(z, e − 1), e = exp(min(z, 0)) = ELU'(z)
        z1 = torch.baddbmm(b0.unsqueeze(1), features, w0.transpose(1, 2))
        e1 = torch.clamp_max(z1, 0.0).exp_()
        a1 = torch.maximum(z1, e1 - 1.0)
        z2 = torch.baddbmm(b1.unsqueeze(1), a1, w1.transpose(1, 2))
        e2 = torch.clamp_max(z2, 0.0).exp_()
        torch.maximum(z2, e2 - 1.0, out=a2)
        if padded_rows:
            a2.mul_(row_mask)
        scaled_out = torch.cat([w2, b2.unsqueeze(2)], dim=2).mul_(column_scale)  # (B, m, h + 1)
        residual = torch.baddbmm(targets, a2_ones, scaled_out.transpose(1, 2), beta=-1.0)  # (F(x) − y) ∘ s
        losses[step] = torch.linalg.vector_norm(residual, dim=(1, 2)).square_().mul_(0.5)
        if step == iterations:
            break
        if stopping and step >= warmup + settings.stop_window and step % 50 == 0:
            before, now = losses[step - settings.stop_window], losses[step]
            converged = ((before - now).abs() <= settings.stop_tolerance * before).unsqueeze(1) & (active > 0)
            if bool(converged.any()):
                for b in torch.nonzero(converged[:, 0]).flatten().tolist():
                    stopped[b] = step
                active = active.masked_fill(converged, 0.0)
                if not bool(active.any()):
                    break
        # d loss / d [W2, b2] = ((F(x) − y) ∘ s²)ᵀ [a2, 1] = s ∘ (residualᵀ [a2, 1]); d loss / d a2 = residual (s ∘ W2).
        gradient_out = torch.bmm(residual.transpose(1, 2), a2_ones).mul_(column_scale)  # (B, m, h + 1)
        d2 = torch.bmm(residual, scaled_out[:, :, :hidden]).mul_(e2)
        gradient_w1 = torch.bmm(d2.transpose(1, 2), a1)
        d1 = torch.bmm(d2, w1).mul_(e1)
        gradient_w0 = torch.bmm(d1.transpose(1, 2), features)
        gradient = torch.cat([gradient_w0.flatten(1), d1.sum(1), gradient_w1.flatten(1), d2.sum(1),
                              gradient_out[:, :, :hidden].flatten(1), gradient_out[:, :, hidden]], dim=1)
        # Adam (torch.optim.Adam's update, per network): moments, bias corrections, step.
        t = step + 1
        rate = learning_rate(step, iterations, warmup, peak)
        first_moment.mul_(beta1).add_(gradient, alpha=1 - beta1)
        second_moment.mul_(beta2).addcmul_(gradient, gradient, value=1 - beta2)
        denominator = (second_moment.sqrt() / math.sqrt(1 - beta2**t)).add_(_ADAM_EPS)
        update = first_moment * active if stopping else first_moment
        params.addcdiv_(update, denominator, value=-rate / (1 - beta1**t))
    losses = losses[: step + 1].cpu().numpy().astype(np.float64)  # rows after an early stop were never written
    params = params.cpu().numpy()
    for b, network in enumerate(networks):
        n, m = network.targets.shape
        unpacked = []
        for i, w in enumerate(network.weights):
            block = params[b, offsets[i]:offsets[i + 1]].reshape(shapes[i])
            unpacked.append(np.ascontiguousarray(block[tuple(slice(0, s) for s in w.shape)]))
        network.weights = unpacked
        last = min(int(stopped[b]), step)
        network.loss_history.append(losses[: last + 1, b].copy())
        network.rounds += 1
