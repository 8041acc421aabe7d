"""Report figures, each saved as PNG and SVG and closed (never shown).

* Every codec has one colour and one marker, the same in every report whatever subset is plotted
  (:func:`codec_style`: a fixed table for the codecs known when this was written, a stable hash of the name for
  any later one); the line style tells its family apart (paper: solid, generic baseline: dashed, production
  reference: dash-dot, mocapbench's own: thick solid), read from the codec's ``family`` trait.
* One metric per figure: bits per joint per frame against L∞, against the mean error, against KG, and against
  ACL's shell error when the rows carry it (:data:`DISTORTIONS`).
* Lossless points (error under :data:`LOSSLESS_CM`, float32 rounding) are kept off the log axes and noted at
  the left edge with their rate.
* Text is at least 10 px high when the figure is shown at the report's page width (:data:`PAGE_PX`): the figures
  are at most :data:`MAX_WIDTH_IN` wide and their fonts at least 10 pt, and :func:`smallest_text_px` checks it.
* Pictures: per-codec error heat maps, each on its own colour scale; a skeleton overlay zoomed on each codec's
  worst joint with joints coloured by error; distributions over clips (ratio per clip at each bound, max error
  per clip, share of samples under the bound).
"""

from __future__ import annotations

import hashlib
import logging
from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")  # files only, also on a machine without a display

import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.transforms import blended_transform_factory  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from mocapbench.io.safe_output import open_output  # noqa: E402

log = logging.getLogger(__name__)

__all__ = ["codec_style", "family_linestyle", "DISTORTIONS", "rd_metric_figure", "rd_per_clip_figure",
           "clip_distribution_figure", "error_heatmap_figure", "skeleton_overlay_figure", "smallest_text_px",
           "published_points_on", "LOSSLESS_CM", "PAGE_PX", "FigurePool"]

# The report's content width in CSS px in a 1024 px window (the narrowest the browser check tries; the page's
# max-width is 1200 px) and the widest figure, in inches.
PAGE_PX = 990
MAX_WIDTH_IN = 12.0
BASE_FONT_PT = 11
DPI = 150
# Below this L∞ (cm) a point is lossless up to float32 rounding: it cannot sit on a log axis honestly.
LOSSLESS_CM = 1e-3

plt.rcParams.update({"font.size": BASE_FONT_PT, "axes.titlesize": BASE_FONT_PT + 1, "axes.labelsize": BASE_FONT_PT,
                     "xtick.labelsize": 10, "ytick.labelsize": 10, "legend.fontsize": 10,
                     "figure.titlesize": BASE_FONT_PT + 2, "svg.fonttype": "none"})

DISTORTIONS = (
    ("max_err_cm", "L∞ joint error (cm)"),
    ("mean_err_cm", "mean joint error (cm)"),
    ("kg_percent", "KG distortion (%)"),
    ("shell_max_err_cm", "ACL shell error, max (cm)"),
)

# Fixed colours and markers: distinct hues (Okabe-Ito, Tol's bright and muted palettes) for the codecs known
# now; any other codec gets one from the name's hash (stable across runs and subsets).
_KNOWN = {
    "raw-zstd": ("#000000", "X"),
    "quant-delta-zstd": ("#E69F00", "s"),
    "quant-rot-zstd": ("#56B4E9", "D"),
    "quant-pred-zstd": ("#AA7700", "8"),
    "svd": ("#009E73", "^"),
    "fourier-mlp-int": ("#CC79A7", "v"),
    "fourier-mlp-dct": ("#882255", "<"),
    "lsdt-frame": ("#0072B2", "o"),
    "lsdt-clip": ("#332288", "p"),
    "dct-spatial-frame": ("#D55E00", ">"),
    "dct-spatial-clip": ("#AA4499", "h"),
    "dwt-spatial-frame": ("#999933", "P"),
    "dwt-spatial-clip": ("#44AA99", "*"),
    "pga-ik": ("#661100", "d"),
    "mcb-linf": ("#EE3377", "o"),
    "mcb-rot": ("#117733", "s"),
    "acl": ("#4477AA", "D"),
}
_SPARE_COLOURS = ("#88CCEE", "#DDCC77", "#CC6677", "#AA3377", "#228833", "#66CCEE", "#EE7733", "#0077BB",
                  "#33BBEE", "#EE6677", "#BBBBBB", "#CCBB44")
