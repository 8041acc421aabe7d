"""Model files are untrusted input: bounded before they are read, checked against the codec's list, validated.

Every refusal is one :class:`ModelFileError` line naming the file. The corrupted states are those a model file
can carry: each array of each fittable codec's model made non-finite, zero, negative, rescaled, of another dtype
or shape, or inconsistent with the joint count; the file itself not a zip, a zip bomb, an unknown array, a list or
deeply nested JSON where the config belongs.
"""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from mocapbench.codecs import model_file
from mocapbench.codecs.model_file import ModelFileError, fit_codec, load_model, model_bytes
from mocapbench.synthetic import rig_motion

ROOT = Path(__file__).resolve().parents[2]
CODECS = [("mcb-linf", {}), ("mcb-linf", {"representation": "bone"}), ("lsdt-clip", {}), ("lsdt-frame", {})]


@pytest.fixture(scope="module")
def models() -> dict[str, dict[str, np.ndarray]]:
    """The arrays of a model file of each fittable codec (fit on a 15-joint rig)."""
    motions = [rig_motion(num_joints=15, num_frames=120, seed=seed) for seed in (1, 2)]
    out = {}
    for name, settings in CODECS:
        key = name + "".join(f"-{v}" for v in settings.values())
        with np.load(io.BytesIO(model_bytes(fit_codec(name, settings, motions)))) as stored:
            out[key] = {member: stored[member] for member in stored.files}
    return out


@pytest.fixture(scope="module")
def target():
    return rig_motion(num_joints=15, num_frames=60, seed=3)


def _write(path: Path, arrays: dict[str, np.ndarray]) -> Path:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    path.write_bytes(buffer.getvalue())
    return path


def _refused(path: Path, match: str) -> str:
    with pytest.raises(ModelFileError, match=match) as error:
        load_model(path)
    message = str(error.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    return message


def test_every_fitted_model_loads_and_codes(tmp_path, models, target):
    for key, arrays in models.items():
        codec = load_model(_write(tmp_path / f"{key}.npz", arrays))
        decoded = codec.decode(codec.encode(target))
        assert decoded.positions.shape == (60, 15, 3)


@pytest.mark.parametrize(
    ("data", "match"),
    [(b"not a zip at all", "not a zip archive"), (b"PK\x03\x04" + b"\0" * 40, "not a zip archive"), (b"", "not a zip")],
)
def test_a_file_that_is_not_a_zip_is_one_line(tmp_path, data, match):
    path = tmp_path / "bad.npz"
    path.write_bytes(data)
    _refused(path, match)


def test_a_folder_a_pipe_and_a_missing_file_are_one_line(tmp_path):
    _refused(tmp_path, "not a regular file")
    os.mkfifo(tmp_path / "pipe.npz")
    _refused(tmp_path / "pipe.npz", "not a regular file")
    _refused(tmp_path / "missing.npz", "cannot read the model file")


@pytest.mark.parametrize(
    ("config", "match"),
    [
        ("[1, 2, 3]", "its config must be a JSON object of settings, got a JSON list"),
        ('"eps_cm"', "got a JSON str"),
        ("{not json", "its config is not JSON"),
        ("[" * 50_000 + "]" * 50_000, "mcb_config is longer than 65536 characters"),
        ("[" * 20_000 + "]" * 20_000, "nested deeper than the parser allows"),
        ('{"no_such_field": 1}', "its config does not make a mcb-linf codec"),
        ('{"eps_cm": -1}', "its config does not make a mcb-linf codec"),
    ],
)
def test_a_config_that_is_not_an_object_of_settings_is_one_line(tmp_path, models, config, match):
    arrays = dict(models["mcb-linf"], mcb_config=np.array(config))
    _refused(_write(tmp_path / "m.npz", arrays), match)


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        ({"mcb_format": np.array(2)}, "model format 2, this mocapbench reads 1"),
        ({"mcb_format": np.array([1, 1])}, "mcb_format must be a scalar"),
        ({"mcb_format": np.array(1.0)}, "mcb_format must be a scalar of kind 'iu'"),
        ({"mcb_codec": np.array("svd")}, "codecs with a model are"),
        ({"mcb_num_joints": np.array(16)}, "16 joints|for 16 joints"),
        ({"mcb_num_joints": np.array(0)}, "mcb_num_joints is 0"),
        ({"mcb_num_joints": np.array(10**6)}, "mcb_num_joints is 1000000"),
        ({"surprise": np.zeros(3)}, "array 'surprise' is not part of a model file"),
        ({"state_surprise": np.zeros(3)}, "array 'state_surprise' is not one mcb-linf holds"),
        ({"state_j15__basis": np.zeros(3)}, "repeat the main state's joint count 15"),
        ({"state_j9__basis": np.zeros(3)}, "no array 'state_j9__representation'"),
    ],
)
def test_the_fields_and_the_list_of_arrays_are_checked(tmp_path, models, edit, match):
    _refused(_write(tmp_path / "m.npz", {**models["mcb-linf"], **edit}), match)


