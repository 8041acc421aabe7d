"""The headline that decides: per dataset and per L∞ bound, codecs ranked by compression ratio, winner in a sentence.

Input: :func:`mocapbench.experiments.aggregate.curve_points` (one row per dataset, codec, config) and, optionally,
the failed jobs (:func:`mocapbench.experiments.aggregate.read_errors`). Each codec's best complete config under
the bound (highest ratio whose worst-clip L∞ stays below it) is ranked; a codec with no such config, a codec whose
every job failed and a codec that cannot run here (:data:`mocapbench.codecs.registry.UNAVAILABLE`) keep a row with
the reason instead of a rank. Codecs are ranked by the measured config (the stream a user gets); every ratio
*between* codecs (the winner's margin over the runner-up) is taken at one L∞, read off each codec's curve
(log-log interpolation on its Pareto front, as BD-rate does), never from two grid points at two errors. Beside rate and error the columns say what a user choosing a codec must know: does
it output rotations (can it write BVH/glTF), does it need a model fit for the skeleton (and how many bytes), its
latency in frames, random access, its family.
"""

from __future__ import annotations

from typing import Iterable, Sequence

import numpy as np
import pandas as pd

from mocapbench.experiments.animator_report import FLAG_COLUMN, HEADLINE_COLUMNS, animator_flag, headline_values

__all__ = ["DEFAULT_BOUNDS_CM", "TRAIT_COLUMNS", "EQUAL_CR", "EQUAL_FACTOR", "EQUAL_AT", "headline_table", "winner_sentences", "synthetic_only_note",
           "datasets_side_by_side",
           "is_synthetic", "failure_reasons"]

DEFAULT_BOUNDS_CM = (1.0, 3.0)
TRAIT_COLUMNS = ("codes_rotations", "family", "needs_model", "random_access", "latency_frames")

_METRICS = {
    "compression_ratio": "CR", "bits_per_joint_frame": "bits/joint/frame", "max_err_cm": "L∞ cm",
    "mean_err_cm": "mean cm", "encode_fps": "encode frames/s", "decode_fps": "decode frames/s (via Python)",
}


def bounds_with(extra: Iterable[float] | None) -> tuple[float, ...]:
    """1 cm, 3 cm and the user's bounds, sorted, without duplicates."""
    values = set(DEFAULT_BOUNDS_CM) | {float(b) for b in (extra or ())}
    bad = [b for b in values if not np.isfinite(b) or b <= 0]
    if bad:
        raise ValueError(f"L∞ bounds must be positive numbers of cm, got {sorted(bad)}")
    return tuple(sorted(values))


def is_synthetic(frame: pd.DataFrame) -> pd.Series:
    """Per row, whether its dataset is the embedded synthetic one (sinusoids, not motion capture)."""
    desc = frame["dataset_desc"].astype(str) if "dataset_desc" in frame else pd.Series("", index=frame.index)
    return desc.str.startswith("synthetic") | frame["dataset"].astype(str).str.startswith("synthetic")


def synthetic_only_note(rows: pd.DataFrame) -> str | None:
    """The report's first line when no real clip was measured (else None)."""
    if rows.empty or not is_synthetic(rows).all():
        return None
    return ("Synthetic data only: every number below is measured on generated sinusoidal skeletons, not on motion "
            "capture; they check that the codecs work, not how well they compress real motion (run with the CMU "
            "data for that).")


def _traits(codec: str, row: pd.Series | None) -> dict:
    """Trait columns from the result row when it holds them, else from the registered class's defaults."""
    values = {}
    if row is not None:
        values = {k: row[k] for k in TRAIT_COLUMNS if k in row.index and _present(row[k])}
    missing = [k for k in TRAIT_COLUMNS if k not in values]
    if missing:
        try:
            from mocapbench.codecs import create

            instance = create(codec)
            for key in missing:
                values[key] = getattr(instance, key)
        except Exception:  # noqa: BLE001 - unknown or unavailable here: the columns stay empty
            pass
    latency = values.get("latency_frames")
    return {
        "family": values.get("family", ""),
        "rotations (BVH/glTF)": _yes_no(values.get("codes_rotations")),
        "needs model": _yes_no(values.get("needs_model")),
        "latency frames": ("whole clip" if latency is not None and int(latency) < 0
                           else "" if latency is None else int(latency)),
        "random access": _yes_no(values.get("random_access")),
    }