_SPARE_MARKERS = "os^vD<>pPXh*d"
_FAMILY_STYLE = {"paper": ("-", 1.5), "generic": ("--", 1.5), "production": ("-.", 1.8), "mocapbench": ("-", 3.0)}


def family_linestyle(family: str | None) -> tuple[str, float]:
    """``(linestyle, linewidth)`` of a codec family (unknown: dotted)."""
    return _FAMILY_STYLE.get(str(family), (":", 1.5))


def _family(codec: str) -> str | None:
    try:
        from mocapbench.codecs import CODECS
    except ImportError:
        return None
    cls = CODECS.get(codec)
    return getattr(cls, "family", None) if cls is not None else None


def codec_style(codec: str, family: str | None = None) -> dict:
    """Matplotlib style of ``codec``: fixed colour and marker, line style of its family (default: registry's)."""
    base, _, source = codec.partition(" [")  # `mocapbench plot` labels a codec from a second run "name [run]"
    if base in _KNOWN:
        color, marker = _KNOWN[base]
        if source:
            marker = _SPARE_MARKERS[int(hashlib.sha1(codec.encode()).hexdigest(), 16) % len(_SPARE_MARKERS)]
    else:
        digest = int(hashlib.sha1(codec.encode()).hexdigest(), 16)
        color = _SPARE_COLOURS[digest % len(_SPARE_COLOURS)]
        marker = _SPARE_MARKERS[(digest // len(_SPARE_COLOURS)) % len(_SPARE_MARKERS)]
    linestyle, linewidth = family_linestyle(family or _family(base))
    return {"color": color, "marker": marker, "linestyle": linestyle, "linewidth": linewidth}


def smallest_text_px(fig, page_px: float = PAGE_PX, draw: bool = True) -> float:
    """Height in CSS px of the smallest font of ``fig`` when its saved image (tight bounding box, as
    :func:`_save` writes it) is shown ``page_px`` wide or at its natural size if that is narrower.

    ``draw=False`` when the figure was just drawn (saved): its layout is done, and a draw costs as much as a save.
    """
    if draw:
        fig.canvas.draw()
    width_in = fig.get_tightbbox(fig.canvas.get_renderer()).width
    scale = min(1.0, page_px / (width_in * DPI)) * DPI / 72.0  # px per pt on the page
    sizes = [t.get_fontsize() for t in fig.findobj(matplotlib.text.Text) if t.get_text().strip() and t.get_visible()]
    return min(sizes) * scale if sizes else float("inf")


class FigurePool:
    """Figures drawn in ``workers`` processes of their own while the caller goes on (a report's other sections).

    :meth:`draw` returns a ``concurrent.futures.Future`` of the figure function's result; with ``workers`` 1 the
    function runs at once, here, and the future is already done (an error is raised at once, as without a pool).
    The workers are started fresh (``spawn``) and draw with the same functions on the same data (pickled), so the
    files are the ones this process would write. They ignore Ctrl-C: it is this process's to handle (leaving the
    pool then waits for the figures under way, instead of each worker dying with a traceback of its own). Use it as
    a context manager: leaving it waits for every figure.
    """

    def __init__(self, workers: int = 1) -> None:
        self.workers = max(1, int(workers))
        self._pool = None
        if self.workers > 1:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            self._pool = ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context("spawn"),
                                             initializer=_ignore_interrupt)

    def draw(self, function, *args, **kwargs):
        from concurrent.futures import Future

        if self._pool is not None:
            return self._pool.submit(function, *args, **kwargs)
        done: Future = Future()
        done.set_result(function(*args, **kwargs))
        return done

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def __enter__(self) -> "FigurePool":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _ignore_interrupt() -> None:
    """A figure worker's start: Ctrl-C (SIGINT, sent to the whole process group) is left to the parent."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _save(fig, path: Path) -> Path:
    """Write ``path`` (PNG) and the same figure as SVG beside it; warn about text under 10 px at page width."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        for target, kind in ((path, "png"), (path.with_suffix(".svg"), "svg")):
            with open_output(target, "wb") as handle:
                fig.savefig(handle, format=kind, dpi=DPI, bbox_inches="tight")
            if kind == "png":  # measured on the layout the PNG was drawn with, without a draw of its own
                smallest = smallest_text_px(fig, draw=False)
                if smallest < 10.0:  # e.g. a legend of very long labels widened the figure; the browser check fails
                    log.warning("%s: smallest text %.1f px at a %d px page (under 10 px)", path.name, smallest,
                                PAGE_PX)
    finally:
        plt.close(fig)
    return path


def _plain_log(axis) -> None:
    """Tick labels of a log axis in plain numbers (``0.5``, ``20``), not ``2×10^1``; 2 and 5 between decades."""
    from matplotlib.ticker import FuncFormatter, LogLocator

    def label(value, _position):
        mantissa = value / 10 ** np.floor(np.log10(value)) if value > 0 else 0
        return f"{float(f'{value:.2g}'):,g}" if round(mantissa) in (1, 2, 5) else ""

    axis.set_major_locator(LogLocator(base=10))
    axis.set_minor_locator(LogLocator(base=10, subs=(2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(label))
    axis.set_minor_formatter(FuncFormatter(label))


def _include(ax, values: Sequence[float]) -> None:
    """Widen the x range of a log axis so that every value of ``values`` (a bound) is inside with a margin."""
    if not values:
        return
    low, high = ax.get_xlim()
    ax.set_xlim(min(low, min(values) / 1.3), max(high, max(values) * 1.3))


def _front(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Mask of the points no other point beats on both axes (lower error ``x``, lower rate ``y``)."""
    keep = np.ones(len(x), dtype=bool)
    for i in range(len(x)):
        better = (x <= x[i]) & (y <= y[i]) & ((x < x[i]) | (y < y[i]))
        keep[i] = not better.any()
    return keep


def _curve(ax, frame: pd.DataFrame, x: str, y: str, style: dict, label: str) -> list[tuple[str, float]]:
    """Markers for every lossy point, a line through the Pareto front; returns lossless points (label, rate)."""
    frame = frame[np.isfinite(frame[x].astype(float)) & np.isfinite(frame[y].astype(float))]
    lossless = frame[frame[x] < LOSSLESS_CM] if x.endswith("_cm") else frame[frame[x] <= 0]
    lossy = frame.drop(lossless.index)
    out = [(label, float(r)) for r in lossless[y]]
    if lossy.empty:
        return out
    xs, ys = lossy[x].to_numpy(float), lossy[y].to_numpy(float)
    front = _front(xs, ys)
    order = np.argsort(xs[front])
    ax.plot(xs[front][order], ys[front][order], markersize=6, label=label, **style)
    if (~front).any():
        ax.plot(xs[~front], ys[~front], linestyle="none", markersize=5, alpha=0.45, marker=style["marker"],
                color=style["color"])
    return out


def _note_lossless(ax, lossless: list[tuple[str, float]]) -> None:
    """Mark lossless points at the left edge (x in axes coordinates, y in data) with their rate."""
    transform = blended_transform_factory(ax.transAxes, ax.transData)
    previous = None
    offset = 0.0
    for label, rate in sorted(lossless, key=lambda item: item[1]):
        # Notes at nearly the same rate are stacked downwards instead of printed over each other.
        offset = offset - 13.0 if previous is not None and rate < previous * 1.15 else 0.0
        previous = rate
        ax.plot([0.0], [rate], marker="<", color="black", markersize=9, transform=transform, clip_on=False)
        ax.annotate(f"{label}: lossless, {rate:.3g} bits", (0.0, rate), xycoords=transform, xytext=(6, offset),
                    textcoords="offset points", va="center", fontsize=10)


def published_points_on(ax, metric: str, points: Sequence[dict]) -> bool:
    """Plot published reference points of ``metric`` (black stars, labelled); True if any was drawn."""
    drawn = False
    for point in points:
        if point.get("metric") != metric:
            continue
        if point.get("bits_range"):
            low, high = point["bits_range"]
            ax.plot([point["error"]] * 2, [low, high], color="black", linewidth=3, alpha=0.5, zorder=4)
        ax.plot([point["error"]], [point["bits_per_joint_frame"]], marker="*", markersize=15, color="black",
                markerfacecolor="white", linestyle="none", zorder=5)
        ax.annotate(point["label"], (point["error"], point["bits_per_joint_frame"]), xytext=(8, 4),
                    textcoords="offset points", fontsize=10)
        drawn = True
    return drawn


def rd_metric_figure(points: pd.DataFrame, title: str, metric: str, path: Path,
                     bounds: Sequence[float] = (), published: Sequence[dict] = ()) -> Path | None:
    """Bits per joint per frame (log) against one distortion (log), every codec of ``points``.

    Parameters
    ----------
    points : DataFrame
        Curve points (``codec``, ``bits_per_joint_frame``, ``metric``; ``family`` if known).
    metric : str
        One of :data:`DISTORTIONS`' columns. Returns None when no row has it.
    bounds : floats, cm
        Vertical guides on an L∞ figure.
    published : dicts
        Reference points (:mod:`mocapbench.experiments.published`) drawn as black stars.
    """
    if metric not in points or not points[metric].notna().any():
        return None
    label = dict(DISTORTIONS).get(metric, metric)
    # The legend sits right of the axes, one line per curve: the figure grows with it (an overlay of two runs
    # of 17 codecs has 34 curves), so the axes never collapse under it.
    entries = points["codec"].nunique() + bool(published)
    fig, ax = plt.subplots(figsize=(10, max(6.0, 0.3 * entries + 1.5)), layout="constrained")
    lossless: list[tuple[str, float]] = []
    for codec, group in points.groupby("codec", sort=True):
        family = group["family"].dropna().iloc[0] if "family" in group and group["family"].notna().any() else None
        lossless += _curve(ax, group, metric, "bits_per_joint_frame", codec_style(codec, family),
                           f"{codec} ({family})" if family else codec)
    published_points_on(ax, metric, published)
    ax.set_xscale("log")
    ax.set_yscale("log")
    if metric == "max_err_cm":
        _include(ax, list(bounds))
    _plain_log(ax.xaxis)
    _plain_log(ax.yaxis)
    ax.set_xlabel(label + ", log scale (lower is better)")
    ax.set_ylabel("bits per joint per frame, log scale")
    ax.grid(True, which="both", alpha=0.3)
    if metric == "max_err_cm":
        for bound in bounds:
            ax.axvline(bound, color="grey", linestyle=":", linewidth=1.2)
            ax.annotate(f"{bound:g} cm", (bound, 1.0), xycoords=("data", "axes fraction"), xytext=(3, -14),
                        textcoords="offset points", fontsize=10, color="grey")
    _note_lossless(ax, lossless)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), title="codec (line: family)", frameon=False)
    ax.set_title(f"{title}: bits/joint/frame vs {label}")
    return _save(fig, path)


def rd_per_clip_figure(rows: pd.DataFrame, dataset: str, path: Path, max_clips: int = 12) -> Path:
    """Bits per joint per frame against L∞, one panel per clip (at most ``max_clips``), every codec."""
    clips = sorted(rows["clip"].unique())[:max_clips]
    cols = min(3, len(clips))
    nrows = int(np.ceil(len(clips) / cols))
    fig, axes = plt.subplots(nrows, cols, figsize=(min(MAX_WIDTH_IN, 4.6 * cols), 3.8 * nrows), squeeze=False,
                             layout="constrained")
    for ax, clip in zip(axes.flat, clips):
        lossless = []
        for codec, group in rows[rows["clip"] == clip].groupby("codec", sort=True):
            family = group["family"].dropna().iloc[0] if "family" in group and group["family"].notna().any() else None
            lossless += _curve(ax, group, "max_err_cm", "bits_per_joint_frame", codec_style(codec, family), codec)
        ax.set_xscale("log")
        ax.set_yscale("log")
        _plain_log(ax.xaxis)
        _plain_log(ax.yaxis)
        ax.set_title(str(clip))
        ax.set_xlabel("L∞ (cm)")
        ax.set_ylabel("bits/joint/frame")
        ax.grid(True, which="both", alpha=0.3)
    for ax in list(axes.flat)[len(clips):]:
        ax.axis("off")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside right center", frameon=False)
    fig.suptitle(f"{dataset}: per clip, bits/joint/frame vs L∞ (lossless points left out)")
    return _save(fig, path)


def clip_distribution_figure(per_clip: pd.DataFrame, dataset: str, bound: float, path: Path,
                             panels: Sequence[tuple[str, str, bool]] | None = None) -> Path | None:
    """Distributions over clips at one bound: ratio per clip, max error per clip, share of samples under it.

    Parameters
    ----------
    per_clip : DataFrame
        One row per (codec, clip) of each codec's headline config under ``bound``: ``codec``, ``clip``,
        ``compression_ratio``, ``max_err_cm``, ``share_under_bound`` (0-1), or the columns of ``panels``.
    panels : sequence of (column, axis label, log scale), optional
        The panels, left to right (default: the three above); a clip whose value is NaN is left out.
    """
    if per_clip.empty:
        return None
    codecs = sorted(per_clip["codec"].unique(), key=lambda c: -per_clip.loc[per_clip["codec"] == c,
                                                                              "compression_ratio"].median())
    panels = panels or (("compression_ratio", "ratio per clip (log)", True),
                        ("max_err_cm", "max error per clip (cm)", False),
                        ("share_under_bound", f"share of samples under {bound:g} cm (%)", False))
    fig, axes = plt.subplots(1, len(panels), figsize=(MAX_WIDTH_IN, 0.45 * len(codecs) + 2.2), layout="constrained",
                             sharey=True)
    rng = np.random.default_rng(0)
    for ax, (column, label, log) in zip(axes, panels):
        for y, codec in enumerate(codecs):
            values = per_clip.loc[per_clip["codec"] == codec, column].to_numpy(float)
            values = values[np.isfinite(values)]
            if column == "share_under_bound":
                values = 100 * values
            style = codec_style(codec)
            jitter = rng.uniform(-0.18, 0.18, len(values))
            ax.plot(values, y + jitter, linestyle="none", marker=style["marker"], color=style["color"],
                    markersize=6, alpha=0.8)
            if len(values):
                ax.plot([np.median(values)] * 2, [y - 0.35, y + 0.35], color="black", linewidth=2)
        if log:
            ax.set_xscale("log")
            _plain_log(ax.xaxis)
        if column == "share_under_bound":
            shares = 100 * per_clip[column].dropna().to_numpy(float)
            ax.set_xlim(max(0.0, (shares.min() if len(shares) else 0.0) - 2.0), 100.5)
        if column == "max_err_cm":
            ax.axvline(bound, color="grey", linestyle=":", linewidth=1.2)
        ax.set_xlabel(label)
        ax.grid(True, axis="x", which="both", alpha=0.3)
    axes[0].set_yticks(range(len(codecs)), codecs)
    axes[0].invert_yaxis()
    clips = per_clip["clip"].nunique()
    fig.suptitle(f"{dataset}: each codec's headline config under {bound:g} cm, over {clips} clip(s) "
                 "(bar: median)")
    return _save(fig, path)


def error_heatmap_figure(examples: list[tuple[str, dict]], path: Path) -> Path:
    """Per-joint × time error (cm) of one clip, one panel per codec, each on its own colour scale.

    Parameters
    ----------
    examples : list of (label, npz dict with ``original``, ``decoded`` (F, J, 3) cm, ``names``, ``clip``, ``fps``)
    """
    fig, axes = plt.subplots(len(examples), 1, figsize=(12, 2.9 * len(examples)), squeeze=False,
                             layout="constrained")
    for ax, (label, example) in zip(axes[:, 0], examples):
        error = np.linalg.norm(example["original"] - example["decoded"], axis=-1)  # (F, J) cm
        top = float(error.max()) or 1e-9
        image = ax.imshow(error.T, aspect="auto", interpolation="nearest", cmap="viridis", vmin=0, vmax=top,
                          extent=(0, error.shape[0] / float(example["fps"]), error.shape[1] - 0.5, -0.5))
        peak = f"max {float(error.max()):.3g} cm (own colour scale)" if error.max() > 0 else "no error (lossless)"
        ax.set_title(f"{label}: clip {example['clip']}, {peak}")
        ax.set_ylabel("joint")
        names = [str(n) for n in example["names"]]
        step = max(1, len(names) // 8)
        ax.set_yticks(range(0, len(names), step), names[::step], fontsize=10)
        fig.colorbar(image, ax=ax, label="error (cm)", pad=0.01)
    axes[-1, 0].set_xlabel("time (s)")
    return _save(fig, path)


def skeleton_overlay_figure(examples: list[tuple[str, dict]], path: Path) -> Path:
    """Per codec: the frame of its worst joint, whole body (left) and zoomed on that joint (right).

    Original bones grey and thick, decoded bones black and thin, decoded joints coloured by their error (cm, the
    codec's own scale); the zoom window is sized to the error so that a 1 mm error is as visible as a 5 cm one.
    Front view: X right, Y up.
    """
    fig, axes = plt.subplots(len(examples), 2, figsize=(9, 3.9 * len(examples)), squeeze=False,
                             layout="constrained", gridspec_kw={"width_ratios": [1, 1]})
    for row, (label, example) in enumerate(examples):
        original, decoded, parents = example["original"], example["decoded"], example["parents"]
        error = np.linalg.norm(original - decoded, axis=-1)  # (F, J)
        frame, joint = np.unravel_index(int(np.argmax(error)), error.shape)
        bones = [(parent, j) for j, parent in enumerate(parents) if parent >= 0]
        top = float(error[frame].max()) or 1e-9
        for col, ax in enumerate(axes[row]):
            for positions, color, width in ((original, "0.6", 4.0), (decoded, "black", 1.2)):
                pose = positions[frame]
                segments = [[pose[p, :2], pose[j, :2]] for p, j in bones]
                ax.add_collection(LineCollection(segments, colors=color, linewidths=width))
            dots = ax.scatter(decoded[frame, :, 0], decoded[frame, :, 1], c=error[frame], cmap="plasma", vmin=0,
                              vmax=top, s=28 if col == 0 else 60, zorder=3, edgecolors="black", linewidths=0.4)
            if col == 0:
                center = original[frame].mean(axis=0)
                extent = max(np.ptp(original[frame, :, 0]), np.ptp(original[frame, :, 1])) / 2 + 15
                ax.set_xlim(center[0] - extent, center[0] + extent)
                ax.set_ylim(center[1] - extent, center[1] + extent)
                ax.set_title(f"{label}\nframe {frame}, whole body")
            else:
                half = max(4.0 * float(error[frame, joint]), 2.0)  # cm
                focus = original[frame, joint]
                ax.set_xlim(focus[0] - half, focus[0] + half)
                ax.set_ylim(focus[1] - half, focus[1] + half)
                ax.plot(*original[frame, joint, :2], marker="o", markersize=12, markerfacecolor="none",
                        markeredgecolor="0.4", markeredgewidth=2)
                name = str(example["names"][joint])
                ax.set_title(f"zoom on worst joint {name}: {error[frame, joint]:.3g} cm\n"
                             f"window {2 * half:.3g} cm wide")
                fig.colorbar(dots, ax=ax, label="joint error (cm)", pad=0.02)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
    fig.suptitle("Original (grey, thick) vs decoded (black; joints coloured by error), front view")
    return _save(fig, path)
