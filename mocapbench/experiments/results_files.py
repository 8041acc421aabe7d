"""Machine-readable results of a report: one JSON per codec and dataset, one CSV of every row.

Layout inside a report folder::

    results/<dataset>/<codec>.json   # CompressAI-style: name, description, one entry per config, metric arrays
    results/rows.csv                 # every per-clip results row of the report (the frame the tables come from)

A JSON file holds::

    {"name": "quant-delta-zstd", "description": "...", "dataset": "synthetic", "family": "generic",
     "traits": {"codes_rotations": false, "needs_model": false, ...},
     "configs": [{"config_hash": "...", "clips": 3, "params": {"step_cm": 0.5, ...}}, ...],
     "results": {"compression_ratio": [...], "bits_per_joint_frame": [...], "max_err_cm": [...],
                 "mean_err_cm": [...], "p99_err_cm": [...], "kg_percent": [...], "encode_fps": [...], ...}}

``results`` arrays are aligned with ``configs`` (index i = config i), pooled over the dataset's clips as in
:func:`mocapbench.experiments.aggregate.curve_points`. ``mocapbench plot`` reads them back with :func:`load`.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Iterable

import pandas as pd

from mocapbench.io.safe_output import write_text

__all__ = ["write_results", "load", "load_many", "METRICS", "ResultsFileError"]

METRICS = ("compression_ratio", "bits_per_joint_frame", "max_err_cm", "mean_err_cm", "p99_err_cm", "kg_percent",
           "shell_max_err_cm", "shell_p99_err_cm", "encode_fps", "decode_fps", "encode_wall_fps", "decode_wall_fps",
           "model_bytes")
_TRAITS = ("codes_rotations", "needs_model", "random_access", "latency_frames")
RESULTS_DIR = "results"
ROWS_CSV = "rows.csv"


class ResultsFileError(ValueError):
    """A file given to ``mocapbench plot`` that is not a results JSON (the message names it and says why)."""


def _clean(value):
    """JSON-safe scalar: NaN/inf become None, numpy scalars plain Python."""
    if hasattr(value, "item") and callable(value.item):
        try:
            value = value.item()
        except (TypeError, ValueError):
            pass
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._+-]", "_", str(text)) or "_"


def _description(codec: str) -> str:
    try:
        from mocapbench.codecs import CODECS

        doc = (CODECS[codec].__doc__ or "").strip()
        return doc.splitlines()[0] if doc else ""
    except (ImportError, KeyError):
        return ""


def write_results(folder: Path, rows: pd.DataFrame, points: pd.DataFrame) -> list[Path]:
    """Write ``results/<dataset>/<codec>.json`` for every codec and dataset of ``points`` and ``results/rows.csv``.

    Returns the written paths (the CSV last).
    """
    base = Path(folder) / RESULTS_DIR
    written = []
    for (dataset, codec), group in points.groupby(["dataset", "codec"], sort=True):
        group = group.sort_values("bits_per_joint_frame")
        params = [c for c in group.columns if c.startswith("param_")]
        first = group.iloc[0]
        document = {
            "name": codec,
            "description": _description(codec),
            "dataset": dataset,
            "family": _clean(first.get("family")) if "family" in group else None,
            "traits": {k: _clean(first[k]) for k in _TRAITS if k in group},
            "configs": [
                {"config_hash": row["config_hash"], "clips": int(row["clips"]),
                 "params": {k[6:]: _clean(row[k]) for k in params if not pd.isna(row[k])}}
                for _, row in group.iterrows()
            ],
            "results": {m: [_clean(v) for v in group[m]] for m in METRICS if m in group},
        }
        path = base / _safe_name(dataset) / f"{_safe_name(codec)}.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text(path, json.dumps(document, indent=1) + "\n")
        written.append(path)
    base.mkdir(parents=True, exist_ok=True)
    frame = rows.drop(columns=[c for c in ("error_quantiles_cm",) if c in rows])
    written.append(write_text(base / ROWS_CSV, frame.to_csv(index=False)))
    return written


def load(path: str | Path) -> pd.DataFrame:
    """One results JSON as curve points: ``dataset, codec, family, config_hash, clips, param_*, <metrics>``.

    Raises
    ------
    ResultsFileError
        If the file is unreadable, not JSON, or lacks ``name`` / ``results``.
    """
    path = Path(path)
    try:
        document = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as error:
        raise ResultsFileError(f"{path}: cannot read it ({error})") from None
    except json.JSONDecodeError as error:
        raise ResultsFileError(f"{path}: not JSON (line {error.lineno}: {error.msg})") from None
    if not isinstance(document, dict) or "name" not in document or not isinstance(document.get("results"), dict):
        raise ResultsFileError(f"{path}: not a mocapbench results file (expected keys 'name' and 'results')")
    results = document["results"]
    lengths = {len(v) for v in results.values() if isinstance(v, list)}
    if len(lengths) != 1:
        raise ResultsFileError(f"{path}: the 'results' arrays differ in length ({sorted(lengths)})")
    (count,) = lengths
    frame = pd.DataFrame({k: pd.to_numeric(pd.Series(v, dtype=object), errors="coerce")
                          for k, v in results.items() if isinstance(v, list)})
    if "bits_per_joint_frame" not in frame:
        raise ResultsFileError(f"{path}: 'results' has no 'bits_per_joint_frame' array")
    configs = document.get("configs") or [{}] * count
    frame.insert(0, "codec", str(document["name"]))
    frame.insert(0, "dataset", str(document.get("dataset", "")))
    frame["family"] = document.get("family")
    frame["config_hash"] = [c.get("config_hash", str(i)) for i, c in enumerate(configs)]
    frame["clips"] = [c.get("clips", 0) for c in configs]
    for i, config in enumerate(configs):
        for key, value in (config.get("params") or {}).items():
            frame.loc[i, f"param_{key}"] = value
    frame["complete"] = True
    frame["source_file"] = str(path)
    return frame


def load_many(paths: Iterable[str | Path]) -> pd.DataFrame:
    """Every results JSON of ``paths``: files, or report folders (their ``results/**/*.json``)."""
    frames = []
    for path in paths:
        path = Path(path)
        if path.is_dir():
            found = sorted((path / RESULTS_DIR).rglob("*.json")) if (path / RESULTS_DIR).is_dir() else \
                sorted(path.rglob("*.json"))
            if not found:
                raise ResultsFileError(f"{path}: a folder without results/*/*.json (not a report folder)")
            frames += [load(p) for p in found]
        elif path.exists():
            frames.append(load(path))
        else:
            raise ResultsFileError(f"{path}: no such file or folder")
    if not frames:
        raise ResultsFileError("no results files given")
    return pd.concat(frames, ignore_index=True, sort=False)
