"""BVH (Biovision Hierarchy) motion files: read any Euler channel order, write with a chosen precision.

Conventions of the reading (the common one, e.g. the CMU/cgspeed files and Blender's importer):

* ``CHANNELS 3 Zrotation Yrotation Xrotation`` means the joint's local rotation is
  ``R = Rz(z) @ Ry(y) @ Rx(x)`` acting on column vectors of the joint frame: the listed order is the
  multiplication order, i.e. scipy's intrinsic ``Rotation.from_euler("ZYX", [z, y, x], degrees=True)``.
  Any order and any subset of the three axes is read; a joint's ``Skeleton.channel_orders`` entry keeps
  the file's order (missing axes appended) so that :func:`write_bvh` writes it back the same way.
* Position channels are read on the root only, in any order; they are absolute root positions. An axis
  without a channel takes the root ``OFFSET``; with no position channel at all the root stays at its OFFSET.
  Position channels on another joint raise :class:`~mocapbench.motion.MotionFormatError` (a
  :class:`~mocapbench.motion.Motion` carries the root translation only).
* ``End Site`` blocks become ``Skeleton.end_site_parents`` / ``end_site_offsets``.
* ``length_unit_cm`` is the length of one file unit in cm: offsets and root positions are multiplied by it
  on reading and divided by it on writing (the CMU files use ASF units: pass
  :data:`mocapbench.io.asf_amc.CMU_CM_PER_UNIT`).

The MOTION block is validated per line with numpy (values per line, ``Frames:`` against the number of data
lines) and converted in one ``np.array(text.split(), float)`` call; Python loops run over joints, never over
frames, except to locate the line of an error.
"""

from __future__ import annotations

import io
import math
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mocapbench.lazy_imports import Rotation

from mocapbench.io import read_text
from mocapbench.io.safe_output import check_output, open_output
from mocapbench.motion import Motion, MotionFormatError, Skeleton

__all__ = ["read_bvh", "write_bvh"]

# Channel name (lower case) -> (kind, axis).
_CHANNELS = {f"{axis.lower()}{kind}": (kind, axis) for axis in "XYZ" for kind in ("position", "rotation")}
_CHANNEL_LIST = "Xposition Yposition Zposition Xrotation Yrotation Zrotation"
# What np.loadtxt reads as a float64 (decimal notation, nan, inf); Python's float() also takes "1_0" and "١".
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?|nan|inf|infinity)\Z", re.IGNORECASE)
_MOTION_LINE = re.compile(r"^[ \t]*MOTION[ \t]*\r?$", re.MULTILINE)
_WRITE_CHUNK_FRAMES = 4096  # frames formatted per write: bounded memory for long motions
_IS_WHITESPACE_BYTE = np.zeros(256, dtype=bool)
_IS_WHITESPACE_BYTE[[ord(c) for c in " \t\n\r\v\f"]] = True


@dataclass
class _Joint:
    """A joint as parsed from the HIERARCHY block (file units, channel names not yet checked)."""

    name: str
    parent: int
    line: int
    offset: tuple[float, float, float] | None = None
    channels: list[tuple[str, str]] = field(default_factory=list)  # (kind, axis) in file order
    channels_line: int = 0


