"""A player page: the original and the decoded skeleton of clips, overlaid, frame by frame, in any browser.

:func:`player_html` writes one HTML page for a list of :class:`PlayerEntry` (the report writes one page per dataset
holding the worst clip of every codec at each headline bound; ``mocapbench view`` writes one for a file). The page
draws on a canvas with a small script (``templates/player.js``, beside the page or inside it), with no network
access: play/pause, scrub, step, speed, the view turned about the up axis, the worst frame marked on the error
timeline and ringed on the skeleton, every decoded joint coloured by its error (green 0 → orange → red at the
clip's largest error). The right half magnifies the worst joint, where a 1 cm error is a few pixels in the whole
body.

Data kept small: positions as little-endian float32 (base64 in the page, about 1e-5 cm of rounding at 1 m), a
track shared by entries that show the same frames of the same clip stored once, and a clip longer than
:data:`MAX_PLAYER_FRAMES` frames shown every k-th frame (k = ceil(F / MAX_PLAYER_FRAMES)), the worst frame always
among them; the page says when it decimated. Errors are computed from the float32 positions, as the page does.
"""

from __future__ import annotations

import base64
import hashlib
import json
import math
from dataclasses import dataclass
from importlib import resources
from typing import Sequence

import numpy as np

__all__ = ["MAX_PLAYER_FRAMES", "PlayerEntry", "player_data", "player_html", "player_script"]

MAX_PLAYER_FRAMES = 600
"""Frames a clip keeps in the page; longer clips are decimated (every k-th frame, the worst one kept)."""


@dataclass(frozen=True)
class PlayerEntry:
    """One clip of a player page.

    Attributes
    ----------
    label : str
        Its line in the page's clip menu.
    names : sequence of str, length J
    parents : array_like, shape (J,), int
    fps : float
        Frames per second of the positions.
    up_axis : str
        ``"x"``, ``"y"`` or ``"z"`` (``Motion.up_axis``).
    original : array_like, shape (F, J, 3), float, cm
    decoded : array_like, shape (F, J, 3), float, cm, or None
        None shows the original alone (no error).
    note : str
        A sentence shown above the canvas.
    """

    label: str
    names: Sequence[str]
    parents: np.ndarray
    fps: float
    up_axis: str
    original: np.ndarray
    decoded: np.ndarray | None = None
    note: str = ""

    def __post_init__(self) -> None:
        original = np.asarray(self.original, dtype=np.float32)
        if original.ndim != 3 or original.shape[-1] != 3 or 0 in original.shape:
            raise ValueError(f"player entry {self.label!r}: expected original positions (F, J, 3), got {original.shape}")
        if len(self.names) != original.shape[1] or np.shape(self.parents) != (original.shape[1],):
            raise ValueError(f"player entry {self.label!r}: {original.shape[1]} joints in the positions, "
                             f"{len(self.names)} names, {np.shape(self.parents)} parents")
        if self.decoded is not None and np.shape(self.decoded) != original.shape:
            raise ValueError(f"player entry {self.label!r}: decoded positions {np.shape(self.decoded)} do not match "
                             f"the original's {original.shape} (frames, joints, 3)")
        if self.up_axis not in ("x", "y", "z") or not (math.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"player entry {self.label!r}: up axis {self.up_axis!r}, fps {self.fps}")
        for name, array in (("original", original), ("decoded", self.decoded)):
            if array is not None and not np.all(np.isfinite(np.asarray(array, dtype=np.float32))):
                raise ValueError(f"player entry {self.label!r}: {name} positions hold NaN or inf (or exceed float32)")


def _shown_frames(num_frames: int, worst_frame: int) -> np.ndarray:
    step = max(1, math.ceil(num_frames / MAX_PLAYER_FRAMES))
    return np.arange(worst_frame % step, num_frames, step)


