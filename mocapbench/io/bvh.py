"""BVH (Biovision Hierarchy) motion files: read any Euler channel order, write with a chosen precision.

Conventions of the reading (the common one, e.g. the CMU/cgspeed files and Blender's importer):

* ``CHANNELS 3 Zrotation Yrotation Xrotation`` means the joint's local rotation is
  ``R = Rz(z) @ Ry(y) @ Rx(x)`` acting on column vectors of the joint frame: the listed order is the
  multiplication order, i.e. scipy's intrinsic ``Rotation.from_euler("ZYX", [z, y, x], degrees=True)``.
  Any order and any subset of the three axes is read; a joint's ``Skeleton.channel_orders`` entry keeps
  the file's order (missing axes appended) so that :func:`write_bvh` writes it back the same way.
* Position channels on the root, in any order, are absolute root positions. An axis without a channel takes
  the root ``OFFSET``; with no position channel at all the root stays at its OFFSET.
* Position channels on other joints (MotionBuilder and game tools write ``CHANNELS 6`` on every joint; a game rig
  moves its pelvis under a ground-level root) are the joint's local translation in its parent's frame, read into
  :attr:`Motion.translations <mocapbench.motion.Motion.translations>` (an axis without a channel takes the OFFSET).
  A joint whose channels stay equal to its OFFSET in every frame (within :data:`POSITION_TOLERANCE` file units,
  relative to the offset's size: files print 6 significant digits) is *folded*: it sits at its OFFSET, and a file
  in which no joint moves has ``translations`` ``None``, as a file with position channels on the root only.
* ``End Site`` blocks become ``Skeleton.end_site_parents`` / ``end_site_offsets``.
* ``length_unit_cm`` is the length of one file unit in cm: offsets and root positions are multiplied by it
  on reading and divided by it on writing (the CMU files use ASF units: pass
  :data:`mocapbench.io.asf_amc.CMU_CM_PER_UNIT`).

Reading streams: the HIERARCHY block is parsed without recursion (any depth, at most :data:`MAX_JOINTS`
joints), the MOTION numbers are parsed in blocks of 2 MiB into arrays allocated once from
``Frames:`` (bounded by what the file's bytes can hold), and each block is turned into quaternions at once, so
the peak memory is about the decoded motion (twice its quaternions while :class:`Motion` normalizes them) plus a
block, not a multiple of the file. Each block is validated with numpy (characters, values per line, finite
values) and parsed by ``np.loadtxt``'s C parser; Python loops run over joints and blocks, never over frames,
except to locate the line of an error. ``Frame Time`` must be finite and in [1e-5, 1000] s (100,000 to 0.001
frames per second, the container's range).
"""

from __future__ import annotations

import io
import math
import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import numpy as np
from mocapbench.lazy_imports import Rotation

from mocapbench.io.text import MotionFileNotFoundError
from mocapbench.io.read_limits import check_motion_size
from mocapbench.io.safe_output import check_output, open_output
from mocapbench.motion import Motion, MotionFormatError, OwnedQuaternions, Skeleton

__all__ = ["read_bvh", "write_bvh", "MAX_JOINTS", "POSITION_TOLERANCE"]

#: Most joints a BVH file may declare (the container's limit; real rigs have 15-150).
MAX_JOINTS = 4096
#: A non-root joint whose position channels stay within this many file units of its OFFSET (times
#: max(1, |offset|)) in every frame is folded to its OFFSET.
POSITION_TOLERANCE = 1e-4
# Frame Time range, seconds: the frame rates a stream may carry (mocapbench.codecs.container.MIN_FPS/MAX_FPS).
MIN_FRAME_TIME_S = 1e-5
MAX_FRAME_TIME_S = 1e3
_MAX_HIERARCHY_BYTES = 16 << 20  # 4096 joints need well under 1 MiB
_CHUNK_BYTES = 2 << 20  # MOTION bytes parsed at a time (its temporaries are a few times this)