class _HierarchyParser:
    """Recursive-descent parser of the HIERARCHY block over ``(token, line number)`` pairs."""

    def __init__(self, path: Path, tokens: list[tuple[str, int]], end_line: int, end_what: str) -> None:
        self.path = path
        self.tokens = tokens
        self.position = 0
        self.end_line = end_line
        self.end_what = end_what
        self.joints: list[_Joint] = []
        self.end_parents: list[int] = []
        self.end_offsets: list[tuple[float, float, float]] = []

    def error(self, line: int, message: str) -> MotionFormatError:
        return MotionFormatError(f"{self.path}: line {line}: {message}")

    def next(self, expected: str) -> tuple[str, int]:
        if self.position >= len(self.tokens):
            raise self.error(self.end_line, f"expected {expected}, reached {self.end_what}.")
        token = self.tokens[self.position]
        self.position += 1
        return token

    def rest_of_line(self, line: int) -> list[str]:
        """Tokens after the current one that sit on ``line``."""
        start = self.position
        while self.position < len(self.tokens) and self.tokens[self.position][1] == line:
            self.position += 1
        return [token for token, _ in self.tokens[start : self.position]]

    def numbers(self, keyword: str, line: int, count: int) -> tuple[float, ...]:
        words = self.rest_of_line(line)
        if len(words) != count:
            raise self.error(line, f"expected {count} numbers after {keyword}, got {len(words)}: {words}.")
        try:
            values = tuple(float(word) for word in words)
        except ValueError:
            raise self.error(line, f"expected {count} numbers after {keyword}, got {words}.") from None
        if not all(math.isfinite(v) for v in values):
            raise self.error(line, f"expected {count} finite numbers after {keyword}, got {words}.")
        return values

    def parse(self) -> None:
        token, line = self.next("'HIERARCHY'")
        if token != "HIERARCHY":
            raise self.error(line, f"expected 'HIERARCHY' to start the file, got {token!r}.")
        token, line = self.next("'ROOT'")
        if token != "ROOT":
            raise self.error(line, f"expected 'ROOT', got {token!r}.")
        self.joint(parent=-1, keyword_line=line)
        if self.position < len(self.tokens):
            token, line = self.tokens[self.position]
            if token == "}":
                raise self.error(line, "unbalanced braces: this '}' closes nothing.")
            if token == "ROOT":
                raise self.error(line, "found a second ROOT; mocapbench reads one skeleton per BVH file.")
            raise self.error(line, f"expected 'MOTION' after the root joint's closing brace, got {token!r}.")

    def joint(self, parent: int, keyword_line: int) -> None:
        name_words = self.rest_of_line(keyword_line)
        if len(name_words) != 1 or name_words[0] in "{}":
            raise self.error(keyword_line, f"expected one joint name after ROOT/JOINT, got {name_words}.")
        name = name_words[0]
        if any(joint.name == name for joint in self.joints):
            raise self.error(keyword_line, f"joint name {name!r} is used twice; joint names must be unique.")
        token, open_line = self.next(f"'{{' opening joint {name!r}")
        if token != "{":
            raise self.error(open_line, f"expected '{{' opening joint {name!r}, got {token!r}.")
        index = len(self.joints)
        joint = _Joint(name=name, parent=parent, line=keyword_line)
        self.joints.append(joint)
        closing = f"'}}' closing joint {name!r} (opened at line {open_line})"
        while True:
            token, line = self.next(closing)
            if token == "}":
                break
            if token == "OFFSET":
                if joint.offset is not None:
                    raise self.error(line, f"second OFFSET in joint {name!r}.")
                joint.offset = self.numbers("OFFSET", line, 3)
            elif token == "CHANNELS":
                if joint.channels_line:
                    raise self.error(line, f"second CHANNELS in joint {name!r} (first at line {joint.channels_line}).")
                joint.channels = self.channels(name, line)
                joint.channels_line = line
            elif token == "JOINT":
                self.joint(parent=index, keyword_line=line)
            elif token == "End":
                self.end_site(index, line)
            elif token == "{":
                raise self.error(line, f"unbalanced braces: unexpected '{{' inside joint {name!r}.")
            else:
                raise self.error(
                    line, f"expected OFFSET, CHANNELS, JOINT, End Site or {closing} in joint {name!r}, got {token!r}."
                )
        if joint.offset is None:
            raise self.error(keyword_line, f"joint {name!r} has no OFFSET.")

    def channels(self, joint: str, line: int) -> list[tuple[str, str]]:
        words = self.rest_of_line(line)
        if not words or not words[0].isdigit():
            raise self.error(line, f"expected a channel count after CHANNELS, got {words}.")
        count, names = int(words[0]), words[1:]
        if len(names) != count:
            raise self.error(line, f"CHANNELS announces {count} channels for joint {joint!r} but names {len(names)}.")
        channels = []
        for channel in names:
            if channel.lower() not in _CHANNELS:
                raise self.error(line, f"unknown channel name {channel!r} in joint {joint!r}; known: {_CHANNEL_LIST}.")
            channels.append(_CHANNELS[channel.lower()])
        if len(set(channels)) != len(channels):
            raise self.error(line, f"a channel is repeated in joint {joint!r}: {names}.")
        return channels

    def end_site(self, parent: int, line: int) -> None:
        words = self.rest_of_line(line)
        if words != ["Site"]:
            raise self.error(line, f"expected 'End Site', got {' '.join(['End', *words])!r}.")
        token, open_line = self.next("'{' opening the End Site")
        if token != "{":
            raise self.error(open_line, f"expected '{{' opening the End Site, got {token!r}.")
        token, offset_line = self.next("OFFSET in the End Site")
        if token != "OFFSET":
            raise self.error(offset_line, f"expected OFFSET in the End Site, got {token!r}.")
        offset = self.numbers("OFFSET", offset_line, 3)
        token, close_line = self.next(f"'}}' closing the End Site opened at line {open_line}")
        if token != "}":
            raise self.error(
                close_line, f"expected '}}' closing the End Site opened at line {open_line}, got {token!r}."
            )
        self.end_parents.append(parent)
        self.end_offsets.append(offset)


