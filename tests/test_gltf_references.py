"""A glTF reads nothing outside its folder and nothing larger than the limits: every refusal is one line naming the URI.

The cases are those of a hostile upload: a buffer ``uri`` escaping the folder (``..``, an absolute path, a scheme,
percent-encoding, a symbolic link), a device or a pipe, a ``data:`` URI longer than its declared length, deeply
nested JSON, and a small file whose last key time asks for gigabytes of frames.
"""

from __future__ import annotations

import base64
import json
import os
import struct
import sys
import warnings

import numpy as np
import pytest

from mocapbench.codecs.limits import DecodeLimits, using_limits
from mocapbench.io.gltf import read_gltf, write_gltf
from mocapbench.motion import MotionFormatError
from mocapbench.synthetic import rig_motion


def _document(tmp_path) -> dict:
    """A small valid glTF (15 joints, 8 frames) as a JSON dict with its buffer as a data URI."""
    path = write_gltf(rig_motion(num_joints=15, num_frames=8), tmp_path / "base.gltf", force=True)
    return json.loads(path.read_text())


def _with_external_buffer(tmp_path, uri: str, *, folder=None, write_blob: str | None = "anim.bin"):
    """The document with its buffer moved to a file ``write_blob`` in ``folder`` and referenced as ``uri``."""
    folder = folder or tmp_path / "scene"
    folder.mkdir(exist_ok=True)
    document = _document(tmp_path)
    blob = base64.b64decode(document["buffers"][0]["uri"].split(",", 1)[1])
    if write_blob is not None:
        (tmp_path / write_blob if write_blob.startswith("../") else folder / write_blob).write_bytes(blob)
    document["buffers"][0]["uri"] = uri
    path = folder / "scene.gltf"
    path.write_text(json.dumps(document))
    return path, blob


def _refused(path, *fragments):
    with pytest.raises(MotionFormatError) as error:
        read_gltf(path)
    message = str(error.value)
    assert message.startswith(str(path)) and "\n" not in message
    for fragment in fragments:
        assert fragment in message, message
    return message


def test_a_buffer_beside_the_gltf_is_read(tmp_path):
    path, _ = _with_external_buffer(tmp_path, "anim.bin")
    assert read_gltf(path).num_frames == 8


def test_a_buffer_in_a_subfolder_and_a_link_inside_the_folder_are_read(tmp_path):
    folder = tmp_path / "scene"
    (folder / "data").mkdir(parents=True)
    path, blob = _with_external_buffer(tmp_path, "data/../data/anim%20one.bin", write_blob="data/anim one.bin")
    assert read_gltf(path).num_frames == 8
    os.symlink("data/anim one.bin", folder / "linked.bin")
    path, _ = _with_external_buffer(tmp_path, "linked.bin", write_blob=None)
    assert read_gltf(path).num_frames == 8


@pytest.mark.parametrize(
    ("uri", "fragment"),
    [
        ("../secret.bin", "leads outside the glTF's folder"),
        ("%2e%2e/secret.bin", "leads outside the glTF's folder"),
        ("data/../../secret.bin", "leads outside the glTF's folder"),
        ("/etc/passwd", "absolute path"),
        ("/dev/zero", "absolute path"),
        ("file:///etc/passwd", "has a scheme"),
        ("https://example.com/anim.bin", "has a scheme"),
        ("C:\\secret.bin", "has a scheme"),
        ("..\\secret.bin", "backslash"),
        ("anim%00.bin", "NUL"),
        ("missing.bin", "No such file"),
    ],
)
def test_a_buffer_uri_outside_the_folder_is_refused_naming_it(tmp_path, uri, fragment):
    (tmp_path / "scene" / "data").mkdir(parents=True)
    path, _ = _with_external_buffer(tmp_path, uri, write_blob="../secret.bin")
    _refused(path, fragment, f"buffers[0]: uri {uri!r}")


