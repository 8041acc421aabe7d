"""Read one or more sweep folders (every ``results.jsonl`` below them) into one pandas DataFrame.

Usage: ``python -m mocapbench.experiments.aggregate SWEEP_DIR... [--csv out.csv]`` prints a summary per codec.
A results line that does not parse stops it with one line naming the file and the line (exit code 2): a dropped
row would change the tables silently; re-running the sweep with the same ``hydra.sweep.dir`` redoes its clip.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Iterable

import numpy as np
import pandas as pd

from mocapbench.experiments.animator_metrics import pool_animator_columns
from mocapbench.experiments.document import markdown_table
from mocapbench.experiments.results import ERRORS_FILE, RESULTS_FILE, CorruptResultsError, read_rows, scan_rows
from mocapbench.io.safe_output import check_output, write_text

__all__ = ["aggregate", "read_errors", "curve_points", "AggregateError", "CorruptResultsError"]


class AggregateError(ValueError):
    """No results where results were expected (the message names the folders)."""


def _result_files(folders: Iterable[str | Path], name: str) -> list[Path]:
    files: list[Path] = []
    for folder in folders:
        folder = Path(folder)
        if folder.is_file() and folder.name == name:
            files.append(folder)
        elif folder.is_dir():
            files.extend(sorted(folder.rglob(name)))
        elif name == RESULTS_FILE:
            raise AggregateError(f"{folder}: no such sweep folder or {RESULTS_FILE} file.")
    return files


def aggregate(folders: Iterable[str | Path]) -> pd.DataFrame:
    """Every results row below ``folders``, one DataFrame, with ``sweep_dir`` (the folder given) added.

    Rows repeated across folders (same codec, config hash, dataset, clip and job folder) are kept once.

    Raises
    ------
    AggregateError
        A folder does not exist or no folder holds a single row.
    CorruptResultsError
        A line of a ``results.jsonl`` does not parse (the message names the file and the line).
    """
    folders = list(folders)
    frames = []
    for folder in folders:
        for path in _result_files([folder], RESULTS_FILE):
            rows = read_rows(path)
            if rows:
                frame = pd.DataFrame(rows)
                frame["sweep_dir"] = str(folder)
                frame["job_dir"] = str(path.parent)
                frames.append(frame)
    if not frames:
        raise AggregateError(f"no {RESULTS_FILE} rows under {[str(f) for f in folders]}.")
    data = pd.concat(frames, ignore_index=True, sort=False)
    if "dataset" not in data:
        data["dataset"] = "unknown"
    data["dataset"] = data["dataset"].fillna("unknown")
    key = [c for c in ("codec", "config_hash", "dataset", "clip", "job_dir") if c in data]
    return data.drop_duplicates(subset=key, keep="last").reset_index(drop=True)


def _job_dataset(job_dir: Path) -> str | None:
    """The dataset name of a job folder, from Hydra's saved ``.hydra/config.yaml`` (None if unreadable)."""
    saved = job_dir / ".hydra" / "config.yaml"
    if not saved.exists():
        return None
    try:
        from omegaconf import OmegaConf

        name = OmegaConf.load(saved).get("dataset", {}).get("name")
    except Exception:  # noqa: BLE001 - a damaged config only loses the dataset column
        return None
    return None if name is None else str(name)


def read_errors(folders: Iterable[str | Path]) -> pd.DataFrame:
    """Every ``errors.jsonl`` record below ``folders`` (empty DataFrame if there is none).

    A record without a ``dataset`` gets the one of its job (Hydra's saved config), so a failed job can be shown
    in the right dataset's headline.
    """
    records = []
    for path in _result_files(folders, ERRORS_FILE):
        dataset = None
        for record in scan_rows(path)[0]:  # an error log's torn last line does not hide the other errors
            record["job_dir"] = str(path.parent)
            if not record.get("dataset"):
                dataset = dataset or _job_dataset(path.parent)
                record["dataset"] = dataset
            records.append(record)
    return pd.DataFrame(records)


# Per-config columns carried into the curve points when the rows hold them: codec traits, timing facts.
_FIRST = ("codes_rotations", "family", "needs_model", "random_access", "latency_frames", "dataset_desc", "cmu_data",
          "bandai_data")
_SUMS = ("encode_cpu_s", "decode_cpu_s")
_MAXES = ("encode_wall_spread_s", "decode_wall_spread_s", "encode_load_after", "decode_load_after",
          "encode_threads", "decode_threads", "shell_max_err_cm", "shell_p99_err_cm")  # shell: worst clip, as L∞
_MINS = ("encode_repeats", "decode_repeats")