# Channel name (lower case) -> (kind, axis).
_CHANNELS = {f"{axis.lower()}{kind}": (kind, axis) for axis in "XYZ" for kind in ("position", "rotation")}
_CHANNEL_LIST = "Xposition Yposition Zposition Xrotation Yrotation Zrotation"
# What np.loadtxt reads as a float64 (decimal notation, nan, inf); Python's float() also takes "1_0" and "١".
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?|nan|inf|infinity)\Z", re.IGNORECASE)
_WRITE_CHUNK_FRAMES = 4096  # frames formatted per write: bounded memory for long motions
_IS_WHITESPACE_BYTE = np.zeros(256, dtype=bool)
_IS_WHITESPACE_BYTE[[ord(c) for c in " \t\n\r\v\f"]] = True
# Bytes that may appear in the MOTION block: whitespace, digits, sign, point, exponent, and the letters of nan/inf.
_IS_NUMBER_BYTE = _IS_WHITESPACE_BYTE.copy()
_IS_NUMBER_BYTE[list(b"0123456789+-.eEnNaAiIfFtTyY")] = True


@dataclass
class _Joint:
    """A joint as parsed from the HIERARCHY block (file units, channel names not yet checked)."""

    name: str
    parent: int
    line: int
    offset: tuple[float, float, float] | None = None
    channels: list[tuple[str, str]] = field(default_factory=list)  # (kind, axis) in file order
    channels_line: int = 0
    open_line: int = 0


class _HierarchyParser:
    """Parser of the HIERARCHY block over ``(token, line number)`` pairs, with an explicit stack (any depth)."""

    def __init__(self, path: Path, tokens: list[tuple[str, int]], end_line: int, end_what: str) -> None:
        self.path = path
        self.tokens = tokens
        self.position = 0
        self.end_line = end_line
        self.end_what = end_what
        self.joints: list[_Joint] = []
        self.names: set[str] = set()
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
        stack = [self.open_joint(parent=-1, keyword_line=line)]
        while stack:
            joint = self.joints[stack[-1]]
            closing = f"'}}' closing joint {joint.name!r} (opened at line {joint.open_line})"
            token, line = self.next(closing)
            if token == "}":
                if joint.offset is None:
                    raise self.error(joint.line, f"joint {joint.name!r} has no OFFSET.")
                stack.pop()
            elif token == "OFFSET":
                if joint.offset is not None:
                    raise self.error(line, f"second OFFSET in joint {joint.name!r}.")
                joint.offset = self.numbers("OFFSET", line, 3)
            elif token == "CHANNELS":
                if joint.channels_line:
                    raise self.error(
                        line, f"second CHANNELS in joint {joint.name!r} (first at line {joint.channels_line})."
                    )
                joint.channels = self.channels(joint.name, line)
                joint.channels_line = line
            elif token == "JOINT":
                stack.append(self.open_joint(parent=stack[-1], keyword_line=line))
            elif token == "End":
                self.end_site(stack[-1], line)
            elif token == "{":
                raise self.error(line, f"unbalanced braces: unexpected '{{' inside joint {joint.name!r}.")
            else:
                raise self.error(
                    line,
                    f"expected OFFSET, CHANNELS, JOINT, End Site or {closing} in joint {joint.name!r}, got {token!r}.",
                )
        if self.position < len(self.tokens):
            token, line = self.tokens[self.position]
            if token == "}":
                raise self.error(line, "unbalanced braces: this '}' closes nothing.")
            if token == "ROOT":
                raise self.error(line, "found a second ROOT; mocapbench reads one skeleton per BVH file.")
            raise self.error(line, f"expected 'MOTION' after the root joint's closing brace, got {token!r}.")

    def open_joint(self, parent: int, keyword_line: int) -> int:
        """Read ``NAME {`` after ROOT/JOINT; returns the new joint's index."""
        name_words = self.rest_of_line(keyword_line)
        if len(name_words) != 1 or name_words[0] in "{}":
            raise self.error(keyword_line, f"expected one joint name after ROOT/JOINT, got {name_words}.")
        name = name_words[0]
        if any(ord(c) < 32 or c == "\x7f" for c in name):
            raise self.error(keyword_line, f"joint name {name!r} holds a control character (NUL, ...); expected text.")
        if name in self.names:
            raise self.error(keyword_line, f"joint name {name!r} is used twice; joint names must be unique.")
        if len(self.joints) >= MAX_JOINTS:
            raise self.error(keyword_line, f"more than {MAX_JOINTS} joints; mocapbench reads at most {MAX_JOINTS}.")
        token, open_line = self.next(f"'{{' opening joint {name!r}")
        if token != "{":
            raise self.error(open_line, f"expected '{{' opening joint {name!r}, got {token!r}.")
        self.names.add(name)
        self.joints.append(_Joint(name=name, parent=parent, line=keyword_line, open_line=open_line))
        return len(self.joints) - 1

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