def test_a_link_leading_out_of_the_folder_is_refused(tmp_path):
    folder = tmp_path / "scene"
    folder.mkdir()
    os.symlink(tmp_path / "secret.bin", folder / "anim.bin")
    path, _ = _with_external_buffer(tmp_path, "anim.bin", write_blob="../secret.bin")
    _refused(path, "leads outside the glTF's folder", "'anim.bin'")
    # A link to a folder outside, then a file name under it.
    os.symlink(tmp_path, folder / "up")
    path, _ = _with_external_buffer(tmp_path, "up/secret.bin", write_blob=None)
    _refused(path, "leads outside the glTF's folder")


@pytest.mark.skipif(sys.platform == "win32", reason="named pipes and /dev links are POSIX")
def test_a_pipe_or_device_inside_the_folder_is_refused_before_it_is_opened(tmp_path):
    folder = tmp_path / "scene"
    folder.mkdir()
    os.mkfifo(folder / "pipe.bin")  # opening it for reading would block forever: the refusal comes first
    path, _ = _with_external_buffer(tmp_path, "pipe.bin", write_blob=None)
    _refused(path, "not a regular file", "'pipe.bin'")
    os.symlink("/dev/zero", folder / "zero.bin")
    path, _ = _with_external_buffer(tmp_path, "zero.bin", write_blob=None)
    _refused(path, "leads outside the glTF's folder")


def test_a_buffer_file_shorter_than_declared_is_refused_and_a_longer_one_read_up_to_its_length(tmp_path):
    path, blob = _with_external_buffer(tmp_path, "anim.bin")
    (path.parent / "anim.bin").write_bytes(blob[:-4])
    _refused(path, f"declares {len(blob)} bytes", f"holds {len(blob) - 4}")
    (path.parent / "anim.bin").write_bytes(blob + b"\0" * 4096)
    assert read_gltf(path).num_frames == 8


def test_an_image_uri_outside_the_folder_is_refused_but_a_missing_image_inside_is_not(tmp_path):
    path, _ = _with_external_buffer(tmp_path, "anim.bin")
    document = json.loads(path.read_text())
    document["images"] = [{"uri": "textures/skin.png"}]
    path.write_text(json.dumps(document))
    assert read_gltf(path).num_frames == 8
    document["images"] = [{"uri": "../../etc/passwd"}]
    path.write_text(json.dumps(document))
    _refused(path, "images[0]: uri '../../etc/passwd'", "outside")


def test_a_data_uri_longer_than_its_declared_length_is_refused_before_decoding(tmp_path):
    document = _document(tmp_path)
    head, encoded = document["buffers"][0]["uri"].split(",", 1)
    document["buffers"][0]["uri"] = head + "," + encoded + "A" * 4000
    path = tmp_path / "long.gltf"
    path.write_text(json.dumps(document))
    _refused(path, "buffers[0]: the data URI holds", "base64 characters")
    document["buffers"][0]["byteLength"] = 1 << 40
    path.write_text(json.dumps(document))
    _refused(path, "buffers[0] declares byteLength 1099511627776")


@pytest.mark.parametrize("binary", [False, True])
def test_deeply_nested_json_is_one_line(tmp_path, binary):
    document = _document(tmp_path)
    text = json.dumps(document)[:-1] + ',"extras":' + "[" * 200_000 + "]" * 200_000 + "}"
    if binary:
        chunk = text.encode() + b" " * (-len(text) % 4)
        data = struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(chunk)) + struct.pack("<I4s", len(chunk), b"JSON") + chunk
        path = tmp_path / "deep.glb"
        path.write_bytes(data)
    else:
        path = tmp_path / "deep.gltf"
        path.write_text(text)
    _refused(path, "nested deeper than the parser allows")


