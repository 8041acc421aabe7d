"""Quantizing the base layer of ``mcb-rot``, optionally with each joint compensating its ancestors' errors.

Coded independently, the local rotations' quantization errors add up down the hierarchy: an error at the hips turns
the whole body, and the hand's position error sums the errors of the eight joints above it, each times its chain
length to the hand. *Compensated* quantization codes the joints in tree-depth order and gives each joint, as its
target, the local rotation that puts its **global** rotation where the original's is, given its parent's global
rotation as the decoder will rebuild it: ``conj(Ĝ_parent) G_joint``. The decoded global rotation of every joint then
carries only its own quantization error, and a joint's position error sums one error per bone of its chain (bone
length, not chain length), several times less at the extremities for the same steps. The decoder is unchanged: it
decodes local rotations as always (the targets differ, not the format).

Both functions return ``dc`` (S, C) int64 (quantized segment means) and ``coefficients`` (segment -> (n - 1, C) int64
AC coefficients), quantized as :func:`mocapbench.codecs.mcb_rot.stream.steps_of` says (dead zone ``rounding``).
"""

from __future__ import annotations

import numpy as np
import scipy  # scipy.fft loads on first use (see mocapbench.lazy_imports)

from mocapbench.codecs.mcb_rot import quaternions as quat
from mocapbench.codecs.mcb_rot.checks import global_quaternions, tree_levels
from mocapbench.codecs.mcb_rot.stream import StreamInfo, steps_of

__all__ = ["quantize", "Compensator"]


def _steps(info: StreamInfo) -> dict[int, np.ndarray]:
    """length -> (n, C) quantization steps of the segments of that length."""
    return {length: steps_of(info, length) for length in info.layout.groups}


def _empty(info: StreamInfo) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    layout = info.layout
    dc = np.zeros((layout.num_segments, info.channels), dtype=np.int64)
    coefficients = {s: np.zeros((int(n) - 1, info.channels), dtype=np.int64) for s, n in enumerate(layout.lengths)}
    return dc, coefficients


def quantize(info: StreamInfo, spectra) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """Every channel quantized independently from its spectra (segment-ordered list of (n, C))."""
    dc, coefficients = _empty(info)
    steps = _steps(info)
    rounding = info.settings.rounding
    for segment, spectrum in enumerate(spectra):
        step = steps[len(spectrum)]
        dc[segment] = np.floor(spectrum[0] / step[0] + 0.5).astype(np.int64)
        scaled = spectrum[1:] / step[1:]
        coefficients[segment][...] = (np.sign(scaled) * np.floor(np.abs(scaled) + rounding)).astype(np.int64)
    return dc, coefficients


#: Segments up to this many frames are transformed by a product with their DCT matrix (one BLAS call, no FFT
#: planning: the DCT of a short segment costs its call more than its arithmetic); longer ones by scipy's DCT.
_MATRIX_FRAMES = 160


def _dct_matrix(length: int) -> np.ndarray:
    """(n, n) orthonormal DCT-II matrix: ``spectrum = M @ signal``, ``signal = M.T @ spectrum``."""
    return scipy.fft.dct(np.eye(length), axis=0, norm="ortho")


class _Transform:
    """The segments' DCT along the frame axis (1) of component-major arrays (a, F, ...), grouped by length: a
    contiguous run of equal-length segments is a reshape, a length-1 segment is its own transform (the identity).
    The quantizer only predicts what the decoder will rebuild (to compensate the children), so the transform need
    not match the decoder's bit for bit: a short segment's is a matrix product."""

    def __init__(self, layout) -> None:
        self.groups = []
        for length, segments in layout.groups.items():
            index = layout.starts[segments, None] + np.arange(length)  # (S_g, n)
            first = int(index[0, 0])
            contiguous = bool(np.array_equal(index.ravel(), np.arange(first, first + index.size)))
            where = slice(first, first + index.size) if contiguous else index.ravel()
            matrix = _dct_matrix(length) if 1 < length <= _MATRIX_FRAMES else None
            self.groups.append((length, len(segments), where, matrix))

    def apply(self, x: np.ndarray, inverse: bool) -> np.ndarray:
        """DCT-II (or its inverse) of every segment of ``x`` (a, F, ...) along axis 1, orthonormal: (a, F, ...)."""
        out = np.empty_like(x)
        a, rest = x.shape[0], x.shape[2:]
        for length, count, where, matrix in self.groups:
            if length == 1:
                out[:, where] = x[:, where]
            elif matrix is not None:
                part = x[:, where].reshape(a * count, length, -1)
                out[:, where] = np.matmul(matrix.T if inverse else matrix, part).reshape((a, count * length) + rest)
            else:
                transform = scipy.fft.idct if inverse else scipy.fft.dct
                part = x[:, where].reshape((a, count, length) + rest)
                out[:, where] = transform(part, axis=2, norm="ortho", overwrite_x=True).reshape(
                    (a, count * length) + rest)
        return out


