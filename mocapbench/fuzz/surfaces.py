"""Hostile input files for the fuzz harness: motion files (BVH, glTF, GLB, FBX) and model files, and one read of each.

Beside the streams (:mod:`.harness`), every input a user hands mocapbench is a surface: a motion file read by
``compress`` and ``inspect`` (:func:`mocapbench.io.formats.read_motion`) and a model file read by ``--model``
(:func:`mocapbench.codecs.model_file.load_model`). Each surface has seeds (valid files written by mocapbench's own
writers, the ASCII FBX one of :mod:`mocapbench.io.fbx_ascii` among them) and two kinds of hostile inputs, drawn
in turn from a seeded generator:

* ``mutated``: a seed edited: a number replaced by a boundary or absurd value (NaN, inf, 1e308, 4294967296, ...),
  a line deleted or repeated, a byte replaced or inserted (NUL, 0xFF, a byte-order mark), the file truncated; for
  glTF/GLB a JSON value anywhere in the document replaced by a hostile one (an escaping ``uri``, a huge count,
  a wrong type) with the GLB chunk lengths kept right, or key times and values in the binary chunk overwritten;
  for model files an array corrupted (non-finite, zero, negative, rescaled, another dtype or shape, removed,
  an extra one, a declared shape of gigabytes) or the config replaced, the archive rebuilt so its CRCs are valid;
* ``generated``: an input built to be hostile from scratch: a BVH chain of thousands of joints or a ``Frames:``
  of billions, a glTF nested a hundred thousand levels deep or whose last key sits at 10^5 s, a model whose
  arrays declare gigabytes.

A read counts as *clean* when it returns a motion (or a model that then codes a motion) or raises the surface's
one-line error (:class:`~mocapbench.motion.MotionFormatError`, :class:`~mocapbench.codecs.model_file.ModelFileError`,
and for a loaded model a refusal to code: ``NotFittedError``, ``BitstreamError``); anything else is a finding.
"""

from __future__ import annotations

import importlib.util
import io
import json
import re
import struct
import tempfile
import zipfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

__all__ = ["SURFACES", "SURFACE_LABELS", "clean_errors", "file_mutations", "read_input", "seed_files"]

#: Surfaces and the suffix their inputs are written with.
SURFACES = {"bvh": ".bvh", "gltf": ".gltf", "glb": ".glb", "fbx": ".fbx", "model": ".npz"}
#: The row of the campaign table each surface counts in.
SURFACE_LABELS = {"bvh": "BVH", "gltf": "glTF/GLB", "glb": "glTF/GLB", "fbx": "FBX", "model": "models"}
_MODEL_CODECS = (("mcb-linf", {}), ("mcb-linf", {"representation": "bone"}), ("lsdt-clip", {}), ("lsdt-frame", {}))
#: Joints and frames of the motion a loaded model codes (the seeds' skeleton).
_MODEL_JOINTS, _MODEL_FRAMES = 15, 40

_NUMBERS = (b"nan", b"inf", b"-inf", b"1e308", b"-1e308", b"1e-320", b"0", b"-0", b"4294967296", b"99999999999",
            b"1e9", b"-1", b"3.4e38", b"0x10", b"1_0", "\u0661".encode(), b"1e99999", b"")
_BYTES = (b"\x00", b"\xff", b"\xef\xbb\xbf", b"{", b"}", b"\n", b"\r", b" ", b"\t", b"\x80")
_JSON_VALUES = (-1, 0, 1, 2**31, 2**32 + 7, 10**12, 1e308, -1e308, 0.5, None, "", "../secret.bin", "/dev/zero",
                "file:///etc/passwd", "data:application/octet-stream;base64,AAAA", "CUBICSPLINE", "MAT4", [], {},
                [0, 0, 0], [1e30, 0, 0, 1], "x" * 1000, True)
_NUMBER = re.compile(rb"-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")


# -- seeds ------------------------------------------------------------------------------------------------------