class _Reader:
    """One read of one BVH file from an open binary handle (see :func:`read_bvh`)."""

    def __init__(self, path: Path, handle: BinaryIO, size: int) -> None:
        self.path, self.handle, self.size = path, handle, size
        self.line = 0  # number of the last line read

    def error(self, line: int, message: str) -> MotionFormatError:
        return MotionFormatError(f"{self.path}: line {line}: {message}")

    def _text_line(self) -> str | None:
        raw = self.handle.readline(_MAX_HIERARCHY_BYTES + 1)
        if not raw:
            return None
        self.line += 1
        if self.line == 1 and raw.startswith(b"\xef\xbb\xbf"):
            raw = raw[3:]  # a UTF-8 byte-order mark, as some Windows editors write
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError as error:
            raise MotionFormatError(
                f"{self.path}: expected a BVH file as text, got undecodable bytes on line {self.line} ({error.reason})."
            ) from None

    # -- HIERARCHY ------------------------------------------------------------------------------------------
    def hierarchy(self) -> tuple[_HierarchyParser, int]:
        """Parse up to the MOTION line; returns the parser and the MOTION line's number."""
        tokens: list[tuple[str, int]] = []
        read = 0
        while True:
            text = self._text_line()
            if text is None:
                break
            read += len(text)
            words = text.split()
            if words == ["MOTION"] and text.strip(" \t\r\n") == "MOTION":
                parser = _HierarchyParser(self.path, tokens, self.line, "the MOTION line before the hierarchy ended")
                parser.parse()
                return parser, self.line
            if read > _MAX_HIERARCHY_BYTES:
                raise MotionFormatError(
                    f"{self.path}: no MOTION line in the first {_MAX_HIERARCHY_BYTES >> 20} MiB; expected a HIERARCHY "
                    f"of at most {MAX_JOINTS} joints followed by 'MOTION'."
                )
            tokens.extend((word, self.line) for word in words)
        if not tokens:
            raise MotionFormatError(f"{self.path}: the BVH file is empty.")
        if tokens[0][0] != "HIERARCHY":
            raise MotionFormatError(
                f"{self.path}: line {tokens[0][1]}: expected 'HIERARCHY' to start a BVH file, got {tokens[0][0]!r}."
            )
        raise MotionFormatError(f"{self.path}: no MOTION section: expected a line 'MOTION' after the HIERARCHY block.")

    # -- Frames: / Frame Time: -----------------------------------------------------------------------------
    def motion_header(self) -> tuple[int, float, int]:
        """``(frames, fps, frames_line)`` from the two lines after MOTION."""
        found: list[tuple[list[str], int]] = []
        for expected in ("Frames:", "Frame Time:"):
            while True:
                text = self._text_line()
                if text is None:
                    raise self.error(self.line + 1, f"expected '{expected} <number>', reached the end of the file.")
                if text.strip():
                    break
            words, label_words = text.split(), expected.split()
            if words[: len(label_words)] != label_words or len(words) != len(label_words) + 1:
                raise self.error(self.line, f"expected '{expected} <number>', got {text.strip()!r}.")
            found.append((words, self.line))
        (frames_words, frames_line), (time_words, time_line) = found
        try:
            frames = int(frames_words[1])
        except ValueError:
            raise self.error(frames_line, f"expected an integer frame count, got {frames_words[1]!r}.") from None
        if frames < 0:
            raise self.error(frames_line, f"expected a frame count >= 1, got {frames}.")
        if frames == 0:
            raise self.error(frames_line, "'Frames: 0'; a motion needs at least one frame.")
        try:
            frame_time = float(time_words[2])
        except ValueError:
            frame_time = math.nan
        if not (math.isfinite(frame_time) and frame_time > 0):
            raise self.error(time_line, f"expected a frame time in seconds > 0, got {time_words[2]!r}.")
        if not MIN_FRAME_TIME_S <= frame_time <= MAX_FRAME_TIME_S:
            raise self.error(
                time_line,
                f"expected a frame time in [{MIN_FRAME_TIME_S:g}, {MAX_FRAME_TIME_S:g}] s "
                f"({1 / MIN_FRAME_TIME_S:g} to {1 / MAX_FRAME_TIME_S:g} frames per second), got {time_words[2]!r}.",
            )
        return frames, _frames_per_second(frame_time, time_words[2]), frames_line


