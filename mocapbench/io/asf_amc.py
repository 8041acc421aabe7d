"""Acclaim ASF (skeleton) and AMC (motion) files, as in the CMU Graphics Lab Motion Capture Database.

An ASF bone is a segment: it starts where its parent bone ends, points along ``direction`` (world
coordinates of the rest pose) for ``length``, and rotates about its start. mocapbench joints are points
(the BVH view), so :func:`read_asf` makes

* joint 0 ``"root"`` and one joint per bone, named as the bone, placed at the **start** of the bone;
  ``offsets[b] = direction[p] * length[p]`` of its parent bone ``p`` (zero for the root's children);
* one end site at the end of every leaf bone (``direction * length`` of the leaf);
* the local rotation of joint ``b``: ``L_b = C_b @ M_b @ C_b^-1`` with ``C_b`` the ASF ``axis`` rotation
  (``axis a b c XYZ`` -> ``Rotation.from_euler("xyz", [a, b, c])``, extrinsic: ``Rz(c) Ry(b) Rx(a)``) and
  ``M_b`` the AMC angles composed in the ``dof`` order (``dof rx ry rz`` -> ``from_euler("xyz", ...)``,
  X applied first); bones without DOF (CMU's ``lhipjoint``/``rhipjoint``) get the identity. The root
  likewise with its ``axis``/``orientation`` and the rotational part of its ``order``; its position is
  the AMC ``TX TY TZ`` (axes without a translation DOF keep the ASF ``position``).

This is exactly the joint layout, rotation and rest pose of the CMU BVH release (see the data README),
except that the BVH release zeroes the thorax and wrist vectors; joint order is a depth-first walk of
``:hierarchy`` (CMU: the BVH joint order).

Lengths: the CMU convention is that one ASF unit is ``1 / length`` inch, where ``length`` is the
``:units length`` value (0.45 in every CMU file), i.e. :data:`CMU_CM_PER_UNIT` = 5.644 cm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mocapbench.lazy_imports import Rotation

from mocapbench.io.text import read_text
from mocapbench.motion import Motion, MotionFormatError, Skeleton

__all__ = ["CMU_LENGTH_SCALE", "CMU_CM_PER_UNIT", "AsfSkeleton", "read_asf", "read_amc"]

CMU_LENGTH_SCALE = 0.45
"""``:units length`` of every CMU ASF file."""

CMU_CM_PER_UNIT = 2.54 / CMU_LENGTH_SCALE
"""Centimetres per CMU ASF length unit, 5.6444. Source: CMU Graphics Lab Motion Capture Database FAQ
(http://mocap.cs.cmu.edu/faqs.php): "The bone length and the root position data ... should be multiplied
by this scale to convert to meters: (1.0/0.45)*2.54/100.0 = 0.056444 ... 0.45 is the scale from ASF file ...
2.54/100 to convert from inches to meters because the data is in inches"."""

_ROTATION_DOFS = ("rx", "ry", "rz")
_TRANSLATION_DOFS = ("tx", "ty", "tz")


@dataclass(frozen=True, eq=False)
class AsfSkeleton:
    """A parsed ASF file: the BVH-style :class:`Skeleton` plus what reading an AMC needs.

    Parameters
    ----------
    skeleton : Skeleton
        Joint 0 ``"root"`` and one joint per bone (depth-first order of ``:hierarchy``), offsets in cm,
        one end site per leaf bone, ``channel_orders`` all ``"ZYX"`` (as the CMU BVH files).
    dofs : tuple of tuple of str, length J
        AMC value order of each joint, lower case: the root's ``order`` (e.g. ``("tx", "ty", "tz", "rx",
        "ry", "rz")``), each bone's ``dof`` (``()`` for a bone without DOF).
    axis_rotations : ndarray, shape (J, 4), float
        ``C`` of each joint (ASF ``axis``; the root's ``orientation``) as scalar-last quaternions.
    cm_per_unit : float
        Centimetres per ASF length unit.
    angles_in_degrees : bool
        ``:units angle`` is ``deg`` (True) or ``rad`` (False).
    path : Path or None
        The ASF file read.
    """

    skeleton: Skeleton
    dofs: tuple[tuple[str, ...], ...]
    axis_rotations: np.ndarray
    cm_per_unit: float
    angles_in_degrees: bool = True
    path: Path | None = None

    @property
    def names(self) -> tuple[str, ...]:
        """Joint (bone) names, ``"root"`` first."""
        return self.skeleton.names

    def num_values(self, bone: str) -> int:
        """Number of AMC values on the line of ``bone`` (its DOF count; 6 for a CMU root)."""
        return len(self.dofs[self.skeleton.index(bone)])


@dataclass
class _Bone:
    name: str | None = None
    direction: tuple[float, ...] | None = None
    length: float | None = None
    axis: tuple[float, ...] | None = None
    axis_order: str | None = None
    dofs: tuple[str, ...] = ()
    line: int = 0


class _AsfParser:
    """Line-based ASF parser; keeps line numbers for messages."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.length_scale = 1.0
        self.angles_in_degrees = True
        self.root_order: tuple[str, ...] = ("tx", "ty", "tz", "rx", "ry", "rz")
        self.root_axis = "XYZ"
        self.root_position = (0.0, 0.0, 0.0)
        self.root_orientation = (0.0, 0.0, 0.0)
        self.bones: dict[str, _Bone] = {}
        self.children: dict[str, list[str]] = {}
        self.parent_line: dict[str, int] = {}
        self.sections: set[str] = set()

    def error(self, line: int, message: str) -> MotionFormatError:
        return MotionFormatError(f"{self.path}: line {line}: {message}")

    def numbers(self, words: list[str], count: int, what: str, line: int) -> tuple[float, ...]:
        if len(words) != count:
            raise self.error(line, f"expected {count} numbers for {what}, got {len(words)}: {words}.")
        try:
            values = tuple(float(word) for word in words)
        except ValueError:
            raise self.error(line, f"expected {count} numbers for {what}, got {words}.") from None
        if not all(math.isfinite(v) for v in values):
            raise self.error(line, f"expected {count} finite numbers for {what}, got {words}.")
        return values

    def axis_order(self, word: str, line: int) -> str:
        order = word.upper()
        if sorted(order) != ["X", "Y", "Z"]:
            raise self.error(line, f"expected an axis order such as XYZ (a permutation of X, Y, Z), got {word!r}.")
        return order

    def parse(self, text: str) -> None:
        section = None
        bone: _Bone | None = None
        in_hierarchy = False
        for number, raw in enumerate(text.splitlines(), 1):
            content = raw.split("#", 1)[0].strip()
            if not content:
                continue
            words = content.split()
            if words[0].startswith(":"):
                if bone is not None:
                    raise self.error(
                        number, f"expected 'end' closing the bone opened at line {bone.line}, got {words[0]!r}."
                    )
                section = words[0].lower()
                self.sections.add(section)
                continue
            key = words[0].lower()
            if section == ":units":
                self.unit(key, words[1:], number)
            elif section == ":root":
                self.root(key, words[1:], number)
            elif section == ":bonedata":
                if key == "begin":
                    if bone is not None:
                        raise self.error(
                            number, f"expected 'end' closing the bone opened at line {bone.line}, got 'begin'."
                        )
                    bone = _Bone(line=number)
                elif bone is None:
                    if not content.startswith("("):
                        raise self.error(number, f"expected 'begin' to open a bone in :bonedata, got {words[0]!r}.")
                elif key == "end":
                    self.finish_bone(bone, number)
                    bone = None
                else:
                    self.bone_field(bone, key, words[1:], number, content)
            elif section == ":hierarchy":
                if key == "begin":
                    in_hierarchy = True
                elif key == "end":
                    in_hierarchy = False
                elif not in_hierarchy:
                    raise self.error(number, f"expected 'begin' to open :hierarchy, got {words[0]!r}.")
                else:
                    self.hierarchy_line(words, number)
            # :version, :name, :documentation and unknown sections carry nothing mocapbench uses.
        if bone is not None:
            raise self.error(bone.line, "this bone has no 'end' before the end of the file.")
        for needed in (":bonedata", ":hierarchy"):
            if needed not in self.sections:
                raise MotionFormatError(
                    f"{self.path}: no {needed} section; an ASF file needs :bonedata and :hierarchy."
                )

    def unit(self, key: str, values: list[str], line: int) -> None:
        if key == "length":
            (scale,) = self.numbers(values, 1, "':units length'", line)
            if scale <= 0:
                raise self.error(line, f"expected ':units length' > 0, got {scale}.")
            self.length_scale = scale
        elif key == "angle":
            if len(values) != 1 or values[0].lower() not in ("deg", "rad"):
                raise self.error(line, f"expected ':units angle deg' or 'rad', got {values}.")
            self.angles_in_degrees = values[0].lower() == "deg"
        # mass and any other unit are not needed for kinematics.

    def root(self, key: str, values: list[str], line: int) -> None:
        if key == "order":
            order = tuple(v.lower() for v in values)
            allowed = _TRANSLATION_DOFS + _ROTATION_DOFS
            if any(v not in allowed for v in order) or len(set(order)) != len(order):
                raise self.error(line, f"expected root order tokens among TX TY TZ RX RY RZ, each once, got {values}.")
            self.root_order = order
        elif key == "axis":
            if len(values) != 1:
                raise self.error(line, f"expected one axis order after root 'axis', got {values}.")
            self.root_axis = self.axis_order(values[0], line)
        elif key == "position":
            self.root_position = self.numbers(values, 3, "the root position", line)
        elif key == "orientation":
            self.root_orientation = self.numbers(values, 3, "the root orientation", line)
        else:
            raise self.error(line, f"unknown :root field {key!r}; expected order, axis, position or orientation.")

    def bone_field(self, bone: _Bone, key: str, values: list[str], line: int, content: str) -> None:
        if key == "name":
            if len(values) != 1:
                raise self.error(line, f"expected one bone name, got {values}.")
            bone.name = values[0]
        elif key == "direction":
            bone.direction = self.numbers(values, 3, "the bone direction", line)
        elif key == "length":
            (bone.length,) = self.numbers(values, 1, "the bone length", line)
        elif key == "axis":
            if len(values) != 4:
                raise self.error(line, f"expected 'axis <x> <y> <z> <order>', got {values}.")
            bone.axis = self.numbers(values[:3], 3, "the bone axis", line)
            bone.axis_order = self.axis_order(values[3], line)
        elif key == "dof":
            dofs = tuple(v.lower() for v in values)
            for dof in dofs:
                if dof in _TRANSLATION_DOFS or dof == "l":
                    raise self.error(
                        line, f"bone dof {dof!r} (translation or length) is not supported; expected rx, ry, rz only."
                    )
                if dof not in _ROTATION_DOFS:
                    raise self.error(line, f"unknown dof {dof!r}; expected rx, ry, rz.")
            if len(set(dofs)) != len(dofs):
                raise self.error(line, f"a dof is repeated: {values}.")
            bone.dofs = dofs
        elif key in ("id", "limits", "bodymass", "cofmass") or content.startswith("("):
            pass  # not needed for kinematics (limits continue on lines starting with '(')
        else:
            raise self.error(
                line, f"unknown bone field {key!r}; expected id, name, direction, length, axis, dof, limits."
            )

    def finish_bone(self, bone: _Bone, line: int) -> None:
        for field_name in ("name", "direction", "length", "axis"):
            if getattr(bone, field_name) is None:
                raise self.error(
                    bone.line, f"the bone opened here has no {field_name!r} before its 'end' (line {line})."
                )
        if bone.name == "root" or bone.name in self.bones:
            raise self.error(bone.line, f"bone name {bone.name!r} is used twice (or is 'root').")
        self.bones[bone.name] = bone

    def hierarchy_line(self, words: list[str], line: int) -> None:
        parent, children = words[0], words[1:]
        for name in words:
            if name != "root" and name not in self.bones:
                raise self.error(line, f"unknown bone {name!r} in :hierarchy; it is not defined in :bonedata.")
        for child in children:
            if child == "root" or child in self.parent_line:
                raise self.error(line, f"bone {child!r} is given a second parent (or is the root).")
            self.parent_line[child] = line
        self.children.setdefault(parent, []).extend(children)

    def build(self, cm_per_unit: float | None) -> AsfSkeleton:
        cm = 2.54 / self.length_scale if cm_per_unit is None else cm_per_unit
        order = ["root"]
        stack = list(reversed(self.children.get("root", [])))
        while stack:
            name = stack.pop()
            order.append(name)
            stack.extend(reversed(self.children.get(name, [])))
        missing = [name for name in self.bones if name not in order]
        if missing:
            raise MotionFormatError(f"{self.path}: bones {missing} are not connected to the root in :hierarchy.")
        parent_of = {child: parent for parent, kids in self.children.items() for child in kids}
        parents = [-1] + [order.index(parent_of[name]) for name in order[1:]]
        offsets = np.zeros((len(order), 3))
        offsets[0] = self.root_position
        for joint, name in enumerate(order[1:], 1):
            parent_bone = self.bones.get(parent_of[name])
            if parent_bone is not None:
                offsets[joint] = np.multiply(parent_bone.direction, parent_bone.length)
        leaves = [joint for joint, name in enumerate(order) if joint > 0 and not self.children.get(name)]
        end_offsets = np.array(
            [np.multiply(self.bones[order[j]].direction, self.bones[order[j]].length) for j in leaves]
        ).reshape(-1, 3)
        degrees = self.angles_in_degrees
        axes = [Rotation.from_euler(self.root_axis.lower(), self.root_orientation, degrees=degrees)]
        axes += [
            Rotation.from_euler(self.bones[n].axis_order.lower(), self.bones[n].axis, degrees=degrees)
            for n in order[1:]
        ]
        skeleton = Skeleton(
            names=tuple(order),
            parents=np.array(parents),
            offsets=offsets * cm,
            channel_orders=("ZYX",) * len(order),
            end_site_parents=np.array(leaves, dtype=np.int64),
            end_site_offsets=end_offsets * cm,
        )
        return AsfSkeleton(
            skeleton=skeleton,
            dofs=(self.root_order,) + tuple(self.bones[name].dofs for name in order[1:]),
            axis_rotations=np.array([axis.as_quat() for axis in axes]),
            cm_per_unit=cm,
            angles_in_degrees=degrees,
            path=self.path,
        )


def find_asf(amc_path: str | Path) -> Path:
    """The skeleton of an AMC file: the only ``.asf`` in its folder, else ``SS.asf`` for ``SS_TT.amc``.

    Raises
    ------
    MotionFormatError
        If neither exists (the message lists the ``.asf`` files found).
    """
    amc_path = Path(amc_path)
    folder = amc_path.parent
    candidates = sorted(p for p in folder.iterdir() if p.suffix.lower() == ".asf") if folder.is_dir() else []
    if len(candidates) == 1:
        return candidates[0]
    by_subject = folder / f"{amc_path.stem.split('_', 1)[0]}.asf"
    if by_subject.is_file():
        return by_subject
    raise MotionFormatError(
        f"{amc_path}: no skeleton: expected one .asf in {folder} or {by_subject.name}, "
        f"found {[p.name for p in candidates]}."
    )


def read_asf(path: str | Path, *, cm_per_unit: float | None = None) -> AsfSkeleton:
    """Read an Acclaim ASF skeleton.

    Parameters
    ----------
    path : str or Path
    cm_per_unit : float, optional, keyword-only
        Centimetres per ASF length unit; default the CMU convention ``2.54 / <:units length>`` (5.6444 for
        CMU files, :data:`CMU_CM_PER_UNIT`).

    Returns
    -------
    AsfSkeleton
        With ``.skeleton``: J = bones + 1 joints (31 for CMU), offsets in cm, an end site per leaf bone.

    Raises
    ------
    MotionFormatError
        Missing, empty or malformed file (message names the file, the line and the expectation);
        translation or length DOF on a bone; bones not connected to the root.
    """
    if cm_per_unit is not None and not (math.isfinite(cm_per_unit) and cm_per_unit > 0):
        raise ValueError(f"`cm_per_unit` must be a finite number > 0, got {cm_per_unit}.")
    path = Path(path)
    parser = _AsfParser(path)
    parser.parse(read_text(path, "ASF file"))
    return parser.build(cm_per_unit)


def _is_integer(word: str) -> bool:
    return word.isdigit() or (word[:1] in "+-" and word[1:].isdigit())


def _amc_header(path: Path, text: str) -> tuple[bool | None, int, int]:
    """Skip the AMC header (comments, ``:`` keywords).

    Returns
    -------
    (degrees, body_start, body_line) : True/False for ``:DEGREES``/``:RADIANS`` (None if absent), the index in
    ``text`` of the first frame-number line and its line number.
    """
    degrees = None
    start, number = 0, 1
    while start < len(text):
        stop = text.find("\n", start)
        stop = len(text) if stop < 0 else stop
        content = text[start:stop].split("#", 1)[0].strip()
        if content:
            keyword = content.split()[0].upper()
            if keyword in (":DEGREES", ":RADIANS"):
                degrees = keyword == ":DEGREES"
            elif not content.startswith(":"):
                if not _is_integer(content):
                    raise MotionFormatError(
                        f"{path}: line {number}: expected a frame number (e.g. '1'), got {content!r}."
                    )
                return degrees, start, number
        start, number = stop + 1, number + 1
    raise MotionFormatError(f"{path}: no frames: expected a frame number line (e.g. '1') after the header.")


def _fixed_layout(tokens: list[str], num_values: dict[str, int], required: set[str]):
    """Fast path for the CMU layout: every frame lists the same bones in the same order, one token stream.

    Returns ``(frame_numbers, {bone: values (F, n)})`` or None when the stream does not fit (the general
    path then parses it, or reports the exact line at fault).
    """
    layout, seen, index = [], set(), 1
    while index < len(tokens) and tokens[index] in num_values and tokens[index] not in seen:
        seen.add(tokens[index])
        layout.append((tokens[index], index))
        index += 1 + num_values[tokens[index]]
    stride = index
    if not required <= seen or len(tokens) % stride:
        return None
    num_frames = len(tokens) // stride
    for bone, column in layout:
        if tokens[column::stride] != [bone] * num_frames:
            return None
    try:
        frame_numbers = np.array(tokens[0::stride], dtype=np.int64)
        values = {}
        for bone, column in layout:
            count = num_values[bone]
            columns = [tokens[c::stride] for c in range(column + 1, column + 1 + count)]
            values[bone] = np.array(columns, dtype=np.float64).reshape(count, num_frames).T
    except ValueError:
        return None
    if not np.array_equal(frame_numbers, frame_numbers[0] + np.arange(num_frames)):
        return None
    if not all(np.isfinite(v).all() for v in values.values()):
        return None
    return frame_numbers, values


def _general_layout(path: Path, body: str, first_line: int, num_values: dict[str, int], required: set[str]):
    """Line-by-line AMC parsing (any bone order per frame); raises naming the line at fault."""
    frames: list[dict[str, np.ndarray]] = []
    frame_numbers: list[int] = []
    frame_lines: list[int] = []

    def close_frame() -> None:
        if frames:
            missing = [bone for bone in num_values if bone in required and bone not in frames[-1]]
            if missing:
                raise MotionFormatError(
                    f"{path}: line {frame_lines[-1]}: frame {frame_numbers[-1]} has no line for bones {missing}; "
                    "expected every bone with DOF in every frame."
                )

    for number, raw in enumerate(body.splitlines(), first_line):
        content = raw.split("#", 1)[0].strip()
        if not content:
            continue
        words = content.split()
        if len(words) == 1 and words[0] not in num_values:
            if not _is_integer(words[0]):
                raise MotionFormatError(
                    f"{path}: line {number}: expected a bone line or an integer frame number, got {words[0]!r}."
                )
            close_frame()
            frame = int(words[0])
            if frame_numbers and frame != frame_numbers[-1] + 1:
                raise MotionFormatError(
                    f"{path}: line {number}: expected frame number {frame_numbers[-1] + 1} (frames must be "
                    f"consecutive), got {frame}."
                )
            frames.append({})
            frame_numbers.append(frame)
            frame_lines.append(number)
            continue
        bone, words = words[0], words[1:]
        if bone not in num_values:
            raise MotionFormatError(
                f"{path}: line {number}: unknown bone {bone!r}; the ASF defines {sorted(num_values)}."
            )
        if bone in frames[-1]:
            raise MotionFormatError(f"{path}: line {number}: bone {bone!r} appears twice in frame {frame_numbers[-1]}.")
        if len(words) != num_values[bone]:
            raise MotionFormatError(
                f"{path}: line {number}: expected {num_values[bone]} values for bone {bone!r} (its DOF count in the "
                f"ASF), got {len(words)}."
            )
        try:
            values = np.array([float(word) for word in words])
        except ValueError:
            bad = next(word for word in words if not _is_float(word))
            raise MotionFormatError(
                f"{path}: line {number}: expected a number for bone {bone!r}, got {bad!r}."
            ) from None
        if not np.isfinite(values).all():
            raise MotionFormatError(f"{path}: line {number}: expected finite numbers for bone {bone!r}, got {words}.")
        frames[-1][bone] = values
    close_frame()
    values = {
        bone: np.array([frame[bone] for frame in frames]).reshape(len(frames), num_values[bone])
        for bone in num_values
        if bone in required
    }
    return np.array(frame_numbers), values


def _is_float(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def read_amc(
    amc_path: str | Path,
    asf: AsfSkeleton | str | Path,
    *,
    name: str | None = None,
    fps: float = 120.0,
) -> Motion:
    """Read an Acclaim AMC motion on its ASF skeleton.

    Parameters
    ----------
    amc_path : str or Path
    asf : AsfSkeleton, str or Path
        The skeleton, or the path of its ASF file.
    name : str, optional, keyword-only
        ``Motion.name``; default the AMC file name without suffix (``"09_06"``).
    fps : float, keyword-only
        Frame rate, which AMC files do not record. Default 120 (every CMU capture here; the CMU index lists
        60 fps for a few subjects).

    Returns
    -------
    Motion
        F frames (as numbered in the file), J = bones + 1 joints of ``asf.skeleton``; root positions in cm,
        local rotations ``C M C^-1`` (module docstring). Angles in degrees unless the AMC says ``:RADIANS``
        (or, with no such line, the ASF says ``angle rad``).

    Raises
    ------
    MotionFormatError
        Missing, empty or malformed file: no frames, non-consecutive frame numbers, an unknown bone, a
        bone line with the wrong number of values, a non-number, NaN/inf, a frame missing a bone. The
        message names the file, the line and what was expected.
    """
    asf = asf if isinstance(asf, AsfSkeleton) else read_asf(asf)
    amc_path = Path(amc_path)
    text = read_text(amc_path, "AMC file")
    degrees, body_start, body_line = _amc_header(amc_path, text)
    degrees = asf.angles_in_degrees if degrees is None else degrees
    body = text[body_start:]
    num_values = {bone: len(dofs) for bone, dofs in zip(asf.names, asf.dofs, strict=True)}
    required = {bone for bone, count in num_values.items() if count}
    parsed = None if "#" in body else _fixed_layout(body.split(), num_values, required)
    if parsed is None:
        parsed = _general_layout(amc_path, body, body_line, num_values, required)
    frame_numbers, values = parsed
    num_frames = len(frame_numbers)
    root_positions, rotations = _amc_to_rotations(asf, values, num_frames, degrees)
    return Motion(asf.skeleton, fps, root_positions, rotations, name=amc_path.stem if name is None else name)


def _amc_to_rotations(asf: AsfSkeleton, values: dict[str, np.ndarray], num_frames: int, degrees: bool):
    """Root positions (F, 3) in cm and local quaternions (F, J, 4) from per-bone AMC values."""
    skeleton = asf.skeleton
    root_positions = np.tile(skeleton.offsets[0], (num_frames, 1))
    rotations = np.zeros((num_frames, skeleton.num_joints, 4))
    rotations[..., 3] = 1.0
    groups: dict[str, tuple[list[int], list[np.ndarray]]] = {}
    for joint, (bone, dofs) in enumerate(zip(skeleton.names, asf.dofs, strict=True)):
        if not dofs:
            continue
        bone_values = values[bone]
        axes, columns = "", []
        for column, dof in enumerate(dofs):
            if dof in _TRANSLATION_DOFS:
                root_positions[:, _TRANSLATION_DOFS.index(dof)] = bone_values[:, column] * asf.cm_per_unit
            else:
                axes += dof[1]
                columns.append(column)
        if axes:
            members = groups.setdefault(axes, ([], []))
            members[0].append(joint)
            members[1].append(bone_values[:, columns])
    for axes, (joints, angles) in groups.items():
        motion = Rotation.from_euler(axes, np.stack(angles, axis=1), degrees=degrees)  # (F, k), extrinsic
        axis = Rotation.from_quat(asf.axis_rotations[joints])  # (k,)
        rotations[:, joints] = (axis * motion * axis.inv()).as_quat()
    return root_positions, rotations
