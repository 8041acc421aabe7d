"""``compare``'s rows as the report reads them: pooled as the table pools them, configs as a user set them.

The rate search of ``compare`` picks a setting per clip (a step of 0.52 cm on one clip, 0.61 cm on the next). The
report pools rows by configuration, so each clip's row would be a configuration of one clip: no configuration
"complete" over the clips, a figure whose curve joins per-clip points, a config column of every field. Here each
codec's rows become one configuration, "the rate search at L∞ <= bound", whose knob reads as the range it took over
the clips (rounded); every other field is left out when it is the codec's default, so the config column says what
differs from the defaults and nothing else. The report then ranks and draws what the table ranks.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from mocapbench.experiments.compare_run import CodecOutcome

__all__ = ["pooled_rows"]


def _defaults(codec: str) -> dict[str, Any]:
    from mocapbench.codecs import CODECS

    return CODECS[codec].Config().as_dict() if codec in CODECS else {}


def pooled_rows(outcomes: Sequence[CodecOutcome], bound_cm: float) -> dict[str, list[dict[str, Any]]]:
    """Per codec, its rows as one configuration (see the module docstring); codecs without rows are left out.

    Each row keeps its measurements; ``config_hash`` becomes ``rate-search-<bound>`` (one per codec), the searched
    fields read as their range over the clips (``"0.52..0.61 (rate search per clip)"``), fields at their default
    are dropped, and ``models_total_bytes`` holds the bytes of every model the codec used
    (:func:`mocapbench.experiments.held_out.models_bytes`).
    """
    from mocapbench.experiments.compare_run import setting_text

    out = {}
    for outcome in outcomes:
        if not outcome.rows:
            continue
        defaults = _defaults(outcome.codec)
        searched = {key for settings in outcome.settings for key in settings}
        ranges = {key: setting_text([{key: s[key]} for s in outcome.settings if key in s]).split("=", 1)[1]
                  for key in searched}
        rows = []
        for row in outcome.rows:
            pooled = {key: value for key, value in row.items() if not key.startswith("param_")}
            for key, value in row.items():
                if not key.startswith("param_"):
                    continue
                name = key[len("param_"):]
                if name in ranges:
                    pooled[key] = f"{ranges[name]} (rate search per clip)" if ".." in ranges[name] else ranges[name]
                elif name not in defaults or defaults[name] != value:
                    pooled[key] = value
            pooled["config_hash"] = f"rate-search-{bound_cm:g}cm"
            pooled["models_total_bytes"] = outcome.model_bytes
            rows.append(pooled)
        out[outcome.codec] = rows
    return out
