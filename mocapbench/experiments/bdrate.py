"""Bjontegaard-delta rate of every codec against an anchor codec, with the ``bjontegaard`` package.

BD-rate averages, over the quality range both curves cover, how much more (positive) or less (negative) rate a
codec needs than the anchor for the same quality (Bjontegaard, VCEG-M33, 2001). The package expects quality to
rise with rate (PSNR), so quality here is ``-log(error)`` with the error in cm; rate is bits per joint per frame
of the pooled dataset (:func:`mocapbench.experiments.aggregate.curve_points`). Each curve is first reduced to
its Pareto front (more rate must buy strictly less error), and lossless points (error 0) are left out because
``-log(0)`` is infinite.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

__all__ = ["pareto_front", "rate_at_error", "common_error", "bd_rate_percent", "bd_rate_table", "DEFAULT_ANCHOR"]

# The strongest generic pipeline (channel-major, order-1/2 prediction, byte shuffle, zstd): what a user would
# otherwise build from off-the-shelf tools, so a negative BD-rate means beating the best generic baseline.
DEFAULT_ANCHOR = "quant-pred-zstd"


def pareto_front(rate: np.ndarray, error: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points of a curve where every increase of ``rate`` strictly lowers ``error``.

    Parameters
    ----------
    rate : ndarray, shape (N,), float, bits per joint per frame
    error : ndarray, shape (N,), float, cm (points with error <= 0 or non-finite values are dropped)

    Returns
    -------
    rate, error : ndarray, shape (M,), sorted by increasing rate and strictly decreasing error.
    """
    rate, error = np.asarray(rate, float), np.asarray(error, float)
    keep = np.isfinite(rate) & np.isfinite(error) & (error > 0) & (rate > 0)
    order = np.lexsort((error[keep], rate[keep]))
    rate, error = rate[keep][order], error[keep][order]
    out_rate, out_error = [], []
    for r, e in zip(rate, error):
        if out_error and e >= out_error[-1]:
            continue
        if out_rate and r == out_rate[-1]:
            continue
        out_rate.append(r)
        out_error.append(e)
    return np.array(out_rate), np.array(out_error)


def rate_at_error(rate, error, target_cm: float) -> float:
    """The rate of a curve at exactly ``target_cm`` of error, interpolated on its Pareto front in log-log.

    Between two front points, ``log(rate)`` is linear in ``log(error)`` (the space BD-rate integrates in), so a
    codec's rate at an L∞ it was not run at is read off its own curve, never taken from the nearest grid point.

    Parameters
    ----------
    rate, error : array-like, shape (N,)
        A codec's points: any positive rate measure (bits per joint per frame, or 1 / compression ratio) and the
        error in cm.
    target_cm : float

    Returns
    -------
    float
        The rate at ``target_cm``; NaN when the front does not span it (no extrapolation).
    """
    front_rate, front_error = pareto_front(rate, error)
    if not len(front_rate) or not front_error.min() <= target_cm <= front_error.max():
        return float("nan")
    # np.interp needs increasing x: the front's error falls as its rate rises, so read it backwards.
    log_rate = np.interp(np.log(target_cm), np.log(front_error[::-1]), np.log(front_rate[::-1]))
    return float(np.exp(log_rate))


def common_error(curves, at_most_cm: float) -> float:
    """The largest error <= ``at_most_cm`` that every curve's Pareto front spans (NaN when there is none).

    Parameters
    ----------
    curves : iterable of (rate, error) pairs of arrays
    at_most_cm : float
        The bound the comparison is made at: codecs are compared at it when they all reach it, else at the
        largest error below it they share.
    """
    low, high = 0.0, float(at_most_cm)
    for rate, error in curves:
        _, front_error = pareto_front(rate, error)
        if not len(front_error):
            return float("nan")
        low, high = max(low, front_error.min()), min(high, front_error.max())
    return high if high >= low else float("nan")


def bd_rate_percent(anchor_rate, anchor_error, test_rate, test_error, method: str = "pchip") -> tuple[float, str]:
    """BD-rate (%) of test against anchor, quality = ``-log(error)``; returns ``(value, note)``.

    ``value`` is NaN with a note saying why when it cannot be computed (fewer than 2 Pareto points on a curve,
    or curves whose error ranges do not overlap); the note also reports a partial overlap.
    """
    from bjontegaard import bd_rate

    ar, ae = pareto_front(anchor_rate, anchor_error)
    tr, te = pareto_front(test_rate, test_error)
    if len(ar) < 2 or len(tr) < 2:
        return float("nan"), f"needs >= 2 lossy Pareto points per curve (anchor {len(ar)}, test {len(tr)})"
    qa, qt = -np.log(ae), -np.log(te)
    low, high = max(qa.min(), qt.min()), min(qa.max(), qt.max())
    if high <= low:
        return float("nan"), "error ranges do not overlap"
    overlap = (high - low) / (max(qa.max(), qt.max()) - min(qa.min(), qt.min()))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        value = float(bd_rate(ar, qa, tr, qt, method=method, require_matching_points=False, min_overlap=0))
    note = f"error overlap {overlap:.0%}" + (" (partial: read with care)" if overlap < 0.5 else "")
    return value, note


def bd_rate_table(points: pd.DataFrame, anchor: str = DEFAULT_ANCHOR, error: str = "max_err_cm") -> pd.DataFrame:
    """BD-rate of every codec against ``anchor`` per dataset, from :func:`curve_points` rows.

    Returns a table with ``dataset, codec, anchor, bd_rate_percent, note``; the anchor's own row is 0 by
    definition, a dataset without the anchor gets a note saying so.
    """
    rows = []
    for dataset, group in points.groupby("dataset", sort=True):
        codecs = sorted(group["codec"].unique())
        base = group[group["codec"] == anchor]
        for codec in codecs:
            if codec == anchor:
                rows.append((dataset, codec, anchor, 0.0, "anchor"))
                continue
            if base.empty:
                rows.append((dataset, codec, anchor, float("nan"), f"anchor {anchor} not in the results"))
                continue
            test = group[group["codec"] == codec]
            value, note = bd_rate_percent(
                base["bits_per_joint_frame"], base[error], test["bits_per_joint_frame"], test[error]
            )
            rows.append((dataset, codec, anchor, value, note))
    return pd.DataFrame(rows, columns=["dataset", "codec", "anchor", f"bd_rate_percent ({error})", "note"])
