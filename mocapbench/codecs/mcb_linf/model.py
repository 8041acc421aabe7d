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
    "check_stored",
    "load_default_model",
    "shifted_classes",
    "stored_layout",
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
        """The model of stored arrays (:meth:`arrays`), checked first (:func:`check_stored`)."""
        check_stored(stored)
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


def stored_layout(representation: str, num_joints: int) -> dict[str, tuple[str, tuple[int, ...]]]:
    """dtype and shape of every stored array (:meth:`TrainedModel.arrays`) of a model for ``num_joints`` joints."""
    size = 3 * (num_joints - 1) if representation == "pca" else 0
    return {
        "representation": ("|u1", ()),
        "num_joints": ("<u4", ()),
        "clip_frames": ("<u4", ()),
        "basis": ("<f4", (size, size)),
        "mean": ("<f4", (size,)),
        "band_scale": ("<f4", (len(BAND_EDGES), 3 * num_joints)),
        "class_edges": ("<f8", (NUM_CLASSES - 1,)),
        "token_counts": ("<u4", (NUM_CLASSES, TOKEN_COUNT)),
        "lattice_counts": ("<u4", (1, TOKEN_COUNT)),
    }


#: Largest |mean| of a stored basis' centring, cm (the codecs' coordinate range), and the largest departure of a
#: stored basis from orthonormality (float32 rounding of an orthonormal basis is ~1e-7).
_MAX_MEAN_CM = 1e6
_ORTHONORMAL_TOLERANCE = 1e-4
_MAX_CLIP_FRAMES = 1 << 16


def check_stored(stored) -> None:
    """Refuse stored arrays that no fit can have made: a corrupted or hostile model (one line, ValueError).

    Checked: every array present with its dtype and shape (:func:`stored_layout`), a known representation, a
    clip length in 1..65536, finite values, an orthonormal basis (within float32 rounding), a centring within
    the coordinate range, band scales at least the fit's floor (1e-6 cm), the fixed class edges, token counts
    >= 1. What cannot be told from a fit's (a rescaled band scale, other counts) only costs rate: the encoder
    checks its own stream.
    """
    missing = [key for key in stored_layout("pca", 1) if key not in stored]
    if missing:
        raise ValueError(f"mcb-linf: the model has no {missing[0]!r} array.")
    code = np.asarray(stored["representation"])
    if code.shape != () or code.dtype.kind not in "iu" or not 0 <= int(code) < len(REPRESENTATIONS):
        raise ValueError(
            f"mcb-linf: the model's representation code is {code!r}; expected 0..{len(REPRESENTATIONS) - 1}."
        )
    joints = np.asarray(stored["num_joints"])
    if joints.shape != () or joints.dtype.kind not in "iu" or not 1 <= int(joints) <= 4096:
        raise ValueError(f"mcb-linf: the model's joint count is {joints!r}; expected 1..4096.")
    for key, (dtype, shape) in stored_layout(REPRESENTATIONS[int(code)], int(joints)).items():
        value = np.asarray(stored[key])
        if value.dtype != np.dtype(dtype) or value.shape != shape:
            raise ValueError(f"mcb-linf: the model's {key} is {value.shape} of {value.dtype}; expected {shape} of "
                             f"{np.dtype(dtype)}.")
        if value.dtype.kind == "f" and not np.all(np.isfinite(value)):
            raise ValueError(f"mcb-linf: the model's {key} holds a non-finite value.")
    clip_frames = int(stored["clip_frames"])
    if not 1 <= clip_frames <= _MAX_CLIP_FRAMES:
        raise ValueError(f"mcb-linf: the model's clip length is {clip_frames}; expected 1..{_MAX_CLIP_FRAMES}.")
    basis = np.asarray(stored["basis"], dtype=np.float64)
    if basis.size:
        departure = float(np.abs(basis @ basis.T - np.eye(len(basis))).max())
        if not departure < _ORTHONORMAL_TOLERANCE:
            raise ValueError(f"mcb-linf: the model's basis is not orthonormal (max |B Bᵀ - I| = {departure:.3g}).")
    if not np.abs(np.asarray(stored["mean"], dtype=np.float64)).max(initial=0.0) <= _MAX_MEAN_CM:
        raise ValueError(f"mcb-linf: the model's mean exceeds {_MAX_MEAN_CM:g} cm.")
    if not np.asarray(stored["band_scale"]).min() >= np.float32(1e-6):
        raise ValueError("mcb-linf: the model's band scales must be >= 1e-6 cm (the fit's floor).")
    if not np.allclose(stored["class_edges"], _class_edges(), rtol=1e-12, atol=0.0):
        raise ValueError("mcb-linf: the model's class edges are not the quarter octaves every model uses.")
    for key in ("token_counts", "lattice_counts"):
        if not np.asarray(stored[key]).min() >= 1:
            raise ValueError(f"mcb-linf: the model's {key} must all be >= 1.")


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