def _fbx_writer():
    """The ASCII FBX writer (FBX seeds are read back with ``ufbx``: None where it is not installed)."""
    if importlib.util.find_spec("ufbx") is None:
        return None
    from mocapbench.io.fbx_ascii import write_fbx_ascii

    return write_fbx_ascii


def seed_files(surfaces: list[str] | None = None) -> dict[str, list[bytes]]:
    """Valid inputs per surface: two rigs (15 joints Y-up cm, 22 joints Z-up mm) in each motion format, and the
    model files of every fittable codec fit on a 15-joint rig. FBX is absent where it cannot be written or read."""
    from mocapbench.codecs.model_file import fit_codec, model_bytes
    from mocapbench.io.bvh import write_bvh
    from mocapbench.io.gltf import write_gltf
    from mocapbench.synthetic import rig_motion

    wanted = list(SURFACES) if surfaces is None else surfaces
    rigs = [rig_motion(num_joints=15, num_frames=12, seed=1),
            rig_motion(num_joints=22, num_frames=20, up_axis="z", unit="mm", euler_orders="mixed", seed=2)]
    seeds: dict[str, list[bytes]] = {}
    with tempfile.TemporaryDirectory() as folder:
        for index, motion in enumerate(rigs):
            path = Path(folder) / f"seed{index}"
            if "bvh" in wanted:
                seeds.setdefault("bvh", []).append(write_bvh(motion, path.with_suffix(".bvh")).read_bytes())
            for surface in ("gltf", "glb"):
                if surface in wanted:
                    written = write_gltf(motion, path.with_suffix(SURFACES[surface]))
                    seeds.setdefault(surface, []).append(written.read_bytes())
            writer = _fbx_writer() if "fbx" in wanted else None
            if writer is not None:
                fbx = writer(motion, path.with_suffix(".fbx"), unit_cm=motion.source_unit_cm)
                seeds.setdefault("fbx", []).append(fbx.read_bytes())
    if "model" in wanted:
        motions = [rig_motion(num_joints=_MODEL_JOINTS, num_frames=80, seed=seed) for seed in (3, 4)]
        seeds["model"] = [model_bytes(fit_codec(name, settings, motions)) for name, settings in _MODEL_CODECS]
    return seeds


# -- mutations --------------------------------------------------------------------------------------------------


def _text_mutation(data: bytes, rng: np.random.Generator) -> bytes:
    """A number, a line or a byte of a text file edited, or the file truncated."""
    kind = int(rng.integers(0, 5))
    if kind == 0:
        numbers = list(_NUMBER.finditer(data))
        if numbers:
            for _ in range(int(rng.integers(1, 4))):
                match = numbers[int(rng.integers(len(numbers)))]
                value = _NUMBERS[int(rng.integers(len(_NUMBERS)))]
                data = data[: match.start()] + value + data[match.end():] if len(data) >= match.end() else data
            return data
    lines = data.split(b"\n")
    if kind == 1 and len(lines) > 1:
        at = int(rng.integers(len(lines)))
        if rng.integers(2):
            del lines[at]
        else:
            lines[at:at] = [lines[at]] * int(rng.integers(1, 4))
        return b"\n".join(lines)
    if kind == 2:
        return data[: int(rng.integers(len(data) + 1))]
    out = bytearray(data)
    for _ in range(int(rng.integers(1, 6))):
        at = int(rng.integers(len(out) + 1))
        value = _BYTES[int(rng.integers(len(_BYTES)))]
        if rng.integers(2) and at < len(out):
            out[at:at + len(value)] = value
        else:
            out[at:at] = value
    return bytes(out)


def _json_paths(node, path=()) -> Iterator[tuple]:
    yield path
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _json_paths(value, (*path, key))
    elif isinstance(node, list):
        for index, value in enumerate(node[:64]):
            yield from _json_paths(value, (*path, index))


