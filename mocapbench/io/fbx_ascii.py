"""A minimal ASCII FBX 7.4 writer: FBX files of a motion for tests, fuzzing and the reader benchmarks.

mocapbench reads FBX through ufbx and has no product FBX writer (``write_motion`` writes BVH and glTF; Blender's
importer refuses ASCII FBX). This module writes what the FBX reader is checked on: a skeleton as ``LimbNode`` models
with ``Lcl Translation`` = the offsets and one animation stack with ``Lcl Rotation`` curves (Euler XYZ degrees, the
FBX default ``RotationOrder`` 0) on every joint, ``Lcl Translation`` curves on the root and on the joints that move,
``Lcl Scaling`` curves on the joints that scale, one linear key per frame. Optionally the static ``Lcl Rotation`` of
every bone is a frame of the motion (as Blender saves the current frame) and a ``BindPose`` holds the rest pose.
Units: ``UnitScaleFactor`` = cm per file unit; axes from ``up_axis``. End sites are not written.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mocapbench.io.safe_output import write_bytes
from mocapbench.motion import Motion

__all__ = ["write_fbx_ascii"]

_TICKS_PER_SECOND = 46_186_158_000


def _array(values) -> str:
    values = list(values)
    numbers = ",".join(f"{v:.9g}" if isinstance(v, float) else str(v) for v in values)
    return f"*{len(values)} {{\n\t\t\ta: {numbers}\n\t\t}}"


def write_fbx_ascii(
    motion: Motion,
    path: str | Path,
    *,
    unit_cm: float = 1.0,
    moving_joint: int | None = None,
    saved_frame: int | None = None,
    bind_pose: bool = False,
    declared_fps: float | None = None,
    overwrite: bool = False,
) -> Path:
    """Write ``motion`` (cm) as an ASCII FBX in ``unit_cm`` cm per unit; ``moving_joint`` also animates that
    joint's translation by up to 5 units along x; ``saved_frame`` makes that frame's rotations the bones' static
    ``Lcl Rotation``; ``bind_pose`` writes a ``BindPose`` of the rest pose (identity rotations, the offsets);
    ``declared_fps`` is the ``CustomFrameRate`` written (default the motion's). Written atomically through
    :mod:`mocapbench.io.safe_output`; an existing file is replaced only with ``overwrite``."""
    skeleton = motion.skeleton
    num_frames, num_joints = motion.num_frames, motion.num_joints
    up = {"y": (1, 2), "z": (2, -1)}[motion.up_axis]  # (UpAxis, FrontAxisSign-ish) as Maya/Max export
    times = [int(round(f * _TICKS_PER_SECOND / motion.fps)) for f in range(num_frames)]
    euler = Rotation.from_quat(motion.rotations.reshape(-1, 4)).as_euler("xyz", degrees=True)  # extrinsic XYZ
    euler = np.unwrap(np.radians(euler.reshape(num_frames, num_joints, 3)), axis=0)
    euler = np.degrees(euler)
    translations = motion.local_translations()
    moving = set(int(j) for j in motion.moving_joints())
    scaled = set(int(j) for j in motion.scaled_joints())
    objects, connections = [], []
    next_id = [1000]

    def new_id() -> int:
        next_id[0] += 1
        return next_id[0]

    def curve_node(owner: int, prop: str, name: str, values: np.ndarray) -> None:
        node = new_id()
        objects.append(
            f'\tAnimationCurveNode: {node}, "AnimCurveNode::{name}", "" {{\n\t\tProperties70:  {{\n'
            + "".join(f'\t\t\tP: "d|{a}", "Number", "", "A",{values[0, i]:.9g}\n' for i, a in enumerate("XYZ"))
            + "\t\t}\n\t}\n"
        )
        connections.append(f'\tC: "OO",{node},{layer}\n\tC: "OP",{node},{owner}, "{prop}"\n')
        for i, axis in enumerate("XYZ"):
            curve = new_id()
            objects.append(
                f'\tAnimationCurve: {curve}, "AnimCurve::", "" {{\n\t\tDefault: {values[0, i]:.9g}\n\t\tKeyVer: 4009\n'
                f"\t\tKeyTime: {_array(times)}\n\t\tKeyValueFloat: {_array(values[:, i].astype(float).tolist())}\n"
                f"\t\tKeyAttrFlags: *1 {{\n\t\t\ta: 8452\n\t\t}}\n"  # linear interpolation
                f"\t\tKeyAttrDataFloat: *4 {{\n\t\t\ta: 0,0,0,0\n\t\t}}\n"
                f"\t\tKeyAttrRefCount: *1 {{\n\t\t\ta: {num_frames}\n\t\t}}\n\t}}\n"
            )
            connections.append(f'\tC: "OP",{curve},{node}, "d|{axis}"\n')

    stack, layer = new_id(), new_id()
    stop = times[-1]
    objects.append(
        f'\tAnimationStack: {stack}, "AnimStack::Take 001", "" {{\n\t\tProperties70:  {{\n'
        f'\t\t\tP: "LocalStop", "KTime", "Time", "",{stop}\n\t\t\tP: "ReferenceStop", "KTime", "Time", "",{stop}\n'
        "\t\t}\n\t}\n"
    )
    objects.append(f'\tAnimationLayer: {layer}, "AnimLayer::BaseLayer", "" {{\n\t}}\n')
    connections.append(f'\tC: "OO",{layer},{stack}\n')
    model_ids = []
    for j in range(num_joints):
        model, attribute = new_id(), new_id()
        model_ids.append(model)
        offset = (motion.root_positions[0] if j == 0 else skeleton.offsets[j]) / unit_cm
        static = np.zeros(3) if saved_frame is None else euler[saved_frame, j]
        objects.append(
            f'\tNodeAttribute: {attribute}, "NodeAttribute::", "LimbNode" {{\n\t\tTypeFlags: "Skeleton"\n\t}}\n'
            f'\tModel: {model}, "Model::{skeleton.names[j]}", "LimbNode" {{\n\t\tVersion: 232\n\t\tProperties70:  {{\n'
            f'\t\t\tP: "Lcl Translation", "Lcl Translation", "", "A",{offset[0]:.9g},{offset[1]:.9g},{offset[2]:.9g}\n'
            f'\t\t\tP: "Lcl Rotation", "Lcl Rotation", "", "A",{static[0]:.9g},{static[1]:.9g},{static[2]:.9g}\n'
            "\t\t}\n\t}\n"
        )
        parent = 0 if j == 0 else model_ids[skeleton.parents[j]]
        connections.append(f'\tC: "OO",{attribute},{model}\n\tC: "OO",{model},{parent}\n')
        curve_node(model, "Lcl Rotation", "R", euler[:, j])
        if j == 0 or j in moving:
            curve_node(model, "Lcl Translation", "T", translations[:, j] / unit_cm)
        elif j == moving_joint:
            moving = skeleton.offsets[j] / unit_cm + np.linspace(0, 5.0, num_frames)[:, None] * np.array([1.0, 0, 0])
            curve_node(model, "Lcl Translation", "T", moving)
        if j in scaled:
            curve_node(model, "Lcl Scaling", "S", motion.scales[:, j])
    if bind_pose:
        rest = skeleton.rest_positions() + motion.root_positions[0]
        pose_nodes = "".join(
            f"\t\tPoseNode:  {{\n\t\t\tNode: {model_ids[j]}\n\t\t\tMatrix: *16 {{\n\t\t\t\ta: "
            + ",".join(f"{v:.9g}" for v in [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, *(rest[j] / unit_cm), 1])
            + "\n\t\t\t}\n\t\t}\n"
            for j in range(num_joints)
        )
        objects.append(f'\tPose: {new_id()}, "Pose::BIND_POSES", "BindPose" {{\n\t\tType: "BindPose"\n'
                       f"\t\tVersion: 100\n\t\tNbPoseNodes: {num_joints}\n{pose_nodes}\t}}\n")
    header = (
        "; FBX 7.4.0 project file\n"
        "FBXHeaderExtension:  {\n\tFBXHeaderVersion: 1003\n\tFBXVersion: 7400\n\tCreator: \"mocapbench tests\"\n}\n"
        "GlobalSettings:  {\n\tVersion: 1000\n\tProperties70:  {\n"
        f'\t\tP: "UpAxis", "int", "Integer", "",{up[0]}\n\t\tP: "UpAxisSign", "int", "Integer", "",1\n'
        f'\t\tP: "FrontAxis", "int", "Integer", "",{2 if motion.up_axis == "y" else 1}\n'
        f'\t\tP: "FrontAxisSign", "int", "Integer", "",{1 if motion.up_axis == "y" else -1}\n'
        '\t\tP: "CoordAxis", "int", "Integer", "",0\n\t\tP: "CoordAxisSign", "int", "Integer", "",1\n'
        f'\t\tP: "UnitScaleFactor", "double", "Number", "",{unit_cm:.9g}\n'
        f'\t\tP: "OriginalUnitScaleFactor", "double", "Number", "",{unit_cm:.9g}\n'
        '\t\tP: "TimeMode", "enum", "", "",14\n'
        f'\t\tP: "CustomFrameRate", "double", "Number", "",{declared_fps or motion.fps:.9g}\n'
        "\t}\n}\n"
    )
    text = header + "Objects:  {\n" + "".join(objects) + "}\nConnections:  {\n" + "".join(connections) + "}\n"
    return write_bytes(path, text.encode("utf-8"), force=overwrite)