def _tokenize(text: str, first_line: int) -> list[tuple[str, int]]:
    """``(token, line number)`` pairs of ``text``; its first line has number ``first_line``."""
    return [(word, number) for number, line in enumerate(text.splitlines(), first_line) for word in line.split()]


def _tokens_per_line(data: str) -> np.ndarray:
    """Number of whitespace-separated tokens on each line of ``data`` (a final line without newline counts).

    Vectorized over bytes; falls back to ``str.split`` per line when ``data`` holds non-ASCII text (where a
    byte is not a character).
    """
    raw = np.frombuffer(data.encode("utf-8"), dtype=np.uint8)
    if raw.size == 0:
        return np.zeros(0, dtype=np.int64)
    if raw.size != len(data):
        return np.array([len(line.split()) for line in data.split("\n")], dtype=np.int64)
    space = _IS_WHITESPACE_BYTE[raw]
    starts = ~space
    starts[1:] &= space[:-1]
    line_ends = np.flatnonzero(raw == 10)
    if raw[-1] != 10:
        line_ends = np.append(line_ends, raw.size)
    cumulative = np.concatenate(([0], np.cumsum(starts)))
    return np.diff(cumulative[np.concatenate(([0], line_ends))])


def _frames_per_second(frame_time: float, text: str) -> float:
    """``1 / frame_time``, snapped to the nearest integer rate when the printed frame time is that rate rounded.

    ``Frame Time: .0083333`` gives 120.0, not 120.0005: files print ``1 / fps`` with a few decimals.
    """
    fps = 1.0 / frame_time
    decimals = len(text.split(".", 1)[1].lower().split("e")[0]) if "." in text and "e" not in text.lower() else None
    rounded = round(fps)
    if decimals is not None and rounded > 0 and round(1.0 / rounded, decimals) == round(frame_time, decimals):
        return float(rounded)
    return fps


def _motion_header(path: Path, text: str, start: int, first_line: int) -> tuple[int, float, int, int, int]:
    """Parse the ``Frames:`` and ``Frame Time:`` lines that follow the MOTION line.

    Parameters
    ----------
    text : str
        The whole file; ``start`` is the index just after the MOTION line's newline, on line ``first_line``.

    Returns
    -------
    (frames, fps, frames_line, data_start, data_line) : declared frame count, frames per second, the line
    number of ``Frames:``, the index in ``text`` where the data lines start and the number of their first line.
    """
    found: list[tuple[list[str], int]] = []
    line_number = first_line
    for expected in ("Frames:", "Frame Time:"):
        while True:
            if start >= len(text):
                raise MotionFormatError(
                    f"{path}: line {line_number}: expected '{expected} <number>', reached the end of the file."
                )
            stop = text.find("\n", start)
            stop = len(text) if stop < 0 else stop
            line, start, line_number = text[start:stop], stop + 1, line_number + 1
            if line.strip():
                break
        words, label_words = line.split(), expected.split()
        if words[: len(label_words)] != label_words or len(words) != len(label_words) + 1:
            raise MotionFormatError(
                f"{path}: line {line_number - 1}: expected '{expected} <number>', got {line.strip()!r}."
            )
        found.append((words, line_number - 1))
    (frames_words, frames_line), (time_words, time_line) = found
    try:
        frames = int(frames_words[1])
    except ValueError:
        raise MotionFormatError(
            f"{path}: line {frames_line}: expected an integer frame count, got {frames_words[1]!r}."
        ) from None
    if frames < 0:
        raise MotionFormatError(f"{path}: line {frames_line}: expected a frame count >= 1, got {frames}.")
    try:
        frame_time = float(time_words[2])
    except ValueError:
        frame_time = math.nan
    if not (math.isfinite(frame_time) and frame_time > 0):
        raise MotionFormatError(
            f"{path}: line {time_line}: expected a frame time in seconds > 0, got {time_words[2]!r}."
        )
    return frames, _frames_per_second(frame_time, time_words[2]), frames_line, min(start, len(text)), line_number


