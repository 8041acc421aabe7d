"""Published reference points, converted to bits per joint per frame so they can sit on our RD figures.

A ratio is only comparable when the raw sizes agree; bits per joint per frame (stored bits / joints / frames)
does not depend on the raw-size definition, so each published ratio is converted with the source's own raw-size
definition, written beside it. Nothing here is measured by mocapbench.

* ACL 2.1, ``docs/cmu_performance.md``: 21.77:1 over the CMU database at 24 fps, raw = 10 float32 per bone per
  sample (320 bits), so 320 / 21.77 = 14.7 bits/joint/frame; max error 0.0495 cm on ACL's virtual shell 3 cm
  from each bone (our ``shell_max_err_cm``, not the joint L∞).
* PGA, Tournier et al. 2009, Table 2: ratio 1:x with raw = 3(m+1) numbers per frame for m+1 joints (§3.6);
  taken as float32 (the paper does not say), that is 96 / x bits/joint/frame; distortion rate = our KG %.
* Neural Fourier, Tojo et al. 2022: 2-15x smaller than the pose parameters (3 + 4 + 3(J-1) numbers per frame,
  float32 taken) at L∞ under 2 % of the character's height (about 3 cm), "in most of 116 random CMU clips":
  a range, drawn as a vertical bar at 3 cm; for J = 31, 32 (3J + 4) / J / x bits/joint/frame.
* LSDT (Hou et al. 2016) publishes curves only (no table), so it has no point here.
"""

from __future__ import annotations

from mocapbench.experiments.reproduction import PGA_TABLE_2

__all__ = ["PUBLISHED_POINTS", "points_for"]


def _pga_points() -> list[dict]:
    out = []
    for clip, _geodesics, _lod_root, _lod_end, ratio, distortion, _ms in PGA_TABLE_2:
        out.append({"source": "PGA (Tournier et al. 2009), Table 2", "label": f"PGA {clip} (paper)",
                    "clips": [clip], "metric": "kg_percent", "error": distortion,
                    "bits_per_joint_frame": 96.0 / ratio,
                    "note": f"1:{ratio} over 3(m+1) float32 numbers per frame"})
    return out


_NF_BITS_PER_JOINT = 32.0 * (3 * 31 + 4) / 31  # pose parameters of a 31-joint skeleton, float32

PUBLISHED_POINTS: tuple[dict, ...] = (
    {"source": "ACL 2.1 docs/cmu_performance.md", "label": "ACL 2.1, CMU 24 fps (published)", "clips": None,
     "metric": "shell_max_err_cm", "error": 0.0495, "bits_per_joint_frame": 320.0 / 21.77,
     "note": "21.77:1 over 10 float32 per bone per sample; error on a shell 3 cm from each bone"},
    *_pga_points(),
    {"source": "Neural Fourier (Tojo et al. 2022)", "label": "neural Fourier 2-15x (paper)", "clips": None,
     "metric": "max_err_cm", "error": 3.0, "bits_per_joint_frame": _NF_BITS_PER_JOINT / 15.0,
     "bits_range": (_NF_BITS_PER_JOINT / 15.0, _NF_BITS_PER_JOINT / 2.0),
     "note": "2-15x over pose parameters (3 + 4 + 3(J-1) float32 per frame) at L∞ < 2 % of height (~3 cm)"},
)


def points_for(clips: set[str] | None = None, *, cmu: bool = True) -> list[dict]:
    """The published points that belong on a figure of a dataset with ``clips`` (None: any dataset).

    Clip-specific points (PGA's Table 2) need their clip in ``clips``; database-wide CMU points need ``cmu``.
    """
    out = []
    for point in PUBLISHED_POINTS:
        if point["clips"] is None:
            if cmu:
                out.append(point)
        elif clips is None or set(point["clips"]) & set(clips):
            out.append(point)
    return out
