"""FBX skeletal animation in (read only), through the ``ufbx`` bindings (optional: ``pip install ufbx``).

:func:`read_fbx` takes the bone nodes (``LimbNode`` / skeleton attributes) of an FBX file (binary or ASCII, any
version ufbx reads) and one animation stack, in named steps:

1. the bone tree (one root bone, bones directly under bones), depth first;
2. the sampling times: the stack's span (the keys' span when it declares none) at the file's frame rate, snapped
   to the integer rate it is a rounding of (``120.0048`` -> 120, as the BVH and glTF readers do), and frames x
   bones checked against the decode limits before anything is evaluated;
3. the tracks: ufbx bakes every node's local transform (pre/post rotations, pivots and Euler orders are ufbx's
   job) in C at the sampling rate, whole tracks at once, and the baked keys are interpolated at the sampling
   times with numpy (:func:`mocapbench.io.keyframes.sample_keys`): no Python call per bone per frame;
4. the rest pose: the bind pose (``Pose`` of type ``BindPose``) when it holds every bone, else the bones' static
   ``Lcl`` transforms. Exporters such as Blender save the current frame in the static transforms, so the bind pose
   is the skeleton's rest; the rest rotations are what the result's identity rotations stand for, and the offset
   of a joint that moves is its rest translation;
5. :func:`mocapbench.io.node_motion.motion_from_nodes` makes the Motion (identity rest rotations, the transform
   above the root bone baked into the root, translation and scale tracks where bones move or scale).

Units: the file's ``UnitScaleFactor`` (cm per unit, ufbx's ``unit_meters``) unless ``length_unit_cm`` is given.
Up axis: the file's ``UpAxis`` (``"y"`` or ``"z"``); the data keep the file's axes.

Not read: meshes, skin weights, blend shapes, cameras, more than one stack at a time (``stack=`` chooses). A bone
that scales while it or its parent inherits scale in a non-standard way (FBX's "RSrs"/"Rrs" inheritance, Maya's
segment scale compensation) is refused: a Motion composes ``T R S`` down the tree. ufbx 0.0.5 is an early
release of the bindings: FBX is read where it installs, and ``read_fbx`` says in one line when it does not.
"""

from __future__ import annotations

import itertools
import math
import operator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mocapbench.io.keyframes import sample_keys
from mocapbench.io.node_motion import motion_from_nodes
from mocapbench.io.read_limits import check_array_bytes, check_motion_size
from mocapbench.io.reader_errors import one_line_errors
from mocapbench.motion import Motion, MotionFormatError

__all__ = ["read_fbx"]

_MAX_FRAMES = 10_000_000
_UP = {2: "y", 3: "y", 4: "z", 5: "z"}  # ufbx CoordinateAxis: POSITIVE_Y, NEGATIVE_Y, POSITIVE_Z, NEGATIVE_Z
#: A frame rate this close (relative) to an integer is that integer: files store 120 as 120.0048 and the like.
RATE_SNAP_TOLERANCE = 1e-4
# Bytes ufbx's bake holds per node and baked key (time, value, flags), for the check before baking.
_BAKED_KEY_BYTES = 3 * 48


def _matrix(m) -> np.ndarray:
    """ufbx's column-wise affine Matrix (c0, c1, c2 axes, c3 translation) as a 4x4 array."""
    out = np.eye(4)
    out[:3, :4] = np.array([list(m.c0), list(m.c1), list(m.c2), list(m.c3)]).T
    return out


