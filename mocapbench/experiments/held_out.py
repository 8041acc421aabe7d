"""How a learned codec's model is obtained when codecs are compared on a user's clips: held out, shipped or paid for.

A codec with learned state (a PCA basis, LSDT bases, an entropy model) looks better the more its model has seen
of the clips it is measured on: fit on those very clips, a model can hold more bytes than the clips themselves
and still leave a tiny stream. So every ratio says where its model came from:

``out-of-sample`` (the default)
    Each clip is coded with a model fit on *other* clips of the same skeleton (same joint names and parents):
    leave-one-out when the skeleton has at most ``folds`` clips, else ``folds``-fold (clip ``i`` in fold
    ``i mod folds``, in name order). The stream's ratio is then what a user gets with a model fit beforehand on
    their own library; the model's bytes are shown beside it.
``in-sample`` (only when asked)
    One model per skeleton fit on all its clips, the measured clip included; the ratio then *includes* the model
    bytes (a decoder needs them, and they were fit on what they code).
no fit
    A skeleton with one clip has no other clip to fit on: the codec codes it as it would without a model of its
    own, with the model it ships (``shipped``: fit elsewhere, its bytes shown), its untrained mode (``untrained``:
    no model) or not at all (the codec's one-line reason, which names ``mocapbench fit``).

A fit that leaves the codec's model as it was (LSDT keeps its committed 31-joint bases unless ``basis=fit``) is
reported as ``shipped``: the state is compared before and after the fit.

Model bytes a run pays: one model per skeleton (the largest of its folds' models: a user ships one) plus each
shipped model once (:func:`models_bytes`).
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from mocapbench.codecs.base import Codec
    from mocapbench.motion import Motion

__all__ = ["POLICIES", "DEFAULT_FOLDS", "Fold", "ModelSource", "skeleton_key", "plan_folds", "FoldModels",
           "models_bytes", "describe_models"]

POLICIES = ("out-of-sample", "in-sample")
DEFAULT_FOLDS = 5


def skeleton_key(motion: Motion) -> str:
    """Clips share a model when their skeletons share joint names and parents (a short hash of both)."""
    skeleton = motion.skeleton
    text = "|".join(skeleton.names) + "#" + ",".join(str(int(p)) for p in skeleton.parents)
    return hashlib.sha1(text.encode()).hexdigest()[:10]


@dataclasses.dataclass(frozen=True)
class Fold:
    """The clips a fold's model is fit on and the clips it codes (indices into the compared motions)."""

    skeleton: str
    index: int
    train: tuple[int, ...]
    test: tuple[int, ...]
    scheme: str  # "leave-one-out", "5-fold", "in-sample" or "no fit"


def plan_folds(motions: Sequence[Motion], policy: str = "out-of-sample", folds: int = DEFAULT_FOLDS) -> list[Fold]:
    """The folds of a comparison: every clip is in exactly one fold's ``test``.

    Raises
    ------
    ValueError
        An unknown policy or fewer than 2 folds.
    """
    if policy not in POLICIES:
        raise ValueError(f"model policy must be one of {list(POLICIES)}, got {policy!r}.")
    if folds < 2:
        raise ValueError(f"--folds must be 2 or more, got {folds}.")
    groups: dict[str, list[int]] = {}
    for index, motion in enumerate(motions):
        groups.setdefault(skeleton_key(motion), []).append(index)
    out = []
    for key, members in groups.items():
        members = sorted(members, key=lambda i: motions[i].name)
        if policy == "in-sample":
            out.append(Fold(key, 0, tuple(members), tuple(members), "in-sample"))
        elif len(members) == 1:
            out.append(Fold(key, 0, (), tuple(members), "no fit"))
        elif len(members) <= folds:
            out += [Fold(key, i, tuple(m for m in members if m != clip), (clip,), "leave-one-out")
                    for i, clip in enumerate(members)]
        else:
            for i in range(folds):
                test = tuple(members[i::folds])
                out.append(Fold(key, i, tuple(m for m in members if m not in test), test, f"{folds}-fold"))
    return out


@dataclasses.dataclass(frozen=True)
class ModelSource:
    """Where the model that coded one clip came from, and its size.

    Attributes
    ----------
    mode : str
        ``"none"`` (the codec learns nothing), ``"out-of-sample"``, ``"in-sample"``, ``"shipped"`` or
        ``"untrained"``.
    model_key : str
        Identifies the model (``<skeleton>/<fold>`` or ``shipped/<joints>``); "" without a model.
    model_bytes : int
    train_clips : tuple of str
        Names of the clips the model was fit on (empty unless fit here).
    scheme : str
        The fold scheme (``"leave-one-out"``, ``"5-fold"``, ``"in-sample"``, ``"no fit"``).
    """

    mode: str
    model_key: str = ""
    model_bytes: int = 0
    train_clips: tuple[str, ...] = ()
    scheme: str = ""

    def row_fields(self) -> dict[str, Any]:
        """The columns a results row carries (``train_set`` in the words the report prints)."""
        if self.mode in ("out-of-sample", "in-sample"):
            what = f"{self.mode} ({self.scheme}): fit on {', '.join(self.train_clips)}"
        elif self.mode == "shipped":
            what = "shipped with the package (fit elsewhere)"
        else:
            what = {"untrained": "no model (the codec's untrained mode)", "none": "nothing to learn"}[self.mode]
        return {"model_source": self.mode, "model_key": self.model_key, "model_bytes": int(self.model_bytes),
                "model_scheme": self.scheme, "train_set": what, "model_train_clips": list(self.train_clips)}


