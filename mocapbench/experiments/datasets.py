"""Datasets of a benchmark run, from a ``configs/dataset/*.yaml`` node: the clips to measure and the training set.

A dataset config is a plain mapping with a ``kind``:

``synthetic``
    ``clips: {seeds: [...], num_frames: F}`` sinusoidal motions (:func:`mocapbench.synthetic.sinusoidal_motion`);
    ``train`` the same with other seeds. Needs no file: the embedded default of ``make run``.
``cmu``
    ``split`` (``cmu_train``, ``cmu_test``, ``cmu_all``) or an explicit ``clips`` list (e.g. ``[09_06]``) read
    from ASF/AMC under ``data_dir``; ``train`` names a split or a clip list in the same form.
``folder``
    Every ``*.bvh`` and ``*.amc`` file in the folder ``path`` (:func:`mocapbench.datasets.cmu.load_folder`: an AMC
    is read on the folder's ASF; ``length_unit_cm``, ``drop_first_frame`` and ``fps`` are passed on); ``train``
    another folder (``train: {path: ...}``) or ``null`` to fit learned codecs on the measured clips themselves
    (stated in the report as in-sample).

Loaded clips are cached per process, so the jobs of a sweep that a worker runs one after another parse them once.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path
from typing import Any, Mapping

from mocapbench.motion import Motion

__all__ = ["DatasetError", "load_clips", "load_training", "describe_dataset", "describe_training", "cmu_used"]


class DatasetError(ValueError):
    """A dataset config is malformed (the message names the key and what was expected)."""


def _plain(node: Any) -> Any:
    """An OmegaConf node or a mapping as plain Python (lists and dicts), for hashing and caching."""
    try:
        from omegaconf import OmegaConf

        if OmegaConf.is_config(node):
            return OmegaConf.to_container(node, resolve=True)
    except ImportError:  # pragma: no cover - hydra is a dependency
        pass
    return node


def _key(node: Any) -> str:
    return json.dumps(_plain(node), sort_keys=True, default=str)


def _require(spec: Mapping[str, Any], key: str, where: str) -> Any:
    if key not in spec or spec[key] is None:
        raise DatasetError(f"dataset {where}: missing required key `{key}` (got keys {sorted(spec)}).")
    return spec[key]


def load_clips(spec: Mapping[str, Any]) -> list[Motion]:
    """The clips to measure.

    Parameters
    ----------
    spec : mapping
        A ``configs/dataset/*.yaml`` node (``kind`` plus its keys).

    Returns
    -------
    list of Motion
        In a fixed order (the config's order; files sorted by name).

    Raises
    ------
    DatasetError
        Malformed config or an empty dataset.
    mocapbench.datasets.cmu.DataNotFoundError
        A CMU dataset whose data folder is missing.
    """
    return list(_load_cached(_key(spec)))


def load_training(spec: Mapping[str, Any]) -> list[Motion]:
    """The motions that codecs with learned state are fit on (``spec["train"]``; the clips themselves if null)."""
    spec = _plain(spec)
    train = spec.get("train")
    if train is None:
        return load_clips(spec)
    return list(_load_cached(_key(_inherit(spec, train))))


def describe_dataset(spec: Mapping[str, Any]) -> str:
    """One line naming what ``spec`` measures, for the results row and the report."""
    return _describe(_plain(spec))


def describe_training(spec: Mapping[str, Any]) -> str:
    """One line naming the training set of ``spec``, flagged as in-sample when it is the measured clips."""
    spec = _plain(spec)
    train = spec.get("train")
    if train is None:
        return f"in-sample: {_describe(spec)}"
    return _describe(_inherit(spec, train))


def cmu_used(spec: Mapping[str, Any]) -> bool:
    """Whether ``spec`` (or its training set) reads CMU clips, so the report must carry CMU's acknowledgement."""
    spec = _plain(spec)
    kinds = {spec.get("kind")}
    if isinstance(spec.get("train"), Mapping):
        kinds.add(spec["train"].get("kind", spec.get("kind")))
    return "cmu" in kinds


def _inherit(parent: Mapping[str, Any], train: Any) -> dict[str, Any]:
    """The training spec: a mapping that inherits ``kind`` and ``data_dir`` from the measured dataset."""
    if not isinstance(train, Mapping):
        raise DatasetError(f"dataset {parent.get('name')!r}: `train` must be a mapping or null, got {train!r}.")
    merged = {key: parent[key] for key in ("kind", "data_dir") if key in parent}
    merged.update(train)
    merged["name"] = train.get("name", f"{parent.get('name', 'dataset')}-train")
    merged["train"] = None
    return merged


def _describe(spec: Mapping[str, Any]) -> str:
    kind = spec.get("kind")
    if kind == "synthetic":
        clips = spec.get("clips", {})
        return f"synthetic sinusoidal, seeds {list(clips.get('seeds', []))}, {clips.get('num_frames')} frames each"
    if kind == "cmu":
        what = spec.get("split") or ",".join(str(c) for c in spec.get("clips") or [])
        return f"CMU ASF/AMC {what}"
    if kind == "folder":
        return f"folder {spec.get('path')}"
    return str(spec.get("name", kind))


@lru_cache(maxsize=16)
def _load_cached(key: str) -> tuple[Motion, ...]:
    spec = json.loads(key)
    where = repr(spec.get("name", "?"))
    kind = _require(spec, "kind", where)
    if kind == "synthetic":
        motions = _synthetic(spec, where)
    elif kind == "cmu":
        motions = _cmu(spec, where)
    elif kind == "folder":
        motions = _folder(spec, where)
    else:
        raise DatasetError(f"dataset {where}: `kind` must be one of ['synthetic', 'cmu', 'folder'], got {kind!r}.")
    if not motions:
        raise DatasetError(f"dataset {where}: no clips.")
    return tuple(motions)


def _synthetic(spec: Mapping[str, Any], where: str) -> list[Motion]:
    from mocapbench.synthetic import sinusoidal_motion

    clips = _require(spec, "clips", where)
    seeds = _require(clips, "seeds", where + ".clips")
    extra = {key: value for key, value in clips.items() if key != "seeds"}
    return [sinusoidal_motion(seed=int(seed), **extra) for seed in seeds]


def _resolve_data_dir(value: Any) -> Path | None:
    """``data_dir`` of the config; a relative path is taken from the working directory, else the repository root."""
    if value is None:
        return None
    path = Path(str(value)).expanduser()
    if not path.is_absolute() and not path.exists():
        from_repo = Path(__file__).resolve().parents[2] / path
        if from_repo.exists():
            return from_repo
    return path


def _cmu(spec: Mapping[str, Any], where: str) -> list[Motion]:
    from mocapbench.datasets import cmu

    data_dir = cmu.cmu_data_dir(_resolve_data_dir(spec.get("data_dir")))
    split, clips = spec.get("split"), spec.get("clips")
    if (split is None) == (clips is None):
        raise DatasetError(
            f"dataset {where}: give exactly one of `split` or `clips`, got split={split!r}, clips={clips!r}."
        )
    fmt = str(spec.get("format", "amc"))
    if split is not None:
        return list(cmu.load_split(str(split), fmt=fmt, data_dir=data_dir))
    return [cmu.load_clip(str(clip), fmt=fmt, data_dir=data_dir) for clip in clips]


def _folder(spec: Mapping[str, Any], where: str) -> list[Motion]:
    from mocapbench.datasets import cmu

    path = Path(str(_require(spec, "path", where))).expanduser()
    return list(cmu.load_folder(path, length_unit_cm=float(spec.get("length_unit_cm", 1.0)),
                                drop_first_frame=bool(spec.get("drop_first_frame", False)),
                                fps=float(spec.get("fps", 120.0))))