@one_line_errors
def read_fbx(
    path: str | Path,
    *,
    length_unit_cm: float | None = None,
    fps: float | None = None,
    stack: int = 0,
    name: str | None = None,
) -> Motion:
    """Read the skeleton animation of an FBX file (see the module docstring for the steps).

    Parameters
    ----------
    path : str or Path
    length_unit_cm : float, optional, keyword-only
        cm per file unit; default the file's own (``UnitScaleFactor``).
    fps : float, optional, keyword-only
        Sampling rate; default the file's frame rate (snapped to an integer rate it rounds; 30 when it has none).
    stack : int, keyword-only
        Which animation stack (take). Default the first.
    name : str, optional, keyword-only
        ``Motion.name``; default the file name without suffix.

    Returns
    -------
    Motion
        F = ``floor((end - begin) * fps + 0.01) + 1`` frames over the stack's time span (the keys' span when the
        stack declares none), J bones in depth-first order, cm, ``translations``/``scales`` where bones move or
        scale, ``source_unit_cm`` and ``up_axis`` from the file.

    Raises
    ------
    MotionFormatError
        One line: ufbx missing, an unreadable file, no bones, no animation, several root bones, a size over the
        decode limits, a scale <= 0 or one a Motion cannot compose.
    """
    path = Path(path)

    def error(message: str) -> MotionFormatError:
        return MotionFormatError(f"{path}: {message}.")

    try:
        import ufbx
    except ImportError:
        raise error("reading FBX needs the optional package ufbx (pip install ufbx), which is not installed") from None
    if length_unit_cm is not None and not (math.isfinite(length_unit_cm) and length_unit_cm > 0):
        raise ValueError(f"`length_unit_cm` must be a finite number > 0, got {length_unit_cm}.")
    if fps is not None and not (math.isfinite(fps) and fps > 0):
        raise ValueError(f"`fps` must be a finite number > 0, got {fps}.")
    if not path.is_file():
        raise error("no such file" if not path.exists() else "expected an FBX file, got a folder")
    scene = _read_scene(ufbx, path, stack, fps, error)
    unit_cm = length_unit_cm or scene.unit_cm
    return motion_from_nodes(
        scene.names,
        scene.parents,
        scene.translations,
        scene.rotations,
        scene.rest_rotations,
        scene.above,
        length_unit_cm=unit_cm,
        fps=scene.rate,
        name=path.stem if name is None else name,
        up_axis=scene.up_axis,
        error=error,
        rest_translations=scene.rest_translations,
        scales=scene.scales,
    )


@dataclass(frozen=True)
class _SceneData:
    """What :func:`read_fbx` takes from the ufbx scene, as plain arrays (no ufbx object outlives the read)."""

    names: list[str]
    parents: np.ndarray  # (J,)
    above: np.ndarray  # (4, 4) file units
    translations: np.ndarray  # (F, J, 3) file units
    rotations: np.ndarray  # (F, J, 4)
    scales: np.ndarray | None  # (F, J, 3)
    rest_translations: np.ndarray  # (J, 3) file units
    rest_rotations: np.ndarray  # (J, 4)
    rate: float
    unit_cm: float
    up_axis: str


def _read_scene(ufbx, path: Path, stack: int, fps: float | None, error) -> _SceneData:
    """Load the file and run steps 1-4 (module docstring) into a :class:`_SceneData`."""
    try:
        scene = ufbx.load_file(str(path))
    except (ufbx.UfbxError, OSError, ValueError, RuntimeError) as failure:
        raise error(f"not a readable FBX file ({type(failure).__name__}: {failure})") from None
    # ufbx 0.0.5 invalidates the items of a list when the Python list they came from is freed (a segmentation fault
    # in a later call): every list the steps make is kept here until the read ends, as one function's locals would.
    keep: list = []
    bones = _bone_tree(scene, error, keep)
    anim_stack, times, rate = _sampling(scene, stack, fps, len(bones.order), error, keep)
    translations, rotations, scales = _baked_tracks(ufbx, scene, anim_stack, bones, times, rate, error, keep)
    rest_translations, rest_rotations = _rest_pose(ufbx, scene, bones, keep)
    return _SceneData(
        names=[node.name or f"bone{j}" for j, node in enumerate(bones.order)],
        parents=bones.parents,
        above=bones.above,
        translations=translations,
        rotations=rotations,
        scales=scales,
        rest_translations=rest_translations,
        rest_rotations=rest_rotations,
        rate=rate,
        unit_cm=scene.settings.unit_meters * 100.0,
        up_axis=_UP.get(int(scene.settings.axes.up), "y"),
    )


@dataclass(frozen=True)
class _Bones:
    """The bone nodes depth first, their parents, and the static global transform above the root bone."""

    order: list  # ufbx Nodes
    parents: np.ndarray  # (J,) int, -1 for the root
    above: np.ndarray  # (4, 4) file units
    num_nodes: int  # nodes in the scene (bones and others), which ufbx bakes