def _json_mutation(document: dict, rng: np.random.Generator) -> dict:
    """One to three values anywhere in a glTF document replaced by hostile ones."""
    document = json.loads(json.dumps(document))
    for _ in range(int(rng.integers(1, 4))):
        paths = [path for path in _json_paths(document) if path]
        path = paths[int(rng.integers(len(paths)))]
        parent = document
        for key in path[:-1]:
            parent = parent[key]
        value = _JSON_VALUES[int(rng.integers(len(_JSON_VALUES)))]
        if isinstance(parent[path[-1]], (int, float)) and not isinstance(parent[path[-1]], bool) and rng.integers(2):
            value = parent[path[-1]] * float(rng.choice([-1, 2, 1e4, 1e9, 0.5]))  # near the original, scaled
        parent[path[-1]] = value
    return document


def _glb_parts(data: bytes) -> tuple[dict, bytes]:
    length = struct.unpack_from("<I", data, 12)[0]
    document = json.loads(data[20:20 + length])
    rest = data[20 + length:]
    blob = rest[8:8 + struct.unpack_from("<I", rest, 0)[0]] if len(rest) >= 8 else b""
    return document, blob


def _glb(document: dict, blob: bytes) -> bytes:
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    chunks = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(blob), b"BIN\0") + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks


