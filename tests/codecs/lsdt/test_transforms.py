"""Spatial transforms (DCT, Haar DWT) and LSDT training (Hou et al. 2016, Algorithm 1)."""

from __future__ import annotations

import numpy as np
import pytest
import pywt
import scipy.fft

from mocapbench.codecs.lsdt.spatial import dct_matrix, haar_dwt_matrix, is_orthogonal, spatial_basis
from mocapbench.codecs.lsdt.training import lsdt_objective, orthogonal_step, train_lsdt, train_lsdt_bases, truncate
from mocapbench.synthetic import sinusoidal_motion


def _orthogonality_error(matrix):
    return np.abs(matrix @ matrix.T - np.eye(matrix.shape[0])).max()


# -- fixed transforms ---------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 3, 7, 8, 31, 32, 33])
def test_dct_matrix_is_orthonormal_and_matches_scipy(n):
    matrix = dct_matrix(n)
    assert _orthogonality_error(matrix) < 1e-12
    x = np.random.default_rng(n).normal(size=n)
    np.testing.assert_allclose(matrix @ x, scipy.fft.dct(x, norm="ortho"), atol=1e-12)


@pytest.mark.parametrize("n", [1, 2, 3, 5, 7, 8, 15, 16, 31, 33])
def test_haar_matrix_is_square_and_orthonormal_for_any_length(n):
    matrix = haar_dwt_matrix(n, levels=3)
    assert matrix.shape == (n, n)
    assert _orthogonality_error(matrix) < 1e-12


def test_haar_matrix_equals_pywavelets_wavedec_on_even_lengths():
    x = np.random.default_rng(0).normal(size=32)
    expected = np.concatenate(pywt.wavedec(x, "haar", mode="periodization", level=3))
    np.testing.assert_allclose(haar_dwt_matrix(32, levels=3) @ x, expected, atol=1e-12)


def test_haar_matrix_carries_the_odd_sample_to_the_next_level():
    # For n = 3 and one level: pairs (x0, x1), x2 passes through into the approximation.
    matrix = haar_dwt_matrix(3, levels=1)
    s = 1 / np.sqrt(2)
    np.testing.assert_allclose(matrix, [[s, s, 0], [0, 0, 1], [s, -s, 0]], atol=1e-15)


def test_haar_constant_signal_has_energy_only_in_the_approximation():
    coefficients = haar_dwt_matrix(32, levels=3) @ np.ones(32)
    assert np.abs(coefficients[4:]).max() < 1e-12  # 32 / 2**3 = 4 approximation coefficients


def test_spatial_basis_shapes_and_errors():
    assert spatial_basis("dct", 31).shape == (3, 31, 31)
    assert spatial_basis("dwt", 31).shape == (3, 31, 31)
    with pytest.raises(ValueError, match="Unknown spatial transform 'pca'"):
        spatial_basis("pca", 31)
    with pytest.raises(ValueError, match="transform length `n` >= 1, got 0"):
        dct_matrix(0)
    assert is_orthogonal(dct_matrix(5)) and not is_orthogonal(2 * dct_matrix(5)) and not is_orthogonal(np.ones((2, 3)))


# -- truncation (eq. 8) and the orthogonal step (eq. 11) ------------------------------------------------


@pytest.mark.parametrize("sparsity", [1, 2, 5, 8, 11, 30, 31])
def test_truncation_keeps_exactly_p_largest_entries_per_column(sparsity):
    coefficients = np.random.default_rng(sparsity).normal(size=(31, 200))
    truncated = truncate(coefficients, sparsity)
    assert np.all(np.count_nonzero(truncated, axis=0) == sparsity)
    kept = truncated != 0
    np.testing.assert_array_equal(truncated[kept], coefficients[kept])  # values are kept, not shrunk
    # Every kept magnitude is >= every dropped magnitude, column by column.
    magnitude = np.abs(coefficients)
    smallest_kept = np.where(kept, magnitude, np.inf).min(axis=0)
    largest_dropped = np.where(kept, -np.inf, magnitude).max(axis=0)
    assert np.all(smallest_kept >= largest_dropped)


