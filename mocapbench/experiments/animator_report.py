"""The report's "What animators see": jitter, foot sliding, rigid bones, end sites and the player, per codec.

The headline (:mod:`mocapbench.experiments.headline`) shows :data:`HEADLINE_COLUMNS` beside L∞ and flags, without
unranking it, a codec whose jitter or foot sliding passes a stated limit (:func:`animator_flag`). The section
(:func:`add_animator_section`, one call in the report builder) shows, per dataset and headline bound, each ranked
codec's headline config: a table of the pooled figures, their distributions over clips, and a player page
(:mod:`mocapbench.experiments.player`) with the worst clip of every codec at every bound, read from the
``worst.npz`` of the job that measured it (:mod:`mocapbench.experiments.worst_clip`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd

from mocapbench.metrics.foot_sliding import ContactSettings

__all__ = ["JITTER_LIMIT", "SLIDING_LIMIT_CM", "HEADLINE_COLUMNS", "FLAG_COLUMN", "animator_flag",
           "headline_picks", "add_animator_section", "method_bullets"]

JITTER_LIMIT = 1.0
"""Flag limit of the jitter ratio: the RMS acceleration error pooled over a dataset divided by the RMS acceleration
of the original clips themselves (their motion and their capture noise, at their frame rate). Above 1 the codec
adds more acceleration than the whole captured motion has: the decoded motion is seen to shake or to move in
steps. Both sides are in cm/s² at the clip's own frame rate, so the ratio compares 24 fps with 120 fps clips."""

SLIDING_LIMIT_CM = 2.0
"""Flag limit of the foot sliding a codec adds, cm per contact: the decoded foot's mean horizontal travel per
contact minus the original's over the same contacts. A planted foot that moves 2 cm more than in the capture is
seen to slide on the floor."""

HEADLINE_COLUMNS = {
    "end_site_max_err_cm": "end sites L∞ cm",
    "accel_rms_err_cm_s2": "jitter RMS cm/s²",
    "jitter_ratio": "jitter ÷ motion",
    "foot_slide_added_cm": "foot slide +cm/contact",
    "bone_len_max_dev_cm": "bone Δ max cm",
}
"""Result column -> headline column, shown beside L∞ (derived: ``jitter_ratio``, the RMS acceleration error over
the original's RMS acceleration, and ``foot_slide_added_cm``, the decoded foot's travel minus the original's)."""

FLAG_COLUMN = "animators"


def _jitter_ratio(point) -> float:
    error, own = (pd.to_numeric(point.get(c, np.nan), errors="coerce")
                  for c in ("accel_rms_err_cm_s2", "accel_rms_ref_cm_s2"))
    return float(error / own) if np.isfinite(error) and np.isfinite(own) and own > 0 else float("nan")


def _added_sliding(point) -> float:
    decoded, original = point.get("foot_slide_mean_cm", np.nan), point.get("foot_slide_ref_mean_cm", np.nan)
    try:
        return float(decoded) - float(original)
    except (TypeError, ValueError):
        return float("nan")


def headline_values(point: pd.Series) -> dict[str, float]:
    """The :data:`HEADLINE_COLUMNS` of one curve point (NaN where the rows do not hold them)."""
    values = {}
    for column, label in HEADLINE_COLUMNS.items():
        derived = {"foot_slide_added_cm": _added_sliding, "jitter_ratio": _jitter_ratio}.get(column)
        value = derived(point) if derived else point.get(column, np.nan)
        values[label] = pd.to_numeric(value, errors="coerce")
    return values