def _yes_no(value) -> str:
    if value is None or not _present(value):
        return ""
    return "yes" if bool(value) else "no"


def _present(value) -> bool:
    try:
        return not pd.isna(value)
    except (TypeError, ValueError):
        return True


def failure_reasons(errors: pd.DataFrame) -> dict[tuple[str, str], str]:
    """``(dataset, codec) -> reason`` of failed jobs: the most frequent error message, with counts."""
    if errors is None or errors.empty or "codec" not in errors:
        return {}
    out = {}
    frame = errors.copy()
    if "dataset" not in frame:
        frame["dataset"] = ""
    frame["dataset"] = frame["dataset"].fillna("")
    frame["_message"] = frame["error"].astype(str).str.split("\n").str[0].str.slice(0, 160)
    for (dataset, codec), group in frame.groupby(["dataset", "codec"], sort=True):
        counts = group["_message"].value_counts()
        reason = counts.index[0]
        more = f" (+{len(counts) - 1} other error(s))" if len(counts) > 1 else ""
        # A codec that cannot carry a rig's tracks refused the clips (TrackRefusal): its reason, not a failure.
        refused = "stage" in group and bool((group["stage"] == "refused").all())
        out[(str(dataset), str(codec))] = f"{'refused' if refused else 'failed'} {len(group)}x: {reason}{more}"
    return out


def headline_table(
    points: pd.DataFrame,
    bounds: Sequence[float] = DEFAULT_BOUNDS_CM,
    errors: pd.DataFrame | None = None,
    unavailable: dict[str, str] | None = None,
    config_text=None,
) -> pd.DataFrame:
    """Ranked headline rows for every dataset and bound.

    Parameters
    ----------
    points : DataFrame
        ``curve_points`` rows (``dataset, codec, config_hash, complete, compression_ratio, max_err_cm, ...``).
    bounds : floats, cm
        L∞ bounds; a config qualifies when its worst-clip L∞ is strictly below the bound.
    errors : DataFrame, optional
        Failed jobs (``codec``, ``error``, ``dataset`` when known): a codec without any result on a dataset
        gets a row with the reason.
    unavailable : dict, optional
        Codecs that cannot run here and why (default: the registry's ``UNAVAILABLE``).
    config_text : callable(row) -> str, optional
        Renders a point's config (default: its ``param_*`` columns).

    Returns
    -------
    DataFrame
        ``dataset, L∞ bound, rank, codec, config, CR, bits/joint/frame, L∞ cm``, what animators see
        (:data:`mocapbench.experiments.animator_report.HEADLINE_COLUMNS` and the ``animators`` flag: a flagged
        codec keeps its rank), ``mean cm, encode frames/s, decode frames/s (via Python), rotations (BVH/glTF), needs model, model bytes, latency frames, random access, family,
        clips, note``; ranked rows first (rank 1 = highest ratio), then the rows without a rank, whose ``config``
        cell says why (no config under the bound, failed, not run on this dataset, unavailable here); ``note`` holds failures of ranked
        codecs' other jobs.
    """
    if unavailable is None:
        from mocapbench.codecs.registry import UNAVAILABLE

        unavailable = dict(UNAVAILABLE)
    config_text = config_text or _default_config_text
    failures = failure_reasons(errors) if errors is not None else {}
    datasets = sorted(set(points["dataset"]) if not points.empty else set())
    datasets += sorted({d for d, _ in failures if d and d not in datasets})
    out = []
    for dataset in datasets:
        out += _dataset_rows(points, dataset, bounds, failures, unavailable, config_text)
    return _as_table(out)


