"""The CMU motion capture clips in ``../shared/data/cmu``: where they are, the benchmark splits, loading.

The folder is found by :func:`cmu_data_dir` (argument, then ``$MOCAPBENCH_CMU_DIR``, then
``../shared/data/cmu`` from the working directory or from the repository); it is read in place, never
copied. ASF/AMC is the primary source (frame counts as in the papers); the BVH release is loaded with its
reference frame 0 dropped and its ASF units converted, so both give motions in cm on 31 joints.
"""

from __future__ import annotations

import csv
import logging
import os
from pathlib import Path

from mocapbench.io.asf_amc import CMU_CM_PER_UNIT, AsfSkeleton, find_asf, read_amc, read_asf
from mocapbench.io.bvh import read_bvh
from mocapbench.motion import Motion, MotionFormatError

log = logging.getLogger(__name__)

__all__ = [
    "DataNotFoundError",
    "ENV_VAR",
    "CMU_CM_PER_UNIT",
    "SPLITS",
    "cmu_data_dir",
    "clip_names",
    "load_clip",
    "load_split",
    "load_folder",
]

ENV_VAR = "MOCAPBENCH_CMU_DIR"
"""Environment variable naming the CMU data folder."""

_DEFAULT_RELATIVE = Path("..") / "shared" / "data" / "cmu"

SPLITS: dict[str, tuple[str, ...]] = {
    # Split by subject (data README, "Benchmark splits"): 13,063 AMC frames.
    "cmu_train": ("13_17", "13_18", "124_01", "124_02", "135_06"),
    # 5,587 AMC frames, 7 subjects; holds 09_06, the one clip the papers name.
    "cmu_test": (
        "02_01",
        "02_02",
        "05_01",
        "09_06",
        "10_01",
        "10_02",
        "16_01",
        "16_07",
        "64_01",
        "64_05",
        "118_01",
        "118_10",
    ),
}
"""Fixed benchmark splits. ``"cmu_all"`` (every clip with an AMC in ``manifest.csv``) is read from the data folder
by :func:`clip_names`."""

ALL_SPLIT = "cmu_all"


class DataNotFoundError(FileNotFoundError):
    """The CMU data folder, its manifest or a clip file is missing; the message says where it looked."""


def cmu_data_dir(path: str | Path | None = None) -> Path:
    """The CMU data folder.

    Parameters
    ----------
    path : str or Path, optional
        Use this folder. Default: ``$MOCAPBENCH_CMU_DIR`` if set, else ``../shared/data/cmu`` relative to the
        working directory, else relative to the repository root (the folder holding ``mocapbench/``).

    Returns
    -------
    Path
        An existing folder holding ``asf_amc/`` or ``bvh/``.

    Raises
    ------
    DataNotFoundError
        No such folder; the message lists where it looked and how to set it.
    """
    if path is not None:
        candidates = [(Path(path), "the `path` argument")]
    elif os.environ.get(ENV_VAR):
        candidates = [(Path(os.environ[ENV_VAR]), f"${ENV_VAR}")]
    else:
        repo_root = Path(__file__).resolve().parents[2]
        candidates = [
            (Path.cwd() / _DEFAULT_RELATIVE, "the working directory"),
            (repo_root / _DEFAULT_RELATIVE, "the repository root"),
        ]
    for candidate, _ in candidates:
        if candidate.is_dir() and ((candidate / "asf_amc").is_dir() or (candidate / "bvh").is_dir()):
            return candidate.resolve()
    looked = "; ".join(f"{candidate} (from {source})" for candidate, source in candidates)
    raise DataNotFoundError(
        f"CMU data folder not found (a folder holding asf_amc/ or bvh/). Looked in: {looked}. "
        f"Pass data_dir=..., set ${ENV_VAR}, or put the data in ../shared/data/cmu next to the repository."
    )


def clip_names(split: str, *, data_dir: str | Path | None = None) -> tuple[str, ...]:
    """Clip names (``"09_06"``) of ``split``: a key of :data:`SPLITS` or ``"cmu_all"``.

    ``"cmu_all"`` lists every AMC in the folder's ``manifest.csv``, in manifest order.
    """
    if split in SPLITS:
        return SPLITS[split]
    if split != ALL_SPLIT:
        raise ValueError(f"Unknown split {split!r}; expected one of {sorted([*SPLITS, ALL_SPLIT])}.")
    manifest = cmu_data_dir(data_dir) / "manifest.csv"
    if not manifest.is_file():
        raise DataNotFoundError(f"{manifest} does not exist; split {ALL_SPLIT!r} is read from it.")
    with open(manifest, newline="", encoding="utf-8") as handle:
        files = [row["file"] for row in csv.DictReader(handle)]
    return tuple(Path(file).stem for file in files if file.startswith("asf_amc/") and file.endswith(".amc"))


