"""Model files: the learned state of a codec fit on a user's clips (``mocapbench fit``), read back by ``--model``.

A model file is an ``.npz`` holding the codec's registry name, its config (JSON), the joint count it was fit for,
a format number, and the codec's own arrays (``state_<name>``: the PCA basis and entropy tables of ``mcb-linf``,
the bases of the LSDT codecs). Codecs that learn something implement ``model_state() -> dict[str, ndarray]`` and
``load_model_state(arrays)``; :func:`fittable_codecs` lists them.

A stream coded with a model carries the model's fingerprint, so a decoder holding another model refuses it.
"""

from __future__ import annotations

import io
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mocapbench.codecs.base import Codec
from mocapbench.codecs.registry import CODECS, create
from mocapbench.motion import Motion

__all__ = [
    "MODEL_FORMAT",
    "ModelFileError",
    "fit_codec",
    "fittable_codecs",
    "join_states",
    "load_model",
    "model_bytes",
    "save_model",
    "split_states",
]

#: Format number of model files (append-only).
MODEL_FORMAT = 1

# Settings that make a codec learn from the clips when it would otherwise use committed state.
_FIT_DEFAULTS = {"lsdt-clip": {"basis": "fit"}, "lsdt-frame": {"basis": "fit"}}


class ModelFileError(ValueError):
    """A model file that cannot be used (unreadable, another format, another codec); the message names it."""


def fittable_codecs() -> list[str]:
    """Registered codecs with learned state a model file can hold, sorted."""
    return sorted(name for name, cls in CODECS.items() if hasattr(cls, "model_state"))


def fit_codec(name: str, settings: Mapping[str, Any], motions: Sequence[Motion]) -> Codec:
    """A codec ``name`` with config ``settings`` fit on ``motions`` (any count >= 1, any length, one skeleton).

    LSDT codecs are fit with ``basis='fit'`` unless ``settings`` says otherwise (a user asking for a fit wants
    bases learned from the clips, not the committed CMU ones).

    Raises
    ------
    ValueError
        A codec with nothing to learn, no motion, or motions of several joint counts (named with their clips).
    """
    if name not in fittable_codecs():
        raise ValueError(f"codec {name!r} learns nothing from clips; codecs with a model are {fittable_codecs()}.")
    if not motions:
        raise ValueError("fit needs at least one clip.")
    joints: dict[int, list[str]] = {}
    for motion in motions:
        joints.setdefault(motion.num_joints, []).append(motion.name or "?")
    if len(joints) > 1:
        groups = "; ".join(f"{count} joints: {', '.join(names[:3])}{' ...' if len(names) > 3 else ''}"
                           for count, names in sorted(joints.items()))
        raise ValueError(f"fit needs clips of one skeleton, got {groups}; fit one model per skeleton.")
    codec = create(name, **{**_FIT_DEFAULTS.get(name, {}), **settings})
    return codec.fit(list(motions))


def model_bytes(codec: Codec) -> bytes:
    """The model file's bytes for a fitted ``codec``."""
    state = codec.model_state()
    if not state:
        raise ValueError(f"{codec.name}: nothing was learned from these clips (the committed state serves them).")
    num_joints = _state_joints(codec.name, state)
    arrays = {
        "mcb_format": np.array(MODEL_FORMAT),
        "mcb_codec": np.array(codec.name),
        "mcb_config": np.array(json.dumps(codec.config.as_dict(), sort_keys=True)),
        "mcb_num_joints": np.array(num_joints),
    }
    arrays.update({f"state_{key}": np.asarray(value) for key, value in state.items()})
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    return buffer.getvalue()


def save_model(codec: Codec, path: str | Path, *, force: bool = False) -> Path:
    """Write the model file of a fitted ``codec`` to ``path`` (atomically; an existing file needs ``force``)."""
    from mocapbench.io.safe_output import write_bytes

    return write_bytes(path, model_bytes(codec), force=force)


def load_model(path: str | Path, settings: Mapping[str, Any] | None = None, codec_name: str | None = None) -> Codec:
    """The codec a model file was fit for, holding its model.

    Parameters
    ----------
    path : str or Path
    settings : mapping, optional
        Config fields to change (``--set``), e.g. ``eps_cm``; the fields the model depends on must not change.
    codec_name : str, optional
        The codec the user asked for (``--codec``); it must be the model's.

    Raises
    ------
    ModelFileError
        Unreadable file, another format, another codec than ``codec_name``.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as stored:
            arrays = {key: stored[key] for key in stored.files}
    except (OSError, ValueError, EOFError) as error:
        raise ModelFileError(f"{path}: not a mocapbench model file ({error}).") from None
    if "mcb_format" not in arrays or "mcb_codec" not in arrays or "mcb_config" not in arrays:
        raise ModelFileError(f"{path}: not a mocapbench model file (no codec name, config or format number).")
    if int(arrays["mcb_format"]) != MODEL_FORMAT:
        raise ModelFileError(f"{path}: model format {int(arrays['mcb_format'])}, this mocapbench reads {MODEL_FORMAT}.")
    name = str(arrays["mcb_codec"])
    if codec_name is not None and codec_name != name:
        raise ModelFileError(f"{path}: the model is for codec {name!r}, not {codec_name!r}.")
    config = json.loads(str(arrays["mcb_config"]))
    config.update(settings or {})
    codec = create(name, **config)
    state = {key[len("state_"):]: value for key, value in arrays.items() if key.startswith("state_")}
    try:
        return codec.load_model_state(state)
    except (KeyError, ValueError) as error:
        raise ModelFileError(f"{path}: {error}") from None


def join_states(main: Mapping[str, np.ndarray], others: Mapping[int, Mapping[str, np.ndarray]]) -> dict:
    """One flat state for models of several skeletons: the main model's arrays as they are, every other model's
    under ``j<joints>__<name>`` (a state of one skeleton is unchanged, so single-model files stay as they were)."""
    flat = dict(main)
    for joints, state in others.items():
        flat.update({f"j{joints}__{key}": value for key, value in state.items()})
    return flat


def split_states(flat: Mapping[str, np.ndarray]) -> tuple[dict[str, np.ndarray], dict[int, dict[str, np.ndarray]]]:
    """Inverse of :func:`join_states`: ``(main state, {joints: state})``."""
    main: dict[str, np.ndarray] = {}
    others: dict[int, dict[str, np.ndarray]] = {}
    for key, value in flat.items():
        prefix, sep, rest = key.partition("__")
        if sep and prefix.startswith("j") and prefix[1:].isdigit():
            others.setdefault(int(prefix[1:]), {})[rest] = value
        else:
            main[key] = value
    return main, others


def _state_joints(name: str, state: Mapping[str, np.ndarray]) -> int:
    """Joint count a model state was fit for."""
    if "num_joints" in state:
        return int(state["num_joints"])
    if "bases" in state:
        return int(np.shape(state["bases"])[-1])
    raise ValueError(f"{name}: the model state names no joint count.")
