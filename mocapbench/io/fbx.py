"""FBX skeletal animation in (read only), through the ``ufbx`` bindings (optional: ``pip install ufbx``).

:func:`read_fbx` takes the bone nodes (``LimbNode`` / skeleton attributes) of an FBX file (binary or ASCII, any
version ufbx reads), one animation stack, and evaluates every bone's local transform with ufbx (pre/post rotations,
pivots and Euler orders are ufbx's job) at a fixed rate; the node tree becomes a Motion by
:func:`mocapbench.io.node_motion.motion_from_nodes` (identity rest rotations; the transform above the root bone
baked into the root; a non-root bone whose translation moves is refused in one line).

Units: the file's ``UnitScaleFactor`` (cm per unit, ufbx's ``unit_meters``) unless ``length_unit_cm`` is given.
Up axis: the file's ``UpAxis`` (``"y"`` or ``"z"``); the data keep the file's axes.

Not read: meshes, skin weights, blend shapes, cameras, more than one stack at a time (``stack=`` chooses), bones
with a non-unit scale (refused). ufbx 0.0.5 is an early release of the bindings: FBX is read where it installs,
and ``read_fbx`` says in one line when it does not.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from mocapbench.io.node_motion import motion_from_nodes
from mocapbench.motion import Motion, MotionFormatError

__all__ = ["read_fbx"]

_MAX_FRAMES = 10_000_000
_UP = {2: "y", 3: "y", 4: "z", 5: "z"}  # ufbx CoordinateAxis: POSITIVE_Y, NEGATIVE_Y, POSITIVE_Z, NEGATIVE_Z


def _matrix(m) -> np.ndarray:
    """ufbx's column-wise affine Matrix (c0, c1, c2 axes, c3 translation) as a 4x4 array."""
    out = np.eye(4)
    out[:3, :4] = np.array([list(m.c0), list(m.c1), list(m.c2), list(m.c3)]).T
    return out


def read_fbx(
    path: str | Path,
    *,
    length_unit_cm: float | None = None,
    fps: float | None = None,
    stack: int = 0,
    name: str | None = None,
) -> Motion:
    """Read the skeleton animation of an FBX file.

    Parameters
    ----------
    path : str or Path
    length_unit_cm : float, optional, keyword-only
        cm per file unit; default the file's own (``UnitScaleFactor``).
    fps : float, optional, keyword-only
        Sampling rate; default the file's frame rate (30 when it has none).
    stack : int, keyword-only
        Which animation stack (take). Default the first.
    name : str, optional, keyword-only
        ``Motion.name``; default the file name without suffix.

    Returns
    -------
    Motion
        F = ``floor((end - begin) * fps + 0.01) + 1`` frames over the stack's time span (the keys' span when the
        stack declares none), J bones in depth-first order, cm, ``source_unit_cm`` and ``up_axis`` from the file.

    Raises
    ------
    MotionFormatError
        One line: ufbx missing, an unreadable file, no bones, no animation, several root bones, a moving bone.
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
    try:
        scene = ufbx.load_file(str(path))
    except (ufbx.UfbxError, OSError, ValueError, RuntimeError) as failure:
        raise error(f"not a readable FBX file ({type(failure).__name__}: {failure})") from None

    # Hold every ufbx list in a variable while iterating it: ufbx 0.0.5 frees a temporary list's items under the
    # iterator (a segmentation fault or wrong parents otherwise).
    all_nodes = list(scene.nodes)
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
        stack_nodes.extend(reversed([child for child in children if child.element_id in ids]))
    if len(order) != len(bones):
        missing = next(node for node in bones if node.element_id not in {n.element_id for n in order})
        raise error(f"bone {missing.name!r} hangs from a node that is not a bone; expected bones directly under bones")
    position = {node.element_id: i for i, node in enumerate(order)}
    parents = np.array([-1] + [position[node.parent.element_id] for node in order[1:]])

    anim_stacks = list(scene.anim_stacks)
    if not anim_stacks:
        raise error("has no animation stack; nothing to read")
    if not 0 <= stack < len(anim_stacks):
        raise error(f"stack={stack}, but the file has {len(anim_stacks)} animation stacks")
    anim_stack = anim_stacks[stack]
    begin, end = anim_stack.time_begin, anim_stack.time_end
    if not end > begin:
        all_curves = list(scene.anim_curves)
        curves = [curve for curve in all_curves if len(curve.keyframes)]
        if curves:
            begin, end = min(curve.min_time for curve in curves), max(curve.max_time for curve in curves)
    rate = fps or (scene.settings.frames_per_second if scene.settings.frames_per_second > 0 else 30.0)
    num_frames = int(math.floor(max(end - begin, 0.0) * rate + 0.01)) + 1
    if num_frames > _MAX_FRAMES:
        raise error(f"{num_frames} frames at {rate} fps exceed the limit of {_MAX_FRAMES}")
    times = begin + np.arange(num_frames) / rate

    anim = anim_stack.anim
    translations = np.empty((num_frames, len(order), 3))
    rotations = np.empty((num_frames, len(order), 4))
    for j, node in enumerate(order):
        for f, time in enumerate(times.tolist()):
            transform = ufbx.evaluate_transform(anim, node, time)
            translations[f, j] = transform.translation
            rotations[f, j] = transform.rotation
            if f == 0 and max(abs(s - 1.0) for s in transform.scale) > 1e-4:
                raise error(f"bone {node.name!r} has scale {list(transform.scale)}; expected 1")
    rest_rotations = np.array([list(node.local_transform.rotation) for node in order])
    root_parent = roots[0].parent
    above = _matrix(root_parent.node_to_world) if root_parent is not None else np.eye(4)
    unit_cm = length_unit_cm or scene.settings.unit_meters * 100.0
    return motion_from_nodes(
        [node.name or f"bone{j}" for j, node in enumerate(order)],
        parents,
        translations,
        rotations,
        rest_rotations,
        above,
        length_unit_cm=unit_cm,
        fps=float(rate),
        name=path.stem if name is None else name,
        up_axis=_UP.get(int(scene.settings.axes.up), "y"),
        error=error,
    )