def _parse_values(path: Path, data: str, line_numbers: np.ndarray, num_channels: int) -> np.ndarray:
    """The MOTION numbers as an ``(F, C)`` array; every non-blank line already holds ``C`` tokens.

    ``np.loadtxt``'s C parser is strict (no hex, no ``1_0``, no trailing letters) and skips blank lines; on its
    error the lines are scanned again in Python to name the line and the token.
    """
    try:
        values = np.loadtxt(io.StringIO(data), dtype=np.float64, comments=None, ndmin=2)
    except ValueError as error:
        lines = [line for line in data.split("\n") if line.strip()]
        for number, line in zip(line_numbers, lines, strict=True):
            for word in line.split():
                if not _NUMBER.match(word):
                    raise MotionFormatError(f"{path}: line {number}: expected a number, got {word!r}.") from None
        raise MotionFormatError(f"{path}: the MOTION section holds a value that is not a number ({error}).") from None
    finite = np.isfinite(values)
    if not finite.all():
        frame, channel = np.argwhere(~finite)[0]
        raise MotionFormatError(
            f"{path}: line {line_numbers[frame]}: expected finite numbers, got {values[frame, channel]} "
            f"(value {channel + 1} of {num_channels})."
        )
    return values


def read_bvh(
    path: str | Path, *, length_unit_cm: float = 1.0, drop_first_frame: bool = False, name: str | None = None
) -> Motion:
    """Read a BVH file.

    Parameters
    ----------
    path : str or Path
    length_unit_cm : float, keyword-only
        Length of one file unit in cm (> 0). Default 1 (the file is in cm); the CMU BVH files are in ASF
        units: 2.54 / 0.45 cm.
    drop_first_frame : bool, keyword-only
        Drop frame 0 (the CMU/cgspeed files start with a reference "T" pose that is not capture).
    name : str, optional, keyword-only
        ``Motion.name``; default the file name without its suffix.

    Returns
    -------
    Motion
        Root positions (F, 3) in cm, local rotations (F, J, 4) as scalar-last quaternions; J joints (end
        sites in ``skeleton.end_site_*``), fps from ``Frame Time`` (snapped to an integer rate when the
        printed frame time is that rate rounded).

    Raises
    ------
    MotionFormatError
        A missing (:class:`~mocapbench.io.MotionFileNotFoundError`), empty or malformed file; the message
        names the file, the line and what was expected. ``ValueError`` for a bad ``length_unit_cm``.
    """
    if not (math.isfinite(length_unit_cm) and length_unit_cm > 0):
        raise ValueError(f"`length_unit_cm` must be a finite number > 0, got {length_unit_cm}.")
    path = Path(path)
    text = read_text(path, "BVH file")
    motion_match = _MOTION_LINE.search(text)
    if motion_match is None:
        first = text.split(None, 1)[0]
        if first != "HIERARCHY":
            line = text.count("\n", 0, text.index(first)) + 1
            raise MotionFormatError(f"{path}: line {line}: expected 'HIERARCHY' to start a BVH file, got {first!r}.")
        raise MotionFormatError(f"{path}: no MOTION section: expected a line 'MOTION' after the HIERARCHY block.")
    motion_line = text.count("\n", 0, motion_match.start()) + 1
    parser = _HierarchyParser(
        path, _tokenize(text[: motion_match.start()], 1), motion_line, "the MOTION line before the hierarchy ended"
    )
    parser.parse()
    joints = parser.joints
    num_channels = _check_channels(path, joints)

    # Frames: and Frame Time: lines, then the data block.
    after_motion = text.find("\n", motion_match.end())
    after_motion = len(text) if after_motion < 0 else after_motion + 1
    num_frames, fps, frames_line, data_start, first_data_line = _motion_header(
        path, text, after_motion, motion_line + 1
    )
    data = text[data_start:]
    counts = _tokens_per_line(data)
    nonblank = np.flatnonzero(counts > 0)
    line_numbers = first_data_line + nonblank
    if num_frames == 0:
        raise MotionFormatError(f"{path}: line {frames_line}: 'Frames: 0'; a motion needs at least one frame.")
    wrong = np.flatnonzero(counts[nonblank] != num_channels)
    if wrong.size:
        bad = nonblank[wrong[0]]
        raise MotionFormatError(
            f"{path}: line {first_data_line + bad}: expected {num_channels} values (the channels of the HIERARCHY), "
            f"got {counts[bad]}."
        )
    if nonblank.size != num_frames:
        span = f"lines {line_numbers[0]}-{line_numbers[-1]}" if nonblank.size else f"after line {first_data_line - 1}"
        raise MotionFormatError(
            f"{path}: line {frames_line}: 'Frames: {num_frames}' but the MOTION section has {nonblank.size} data "
            f"lines ({span})."
        )
    values = _parse_values(path, data, line_numbers, num_channels)
    if drop_first_frame:
        if num_frames < 2:
            raise MotionFormatError(f"{path}: line {frames_line}: drop_first_frame needs 2 frames or more, got 1.")
        values = values[1:]
    skeleton, root_positions, rotations = _to_motion_arrays(parser, values, length_unit_cm)
    return Motion(skeleton, fps, root_positions, rotations, name=path.stem if name is None else name)


