"""Training many neural Fourier networks side by side (mocapbench.codecs.neural_fourier.training)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapbench.codecs import create
from mocapbench.codecs.neural_fourier.training import (
    Network,
    TrainingSettings,
    frame_groups,
    learning_rate,
    train_round,
)
from mocapbench.synthetic import sinusoidal_motion

SETTINGS = TrainingSettings(learning_rate=0.01, warmup_fraction=0.2, round_lr_decay=0.8, seed=0)


def _network(frames: int, outputs: int = 13, seed: int = 0) -> Network:
    rng = np.random.default_rng(frames * 31 + outputs)
    t = np.linspace(0, 1, frames)[:, None]
    targets = np.sin(2 * np.pi * (1 + rng.random((1, outputs)) * 3) * t + rng.random((1, outputs)) * 6)
    return Network(targets, 0.5 + rng.random(outputs), seed)


def _reference_losses(network: Network, omegas: list[float], iterations: int) -> np.ndarray:
    """The same round through autograd and torch.optim.Adam: one network, the codec's loss (its frames weighted by
    ``network.frame_weights`` when set) and schedule."""
    import torch

    from mocapbench.codecs.neural_fourier.codec import fourier_features

    x = torch.tensor(fourier_features(np.linspace(0, 1, network.num_frames), np.asarray(omegas)), dtype=torch.float32)
    y = torch.tensor(network.targets, dtype=torch.float32)
    w = torch.tensor(network.loss_weights, dtype=torch.float32)
    v = torch.ones(network.num_frames, 1)
    if network.frame_weights is not None:
        v = torch.tensor(network.frame_weights, dtype=torch.float32)[:, None]
    params = [torch.tensor(p).requires_grad_(True) for p in network.weights]
    optimizer = torch.optim.Adam(params, lr=SETTINGS.learning_rate)
    warmup = max(1, int(round(SETTINGS.warmup_fraction * iterations)))
    elu, linear = torch.nn.functional.elu, torch.nn.functional.linear
    losses = []
    for step in range(iterations + 1):
        w0, b0, w1, b1, w2, b2 = params
        loss = torch.mean(v * ((linear(elu(linear(elu(linear(x, w0, b0)), w1, b1)), w2, b2) - y) * w) ** 2)
        losses.append(float(loss.detach()))
        if step == iterations:
            break
        for group in optimizer.param_groups:
            group["lr"] = learning_rate(step, iterations, warmup, SETTINGS.learning_rate)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    return np.array(losses)


@pytest.mark.torch
def test_hand_written_gradients_and_adam_follow_autograd_and_torch_adam():
    pytest.importorskip("torch")
    omegas = [1.0, 2.5]
    network = _network(90)
    network.grow(len(omegas))
    reference = _reference_losses(network, omegas, 60)
    network.weights = None  # the same draw again: the generator restarts from the seed
    network._generator = None
    train_round([network], [omegas], 60, SETTINGS)
    np.testing.assert_allclose(network.loss_history[0], reference, rtol=2e-4)
    assert reference[-1] < 0.7 * reference[0]  # the round did train


@pytest.mark.torch
def test_frame_weighted_loss_and_gradients_follow_autograd_beside_a_longer_unweighted_network():
    """Frame weights (the L-inf passes of fourier-mlp-dct) enter the loss and every gradient as in autograd, also
    in a batch padded for a longer network that has none."""
    pytest.importorskip("torch")
    omegas = [1.0, 2.5]
    network = _network(90)
    network.grow(len(omegas))
    network.frame_weights = np.random.default_rng(3).random(90) * 3
    reference = _reference_losses(network, omegas, 60)
    network.weights, network._generator = None, None  # the same draw again
    companion = _network(130)
    train_round([network, companion], [omegas, omegas], 60, SETTINGS)
    np.testing.assert_allclose(network.loss_history[0], reference, rtol=5e-4)
    unweighted = _network(90)
    train_round([unweighted], [omegas], 60, SETTINGS)
    assert abs(unweighted.loss_history[0][-1] - reference[-1]) > 0.01 * reference[-1]  # the weights did count


def test_reweighting_multiplies_by_the_error_ratio_to_a_power_and_keeps_mean_one():
    network = _network(4)
    network.reweight_frames(np.array([1.0, 2.0, 3.0, 2.0]), 2.0)
    np.testing.assert_allclose(network.frame_weights, np.array([1.0, 4.0, 9.0, 4.0]) / 4.5)
    network.reweight_frames(np.array([2.0, 1.0, 1.0, 0.0]), 1.0)
    expected = np.array([1.0, 4.0, 9.0, 4.0]) * np.array([2.0, 1.0, 1.0, 0.0])
    np.testing.assert_allclose(network.frame_weights, expected / expected.mean())
    before = network.frame_weights.copy()
    network.reweight_frames(np.zeros(4), 2.0)  # nothing to weigh by: unchanged
    np.testing.assert_array_equal(network.frame_weights, before)


@pytest.mark.torch
def test_networks_trained_together_match_each_trained_alone():
    """Different lengths and output counts in one call (padded frames and outputs) change nothing but sum order."""
    pytest.importorskip("torch")
    shapes = [(40, 13), (75, 13), (75, 7), (120, 13)]
    omegas = [[1.0, 3.0]] * len(shapes)
    together = [_network(f, m) for f, m in shapes]
    train_round(together, omegas, 120, SETTINGS)
    for (frames, outputs), network in zip(shapes, together):
        alone = _network(frames, outputs)
        train_round([alone], omegas[:1], 120, SETTINGS)
        np.testing.assert_allclose(network.loss_history[0], alone.loss_history[0], rtol=1e-3)
        for a, b in zip(network.weights, alone.weights):
            assert a.shape == b.shape
            np.testing.assert_allclose(a, b, atol=1e-3)


def _first_stop(history: np.ndarray, settings: TrainingSettings, iterations: int) -> int:
    """The step at which Adam's stopping test first holds on ``history`` alone (the test :func:`_adam` runs: every
    50 steps after the warm-up and a window, the loss changed by at most the tolerance over the window), else
    ``iterations``. Done in float32 as the trainer does."""
    losses = history.astype(np.float32)
    warmup = max(1, int(round(settings.warmup_fraction * iterations)))
    for step in range(warmup + settings.stop_window, min(len(losses), iterations), 50):
        before, now = losses[step - settings.stop_window], losses[step]
        if abs(before - now) <= np.float32(settings.stop_tolerance) * before:
            return step
    return iterations


@pytest.mark.torch
def test_each_network_stops_on_its_own_loss_whatever_shares_its_batch():
    """Each network of a batch stops at the first check where its own loss meets the test, as it does alone.

    Together and alone differ only in the order of sums, so the loss curves start identical to rounding (below
    1e-6 relative over the first 300 steps, under every MKL, OpenBLAS and ATen kernel tried); but 1,500 Adam steps
    can amplify that rounding: on MKL's AVX and COMPATIBLE paths the 45-frame network's curves part between steps
    300 and 500 (8 % apart at step 500, 4 % at the end) and its output weights by up to 20 %. So the weights are not
    compared; what holds whatever the kernel is asserted: the early curve, the stop as a function of the network's
    own history (the first check that passes, none before it), and the same depth at the end. A network stopped by
    its neighbour (or with the batch) fails the stop rule on its own history; one trained on its neighbour's loss
    parts from its curve alone at the first steps.
    """
    pytest.importorskip("torch")
    stopping = TrainingSettings(**{**SETTINGS.__dict__, "stop_tolerance": 1e-2, "stop_window": 50})
    together = [_network(60, 5), _network(45, 5)]
    train_round(together, [[1.0], [1.0]], 1500, stopping)
    lengths = [len(n.loss_history[0]) for n in together]
    assert min(lengths) < 1501 and lengths[0] != lengths[1]  # the test fired, at different steps for the two
    for network in together:
        alone = _network(network.num_frames, 5)
        train_round([alone], [[1.0]], 1500, stopping)
        history, reference = network.loss_history[0], alone.loss_history[0]
        np.testing.assert_allclose(history[:300], reference[:300], rtol=1e-4)
        assert len(history) - 1 == _first_stop(history, stopping, 1500)
        assert len(reference) - 1 == _first_stop(reference, stopping, 1500)
        assert abs(len(reference) - len(history)) <= 100  # checks fall every 50 steps; measured: the same check
        assert 0.8 < history[-1] / reference[-1] < 1.25  # measured 0.96-1.0
        assert history[-1] < 0.05 * history[0]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(1, 3000), min_size=1, max_size=30), st.integers(0, 1000))
def test_frame_groups_cover_every_network_once_and_bound_padding(frames, overhead):
    groups = frame_groups(frames, overhead_frames=overhead, max_group_frames=8000)
    assert sorted(i for g in groups for i in g) == list(range(len(frames)))
    for group in groups:
        padded = len(group) * max(frames[i] for i in group)
        assert padded <= 8000 or len(group) == 1
    # Never worse than one group per network or (when it fits) one group for all.
    cost = sum(len(g) * max(frames[i] for i in g) + overhead for g in groups)
    assert cost <= sum(frames) + overhead * len(frames)
    if len(frames) * max(frames) <= 8000:
        assert cost <= len(frames) * max(frames) + overhead


def test_learning_rate_warms_up_then_decays_to_five_percent():
    rates = [learning_rate(s, 100, 20, 1.0) for s in range(100)]
    assert rates[0] == pytest.approx(1 / 20) and rates[19] == pytest.approx(1.0)
    assert all(a >= b for a, b in zip(rates[19:], rates[20:]))
    assert rates[-1] == pytest.approx(0.05 + 0.95 * 0.5 * (1 + math.cos(math.pi * 79 / 80)))


@pytest.mark.torch
@pytest.mark.parametrize("name", ["fourier-mlp-int", "fourier-mlp-dct"])
def test_encode_many_gives_each_clip_its_own_stream_and_refuses_bad_ones_alone(name):
    pytest.importorskip("torch")
    # Adam on eq. (3): L-BFGS's line search (and the L-inf passes, which weight each frame by the error of the pass
    # before) can grow a difference in the order of sums into another fit of about the same error; the test below
    # checks the default trainer for that.
    params = {**create(name).smoke_params, "optimizer": "adam", "solve_output": False, "reweight_passes": 0}
    codec = create(name, **params)
    good = [sinusoidal_motion(num_frames=f, seed=s) for f, s in ((50, 1), (80, 2))]
    results = codec.encode_many([good[0], "not a motion", good[1]])
    assert isinstance(results[1][0], TypeError)
    for motion, (data, stats) in zip(good, (results[0], results[2])):
        alone = create(name, **params)
        single = alone.decode(alone.encode(motion))
        batched = codec.decode(data)
        assert batched.positions.shape == motion.positions().shape
        assert stats["K"] == alone.last_encode_stats["K"]
        # Same network up to the order of sums: the decoded motions agree far inside the codec's error.
        assert np.abs(batched.positions - single.positions).max() < 0.05 * max(
            1e-3, np.abs(single.positions - motion.positions()).max()) + 0.05


@pytest.mark.torch
@pytest.mark.parametrize("name", ["fourier-mlp-int", "fourier-mlp-dct"])
def test_default_trainer_side_by_side_gives_each_clip_a_fit_as_good_as_alone(name):
    """The default (L-BFGS) trainer in lockstep: each clip's stream decodes to the error its stats report, the same
    K, and an error of the size the clip gets alone (a padding or batching mistake would be far off)."""
    pytest.importorskip("torch")
    params = create(name).smoke_params
    codec = create(name, **params)
    good = [sinusoidal_motion(num_frames=f, seed=s) for f, s in ((50, 1), (80, 2))]
    for motion, (data, stats) in zip(good, codec.encode_many(good)):
        alone = create(name, **params)
        alone.encode(motion)
        error = np.linalg.norm(codec.decode(data).positions - motion.positions(), axis=-1).max()
        assert error == pytest.approx(stats["encoder_max_err_cm"], rel=1e-5)  # the decoder sums block by block
        assert stats["K"] == alone.last_encode_stats["K"]
        assert error < 3 * alone.last_encode_stats["encoder_max_err_cm"] + 0.1


@pytest.mark.torch
def test_cuda_asked_for_without_a_gpu_is_one_clear_error():
    torch = pytest.importorskip("torch")
    if torch.cuda.is_available():
        pytest.skip("this machine has CUDA")
    codec = create("fourier-mlp-int", **{**create("fourier-mlp-int").smoke_params, "device": "cuda"})
    with pytest.raises(ValueError, match="device=cuda"):
        codec.encode(sinusoidal_motion(num_frames=30, seed=1))


LBFGS = TrainingSettings(**{**SETTINGS.__dict__, "optimizer": "lbfgs", "solve_output": True})


def _hidden(network: Network, omegas: list[float]) -> np.ndarray:
    """``[a2; 1]`` of the trained network, float64, shape (N, h + 1)."""
    from mocapbench.codecs.neural_fourier.codec import _elu, fourier_features

    w0, b0, w1, b1, _, _ = network.weights64()
    x = fourier_features(np.linspace(0, 1, network.num_frames), np.asarray(omegas))
    a2 = _elu(_elu(x @ w0.T + b0) @ w1.T + b1)
    return np.hstack([a2, np.ones((len(a2), 1))])


def _assert_output_layer_solved(network: Network, omegas: list[float]):
    """The stored output layer is the weighted least-squares fit on the final hidden activations (eq. (3) is
    separable per output, so the weights w drop out of each row's fit). Returns (hidden, best fit, its residual)."""
    hidden = _hidden(network, omegas)
    best, *_ = np.linalg.lstsq(hidden, network.targets, rcond=None)
    stored = np.hstack([network.weights64()[4], network.weights64()[5][:, None]]).T
    residual_best = np.linalg.norm((hidden @ best - network.targets) * network.loss_weights)
    residual_stored = np.linalg.norm((hidden @ stored - network.targets) * network.loss_weights)
    assert residual_stored <= residual_best * (1 + 1e-3)
    return hidden, best, residual_best


@pytest.mark.torch
def test_lbfgs_with_a_solved_output_layer_never_raises_the_loss_and_solves_the_output_layer():
    pytest.importorskip("torch")
    omegas = [1.0, 2.5]
    network = _network(90)
    train_round([network], [omegas], 40, LBFGS)
    history = network.loss_history[0]
    assert len(history) > 10
    assert np.all(np.diff(history) <= 0)  # a step is accepted only when the loss does not rise (Armijo)
    hidden, best, residual_best = _assert_output_layer_solved(network, omegas)
    # A wrong output layer (the least-squares fit, perturbed) is measurably worse: the check above can fail.
    assert np.linalg.norm((hidden @ (best * 1.05) - network.targets) * network.loss_weights) > residual_best * 1.001


@pytest.mark.torch
def test_lbfgs_reaches_in_a_tenth_of_the_steps_a_lower_loss_than_adam():
    pytest.importorskip("torch")
    omegas = [1.0, 2.5]
    adam, lbfgs = _network(120), _network(120)
    train_round([adam], [omegas], 600, SETTINGS)
    train_round([lbfgs], [omegas], 60, LBFGS)
    assert lbfgs.loss_history[0][-1] < adam.loss_history[0][-1]
    assert len(lbfgs.loss_history[0]) <= 61


@pytest.mark.torch
def test_lbfgs_networks_trained_together_match_each_trained_alone():
    """Padded frames and outputs change nothing in the least-squares output layer or the line search.

    Together and alone are equal in exact arithmetic and differ in the order of sums: the first loss (its output
    layer solved on the initial hidden layers) agrees to 2e-5 relative, bit for bit on some kernels, and each
    L-BFGS iteration amplifies the difference about tenfold (4e-4 at the second loss, 1-3 % at the third on MKL's
    AVX2, AVX and COMPATIBLE paths), after which a line search may accept on one side what it shrinks on the other
    (8-14 % apart at the end). So the first two losses are compared as tightly as that allows, then the end state:
    the same depth, far below the start, and the output layer the least-squares fit on the network's own hidden
    layers. A network trained with the padded frames in its loss, or on another's data, is off at the first loss.
    """
    pytest.importorskip("torch")
    omegas = [[1.0, 3.0]]
    shapes = [(40, 13), (75, 7), (120, 13)]
    together = [_network(f, m) for f, m in shapes]
    train_round(together, omegas * len(shapes), 15, LBFGS)
    for (frames, outputs), network in zip(shapes, together):
        alone = _network(frames, outputs)
        train_round([alone], omegas, 15, LBFGS)
        history, reference = network.loss_history[0], alone.loss_history[0]
        np.testing.assert_allclose(history[0], reference[0], rtol=2e-4)
        np.testing.assert_allclose(history[1], reference[1], rtol=5e-3)
        assert 0.67 < history[-1] / reference[-1] < 1.5  # measured 0.86-1.08
        assert history[-1] < 0.1 * history[0]  # measured 0.013-0.025
        assert network.weights[4].shape == alone.weights[4].shape
        _assert_output_layer_solved(network, omegas[0])


@pytest.mark.torch
def test_reduced_targets_keep_the_energy_and_leave_out_only_the_tolerated_part():
    torch = pytest.importorskip("torch")
    from mocapbench.codecs.neural_fourier.training import _reduced_targets

    rng = np.random.default_rng(3)
    # Two networks of 9 outputs and 50 frames: rank 3 and rank 5 plus components of energy ~1e-12 of the total.
    low = [rng.standard_normal((9, r)) @ rng.standard_normal((r, 50)) for r in (3, 5)]
    targets = torch.tensor(np.stack([t + 1e-6 * rng.standard_normal(t.shape) for t in low]), dtype=torch.float64)
    reduced, offset = _reduced_targets(torch, targets, 1e-8)
    assert reduced.shape == (2, 5, 50)  # the widest network's rank; the rank-3 one has zero rows
    assert torch.count_nonzero(reduced[0].abs().sum(dim=1) > 0) == 3
    total = targets.square().sum(dim=(1, 2))
    kept = reduced.square().sum(dim=(1, 2))
    np.testing.assert_allclose((kept + 2 * offset).numpy(), total.numpy(), rtol=1e-12)
    assert np.all(offset.numpy() <= 0.5e-8 * total.numpy()) and np.all(offset.numpy() > 0)
    # A tolerance of 0 keeps every nonzero component: nothing left out but exact zeros.
    full, none_left = _reduced_targets(torch, targets, 0.0)
    assert full.shape[1] == 9 and float(none_left.max()) < 1e-20 * float(total.min())


@pytest.mark.torch
def test_lbfgs_on_the_leading_components_fits_as_the_full_targets_and_solves_every_output():
    pytest.importorskip("torch")
    omegas = [1.0, 2.5]
    rng = np.random.default_rng(5)
    full, reduced = _network(90), _network(90)
    # 13 outputs of rank 4: the reduced fit works on 4 components.
    mix = rng.standard_normal((4, 13))
    for network in (full, reduced):
        network.targets = network.targets[:, :4] @ mix
    train_round([full], [omegas], 30, LBFGS)
    train_round([reduced], [omegas], 30, dataclasses.replace(LBFGS, rank_tolerance=1e-8))
    # The two problems are equal in exact arithmetic (the left-out energy is below float32's resolution of the loss),
    # so their L-BFGS trajectories start together and drift apart with rounding: the same loss at the start (to the
    # order of float32 sums), then a difference that grows about tenfold per iteration (1e-6, 1e-4, 1e-3 relative
    # on one Xeon under eight torch and MKL kernel choices, below 1 % through the sixth loss; the output layer's
    # Gram matrix summed in float64 instead of float32 gives the same losses bit for bit, so its rounding is not
    # the cause); after that a line search may accept on one side what it shrinks on the other, and the losses
    # differ by tens of percent. Both then end at the same depth: within a factor 2 of each other (0.77-1.08
    # measured), far below the start. Fitting the wrong components would be off at the first loss.
    reduced_losses, full_losses = reduced.loss_history[0], full.loss_history[0]
    np.testing.assert_allclose(reduced_losses[0], full_losses[0], rtol=1e-5)
    np.testing.assert_allclose(reduced_losses[:6], full_losses[:6], rtol=3e-2)
    assert 0.5 < reduced_losses[-1] / full_losses[-1] < 2.0
    assert reduced_losses[-1] < 1e-2 * reduced_losses[0]
    # The stored output layer covers all 13 outputs and is their least-squares fit on the final hidden layers.
    _assert_output_layer_solved(reduced, omegas)


@pytest.mark.torch
def test_lbfgs_bookkeeping_gives_the_same_bits_with_its_numbers_copied_to_the_device(monkeypatch):
    """L-BFGS keeps its per-network numbers in numpy and hands them to torch without copies on the CPU; on a GPU
    it copies them. Both ways do the same float32 operations, so the networks come out bit for bit the same
    (the copying way is the one a CUDA device takes, run here on the CPU)."""
    pytest.importorskip("torch")
    from mocapbench.codecs.neural_fourier import training

    shapes = [(60, 13), (90, 7)]
    omegas = [[1.0, 3.0]] * len(shapes)
    shared = [_network(f, m) for f, m in shapes]
    train_round(shared, omegas, 30, LBFGS)
    monkeypatch.setattr(training, "_host_shares_memory", lambda device: False)
    copied = [_network(f, m) for f, m in shapes]
    train_round(copied, omegas, 30, LBFGS)
    for a, b in zip(shared, copied):
        np.testing.assert_array_equal(a.loss_history[0], b.loss_history[0])
        for wa, wb in zip(a.weights, b.weights):
            np.testing.assert_array_equal(wa, wb)
        assert a.loss_history[0][-1] < a.loss_history[0][0]  # it trained


@pytest.mark.torch
def test_lbfgs_output_layer_is_solved_at_the_accepted_point_when_the_last_trial_is_rejected():
    """The stored output layer is the least-squares fit on the hidden layers L-BFGS accepted, whatever the last
    trial point was. A round ends after its last iteration's trial, which the line search may have rejected; the
    output layer solved there belongs to hidden layers the network does not keep (with it, the stored network's
    loss is not the loss the round reports, and can be far above it). Every round length from 1 to 12 at a
    first step large enough to be rejected: some of them end on a rejected trial on any CPU."""
    pytest.importorskip("torch")
    omegas = [1.0, 2.5]
    bold = dataclasses.replace(LBFGS, learning_rate=1.0)
    ended_on_a_rejection = 0
    for iterations in range(1, 13):
        network = _network(90)
        train_round([network], [omegas], iterations, bold)
        history = network.loss_history[0]
        ended_on_a_rejection += len(history) == iterations + 1 and history[-1] == history[-2]
        _assert_output_layer_solved(network, omegas)
    assert ended_on_a_rejection > 0  # the case under test happened
