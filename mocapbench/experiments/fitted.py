"""Learned state of a sweep: fit once per (codec config, training set), stored beside the sweep, shared by shards.

Every job of a sweep used to call ``codec.fit(training motions)``: ``mcb-linf`` refit its model on ``cmu_train``
in each of its jobs (half of its wall time) and got a model tag different from the shipped model's, so its
streams needed that job's refit model to decode. Now :func:`prepare` gives a job's codec its learned state by,
in order:

1. nothing, when the config learns nothing (``lsdt-*`` with the committed bases on a CMU or synthetic training
   set, whose skeleton they fit; on a folder they learn bases for its other skeletons; ``mcb-linf`` with
   ``representation`` not ``pca`` and ``entropy`` not ``trained``, every codec without ``fit``);
2. the **shipped model**, when the codec config and the training set are the ones it was fit with (``mcb-linf``
   with its default fit settings on the ``cmu_train`` split: the streams carry the shipped model's tag);
3. the state stored at ``<sweep dir>/fitted/<codec>-<key>.npz``, ``key`` a hash of the fit settings and the
   training set's spec, written by the first shard that needed it (an exclusive ``flock`` on a lock file beside it
   keeps the other shards waiting instead of fitting the same thing again; the file is written to a temporary
   name and renamed, so a reader never sees half of it);
4. for a codec with ``fit`` but no adapter here (a codec added later), ``fit`` in the job, as before.

An adapter says which config fields the fit depends on, how to export the state as arrays and load it back;
``npz`` files are read with ``allow_pickle=False``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import logging
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

import numpy as np

from mocapbench.codecs.base import Codec

__all__ = ["Adapter", "ADAPTERS", "prepare", "FITTED_DIR"]

log = logging.getLogger(__name__)

FITTED_DIR = "fitted"


@dataclass(frozen=True)
class Adapter:
    """How the sweep shares one codec's learned state.

    Attributes
    ----------
    fields : tuple of str
        Config fields the fit depends on (the rest, e.g. a quantization step, share one fit).
    needs_fit : callable(codec, training spec) -> bool
    export : callable(codec) -> dict of str to ndarray
    load : callable(codec, arrays) -> None
    shipped : callable(codec, training spec) -> bool
        Whether the package's shipped state is exactly what fitting this config on this training set gives.
    """

    fields: tuple[str, ...]
    needs_fit: Callable[[Codec, Mapping[str, Any]], bool]
    export: Callable[[Codec], dict[str, np.ndarray]]
    load: Callable[[Codec, Mapping[str, np.ndarray]], None]
    shipped: Callable[[Codec, Mapping[str, Any]], bool] = lambda codec, train: False


def _is_cmu_train(train: Mapping[str, Any]) -> bool:
    """The ``cmu_train`` clips read from ASF/AMC (the set every shipped model was fit on), by split or by name."""
    from mocapbench.datasets.cmu import SPLITS

    if str(train.get("format", "amc")) != "amc" or train.get("kind") not in ("cmu", "cmu_tree"):
        return False
    if train.get("split") is not None:
        return train.get("split") == "cmu_train" and train.get("kind") == "cmu"
    clips = [str(c) for c in train.get("clips") or []]
    return sorted(clips) == sorted(SPLITS["cmu_train"]) and not train.get("exclude")


_MCB_FIT_FIELDS = ("representation", "clip_frames", "frequency_slope", "root_step_rel", "rounding")


def _mcb_needs_fit(codec: Codec) -> bool:
    from mocapbench.codecs.mcb_linf import codec as mcb_linf

    return mcb_linf._needs_model(codec.config.representation, codec.config.entropy)


def _mcb_shipped(codec: Codec, train: Mapping[str, Any]) -> bool:
    """The shipped model was fit by ``benchmarks.mcb_linf.train`` with the default settings on ``cmu_train``."""
    defaults = type(codec.config)()
    same = all(getattr(codec.config, f) == getattr(defaults, f) for f in _MCB_FIT_FIELDS)
    return same and codec.config.representation == "pca" and _is_cmu_train(train)


def _load_state(codec: Codec, arrays: Mapping[str, np.ndarray]) -> None:
    """The codec's own loader (every model of a training set of several skeletons, see ``model_state``)."""
    codec.load_model_state(arrays)


def _lsdt_needs_fit(codec: Codec, train: Mapping[str, Any]) -> bool:
    """basis='fit', or a training set that may hold other skeletons than the committed bases' 31-joint one (a
    folder): there ``fit`` learns bases for every other skeleton (an empty state when there is none)."""
    return codec.config.basis == "fit" or train.get("kind") not in ("synthetic", "cmu", "cmu_tree")