def _last_key_at(tmp_path, seconds: float):
    """The document with the key times' last value moved to ``seconds`` (a few kB asking for many frames)."""
    document = _document(tmp_path)
    blob = bytearray(base64.b64decode(document["buffers"][0]["uri"].split(",", 1)[1]))
    times = document["animations"][0]["samplers"][0]["input"]
    accessor = document["accessors"][times]
    view = document["bufferViews"][accessor["bufferView"]]
    start = view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
    last = start + 4 * (accessor["count"] - 1)
    blob[last:last + 4] = np.float32(seconds).tobytes()
    accessor["max"] = [seconds]
    document["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
    path = tmp_path / "long.gltf"
    path.write_text(json.dumps(document))
    return path


def test_frames_times_joints_is_checked_against_the_limits_before_allocating(tmp_path):
    path = _last_key_at(tmp_path, 80_000.0)
    # 80,000 s at 120 fps: 9.6 M frames, under the frame cap alone, but x 15 joints far over 2 GiB of arrays.
    message = _refused(path, "over the limit output_bytes=2,147,483,648", "15 joints", "--limit output_bytes=N")
    assert "9,600,001 frames" in message
    small = _last_key_at(tmp_path, 10.0)
    assert read_gltf(small).num_frames > 1000
    with using_limits(DecodeLimits(max_output_bytes=10**6)):
        _refused(small, "over the limit output_bytes=1,000,000")
    with using_limits(DecodeLimits(max_joints=10)):
        _refused(small, "over the limit joints=10")


def _set(path_in_document, value):
    def edit(document):
        node = document
        for key in path_in_document[:-1]:
            node = node[key]
        node[path_in_document[-1]] = value
    return edit


@pytest.mark.parametrize(
    ("edit", "fragment"),
    [
        (_set(("nodes", 1, "rotation"), [0, 0, 1]), "nodes[1].rotation must be 4 finite numbers"),
        (_set(("nodes", 1, "translation"), "up"), "nodes[1].translation must be 3 finite numbers"),
        (_set(("nodes", 0, "children"), [1, -2]), "nodes[0].children must be an array of integers >= 0"),
        (_set(("animations", 0, "samplers", 0), None), "animations[0].samplers must be an array of JSON objects"),
        (_set(("animations", 0, "channels", 0, "target"), 5), "animations[0].channels[0].target must be a JSON object"),
        (_set(("accessors", 0, "byteOffset"), -1), "accessors[0].byteOffset must be an integer >= 0, got -1"),
        (_set(("bufferViews", 0, "byteStride"), 1e308), "bufferViews[0].byteStride must be an integer >= 0"),
        (_set(("buffers", 0, "uri"), 7), "buffers[0].uri must be a string"),
        (_set(("skins",), {"joints": [0]}), "skins must be a JSON array"),
        (_set(("asset",), None), "asset must be a JSON object"),
    ],
)
@pytest.mark.parametrize("binary", [False, True])
def test_a_field_of_the_wrong_json_type_is_one_line_naming_it(tmp_path, edit, fragment, binary):
    document = _document(tmp_path)
    edit(document)
    if binary:
        blob = base64.b64decode(_document(tmp_path)["buffers"][0]["uri"].split(",", 1)[1])
        if isinstance(document.get("buffers"), list) and isinstance(document["buffers"][0].get("uri"), str):
            del document["buffers"][0]["uri"]
        text = json.dumps(document).encode()
        text += b" " * (-len(text) % 4)
        chunks = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(blob), b"BIN\0") + blob
        path = tmp_path / "typed.glb"
        path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks)
    else:
        path = tmp_path / "typed.gltf"
        path.write_text(json.dumps(document))
    _refused(path, fragment)


@pytest.mark.parametrize(
    "nodes",
    [
        {14: {"translation": [1e308, 0, 0]}},
        {0: {"scale": [1e200] * 3}, 3: {"translation": [1e200, 0, 0]}},
        {0: {"rotation": [1e300, 1e300, 0, 0]}},
    ],
)
def test_finite_values_whose_products_overflow_are_one_line_without_warnings(tmp_path, nodes):
    document = _document(tmp_path)
    for index, fields in nodes.items():
        document["nodes"][index].update(fields)
    path = tmp_path / "huge.gltf"
    path.write_text(json.dumps(document))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        message = _refused(path)
    assert "do not make a motion" in message or "degenerate or mirroring" in message