def _track(tracks: dict, positions: np.ndarray) -> str:
    """Key of ``positions`` (float32, C order) in ``tracks``, added if new (identical tracks are stored once)."""
    raw = np.ascontiguousarray(positions, dtype="<f4").tobytes()
    key = hashlib.sha1(raw).hexdigest()[:16]
    if key not in tracks:
        tracks[key] = {"frames": int(positions.shape[0]), "positions": base64.b64encode(raw).decode("ascii")}
    return key


def player_data(entries: Sequence[PlayerEntry]) -> dict:
    """The page's JSON: ``tracks`` (base64 float32 positions) and one record per entry (see ``player.js``)."""
    if not entries:
        raise ValueError("a player page needs at least one clip")
    tracks: dict = {}
    records = []
    for entry in entries:
        original = np.asarray(entry.original, dtype=np.float32)
        decoded = None if entry.decoded is None else np.asarray(entry.decoded, dtype=np.float32)
        worst_frame = worst_joint = None
        scale = 0.0
        if decoded is not None:
            # float64 arithmetic on the float32 values, in the page's order: the page finds the same largest error
            delta = decoded.astype(np.float64) - original.astype(np.float64)
            errors = np.sqrt(delta[..., 0] * delta[..., 0] + delta[..., 1] * delta[..., 1]
                             + delta[..., 2] * delta[..., 2])
            worst_frame, worst_joint = (int(i) for i in np.unravel_index(int(np.argmax(errors)), errors.shape))
            scale = float(errors[worst_frame, worst_joint])
        frames = _shown_frames(original.shape[0], worst_frame or 0)
        step = int(frames[1] - frames[0]) if len(frames) > 1 else 1
        note = entry.note
        if step > 1:
            note = (note + " " if note else "") + (f"Shown one frame in {step} ({len(frames)} of {original.shape[0]}, "
                                                    f"the worst frame among them) to keep the page small.")
        records.append({
            "label": entry.label, "names": [str(n) for n in entry.names],
            "parents": [int(p) for p in np.asarray(entry.parents)], "up": entry.up_axis,
            "fps": float(entry.fps), "fps_shown": float(entry.fps) / step, "source_frames": int(original.shape[0]),
            "frame_numbers": frames.tolist(), "original": _track(tracks, original[frames]),
            "decoded": None if decoded is None else _track(tracks, decoded[frames]),
            "worst_frame": None if worst_frame is None else int(np.searchsorted(frames, worst_frame)),
            "worst_joint": worst_joint, "max_err_cm": scale, "scale_cm": scale, "note": note,
        })
    return {"tracks": tracks, "entries": records}


def player_script() -> str:
    """The page's script (``templates/player.js``)."""
    return resources.files("mocapbench.experiments").joinpath("templates/player.js").read_text(encoding="utf-8")


def player_html(title: str, entries: Sequence[PlayerEntry], *, intro: Sequence[str] = (),
                script_src: str | None = None) -> str:
    """The player page.

    Parameters
    ----------
    title : str
    entries : sequence of PlayerEntry
        The clips of its menu, the first one shown.
    intro : sequence of str
        Paragraphs above the player.
    script_src : str, optional
        Relative URL of ``player.js`` beside the page (the report writes it once for all its pages); default: the
        script inside the page, which then stands alone.

    Returns
    -------
    str
        HTML.
    """
    from jinja2 import Environment, PackageLoader, select_autoescape

    env = Environment(loader=PackageLoader("mocapbench.experiments", "templates"),
                      autoescape=select_autoescape(["html", "j2"]), trim_blocks=True, lstrip_blocks=True)
    data = json.dumps(player_data(entries), separators=(",", ":"))
    # Inside <script> the JSON is raw text: "</" would end the element, so it is written "<\/".
    from markupsafe import Markup

    script = player_script() if script_src is None else ""
    return env.get_template("player.html.j2").render(
        title=title, intro=list(intro), data_json=Markup(data.replace("</", "<\\/")),
        script_inline=script_src is None, script=Markup(script.replace("</", "<\\/")), script_src=script_src)