_LSDT = Adapter(
    fields=("sparsity", "train_iterations", "basis"),
    needs_fit=_lsdt_needs_fit,
    export=lambda codec: codec.model_state(),
    load=_load_state,
)

ADAPTERS: dict[str, Adapter] = {
    "mcb-linf": Adapter(
        fields=_MCB_FIT_FIELDS,
        needs_fit=lambda codec, train: _mcb_needs_fit(codec),
        export=lambda codec: codec.model_state(),
        load=_load_state,
        shipped=_mcb_shipped,
    ),
    "lsdt-frame": _LSDT,
    "lsdt-clip": _LSDT,
    # mcb-rot's prior (the training set's rigs, mocapbench.codecs.mcb_rot.prior): a stream of a rig it holds names
    # it; the coding itself learns nothing, so one fit serves every eps.
    "mcb-rot": Adapter(
        fields=("static_root",),
        needs_fit=lambda codec, train: True,
        export=lambda codec: codec.model_state(),
        load=_load_state,
    ),
}


def _learns(codec: Codec) -> bool:
    return type(codec).fit is not Codec.fit


def _training_key(train: Mapping[str, Any]) -> dict[str, Any]:
    return {key: value for key, value in train.items() if key not in ("name", "train")}


def state_key(codec: Codec, adapter: Adapter, train: Mapping[str, Any]) -> str:
    """Hash of what the fit depends on: codec name, the adapter's config fields, the training set's spec."""
    config = dataclasses.asdict(codec.config)
    text = json.dumps({"codec": codec.name, "fit": {f: config.get(f) for f in adapter.fields},
                       "train": _training_key(train)}, sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:16]


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    """An exclusive ``flock`` on ``path`` (created); a file system without locks gives no lock, not an error."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            import fcntl

            fcntl.flock(fd, fcntl.LOCK_EX)
        except (ImportError, OSError) as error:  # pragma: no cover - NFS without lockd, Windows
            log.warning("no lock on %s (%s): shards may fit the same state at once", path, error)
        yield
    finally:
        os.close(fd)


def prepare(codec: Codec, dataset: Mapping[str, Any], folder: Path | None,
            load_training: Callable[[], list] | None = None) -> dict[str, Any]:
    """Give ``codec`` its learned state for ``dataset`` (see the module docstring); return facts for the row.

    Parameters
    ----------
    codec : Codec
    dataset : mapping
        The job's dataset spec (its ``train`` names the training set).
    folder : Path or None
        Where the sweep keeps fitted state (``<sweep dir>/fitted``); None fits in the job.
    load_training : callable, optional
        Returns the training motions (default: :func:`mocapbench.experiments.datasets.load_training`).

    Returns
    -------
    dict
        ``fit_s`` (seconds this job spent fitting or loading), ``fit_source`` (``none``, ``shipped``,
        ``sweep`` (loaded from the sweep's folder), ``fitted`` (fit by this job and stored) or ``job``
        (fit by this job, not shared)) and ``fit_file`` (the stored state, if any).
    """
    from mocapbench.experiments import datasets

    def training() -> list:
        return load_training() if load_training is not None else datasets.load_training(dataset)

    start = time.perf_counter()
    if not _learns(codec):
        return {"fit_s": 0.0, "fit_source": "none", "fit_file": None}
    adapter = ADAPTERS.get(codec.name)
    if adapter is None or folder is None:
        codec.fit(training())
        return {"fit_s": time.perf_counter() - start, "fit_source": "job", "fit_file": None}
    train = datasets.training_spec(dataset)
    if not adapter.needs_fit(codec, train):
        return {"fit_s": 0.0, "fit_source": "none", "fit_file": None}
    if adapter.shipped(codec, train):
        return {"fit_s": 0.0, "fit_source": "shipped", "fit_file": None}
    path = Path(folder) / f"{codec.name}-{state_key(codec, adapter, train)}.npz"
    with _locked(path.with_suffix(".lock")):
        if path.exists():
            with np.load(path, allow_pickle=False) as stored:
                adapter.load(codec, {key: stored[key] for key in stored.files})
            source = "sweep"
        else:
            codec.fit(training())
            tmp = path.with_name(f".{path.stem}.tmp-{os.getpid()}.npz")
            np.savez(tmp, **adapter.export(codec))
            os.replace(tmp, path)
            source = "fitted"
    return {"fit_s": time.perf_counter() - start, "fit_source": source, "fit_file": str(path)}