class _Level:
    """One tree depth's fixed state: its joints, their parents, coded slots (slot 0 the root translation, 1 + j
    joint j), the original global rotations (4, F, n), the columns on principal axes, the re-referenced segments."""

    def __init__(self, joints, parents, has_children, globals_, axes, overrides, layout, root: bool) -> None:
        self.joints = joints
        self.parents = parents[joints]
        self.slots = np.concatenate([[0], joints + 1]) if root else joints + 1
        self.globals = np.ascontiguousarray(globals_[:, :, joints])
        turned = np.flatnonzero(np.any(axes[joints] != np.eye(3), axis=(1, 2)))
        self.turned = turned
        self.axes = axes[joints[turned]]  # (t, 3, 3)
        self.inner = np.flatnonzero(has_children[joints])  # columns whose decoded rotation a child needs
        self.all_inner = len(self.inner) == len(joints)
        column = {int(j): i for i, j in enumerate(joints)}
        self.overrides = []
        for (segment, joint), reference in overrides.items():
            if joint in column:
                frames = slice(int(layout.starts[segment]), int(layout.starts[segment] + layout.lengths[segment]))
                self.overrides.append((frames, column[joint], reference))


def _log_map(q: np.ndarray) -> np.ndarray:
    """:func:`.quaternions.log_map` of component-major quaternions (4, ...): (3, ...), the same bits."""
    x, y, z, w = q
    norm = np.sqrt(x * x + y * y + z * z)
    angle = 2.0 * np.arctan2(norm, w)
    small = norm < 1e-9
    if small.any():
        scale = np.where(small, 2.0 / np.where(small, w, 1.0), angle / np.where(small, 1.0, norm))
    else:
        scale = np.divide(angle, norm, out=angle)
    return q[:3] * scale


def _exp_map(r: np.ndarray) -> np.ndarray:
    """:func:`.quaternions.exp_map` of component-major rotation vectors (3, ...): (4, ...), the same bits."""
    x, y, z = r
    angle = np.sqrt(x * x + y * y + z * z)
    half = 0.5 * angle
    small = angle < 1e-6
    out = np.empty((4,) + r.shape[1:])
    if small.any():
        scale = np.where(small, 0.5 - angle * angle / 48.0, np.sin(half) / np.where(small, 1.0, angle))
    else:
        scale = np.sin(half)
        scale /= angle
    np.multiply(r, scale, out=out[:3])
    np.cos(half, out=out[3])
    return out


