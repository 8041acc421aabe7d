"""glTF 2.0 / GLB skinned animation in and out (parsed and built with ``pygltflib``).

Reading (:func:`read_gltf`) takes one skin's joints and one animation's ``rotation``/``translation`` channels on
them, samples the channels at a fixed rate (LINEAR = lerp/slerp, STEP, CUBICSPLINE Hermite, as the glTF 2.0
specification defines them) and returns a :class:`~mocapbench.motion.Motion` in cm:

* the joint tree is the skin's joints under their nearest joint ancestor; a node between two joints that is not
  a joint, or more than one root joint, is refused in one line naming the node; a childless node under a joint
  that is not a joint and carries no mesh, skin or camera is an end site (the writer's end sites read back);
* ``translation`` and ``scale`` channels (and static scales) on any joint are read: a joint that moves gets a
  translation track, a joint that scales a scale track (:mod:`mocapbench.io.node_motion` folds the still ones);
  a scale <= 0 is refused naming the joint and the key or frame;
* the static transform of the nodes above the root joint (an "Armature" node turning Z-up to Y-up, or scaling
  cm to m) is baked into the root: it may rotate, translate and scale uniformly;
* the result has identity rest rotations, as BVH: local rotations are re-expressed relative to the nodes' static
  rotations (``R'_j = G_parent R_j G_j^-1`` with ``G`` the static global rotations) and offsets are the static
  translations turned into the parent's rest frame (``o'_j = G_parent t_j``). Joint positions are unchanged,
  and ``Skeleton.rest_positions`` is the file's rest pose;
* lengths are metres by the specification (``length_unit_cm`` = 100); ``up_axis`` is ``"y"``.

Writing (:func:`write_gltf`) produces what a glTF viewer plays: one node per joint (no static rotation, so the
nodes' own pose is the rest pose; translation the offset, the root's the first root position), a skin over them,
a childless node per end site under its joint (outside the skin), a line mesh of the bones and end sites skinned
to the joints (so a viewer shows a stick figure), and one animation with a LINEAR rotation sampler per joint, a
translation sampler on the root and on every joint that moves, a scale sampler on every joint that scales, one
key per frame. Lengths in metres, Y-up (a Z-up motion is turned by -90
degrees about X first). ``.glb`` is binary glTF; ``.gltf`` embeds its buffer as a base64 data URI (one file).

Not read: morph-target weights (ignored), sparse accessors, KHR extensions that change the data (refused), more
than one skin at a time (``skin=`` chooses), cameras and meshes (ignored).
"""

from __future__ import annotations

import base64
import json
import math
import struct
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mocapbench.io.external_files import check_reference, read_data_uri, read_reference
from mocapbench.io.gltf_schema import check_document
from mocapbench.io.keyframes import sample_keys as _sample
from mocapbench.io.node_motion import motion_from_nodes
from mocapbench.io.read_limits import check_array_bytes, check_motion_size
from mocapbench.io.reader_errors import one_line_errors
from mocapbench.motion import Motion, MotionFormatError

__all__ = ["read_gltf", "write_gltf"]

# componentType -> numpy dtype, and the divisor of a normalized integer (glTF 2.0, 3.6.2 and 3.11).
_COMPONENTS = {
    5120: (np.int8, 127.0),
    5121: (np.uint8, 255.0),
    5122: (np.int16, 32767.0),
    5123: (np.uint16, 65535.0),
    5125: (np.uint32, None),
    5126: (np.float32, None),
}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
_MAX_FILE_BYTES = 1 << 31
_MAX_FRAMES = 10_000_000