def _bone_tree(scene, error, keep: list) -> _Bones:
    """Step 1: one root bone, bones directly under bones, depth first following each node's children."""
    all_nodes = list(scene.nodes)
    keep.append(all_nodes)
    bones = [node for node in all_nodes if node.bone is not None]
    if not bones:
        raise error("has no skeleton (no LimbNode or bone nodes)")
    ids = {node.element_id for node in bones}
    roots = [node for node in bones if node.parent is None or node.parent.element_id not in ids]
    if len(roots) != 1:
        raise error(f"has {len(roots)} root bones {[node.name for node in roots][:5]}; expected one bone tree")
    order, stack_nodes = [], [roots[0]]
    while stack_nodes:
        node = stack_nodes.pop()
        order.append(node)
        children = list(node.children)
        keep.append(children)
        stack_nodes.extend(reversed([child for child in children if child.element_id in ids]))
    if len(order) != len(bones):
        missing = next(node for node in bones if node.element_id not in {n.element_id for n in order})
        raise error(f"bone {missing.name!r} hangs from a node that is not a bone; expected bones directly under bones")
    position = {node.element_id: i for i, node in enumerate(order)}
    parents = np.array([-1] + [position[node.parent.element_id] for node in order[1:]])
    root_parent = roots[0].parent
    above = _matrix(root_parent.node_to_world) if root_parent is not None else np.eye(4)
    return _Bones(order=order, parents=parents, above=above, num_nodes=len(all_nodes))


def _snapped_rate(rate: float) -> float:
    """``rate`` snapped to the nearest integer within :data:`RATE_SNAP_TOLERANCE` (relative)."""
    rounded = round(rate)
    return float(rounded) if rounded > 0 and abs(rate - rounded) <= RATE_SNAP_TOLERANCE * rate else float(rate)


def _sampling(scene, stack: int, fps: float | None, num_bones: int, error, keep: list):
    """Step 2: the animation stack, the sampling times (F,) s and the rate; F x J checked against the limits."""
    anim_stacks = list(scene.anim_stacks)
    keep.append(anim_stacks)
    if not anim_stacks:
        raise error("has no animation stack; nothing to read")
    if not 0 <= stack < len(anim_stacks):
        raise error(f"stack={stack}, but the file has {len(anim_stacks)} animation stacks")
    anim_stack = anim_stacks[stack]
    begin, end = anim_stack.time_begin, anim_stack.time_end
    if not end > begin:
        all_curves = list(scene.anim_curves)
        keep.append(all_curves)
        curves = [curve for curve in all_curves if len(curve.keyframes)]
        if curves:
            begin, end = min(curve.min_time for curve in curves), max(curve.max_time for curve in curves)
    file_rate = scene.settings.frames_per_second
    rate = fps or (_snapped_rate(file_rate) if file_rate > 0 and math.isfinite(file_rate) else 30.0)
    span = max(end - begin, 0.0)
    if not math.isfinite(span) or span * rate > _MAX_FRAMES:
        raise error(f"an animation of {span:.6g} s at {rate:g} fps exceeds the limit of {_MAX_FRAMES} frames")
    num_frames = int(math.floor(span * rate + 0.01)) + 1
    check_motion_size(num_frames, num_bones, error, f"at {rate:g} fps")
    return anim_stack, begin + np.arange(num_frames) / rate, rate


def _baked_tracks(ufbx, scene, anim_stack, bones: _Bones, times: np.ndarray, rate: float, error, keep: list):
    """Step 3: every bone's local translation (F, J, 3), rotation (F, J, 4) and scale (F, J, 3, or None).

    ufbx bakes the whole scene's transforms at ``rate`` in C (whole tracks at once, constant tracks as one key);
    the keys of the bones are then interpolated at ``times`` with numpy (exact where a key sits on a sample time).
    """
    num_nodes = bones.num_nodes
    check_array_bytes(len(times) * num_nodes * _BAKED_KEY_BYTES, error,
                      f"baking {num_nodes} nodes over {len(times):,} frames")
    try:
        anim = anim_stack.anim
        bake = ufbx.bake_anim(scene, anim, resample_rate=rate, minimum_sample_rate=rate, maximum_sample_rate=rate)
        keep.append(bake)
    except (ufbx.UfbxError, ValueError, RuntimeError) as failure:
        raise error(f"cannot evaluate the animation ({type(failure).__name__}: {failure})") from None
    num_frames, num_bones = len(times), len(bones.order)
    translations = np.empty((num_frames, num_bones, 3))
    rotations = np.empty((num_frames, num_bones, 4))
    scales = np.empty((num_frames, num_bones, 3))
    for j, node in enumerate(bones.order):
        baked = ufbx.find_baked_node(bake, node)
        local = node.local_transform
        for out, keys, rest, rotation in (
            (translations, None if baked is None else baked.translation_keys, local.translation, False),
            (rotations, None if baked is None else baked.rotation_keys, local.rotation, True),
            (scales, None if baked is None else baked.scale_keys, local.scale, False),
        ):
            out[:, j] = _sampled_keys(keys, rest, times, rotation)
    for what, track in (("translation", translations), ("rotation", rotations), ("scale", scales)):
        finite = np.isfinite(track).all(axis=2)
        if what == "rotation":
            finite &= np.einsum("fjq,fjq->fj", np.nan_to_num(track), np.nan_to_num(track)) > 1e-12
        if not finite.all():
            frame, joint = (int(i) for i in np.argwhere(~finite)[0])
            expected = "a rotation (finite, not zero)" if what == "rotation" else "finite numbers"
            raise error(f"bone {bones.order[joint].name!r} has the {what} {track[frame, joint].tolist()} at frame "
                        f"{frame}; expected {expected}")
    bad = ~(scales > 0).all(axis=2)
    if bad.any():
        frame, joint = (int(i) for i in np.argwhere(bad)[0])
        raise error(f"bone {bones.order[joint].name!r} has scale {scales[frame, joint].tolist()} at frame {frame}; "
                    "a scale must be > 0")
    if np.all(scales == 1.0):
        return translations, rotations, None
    _check_scale_inheritance(ufbx, bones, scales, error)
    return translations, rotations, scales