def _state_fingerprint(codec: Codec) -> str | None:
    """A hash of the codec's learned state (None when it holds none of its own)."""
    try:
        state = codec.model_state()
    except Exception:  # noqa: BLE001 - NotFittedError, or a codec without model_state: no state of its own
        return None
    digest = hashlib.sha1()
    for key in sorted(state):
        digest.update(key.encode())
        digest.update(memoryview(state[key]).tobytes() if hasattr(state[key], "tobytes") else repr(state[key]).encode())
    return digest.hexdigest()


class FoldModels:
    """The fitted codec of each fold of one codec, fit once each, and the source of each coded clip.

    Parameters
    ----------
    name : str
        Registry name.
    motions : sequence of Motion
    folds : list of Fold
    fit : callable, optional
        ``(name, training motions) -> Codec``; default ``create(name).fit(training)``.
    """

    def __init__(self, name: str, motions: Sequence[Motion], folds: list[Fold],
                 fit: Callable[[str, list], Codec] | None = None) -> None:
        from mocapbench.codecs import CODECS, Codec, create

        self.name = name
        self.motions = motions
        self.learns = CODECS[name].fit is not Codec.fit
        self._fit = fit or (lambda codec_name, training: create(codec_name).fit(training))
        self._fold_of = {clip: fold for fold in folds for clip in fold.test}
        self._fitted: dict[tuple[str, int], Codec | None] = {}
        self._fresh = _state_fingerprint(create(name)) if self.learns else None

    def fitted(self, clip: int) -> Codec | None:
        """The codec fit for the fold that codes clip ``clip`` (None: no fit, or a fit that changed nothing)."""
        if not self.learns:
            return None
        fold = self._fold_of[clip]
        key = (fold.skeleton, fold.index)
        if key not in self._fitted:
            codec = self._fit(self.name, [self.motions[i] for i in fold.train]) if fold.train else None
            if codec is not None and _state_fingerprint(codec) == self._fresh:
                codec = None  # the fit kept the codec's own model (e.g. LSDT's committed bases)
            self._fitted[key] = codec
        return self._fitted[key]

    def source(self, clip: int, coded_with: Codec) -> ModelSource:
        """Where the model of ``coded_with`` (the codec that wrote clip ``clip``'s stream) came from."""
        if not self.learns:
            return ModelSource("none")
        fold = self._fold_of[clip]
        model_bytes = int(coded_with.model_bytes)
        if self.fitted(clip) is not None:
            mode = "in-sample" if fold.scheme == "in-sample" else "out-of-sample"
            names = tuple(self.motions[i].name for i in fold.train)
            return ModelSource(mode, f"{fold.skeleton}/{fold.index}", model_bytes, names, fold.scheme)
        if model_bytes > 0:
            joints = self.motions[clip].num_joints
            return ModelSource("shipped", f"shipped/{joints}", model_bytes, (), fold.scheme)
        return ModelSource("untrained", "", 0, (), fold.scheme)


def models_bytes(rows: Sequence[dict[str, Any]]) -> int:
    """Bytes of the models a run's rows used: per skeleton one fitted model (the largest fold's), shipped ones once.

    Rows carry :meth:`ModelSource.row_fields` (``model_key`` ``<skeleton>/<fold>`` or ``shipped/<joints>``).
    """
    by_model: dict[str, int] = {}
    for row in rows:
        key = row.get("model_key") or ""
        if key:
            by_model[key] = max(by_model.get(key, 0), int(row.get("model_bytes") or 0))
    per_skeleton: dict[str, int] = {}
    for key, size in by_model.items():
        owner = key if key.startswith("shipped/") else key.split("/", 1)[0]
        per_skeleton[owner] = max(per_skeleton.get(owner, 0), size)
    return sum(per_skeleton.values())


def describe_models(rows: Sequence[dict[str, Any]]) -> str:
    """The model cell of a codec's row: how its models were obtained and their bytes (``-`` without a model)."""
    modes = [row.get("model_source", "none") for row in rows]
    if not rows or all(mode == "none" for mode in modes):
        return "-"
    counts = {mode: modes.count(mode) for mode in dict.fromkeys(modes)}
    schemes = sorted({row.get("model_scheme", "") for row in rows} - {""})
    parts = []
    for mode, count in counts.items():
        text = f"{mode} x{count}" if len(counts) > 1 else mode
        if mode in ("out-of-sample", "in-sample") and schemes:
            text += f" ({', '.join(s for s in schemes if s != 'no fit')})"
        parts.append(text)
    return f"{', '.join(parts)}; {models_bytes(rows):,} B"