class _Reader:
    """The parsed document, its buffers and accessors, with every failure as a one-line MotionFormatError."""

    def __init__(self, path: Path) -> None:
        import pygltflib

        self.path = path
        try:
            size = path.stat().st_size
            if size > _MAX_FILE_BYTES:
                raise self.error(f"file of {size} bytes exceeds the {_MAX_FILE_BYTES}-byte limit")
            data = path.read_bytes()
        except OSError as error:
            raise self.error(f"cannot read the file: {error.strerror or error}") from None
        if not data.strip():
            raise self.error("the file is empty")
        try:
            if data[:4] == b"glTF":
                check_document(json.loads(_glb_json(data)), self.error)
                with warnings.catch_warnings():  # chunks of unknown type are ignored, as the specification says
                    warnings.simplefilter("ignore")
                    self.gltf = pygltflib.GLTF2.load_from_bytes(data)
                self.blob = self.gltf.binary_blob()
            else:
                if path.suffix.lower() == ".glb":
                    raise self.error(f"expected a binary glTF (magic b'glTF'), found {data[:4]!r}")
                text = data.decode("utf-8")
                check_document(json.loads(text), self.error)
                self.gltf = pygltflib.GLTF2.from_json(text)
                self.blob = None
        except MotionFormatError:
            raise
        except (ValueError, KeyError, TypeError, AttributeError, struct.error, OSError, UnicodeDecodeError) as error:
            # pygltflib raises whatever the JSON or dataclass layer raises on a malformed document.
            raise self.error(f"not a readable glTF 2.0 document ({type(error).__name__}: {error})") from None
        except RecursionError:
            raise self.error("not a readable glTF 2.0 document (its JSON is nested deeper than the parser allows)") \
                from None
        version = str(getattr(self.gltf.asset, "version", "") or "")
        if not version.startswith("2."):
            raise self.error(f"expected glTF version 2.x in asset.version, found {version!r}")
        self.buffers: dict[int, bytes] = {}
        self._check_references()

    def _check_references(self) -> None:
        """Refuse, before anything is read, a buffer or image URI that is not data: or a file inside the folder."""
        for kind in ("buffers", "images"):
            for index, item in enumerate(getattr(self.gltf, kind) or []):
                uri = getattr(item, "uri", None)
                if uri is None:
                    continue
                if not isinstance(uri, str):
                    raise self.error(f"{kind}[{index}]: expected a string uri, got {type(uri).__name__}")
                if not uri.startswith("data:"):
                    check_reference(self.path.parent, uri, f"{kind}[{index}]", self.error, must_exist=kind == "buffers")

    def error(self, message: str) -> MotionFormatError:
        return MotionFormatError(f"{self.path}: {message}.")

    def item(self, kind: str, index, what: str):
        items = getattr(self.gltf, kind) or []
        if not isinstance(index, int) or not 0 <= index < len(items):
            raise self.error(f"{what} refers to {kind}[{index}], but the file has {len(items)} {kind}")
        return items[index]

    def buffer(self, index: int) -> bytes:
        if index in self.buffers:
            return self.buffers[index]
        buffer = self.item("buffers", index, "a bufferView")
        uri = buffer.uri
        if uri is None:
            if self.blob is None:
                raise self.error(f"buffers[{index}] has no uri and the file has no binary chunk")
            data = self.blob
        elif not isinstance(buffer.byteLength, int) or not 0 < buffer.byteLength <= _MAX_FILE_BYTES:
            raise self.error(f"buffers[{index}] declares byteLength {buffer.byteLength}; expected 1..{_MAX_FILE_BYTES}")
        elif uri.startswith("data:"):
            data = read_data_uri(uri, buffer.byteLength, f"buffers[{index}]", self.error)
        else:
            data = read_reference(self.path.parent, uri, buffer.byteLength, f"buffers[{index}]", self.error)
        if buffer.byteLength is None or len(data) < buffer.byteLength:
            raise self.error(f"buffers[{index}] declares {buffer.byteLength} bytes, found {len(data)}")
        self.buffers[index] = data
        return data

    def accessor(self, index: int, what: str) -> np.ndarray:
        """Accessor ``index`` as a float64 array of shape (count, width), normalized integers scaled to [-1, 1]."""
        accessor = self.item("accessors", index, what)
        where = f"accessors[{index}] ({what})"
        if accessor.sparse is not None:
            raise self.error(f"{where} is sparse; mocapbench reads dense accessors only")
        if accessor.componentType not in _COMPONENTS or accessor.type not in _WIDTH:
            raise self.error(f"{where} has componentType {accessor.componentType} and type {accessor.type!r}")
        dtype, scale = _COMPONENTS[accessor.componentType]
        width, count = _WIDTH[accessor.type], accessor.count
        if not isinstance(count, int) or not 1 <= count <= _MAX_FRAMES * 4:
            raise self.error(f"{where} has count {count}; expected 1..{_MAX_FRAMES * 4}")
        check_array_bytes(count * width * 8, self.error, f"{where} as float64")
        if accessor.bufferView is None:
            raise self.error(f"{where} has no bufferView (an all-zero accessor); expected data")
        view = self.item("bufferViews", accessor.bufferView, where)
        data = self.buffer(view.buffer)
        item_size = np.dtype(dtype).itemsize * width
        stride = view.byteStride or item_size
        start = (view.byteOffset or 0) + (accessor.byteOffset or 0)
        needed = start + stride * (count - 1) + item_size
        view_end = (view.byteOffset or 0) + (view.byteLength or 0)
        if stride < item_size or needed > view_end or view_end > len(data):
            raise self.error(
                f"{where} needs bytes {start}..{needed} of bufferViews[{accessor.bufferView}], which ends at "
                f"{view_end} in a {len(data)}-byte buffer"
            )
        rows = np.ndarray((count, width), dtype=np.dtype(dtype).newbyteorder("<"), buffer=data, offset=start,
                          strides=(stride, np.dtype(dtype).itemsize))
        values = rows.astype(np.float64)
        if accessor.normalized and scale is not None:
            values = np.maximum(values / scale, -1.0)
        finite = np.isfinite(values).all(axis=1)
        if not finite.all():  # the item is the key of an animation output: the frame a reader reports
            item = int(np.argmin(finite))
            raise self.error(f"{where} holds a non-finite value at item {item}: {values[item].tolist()}")
        return values