def _sampled_keys(keys, rest, times: np.ndarray, rotation: bool) -> np.ndarray:
    """One baked track (ufbx key list, or None: the static ``rest`` value) at ``times``, (F, 3) or (F, 4).

    A track baked at the sampling rate has one key per sample time: its values are the result (the key times are
    not read one by one, half the cost of a key); a constant track has a key or two, interpolated.
    """
    count = 0 if keys is None else len(keys)
    width = 4 if rotation else 3
    if not count:
        return np.broadcast_to(np.array(list(rest), dtype=np.float64), (len(times), width))
    # ufbx's Vec3 and Quat are tuples: one flat pass over the values, no per-key Python list or array.
    values = np.fromiter(itertools.chain.from_iterable(map(operator.attrgetter("value"), keys)), np.float64,
                         count * width).reshape(count, width)
    first, last = keys[0].time, keys[count - 1].time
    if count == len(times) and abs(first - times[0]) <= 1e-9 and abs(last - times[-1]) <= 1e-9:
        return values
    key_times = np.fromiter(map(operator.attrgetter("time"), keys), np.float64, count)
    return sample_keys(key_times, values, "LINEAR", times, rotation)


def _check_scale_inheritance(ufbx, bones: _Bones, scales: np.ndarray, error) -> None:
    """Refuse a scaling bone whose scale does not pass to its children as ``T R S`` composes it."""
    normal = ufbx.InheritMode.NORMAL
    scaled = np.any(scales != 1.0, axis=(0, 2))
    for j, node in enumerate(bones.order):
        parent_scaled = j > 0 and scaled[bones.parents[j]]
        if (scaled[j] or parent_scaled) and node.inherit_mode != normal:
            frame = int(np.flatnonzero(np.any(scales[:, bones.parents[j] if parent_scaled else j] != 1.0, axis=1))[0])
            raise error(f"bone {node.name!r} inherits scale as {node.inherit_mode.name} (frame {frame} scales); "
                        "a Motion composes T R S down the tree")


def _rest_pose(ufbx, scene, bones: _Bones, keep: list) -> tuple[np.ndarray, np.ndarray]:
    """Step 4: each bone's rest translation (J, 3) file units and rotation (J, 4): the bind pose when it holds
    every bone, else the static ``Lcl`` transforms."""
    poses = list(scene.poses)
    keep.append(poses)
    for pose in poses:
        if not pose.is_bind_pose:
            continue
        world = [ufbx.get_bone_pose(pose, node) for node in bones.order]
        if any(bone_pose is None for bone_pose in world):
            continue
        world = [_matrix(bone_pose.bone_to_world) for bone_pose in world]
        parents_world = [bones.above if p < 0 else world[p] for p in bones.parents]
        local = [np.linalg.solve(parent, matrix) for parent, matrix in zip(parents_world, world)]
        linear = np.array([m[:3, :3] for m in local])
        lengths = np.linalg.norm(linear, axis=1)  # column norms: the scale along each axis
        if np.any(lengths < 1e-12) or np.any(np.linalg.det(linear) <= 0):
            continue  # a degenerate or mirrored bind pose: keep the static transforms
        rotations = Rotation.from_matrix(linear / lengths[:, None, :]).as_quat()
        return np.array([m[:3, 3] for m in local]), rotations
    translations = np.array([list(node.local_transform.translation) for node in bones.order], dtype=np.float64)
    rotations = np.array([list(node.local_transform.rotation) for node in bones.order], dtype=np.float64)
    return translations, rotations