class _MotionBlock:
    """Turns blocks of MOTION values into root positions and quaternions, written into preallocated arrays."""

    def __init__(self, reader: _Reader, joints: list[_Joint], capacity: int) -> None:
        self.reader, self.joints = reader, joints
        num_joints = len(joints)
        self.root = np.tile(np.array(joints[0].offset, dtype=np.float64), (capacity, 1))
        self.rotations = np.zeros((capacity, num_joints, 4))
        self.rotations[..., 3] = 1.0
        self.by_order: dict[str, tuple[list[int], list[int]]] = {}  # axes -> (joints, columns in axis order)
        self.root_columns: list[tuple[int, int]] = []  # (column, axis)
        self.translation_columns: list[tuple[int, int, int]] = []  # (column, joint, axis) of non-root positions
        column = 0
        for index, joint in enumerate(joints):
            axes, columns = "", []
            for kind, axis in joint.channels:
                if kind == "position":
                    if index == 0:
                        self.root_columns.append((column, "XYZ".index(axis)))
                    else:
                        self.translation_columns.append((column, index, "XYZ".index(axis)))
                else:
                    axes += axis
                    columns.append(column)
                column += 1
            if axes:
                members, cols = self.by_order.setdefault(axes, ([], []))
                members.append(index)
                cols.extend(columns)
        self.num_channels = column
        # Joints with position channels below the root: their translations, file units, OFFSET where no channel.
        self.translated = sorted({joint for _, joint, _ in self.translation_columns})
        self.translations = None
        if self.translated:
            offsets = np.array([joints[j].offset for j in self.translated], dtype=np.float64)
            self.translations = np.tile(offsets, (capacity, 1, 1))
        self.translation_slot = {joint: slot for slot, joint in enumerate(self.translated)}

    def store(self, values: np.ndarray, row: int, line_numbers: np.ndarray) -> None:
        """Put the ``(n, C)`` block ``values`` (file lines ``line_numbers``) at frames ``row .. row + n``."""
        n = len(values)
        for column, joint, axis in self.translation_columns:
            self.translations[row : row + n, self.translation_slot[joint], axis] = values[:, column]
        for column, axis in self.root_columns:
            self.root[row : row + n, axis] = values[:, column]
        for axes, (members, columns) in self.by_order.items():
            angles = values[:, np.array(columns)].reshape(n, len(members), len(axes))
            self.rotations[row : row + n, members] = Rotation.from_euler(axes, angles, degrees=True).as_quat()

    def joint_translations(self, start: int, root: np.ndarray, length_unit_cm: float) -> np.ndarray | None:
        """The (F, J, 3) cm translation track of frames ``start:`` with still joints folded to their OFFSET, or
        ``None`` when no joint below the root moves (see :data:`POSITION_TOLERANCE`)."""
        if self.translations is None:
            return None
        moving = []
        for slot, joint in enumerate(self.translated):
            offset = np.array(self.joints[joint].offset)
            deviation = np.abs(self.translations[start:, slot] - offset).max(axis=0)
            if np.any(deviation > POSITION_TOLERANCE * np.maximum(1.0, np.abs(offset))):
                moving.append(slot)
        if not moving:
            return None
        offsets = np.array([joint.offset for joint in self.joints], dtype=np.float64)
        track = np.empty((len(root), len(self.joints), 3))
        track[:] = offsets * length_unit_cm
        track[:, 0] = root
        for slot in moving:
            track[:, self.translated[slot]] = self.translations[start:, slot] * length_unit_cm
        return track