def _check_channels(path: Path, joints: list[_Joint]) -> int:
    """Refuse position channels below the root; return the total channel count C."""
    for index, joint in enumerate(joints):
        if index > 0 and any(kind == "position" for kind, _ in joint.channels):
            raise MotionFormatError(
                f"{path}: line {joint.channels_line}: position channels on joint {joint.name!r}, which is not the "
                "root; expected rotation channels only (a Motion carries the root translation only)."
            )
    return sum(len(joint.channels) for joint in joints)


def _to_motion_arrays(parser: _HierarchyParser, values: np.ndarray, length_unit_cm: float):
    """Skeleton (cm), root positions (F, 3) in cm and quaternions (F, J, 4) from the (F, C) channel values."""
    joints = parser.joints
    num_frames, num_joints = values.shape[0], len(joints)
    root_offset = np.array(joints[0].offset)
    root_positions = np.tile(root_offset, (num_frames, 1))
    rotations = np.zeros((num_frames, num_joints, 4))
    rotations[..., 3] = 1.0
    by_order: dict[str, tuple[list[int], list[list[int]]]] = {}
    orders = []
    column = 0
    for index, joint in enumerate(joints):
        rotation_axes, rotation_columns = "", []
        for kind, axis in joint.channels:
            if kind == "position":
                root_positions[:, "XYZ".index(axis)] = values[:, column]
            else:
                rotation_axes += axis
                rotation_columns.append(column)
            column += 1
        orders.append(rotation_axes + "".join(a for a in "XYZ" if a not in rotation_axes))
        if rotation_axes:
            members = by_order.setdefault(rotation_axes, ([], []))
            members[0].append(index)
            members[1].append(rotation_columns)
    for axes, (members, columns) in by_order.items():
        angles = values[:, np.array(columns)]  # (F, k, len(axes))
        rotations[:, members] = Rotation.from_euler(axes, angles, degrees=True).as_quat()
    skeleton = Skeleton(
        names=tuple(joint.name for joint in joints),
        parents=np.array([joint.parent for joint in joints]),
        offsets=np.array([joint.offset for joint in joints]) * length_unit_cm,
        channel_orders=tuple(orders),
        end_site_parents=np.array(parser.end_parents, dtype=np.int64),
        end_site_offsets=np.array(parser.end_offsets, dtype=np.float64).reshape(-1, 3) * length_unit_cm,
    )
    return skeleton, root_positions * length_unit_cm, rotations


