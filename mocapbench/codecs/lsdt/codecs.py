"""The six registered spatial-transform codecs: the pipeline of :mod:`.pipeline` with learned (LSDT) or fixed
(DCT, Haar DWT) bases, in the frame (§3.1) or clip (§3.2) scheme of Hou et al. 2016."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import ClassVar, Sequence

import numpy as np

from mocapbench.codecs.base import NotFittedError, single_threaded_blas
from mocapbench.codecs.lsdt.bases import basis_fingerprint, load_committed_bases
from mocapbench.codecs.lsdt.pipeline import (
    ClipConfig,
    FrameConfig,
    LsdtClipConfig,
    LsdtFrameConfig,
    SpatialTransformCodec,
)
from mocapbench.codecs.lsdt.spatial import spatial_basis
from mocapbench.codecs.lsdt.training import train_lsdt_bases
from mocapbench.codecs.registry import register_codec
from mocapbench.motion import Motion

__all__ = [
    "DctSpatialClipCodec",
    "DctSpatialFrameCodec",
    "DwtSpatialClipCodec",
    "DwtSpatialFrameCodec",
    "LsdtClipCodec",
    "LsdtFrameCodec",
]

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
        produced from ``cmu_train`` by ``python -m mocapbench.benchmarks.lsdt.train``; refitting on the CMU
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
            with single_threaded_blas():  # the same bases whatever the machine's BLAS threads
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
        if not np.all(np.isfinite(bases)):
            raise ValueError(f"{self.name}: the bases hold a non-finite value.")
        identity = np.eye(bases.shape[1])
        if not max(np.abs(b @ b.T - identity).max() for b in bases) < 1e-10:
            raise ValueError(f"{self.name}: the bases must be orthogonal (||B Bᵀ − I|| < 1e-10).")
        self._trained = bases
        self._trained_by_joints = {**self._trained_by_joints, bases.shape[-1]: bases}
        return self

    def model_arrays(self, num_joints: int) -> dict:
        """The arrays a model file holds for a skeleton of ``num_joints`` joints (:mod:`.model_file` checks them)."""
        from mocapbench.codecs.model_file import ModelArray

        return {"bases": ModelArray("<f8", (3, num_joints, num_joints))}

    def model_state(self) -> dict[str, np.ndarray]:
        """The learned bases as arrays, for a model file or a sweep's shared state (:mod:`mocapbench.codecs.model_file`).

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
            raise NotFittedError(
                f"{self.name}: basis='fit' needs bases fit on clips of this skeleton: `mocapbench fit CLIPS... -o "
                f"MODEL.npz --codec {self.name} --set basis=fit`, then `--model MODEL.npz`."
            )
        return load_committed_bases(self.config.sparsity)

    def _fingerprint(self, num_joints: int) -> bytes:
        return basis_fingerprint(self._bases(num_joints))

    def _model_needed(self, num_joints: int, fingerprint: bytes) -> str:
        committed = load_committed_bases(self.config.sparsity)
        if committed.shape[-1] == num_joints and basis_fingerprint(committed) == fingerprint:
            return f"the committed LSDT bases shipped with the package ({num_joints} joints, {fingerprint.hex()})"
        return (f"LSDT bases {fingerprint.hex()} for {num_joints} joints, not the shipped ones: decode with "
                f"`mocapbench decompress --model MODEL.npz`, MODEL the `mocapbench fit` output it was coded with")

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

    def _model_needed(self, num_joints: int, fingerprint: bytes) -> str:
        return f"none (a fixed {self.transform.upper()} transform)"

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
class LsdtFrameCodec(_LsdtBases, SpatialTransformCodec):
    """LSDT frame-based codec (Hou et al. 2016, §3.1): zero latency, closed-loop prediction, learned B."""

    name = "lsdt-frame"
    scheme = "frame"

    @dataclass(frozen=True)
    class Config(LsdtFrameConfig):
        """Fields: see the module docstring and ``describe_fields()``."""


@register_codec
class LsdtClipCodec(_LsdtBases, SpatialTransformCodec):
    """LSDT clip-based codec (Hou et al. 2016, §3.2): temporal DCT over clips of L frames, then learned B."""

    name = "lsdt-clip"
    scheme = "clip"

    @dataclass(frozen=True)
    class Config(LsdtClipConfig):
        """Fields: see the module docstring and ``describe_fields()``."""


@register_codec
class DctSpatialFrameCodec(_FixedBases, SpatialTransformCodec):
    """Frame-based codec with the spatial 1-D DCT (Kwak & Bajic, ICME 2011, as compared in Hou et al. 2016)."""

    name = "dct-spatial-frame"
    scheme = "frame"
    transform = "dct"

    @dataclass(frozen=True)
    class Config(FrameConfig):
        """Fields: see the module docstring and ``describe_fields()``."""


@register_codec
class DctSpatialClipCodec(_FixedBases, SpatialTransformCodec):
    """Clip-based pipeline of Hou et al. 2016 with the spatial 1-D DCT in place of the LSDT."""

    name = "dct-spatial-clip"
    scheme = "clip"
    transform = "dct"

    @dataclass(frozen=True)
    class Config(ClipConfig):
        """Fields: see the module docstring and ``describe_fields()``."""


@register_codec
class DwtSpatialFrameCodec(_FixedBases, SpatialTransformCodec):
    """Frame-based pipeline of Hou et al. 2016 with a 3-level Haar DWT (PyWavelets) in place of the LSDT."""

    name = "dwt-spatial-frame"
    scheme = "frame"
    transform = "dwt"

    @dataclass(frozen=True)
    class Config(FrameConfig):
        """Fields: see the module docstring and ``describe_fields()``."""


@register_codec
class DwtSpatialClipCodec(_FixedBases, SpatialTransformCodec):
    """Clip-based pipeline of Hou et al. 2016 with a 3-level Haar DWT (PyWavelets) in place of the LSDT."""

    name = "dwt-spatial-clip"
    scheme = "clip"
    transform = "dwt"

    @dataclass(frozen=True)
    class Config(ClipConfig):
        """Fields: see the module docstring and ``describe_fields()``."""