def _blob_mutation(blob: bytes, rng: np.random.Generator) -> bytes:
    """Float32 values of the binary chunk (key times, rotations) overwritten with hostile ones."""
    out = bytearray(blob)
    for _ in range(int(rng.integers(1, 5))):
        if len(out) >= 4:
            at = 4 * int(rng.integers(len(out) // 4))
            value = float(rng.choice([np.nan, np.inf, 1e30, -1e30, 1e5, 0.0, -1.0, 8e4]))
            out[at:at + 4] = struct.pack("<f", value)
    return bytes(out)


def _gltf_mutation(data: bytes, binary: bool, rng: np.random.Generator) -> bytes:
    kind = int(rng.integers(0, 4))
    if kind == 3:
        return _text_mutation(data, rng) if not binary else _text_mutation(data[:20], rng) + data[20:]
    if binary:
        document, blob = _glb_parts(data)
    else:
        document = json.loads(data)
        head, _, encoded = document["buffers"][0]["uri"].partition(",")
        import base64

        blob = base64.b64decode(encoded)
    if kind in (0, 1):
        document = _json_mutation(document, rng)
    else:
        blob = _blob_mutation(blob, rng)
    if binary:
        return _glb(document, blob)
    if kind == 2:
        import base64

        document["buffers"][0]["uri"] = head + "," + base64.b64encode(blob).decode()
    return json.dumps(document).encode()


def _npy(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array(buffer, np.asarray(array), allow_pickle=False)
    return buffer.getvalue()


def _npy_header_only(shape: tuple[int, ...], dtype: str = "<f8") -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": dtype, "fortran_order": False, "shape": shape})
    return buffer.getvalue()


def _zip(members: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, content in members.items():  # a fixed date: the same seed gives the same bytes
            archive.writestr(zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0)), content, zipfile.ZIP_DEFLATED)
    return buffer.getvalue()


def _corrupt_array(array: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    with np.errstate(all="ignore"):  # casts of NaN and overflowing values are the point
        return _corrupted(array, rng)


def _corrupted(array: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    kind = int(rng.integers(0, 9))
    if kind == 0 and array.dtype.kind == "f" and array.size:
        out = array.copy()
        out.flat[int(rng.integers(array.size))] = float(rng.choice([np.nan, np.inf, -np.inf]))
        return out
    if kind == 1:
        return np.zeros_like(array)
    if kind == 2 and array.dtype.kind in "fi":
        return (-np.abs(array) - 1).astype(array.dtype)
    if kind == 3 and array.dtype.kind in "fiu":
        return (array * float(rng.choice([2.0, 1e6, 1e-6])) + 1).astype(array.dtype)
    if kind == 4 and array.dtype.kind != "U":
        return array.astype(rng.choice([np.float64, np.float16, np.int64, np.uint8, np.bool_]))
    if kind == 5:
        return array.reshape(-1)[: max(array.size - 1, 0)]
    if kind == 6 and array.dtype.kind in "iu" and array.size:
        out = array.copy()
        out.flat[int(rng.integers(array.size))] = np.iinfo(array.dtype).max
        return out
    if kind == 7:
        return np.ones(tuple(int(n) for n in rng.integers(0, 5, size=int(rng.integers(0, 4)))), array.dtype)
    return np.array(["x"]) if array.dtype.kind != "U" else np.array(0)


_CONFIGS = ("[1, 2]", '"eps_cm"', "{", "[" * 30000 + "]" * 30000, '{"eps_cm": -1}', '{"no_field": 1}',
            '{"eps_cm": 1e308}', '{"clip_frames": 0}', "null", '{"representation": "pca"}', '{"basis": "cmu-v1"}')


def _model_mutation(data: bytes, rng: np.random.Generator) -> bytes:
    kind = int(rng.integers(0, 6))
    if kind == 5:  # the archive's bytes themselves (most edits fail its CRCs)
        return _text_mutation(data, rng) if rng.integers(2) else data[: int(rng.integers(len(data) + 1))]
    with np.load(io.BytesIO(data)) as stored:
        arrays = {name: stored[name] for name in stored.files}
    members = {f"{name}.npy": _npy(value) for name, value in arrays.items()}
    names = sorted(arrays)
    name = names[int(rng.integers(len(names)))]
    if kind <= 1:
        members[f"{name}.npy"] = _npy(_corrupt_array(arrays[name], rng))
    elif kind == 2:
        members["mcb_config.npy"] = _npy(np.array(_CONFIGS[int(rng.integers(len(_CONFIGS)))]))
    elif kind == 3:
        del members[f"{name}.npy"]
    else:  # an extra array: small, or declaring gigabytes it does not hold
        extra = f"state_{'j9__' if rng.integers(2) else ''}extra{int(rng.integers(3))}.npy"
        members[extra] = _npy(np.zeros(3)) if rng.integers(2) else _npy_header_only((int(rng.integers(1, 1 << 40)),))
        if rng.integers(2):
            members[f"{name}.npy"] = _npy_header_only((1 << 29, 3)) + b"\0" * 64
    return _zip(members)


def _generated(surface: str, rng: np.random.Generator, seed: bytes) -> bytes:
    """An input hostile from scratch (see the module docstring)."""
    if surface == "bvh":
        kind = int(rng.integers(0, 3))
        if kind == 0:  # a chain of thousands of joints
            depth = int(rng.choice([100, 4096, 5000]))
            root = "ROOT j0\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
            chain = "".join(f"JOINT j{i}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n"
                            for i in range(1, depth))
            text = "HIERARCHY\n" + root + chain + "}\n" * depth
            return (text + "MOTION\nFrames: 1\nFrame Time: 0.0083333\n" + "0 " * (3 * depth + 3) + "\n").encode()
        if kind == 1:  # a Frames: of billions over a few bytes of data
            return re.sub(rb"Frames: \d+", b"Frames: " + str(int(rng.integers(10**6, 10**12))).encode(), seed)
        return re.sub(rb"Frame Time: [^\n]+", b"Frame Time: " + bytes(rng.choice([b"1e-300", b"0", b"1e300"])), seed)
    if surface in ("gltf", "glb"):
        binary = surface == "glb"
        document, blob = _glb_parts(seed) if binary else (json.loads(seed), b"")
        if rng.integers(2):  # nested deeper than any parser
            text = json.dumps(document)[:-1] + ',"extras":' + "[" * 100_000 + "]" * 100_000 + "}"
            if not binary:
                return text.encode()
            chunk = text.encode() + b" " * (-len(text) % 4)
            return struct.pack("<4sII", b"glTF", 2, 20 + len(chunk)) + struct.pack("<I4s", len(chunk), b"JSON") + chunk
        # The key times' accessor bounds declaring 1e5 s: the reader must size F x J from them before allocating.
        times = document["animations"][0]["samplers"][0]["input"]
        document["accessors"][times]["max"] = [1e5]
        if binary:
            view = document["bufferViews"][document["accessors"][times]["bufferView"]]
            at = view.get("byteOffset", 0) + 4 * (document["accessors"][times]["count"] - 1)
            blob = blob[:at] + struct.pack("<f", float(rng.choice([1e5, 8e4, 3e4]))) + blob[at + 4:]
            return _glb(document, blob)
        return json.dumps(document).encode()
    if surface == "fbx":  # key times scaled (a capture of hours), or a key count far beyond the keys given
        scale = int(rng.choice([10**3, 10**4, 10**5, 10**9]))
        return re.sub(rb"KeyTime: \*(\d+) \{\s*a: ([^}]*)\}", lambda m: m.group(0).replace(
            m.group(2), b",".join(str(int(v) * scale).encode() for v in m.group(2).split(b",") if v.strip())),
            seed) if rng.integers(2) else re.sub(rb"KeyTime: \*\d+", b"KeyTime: *4000000000", seed)
    # model: every array declaring a large shape, and a zip bomb of zeros
    with np.load(io.BytesIO(seed)) as stored:
        members = {f"{name}.npy": _npy(stored[name]) for name in stored.files}
    if rng.integers(2):
        return _zip({**members, "state_bomb.npy": _npy_header_only((3 << 27,))})
    return _zip({**members, "state_zeros.npy": _npy(np.zeros(1 << 20))})


def file_mutations(surface: str, seed: bytes, count: int, seed_value: int) -> Iterator[tuple[str, bytes]]:
    """``count`` hostile variants of ``seed`` for ``surface``: ``(kind, data)``, 3 mutated for each generated."""
    rng = np.random.default_rng(seed_value)
    for index in range(count):
        if index % 4 == 3:
            yield "generated", _generated(surface, rng, seed)
        elif surface in ("gltf", "glb"):
            yield "mutated", _gltf_mutation(seed, surface == "glb", rng)
        elif surface == "model":
            yield "mutated", _model_mutation(seed, rng)
        else:
            yield "mutated", _text_mutation(seed, rng)


# -- one read, in a worker --------------------------------------------------------------------------------------


def read_input(surface: str, data: bytes, folder: Path, limits) -> int:
    """Read one input of ``surface`` from a file in ``folder`` (nothing else in it) under ``limits``.

    Returns the bytes of the arrays built (the motion's, or those a loaded model decoded). Raises the surface's
    clean error, or anything else (a finding).
    """
    from mocapbench.codecs.limits import using_limits

    for old in folder.glob("input.*"):  # the folder holds this input only (a glTF may name files beside it)
        old.unlink()
    path = folder / f"input{SURFACES[surface]}"
    path.write_bytes(data)
    with using_limits(limits):
        if surface == "model":
            return _code_with_model(path)
        from mocapbench.io.formats import read_motion

        motion, _ = read_motion(path)
        return motion.rotations.nbytes + motion.root_positions.nbytes + motion.num_frames * motion.num_joints * 24


_MODEL_MOTION = []


def _code_with_model(path: Path) -> int:
    """Load a model file and code a motion of its skeleton with it (a model that loads must code)."""
    from mocapbench.codecs.model_file import load_model
    from mocapbench.synthetic import rig_motion

    codec = load_model(path)
    if not _MODEL_MOTION:
        _MODEL_MOTION.append(rig_motion(num_joints=_MODEL_JOINTS, num_frames=_MODEL_FRAMES, seed=5))
    decoded = codec.decode(codec.encode(_MODEL_MOTION[0]))
    return decoded.positions.nbytes


def clean_errors() -> tuple[type[BaseException], ...]:
    """The exceptions that are a clean refusal of an input (one line naming it)."""
    from mocapbench.codecs.base import NotFittedError
    from mocapbench.codecs.model_file import ModelFileError
    from mocapbench.entropy.errors import BitstreamError
    from mocapbench.motion import MotionFormatError

    return MotionFormatError, ModelFileError, NotFittedError, BitstreamError
