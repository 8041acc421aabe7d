"""Training of the neural Fourier codecs' networks, many at once (torch, imported only by the encoders).

Tojo, Chen, Umetani 2022 train one small network per clip: ``h = 2 (2K + 1)`` hidden units, a few thousand
weights. One such network costs little arithmetic per optimizer step and a fixed overhead of dozens of tensor
operations, and it takes tens of thousands of steps; trained one at a time through autograd and ``torch.optim``,
the overhead is most of the time. Here every network of a call is trained side by side:

* **Stacked weights.** The B networks of a group live in one flat parameter tensor ``P`` (B × |α|), viewed as one
  matrix per layer with the bias as its last column, ``[W0 | b0] (B, h, 2K+2)``, ``[W1 | b1] (B, h, h+1)``,
  ``[W2 | b2] (B, m, h+1)``; each layer's input carries a row of ones, so the forward pass of eq. (2) is three
  batched matrix products (``bmm``) over the group's frames. The Fourier features are computed once per round.
* **Frame-minor activations.** Activations are ``(B, width, frames)``: every product has the frames as its long
  dimension, the layer widths as its short ones, in the order in which the CPU's kernels for thin matrices are
  fastest (the frame-major layout, ``(B, frames, width)``, runs the same products markedly slower at small K,
  where the widths are a few units).
* **Gradients by hand.** The loss of eq. (3) and its gradient through the two ELU layers are written out (five
  more batched products, the bias gradients inside the weight gradients), so no autograd graph is built. ELU is
  computed as ``max(z, e − 1)`` with ``e = exp(min(z, 0))``, and ``e`` is also ELU's derivative (1 where
  ``z > 0``), so one exponential serves both.
* **The optimizer** (the paper names none). ``optimizer="lbfgs"`` with ``solve_output=True`` (the default of
  ``fourier-mlp-int``):

  - *Output layer solved* (variable projection). The network is linear in ``[W2 | b2]``, so at every evaluation
    ``[W2 | b2]`` is set to the least-squares fit of eq. (3) on the current hidden activations ``[a2; 1]`` (per
    output row, normal equations of size h + 1, in float64 with a tiny relative ridge), and only ``[W0 | b0]``
    and ``[W1 | b1]`` are optimized: the loss is then a function of the hidden layers alone, and its gradient is
    the gradient of eq. (3) at the solved output layer (the output layer's own gradient is 0 there). The round
    ends with one more solve at the hidden layers it kept: its last evaluation was a trial point, which the line
    search may have rejected, and an output layer solved there does not fit the kept hidden layers.
  - *Fewer outputs to fit* (``rank_tolerance > 0``, opt-in). With the output layer
    solved, the targets enter the loss only through their row space: the hidden layers are fitted to the targets'
    leading principal components (all but ``rank_tolerance`` of their energy; how many on CMU clips: README,
    "Timings"), and the output layer is solved on all outputs once at the end (:func:`_reduced_targets`).
  - *L-BFGS* (:func:`_lbfgs`) on those weights, each network with its own curvature pairs, step length and
    Armijo backtracking, one loss evaluation per iteration (and its gradient when some network accepts the
    point); accepted losses never rise. Its per-network numbers are kept in numpy, its vectors in torch (a step
    of these networks is mostly per-operation overhead; the same float32 operations, so the same values).

  Together they reach in a few hundred iterations the loss that Adam reaches in tens of thousands of steps (the
  README has the measurement). ``optimizer="adam"`` (the default of ``fourier-mlp-dct``) is the update of
  ``torch.optim.Adam`` (β = 0.9, 0.999, ε = 1e-8, bias corrections), each network with its own moments, all
  networks of a group at the same step number and rate (:func:`_adam`).
* **Padding that changes nothing.** Clips of different lengths are padded with frames whose loss weight is 0, and
  skeletons with fewer pose parameters with outputs whose loss weight is 0: the padded rows add 0 to every
  gradient. Padding costs arithmetic, so the networks are cut into groups of similar length
  (:func:`frame_groups`) and the groups are trained one after another.
* **Stopping.** A network whose loss has stopped falling (relative decrease over the last ``stop_window`` steps at
  most ``stop_tolerance``; for Adam tested after the warm-up) is frozen there; so is an L-BFGS network whose line
  search shrinks its step below 10⁻⁶ (float32 lowers its loss no further). The round ends when all are.

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
_LBFGS_MEMORY = 6  # curvature pairs kept per network
_ARMIJO = 1e-4  # sufficient-decrease constant of the L-BFGS line search
_RIDGE = 1e-6  # ridge of the output layer's least squares, relative to the mean of its Gram matrix's diagonal
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
    optimizer: str = "adam"
    solve_output: bool = False
    rank_tolerance: float = 0.0

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
            optimizer=str(getattr(config, "optimizer", "adam")),
            solve_output=bool(getattr(config, "solve_output", False)),
            rank_tolerance=float(getattr(config, "rank_tolerance", 0.0)),
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
    # Per frame, a weight of eq. (3)'s term (N,), mean 1; None: every frame 1 (the paper's loss).
    frame_weights: np.ndarray | None = None
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

    def reweight_frames(self, frame_errors: np.ndarray, power: float) -> None:
        """Multiply each frame's loss weight by ``(error / mean error) ** power`` and rescale them to mean 1.

        The frames with the largest L∞ error weigh more in the next pass (iteratively reweighted least squares
        toward the minimax fit: the codec's stopping test is on L∞, eq. (3) is an L2 loss). Successive passes
        multiply; ``frame_weights = None`` goes back to eq. (3). All-zero errors leave the weights as they are.
        """
        errors = np.asarray(frame_errors, dtype=np.float64)
        mean = float(errors.mean())
        if not mean > 0:
            return
        weights = (errors / mean) ** power
        if self.frame_weights is not None:
            weights = weights * self.frame_weights
        self.frame_weights = weights / weights.mean()

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
                settings: TrainingSettings, same_round: bool = False) -> None:
    """Grow every network to ``len(omegas[i])`` frequencies (warm start) and run one optimizer round on each.

    Parameters
    ----------
    networks : sequence of Network
    omegas : sequence of sequence of float
        Each network's Ω (cycles per clip); networks with the same number of frequencies and rounds so far are
        trained together.
    iterations : int
        Optimizer iterations of the round.
    settings : TrainingSettings
    same_round : bool
        Another pass of the round the networks are in (their frame weights changed): no growth, the round count
        (Adam's per-round rate) unchanged; the pass's losses are one more entry of ``loss_history``.
    """
    if not same_round:
        for network, frequencies in zip(networks, omegas):
            network.grow(len(frequencies))
    by_shape: dict[tuple[int, int], list[int]] = {}
    for index, (network, frequencies) in enumerate(zip(networks, omegas)):
        by_shape.setdefault((len(frequencies), network.rounds), []).append(index)
    for members in by_shape.values():
        for group in frame_groups([networks[i].num_frames for i in members]):
            chosen = [members[i] for i in group]
            _train_group([networks[i] for i in chosen], [omegas[i] for i in chosen], iterations, settings)
    if same_round:
        for network in networks:
            network.rounds -= 1  # _train_group counted the pass as a round


def _features(torch, t, omegas: Sequence[float]):
    """Eq. (1) for one network with a column of ones appended (the first layer's bias as one more weight column):
    ``[t, sin 2πω₁t, cos 2πω₁t, …, 1]``, shape (N, 2K + 2). Computed once per round: Ω is fixed within it."""
    t = t[:, None]
    columns = [t]
    for omega in omegas:
        phase = (2.0 * math.pi * float(omega)) * t
        columns += [torch.sin(phase), torch.cos(phase)]
    columns.append(torch.ones_like(t))
    return torch.cat(columns, dim=1)


def _augmented_shapes(shapes: Sequence[tuple[int, ...]]) -> list[tuple[int, int]]:
    """Each layer as one matrix with its bias as the last column: ``[W0 | b0]``, ``[W1 | b1]``, ``[W2 | b2]``."""
    return [(shapes[0][0], shapes[0][1] + 1), (shapes[2][0], shapes[2][1] + 1), (shapes[4][0], shapes[4][1] + 1)]


def _pack(weights: Sequence[np.ndarray], layers: Sequence[tuple[int, int]]) -> np.ndarray:
    """``[W0, b0, W1, b1, W2, b2]`` into the flat ``[W0 | b0], [W1 | b1], [W2 | b2]`` layout, zero-padded to
    ``layers`` (more output rows for a network with fewer outputs than its group's widest)."""
    blocks = []
    for layer, (rows, columns) in enumerate(layers):
        w, b = weights[2 * layer], weights[2 * layer + 1]
        block = np.zeros((rows, columns), dtype=np.float32)
        block[: w.shape[0], : w.shape[1]] = w
        block[: b.shape[0], -1] = b
        blocks.append(block.ravel())
    return np.concatenate(blocks)


def _unpack(flat: np.ndarray, layers: Sequence[tuple[int, int]], like: Sequence[np.ndarray]) -> list[np.ndarray]:
    """The inverse of :func:`_pack`, cut back to the shapes of ``like``."""
    out, offset = [], 0
    for layer, (rows, columns) in enumerate(layers):
        block = flat[offset: offset + rows * columns].reshape(rows, columns)
        offset += rows * columns
        w, b = like[2 * layer], like[2 * layer + 1]
        out += [np.ascontiguousarray(block[: w.shape[0], : w.shape[1]]), np.ascontiguousarray(block[: b.shape[0], -1])]
    return out


def _train_group(networks: Sequence[Network], omegas: Sequence[Sequence[float]], iterations: int,
                 settings: TrainingSettings) -> None:
    """One round for networks of the same width: lockstep full-batch training on stacked weights.

    Every layer is one matrix with its bias as the last column, and every layer's input has a row of ones (0 on
    padded frames), so a layer is one batched product and a weight gradient (bias included) is another. Activations
    are kept frame-minor, ``(B, h, N)`` (a network's frames along a row): every product then has the clip's frames
    as its long dimension and the layer widths as the short ones in the order the CPU's matrix kernels run fastest.
    """
    import torch

    device = resolve_device(settings.device)
    dtype = torch.float32
    count = len(networks)
    frames = max(n.num_frames for n in networks)
    outputs = max(n.num_outputs for n in networks)
    shapes = [w.shape for w in networks[0].weights]
    # Networks with fewer outputs than the widest one: W2 and b2 get zero rows (zero loss weight keeps them 0).
    shapes[4], shapes[5] = (outputs, shapes[4][1]), (outputs,)
    layers = _augmented_shapes(shapes)
    offsets = np.concatenate([[0], np.cumsum([r * c for r, c in layers])]).astype(int)
    hidden, inputs = layers[0][0], layers[0][1]
    params = torch.zeros(count, int(offsets[-1]), dtype=dtype)
    features = torch.zeros(count, inputs, frames, dtype=dtype)  # x(t_i) of eq. (1) and a 1, column i
    targets = torch.zeros(count, outputs, frames, dtype=dtype)
    # eq. (3) as the mean over the clip's entries (the single-network codec's loss), per network: with
    # s = w · std · sqrt(2 / (N m)) per output (0 on padded outputs), loss = |(F(x) − y) ∘ s|² / 2 and
    # d loss / d output = (F(x) − y) ∘ s². The scaled residual (F(x) − y) ∘ s is one batched product:
    # [s ∘ W2 | s ∘ b2] [a2; 1] − y ∘ s, and padded frames give 0 in it (their [a2; 1] column is 0).
    scale = torch.zeros(count, outputs, 1, dtype=dtype)
    frame_mask = torch.zeros(count, 1, frames, dtype=dtype)
    # sqrt of each frame's loss weight (0 on padded frames): it scales a frame's column of [a2; 1] and of y ∘ s,
    # so the residual's column i is sqrt(v_i) (F(x_i) − y_i) ∘ s.
    frame_root = torch.zeros(count, 1, frames, dtype=dtype)
    weighted = any(network.frame_weights is not None for network in networks)
    for b, (network, frequencies) in enumerate(zip(networks, omegas)):
        n, m = network.targets.shape
        params[b] = torch.from_numpy(_pack(network.weights, layers))
        t = torch.tensor(time_grid(n), dtype=dtype)
        features[b, :, :n] = _features(torch, t, frequencies).T
        scale[b, :m, 0] = torch.from_numpy(np.asarray(network.loss_weights, dtype=np.float32)) * math.sqrt(2.0 / (n * m))
        targets[b, :m, :n] = torch.from_numpy(np.asarray(network.targets, dtype=np.float32)).T * scale[b, :m]
        frame_mask[b, :, :n] = 1.0
        frame_root[b, :, :n] = 1.0
        if network.frame_weights is not None:
            frame_root[b, 0, :n] = torch.from_numpy(np.sqrt(np.asarray(network.frame_weights, dtype=np.float32)))
            targets[b, :m, :n] *= frame_root[b, :, :n]
    padded_frames = bool((frame_mask == 0).any())
    params, features, targets, scale, frame_mask, frame_root = (
        x.to(device) for x in (params, features, targets, scale, frame_mask, frame_root))
    # With the output layer solved, the targets enter the loss only through their row space: the optimizer fits
    # their leading components (_reduced_targets) and the output layer is solved on all of them at the end.
    fit = {"targets": targets, "offset": 0.0, "full": True}
    if settings.solve_output and settings.rank_tolerance > 0:
        reduced, offset = _reduced_targets(torch, targets, settings.rank_tolerance)
        if reduced.shape[1] < targets.shape[1]:
            fit = {"targets": reduced, "offset": offset, "full": False}
    # [a1; 1] and [a2; 1] of every frame (the ones row is 0 on padded frames): the second and third layers' inputs;
    # [a2; 1] scaled by the frame's sqrt weight.
    a1_ones = frame_mask.expand(count, 1, frames).repeat(1, hidden + 1, 1)
    a2_ones = frame_root.expand(count, 1, frames).repeat(1, hidden + 1, 1)
    a1, a2 = a1_ones[:, :hidden], a2_ones[:, :hidden]
    w0, w1, w2 = (params[:, offsets[i]:offsets[i + 1]].unflatten(1, layers[i]) for i in range(3))
    gradient = torch.empty_like(params)
    gradient_w0, gradient_w1, gradient_w2 = (gradient[:, offsets[i]:offsets[i + 1]].unflatten(1, layers[i])
                                             for i in range(3))
    stopping = settings.stop_tolerance > 0 and settings.stop_window > 0
    inverse_scale = torch.where(scale > 0, 1.0 / scale.clamp_min(1e-30), torch.zeros_like(scale))

    saved = {}  # the forward pass's quantities the gradient reuses

    def evaluate(with_gradient: bool = True):
        """eq. (3) per network at ``params`` (B,), and its gradient into ``gradient`` when asked."""
        targets = fit["targets"]
        # eq. (2): W2 ELU(W1 ELU(W0 x + b0) + b1) + b2, ELU(z) = max(z, e − 1), e = exp(min(z, 0)) = ELU'(z)
        z1 = torch.bmm(w0, features)
        e1 = torch.clamp_max(z1, 0.0).exp_()
        torch.maximum(z1, torch.sub(e1, 1.0, out=a1), out=a1)  # in place: no temporary
        z2 = torch.bmm(w1, a1_ones)
        e2 = torch.clamp_max(z2, 0.0).exp_()
        torch.maximum(z2, torch.sub(e2, 1.0, out=a2), out=a2)  # in place: no temporary
        if weighted:
            a2.mul_(frame_root)
        elif padded_frames:
            a2.mul_(frame_mask)
        if settings.solve_output:
            # [W2 | b2] that minimizes eq. (3) for these hidden layers: per output row, linear least squares on
            # [a2; 1] (normal equations in float64, a relative ridge of _RIDGE against a singular Gram matrix).
            gram = torch.bmm(a2_ones, a2_ones.transpose(1, 2)).double()
            gram.diagonal(dim1=1, dim2=2).add_(_RIDGE * gram.diagonal(dim1=1, dim2=2).mean(dim=1, keepdim=True))
            projected = torch.bmm(targets, a2_ones.transpose(1, 2)).double()  # (B, m, h + 1)
            scaled_out = torch.linalg.solve(gram, projected.transpose(1, 2)).transpose(1, 2).to(dtype)
            if fit["full"]:
                torch.mul(scaled_out, inverse_scale, out=w2)
        else:
            scaled_out = w2 * scale  # (B, m, h + 1): [s ∘ W2 | s ∘ b2]
        residual = torch.baddbmm(targets, scaled_out, a2_ones, beta=-1.0)  # (F(x) − y) ∘ s, (B, m, N)
        loss = torch.linalg.vector_norm(residual, dim=(1, 2)).square_().mul_(0.5).add_(fit["offset"])
        saved.update(e1=e1, e2=e2, scaled_out=scaled_out, residual=residual)
        if with_gradient:
            backward()
        return loss

    def backward() -> None:
        """The gradient of eq. (3) at the point of the last :func:`evaluate`, into ``gradient`` (its activations
        ``a1``, ``a2`` and the saved quantities are that point's until the next evaluation)."""
        e1, e2, scaled_out, residual = saved["e1"], saved["e2"], saved["scaled_out"], saved["residual"]
        # d loss / d [W2 | b2] = s ∘ (residual [a2; 1]ᵀ); d loss / d a2 = (s ∘ W2)ᵀ residual; then back through
        # both ELUs (their derivatives are e2, e1) and the first two layers.
        if settings.solve_output:
            gradient_w2.zero_()  # [W2 | b2] is solved, not stepped (its gradient is 0 at the solution)
        else:
            gradient_w2.copy_(torch.bmm(a2_ones, residual.transpose(1, 2)).transpose(1, 2)).mul_(scale)
        d2 = torch.bmm(scaled_out[:, :, :hidden].transpose(1, 2), residual).mul_(e2)
        if weighted:
            d2.mul_(frame_root)  # a2's column i entered the residual times sqrt(v_i)
        gradient_w1.copy_(torch.bmm(d2, a1_ones.transpose(1, 2)))
        d1 = torch.bmm(w1[:, :, :hidden].transpose(1, 2), d2).mul_(e1)
        gradient_w0.copy_(torch.bmm(d1, features.transpose(1, 2)))

    if settings.optimizer == "lbfgs":
        # With a solved output layer only [W0 | b0] and [W1 | b1] are the optimizer's variables.
        free = int(offsets[2]) if settings.solve_output else int(offsets[-1])
        losses, stopped = _lbfgs(torch, params[:, :free], gradient[:, :free], evaluate, backward, iterations,
                                 settings, stopping)
    else:
        losses, stopped = _adam(torch, params, gradient, evaluate, iterations, settings, networks[0].rounds,
                                stopping)
    if settings.solve_output:
        # The output layer solved once more, at the hidden layers the optimizer kept and on every target component.
        # The last evaluation was L-BFGS's last trial point, which its line search may have rejected: the output
        # layer solved there belongs to hidden layers the network does not keep (the stored network's loss is then
        # not the one reported, and can be far above it); with reduced targets it covers their leading components
        # only. Evaluating the kept point again repeats its arithmetic, so the stored network is the reported one.
        fit.update(targets=targets, offset=0.0, full=True)
        evaluate(with_gradient=False)
    step = len(losses) - 1
    losses = losses.cpu().numpy().astype(np.float64)
    params = params.cpu().numpy()
    for b, network in enumerate(networks):
        network.weights = _unpack(params[b], layers, network.weights)
        last = min(int(stopped[b]), step)
        network.loss_history.append(losses[: last + 1, b].copy())
        network.rounds += 1


def _reduced_targets(torch, targets, tolerance: float):
    """The targets' leading components: ``(Uᵀ T, ½ |T − U Uᵀ T|²)`` per network, U the fewest leading left singular
    vectors of ``T`` (B, m, N) whose left-out energy is at most ``tolerance`` of ``|T|²``.

    With the output layer solved by least squares, the loss is ``min_W |W A − T|² / 2`` over the hidden
    activations A, and for ``W = U W'`` it equals ``|W' A − Uᵀ T|² / 2`` plus the left-out energy (a constant): the
    hidden layers can be fitted to ``Uᵀ T`` (r × N instead of m × N; the products over the outputs are most of a
    step's arithmetic). At a tolerance of 1e-8 the left-out part is below
    float32's resolution of the initial loss. Networks with fewer components get zero rows (they add 0).
    Returns the reduced targets (B, r, N) and the offset per network (B,), on the targets' device and dtype.
    """
    t64 = targets.double()
    energy, vectors = torch.linalg.eigh(torch.bmm(t64, t64.transpose(1, 2)))  # ascending, per network
    energy = energy.clamp_min(0.0)
    outputs = energy.shape[1]
    # Per network, the smallest components whose energy together is at most the tolerance are left out.
    left_out = (energy.cumsum(dim=1) <= tolerance * energy.sum(dim=1, keepdim=True)).sum(dim=1)
    keep = int((outputs - left_out).max())
    kept = torch.arange(outputs, device=targets.device)[None, :] >= left_out[:, None]  # (B, m), ascending order
    offset = 0.5 * torch.where(kept, torch.zeros_like(energy), energy).sum(dim=1)
    basis = (vectors * kept[:, None, :])[:, :, outputs - keep:]  # (B, m, r): the r largest, zero where left out
    reduced = torch.bmm(basis.transpose(1, 2), t64)
    return reduced.to(targets.dtype), offset.to(targets.dtype)


def _adam(torch, params, gradient, evaluate, iterations: int, settings: TrainingSettings, rounds: int,
          stopping: bool):
    """Full-batch Adam (``torch.optim.Adam``'s update, per network) with the warm-up and cosine schedule.

    ``evaluate(with_gradient)`` returns the loss per network (B,) at ``params`` (B × |α|, updated in place) and
    writes its gradient into ``gradient``. Returns the loss before each step and after the last one, shape
    (steps + 1, B), and per network the step at which it stopped.
    """
    count = params.shape[0]
    beta1, beta2 = _ADAM_BETAS
    peak = settings.learning_rate * max(settings.round_lr_decay**rounds, _LR_FLOOR)
    warmup = max(1, int(round(settings.warmup_fraction * iterations))) if settings.warmup_fraction > 0 else 0
    first_moment = torch.zeros_like(params)
    second_moment = torch.zeros_like(params)
    losses = torch.empty(iterations + 1, count, dtype=params.dtype, device=params.device)
    active = torch.ones(count, 1, dtype=params.dtype, device=params.device)
    stopped = np.full(count, iterations)
    for step in range(iterations + 1):
        losses[step] = evaluate(step < iterations)
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
        # Adam (torch.optim.Adam's update, per network): moments, bias corrections, step.
        t = step + 1
        rate = learning_rate(step, iterations, warmup, peak)
        first_moment.mul_(beta1).add_(gradient, alpha=1 - beta1)
        second_moment.mul_(beta2).addcmul_(gradient, gradient, value=1 - beta2)
        denominator = (second_moment.sqrt() / math.sqrt(1 - beta2**t)).add_(_ADAM_EPS)
        update = first_moment * active if stopping else first_moment
        params.addcdiv_(update, denominator, value=-rate / (1 - beta1**t))
    return losses[: step + 1], stopped


def _host_shares_memory(device) -> bool:
    """Whether numpy arrays and tensors on ``device`` can share memory (the CPU), so that :func:`_lbfgs` hands its
    per-network numbers to torch without copies."""
    return device.type == "cpu"


def _lbfgs(torch, params, gradient, evaluate, backward, iterations: int, settings: TrainingSettings,
           stopping: bool):
    """Full-batch L-BFGS per network, in lockstep: one loss evaluation per iteration, and one gradient when some
    network accepts its trial point.

    Each network keeps its own last ``_LBFGS_MEMORY`` curvature pairs (two-loop recursion, initial scale
    ``s·y / y·y`` of its newest pair) and its own step length: a trial point that fails the Armijo test
    (``f(x + α d) ≤ f(x) + 10⁻⁴ α ∇f·d``) is rejected and the step shrunk (the minimum of the quadratic through the
    two losses and the slope, kept within 0.1 α … 0.5 α); an accepted one resets α to 1. A pair with too little
    curvature (``s·y ≤ 10⁻⁸ |s| |y|``) is not stored. The first direction is the gradient scaled so that no weight
    moves by more than ``learning_rate``. A network stops when its loss fell by at most ``stop_tolerance``
    (relative) over the last ``stop_window`` iterations, or when its step shrinks below 10⁻⁶ (float32 cannot lower
    the loss further). ``evaluate(with_gradient)`` is as for :func:`_adam`; ``backward()`` writes the gradient at
    the point last evaluated into ``gradient``. Same return values as :func:`_adam` (``losses[i]``: the loss of the
    accepted point after i iterations).

    A step of these small networks costs more in per-operation overhead than in arithmetic, so the bookkeeping
    does only what changes a result, in float32 throughout as before: the vectors (B × |α|: points, gradients,
    directions, curvature pairs) stay torch tensors on the training device, while the per-network numbers (B:
    losses, slopes, step lengths, ρ, γ, the masks) are numpy arrays on the host, where an operation costs a
    fraction of a torch call (the same IEEE float32 operations in the same order, so the same values); a trial
    point's gradient is computed only when some network accepts it (a rejected point's gradient is never read);
    an iteration in which no network accepts stores an empty pair and keeps every direction, so it runs no
    two-loop recursion; and the recursion leaves out the pairs that no network stored (ρ = 0 for all: their
    terms are 0).
    """
    count, size = params.shape
    device, dtype = params.device, params.dtype
    f32 = np.float32

    # Host numbers and their device views: on the CPU the same memory (no copies), elsewhere copied each time.
    on_cpu = _host_shares_memory(device)
    dots = np.empty((5, count), dtype=f32)  # rows: slope, s·y, y·y, s·s, the two-loop's current product
    columns = np.empty((4, count, 1), dtype=f32)  # rows: α, γ, the accepted mask, the two-loop's coefficient
    flags = np.empty((2, count, 1), dtype=bool)  # rows: uphill, accepted
    dot_rows = list(torch.from_numpy(dots).unbind(0))
    column_views = list(torch.from_numpy(columns).unbind(0))
    flag_views = list(torch.from_numpy(flags).unbind(0))

    def host(tensor) -> np.ndarray:
        return tensor.numpy() if on_cpu else tensor.cpu().numpy()

    def dot(x, y, row: int) -> np.ndarray:
        """``x · y`` per network (torch's reduction, as before) into row ``row`` of ``dots``."""
        if on_cpu:
            torch.linalg.vecdot(x, y, out=dot_rows[row])
        else:
            dots[row] = torch.linalg.vecdot(x, y).cpu().numpy()
        return dots[row]

    def column(values: np.ndarray, row: int):
        """(B,) host numbers as a (B, 1) tensor on the device (row ``row`` of ``columns`` or ``flags``): it
        scales or selects the rows of a (B, |α|) tensor."""
        store, views = (flags, flag_views) if values.dtype == bool else (columns, column_views)
        store[row, :, 0] = values
        return views[row] if on_cpu else views[row].to(device)

    memory = _LBFGS_MEMORY
    s_history = torch.zeros(memory, count, size, dtype=dtype, device=device)
    y_history = torch.zeros(memory, count, size, dtype=dtype, device=device)
    s_slots, y_slots = list(s_history.unbind(0)), list(y_history.unbind(0))
    rho = np.zeros((memory, count), dtype=f32)
    holds_pair = [False] * memory  # whether some network stored a pair (ρ > 0) in the slot
    newest = -1  # slot of the newest pair (the history is a ring shared by the networks)
    losses = np.empty((iterations + 1, count), dtype=f32)
    stopped = np.full(count, iterations)
    active = np.ones(count, dtype=bool)
    point = params.clone()
    loss = host(evaluate()).copy()
    grad = gradient.clone()
    losses[0] = loss
    gamma_t = settings.learning_rate / grad.abs().amax(dim=1).clamp_min(1e-30)
    direction = -gamma_t[:, None] * grad
    gamma = host(gamma_t).copy()
    alpha = np.ones(count, dtype=f32)
    step = 0
    for step in range(1, iterations + 1):
        slope = dot(grad, direction, 0)
        descent = slope < 0
        uphill = active & ~descent  # no descent along the quasi-Newton direction: the scaled gradient instead
        if uphill.any():
            direction = torch.where(column(uphill, 0), column(-gamma, 1) * grad, direction)
            slope = dot(grad, direction, 0)
            descent = slope < 0
        moving = active & descent
        alpha_used = np.where(moving, alpha, f32(0))
        torch.addcmul(point, column(alpha_used, 0), direction, out=params)
        trial_loss = host(evaluate(False))
        with np.errstate(all="ignore"):  # a non-finite trial loss is rejected below
            accepted = moving & np.isfinite(trial_loss) & (trial_loss <= loss + _ARMIJO * alpha_used * slope)
            # Rejected: shrink the step (minimum of the quadratic through f(x), f'(x; d) and f(x + α d)).
            excess = np.maximum(trial_loss - loss - slope * alpha_used, f32(1e-30))
            shrunk = np.nan_to_num(-slope * alpha_used * alpha_used / (2 * excess), nan=0.0)
        shrunk = np.minimum(np.maximum(shrunk, 0.1 * alpha_used), 0.5 * alpha_used)
        alpha = np.where(accepted, f32(1), np.where(moving, shrunk, alpha))
        newest = (newest + 1) % memory
        s, y = s_slots[newest], y_slots[newest]
        if accepted.any():
            # Accepted: the gradient there, store the pair, move.
            backward()
            taken = column(accepted, 1)
            mask = column(accepted.astype(f32), 2)
            torch.sub(params, point, out=s).mul_(mask)
            torch.sub(gradient, grad, out=y).mul_(mask)
            sy, yy, ss = dot(s, y, 1), dot(y, y, 2), dot(s, s, 3)
            curved = accepted & (sy > 1e-8 * np.sqrt(ss * yy))
            rho[newest] = np.where(curved, 1.0 / np.maximum(sy, f32(1e-30)), f32(0))
            holds_pair[newest] = bool(curved.any())
            gamma = np.where(curved, sy / np.maximum(yy, f32(1e-30)), gamma)
            point = torch.where(taken, params, point)
            grad = torch.where(taken, gradient, grad)
            loss = np.where(accepted, trial_loss, loss)
            # New directions (two-loop recursion) for the networks that moved; the others retry along theirs.
            q = grad.clone()
            coefficients = []
            for back in range(memory):
                i = (newest - back) % memory
                if holds_pair[i]:
                    a = rho[i] * dot(s_slots[i], q, 4)
                    q.addcmul_(column(a, 3), y_slots[i], value=-1.0)
                    coefficients.append((i, a))
            r = column(gamma, 1) * q
            for i, a in reversed(coefficients):
                b = rho[i] * dot(y_slots[i], r, 4)
                r.addcmul_(column(a - b, 3), s_slots[i])
            direction = torch.where(taken, -r, direction)
        else:  # no network moved: an empty pair; points, losses and directions stay
            s.zero_()
            y.zero_()
            rho[newest] = 0.0
            holds_pair[newest] = False
        losses[step] = loss
        # Stopping (accepted networks go on; of the others, those that could not move or whose step is too short).
        finished = active & ~accepted & (~moving | (alpha < 1e-6))
        if stopping and step >= settings.stop_window and step % 10 == 0:
            before = losses[step - settings.stop_window]
            finished |= active & (np.abs(before - loss) <= settings.stop_tolerance * before)
        if finished.any():
            stopped[finished] = step
            active = active & ~finished
            if not active.any():
                break
    params.copy_(point)
    return torch.from_numpy(losses[: step + 1]), stopped
