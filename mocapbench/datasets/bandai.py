"""The Bandai Namco Research Motion Dataset 1 in ``../shared/data/bandai``: where it is, its splits, its files.

A game studio's capture (Kobayashi et al., "Motion Capture Dataset for Practical Use of AI-based Motion Editing and
Stylization", arXiv:2306.08861, 2023; CC BY-NC 4.0): BVH files of a 22-joint game rig (a ground-level
``joint_Root`` above a translated ``Hips``, position channels on every joint), 30 fps, cm, Y up. The folder holds
``bvh/`` and ``manifest.csv`` (file, content, style, take, frames, ..., ``split``: ``test`` or ``train``); it is
found by :func:`bandai_data_dir` (argument, then ``$MOCAPBENCH_BANDAI_DIR``, then ``../shared/data/bandai`` from the
working directory or from the repository, then beside ``$MOCAPBENCH_CMU_DIR``) and read in place, never copied.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

from mocapbench.datasets.cmu import DataNotFoundError

__all__ = ["ENV_VAR", "SPLITS", "ACKNOWLEDGEMENT", "bandai_data_dir", "clip_files"]

ENV_VAR = "MOCAPBENCH_BANDAI_DIR"
"""Environment variable naming the Bandai Namco data folder."""

_DEFAULT_RELATIVE = Path("..") / "shared" / "data" / "bandai"

SPLITS = ("bandai_test", "bandai_train", "bandai_all")
"""The benchmark splits: the manifest's ``test`` and ``train`` files, and every file."""

ACKNOWLEDGEMENT = (
    "Bandai Namco Research Motion Dataset 1, (c) 2022 Bandai Namco Research Inc., CC BY-NC 4.0: M. Kobayashi, "
    "C.-C. Liao, K. Inoue, S. Yojima, M. Takahashi, \"Motion Capture Dataset for Practical Use of AI-based Motion "
    "Editing and Stylization\", arXiv:2306.08861, 2023."
)


def bandai_data_dir(path: str | Path | None = None) -> Path:
    """The Bandai Namco data folder: an existing folder holding ``manifest.csv`` and ``bvh/``.

    Parameters
    ----------
    path : str or Path, optional
        Use this folder. Default: ``$MOCAPBENCH_BANDAI_DIR`` if set, else ``../shared/data/bandai`` relative to the
        working directory, else relative to the repository root (the folder holding ``mocapbench/``), else
        ``../bandai`` beside ``$MOCAPBENCH_CMU_DIR`` (the shared data folder).

    Raises
    ------
    DataNotFoundError
        No such folder; the message lists where it looked and how to set it.
    """
    if path is not None:
        candidates = [(Path(path).expanduser(), "the `data_dir` of the dataset config")]
    elif os.environ.get(ENV_VAR):
        candidates = [(Path(os.environ[ENV_VAR]).expanduser(), f"${ENV_VAR}")]
    else:
        repo_root = Path(__file__).resolve().parents[2]
        candidates = [
            (Path.cwd() / _DEFAULT_RELATIVE, "the working directory"),
            (repo_root / _DEFAULT_RELATIVE, "the repository root"),
        ]
        if os.environ.get("MOCAPBENCH_CMU_DIR"):  # the shared data folder holds both data sets
            candidates.append((Path(os.environ["MOCAPBENCH_CMU_DIR"]).expanduser() / ".." / "bandai",
                               "beside $MOCAPBENCH_CMU_DIR"))
    for candidate, _ in candidates:
        if (candidate / "manifest.csv").is_file() and (candidate / "bvh").is_dir():
            return candidate.resolve()
    looked = "; ".join(f"{candidate} (from {source})" for candidate, source in candidates)
    raise DataNotFoundError(
        f"Bandai Namco data folder not found (a folder holding manifest.csv and bvh/). Looked in: {looked}. "
        f"Set ${ENV_VAR} or dataset.data_dir=..., or put the data in ../shared/data/bandai next to the repository."
    )


def clip_files(split: str, data_dir: str | Path | None = None) -> list[tuple[str, int, Path]]:
    """(name, frames, BVH file) of every file of ``split`` (a key of :data:`SPLITS`), in manifest order.

    The name is the file's stem (``dataset-1_bow_happy_001``), as :func:`mocapbench.io.bvh.read_bvh` names a motion.

    Raises
    ------
    ValueError
        An unknown split.
    DataNotFoundError
        The folder, its manifest or a file it lists is missing, or the manifest lacks a column.
    """
    if split not in SPLITS:
        raise ValueError(f"Unknown Bandai Namco split {split!r}; expected one of {list(SPLITS)}.")
    root = bandai_data_dir(data_dir)
    manifest = root / "manifest.csv"
    wanted = split.removeprefix("bandai_")
    out = []
    with open(manifest, newline="", encoding="utf-8") as handle:
        for line, row in enumerate(csv.DictReader(handle), start=2):
            try:
                file, frames, row_split = row["file"], int(row["frames"]), row["split"]
            except (KeyError, TypeError, ValueError) as error:
                raise DataNotFoundError(f"{manifest}, line {line}: expected file, frames and split ({error}).") from None
            if wanted != "all" and row_split != wanted:
                continue
            path = root / file
            if not path.is_file() or path.suffix.lower() != ".bvh" or root not in path.resolve().parents:
                raise DataNotFoundError(f"{manifest}, line {line}: {path} is not a BVH file inside {root}.")
            out.append((path.stem, frames, path))
    if not out:
        raise DataNotFoundError(f"{manifest}: no file in split {wanted!r}.")
    return out