def write_bvh(
    motion: Motion,
    path: str | Path,
    *,
    length_unit_cm: float = 1.0,
    overwrite: bool = False,
    decimals: int = 6,
    position_channels: str = "root",
) -> Path:
    """Write ``motion`` as a BVH file.

    The root gets ``Xposition Yposition Zposition`` plus its rotation channels, every other joint three
    rotation channels in ``skeleton.channel_orders[j]`` (e.g. ``"ZYX"`` -> ``Zrotation Yrotation
    Xrotation``), angles in degrees. Joints are written depth first with children in index order, so
    :func:`read_bvh` returns them in the same order whenever ``skeleton`` is in that order (every
    skeleton read from a file is). A joint's end sites are written after its child joints.

    Parameters
    ----------
    motion : Motion
    path : str or Path
    length_unit_cm : float, keyword-only
        Length of one file unit in cm (> 0): offsets and root positions are divided by it. Default 1.
    overwrite : bool, keyword-only
        Replace an existing file or link (the link itself, never its target); default False: raise
        :class:`~mocapbench.io.safe_output.OutputExistsError` (a ``FileExistsError``). The file is written
        atomically by :mod:`mocapbench.io.safe_output`.
    decimals : int, keyword-only
        Decimals of every number, 1..15. Default 6: 1e-6 file units and 1e-6 degrees, so a read-back motion
        has the same joint positions within about 1e-4 cm for a 2 m tall skeleton in cm.
    position_channels : str, keyword-only
        ``"root"`` (default): position channels on the root only. ``"all"``: ``CHANNELS 6 Xposition Yposition
        Zposition`` + rotations on every joint, the non-root ones holding the joint's OFFSET in every frame (what
        MotionBuilder exports).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    FileExistsError
        ``path`` exists (or is a link, dangling or not) and ``overwrite`` is False.
    OSError
        The folder of ``path`` does not exist, or ``path`` is a folder.
    """
    if not (math.isfinite(length_unit_cm) and length_unit_cm > 0):
        raise ValueError(f"`length_unit_cm` must be a finite number > 0, got {length_unit_cm}.")
    if not 1 <= decimals <= 15:
        raise ValueError(f"`decimals` must be in [1, 15], got {decimals}.")
    if position_channels not in ("root", "all"):
        raise ValueError(f"`position_channels` must be 'root' or 'all', got {position_channels!r}.")
    path = check_output(path, force=overwrite)
    skeleton = motion.skeleton
    order = _depth_first_order(skeleton.parents)
    number = f"{{:.{decimals}f}}"
    lines = ["HIERARCHY"]

    def write_joint(joint: int, depth: int) -> None:
        indent = "\t" * depth
        keyword = "ROOT" if joint == 0 else "JOINT"
        offset = " ".join(number.format(v) for v in skeleton.offsets[joint] / length_unit_cm)
        rotation_channels = " ".join(f"{axis}rotation" for axis in skeleton.channel_orders[joint])
        with_position = joint == 0 or position_channels == "all"
        channels = f"6 Xposition Yposition Zposition {rotation_channels}" if with_position else f"3 {rotation_channels}"
        lines.extend([f"{indent}{keyword} {skeleton.names[joint]}", f"{indent}{{", f"{indent}\tOFFSET {offset}"])
        lines.append(f"{indent}\tCHANNELS {channels}")
        for child in skeleton.children(joint):
            write_joint(child, depth + 1)
        for end in np.flatnonzero(skeleton.end_site_parents == joint):
            end_offset = " ".join(number.format(v) for v in skeleton.end_site_offsets[end] / length_unit_cm)
            lines.extend([f"{indent}\tEnd Site", f"{indent}\t{{", f"{indent}\t\tOFFSET {end_offset}", f"{indent}\t}}"])
        lines.append(f"{indent}}}")

    write_joint(0, 0)
    lines.extend(["MOTION", f"Frames: {motion.num_frames}", f"Frame Time: {1.0 / motion.fps:.10g}"])

    columns = [motion.root_positions / length_unit_cm]
    euler = np.empty((motion.num_frames, motion.num_joints, 3))
    for axes in sorted(set(skeleton.channel_orders)):
        members = [j for j in range(motion.num_joints) if skeleton.channel_orders[j] == axes]
        with warnings.catch_warnings():
            # At gimbal lock scipy sets the third angle to 0 and warns; the angles still give the same rotation.
            warnings.filterwarnings("ignore", message="Gimbal lock detected", category=UserWarning)
            euler[:, members] = Rotation.from_quat(motion.rotations[:, members]).as_euler(axes, degrees=True)
    if position_channels == "all":
        positions = np.broadcast_to(skeleton.offsets[order] / length_unit_cm, euler.shape).copy()
        positions[:, 0] = motion.root_positions / length_unit_cm
        values = np.concatenate([positions, euler[:, order]], axis=2).reshape(motion.num_frames, -1)
    else:
        columns.append(euler[:, order].reshape(motion.num_frames, -1))
        values = np.concatenate(columns, axis=1)
    row = " ".join([number] * values.shape[1])
    with open_output(path, "w", force=overwrite) as handle:
        handle.write("\n".join(lines) + "\n")
        for start in range(0, motion.num_frames, _WRITE_CHUNK_FRAMES):
            chunk = values[start : start + _WRITE_CHUNK_FRAMES].tolist()
            handle.write("".join(row.format(*frame) + "\n" for frame in chunk))
    return path


def _depth_first_order(parents: np.ndarray) -> list[int]:
    """Joints in depth-first pre-order, children in index order (the order a BVH file lists them)."""
    children: list[list[int]] = [[] for _ in parents]
    for joint in range(1, len(parents)):
        children[parents[joint]].append(joint)
    order, stack = [], [0]
    while stack:
        joint = stack.pop()
        order.append(joint)
        stack.extend(reversed(children[joint]))
    return order