def _glb_json(data: bytes) -> bytes:
    """The JSON chunk of a GLB file (glTF 2.0, 4.4: a 12-byte header, then a chunk of type ``JSON``)."""
    if len(data) < 20:
        raise ValueError(f"a GLB of {len(data)} bytes has no JSON chunk")
    version = struct.unpack_from("<I", data, 4)[0]
    if version != 2:
        raise ValueError(f"binary glTF version {version}; expected 2")
    length, kind = struct.unpack_from("<I4s", data, 12)
    if kind != b"JSON" or 20 + length > len(data):
        raise ValueError(f"expected a JSON chunk of {length} bytes at byte 12, found type {kind!r} in {len(data)} bytes")
    return data[20:20 + length]


def _trs_matrix(node) -> np.ndarray:
    """The 4x4 local matrix of a node (``matrix`` or T * R * S)."""
    if node.matrix is not None and len(node.matrix) == 16:
        return np.array(node.matrix, dtype=np.float64).reshape(4, 4).T  # column-major in the file
    matrix = np.eye(4)
    scale = np.array(node.scale if node.scale is not None else [1.0, 1.0, 1.0])
    rotation = node.rotation if node.rotation is not None else [0.0, 0.0, 0.0, 1.0]
    matrix[:3, :3] = Rotation.from_quat(rotation).as_matrix() * scale
    matrix[:3, 3] = node.translation if node.translation is not None else [0.0, 0.0, 0.0]
    return matrix