def _parse_block(reader: _Reader, chunk: bytes, first_line: int, num_channels: int):
    """Validate and parse one block of whole MOTION lines.

    Returns
    -------
    (values, line_numbers) : ndarray (n, C) float64 and the file line of each of its n rows (blank lines skipped).
    """
    raw = np.frombuffer(chunk, dtype=np.uint8)
    newlines = np.flatnonzero(raw == 10)
    if not _IS_NUMBER_BYTE[raw].all():
        _raise_bad_token(reader, chunk, int(np.argmin(_IS_NUMBER_BYTE[raw])), first_line, newlines)
    space = _IS_WHITESPACE_BYTE[raw]
    starts = ~space
    starts[1:] &= space[:-1]
    token_starts = np.flatnonzero(starts)
    del space, starts
    line_ends = newlines if raw[-1] == 10 else np.append(newlines, raw.size)
    counts = np.diff(np.searchsorted(token_starts, line_ends), prepend=0)  # tokens per line
    del token_starts
    nonblank = np.flatnonzero(counts > 0)
    wrong = np.flatnonzero(counts[nonblank] != num_channels)
    if wrong.size:
        bad = nonblank[wrong[0]]
        raise reader.error(
            first_line + int(bad),
            f"expected {num_channels} values (the channels of the HIERARCHY), got {counts[bad]}.",
        )
    line_numbers = first_line + nonblank
    if not nonblank.size:
        return np.zeros((0, num_channels)), line_numbers
    try:
        values = np.loadtxt(io.StringIO(chunk.decode("ascii")), dtype=np.float64, comments=None, ndmin=2)
    except ValueError as error:
        text = chunk.decode("ascii")
        for number, line in zip(line_numbers, [line for line in text.split("\n") if line.strip()], strict=True):
            for word in line.split():
                if not _NUMBER.match(word):
                    raise reader.error(int(number), f"expected a number, got {word!r}.") from None
        raise MotionFormatError(
            f"{reader.path}: the MOTION section holds a value that is not a number ({error})."
        ) from None
    finite = np.isfinite(values)
    if not finite.all():
        frame, channel = np.argwhere(~finite)[0]
        raise reader.error(
            int(line_numbers[frame]),
            f"expected finite numbers, got {values[frame, channel]} (value {channel + 1} of {num_channels}).",
        )
    return values, line_numbers