def _product(a: np.ndarray, b: np.ndarray, conjugate_a: bool = False) -> np.ndarray:
    """:func:`.quaternions.multiply` (of ``conjugate(a)`` and ``b`` with ``conjugate_a``) on component-major
    quaternions (4, ...): (4, ...), the same bits (``x + (-y)`` is ``x - y`` in IEEE arithmetic)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    if conjugate_a:
        out[0] = aw * bx - ax * bw - ay * bz + az * by
        out[1] = aw * by + ax * bz - ay * bw - az * bx
        out[2] = aw * bz - ax * by + ay * bx - az * bw
        out[3] = aw * bw + ax * bx + ay * by + az * bz
    else:
        out[0] = aw * bx + ax * bw + ay * bz - az * by
        out[1] = aw * by - ax * bz + ay * bw + az * bx
        out[2] = aw * bz + ax * by - ay * bx + az * bw
        out[3] = aw * bw - ax * bx - ay * by - az * bz
    return out


def _turn(r: np.ndarray, axes: np.ndarray, off: bool) -> np.ndarray:
    """Components on the axes (t, 3, 3) of rotation vectors (3, ..., t) (:func:`.axes.to_axes`, as three
    multiply-adds per component instead of a product summed over a middle axis), or back (:func:`.axes.from_axes`)."""
    if off:
        return np.stack([r[0] * axes[:, i, 0] + r[1] * axes[:, i, 1] + r[2] * axes[:, i, 2] for i in range(3)])
    return np.stack([r[0] * axes[:, 0, i] + r[1] * axes[:, 1, i] + r[2] * axes[:, 2, i] for i in range(3)])


class Compensator:
    """One motion's fixed state for :meth:`quantize` (the original global rotations per tree depth, the segments'
    transform, the level-0 spectra, which no attempt changes).

    Component-major (4, F, n) arrays throughout (a quaternion product is 28 numpy calls on contiguous rows, with
    no stacking); the quaternion arithmetic mirrors :mod:`.quaternions` operation for operation, so the streams are
    the ones the joint-major code wrote.
    """

    def __init__(self, info: StreamInfo, quats: np.ndarray, roots: np.ndarray) -> None:
        """``quats`` (F, J, 4) sign-continuous original local rotations, ``roots`` (F, 3) cm."""
        layout = info.layout
        parents = info.skeleton.parents
        num_joints = len(parents)
        globals_ = np.ascontiguousarray(np.moveaxis(global_quaternions(quats, parents), -1, 0))  # (4, F, J)
        has_children = np.zeros(num_joints, dtype=bool)
        has_children[parents[1:]] = True
        self.segment_of = np.repeat(np.arange(layout.num_segments), layout.lengths)
        self.middle = layout.starts + layout.lengths // 2
        self.starts = layout.starts
        self.layout = layout
        self.transform = _Transform(layout)
        axes = info.axes
        self.levels = [_Level(joints, parents, has_children, globals_, axes, info.overrides, layout, level == 0)
                       for level, joints in enumerate(tree_levels(parents))]
        # Level 0 (the root translation and rotation) codes the same signal in every attempt: its spectra once.
        root = self.levels[0]
        rotvecs = self._rotvecs(root, root.globals[:, :, None].copy())  # (3, F, 1, n)
        self.root_spectra = self.transform.apply(np.concatenate([roots.T[:, :, None, None], rotvecs], axis=3), False)

    def _rotvecs(self, level: _Level, targets: np.ndarray) -> np.ndarray:
        """Rotation vectors (3, F, K, n) on the joints' axes of target local rotations (4, F, K, n) (overwritten),
        as the stream codes them: signs per segment (middle frame w >= 0), re-referenced segments relative to
        their reference."""
        flips = np.where(targets[3, self.middle] < 0, -1.0, 1.0)  # (S, K, n)
        targets *= flips if len(flips) == 1 else flips[self.segment_of]
        rotvecs = _log_map(targets)
        for frames, column, reference in level.overrides:
            relative = quat.multiply(quat.conjugate(reference), np.moveaxis(targets[:, frames, :, column], 0, -1))
            relative = relative * np.where(relative[len(relative) // 2, ..., 3:] < 0, -1.0, 1.0)
            rotvecs[:, frames, :, column] = np.moveaxis(quat.log_map(relative), -1, 0)
        if len(level.turned):
            rotvecs[..., level.turned] = _turn(rotvecs[..., level.turned], level.axes, off=False)
        return rotvecs

    def _rotations(self, level: _Level, rebuilt: np.ndarray, columns) -> np.ndarray:
        """Local rotations (4, F, K, n) the decoder rebuilds from rotation vectors (3, F, K, n) on the axes of the
        joints of ``level`` at ``columns`` (all when None; overwritten)."""
        turned = level.turned if columns is None else np.flatnonzero(np.isin(columns, level.turned))
        if len(turned):
            axes = level.axes if columns is None else level.axes[np.searchsorted(level.turned, columns[turned])]
            rebuilt[..., turned] = _turn(rebuilt[..., turned], axes, off=True)
        quats = _exp_map(rebuilt)
        for frames, column, reference in level.overrides:
            if columns is not None:
                if column not in columns:
                    continue
                column = int(np.flatnonzero(columns == column)[0])
            quats[:, frames, :, column] = np.moveaxis(
                quat.multiply(reference, np.moveaxis(quats[:, frames, :, column], 0, -1)), -1, 0)
        return quats

    def quantize(self, info: StreamInfo) -> tuple[np.ndarray, dict[int, np.ndarray]]:
        """The base layer, joints level by level down the tree, each coding its compensated target."""
        return self.quantize_many([info])[0]

    def quantize_many(self, infos: list[StreamInfo]) -> list[tuple[np.ndarray, dict[int, np.ndarray]]]:
        """:meth:`quantize` of several attempts (their settings differ in multiplier and slope only), side by side
        along an attempts axis K: each numpy call does the work of K attempts (a short clip's quantization costs
        its numpy calls more than their arithmetic). Their coefficients are views of one (F, K, C) array, kept as
        ``last_quantized`` (row ``start`` of a segment: its mean, the next rows its AC coefficients), which
        :func:`.rate.base_bytes_many` reads."""
        layout = self.layout
        num_frames = layout.num_frames
        count = len(infos)
        budgets = infos[0].budgets
        # Steps as steps_of computes them: (multiplier x channel step) x row factor, the DC row's its own.
        factor = np.empty((num_frames, count))
        slot_steps = np.empty((count, len(budgets.base_rad) + 1))
        for k, info in enumerate(infos):
            settings = info.settings
            for length, segments in layout.groups.items():
                row = 1.0 + settings.slope * np.arange(length) / length
                row[0] = np.sqrt(length / settings.segment_frames)
                factor[(layout.starts[segments, None] + np.arange(length)).ravel(), k] = np.tile(row, len(segments))
            slot_steps[k] = settings.multiplier * np.concatenate([[budgets.root_cm], budgets.base_rad])
        rounding = infos[0].settings.rounding
        quantized = np.zeros((num_frames, count, infos[0].channels), dtype=np.int64)
        by_slot = quantized.reshape(num_frames, count, -1, 3)
        decoded = np.empty((4, num_frames, count, infos[0].skeleton.num_joints))
        starts = self.starts
        for number, level in enumerate(self.levels):
            if number == 0:
                spectra = self.root_spectra
            else:
                targets = _product(decoded[..., level.parents], level.globals[:, :, None], conjugate_a=True)
                spectra = self.transform.apply(self._rotvecs(level, targets), False)
            step = factor[:, :, None] * slot_steps[:, level.slots]  # (F, K, n)
            scaled = spectra / step
            values = np.sign(scaled)
            values *= np.floor(np.abs(scaled) + rounding)
            values[:, starts] = np.floor(scaled[:, starts] + 0.5)
            by_slot[:, :, level.slots] = values.transpose(1, 2, 3, 0)
            if number == 0:
                values, step = values[..., 1:], step[..., 1:]  # the root translation is not rebuilt
            if not len(level.inner):
                continue  # no joint below this depth
            columns = None
            if not level.all_inner:
                columns = level.inner
                values, step = values[..., columns], step[..., columns]
            values *= step
            local = self._rotations(level, self.transform.apply(values, True), columns)
            joints, parents = (level.joints, level.parents) if columns is None else (level.joints[columns],
                                                                                   level.parents[columns])
            decoded[..., joints] = local if number == 0 else _product(decoded[..., parents], local)
        results = []
        for k in range(count):
            dc = quantized[starts, k]
            coefficients = {s: quantized[start + 1 : start + n, k] for s, (start, n) in
                            enumerate(zip(starts.tolist(), layout.lengths.tolist()))}
            results.append((dc, coefficients))
        self.last_quantized = quantized
        return results