def test_truncation_rejects_bad_sparsity():
    with pytest.raises(ValueError, match=r"sparsity `P` in \[1, J=4\], got 5"):
        truncate(np.ones((4, 3)), 5)
    with pytest.raises(ValueError, match="sparsity"):
        truncate(np.ones((4, 3)), 0)


def test_orthogonal_step_solves_the_procrustes_problem():
    rng = np.random.default_rng(3)
    frames = rng.normal(size=(8, 100))
    sparse = truncate(rng.normal(size=(8, 100)), 3)
    basis = orthogonal_step(frames, sparse)
    assert _orthogonality_error(basis) < 1e-12
    best = np.trace(basis @ frames @ sparse.T)
    for _ in range(50):  # no random orthogonal matrix does better on eq. (10)
        q, _ = np.linalg.qr(rng.normal(size=(8, 8)))
        assert np.trace(q @ frames @ sparse.T) <= best + 1e-9


# -- Algorithm 1 ------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def synthetic_frames():
    """x-coordinates of 900 synthetic frames, (J, N) = (31, 900), cm."""
    positions = np.concatenate([sinusoidal_motion(num_frames=300, seed=seed).positions() for seed in (11, 12, 13)])
    return positions[:, :, 0].T


@pytest.mark.parametrize("init", ["dct", "dwt"])
def test_training_keeps_b_orthogonal_and_never_increases_the_objective(synthetic_frames, init):
    result = train_lsdt(synthetic_frames, 8, init=init, max_iterations=150, tol=0.0)
    assert _orthogonality_error(result.basis) < 1e-10
    steps = np.diff(result.objective)
    assert np.all(steps <= 1e-9 * result.objective[:-1]), f"objective increased by {steps.max()}"
    assert result.objective[-1] < 0.5 * result.objective[0]  # it does learn something
    # The recorded final value is the objective of the returned basis.
    assert lsdt_objective(result.basis, synthetic_frames, 8) == pytest.approx(result.objective[-1], rel=1e-9)


def test_training_recovers_a_planted_sparse_basis():
    rng = np.random.default_rng(7)
    planted, _ = np.linalg.qr(rng.normal(size=(12, 12)))
    codes = truncate(rng.normal(size=(12, 3000)) * rng.uniform(0.1, 10, size=(12, 1)), 3)
    frames = planted.T @ codes  # every frame is exactly 3-sparse in the planted basis
    result = train_lsdt(frames, 3, init="dct", max_iterations=500)
    dct_objective = lsdt_objective(dct_matrix(12), frames, 3)
    assert result.objective[-1] < 1e-3 * dct_objective


def test_training_stops_at_convergence_and_reports_it(synthetic_frames):
    result = train_lsdt(synthetic_frames, 8, max_iterations=5000, tol=1e-6)
    assert result.converged and result.iterations < 5000
    assert len(result.objective) == result.iterations + 1
    capped = train_lsdt(synthetic_frames, 8, max_iterations=3, tol=0.0)
    assert capped.iterations == 3


def test_train_lsdt_bases_gives_one_orthogonal_basis_per_coordinate():
    positions = sinusoidal_motion(num_frames=200, seed=5).positions()
    bases, results = train_lsdt_bases(positions, 5, max_iterations=20)
    assert bases.shape == (3, 31, 31) and len(results) == 3
    assert all(_orthogonality_error(b) < 1e-10 for b in bases)
    assert not np.allclose(bases[0], bases[1])  # x and y get their own transform


def test_training_rejects_bad_input():
    with pytest.raises(ValueError, match=r"shape \(J, N\)"):
        train_lsdt(np.ones(5), 2)
    with pytest.raises(ValueError, match="non-finite"):
        train_lsdt(np.full((4, 4), np.nan), 2)
    with pytest.raises(ValueError, match="Unknown LSDT initialization 'pca'"):
        train_lsdt(np.ones((4, 4)), 2, init="pca")
    with pytest.raises(ValueError, match="must be orthogonal"):
        train_lsdt(np.ones((4, 4)), 2, init=2 * np.eye(4))
    with pytest.raises(ValueError, match=r"shape \(N, J, 3\)"):
        train_lsdt_bases(np.ones((4, 5)), 2)