def _dataset_rows(points: pd.DataFrame, dataset: str, bounds: Sequence[float], failures: dict, unavailable: dict,
                  config_text) -> list[dict]:
    """The rows of one dataset, bound by bound; a bound that ranks what the previous one ranked is one line."""
    ds = points[points["dataset"] == dataset] if not points.empty else points
    measured = sorted(set(ds["codec"])) if not ds.empty else []
    # Measured on another dataset of this report but not on this one (left out of this dataset's sweep).
    everywhere = set(points["codec"]) if not points.empty else set()
    not_run = sorted(everywhere - set(measured))
    failed_only = sorted({c for (d, c) in failures if d in (dataset, "") and c not in measured})
    out = []
    previous = None  # (bound, the ranked codecs and configs) of the last bound
    for bound in bounds:
        ranked = _ranked_rows(ds, dataset, bound, measured, failures, config_text)
        unranked = [_unranked_row(ds, dataset, bound, codec, failures) for codec in measured
                    if _qualifying(ds, codec, bound).empty]
        unranked += _rows_without_results(dataset, measured, failed_only, not_run, failures, unavailable)
        same = [(row["codec"], row["config"], float(row["CR"])) for row in ranked]
        if ranked and previous is not None and previous[1] == same:
            # A wider bound that admits no other config repeats the table: one line says so instead.
            out.append({"dataset": dataset, "L∞ bound": f"< {bound:g} cm", "rank": "–", "codec": "",
                        "config": f"the same codecs and configs as under {previous[0]:g} cm (no codec has a "
                                  f"config between {previous[0]:g} and {bound:g} cm)"})
            continue
        previous = (bound, same)
        for rank, row in enumerate(ranked, 1):
            out.append({"dataset": dataset, "L∞ bound": f"< {bound:g} cm", "rank": rank, **row})
        for row in unranked:
            out.append({"dataset": dataset, "L∞ bound": f"< {bound:g} cm", "rank": "–", **row})
    return out


def _qualifying(ds: pd.DataFrame, codec: str, bound: float) -> pd.DataFrame:
    """A codec's complete configs whose worst-clip L∞ is strictly below ``bound`` cm."""
    group = ds[(ds["codec"] == codec) & ds["complete"]]
    return group[group["max_err_cm"] < bound]


def _ranked_rows(ds: pd.DataFrame, dataset: str, bound: float, measured: list[str], failures: dict,
                 config_text) -> list[dict]:
    """One row per codec with a config under ``bound``: its highest-ratio one, highest ratio first, with the
    equal-error columns filled."""
    ranked = []
    for codec in measured:
        ok = _qualifying(ds, codec, bound)
        if ok.empty:
            continue
        best = ok.loc[ok["compression_ratio"].idxmax()]
        row = {"codec": codec, "config": config_text(best)}
        row.update({label: best[column] for column, label in _METRICS.items() if column in best.index})
        row.update(_traits(codec, best))
        row.update({**headline_values(best), FLAG_COLUMN: animator_flag(best)})
        row["model bytes"] = int(best["model_bytes"]) if _present(best.get("model_bytes")) else 0
        row["clips"] = int(best["clips"])
        row["note"] = failures.get((dataset, codec)) or failures.get(("", codec), "")
        ranked.append(row)
    ranked.sort(key=lambda r: -float(r["CR"]))
    _equal_error_columns(ranked, ds, bound)
    return ranked


def _unranked_row(ds: pd.DataFrame, dataset: str, bound: float, codec: str, failures: dict) -> dict:
    """The row of a measured codec with no config under ``bound``: its lowest L∞ (and its failures) in ``config``."""
    best = ds[ds["codec"] == codec]
    least = best["max_err_cm"].min() if not best.empty else float("nan")
    note = f"no config under {bound:g} cm (lowest L∞ {least:.3g} cm)"
    if (dataset, codec) in failures:
        note += "; " + failures[(dataset, codec)]
    return {"codec": codec, **_traits(codec, best.iloc[0] if not best.empty else None), "config": note}


def _rows_without_results(dataset: str, measured: list[str], failed_only: list[str], not_run: list[str],
                          failures: dict, unavailable: dict) -> list[dict]:
    """The rows of codecs without a result on ``dataset``, the reason in ``config``: failed, not run, unavailable."""
    rows = []
    for codec in failed_only:
        reason = failures.get((dataset, codec)) or failures.get(("", codec), "failed")
        rows.append({"codec": codec, **_traits(codec, None), "config": reason})
    for codec in not_run:
        if codec not in failed_only:
            rows.append({"codec": codec, **_traits(codec, None),
                         "config": "not run on this dataset (left out of its sweep)"})
    for codec, reason in sorted(unavailable.items()):
        if codec not in measured and codec not in failed_only:
            rows.append({"codec": codec, **_traits(codec, None), "config": f"unavailable here: {reason}"})
    return rows


