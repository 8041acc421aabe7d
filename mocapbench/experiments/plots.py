"""Report figures, saved to PNG files and closed (never shown): RD curves, error heat maps, skeleton overlays."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, also on a machine without a display

import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from mocapbench.io.safe_output import open_output  # noqa: E402

__all__ = ["rd_figure", "rd_per_clip_figure", "error_heatmap_figure", "skeleton_overlay_figure"]

_DISTORTIONS = (("max_err_cm", "L∞ joint error (cm)"), ("mean_err_cm", "mean joint error (cm)"),
                ("kg_percent", "KG distortion (%)"))


def _styles(codecs: list[str]) -> dict[str, dict]:
    markers = "os^vD<>pPX*h"
    cmap = plt.get_cmap("tab20")
    return {c: {"marker": markers[i % len(markers)], "color": cmap(i % 20)} for i, c in enumerate(sorted(codecs))}


def _save(fig, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        with open_output(path, "wb") as file:  # atomic, never through a link, never over an existing file
            fig.savefig(file, format=path.suffix.lstrip(".") or "png", dpi=110, bbox_inches="tight")
    finally:
        plt.close(fig)
    return path


def _front(x: np.ndarray, y: np.ndarray, higher_y_better: bool) -> np.ndarray:
    """Mask of the points no other point beats on both axes (lower error ``x``, better rate ``y``)."""
    y = y if higher_y_better else -y
    keep = np.ones(len(x), dtype=bool)
    for i in range(len(x)):
        better = (x <= x[i]) & (y >= y[i]) & ((x < x[i]) | (y > y[i]))
        keep[i] = not better.any()
    return keep


def _curve(ax, frame: pd.DataFrame, x: str, y: str, style: dict, label: str) -> None:
    """Every point as a marker, the line through the codec's Pareto front (its RD curve)."""
    frame = frame[np.isfinite(frame[x]) & np.isfinite(frame[y]) & (frame[x] > 0)]
    if frame.empty:
        return
    xs, ys = frame[x].to_numpy(float), frame[y].to_numpy(float)
    front = _front(xs, ys, higher_y_better=y == "compression_ratio")
    order = np.argsort(xs[front])
    ax.plot(xs[front][order], ys[front][order], linestyle="-", linewidth=1, markersize=4, label=label, **style)
    if (~front).any():
        ax.plot(xs[~front], ys[~front], linestyle="none", markersize=3, alpha=0.4, marker=style["marker"],
                color=style["color"])


def rd_figure(points: pd.DataFrame, dataset: str, path: Path, rate: str = "compression_ratio") -> Path:
    """Compression ratio (or ``bits_per_joint_frame``) against L∞, mean error and KG, every codec of one dataset.

    Parameters
    ----------
    points : DataFrame
        :func:`mocapbench.experiments.aggregate.curve_points` rows of ``dataset``.
    """
    styles = _styles(list(points["codec"].unique()))
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.8))
    for ax, (column, label) in zip(axes, _DISTORTIONS):
        for codec, group in points.groupby("codec", sort=True):
            _curve(ax, group, column, rate, styles[codec], codec)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(label + " (log)")
        ax.set_ylabel("compression ratio (raw float32 positions / bitstream)" if rate == "compression_ratio"
                      else "bits per joint per frame")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].axvline(1.0, color="grey", linestyle=":", linewidth=1)
    axes[0].axvline(3.0, color="grey", linestyle="--", linewidth=1)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=8)
    fig.suptitle(f"Rate-distortion, dataset {dataset} (pooled over clips; dotted 1 cm, dashed 3 cm)")
    return _save(fig, path)