def _raise_bad_token(reader: _Reader, chunk: bytes, at: int, first_line: int, newlines: np.ndarray) -> None:
    """Raise the error for the byte at ``chunk[at]``, which cannot be part of a number: name its word and line."""
    line = first_line + int(np.searchsorted(newlines, at))
    start = at
    while start > 0 and not _IS_WHITESPACE_BYTE[chunk[start - 1]]:
        start -= 1
    stop = at
    while stop < len(chunk) and not _IS_WHITESPACE_BYTE[chunk[stop]]:
        stop += 1
    word = chunk[start:stop].decode("utf-8", errors="replace")
    raise reader.error(line, f"expected a number, got {word!r}.")


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
        Root positions (F, 3) in cm, local rotations (F, J, 4) as scalar-last quaternions, ``translations``
        (F, J, 3) cm when a joint below the root moves (else ``None``); J joints (end
        sites in ``skeleton.end_site_*``), fps from ``Frame Time`` (snapped to an integer rate when the
        printed frame time is that rate rounded).

    Raises
    ------
    MotionFormatError
        A missing (:class:`~mocapbench.io.MotionFileNotFoundError`), empty or malformed file, a frame time
        outside [1e-5, 1000] s, more than :data:`MAX_JOINTS` joints; the message names the file, the line and
        what was expected. ``ValueError`` for a bad
        ``length_unit_cm``.
    """
    if not (math.isfinite(length_unit_cm) and length_unit_cm > 0):
        raise ValueError(f"`length_unit_cm` must be a finite number > 0, got {length_unit_cm}.")
    path = Path(path)
    if not path.exists():
        raise MotionFileNotFoundError(f"{path}: BVH file does not exist.")
    if path.is_dir():
        raise MotionFormatError(f"{path}: expected a BVH file, got a folder.")
    try:
        handle = open(path, "rb")
    except OSError as error:
        raise MotionFormatError(f"{path}: cannot read the BVH file: {error.strerror or error}.") from None
    with handle:
        try:
            return _read(path, handle, length_unit_cm, drop_first_frame, name)
        except OSError as error:
            raise MotionFormatError(f"{path}: cannot read the BVH file: {error.strerror or error}.") from None


def _read(path: Path, handle: BinaryIO, length_unit_cm: float, drop_first_frame: bool, name: str | None) -> Motion:
    reader = _Reader(path, handle, os.fstat(handle.fileno()).st_size)
    parser, _ = reader.hierarchy()
    joints = parser.joints
    num_frames, fps, frames_line = reader.motion_header()
    first_data_line = reader.line + 1
    num_channels = sum(len(joint.channels) for joint in joints)
    if num_channels == 0:
        raise reader.error(frames_line, "the HIERARCHY declares no channels, so there is no motion to read.")
    capacity = _frame_capacity(reader, joints, num_frames, num_channels, reader.size - handle.tell(), frames_line)
    block = _MotionBlock(reader, joints, max(capacity, 1))
    data_lines, last_data_line = _read_frames(reader, handle, block, capacity, num_channels, first_data_line)
    if data_lines != num_frames:
        span = f"lines {first_data_line}-{last_data_line}" if data_lines else f"after line {first_data_line - 1}"
        raise reader.error(
            frames_line, f"'Frames: {num_frames}' but the MOTION section has {data_lines} data lines ({span})."
        )
    start = 0
    if drop_first_frame:
        if num_frames < 2:
            raise reader.error(frames_line, "drop_first_frame needs 2 frames or more, got 1.")
        start = 1
    skeleton = _skeleton(parser, length_unit_cm)
    root = block.root[start:]
    root *= length_unit_cm
    translations = block.joint_translations(start, root, length_unit_cm)
    rotations = OwnedQuaternions(block.rotations[start:])  # normalized in place by Motion: no second copy
    del block
    return Motion(skeleton, fps, root, rotations, name=path.stem if name is None else name, translations=translations)


def _frame_capacity(reader: _Reader, joints: list, num_frames: int, num_channels: int, data_bytes: int,
                    frames_line: int) -> int:
    """How many frames to allocate: the 'Frames:' count, bounded by what the file's bytes can hold; refuses a
    skeleton whose tracks would take far more memory than the file, and sizes over the decode limits."""
    # A frame is C numbers, C - 1 separators and a newline: a file of B bytes holds at most (B + 1) / 2C frames, so
    # a 'Frames:' that claims more allocates only what the bytes can hold (and fails below naming the real count).
    capacity = min(num_frames, (data_bytes + 1) // (2 * num_channels))
    translated = len({j for j, joint in enumerate(joints) if j and any(k == "position" for k, _ in joint.channels)})
    # Rotations (32 bytes), a translation track in the file and in cm (2 x 24) where a joint below the root has
    # position channels: frames x joints checked against the bytes the file holds before anything is allocated.
    frame_joint_bytes = 32 + (48 if translated else 0)
    if capacity * len(joints) * frame_joint_bytes > 8 * data_bytes + (64 << 20):
        raise reader.error(
            frames_line,
            f"{len(joints)} joints but only {num_channels} channels: {capacity} frames would take "
            f"{capacity * len(joints) * frame_joint_bytes:,} bytes of tracks for a {reader.size:,}-byte file.",
        )
    # The decode limits too (--limit raises them), so that a reader and a decoder refuse the same sizes alike.
    check_motion_size(max(capacity, 1), len(joints), lambda message: reader.error(frames_line, message + "."))
    return capacity


def _read_frames(reader: _Reader, handle: BinaryIO, block: "_MotionBlock", capacity: int, num_channels: int,
                 first_data_line: int) -> tuple[int, int]:
    """Parse the MOTION section in chunks of whole lines into ``block`` (at most ``capacity`` rows).

    Returns ``(data lines, line number of the last one)``: every data line is counted, stored or not, so that a
    wrong 'Frames:' count is reported with the real one.
    """
    row, line, data_lines, last_data_line = 0, first_data_line, 0, 0
    carry = b""
    while True:
        read = handle.read(_CHUNK_BYTES)
        data = carry + read if carry else read
        if read:
            cut = data.rfind(b"\n")
            if cut < 0:
                carry = data
                continue
            chunk, carry = data[: cut + 1], data[cut + 1 :]
        else:
            chunk, carry = data, b""
        if chunk:
            values, line_numbers = _parse_block(reader, chunk, line, num_channels)
            line += chunk.count(b"\n")
            if len(line_numbers):
                last_data_line = int(line_numbers[-1])
            fits = max(0, min(len(values), capacity - row))
            if fits:
                block.store(values[:fits], row, line_numbers[:fits])
                row += fits
            data_lines += len(values)
        if not read:
            break
    return data_lines, last_data_line


def _skeleton(parser: _HierarchyParser, length_unit_cm: float) -> Skeleton:
    """The skeleton the HIERARCHY declares, offsets in cm."""
    joints = parser.joints
    return Skeleton(
        names=tuple(joint.name for joint in joints),
        parents=np.array([joint.parent for joint in joints]),
        offsets=np.array([joint.offset for joint in joints]) * length_unit_cm,
        channel_orders=tuple(_channel_order(joint) for joint in joints),
        end_site_parents=np.array(parser.end_parents, dtype=np.int64),
        end_site_offsets=np.array(parser.end_offsets, dtype=np.float64).reshape(-1, 3) * length_unit_cm,
    )


def _channel_order(joint: _Joint) -> str:
    """The joint's rotation axes in file order, missing axes appended (what :func:`write_bvh` writes back)."""
    axes = "".join(axis for kind, axis in joint.channels if kind == "rotation")
    return axes + "".join(a for a in "XYZ" if a not in axes)