def datasets_side_by_side(table: pd.DataFrame) -> pd.DataFrame:
    """The headline of every dataset in one table: per codec, its ratio and L∞ under each bound, dataset by dataset.

    ``table`` is :func:`headline_table`'s. A row per codec ranked anywhere, in the order of the first dataset's
    first bound (codecs not ranked there after, by the next dataset and bound), then ``rotations (BVH/glTF)``,
    then for each dataset and bound ``<dataset> CR < b cm`` and ``<dataset> L∞ cm < b cm`` (the codec's headline
    config there, L∞ cut to 3 significant digits, never rounded up to the bound; ``–`` where it has none). A bound
    whose rows say "the same codecs and configs as under" the smaller one repeats that bound's values.
    """
    if table.empty:
        return pd.DataFrame(columns=["codec", "rotations (BVH/glTF)"])
    cells: dict[str, dict[str, str]] = {}
    rotations: dict[str, str] = {}
    orders: list[dict[str, int]] = []
    columns = []
    for dataset in dict.fromkeys(table["dataset"]):
        previous: dict[str, tuple[str, str]] = {}
        for bound, group in table[table["dataset"] == dataset].groupby("L∞ bound", sort=False):
            ranked = group[group["rank"] != "–"]
            same = ranked.empty and group["config"].astype(str).str.startswith("the same codecs").any()
            values = previous if same else {str(r["codec"]): (_ratio(r["CR"]), _cut(float(r["L∞ cm"])))
                                            for _, r in ranked.iterrows()}
            cr, linf = f"{dataset} CR {bound}", f"{dataset} L∞ cm {bound}"
            columns += [cr, linf]
            for codec, (ratio, error) in values.items():
                cells.setdefault(codec, {}).update({cr: ratio, linf: error})
            for _, r in ranked.iterrows():
                rotations.setdefault(str(r["codec"]), str(r["rotations (BVH/glTF)"]))
            orders.append({codec: order for order, codec in enumerate(values)})
            previous = values
    codecs = sorted(cells, key=lambda codec: [order.get(codec, len(cells)) for order in orders])
    return pd.DataFrame([{"codec": codec, "rotations (BVH/glTF)": rotations.get(codec, ""),
                          **{column: cells[codec].get(column, "–") for column in columns}} for codec in codecs],
                        columns=["codec", "rotations (BVH/glTF)", *columns])


def _cut(value: float, digits: int = 3) -> str:
    """``value`` cut (not rounded) to ``digits`` significant digits: an L∞ under a bound never reads as the bound."""
    if not np.isfinite(value) or value <= 0:
        return f"{value:g}"
    decimals = digits - 1 - int(np.floor(np.log10(value)))
    cut = np.floor(value * 10.0**decimals) / 10.0**decimals
    return f"{cut:.{max(decimals, 0)}f}"


def _as_table(out: list[dict]) -> pd.DataFrame:
    """The rows as a frame with every headline column, in the order a reader needs them."""
    # What decides first (rate, error, rotations, model, latency), then speeds and the rest: the leading
    # columns fit a laptop screen, the others scroll.
    columns = ["dataset", "L∞ bound", "rank", "codec", "config", "CR", EQUAL_CR, EQUAL_FACTOR, EQUAL_AT,
               "bits/joint/frame", "L∞ cm", *HEADLINE_COLUMNS.values(), FLAG_COLUMN,
               "rotations (BVH/glTF)", "needs model", "latency frames", "random access", "decode frames/s (via Python)",
               "encode frames/s", "mean cm", "model bytes", "family", "clips", "note"]
    table = pd.DataFrame(out)
    for column in columns:
        if column not in table:
            table[column] = (np.nan if column in (*_METRICS.values(), EQUAL_CR, EQUAL_FACTOR, EQUAL_AT,
                                                  *HEADLINE_COLUMNS.values()) else "")
    table[FLAG_COLUMN] = table[FLAG_COLUMN].fillna("")
    return table[columns]


#: Columns of the comparison at equal error: each codec's ratio read off its own curve at exactly the bound, and
#: rank 1's ratio over this codec's at the largest L∞ <= the bound both curves reach (both interpolated in log-log
#: on the Pareto fronts, :func:`mocapbench.experiments.bdrate.rate_at_error`). The ``CR`` column is the best
#: measured config under the bound (the stream a user gets); a ratio between two codecs is never taken from it,
#: because two grid points sit at two different errors.
EQUAL_CR = "CR at L∞ = bound"
EQUAL_FACTOR = "rank 1 ÷ this at equal L∞"
EQUAL_AT = "equal L∞ cm"