def test_a_missing_field_or_array_is_refused(tmp_path, models):
    for missing, match in (("mcb_codec", "no mcb_codec"), ("state_band_scale", "no array 'state_band_scale'")):
        arrays = {k: v for k, v in models["mcb-linf"].items() if k != missing}
        _refused(_write(tmp_path / "m.npz", arrays), match)


def _corruptions(array: np.ndarray) -> dict[str, np.ndarray]:
    """Corrupted copies of a state array that keep its dtype and shape (so that only validation can refuse them)."""
    out = {}
    if array.dtype.kind == "f" and array.size:
        for name, value in (("nan", np.nan), ("inf", np.inf)):
            bad = array.copy()
            bad.flat[array.size // 2] = value
            out[name] = bad
        out["zero"] = np.zeros_like(array)
        out["negative"] = (-np.abs(array) - 1).astype(array.dtype)
        out["doubled"] = (array * 2 + 1).astype(array.dtype)
    elif array.dtype.kind in "ui":
        out["zero"] = np.zeros_like(array)
        out["plus one"] = (array + 1).astype(array.dtype)
    return out


# (codec, array, corruption) that are still a usable model: other token counts, a different clip length (the
# model works for any clip length, "less efficiently"), a shifted mean (any mean is a valid centring), rescaled
# band scales (they set the coefficient classes: a rate cost, the encoder checks its own stream).
_STILL_VALID = {
    ("mcb-linf", "state_token_counts", "plus one"), ("mcb-linf", "state_lattice_counts", "plus one"),
    ("mcb-linf", "state_clip_frames", "plus one"), ("mcb-linf", "state_mean", "zero"),
    ("mcb-linf", "state_band_scale", "doubled"), ("mcb-linf-bone", "state_band_scale", "doubled"),
    ("mcb-linf", "state_mean", "negative"), ("mcb-linf", "state_mean", "doubled"),
    ("mcb-linf-bone", "state_token_counts", "plus one"), ("mcb-linf-bone", "state_lattice_counts", "plus one"),
    ("mcb-linf-bone", "state_clip_frames", "plus one"),
}


def _cases():
    motions = [rig_motion(num_joints=15, num_frames=120, seed=seed) for seed in (1, 2)]
    for name, settings in CODECS:
        key = name + "".join(f"-{v}" for v in settings.values())
        with np.load(io.BytesIO(model_bytes(fit_codec(name, settings, motions)))) as stored:
            for member in stored.files:
                if member.startswith("state_"):
                    for corruption in _corruptions(stored[member]):
                        if (key, member, corruption) not in _STILL_VALID:
                            yield key, member, corruption


@pytest.mark.parametrize(("key", "member", "corruption"), list(_cases()))
def test_every_corrupted_state_is_refused_naming_the_file(tmp_path, models, key, member, corruption):
    arrays = dict(models[key])
    arrays[member] = _corruptions(arrays[member])[corruption]
    _refused(_write(tmp_path / "m.npz", arrays), "mcb-linf: the model|lsdt-.*: the bases|expects|state is fit for")


@pytest.mark.parametrize("key", ["mcb-linf", "lsdt-clip"])
def test_another_dtype_or_shape_is_refused_before_the_array_is_read(tmp_path, models, key, monkeypatch):
    member = "state_basis" if key == "mcb-linf" else "state_bases"
    read = []
    original = model_file._read_member
    monkeypatch.setattr(model_file, "_read_member", lambda a, m, e: read.append(m.key) or original(a, m, e))
    for bad in (models[key][member].astype(np.float16), models[key][member][..., :-1]):
        _refused(_write(tmp_path / "m.npz", {**models[key], member: bad}), "expects")
    assert read and not any(name.startswith("state_") for name in read)


def _npy_header(shape: tuple[int, ...], dtype: str = "<f8") -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": dtype, "fortran_order": False, "shape": shape})
    return buffer.getvalue()


def test_a_zip_bomb_is_refused_from_its_declared_shape_before_it_is_inflated(tmp_path, models):
    path = tmp_path / "bomb.npz"
    _write(path, models["mcb-linf"])
    # 3 GiB declared (2^28 float64 of zeros would deflate to ~3 MB; the member holds only its header).
    with zipfile.ZipFile(path, "a", compression=zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("state_bomb.npy", _npy_header((3 << 27,)))
    message = _refused(path, "array 'state_bomb' declares shape")
    assert "3,221,225,472 bytes" in message and "over the limit of 67,108,864 bytes per array" in message


def test_a_member_larger_than_its_declared_shape_is_refused(tmp_path, models):
    path = tmp_path / "liar.npz"
    _write(path, {k: v for k, v in models["lsdt-clip"].items() if k != "state_bases"})
    bases = models["lsdt-clip"]["state_bases"]
    with zipfile.ZipFile(path, "a", compression=zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("state_bases.npy", _npy_header(bases.shape) + bases.tobytes() + b"\0" * (1 << 20))
    _refused(path, "array 'state_bases' declares 5,400 bytes but its member holds 1,053,976")


def test_an_unused_large_array_is_refused_unread(tmp_path, models, monkeypatch):
    path = tmp_path / "big.npz"
    _write(path, models["lsdt-frame"])
    with zipfile.ZipFile(path, "a", compression=zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("state_unused.npy", _npy_header((1 << 20,)) + bytes(8 << 20))  # 8 MiB of zeros
    read = []
    original = model_file._read_member
    monkeypatch.setattr(model_file, "_read_member", lambda a, m, e: read.append(m.key) or original(a, m, e))
    _refused(path, "array 'state_unused' is not one lsdt-frame holds")
    assert "state_unused" not in read


def test_object_arrays_and_odd_member_names_are_refused(tmp_path, models):
    path = _write(tmp_path / "m.npz", models["mcb-linf"])
    with zipfile.ZipFile(path, "a") as archive:
        archive.writestr("state_pickle.npy", _npy_header((2,), "|O") + b"\x80\x04")
    _refused(path, "holds Python objects")
    path = _write(tmp_path / "n.npz", models["mcb-linf"])
    with zipfile.ZipFile(path, "a") as archive:
        archive.writestr("../escape.txt", b"x")
    _refused(path, "is not a uniquely named .npy array")


FIT_TAG = """
from mocapbench.codecs.model_file import fit_codec
from mocapbench.synthetic import rig_motion
motions = [rig_motion(num_joints=31, num_frames=1500, seed=seed) for seed in (1, 2)]
print(fit_codec("mcb-linf", {}, motions)._model.tag)
"""


def test_the_mcb_linf_fit_gives_the_same_model_at_1_and_2_blas_threads():
    tags = set()
    for threads in ("1", "2"):
        env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": threads, "OMP_NUM_THREADS": threads,
               "MKL_NUM_THREADS": threads}
        result = subprocess.run([sys.executable, "-c", FIT_TAG], env=env, capture_output=True, text=True, check=True)
        tags.add(result.stdout.strip())
    assert len(tags) == 1, tags
