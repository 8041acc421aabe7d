"""Datasets of a benchmark run, from a ``configs/dataset/*.yaml`` node: the clips to measure and the training set.

A dataset config is a plain mapping with a ``kind``:

``synthetic``
    ``clips: {seeds: [...], num_frames: F}`` sinusoidal motions (:func:`mocapbench.synthetic.sinusoidal_motion`);
    ``train`` the same with other seeds. Needs no file: the embedded default of ``make run``.
``cmu``
    ``split`` (``cmu_train``, ``cmu_test``, ``cmu_all``) or an explicit ``clips`` list (e.g. ``[09_06]``) read
    from ASF/AMC under ``data_dir``; ``train`` names a split or a clip list in the same form.
``folder``
    Every ``*.bvh`` and ``*.amc`` file in the folder ``path``, each read and checked by
    :func:`mocapbench.io.formats.read_motion` as the command line reads it (``units`` (or ``length_unit_cm``),
    ``up``, ``drop_first_frame`` and ``fps`` passed on, the file's ``FILE.units`` sidecar read when ``units`` is
    null, the unit and up-axis checks logged, or fatal with ``strict_units: true``); ``train``
    another folder (``train: {path: ...}``) or ``null`` to fit learned codecs on the measured clips themselves
    (stated in the report as in-sample).
``bandai``
    The Bandai Namco Research Motion Dataset 1 (:mod:`mocapbench.datasets.bandai`: a game rig, 30 fps): ``split``
    ``bandai_test``, ``bandai_train`` or ``bandai_all`` (the manifest's ``split`` column) read from BVH under
    ``data_dir`` (null: ``$MOCAPBENCH_BANDAI_DIR``, else ``../shared/data/bandai``); ``train`` names another split.
``cmu_tree``
    The whole CMU database as a user downloads it (``dataset=cmu_full``): every ``SS_TT.amc`` below ``path``, at
    any depth, read on the ``SS.asf`` beside it (the layout of CMU's ``allasfamc.zip``, ``subjects/SS/``, and of
    ``../shared/data/cmu``, ``asf_amc/SS/``), sorted by subject and trial number; ``format: bvh`` reads every
    ``SS_TT.bvh`` instead (the cgspeed BVH release, CMU units, frame 0 dropped). ``clips`` keeps only the named
    clips, ``exclude`` leaves the named clips out (``cmu_full`` leaves out ``cmu_train``, its training set).

Any kind takes ``frame_step: k`` (default 1): every k-th frame from frame 0, at fps / k (``cmu_test_24fps`` is
``cmu_test`` at 24 fps with ``frame_step: 5``); the training set inherits it unless ``train`` sets its own.

A job measures a shard, a list of clips (:mod:`mocapbench.experiments.shards`): :func:`catalogue` names every
clip of a dataset with its frame count (read from ``manifest.csv``, a BVH header or estimated from the file size)
without parsing any motion, and :func:`iter_clips` reads only the named clips, one at a time, so a job holds one
clip in memory whatever the size of the dataset. :func:`load_clips` (every clip at once) is cached per process.
"""

from __future__ import annotations

import csv
import json
import logging
import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Iterator, Mapping, Sequence

from mocapbench.motion import Motion, MotionFormatError

log = logging.getLogger(__name__)

__all__ = [
    "DatasetError",
    "ClipRef",
    "catalogue",
    "iter_clips",
    "load_clips",
    "load_training",
    "training_spec",
    "describe_dataset",
    "describe_training",
    "cmu_used",
    "bandai_used",
]

# Bytes per frame of a CMU AMC file (31 joints; 799 on the 63 clips of ../shared/data/cmu) and of a CMU BVH file,
# used to estimate the frames of a file without reading it (the estimate only balances shards).
_AMC_BYTES_PER_FRAME = 800.0
_BVH_BYTES_PER_FRAME = 760.0