def animator_flag(point: pd.Series) -> str:
    """Why animators would reject this curve point (a codec config pooled over a dataset); empty if nothing.

    Jitter: the jitter ratio above :data:`JITTER_LIMIT`; foot sliding: the added travel per contact above
    :data:`SLIDING_LIMIT_CM`.
    """
    reasons = []
    ratio = _jitter_ratio(point)
    if np.isfinite(ratio) and ratio > JITTER_LIMIT:
        reasons.append(f"jitter: RMS acceleration error {float(point['accel_rms_err_cm_s2']):,.0f} cm/s² is "
                       f"{ratio:.2g}x the motion's own {float(point['accel_rms_ref_cm_s2']):,.0f} cm/s²")
    sliding = _added_sliding(point)
    if np.isfinite(sliding) and sliding > SLIDING_LIMIT_CM:
        reasons.append(f"foot sliding: +{sliding:.2g} cm per contact > {SLIDING_LIMIT_CM:g}")
    return "; ".join(reasons)


def headline_picks(points: pd.DataFrame, bound: float) -> pd.DataFrame:
    """Each (dataset, codec)'s headline config under ``bound``: complete, L∞ < bound, highest ratio.

    The rule of :func:`mocapbench.experiments.headline.headline_table`; returns the chosen curve points.
    """
    ok = points[points["complete"].astype(bool) & (points["max_err_cm"] < bound)]
    if ok.empty:
        return ok
    best = ok.loc[ok.groupby(["dataset", "codec"])["compression_ratio"].idxmax()]
    return best.sort_values(["dataset", "compression_ratio"], ascending=[True, False])


def _clip_rows(rows: pd.DataFrame, pick: pd.Series) -> pd.DataFrame:
    same = ((rows["dataset"] == pick["dataset"]) & (rows["codec"] == pick["codec"])
            & (rows["config_hash"] == pick["config_hash"]))
    return rows[same].drop_duplicates("clip", keep="last")


def _section_table(picks: pd.DataFrame, config_text) -> pd.DataFrame:
    out = []
    for _, pick in picks.iterrows():
        out.append({
            "codec": pick["codec"], "config": config_text(pick), "CR": pick["compression_ratio"],
            "L∞ cm": pick["max_err_cm"], "end sites L∞ cm": pick.get("end_site_max_err_cm", np.nan),
            "end sites mean cm": pick.get("end_site_mean_err_cm", np.nan),
            "jitter RMS cm/s²": pick.get("accel_rms_err_cm_s2", np.nan),
            "jitter max cm/s²": pick.get("accel_max_err_cm_s2", np.nan),
            "motion's own RMS cm/s²": pick.get("accel_rms_ref_cm_s2", np.nan),
            "foot slide cm/contact": pick.get("foot_slide_mean_cm", np.nan),
            "capture's own cm/contact": pick.get("foot_slide_ref_mean_cm", np.nan),
            "foot slide max cm": pick.get("foot_slide_max_cm", np.nan),
            "bone Δ max cm": pick.get("bone_len_max_dev_cm", np.nan),
            "bone Δ mean cm": pick.get("bone_len_mean_dev_cm", np.nan),
            "rotation max °": pick.get("rot_max_err_deg", np.nan),
            "rotation mean °": pick.get("rot_mean_err_deg", np.nan),
            FLAG_COLUMN: animator_flag(pick),
        })
    return pd.DataFrame(out)


_PANELS = (
    ("jitter_ratio", "jitter: RMS acceleration error ÷ the motion's own (log)", True),
    ("foot_slide_added_cm", "foot sliding added (cm per contact)", False),
    ("bone_len_max_dev_cm", "bone-length deviation, max (cm)", False),
    ("end_site_max_err_cm", "end-site L∞ (cm)", False),
)