def _static_trs(reader: _Reader, index: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Translation (3,), quaternion (4,) xyzw and scale (3,) of node ``index`` (decomposing ``matrix``)."""
    node = reader.gltf.nodes[index]
    matrix = _trs_matrix(node)
    scale = np.linalg.norm(matrix[:3, :3], axis=0)
    if np.any(scale < 1e-12) or np.linalg.det(matrix[:3, :3]) < 0:
        raise reader.error(f"node {index} ({node.name!r}) has a degenerate or mirroring transform")
    quat = Rotation.from_matrix(matrix[:3, :3] / scale).as_quat()
    return matrix[:3, 3].copy(), quat, scale


def _frames_per_second(key_times: list[np.ndarray]) -> float:
    """The key rate of the animation, snapped to an integer rate within 0.1 %.

    From the evenly keyed track with the most keys: (K - 1) / its span, which float32 key times give to ~1e-7;
    with no evenly keyed track, 1 / the median key spacing. 30 when no track has two keys.
    """
    tracks = [t for t in key_times if len(t) > 1]
    if not tracks:
        return 30.0
    even = [t for t in tracks if np.ptp(np.diff(t)) <= 0.01 * np.median(np.diff(t))]  # float32 times jitter
    if even:
        longest = max(even, key=len)
        fps = (len(longest) - 1) / float(longest[-1] - longest[0])
    else:
        fps = 1.0 / float(np.median(np.concatenate([np.diff(t) for t in tracks])))
    return float(round(fps)) if abs(fps - round(fps)) < 1e-3 * fps else fps


@one_line_errors
def read_gltf(
    path: str | Path,
    *,
    length_unit_cm: float = 100.0,
    fps: float | None = None,
    skin: int = 0,
    animation: int = 0,
    name: str | None = None,
) -> Motion:
    """Read a skin's animation from a ``.gltf`` or ``.glb`` file (see the module docstring for the rules).

    Parameters
    ----------
    path : str or Path
    length_unit_cm : float, keyword-only
        cm per file unit, > 0. Default 100 (glTF lengths are metres).
    fps : float, optional, keyword-only
        Sampling rate in Hz; default the key rate (of the longest evenly keyed track, snapped to an integer rate).
    skin, animation : int, keyword-only
        Which skin and which animation. Default the first of each.
    name : str, optional, keyword-only
        ``Motion.name``; default the file name without suffix.

    Returns
    -------
    Motion
        F = ``floor((t_last - t_first) * fps + 0.01) + 1`` frames starting at the first key, J = the skin's joints
        (depth-first), lengths in cm, identity rest rotations, ``translations`` for joints that move, ``scales``
        where a joint scales, end sites from the joints' leaf child nodes, ``source_unit_cm`` =
        ``length_unit_cm``, ``up_axis`` = ``"y"``.

    Raises
    ------
    MotionFormatError
        One line naming the file and what is wrong (no skin, no animation, a scale <= 0, ...).
    """
    if not (math.isfinite(length_unit_cm) and length_unit_cm > 0):
        raise ValueError(f"`length_unit_cm` must be a finite number > 0, got {length_unit_cm}.")
    if fps is not None and not (math.isfinite(fps) and fps > 0):
        raise ValueError(f"`fps` must be a finite number > 0, got {fps}.")
    path = Path(path)
    reader = _Reader(path)
    tree = _joint_tree(reader, skin)
    tracks = _joint_tracks(reader, animation, tree)
    times = [t for t, _, _ in tracks.values()]
    start, stop = min(t[0] for t in times), max(t[-1] for t in times)
    rate = fps or _frames_per_second(times)
    # Key times are float32: a span a hair short of a whole number of frames still counts that frame.
    num_frames = int(math.floor((stop - start) * rate + 0.01)) + 1
    if num_frames > _MAX_FRAMES:
        raise reader.error(f"{num_frames} frames at {rate} fps exceed the limit of {_MAX_FRAMES}")
    check_motion_size(num_frames, len(tree.order), reader.error, f"at {rate:g} fps")
    translations, rotations, scales = _sampled_tracks(reader, tree, tracks, start + np.arange(num_frames) / rate)
    nodes = reader.gltf.nodes
    return motion_from_nodes(
        [nodes[node].name or f"node{node}" for node in tree.order], tree.parents, translations, rotations,
        np.array([quat for _, quat, _ in tree.statics]), tree.above, length_unit_cm=length_unit_cm, fps=rate,
        name=path.stem if name is None else name, up_axis="y", error=reader.error,
        rest_translations=np.array([translation for translation, _, _ in tree.statics]), scales=scales,
        end_site_parents=tree.end_site_parents, end_site_offsets=tree.end_site_offsets,
    )


@dataclass(frozen=True)
class _JointTree:
    """A skin's joints as a tree: depth-first node indices, parents, the static transforms, end sites."""

    order: list[int]  # node index of each joint, depth first
    parents: np.ndarray  # (J,) joint index of each joint's parent, -1 for the root
    ancestors: list[int]  # nodes above the root joint
    above: np.ndarray  # (4, 4) static transform of the nodes above the root joint
    statics: list[tuple[np.ndarray, np.ndarray, np.ndarray]]  # each joint's static translation, quaternion, scale
    end_site_parents: np.ndarray  # (E,) joint index
    end_site_offsets: np.ndarray  # (E, 3) file units, in the joint's node frame


def _skin_joints(reader: _Reader, skin: int) -> list[int]:
    """The node indices ``skins[skin].joints`` lists, checked distinct and in range."""
    nodes = reader.gltf.nodes or []
    if not reader.gltf.skins:
        raise reader.error("has no skin; mocapbench reads skinned animation (a skin lists the skeleton's joints)")
    joints = list(reader.item("skins", skin, "skin=").joints or [])
    if not joints or len(set(joints)) != len(joints) or any(not 0 <= j < len(nodes) for j in joints):
        raise reader.error(f"skins[{skin}].joints must list distinct node indices below {len(nodes)}, got {joints}")
    return joints


def _parent_map(reader: _Reader) -> dict[int, int]:
    """Each node's parent node; a child that is missing or listed by two nodes is an error."""
    nodes = reader.gltf.nodes or []
    parent_of: dict[int, int] = {}
    for index, node in enumerate(nodes):
        for child in node.children or []:
            if not isinstance(child, int) or not 0 <= child < len(nodes) or child in parent_of:
                raise reader.error(f"node {index} ({node.name!r}) lists child {child}, which is missing or shared")
            parent_of[child] = index
    return parent_of


def _depth_first_joints(reader: _Reader, skin: int, joints: list[int], parent_of: dict[int, int]) -> list[int]:
    """The skin's joints depth first from its one root joint, following each node's children list."""
    nodes = reader.gltf.nodes or []
    joint_set = set(joints)
    roots = [j for j in joints if parent_of.get(j) not in joint_set]
    if len(roots) != 1:
        names = [nodes[j].name for j in roots]
        raise reader.error(f"skins[{skin}] has {len(roots)} root joints {names}; expected one joint tree")
    order, stack = [], [roots[0]]
    while stack:
        node = stack.pop()
        order.append(node)
        stack.extend(reversed([c for c in nodes[node].children or [] if c in joint_set]))
    missing = joint_set.difference(order)
    if missing:
        first = min(missing)
        raise reader.error(
            f"joint node {first} ({nodes[first].name!r}) hangs from node {parent_of.get(first)}, which is not a joint "
            f"of skins[{skin}]; expected joints directly under joints"
        )
    return order


def _above_root(nodes: list, root: int, parent_of: dict[int, int]) -> tuple[np.ndarray, list[int]]:
    """The static transform above the root joint (a similarity: rotation, uniform scale, translation), and its nodes."""
    above, ancestors = np.eye(4), []
    ancestor = parent_of.get(root)
    while ancestor is not None:
        ancestors.append(ancestor)
        above = _trs_matrix(nodes[ancestor]) @ above
        ancestor = parent_of.get(ancestor)
    return above, ancestors


def _end_sites(nodes: list, position: dict[int, int], parent_of: dict[int, int]) -> list[tuple[int, int]]:
    """``(joint index, node)`` of each end site, sorted: a childless node under a joint that is no joint and carries
    nothing (no mesh, skin or camera)."""
    ends = [(position[parent_of[n]], n) for n in range(len(nodes)) if parent_of.get(n) in position
            and n not in position and not nodes[n].children and nodes[n].mesh is None and nodes[n].skin is None
            and nodes[n].camera is None]
    ends.sort()
    return ends


def _joint_tree(reader: _Reader, skin: int) -> _JointTree:
    """The joint tree of ``skins[skin]``: one root joint, joints directly under joints, leaf children as end sites."""
    nodes = reader.gltf.nodes or []
    joints = _skin_joints(reader, skin)
    parent_of = _parent_map(reader)
    order = _depth_first_joints(reader, skin, joints, parent_of)
    position = {node: i for i, node in enumerate(order)}
    above, ancestors = _above_root(nodes, order[0], parent_of)
    ends = _end_sites(nodes, position, parent_of)
    return _JointTree(
        order=order,
        parents=np.array([-1] + [position[parent_of[node]] for node in order[1:]]),
        ancestors=ancestors,
        above=above,
        statics=[_static_trs(reader, node) for node in order],
        end_site_parents=np.array([joint for joint, _ in ends], dtype=np.int64),
        end_site_offsets=np.array([_static_trs(reader, node)[0] for _, node in ends]).reshape(-1, 3),
    )


def _joint_tracks(reader: _Reader, animation: int, tree: _JointTree) -> dict[tuple[int, str], tuple]:
    """``(node, "rotation" | "translation" | "scale") -> (key times, values, interpolation)`` of the animation."""
    gltf, nodes = reader.gltf, reader.gltf.nodes
    joint_set = set(tree.order)
    if not gltf.animations:
        raise reader.error("has no animation; nothing to read")
    anim = reader.item("animations", animation, "animation=")
    tracks: dict[tuple[int, str], tuple[np.ndarray, np.ndarray, str]] = {}
    for c, channel in enumerate(anim.channels or []):
        target = channel.target
        node, kind = getattr(target, "node", None), getattr(target, "path", None)
        if node in tree.ancestors:
            raise reader.error(
                f"animations[{animation}] animates node {node} ({nodes[node].name!r}) above the root joint"
            )
        if node not in joint_set or kind == "weights":
            continue
        samplers = anim.samplers or []
        if not isinstance(channel.sampler, int) or not 0 <= channel.sampler < len(samplers):
            raise reader.error(f"animations[{animation}].channels[{c}] refers to a missing sampler {channel.sampler}")
        sampler = samplers[channel.sampler]
        what = f"animations[{animation}].channels[{c}] ({nodes[node].name!r} {kind})"
        interpolation = sampler.interpolation or "LINEAR"
        if interpolation not in ("LINEAR", "STEP", "CUBICSPLINE"):
            raise reader.error(f"{what}: unknown interpolation {interpolation!r}")
        times = reader.accessor(sampler.input, what + " input")[:, 0]
        values = reader.accessor(sampler.output, what + " output")
        width = {"rotation": 4, "translation": 3, "scale": 3}.get(kind)
        per_key = 3 if interpolation == "CUBICSPLINE" else 1
        if width is None or values.shape != (len(times) * per_key, width):
            raise reader.error(f"{what}: expected {len(times) * per_key} values of width {width}, got {values.shape}")
        if np.any(np.diff(times) <= 0):
            raise reader.error(f"{what}: key times must increase strictly")
        if kind == "scale":
            keys = values.reshape(len(times), per_key, 3)[:, per_key // 2]
            if np.any(keys <= 0):
                key = int(np.flatnonzero(np.any(keys <= 0, axis=1))[0])
                raise reader.error(f"{what}: key {key} (at {times[key]:.6g} s) has scale {keys[key].tolist()}; "
                                   "a scale must be > 0")
        tracks[(node, kind)] = (times, values, interpolation)
    if not any(kind != "scale" for _, kind in tracks):
        raise reader.error(
            f"animations[{animation}] has no rotation or translation channel on the joints of the skin"
        )
    return tracks


def _sampled_tracks(reader: _Reader, tree: _JointTree, tracks: dict, at: np.ndarray):
    """Every joint's translation (F, J, 3), rotation (F, J, 4) and scale (F, J, 3, or None) at times ``at``.

    A joint without a channel keeps its static value; scales are ``None`` when no joint has a scale other than 1.
    """
    num_frames, num_joints = len(at), len(tree.order)
    rotations = np.empty((num_frames, num_joints, 4))
    translations = np.empty((num_frames, num_joints, 3))
    scales = np.empty((num_frames, num_joints, 3))
    for i, node in enumerate(tree.order):
        translation, quat, scale = tree.statics[i]
        track = tracks.get((node, "rotation"))
        rotations[:, i] = _sample(track[0], track[1], track[2], at, True) if track else quat
        track = tracks.get((node, "translation"))
        translations[:, i] = _sample(track[0], track[1], track[2], at, False) if track else translation
        track = tracks.get((node, "scale"))
        scales[:, i] = _sample(track[0], track[1], track[2], at, False) if track else scale
    if np.all(scales == 1.0):
        return translations, rotations, None
    bad = np.any(scales <= 0, axis=2)
    if bad.any():  # a cubic spline may overshoot below 0 between positive keys
        frame, joint = (int(i) for i in np.argwhere(bad)[0])
        name = reader.gltf.nodes[tree.order[joint]].name
        raise reader.error(f"joint node {tree.order[joint]} ({name!r}) has scale {scales[frame, joint].tolist()} at "
                           f"frame {frame}; a scale must be > 0")
    return translations, rotations, scales


def _pack(chunks: list[bytes], array: np.ndarray) -> tuple[int, int]:
    """Append a little-endian array to the blob (4-byte aligned); return (byte offset, byte length)."""
    offset = sum(len(c) for c in chunks)
    data = np.ascontiguousarray(array).astype(array.dtype.newbyteorder("<")).tobytes()
    chunks.append(data + b"\x00" * (-len(data) % 4))
    return offset, len(data)


def write_gltf(motion: Motion, path: str | Path, *, length_unit_cm: float = 100.0, force: bool = False) -> Path:
    """Write ``motion`` as a glTF 2.0 skinned animation (``.glb`` binary or ``.gltf`` with an embedded buffer).

    Parameters
    ----------
    motion : Motion
        Any skeleton; a Z-up motion is turned to Y-up.
    path : str or Path
        Ends in ``.glb`` or ``.gltf``.
    length_unit_cm : float, keyword-only
        cm per written unit; default 100 (metres, as glTF requires).
    force : bool, keyword-only
        Replace an existing file (through :mod:`mocapbench.io.safe_output`, atomically).

    Returns
    -------
    Path
    """
    import pygltflib as g

    from mocapbench.io.safe_output import check_output, write_bytes
    from mocapbench.io.units import turn_axes

    if not (math.isfinite(length_unit_cm) and length_unit_cm > 0):
        raise ValueError(f"`length_unit_cm` must be a finite number > 0, got {length_unit_cm}.")
    path = Path(path)
    binary = path.suffix.lower() == ".glb"
    if not binary and path.suffix.lower() != ".gltf":
        raise MotionFormatError(f"{path}: expected a .gltf or .glb output, got {path.suffix or 'no extension'}.")
    path = check_output(path, force=force)
    if motion.up_axis == "z":
        motion = turn_axes(motion, Rotation.from_euler("X", -90, degrees=True), "y")
    elif motion.up_axis == "x":
        motion = turn_axes(motion, Rotation.from_euler("Z", 90, degrees=True), "y")
    skeleton = motion.skeleton
    scale = 1.0 / length_unit_cm
    num_frames, num_joints = motion.num_frames, motion.num_joints
    # Hemisphere-continuous quaternions so that LINEAR (slerp) keys interpolate the short way.
    quats = motion.rotations.copy()
    flips = np.cumsum(np.sum(quats[1:] * quats[:-1], axis=2) < 0, axis=0) % 2 == 1
    quats[1:][flips] *= -1

    chunks: list[bytes] = []
    views, accessors = [], []

    def add(array: np.ndarray, kind: str, component: int, *, bounds: bool = False, target: int | None = None) -> int:
        offset, length = _pack(chunks, array)
        views.append(g.BufferView(buffer=0, byteOffset=offset, byteLength=length, target=target))
        flat = array.reshape(array.shape[0], -1)
        accessors.append(g.Accessor(
            bufferView=len(views) - 1, componentType=component, count=array.shape[0], type=kind,
            min=flat.min(axis=0).tolist() if bounds else None, max=flat.max(axis=0).tolist() if bounds else None,
        ))
        return len(accessors) - 1

    rest = skeleton.rest_positions() * scale
    end_parents = skeleton.end_site_parents
    nodes = []
    for j in range(num_joints):
        translation = (motion.root_positions[0] if j == 0 else skeleton.offsets[j]) * scale
        # No static rotation: the nodes' own pose is the rest pose (a T-pose for most rigs); the animation moves them.
        children = skeleton.children(j) + [num_joints + int(e) for e in np.flatnonzero(end_parents == j)]
        nodes.append(g.Node(name=skeleton.names[j], translation=translation.tolist(), children=children or None))
    # End sites (toe, finger and head tips a viewer draws): childless nodes under their joint, outside the skin.
    for e, (joint, offset) in enumerate(zip(end_parents, skeleton.end_site_offsets)):
        nodes.append(g.Node(name=f"{skeleton.names[joint]}_end{e}", translation=(offset * scale).tolist()))
    end_rest = rest[end_parents] + skeleton.end_site_offsets * scale
    inverse_bind = np.tile(np.eye(4, dtype=np.float32), (num_joints, 1, 1))
    inverse_bind[:, 3, :3] = -rest  # column-major: the translation sits in the last column's first 3 entries
    skin = g.Skin(joints=list(range(num_joints)), skeleton=0,
                  inverseBindMatrices=add(inverse_bind.reshape(num_joints, 16).astype(np.float32), "MAT4", 5126))
    meshes = []
    scene_nodes = [0]
    if num_joints > 1 or len(end_parents):
        # One line per bone (parent to joint) and per end site (joint to tip, both ends skinned to the joint).
        bones = np.arange(1, num_joints)
        ends = np.concatenate([np.stack([skeleton.parents[bones], bones], axis=1).reshape(-1),
                               np.repeat(end_parents, 2)])
        positions = np.concatenate([rest[np.stack([skeleton.parents[bones], bones], axis=1).reshape(-1)],
                                    np.stack([rest[end_parents], end_rest], axis=1).reshape(-1, 3)]).astype(np.float32)
        weights = np.zeros((len(ends), 4), np.float32)
        weights[:, 0] = 1.0
        joints_attr = np.zeros((len(ends), 4), np.uint16)
        joints_attr[:, 0] = ends
        attributes = g.Attributes(
            POSITION=add(positions, "VEC3", 5126, bounds=True, target=34962),
            JOINTS_0=add(joints_attr, "VEC4", 5123, target=34962),
            WEIGHTS_0=add(weights, "VEC4", 5126, target=34962),
        )
        meshes.append(g.Mesh(name="bones", primitives=[g.Primitive(attributes=attributes, mode=1)]))
        nodes.append(g.Node(name="bones", mesh=0, skin=0))
        scene_nodes.append(len(nodes) - 1)

    times = add((np.arange(num_frames) / motion.fps).astype(np.float32)[:, None], "SCALAR", 5126, bounds=True)
    samplers, channels = [], []
    for j in range(num_joints):
        samplers.append(g.AnimationSampler(input=times, output=add(quats[:, j].astype(np.float32), "VEC4", 5126),
                                           interpolation="LINEAR"))
        channels.append(g.AnimationChannel(sampler=len(samplers) - 1,
                                           target=g.AnimationChannelTarget(node=j, path="rotation")))
    # Translation samplers on the root and the joints that move, scale samplers on the joints that scale.
    local_translations = motion.local_translations()
    for kind, joints, track in (("translation", [0, *motion.moving_joints()], local_translations * scale),
                                ("scale", list(motion.scaled_joints()), motion.scales)):
        for j in joints:
            samplers.append(g.AnimationSampler(input=times, output=add(track[:, j].astype(np.float32), "VEC3", 5126),
                                               interpolation="LINEAR"))
            channels.append(g.AnimationChannel(sampler=len(samplers) - 1,
                                               target=g.AnimationChannelTarget(node=int(j), path=kind)))

    blob = b"".join(chunks)
    gltf = g.GLTF2(
        asset=g.Asset(version="2.0", generator="mocapbench"),
        scene=0,
        scenes=[g.Scene(nodes=scene_nodes)],
        nodes=nodes,
        meshes=meshes,
        skins=[skin],
        animations=[g.Animation(name=motion.name or "motion", samplers=samplers, channels=channels)],
        accessors=accessors,
        bufferViews=views,
        buffers=[g.Buffer(byteLength=len(blob))],
    )
    if binary:
        gltf.set_binary_blob(blob)
        data = b"".join(gltf.save_to_bytes())
    else:
        gltf.buffers[0].uri = "data:application/octet-stream;base64," + base64.b64encode(blob).decode("ascii")
        data = gltf.gltf_to_json(separators=(",", ":"), indent=None).encode("utf-8")
    return write_bytes(path, data, force=force)