@dataclass(frozen=True)
class ClipRef:
    """One clip of a dataset, named without reading its motion.

    Attributes
    ----------
    name : str
        The clip's name, equal to the ``Motion.name`` its loader gives (the results rows' ``clip``).
    frames : int
        Its frame count, exact where the file says it cheaply, else estimated from the file size (for balancing).
    """

    name: str
    frames: int


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


def training_spec(spec: Mapping[str, Any]) -> dict[str, Any]:
    """The dataset spec of the training set of ``spec`` (``spec`` itself, less its ``train``, if that is null)."""
    spec = _plain(spec)
    train = spec.get("train")
    if train is None:
        return {**spec, "train": None}
    return _inherit(spec, train)


def load_training(spec: Mapping[str, Any]) -> list[Motion]:
    """The motions that codecs with learned state are fit on (``spec["train"]``; the clips themselves if null)."""
    return list(_load_cached(_key(training_spec(spec))))


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


def _kinds(spec: Mapping[str, Any]) -> set:
    """The ``kind`` of ``spec`` and of its training set."""
    spec = _plain(spec)
    kinds = {spec.get("kind")}
    if isinstance(spec.get("train"), Mapping):
        kinds.add(spec["train"].get("kind", spec.get("kind")))
    return kinds


def cmu_used(spec: Mapping[str, Any]) -> bool:
    """Whether ``spec`` (or its training set) reads CMU clips, so the report must carry CMU's acknowledgement."""
    return bool(_kinds(spec) & {"cmu", "cmu_tree"})


def bandai_used(spec: Mapping[str, Any]) -> bool:
    """Whether ``spec`` (or its training set) reads the Bandai Namco dataset, so the report must cite it."""
    return "bandai" in _kinds(spec)


def _inherit(parent: Mapping[str, Any], train: Any) -> dict[str, Any]:
    """The training spec: a mapping that inherits ``kind`` and ``data_dir`` from the measured dataset."""
    if not isinstance(train, Mapping):
        raise DatasetError(f"dataset {parent.get('name')!r}: `train` must be a mapping or null, got {train!r}.")
    merged = {key: parent[key] for key in ("kind", "data_dir", "frame_step") if key in parent}
    merged.update(train)
    merged["name"] = train.get("name", f"{parent.get('name', 'dataset')}-train")
    merged["train"] = None
    return merged


def _frame_step(spec: Mapping[str, Any]) -> int:
    """``frame_step`` of a dataset spec (1 when absent), checked: a positive integer."""
    step = spec.get("frame_step", 1)
    if step is None:
        return 1
    if isinstance(step, bool) or not isinstance(step, int) or step < 1:
        raise DatasetError(
            f"dataset {spec.get('name', '?')!r}: `frame_step` must be a positive integer, got {step!r}."
        )
    return step


def _describe(spec: Mapping[str, Any]) -> str:
    step = _frame_step(spec)
    what = _describe_clips(spec)
    return what if step == 1 else f"{what}, every {step}th frame"


def _describe_clips(spec: Mapping[str, Any]) -> str:
    kind = spec.get("kind")
    if kind == "synthetic":
        clips = spec.get("clips", {})
        return f"synthetic sinusoidal, seeds {list(clips.get('seeds', []))}, {clips.get('num_frames')} frames each"
    if kind == "cmu":
        what = spec.get("split") or ",".join(str(c) for c in spec.get("clips") or [])
        return f"CMU ASF/AMC {what}"
    if kind == "folder":
        return f"folder {spec.get('path')}"
    if kind == "bandai":
        return f"Bandai Namco BVH {spec.get('split')}"
    if kind == "cmu_tree":
        what = f"clips {','.join(str(c) for c in spec['clips'])}" if spec.get("clips") else "every clip"
        less = f" except {len(spec['exclude'])} excluded" if spec.get("exclude") else ""
        return f"CMU {str(spec.get('format', 'amc')).upper()} tree {spec.get('path')}: {what}{less}"
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
    elif kind in ("cmu_tree", "bandai"):
        motions = list(_iter_full_rate(spec, None))
    else:
        raise DatasetError(f"dataset {where}: `kind` must be one of {list(_KINDS)}, got {kind!r}.")
    if not motions:
        raise DatasetError(f"dataset {where}: no clips.")
    step = _frame_step(spec)
    return tuple(motion.every(step) for motion in motions)