def _curve(points: pd.DataFrame, codec: str) -> tuple[np.ndarray, np.ndarray]:
    """``(1 / compression ratio, L∞ cm)`` of a codec's complete configs: a rate curve in the space BD-rate uses."""
    group = points[(points["codec"] == codec) & points["complete"]]
    ratio = group["compression_ratio"].to_numpy(float)
    with np.errstate(divide="ignore"):
        return 1.0 / ratio, group["max_err_cm"].to_numpy(float)


def _equal_error_columns(ranked: list[dict], points: pd.DataFrame, bound: float) -> None:
    """Fill :data:`EQUAL_CR`, :data:`EQUAL_FACTOR` and :data:`EQUAL_AT` of the ranked rows (rank 1 first)."""
    from mocapbench.experiments.bdrate import common_error, rate_at_error

    curves = {row["codec"]: _curve(points, row["codec"]) for row in ranked}
    for row in ranked:
        row[EQUAL_CR] = 1.0 / rate_at_error(*curves[row["codec"]], bound)
    if not ranked:
        return
    first = curves[ranked[0]["codec"]]
    for row in ranked[1:]:
        mine = curves[row["codec"]]
        at = common_error([first, mine], bound)
        row[EQUAL_AT] = at
        row[EQUAL_FACTOR] = rate_at_error(*mine, at) / rate_at_error(*first, at) if np.isfinite(at) else np.nan


def _default_config_text(row: pd.Series) -> str:
    keys = [k for k in row.index if k.startswith("param_") and _present(row[k])]
    return ", ".join(f"{k[6:]}={row[k]}" for k in keys)


def _ratio(value: float) -> str:
    return f"{value:,.3g}:1" if value < 1000 else f"{value:,.0f}:1"


def winner_sentences(table: pd.DataFrame) -> list[str]:
    """One sentence per (dataset, bound): the winner, its margin over the runner-up, the best rotation codec."""
    sentences = []
    if table.empty:
        return sentences
    for (dataset, bound), group in table.groupby(["dataset", "L∞ bound"], sort=False):
        ranked = group[group["rank"] != "–"]
        where = f"{dataset}, L∞ {bound}"
        if ranked.empty and len(group) == 1 and group["codec"].iloc[0] == "":
            sentences.append(f"{where}: {group['config'].iloc[0]}.")
            continue
        if ranked.empty:
            sentences.append(f"{where}: no codec stays under the bound.")
            continue
        first = ranked.iloc[0]
        text = (f"{where}: {first['codec']} wins at {_ratio(float(first['CR']))} "
                f"({float(first['bits/joint/frame']):.3g} bits/joint/frame, L∞ {float(first['L∞ cm']):.3g} cm)")
        if len(ranked) > 1:
            second = ranked.iloc[1]
            factor, at = float(second[EQUAL_FACTOR]), float(second[EQUAL_AT])
            if np.isfinite(factor):
                text += (f"; at equal L∞ ({at:.3g} cm, read off each codec's curve) it is {factor:.3g}x the "
                         f"runner-up {second['codec']} (best config under the bound {_ratio(float(second['CR']))})")
            else:
                text += (f"; the runner-up {second['codec']} ({_ratio(float(second['CR']))}) cannot be compared "
                         f"with it at equal L∞: their measured L∞ ranges do not overlap")
        if first["rotations (BVH/glTF)"] != "yes":
            rotations = ranked[ranked["rotations (BVH/glTF)"] == "yes"]
            if rotations.empty:
                text += "; no codec that outputs rotations (BVH/glTF) stays under the bound"
            else:
                best = rotations.iloc[0]
                text += (f"; it outputs joint positions only: the best codec that outputs rotations (BVH/glTF) is "
                         f"{best['codec']} at {_ratio(float(best['CR']))}")
        if first[FLAG_COLUMN]:
            text += f"; flagged for animators ({first[FLAG_COLUMN]})"
        if first["needs model"] == "yes":
            text += "; the winner needs a model fit for this skeleton"
        sentences.append(text + ".")
    return sentences