def _clip_paths(name: str, fmt: str, root: Path) -> tuple[Path, Path | None]:
    """(motion file, ASF file or None) of clip ``name`` in ``root``."""
    subject = name.split("_", 1)[0]
    if fmt == "amc":
        paths = (root / "asf_amc" / subject / f"{name}.amc", root / "asf_amc" / subject / f"{subject}.asf")
    elif fmt == "bvh":
        paths = (root / "bvh" / f"{name}.bvh", None)
    else:
        raise ValueError(f"Unknown clip format {fmt!r}; expected 'amc' or 'bvh'.")
    for file in paths:
        if file is not None and not file.is_file():
            raise DataNotFoundError(f"Clip {name!r} ({fmt}): {file} does not exist.")
    return paths


def _load_clip(name: str, fmt: str, root: Path, asf_cache: dict[Path, AsfSkeleton]) -> Motion:
    motion_path, asf_path = _clip_paths(name, fmt, root)
    if asf_path is None:
        return read_bvh(motion_path, length_unit_cm=CMU_CM_PER_UNIT, drop_first_frame=True, name=name)
    if asf_path not in asf_cache:
        asf_cache[asf_path] = read_asf(asf_path)
    return read_amc(motion_path, asf_cache[asf_path], name=name)


def load_clip(name: str, *, fmt: str = "amc", data_dir: str | Path | None = None) -> Motion:
    """One CMU clip as a :class:`Motion` in cm, named ``name``.

    Parameters
    ----------
    name : str
        ``"SS_TT"``, e.g. ``"09_06"``.
    fmt : {"amc", "bvh"}, keyword-only
        ``"amc"`` (default, the original capture): ``asf_amc/SS/SS_TT.amc`` on ``asf_amc/SS/SS.asf``.
        ``"bvh"``: ``bvh/SS_TT.bvh`` with ``length_unit_cm=CMU_CM_PER_UNIT`` and ``drop_first_frame=True``.
    data_dir : str or Path, optional, keyword-only
        See :func:`cmu_data_dir`.
    """
    return _load_clip(name, fmt, cmu_data_dir(data_dir), {})


def load_split(split: str, *, fmt: str = "amc", data_dir: str | Path | None = None) -> list[Motion]:
    """Every clip of ``split`` (see :func:`clip_names`), in split order; each ASF is parsed once."""
    root = cmu_data_dir(data_dir)
    cache: dict[Path, AsfSkeleton] = {}
    return [_load_clip(name, fmt, root, cache) for name in clip_names(split, data_dir=root)]


def load_folder(
    path: str | Path, *, length_unit_cm: float = 1.0, drop_first_frame: bool = False, fps: float = 120.0
) -> list[Motion]:
    """Every motion in a folder (not its sub-folders): ``*.bvh`` and ``*.amc`` files, sorted by file name.

    Each ``.amc`` is read on the folder's ASF: the only ``.asf`` there, else ``SS.asf`` for ``SS_TT.amc``.

    Parameters
    ----------
    path : str or Path
    length_unit_cm, drop_first_frame : keyword-only
        Passed to :func:`~mocapbench.io.bvh.read_bvh` for the BVH files (defaults: cm, keep frame 0).
    fps : float, keyword-only
        Frame rate of the AMC files (not recorded in them). Default 120.

    Raises
    ------
    DataNotFoundError
        ``path`` is not a folder, holds no motion file, or none of its files can be read. A file that cannot be
        read (malformed, an AMC with no matching ASF) is skipped with one warning line naming it.
    """
    folder = Path(path)
    if not folder.is_dir():
        raise DataNotFoundError(f"{folder} is not a folder.")
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".bvh", ".amc") and p.is_file())
    if not files:
        raise DataNotFoundError(f"{folder} holds no .bvh or .amc file.")
    cache: dict[Path, AsfSkeleton] = {}
    motions = []
    for file in files:
        try:
            if file.suffix.lower() == ".bvh":
                motions.append(read_bvh(file, length_unit_cm=length_unit_cm, drop_first_frame=drop_first_frame))
                continue
            asf_path = find_asf(file)
            if asf_path not in cache:
                cache[asf_path] = read_asf(asf_path)
            motions.append(read_amc(file, cache[asf_path], fps=fps))
        except (MotionFormatError, OSError, ValueError) as error:
            # One unreadable file must not fail the whole benchmark: it is named and skipped.
            log.warning("skipped %s: %s", file, error)
    if not motions:
        raise DataNotFoundError(f"{folder}: none of its {len(files)} motion file(s) could be read.")
    return motions