def _player_entries(rows: pd.DataFrame, picks: pd.DataFrame, bound: float,
                    config_text) -> tuple[list, list[str]]:
    from mocapbench.experiments.player import PlayerEntry
    from mocapbench.experiments.worst_clip import WORST_FILE, load_worst

    entries, missing = [], []
    for _, pick in picks.iterrows():
        clips = _clip_rows(rows, pick)
        if clips.empty:
            continue
        worst = clips.loc[clips["max_err_cm"].idxmax()]
        path = Path(str(worst.get("job_dir", ""))) / WORST_FILE
        data = load_worst(path) if path.is_file() else None
        if data is None or data["clip"] != worst["clip"] or data["config_hash"] != pick["config_hash"]:
            missing.append(str(pick["codec"]))
            continue
        label = (f"L∞ < {bound:g} cm: {pick['codec']} ({config_text(pick)}), worst clip {worst['clip']}, "
                 f"L∞ {worst['max_err_cm']:.3g} cm")
        note = (f"{pick['codec']} at its headline config under {bound:g} cm ({config_text(pick)}), on the clip "
                f"where its joint error is largest ({worst['clip']}, {data['original'].shape[0]} frames at "
                f"{data['fps']:g} fps).")
        entries.append(PlayerEntry(label, data["names"], data["parents"], data["fps"], data["up_axis"],
                                   data["original"], data["decoded"], note=note))
    return entries, missing


def add_animator_section(doc, rows: pd.DataFrame, points: pd.DataFrame, bounds: Sequence[float], out: Path,
                         config_text, draw=None) -> None:
    """Append "What animators see" to ``doc`` and write its figures and player pages into the report ``out``.

    Parameters
    ----------
    doc : Document
    rows, points : DataFrame
        Results rows and curve points of the report.
    bounds : floats, cm
        The headline bounds.
    out : Path
        The report folder (figures go to ``out/figures``, the player to ``out/player_<dataset>.html`` and
        ``out/player.js``).
    config_text : callable(point) -> str
        How the report writes a config.
    draw : callable, optional
        ``draw(figure function, *args, **kwargs) -> Future`` (:class:`~mocapbench.experiments.plots.FigurePool`);
        default: drawn here, at once.
    """
    from mocapbench.experiments import plots
    from mocapbench.experiments.document import image_fill

    draw = draw or plots.FigurePool().draw
    from mocapbench.experiments.player import player_html, player_script
    from mocapbench.io.safe_output import write_text

    doc.heading("What animators see")
    doc.paragraph(
        "Beside the joint-position error, what a person accepting a compressed clip looks at: the tips of fingers, "
        "toes and head (BVH end sites, which only codecs that return rotations produce), jitter (acceleration error), "
        "a planted foot that slides, bones that stretch, and the joint angles. Per dataset and bound, every ranked "
        "codec at its headline config, pooled over the clips (definitions in Data and method). A codec whose "
        f"RMS acceleration error passes {JITTER_LIMIT:g}x the original motion's own RMS acceleration or whose foot "
        f"sliding adds more than {SLIDING_LIMIT_CM:g} cm per contact is flagged here and in the headline; it keeps "
        "its rank.")
    if not any(c in points for c in ("accel_rms_err_cm_s2", "bone_len_max_dev_cm")):
        doc.paragraph("The result rows predate these measurements: re-run the sweep to fill this section.")
        return
    frame = points.copy()
    frame["foot_slide_added_cm"] = [_added_sliding(p) for _, p in frame.iterrows()]
    clip_rows = rows.copy()
    for column, derive in (("foot_slide_added_cm", _added_sliding), ("jitter_ratio", _jitter_ratio)):
        clip_rows[column] = [derive(r) for _, r in clip_rows.iterrows()]
    wrote_script = False
    for dataset in sorted(frame["dataset"].unique()):
        slug = str(dataset).replace("/", "_")
        entries, missing = [], []
        for bound in bounds:
            picks = headline_picks(frame[frame["dataset"] == dataset], bound)
            doc.heading(f"{dataset}, L∞ < {bound:g} cm: what animators see", 3)
            if picks.empty:
                doc.paragraph(f"No codec stays under {bound:g} cm on {dataset}.")
                continue
            doc.table(_section_table(picks, config_text))
            per_clip = pd.concat([_clip_rows(clip_rows, p) for _, p in picks.iterrows()], ignore_index=True)
            panels = [p for p in _PANELS if p[0] in per_clip and per_clip[p[0]].notna().any()]
            if panels:
                doc.later(draw(plots.clip_distribution_figure, per_clip, dataset, bound,
                               out / "figures" / f"animators_{slug}_{bound:g}cm.png", panels=panels),
                          image_fill(out, f"{dataset}: what animators see per clip at L∞ < {bound:g} cm "
                                          "(bar: median)"))
            found, lost = _player_entries(rows, picks, bound, config_text)
            entries += found
            missing += lost
        if entries:
            if not wrote_script:
                write_text(out / "player.js", player_script())
                wrote_script = True
            intro = [f"{dataset}: for every codec ranked at each headline bound, the clip where its joint error is "
                     "largest, original (grey) and decoded (blue) overlaid, each decoded joint coloured by its "
                     "error (green 0, red the clip's largest). The right half magnifies the worst joint. Keys: "
                     "space plays, arrows step. Positions stored as float32."]
            write_text(out / f"player_{slug}.html", player_html(f"mocapbench player: {dataset}", entries,
                                                                intro=intro, script_src="player.js"))
            doc.link(f"player_{slug}.html", f"{dataset}: play the worst clip of every codec at each bound "
                                            f"({len(entries)} clips, opens in this browser, no network)")
        if missing:
            doc.paragraph(f"{dataset}: no player clip for {', '.join(sorted(set(missing)))} (their jobs kept no "
                          "worst.npz: save_worst was off or the sweep predates it).")


