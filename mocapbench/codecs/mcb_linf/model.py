"""What ``mcb-linf`` learns from training motions: the PCA basis and the trained entropy model.

:class:`TrainedModel` holds the basis, the mean |DCT coefficient| of every (frequency band, channel), the token
counts of each coefficient class and of the refinement's lattice-point index; :func:`fit_model` learns them,
:func:`load_default_model` loads the one shipped with the package (fit on ``cmu_train``). The classes are
computed here too, identically for the encoder and the decoder (:func:`base_classes`, :func:`shifted_classes`).
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np
import scipy  # scipy.linalg loads on first use (see mocapbench.lazy_imports)

from mocapbench.codecs.mcb_linf.layers import (
    BAND_EDGES,
    band_of,
    base_positions,
    bcc_quantize,
    coefficient_channels,
    coefficient_frequencies,
    dead_zone_quantize,
    forward_dct,
    lattice_symbols,
    quantization_steps,
    REPRESENTATIONS,
    root_relative,
    to_signal,
)
from mocapbench.entropy.ans import TOKEN_COUNT, ClassTables, laplace_token_probabilities, tokenize
from mocapbench.motion import Motion

__all__ = [
    "MODEL_FILE",
    "NUM_CLASSES",
    "TrainedModel",
    "base_classes",
    "fit_model",
    "load_default_model",
    "shifted_classes",
]

MODEL_FILE = "models/mcb_linf_model_v2.npz"


# Trained entropy model: classes are quarter octaves of (mean |coefficient| / step), class _CLASS_ONE holding
# ratios near 1; the per-stream shift of a channel group is in [-_MAX_SHIFT, _MAX_SHIFT - 1] quarter octaves.
NUM_CLASSES = 80


_CLASS_ONE = 40


# Steps (cm) at which the training motions are quantized to count each class's tokens, and the weight (in
# pseudo-observations) of the Laplace prior each class's counts start from.
_TRAINING_STEPS_CM = tuple(2.0 ** (i / 2) for i in range(-8, 13))


_PRIOR_WEIGHT = 256.0


# Bounds at which the training motions are refined to count the lattice points' tokens, with the base step the
# rate search usually picks (2 eps), and the scale (in index units) of the Laplace prior of those counts.
_TRAINING_EPS_CM = (0.25, 0.5, 1.0, 2.0, 4.0)


_TRAINING_STEP_PER_EPS = 2.0


_LATTICE_PRIOR_SCALE = 16.0


@dataclass(frozen=True, eq=False)
class TrainedModel:
    """What ``mcb-linf`` learns from training motions: a spatial basis (PCA only) and the entropy model.

    Attributes
    ----------
    representation : str
        The representation the model was fit for (``"pca"``, ``"bone"`` or ``"absolute"``).
    num_joints : int
    clip_frames : int
        The DCT clip length the entropy model was fit for (other lengths work, less efficiently).
    basis : ndarray, shape (D, D), float64 (float32-exact), D = 3 (J - 1); empty unless ``"pca"``
        Rows are orthonormal PCA directions of the root-relative positions, by decreasing variance.
    mean : ndarray, shape (D,), float64 (float32-exact), cm; empty unless ``"pca"``
    band_scale : ndarray, shape (B, 3 J), float64 (float32-exact), cm
        Mean |DCT coefficient| of every frequency band and channel on the training motions.
    class_edges : ndarray, shape (K - 1,), float64
        Upper edges of the coefficient classes on the scale of ``band_scale / step``.
    tables : ClassTables
        Token counts of each of the K classes.
    lattice_tables : ClassTables
        Token counts (one class) of the refinement's lattice points, indexed by
        :func:`~mocapbench.codecs.mcb_linf.layers.lattice_points`.
    """

    representation: str
    num_joints: int
    clip_frames: int
    basis: np.ndarray
    mean: np.ndarray
    band_scale: np.ndarray
    class_edges: np.ndarray
    tables: ClassTables
    lattice_tables: ClassTables

    def arrays(self) -> dict[str, np.ndarray]:
        """The model as stored (float32 arrays, uint32 counts)."""
        return {
            "representation": np.array(REPRESENTATIONS.index(self.representation), dtype=np.uint8),
            "num_joints": np.array(self.num_joints, dtype=np.uint32),
            "clip_frames": np.array(self.clip_frames, dtype=np.uint32),
            "basis": self.basis.astype(np.float32),
            "mean": self.mean.astype(np.float32),
            "band_scale": self.band_scale.astype(np.float32),
            "class_edges": self.class_edges.astype(np.float64),
            "token_counts": self.tables.counts.astype(np.uint32),
            "lattice_counts": self.lattice_tables.counts.astype(np.uint32),
        }

    @classmethod
    def from_arrays(cls, stored) -> "TrainedModel":
        return cls(
            representation=REPRESENTATIONS[int(stored["representation"])],
            num_joints=int(stored["num_joints"]),
            clip_frames=int(stored["clip_frames"]),
            basis=stored["basis"].astype(np.float64),
            mean=stored["mean"].astype(np.float64),
            band_scale=stored["band_scale"].astype(np.float64),
            class_edges=stored["class_edges"].astype(np.float64),
            tables=ClassTables(stored["token_counts"].astype(np.int64)),
            lattice_tables=ClassTables(stored["lattice_counts"].astype(np.int64)),
        )

    @property
    def tag(self) -> int:
        """CRC32 of the stored arrays, written into every stream."""
        crc = 0
        for value in self.arrays().values():
            crc = zlib.crc32(np.ascontiguousarray(value).tobytes(), crc)
        return crc

    @property
    def stored_bytes(self) -> int:
        """Size as shipped (the arrays' bytes)."""
        return sum(value.nbytes for value in self.arrays().values())


def _fit_basis(motions: Sequence[Motion]) -> tuple[np.ndarray, np.ndarray]:
    """PCA of the root-relative joint positions (all frames pooled), rounded to float32: (basis, mean).

    Works from any number of frames (2 upwards): the basis is always square, D x D with D = 3 (J - 1).
    """
    data = np.concatenate([root_relative(m.positions()) for m in motions])
    mean = data.mean(axis=0)
    _, _, rows = np.linalg.svd(data - mean, full_matrices=False)
    if len(rows) < data.shape[1]:
        # Fewer frames than channels: the SVD gives only F directions; complete them to an orthonormal basis of
        # every channel (the remaining directions carry no training variance, their order does not matter).
        rows = np.vstack([rows, scipy.linalg.null_space(rows).T])
    # Round to float32 once: encoder and decoder then use bit-identical arrays, whatever saved them.
    return rows.astype(np.float32).astype(np.float64), mean.astype(np.float32).astype(np.float64)


def _class_edges() -> np.ndarray:
    """Upper edges of the quarter-octave classes: class k holds ratios near 2^((k - _CLASS_ONE) / 4)."""
    return 2.0 ** ((np.arange(1, NUM_CLASSES) - _CLASS_ONE - 0.5) / 4)


def base_classes(model: TrainedModel, frequencies, channels, steps) -> np.ndarray:
    """Class of every coefficient before the per-stream shifts: the quarter octave of band_scale / step."""
    ratio = model.band_scale[band_of(frequencies), channels] / steps
    return np.searchsorted(model.class_edges, ratio, side="right")


def shifted_classes(base_classes: np.ndarray, groups: np.ndarray, shifts: np.ndarray) -> np.ndarray:
    """Classes after each shift group's shift (quarter octaves), clipped to the table; uint8."""
    return np.clip(base_classes + shifts[groups], 0, NUM_CLASSES - 1).astype(np.uint8)


def fit_model(
    motions: Sequence[Motion],
    representation: str = "pca",
    clip_frames: int = 480,
    frequency_slope: float = 2.0,
    root_step_rel: float = 0.2,
    rounding: float = 0.45,
) -> TrainedModel:
    """Learn the basis (PCA) and the entropy model from ``motions``.

    The band scales are the mean |DCT coefficient| per (band, channel); the token counts of each class are those of
    the training coefficients quantized at the steps ``_TRAINING_STEPS_CM`` (with the given slope, root step and
    rounding), added to a Laplace prior of ``_PRIOR_WEIGHT`` pseudo-observations so that every token stays codable.

    Raises
    ------
    ValueError
        If the motions are empty or have different joint counts.
    """
    if not motions:
        raise ValueError("mcb-linf: fit needs at least one training motion, got none.")
    joints = {m.num_joints for m in motions}
    if len(joints) != 1:
        raise ValueError(f"mcb-linf: training motions must share one joint count, got {sorted(joints)}.")
    (num_joints,) = joints
    if representation == "pca":
        basis, mean = _fit_basis(motions)
        spatial = _Spatial(basis, mean)
    else:
        basis, mean, spatial = np.zeros((0, 0)), np.zeros(0), None
    channels_count = 3 * num_joints
    spectra = []
    for motion in motions:
        signal = to_signal(motion.positions(), motion.skeleton.parents, representation, spatial)
        frequencies = coefficient_frequencies(motion.num_frames, clip_frames, channels_count)
        channels = coefficient_channels(motion.num_frames, clip_frames, channels_count)
        spectra.append((forward_dct(signal, clip_frames), frequencies, channels))
    cells = len(BAND_EDGES) * channels_count
    band_sum, band_count = np.zeros(cells), np.zeros(cells)
    for spectrum, frequencies, channels in spectra:
        cell = band_of(frequencies) * channels_count + channels
        band_sum += np.bincount(cell, weights=np.abs(spectrum), minlength=cells)
        band_count += np.bincount(cell, minlength=cells)
    band_scale = (band_sum / np.maximum(band_count, 1)).reshape(len(BAND_EDGES), channels_count)
    band_scale = band_scale.astype(np.float32).astype(np.float64)
    band_scale = np.maximum(band_scale, np.float32(1e-6))  # never 0: the class ratio divides it
    uniform = ClassTables(np.ones((NUM_CLASSES, TOKEN_COUNT), dtype=np.int64))
    partial = TrainedModel(
        representation, num_joints, clip_frames, basis, mean, band_scale, _class_edges(), uniform, uniform
    )
    counts = np.zeros(NUM_CLASSES * TOKEN_COUNT, dtype=np.int64)
    for spectrum, frequencies, channels in spectra:
        for step in _TRAINING_STEPS_CM:
            steps = quantization_steps(frequencies, channels, step, frequency_slope, root_step_rel, clip_frames)
            tokens, _, _ = tokenize(dead_zone_quantize(spectrum, steps, rounding))
            classes = base_classes(partial, frequencies, channels, steps)
            counts += np.bincount(classes * TOKEN_COUNT + tokens, minlength=counts.size)
    counts = counts.reshape(NUM_CLASSES, TOKEN_COUNT)
    class_scales = 2.0 ** ((np.arange(NUM_CLASSES) - _CLASS_ONE) / 4)
    prior = np.array([laplace_token_probabilities(scale, rounding) for scale in class_scales]) * _PRIOR_WEIGHT
    tables = ClassTables(counts + np.maximum(1, np.rint(prior)).astype(np.int64))
    lattice_counts = np.zeros(TOKEN_COUNT, dtype=np.int64)
    for motion, (spectrum, frequencies, channels) in zip(motions, spectra):
        positions = motion.positions().reshape(-1, 3)
        for eps in _TRAINING_EPS_CM:
            step = _TRAINING_STEP_PER_EPS * eps
            steps = quantization_steps(frequencies, channels, step, frequency_slope, root_step_rel, clip_frames)
            base = base_positions(
                dead_zone_quantize(spectrum, steps, rounding), steps, motion.num_frames, motion.skeleton.parents,
                clip_frames, representation, partial,
            ).reshape(-1, 3)
            residual = positions - base
            lattice, _ = bcc_quantize(residual[np.sum(residual**2, axis=-1) > eps**2], eps)
            tokens, _, _ = tokenize(lattice_symbols(lattice)[0])
            lattice_counts += np.bincount(tokens, minlength=TOKEN_COUNT)
    lattice_prior = laplace_token_probabilities(_LATTICE_PRIOR_SCALE, 0.5) * _PRIOR_WEIGHT
    lattice_tables = ClassTables((lattice_counts + np.maximum(1, np.rint(lattice_prior)).astype(np.int64))[None])
    return TrainedModel(
        representation, num_joints, clip_frames, basis, mean, band_scale, _class_edges(), tables, lattice_tables
    )


@lru_cache(maxsize=1)
def load_default_model() -> TrainedModel:
    """The model shipped with the package (fit on ``cmu_train`` by ``mocapbench.benchmarks.mcb_linf.train``)."""
    with resources.files("mocapbench").joinpath(MODEL_FILE).open("rb") as file:
        return TrainedModel.from_arrays(np.load(file))


@dataclass(frozen=True)
class _Spatial:
    """The PCA part of a model, as :func:`to_signal` needs it."""

    basis: np.ndarray
    mean: np.ndarray
