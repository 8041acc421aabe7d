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


def _quantize_into(info: StreamInfo, signal: np.ndarray, channels: np.ndarray, dc, coefficients,
                   steps: dict[int, np.ndarray]) -> np.ndarray:
    """Quantize the signal (F, len(channels)) of ``channels`` segment by segment into ``dc``/``coefficients``;
    returns the signal rebuilt from the quantized spectra (F, len(channels)), as the decoder will see it.

    The segments of one length go through one DCT, one quantization and one inverse DCT (a batched call each).
    ``steps``: length -> (n, C) :func:`steps_of` of the attempt.
    """
    layout = info.layout
    rounding = info.settings.rounding
    rebuilt = np.empty_like(signal)
    for length, segments in layout.groups.items():
        index = layout.starts[segments, None] + np.arange(length)  # (S_g, n)
        spectra = scipy.fft.dct(signal[index], axis=1, norm="ortho")  # (S_g, n, c)
        step = steps[length][:, channels]  # (n, c)
        mean = np.floor(spectra[:, 0] / step[0] + 0.5)
        scaled = spectra[:, 1:] / step[1:]
        ac = np.sign(scaled) * np.floor(np.abs(scaled) + rounding)
        dc[segments[:, None], channels] = mean.astype(np.int64)
        quantized = ac.astype(np.int64)
        for i, segment in enumerate(segments.tolist()):
            coefficients[segment][:, channels] = quantized[i]
        spectra[:, 0] = mean * step[0]
        np.multiply(ac, step[1:], out=spectra[:, 1:])
        rebuilt[index] = scipy.fft.idct(spectra, axis=1, norm="ortho", overwrite_x=True)
    return rebuilt


def _onto(rotvecs: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """:func:`.axes.to_axes` (components (F, n, 3) of rotation vectors (F, n, 3) on axes (n, 3, 3)), the same bits in
    three multiply-adds instead of a (F, n, 3, 3) product summed over a middle axis (3x faster)."""
    return rotvecs[..., 0, None] * axes[:, 0] + rotvecs[..., 1, None] * axes[:, 1] + rotvecs[..., 2, None] * axes[:, 2]


def _off(components: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """:func:`.axes.from_axes`, the same bits, as :func:`_onto`."""
    return (components[..., 0, None] * axes[:, :, 0] + components[..., 1, None] * axes[:, :, 1]
            + components[..., 2, None] * axes[:, :, 2])


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


class Compensator:
    """One motion's fixed state for :meth:`quantize` (the original global rotations, the segment signs)."""

    def __init__(self, info: StreamInfo, quats: np.ndarray, roots: np.ndarray) -> None:
        """``quats`` (F, J, 4) sign-continuous original local rotations, ``roots`` (F, 3) cm."""
        self.roots = roots
        self.parents = info.skeleton.parents
        self.globals = global_quaternions(quats, self.parents)
        self.levels = tree_levels(self.parents)
        layout = info.layout
        self.segment_of = np.repeat(np.arange(layout.num_segments), layout.lengths)
        self.middle = layout.starts + layout.lengths // 2

    def _rotvecs(self, info: StreamInfo, targets: np.ndarray, joints: np.ndarray) -> np.ndarray:
        """Rotation vectors (F, n, 3) of target local rotations (F, n, 4) of ``joints``, as the stream codes them:
        signs per segment (middle frame w >= 0), re-referenced segments relative to their reference."""
        layout = info.layout
        flips = np.where(targets[self.middle, :, 3] < 0, -1.0, 1.0)  # (S, n)
        targets = targets * flips[self.segment_of][..., None]
        rotvecs = quat.log_map(targets)
        column = {int(j): i for i, j in enumerate(joints)}
        for (segment, joint), reference in info.overrides.items():
            if joint in column:
                frames = slice(layout.starts[segment], layout.starts[segment] + layout.lengths[segment])
                relative = quat.multiply(quat.conjugate(reference), targets[frames, column[joint]])
                relative = relative * np.where(relative[len(relative) // 2, 3] < 0, -1.0, 1.0)
                rotvecs[frames, column[joint]] = quat.log_map(relative)
        return rotvecs

    def _rotations(self, info: StreamInfo, rotvecs: np.ndarray, joints: np.ndarray) -> np.ndarray:
        """Local rotations (F, n, 4) the decoder rebuilds from rotation vectors (F, n, 3) of ``joints``."""
        layout = info.layout
        quats = quat.exp_map(rotvecs)
        column = {int(j): i for i, j in enumerate(joints)}
        for (segment, joint), reference in info.overrides.items():
            if joint in column:
                frames = slice(layout.starts[segment], layout.starts[segment] + layout.lengths[segment])
                quats[frames, column[joint]] = quat.multiply(reference, quats[frames, column[joint]])
        return quats

    def quantize(self, info: StreamInfo) -> tuple[np.ndarray, dict[int, np.ndarray]]:
        """The base layer, joints level by level down the tree, each coding its compensated target."""
        dc, coefficients = _empty(info)
        steps = _steps(info)
        axes = info.axes
        decoded = np.empty_like(self.globals)  # decoded global rotations, filled level by level
        for level, joints in enumerate(self.levels):
            if level == 0:
                targets = self.globals[:, joints]
            else:
                targets = quat.multiply(quat.conjugate(decoded[:, self.parents[joints]]), self.globals[:, joints])
            components = _onto(self._rotvecs(info, targets, joints), axes[joints])  # (F, n, 3)
            channels = (3 + 3 * joints[:, None] + np.arange(3)).ravel()
            signal = components.reshape(len(components), -1)
            if level == 0:
                channels = np.concatenate([np.arange(3), channels])
                signal = np.concatenate([self.roots, signal], axis=1)
            rebuilt = _quantize_into(info, signal, channels, dc, coefficients, steps)
            if level == 0:
                rebuilt = rebuilt[:, 3:]
            local = self._rotations(info, _off(rebuilt.reshape(-1, len(joints), 3), axes[joints]), joints)
            decoded[:, joints] = local if level == 0 else quat.multiply(decoded[:, self.parents[joints]], local)
        return dc, coefficients