def curve_points(data: pd.DataFrame) -> pd.DataFrame:
    """One point per (dataset, codec, config) over the clips of the dataset.

    Rate is pooled (total bytes over total joint-frames, so long clips weigh more, as a whole dataset would be
    stored); ``max_err_cm`` is the worst clip's L-inf, ``p99_err_cm`` the worst clip's p99, ``mean_err_cm`` and
    ``kg_percent`` frame-weighted means; what animators see is pooled as
    :func:`mocapbench.experiments.animator_metrics.pool_animator_columns` says; speeds are total frames over total
    CPU seconds (``encode_fps``, ``decode_fps``; wall seconds for rows without CPU times) and over wall seconds (``*_wall_fps``). ``clips``
    counts the clips;
    a config that failed on some clip of the dataset has fewer clips than the others and is flagged in
    ``complete``.
    """
    if data.empty:
        return data.copy()
    # The same config measured in two sweeps (e.g. an RD sweep and a claims sweep) counts once per clip.
    frame = data.drop_duplicates(subset=["dataset", "codec", "config_hash", "clip"], keep="last").copy()
    frame["_joint_frames"] = frame["frames"] * frame["joints"]
    for column in ("mean_err_cm", "kg_percent"):
        frame[f"_w_{column}"] = frame[column] * frame["frames"]
    groups = frame.groupby(["dataset", "codec", "config_hash"], sort=True, dropna=False)
    params = [c for c in frame.columns if c.startswith("param_")]
    out = groups.agg(
        clips=("clip", "nunique"),
        frames=("frames", "sum"),
        raw_bytes=("raw_bytes", "sum"),
        bitstream_bytes=("bitstream_bytes", "sum"),
        model_bytes=("model_bytes", "max"),
        joint_frames=("_joint_frames", "sum"),
        max_err_cm=("max_err_cm", "max"),
        p99_err_cm=("p99_err_cm", "max"),
        max_err_percent_height=("max_err_percent_height", "max"),
        w_mean=("_w_mean_err_cm", "sum"),
        w_kg=("_w_kg_percent", "sum"),
        encode_s=("encode_s", "sum"),
        decode_s=("decode_s", "sum"),
        **{c: (c, "first") for c in params},
        **{c: (c, "first") for c in _FIRST if c in frame},
        **{c: (c, "sum") for c in _SUMS if c in frame},
        **{c: (c, "max") for c in _MAXES if c in frame},
        **{c: (c, "min") for c in _MINS if c in frame},
    ).copy().reset_index()  # the copy consolidates the aggregation's block per column (over a hundred with the
    # params), or pandas warns at each column inserted from here on (a PerformanceWarning in every `make run`)
    out["compression_ratio"] = out["raw_bytes"] / out["bitstream_bytes"]
    out["bits_per_joint_frame"] = 8 * out["bitstream_bytes"] / out["joint_frames"]
    out["mean_err_cm"] = out["w_mean"] / out["frames"]
    out["kg_percent"] = out["w_kg"] / out["frames"]
    for step in ("encode", "decode"):
        # Frames per CPU second of the process where the rows have it (shared machines), else per wall second.
        seconds = f"{step}_cpu_s" if f"{step}_cpu_s" in out and out[f"{step}_cpu_s"].notna().all() else f"{step}_s"
        out[f"{step}_fps"] = out["frames"] / out[seconds].replace(0, np.nan)
        out[f"{step}_wall_fps"] = out["frames"] / out[f"{step}_s"].replace(0, np.nan)
    out = out.merge(pool_animator_columns(frame, ["dataset", "codec", "config_hash"]), how="left",
                    on=["dataset", "codec", "config_hash"])
    most = out.groupby("dataset")["clips"].transform("max")
    out["complete"] = out["clips"] == most
    return out.drop(columns=["w_mean", "w_kg"])


def _main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", help="sweep folders (or results.jsonl files)")
    parser.add_argument("--csv", help="write every row to this CSV file (refused if it exists, unless --force)")
    parser.add_argument("--force", action="store_true", help="replace an existing CSV file (or the link, not its target)")
    args = parser.parse_args(argv)
    if args.csv:
        try:
            check_output(args.csv, force=args.force)
        except OSError as error:
            parser.error(str(error))
    try:
        data = aggregate(args.folders)
    except (AggregateError, CorruptResultsError) as error:
        print(f"aggregate: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    if args.csv:
        write_text(args.csv, data.to_csv(index=False), force=args.force)
    points = curve_points(data)
    columns = ["dataset", "codec", "clips", "compression_ratio", "bits_per_joint_frame", "max_err_cm", "mean_err_cm"]
    print(markdown_table(points[columns]))
    print(json.dumps({"rows": len(data), "configs": len(points)}))


if __name__ == "__main__":
    _main()