def rd_per_clip_figure(rows: pd.DataFrame, dataset: str, path: Path, max_clips: int = 16) -> Path:
    """Compression ratio against L∞, one panel per clip (at most ``max_clips``), every codec."""
    clips = sorted(rows["clip"].unique())[:max_clips]
    styles = _styles(list(rows["codec"].unique()))
    cols = min(4, len(clips))
    nrows = int(np.ceil(len(clips) / cols))
    fig, axes = plt.subplots(nrows, cols, figsize=(4 * cols, 3.2 * nrows), squeeze=False)
    for ax, clip in zip(axes.flat, clips):
        for codec, group in rows[rows["clip"] == clip].groupby("codec", sort=True):
            _curve(ax, group, "max_err_cm", "compression_ratio", styles[codec], codec)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(clip, fontsize=9)
        ax.set_xlabel("L∞ (cm)", fontsize=8)
        ax.set_ylabel("CR", fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
    for ax in list(axes.flat)[len(clips):]:
        ax.axis("off")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=8)
    fig.suptitle(f"Per clip: compression ratio vs L∞, dataset {dataset}")
    fig.tight_layout()
    return _save(fig, path)


def error_heatmap_figure(examples: list[tuple[str, dict]], path: Path) -> Path:
    """Per-joint × time error (cm) of one clip, one panel per codec (its example point).

    Parameters
    ----------
    examples : list of (label, npz dict with ``original``, ``decoded`` (F, J, 3) cm, ``names``, ``clip``)
    """
    fig, axes = plt.subplots(len(examples), 1, figsize=(12, 2.4 * len(examples)), squeeze=False, layout="constrained")
    vmax = max(float(np.linalg.norm(e["original"] - e["decoded"], axis=-1).max()) for _, e in examples) or 1.0
    image = None
    for ax, (label, example) in zip(axes[:, 0], examples):
        error = np.linalg.norm(example["original"] - example["decoded"], axis=-1)  # (F, J) cm
        image = ax.imshow(error.T, aspect="auto", interpolation="nearest", cmap="magma", vmin=0, vmax=vmax,
                          extent=(0, error.shape[0] / float(example["fps"]), error.shape[1] - 0.5, -0.5))
        ax.set_title(f"{label}: clip {example['clip']}, max {error.max():.3g} cm", fontsize=9)
        ax.set_ylabel("joint", fontsize=8)
        names = [str(n) for n in example["names"]]
        ax.set_yticks(range(0, len(names), 3), names[::3], fontsize=6)
    axes[-1, 0].set_xlabel("time (s)")
    fig.colorbar(image, ax=axes[:, 0].tolist(), label="joint position error (cm)", shrink=0.6)
    return _save(fig, path)


def skeleton_overlay_figure(examples: list[tuple[str, dict]], path: Path, num_frames: int = 4) -> Path:
    """Original (grey) and decoded (red) skeletons, front view (X right, Y up), a few frames side by side per codec."""
    fig, axes = plt.subplots(len(examples), num_frames, figsize=(2.6 * num_frames, 3.0 * len(examples)),
                             squeeze=False)
    for row, (label, example) in enumerate(examples):
        original, decoded, parents = example["original"], example["decoded"], example["parents"]
        frames = np.linspace(0, original.shape[0] - 1, num_frames).round().astype(int)
        for col, frame in enumerate(frames):
            ax = axes[row, col]
            bones = [(parent, joint) for joint, parent in enumerate(parents) if parent >= 0]
            for positions, color, width in ((original, "0.55", 3.0), (decoded, "tab:red", 1.2)):
                pose = positions[frame]
                segments = [[pose[p, :2], pose[j, :2]] for p, j in bones]
                ax.add_collection(LineCollection(segments, colors=color, linewidths=width))
            center = original[frame].mean(axis=0)
            ax.set_xlim(center[0] - 100, center[0] + 100)
            ax.set_ylim(center[1] - 110, center[1] + 110)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"frame {frame}", fontsize=8)
        axes[row, 0].set_ylabel(label, fontsize=8)
    fig.suptitle("Original (grey, thick) vs decoded (red), front view")
    fig.tight_layout()
    return _save(fig, path)