def method_bullets() -> list[str]:
    """The definitions, for the report's "Data and method"."""
    contact = ContactSettings()
    return [
        "End sites: the BVH end sites (finger, toe and head tips) by forward kinematics of the decoded rotations; "
        "L∞ and mean Euclidean error (cm). Codecs that return joint positions only have none (—).",
        "Jitter: acceleration a = (p[t+1] − 2p[t] + p[t−1])·fps² (cm/s², so 24 and 120 fps clips share one scale); "
        "RMS and max over joints and frames of |a_decoded − a_original|, beside the original's own RMS "
        "acceleration (its motion and capture noise at its frame rate); jitter ÷ motion is their ratio. The same "
        "position noise is 25 times larger in cm/s² at 120 fps than at 24 fps, and so is a capture's own noise. "
        "Pooled: RMS over every inner frame of every clip, max of the worst clip.",
        f"Foot sliding: contacts found on the original: ankle and toe joints (CMU lfoot/ltoes, LeftFoot/LeftToeBase, "
        f"Bandai Foot_L/Toes_L and their right twins, else the two lowest leaf joints and their parents) within "
        f"{contact.height_cm:g} cm of their own floor level ({contact.floor_percentile:g}th percentile of their "
        f"height on the up axis), slower than {contact.speed_cm_s:g} cm/s, for at least {contact.min_duration_s:g} s. "
        "Sliding = the decoded joint's horizontal path length over each contact (cm); the original's own path over "
        "the same contacts is reported beside it, and the difference is what the codec adds. Pooled: mean per "
        "contact over every contact, max of the worst.",
        "Bone-length deviation: a bone is the segment from a joint's parent to the joint (whatever carries it: the "
        "offset, a translation track or a parent's scale); |length decoded − length original| per frame, max and "
        "mean over bones and frames (cm). Zero up to rounding for codecs that code rotations on the original "
        "skeleton; up to twice the position error for codecs that return points.",
        "Rotation error: the angle of q_original⁻¹·q_decoded of every joint's local rotation (degrees), max and mean; "
        "codecs that return positions only have none.",
        f"Flags: jitter ÷ motion > {JITTER_LIMIT:g} or foot sliding added > {SLIDING_LIMIT_CM:g} cm per contact "
        "(flagged in the headline; the codec keeps its rank).",
    ]