_KINDS = ("synthetic", "cmu", "folder", "cmu_tree", "bandai")


def catalogue(spec: Mapping[str, Any]) -> list[ClipRef]:
    """Every clip of the dataset ``spec`` with its frame count, in :func:`load_clips` order, no motion parsed.

    Raises
    ------
    DatasetError
        Malformed config or an empty dataset.
    mocapbench.datasets.cmu.DataNotFoundError
        A CMU dataset whose data folder is missing.
    """
    spec = _plain(spec)
    where = repr(spec.get("name", "?"))
    kind = _require(spec, "kind", where)
    if kind == "synthetic":
        clips = _require(spec, "clips", where)
        frames = int(clips.get("num_frames", 240))
        refs = [ClipRef(f"synthetic-seed{int(seed)}", frames) for seed in _require(clips, "seeds", where + ".clips")]
    elif kind == "cmu":
        refs = [ClipRef(name, frames) for name, frames, _ in _cmu_files(spec, where)]
    elif kind == "folder":
        refs = [ClipRef(file.stem, _estimate_frames(file)) for file in _folder_files(spec, where)]
    elif kind == "cmu_tree":
        refs = [ClipRef(name, _estimate_frames(file)) for name, file, _ in _tree_files(spec, where)]
    elif kind == "bandai":
        refs = [ClipRef(name, frames) for name, frames, _ in _bandai_files(spec, where)]
    else:
        raise DatasetError(f"dataset {where}: `kind` must be one of {list(_KINDS)}, got {kind!r}.")
    if not refs:
        raise DatasetError(f"dataset {where}: no clips.")
    step = _frame_step(spec)
    return [ClipRef(ref.name, -(-ref.frames // step)) for ref in refs] if step > 1 else refs


def iter_clips(spec: Mapping[str, Any], names: Sequence[str] | None = None) -> Iterator[Motion]:
    """The clips of ``spec`` named in ``names`` (default: every clip), read one at a time in dataset order.

    Only the named files are parsed, and each ASF once; a caller that drops each motion after use holds one clip.
    Clips of a data folder (``cmu``, ``bandai``) are kept for the next jobs of the process, read-only
    (:mod:`mocapbench.experiments.clip_cache`).

    Raises
    ------
    DatasetError
        A name that is not a clip of the dataset (the message lists a few that are).
    """
    spec = _plain(spec)
    step = _frame_step(spec)
    files = _data_files(spec)
    if files is None:
        for motion in _iter_full_rate(spec, names):
            yield motion.every(step)
        return
    # Clips of a data folder are kept across the jobs of this process (mocapbench.experiments.clip_cache).
    from mocapbench.experiments import clip_cache

    spec_key = _key(spec)
    keep = _kept_clips(spec, names, repr(spec.get("name", "?")))
    order = [name for name in files if name in keep]
    keys = {name: (spec_key, name, _signature(files[name])) for name in order}
    kept = {name: clip_cache.get(keys[name]) if keys[name][2] is not None else None for name in order}
    missing = [name for name in order if kept[name] is None]
    read = _iter_full_rate(spec, missing) if missing else iter(())
    for name in order:
        motion = kept[name]
        if motion is None:
            motion = next(read).every(step)
            if keys[name][2] is not None:
                motion = clip_cache.put(keys[name], motion)
        yield motion


def _data_files(spec: Mapping[str, Any]) -> dict[str, tuple[Path, ...]] | None:
    """``name -> files`` of every clip of a ``cmu`` or ``bandai`` spec in dataset order; None for other kinds."""
    where = repr(spec.get("name", "?"))
    kind = spec.get("kind")
    if kind == "cmu":
        return {name: tuple(p for p in paths if p is not None) for name, _, paths in _cmu_files(spec, where)}
    if kind == "bandai":
        return {name: (file,) for name, _, file in _bandai_files(spec, where)}
    return None


def _signature(files: Sequence[Path]) -> tuple | None:
    """What tells a file rewritten in place: each file's path, size and modification time (None if one cannot be
    read: the clip is then read as before, and its reader says what is wrong)."""
    out = []
    for file in files:
        try:
            stat = Path(file).stat()
        except OSError:
            return None
        out.append((str(file), stat.st_size, stat.st_mtime_ns))
    return tuple(out)


def _iter_full_rate(spec: Mapping[str, Any], names: Sequence[str] | None) -> Iterator[Motion]:
    """:func:`iter_clips` before ``frame_step``."""
    where = repr(spec.get("name", "?"))
    kind = _require(spec, "kind", where)
    keep = _kept_clips(spec, names, where)
    if kind == "synthetic":
        yield from _iter_synthetic(spec, keep)
    else:
        yield from _iter_files(spec, kind, keep, where)


def _kept_clips(spec: Mapping[str, Any], names: Sequence[str] | None, where: str) -> set[str]:
    """The clip names to read: ``names`` (each checked to be a clip of the dataset), or every clip."""
    wanted = None if names is None else list(names)
    known = [ref.name for ref in catalogue(spec)]
    if wanted is not None:
        missing = sorted(set(wanted) - set(known))
        if missing:
            raise DatasetError(f"dataset {where}: no clip named {missing[:5]}; it has {known[:5]}... ({len(known)})")
    return set(known if wanted is None else wanted)


def _iter_synthetic(spec: Mapping[str, Any], keep: set[str]) -> Iterator[Motion]:
    """The kept clips of a ``kind: synthetic`` spec, one sinusoidal motion per seed."""
    from mocapbench.synthetic import sinusoidal_motion

    clips = spec["clips"]
    extra = {key: value for key, value in clips.items() if key != "seeds"}
    for seed in clips["seeds"]:
        if f"synthetic-seed{int(seed)}" in keep:
            yield sinusoidal_motion(seed=int(seed), **extra)


def _iter_files(spec: Mapping[str, Any], kind: str, keep: set[str], where: str) -> Iterator[Motion]:
    """The kept clips of a spec whose clips are files (``cmu``, ``folder``, ``cmu_tree``, ``bandai``), each ASF read
    once."""
    from mocapbench.datasets import cmu
    from mocapbench.io.asf_amc import read_amc, read_asf
    from mocapbench.io.bvh import read_bvh

    asf_cache: dict[Path, Any] = {}

    def amc(path: Path, asf_path: Path, name: str, fps: float) -> Motion:
        if asf_path not in asf_cache:
            asf_cache[asf_path] = read_asf(asf_path)
        return read_amc(path, asf_cache[asf_path], name=name, fps=fps)

    if kind == "cmu":
        for name, _, (path, asf_path) in _cmu_files(spec, where):
            if name in keep:
                yield (amc(path, asf_path, name, 120.0) if asf_path is not None else
                       read_bvh(path, length_unit_cm=cmu.CMU_CM_PER_UNIT, drop_first_frame=True, name=name))
    elif kind == "folder":
        for file in _folder_files(spec, where):
            if file.stem in keep:
                motion = _read_folder_file(spec, file)
                if motion is not None:
                    yield motion
    elif kind == "cmu_tree":
        for name, file, asf_path in _tree_files(spec, where):
            if name not in keep:
                continue
            if asf_path is None:
                yield read_bvh(file, length_unit_cm=cmu.CMU_CM_PER_UNIT, drop_first_frame=True, name=name)
            else:
                yield amc(file, asf_path, name, float(spec.get("fps", 120.0)))
    elif kind == "bandai":
        for name, _, file in _bandai_files(spec, where):
            if name in keep:
                yield read_bvh(file, name=name)  # cm, every frame a frame of motion


def _bandai_files(spec: Mapping[str, Any], where: str) -> list[tuple[str, int, Path]]:
    """(name, frames, BVH file) of every clip of a ``kind: bandai`` spec."""
    from mocapbench.datasets import bandai

    split = str(_require(spec, "split", where))
    if split not in bandai.SPLITS:
        raise DatasetError(f"dataset {where}: `split` must be one of {list(bandai.SPLITS)}, got {split!r}.")
    return bandai.clip_files(split, _resolve_data_dir(spec.get("data_dir")))


def _cmu_selection(spec: Mapping[str, Any], where: str) -> tuple[Path, Any, Any, str]:
    """(data folder, split, clips, format) of a ``kind: cmu`` spec; exactly one of split and clips is given."""
    from mocapbench.datasets import cmu

    data_dir = cmu.cmu_data_dir(_resolve_data_dir(spec.get("data_dir")))
    split, clips = spec.get("split"), spec.get("clips")
    if (split is None) == (clips is None):
        raise DatasetError(
            f"dataset {where}: give exactly one of `split` or `clips`, got split={split!r}, clips={clips!r}."
        )
    return data_dir, split, clips, str(spec.get("format", "amc"))


def _cmu_files(spec: Mapping[str, Any], where: str) -> list[tuple[str, int, tuple[Path, Path | None]]]:
    """(name, frames, (motion file, ASF or None)) of every clip of a ``kind: cmu`` spec."""
    from mocapbench.datasets import cmu

    data_dir, split, clips, fmt = _cmu_selection(spec, where)
    names = cmu.clip_names(str(split), data_dir=data_dir) if split is not None else [str(c) for c in clips]
    counts = _manifest_frames(data_dir)
    out = []
    for name in names:
        paths = cmu._clip_paths(name, fmt, data_dir)
        key = str(paths[0].relative_to(data_dir))
        out.append((name, counts.get(key) or _estimate_frames(paths[0]), paths))
    return out


@lru_cache(maxsize=4)
def _manifest_frames(data_dir: Path) -> dict[str, int]:
    """``file -> frames`` of the data folder's ``manifest.csv`` (empty if it has none)."""
    manifest = Path(data_dir) / "manifest.csv"
    if not manifest.is_file():
        return {}
    with open(manifest, newline="", encoding="utf-8") as handle:
        return {row["file"]: int(row["frames"]) for row in csv.DictReader(handle) if row.get("frames")}


def _folder_files(spec: Mapping[str, Any], where: str) -> list[Path]:
    from mocapbench.datasets.cmu import DataNotFoundError
    from mocapbench.io.format_table import motion_files

    folder = Path(str(_require(spec, "path", where))).expanduser()
    if not folder.is_dir():
        raise DataNotFoundError(f"{folder} is not a folder.")
    files = motion_files([folder], suffixes=(".bvh", ".amc"))  # the formats _estimate_frames can count
    if not files:
        raise DataNotFoundError(f"{folder} holds no .bvh or .amc file.")
    return files


_CMU_NAME = re.compile(r"^(\d+)_(\d+)$")


def _tree_files(spec: Mapping[str, Any], where: str) -> list[tuple[str, Path, Path | None]]:
    """(name, motion file, ASF or None) of every CMU clip below ``spec["path"]``, sorted by subject and trial."""
    from mocapbench.datasets.cmu import DataNotFoundError

    root = Path(str(_resolve_data_dir(_require(spec, "path", where)))).expanduser()
    if not root.is_dir():
        raise DataNotFoundError(
            f"dataset {where}: {root} is not a folder; download the CMU database (README, 'Data') and set "
            f"data_dir=... or dataset.path=..."
        )
    fmt = str(spec.get("format", "amc"))
    if fmt not in ("amc", "bvh"):
        raise DatasetError(f"dataset {where}: `format` must be 'amc' or 'bvh', got {fmt!r}.")
    found: dict[str, tuple[Path, Path | None]] = {}
    for file in root.rglob(f"*.{fmt}"):
        match = _CMU_NAME.match(file.stem)
        if not match or not file.is_file():
            continue
        name = file.stem
        if name in found:
            raise DatasetError(f"dataset {where}: clip {name} is in two places: {found[name][0]} and {file}.")
        asf = None
        if fmt == "amc":
            asf = file.with_name(f"{match.group(1)}.asf")
            if not asf.is_file():
                raise DataNotFoundError(f"dataset {where}: {file} has no skeleton {asf.name} beside it.")
        found[name] = (file, asf)
    only = {str(c) for c in spec.get("clips") or []}
    drop = {str(c) for c in spec.get("exclude") or []}
    names = [n for n in found if (not only or n in only) and n not in drop]
    if only - set(found):
        raise DataNotFoundError(f"dataset {where}: clips {sorted(only - set(found))[:5]} are not below {root}.")
    names.sort(key=lambda n: tuple(int(part) for part in n.split("_")))
    if not names:
        raise DataNotFoundError(f"dataset {where}: no SS_TT.{fmt} file below {root}.")
    return [(n, *found[n]) for n in names]


def _estimate_frames(path: Path) -> int:
    """Frames of a motion file: a BVH's ``Frames:`` line (read from its first 64 KiB), else from its size."""
    if path.suffix.lower() == ".bvh":
        with open(path, "rb") as handle:
            head = handle.read(65536)
        match = re.search(rb"Frames:\s*(\d+)", head)
        if match:
            return int(match.group(1))
        return max(1, round(path.stat().st_size / _BVH_BYTES_PER_FRAME))
    return max(1, round(path.stat().st_size / _AMC_BYTES_PER_FRAME))


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

    data_dir, split, clips, fmt = _cmu_selection(spec, where)
    if split is not None:
        return list(cmu.load_split(str(split), fmt=fmt, data_dir=data_dir))
    return [cmu.load_clip(str(clip), fmt=fmt, data_dir=data_dir) for clip in clips]


def _folder(spec: Mapping[str, Any], where: str) -> list[Motion]:
    return list(_iter_full_rate(spec, None))


def _read_folder_file(spec: Mapping[str, Any], file: Path) -> Motion | None:
    """One file of a ``kind: folder`` dataset, read and checked as the command line reads it.

    :func:`mocapbench.io.formats.read_motion` with the dataset's ``units`` (or the older ``length_unit_cm``),
    ``up``, ``fps`` and ``drop_first_frame``, and the file's sidecar (``FILE.units``) when the dataset gives no
    unit: a unit that does not fit the body is logged as a warning in one line, or, with ``strict_units: true``,
    fails the run (:class:`DatasetError`). A file no reader takes is logged and skipped (None), so one bad file does
    not fail every job.
    """
    from mocapbench.io.formats import UnitCheckError, read_motion

    units = spec.get("units")
    if units is None and spec.get("length_unit_cm") is not None:
        units = float(spec["length_unit_cm"])
    try:
        motion, warnings = read_motion(
            file, units=units, up=spec.get("up"), fps=float(spec.get("fps") or 120.0),
            drop_first_frame=bool(spec.get("drop_first_frame", False)), strict=bool(spec.get("strict_units", False)),
        )
    except UnitCheckError as error:
        raise DatasetError(f"dataset {spec.get('name', '?')!r}: {error} (strict_units: true)") from None
    except (MotionFormatError, OSError, ValueError) as error:
        log.warning("skipped %s: %s", file, " ".join(str(error).split()))
        return None
    for warning in warnings:
        log.warning("%s", warning)
    log.info("%s: %s, %s up", file, motion.source_unit_cm, motion.up_axis)
    return motion