def write_bvh(
    motion: Motion,
    path: str | Path,
    *,
    length_unit_cm: float = 1.0,
    overwrite: bool = False,
    decimals: int = 6,
    position_channels: str = "moving",
) -> Path:
    """Write ``motion`` as a BVH file.

    The root gets ``Xposition Yposition Zposition`` plus its rotation channels, and so does every joint that moves
    (:meth:`Motion.moving_joints <mocapbench.motion.Motion.moving_joints>`); every other joint three
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
        ``"moving"`` (default): position channels on the root and on the joints that move. ``"root"``: on the root
        only (a motion whose joints move is refused, naming the first). ``"all"``: ``CHANNELS 6 Xposition
        Yposition Zposition`` + rotations on every joint, a still joint holding its OFFSET in every frame (what
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
    MotionFormatError
        The motion scales a joint (BVH has no scale channel), or ``position_channels="root"`` for a motion whose
        joints move: one line naming the file, the joint and the frame.
    """
    if not (math.isfinite(length_unit_cm) and length_unit_cm > 0):
        raise ValueError(f"`length_unit_cm` must be a finite number > 0, got {length_unit_cm}.")
    if not 1 <= decimals <= 15:
        raise ValueError(f"`decimals` must be in [1, 15], got {decimals}.")
    if position_channels not in ("moving", "root", "all"):
        raise ValueError(f"`position_channels` must be 'moving', 'root' or 'all', got {position_channels!r}.")
    with_position = _joints_with_position_channels(motion, position_channels, Path(path))
    path = check_output(path, force=overwrite)
    skeleton = motion.skeleton
    order = _depth_first_order(skeleton.parents)
    children: list[list[int]] = [[] for _ in range(skeleton.num_joints)]
    for joint in range(1, skeleton.num_joints):
        children[int(skeleton.parents[joint])].append(joint)
    number = f"{{:.{decimals}f}}"
    lines = ["HIERARCHY"]

    # Depth first with an explicit stack (no recursion limit on deep chains): ("open", joint, depth) writes the
    # joint's header and schedules its children, its end sites and its closing brace.
    stack: list[tuple[str, int, int]] = [("open", 0, 0)]
    while stack:
        action, joint, depth = stack.pop()
        indent = "\t" * min(depth, 64)  # a chain thousands deep would otherwise write megabytes of tabs
        if action == "close":
            for end in np.flatnonzero(skeleton.end_site_parents == joint):
                end_offset = " ".join(number.format(v) for v in skeleton.end_site_offsets[end] / length_unit_cm)
                lines.extend(
                    [f"{indent}\tEnd Site", f"{indent}\t{{", f"{indent}\t\tOFFSET {end_offset}", f"{indent}\t}}"]
                )
            lines.append(f"{indent}}}")
            continue
        keyword = "ROOT" if joint == 0 else "JOINT"
        offset = " ".join(number.format(v) for v in skeleton.offsets[joint] / length_unit_cm)
        rotation_channels = " ".join(f"{axis}rotation" for axis in skeleton.channel_orders[joint])
        channels = f"6 Xposition Yposition Zposition {rotation_channels}" if with_position[joint] else f"3 {rotation_channels}"
        lines.extend([f"{indent}{keyword} {skeleton.names[joint]}", f"{indent}{{", f"{indent}\tOFFSET {offset}"])
        lines.append(f"{indent}\tCHANNELS {channels}")
        stack.append(("close", joint, depth))
        stack.extend(("open", child, depth + 1) for child in reversed(children[joint]))
    lines.extend(["MOTION", f"Frames: {motion.num_frames}", f"Frame Time: {1.0 / motion.fps:.10g}"])

    euler = np.empty((motion.num_frames, motion.num_joints, 3))
    for axes in sorted(set(skeleton.channel_orders)):
        members = [j for j in range(motion.num_joints) if skeleton.channel_orders[j] == axes]
        with warnings.catch_warnings():
            # At gimbal lock scipy sets the third angle to 0 and warns; the angles still give the same rotation.
            warnings.filterwarnings("ignore", message="Gimbal lock detected", category=UserWarning)
            euler[:, members] = Rotation.from_quat(motion.rotations[:, members]).as_euler(axes, degrees=True)
    # Per joint in file order: its translation (file units) where it has position channels, then its angles.
    translations = motion.local_translations()
    columns = []
    for joint in order:
        if with_position[joint]:
            columns.append(translations[:, joint] / length_unit_cm)
        columns.append(euler[:, joint])
    values = np.concatenate(columns, axis=1)
    row = " ".join([number] * values.shape[1])
    with open_output(path, "w", force=overwrite) as handle:
        handle.write("\n".join(lines) + "\n")
        for start in range(0, motion.num_frames, _WRITE_CHUNK_FRAMES):
            chunk = values[start : start + _WRITE_CHUNK_FRAMES].tolist()
            handle.write("".join(row.format(*frame) + "\n" for frame in chunk))
    return path


