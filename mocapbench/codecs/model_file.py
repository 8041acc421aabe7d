"""Model files: the learned state of a codec fit on a user's clips (``mocapbench fit``), read back by ``--model``.

A model file is an ``.npz`` holding the codec's registry name, its config (JSON), the joint count it was fit for,
a format number, and the codec's own arrays (``state_<name>``: the PCA basis and entropy tables of ``mcb-linf``,
the bases of the LSDT codecs). Codecs that learn something implement ``model_state() -> dict[str, ndarray]`` and
``load_model_state(arrays)``; :func:`fittable_codecs` lists them.

A stream coded with a model carries the model's fingerprint, so a decoder holding another model refuses it.

A model file is untrusted input (a user may be handed one), read as :func:`load_model` says, in this order:

1. the file: a regular file of at most :data:`MAX_MODEL_FILE_BYTES`, a zip archive of at most
   :data:`MAX_MEMBERS` ``.npy`` members with distinct plain names;
2. every member's ``.npy`` header, read from the archive without reading the array: no object dtype, at most
   :data:`MAX_ARRAY_BYTES` from the declared shape, and a member whose uncompressed size is exactly the header
   plus the declared array (a zip bomb is refused before it is inflated);
3. the four fields every model has (:data:`META_ARRAYS`: format number, codec name, config as a JSON object of
   at most :data:`MAX_CONFIG_CHARS` characters, joint count up to :data:`MAX_MODEL_JOINTS`), read and checked;
4. the state arrays against the list the codec declares (``model_arrays(num_joints)``: each array's dtype and
   shape for a skeleton of that many joints, other skeletons' arrays under ``j<joints>__``): a missing array,
   an unknown one, another dtype or shape is refused before any state array is read;
5. the arrays read (the declared sizes only) and handed to the codec's ``load_model_state``, which validates
   the values (finite, orthonormal bases, positive scales and counts, a state fit for the same joint count).

Every failure is a :class:`ModelFileError`: one line naming the file and what is wrong.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import stat
import zipfile
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mocapbench.codecs.base import Codec
from mocapbench.codecs.registry import CODECS, create
from mocapbench.motion import Motion

__all__ = [
    "MAX_ARRAY_BYTES",
    "MAX_MODEL_FILE_BYTES",
    "MAX_MODEL_JOINTS",
    "MODEL_FORMAT",
    "ModelArray",
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
#: Largest model file, bytes (a fitted model of a 150-joint rig is well under 10 MB).
MAX_MODEL_FILE_BYTES = 256 << 20
#: Largest array a model file may declare, bytes (mcb-linf's basis of a 1024-joint rig: 38 MB).
MAX_ARRAY_BYTES = 64 << 20
#: Largest sum of the arrays a model file declares, bytes.
MAX_TOTAL_BYTES = 256 << 20
#: Most members (arrays) of a model file.
MAX_MEMBERS = 256
#: Largest joint count of a model (the spatial-transform codecs' own bound).
MAX_MODEL_JOINTS = 1024
#: Longest config JSON, characters.
MAX_CONFIG_CHARS = 1 << 16
_MAX_NPY_HEADER_BYTES = 4096


@dataclass(frozen=True)
class ModelArray:
    """An array a codec's model state holds: its dtype and its shape for a given joint count.

    Attributes
    ----------
    dtype : str
        numpy dtype string (``"<f4"``, ``"<u4"``, ``"u1"``), compared exactly.
    shape : tuple of int
        Compared exactly, but for a -1 that takes any length (a byte string whose size the state's own reader
        bounds and checks; the file's limits bound it first).
    """

    dtype: str
    shape: tuple[int, ...]


#: The fields every model file holds beside the codec's state: name -> (dtype kind, largest item bytes).
META_ARRAYS = {"mcb_format": ("iu", 8), "mcb_codec": ("U", 4 * 64), "mcb_config": ("U", 4 * MAX_CONFIG_CHARS),
               "mcb_num_joints": ("iu", 8)}

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
    """The codec a model file was fit for, holding its model (the file checked as the module docstring says).

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
        One line naming the file: unreadable, not a zip of ``.npy`` arrays, an array too large, another format,
        another codec than ``codec_name``, an array the codec does not expect, a state that fails validation.
    """
    path = Path(path)

    def error(message: str) -> ModelFileError:
        return ModelFileError(f"{path}: {message.rstrip('.')}.")

    with _open_regular(path, error) as file:
        try:
            archive = zipfile.ZipFile(file)
        except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError, ValueError) as problem:
            raise error(f"not a mocapbench model file (not a zip archive of arrays: {problem})") from None
        with archive:
            headers = _member_headers(archive, error)
            _check_meta_headers(headers, error)
            meta = {key: _read_member(archive, headers[key], error) for key in META_ARRAYS}
            codec, num_joints = _codec_of(meta, settings, codec_name, error)
            expected = _expected_state(codec, num_joints, headers, error)
            state = {key: _read_member(archive, headers[f"state_{key}"], error) for key in expected}
    try:
        codec = codec.load_model_state(state)
    except (KeyError, ValueError, TypeError, IndexError, ArithmeticError) as problem:
        raise error(str(problem.args[0] if isinstance(problem, KeyError) and problem.args else problem).rstrip("."))\
            from None
    fitted = _state_joints(codec.name, split_states(state)[0])
    if fitted != num_joints:
        raise error(f"the state is fit for {fitted} joints, mcb_num_joints says {num_joints}")
    return codec


@contextlib.contextmanager
def _open_regular(path: Path, error):
    """Open a regular file for reading (never a pipe, device or folder) of at most MAX_MODEL_FILE_BYTES."""
    try:
        handle = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as problem:
        raise error(f"cannot read the model file: {problem.strerror or problem}") from None
    info = os.fstat(handle)
    if not stat.S_ISREG(info.st_mode):
        os.close(handle)
        raise error("not a regular file (a pipe, device or folder); expected a model file")
    if info.st_size > MAX_MODEL_FILE_BYTES:
        os.close(handle)
        raise error(f"a model file of {info.st_size:,} bytes exceeds the limit of {MAX_MODEL_FILE_BYTES:,}")
    with os.fdopen(handle, "rb") as file:
        yield file


@dataclass(frozen=True)
class _Member:
    """A ``.npy`` member of the archive as its header declares it."""

    info: zipfile.ZipInfo
    key: str
    dtype: np.dtype
    shape: tuple[int, ...]


def _member_headers(archive: zipfile.ZipFile, error) -> dict[str, _Member]:
    """Every member's declared dtype and shape, read from the ``.npy`` headers only; sizes checked."""
    infos = archive.infolist()
    if len(infos) > MAX_MEMBERS:
        raise error(f"the archive has {len(infos)} members; a model file has at most {MAX_MEMBERS}")
    headers: dict[str, _Member] = {}
    total = 0
    for info in infos:
        name = info.filename
        key = name[:-4]
        if not name.endswith(".npy") or not key or "/" in key or "\\" in key or key in headers:
            raise error(f"member {name[:80]!r} is not a uniquely named .npy array")
        try:
            with archive.open(info) as member:
                version = np.lib.format.read_magic(member)
                if version == (1, 0):
                    shape, fortran, dtype = np.lib.format.read_array_header_1_0(member, _MAX_NPY_HEADER_BYTES)
                elif version == (2, 0):
                    shape, fortran, dtype = np.lib.format.read_array_header_2_0(member, _MAX_NPY_HEADER_BYTES)
                else:
                    raise ValueError(f".npy format version {version}; expected 1.0 or 2.0")
                header_bytes = member.tell()
        except (zipfile.BadZipFile, zlib.error, OSError, EOFError, ValueError, TypeError, SyntaxError,
                NotImplementedError, RuntimeError) as problem:
            raise error(f"member {name[:80]!r} is not a readable .npy array ({str(problem)[:120]})") from None
        if dtype.hasobject:
            raise error(f"member {name[:80]!r} holds Python objects; a model file holds numbers and text only")
        size = dtype.itemsize
        for extent in shape:
            size *= extent
        if size > MAX_ARRAY_BYTES:
            raise error(f"array {key!r} declares shape {shape} of {dtype} ({size:,} bytes), over the limit of "
                        f"{MAX_ARRAY_BYTES:,} bytes per array")
        if info.file_size != header_bytes + size:
            raise error(f"array {key!r} declares {size:,} bytes but its member holds {info.file_size - header_bytes:,}")
        total += size
        if total > MAX_TOTAL_BYTES:
            raise error(f"the arrays declare more than {MAX_TOTAL_BYTES:,} bytes in all")
        headers[key] = _Member(info, key, dtype, tuple(shape))
    return headers


def _read_member(archive: zipfile.ZipFile, member: _Member, error) -> np.ndarray:
    """The array of a checked member (its declared size only)."""
    try:
        with archive.open(member.info) as file:
            array = np.lib.format.read_array(file, allow_pickle=False, max_header_size=_MAX_NPY_HEADER_BYTES)
    except (zipfile.BadZipFile, zlib.error, OSError, EOFError, ValueError, NotImplementedError) as problem:
        raise error(f"array {member.key!r} cannot be read ({str(problem)[:120]})") from None
    if array.shape != member.shape or array.dtype != member.dtype:
        raise error(f"array {member.key!r} changed between its header and its data")
    return array


def _check_meta_headers(headers: Mapping[str, _Member], error) -> None:
    """The four fields of every model file are present, scalars of the right kind and size (before reading them)."""
    missing = [key for key in META_ARRAYS if key not in headers]
    if missing:
        raise error(f"not a mocapbench model file (no {', '.join(missing)})")
    for key, (kinds, largest) in META_ARRAYS.items():
        member = headers[key]
        if member.shape != () or member.dtype.kind not in kinds:
            raise error(f"{key} must be a scalar of kind {kinds!r}, got shape {member.shape} of {member.dtype}")
        if member.dtype.itemsize > largest:
            raise error(f"{key} is longer than {largest // 4 if kinds == 'U' else largest} "
                        f"{'characters' if kinds == 'U' else 'bytes'}")


def _codec_of(meta: Mapping[str, np.ndarray], settings, codec_name, error) -> tuple[Codec, int]:
    """The codec named by the model's fields (checked: format, name, config object, joint count)."""
    if int(meta["mcb_format"]) != MODEL_FORMAT:
        raise error(f"model format {int(meta['mcb_format'])}, this mocapbench reads {MODEL_FORMAT}")
    name = str(meta["mcb_codec"])
    if codec_name is not None and codec_name != name:
        raise error(f"the model is for codec {name[:64]!r}, not {codec_name!r}")
    if name not in fittable_codecs():
        raise error(f"the model names codec {name[:64]!r}; codecs with a model are {fittable_codecs()}")
    num_joints = int(meta["mcb_num_joints"])
    if not 1 <= num_joints <= MAX_MODEL_JOINTS:
        raise error(f"mcb_num_joints is {num_joints}; expected 1..{MAX_MODEL_JOINTS}")
    config = _config_object(str(meta["mcb_config"]), error)
    config.update(settings or {})
    try:
        return create(name, **config), num_joints
    except (KeyError, ValueError, TypeError) as problem:
        raise error(f"its config does not make a {name} codec: "
                    f"{str(problem.args[0] if isinstance(problem, KeyError) and problem.args else problem)}") from None


def _config_object(text: str, error) -> dict[str, Any]:
    """The config JSON: an object with string keys, at most MAX_CONFIG_CHARS, nested no deeper than the parser."""
    if len(text) > MAX_CONFIG_CHARS:
        raise error(f"its config is {len(text):,} characters; the limit is {MAX_CONFIG_CHARS:,}")
    try:
        config = json.loads(text)
    except ValueError as problem:
        raise error(f"its config is not JSON ({problem})") from None
    except RecursionError:
        raise error("its config JSON is nested deeper than the parser allows") from None
    if not isinstance(config, dict):
        raise error(f"its config must be a JSON object of settings, got a JSON {type(config).__name__}")
    return config


def _expected_state(codec: Codec, num_joints: int, headers: Mapping[str, _Member], error) -> list[str]:
    """The state keys (without ``state_``) of the file, each checked against the codec's declared arrays."""
    state_keys = [key[len("state_"):] for key in headers if key.startswith("state_")]
    unknown = [key for key in headers if key not in META_ARRAYS and not key.startswith("state_")]
    if unknown:
        raise error(f"array {unknown[0][:64]!r} is not part of a model file")
    main, others = split_states(dict.fromkeys(state_keys))
    if num_joints in others:
        raise error(f"arrays 'state_j{num_joints}__...' repeat the main state's joint count {num_joints}")
    groups = {num_joints: main, **others}
    for joints, keys in groups.items():
        if not 1 <= joints <= MAX_MODEL_JOINTS:
            raise error(f"arrays for {joints} joints; expected 1..{MAX_MODEL_JOINTS}")
        declared = codec.model_arrays(joints)
        prefix = "" if keys is main else f"j{joints}__"
        for key in keys:
            if key not in declared:
                raise error(f"array 'state_{prefix}{key}' is not one {codec.name} holds; it holds {sorted(declared)}")
        for key, spec in declared.items():
            member = headers.get(f"state_{prefix}{key}")
            if member is None:
                raise error(f"no array 'state_{prefix}{key}'; {codec.name} needs {sorted(declared)}")
            fits = len(member.shape) == len(spec.shape) and all(
                wanted in (-1, size) for wanted, size in zip(spec.shape, member.shape))  # -1: any length
            if member.dtype != np.dtype(spec.dtype) or not fits:
                raise error(f"array 'state_{prefix}{key}' is {member.shape} of {member.dtype}; {codec.name} expects "
                            f"{spec.shape} of {np.dtype(spec.dtype)} for {joints} joints")
    return state_keys


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