def _joints_with_position_channels(motion: Motion, position_channels: str, path: Path) -> np.ndarray:
    """Which joints :func:`write_bvh` gives position channels, (J,) bool; refuses what BVH cannot hold."""
    scaled = motion.scaled_joints()
    if scaled.size:
        joint = int(scaled[0])
        frame = int(np.flatnonzero(np.any(motion.scales[:, joint] != 1.0, axis=1))[0])
        raise MotionFormatError(
            f"{path}: joint {motion.skeleton.names[joint]!r} has scale {motion.scales[frame, joint].tolist()} at frame "
            f"{frame}; BVH has no scale channel (write glTF/GLB, which holds scale tracks)."
        )
    with_position = np.zeros(motion.num_joints, dtype=bool)
    with_position[0] = True
    if position_channels == "all":
        with_position[:] = True
    moving = motion.moving_joints()
    if position_channels == "root" and moving.size:
        joint = int(moving[0])
        frame = int(np.flatnonzero(np.any(motion.translations[:, joint] != motion.skeleton.offsets[joint], axis=1))[0])
        raise MotionFormatError(
            f"{path}: joint {motion.skeleton.names[joint]!r} moves (translation "
            f"{motion.translations[frame, joint].tolist()} cm at frame {frame}, OFFSET "
            f"{motion.skeleton.offsets[joint].tolist()}); position_channels='root' cannot hold it, use 'moving'."
        )
    with_position[moving] = True
    return with_position


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
