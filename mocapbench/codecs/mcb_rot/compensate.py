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

from mocapbench.codecs.mcb_rot import quaternions as quat
from mocapbench.codecs.mcb_rot.axes import from_axes, to_axes
from mocapbench.codecs.mcb_rot.checks import global_quaternions, tree_levels
from mocapbench.codecs.mcb_rot.segments import forward, inverse
from mocapbench.codecs.mcb_rot.stream import StreamInfo, steps_of

__all__ = ["quantize", "quantize_compensated"]


def _quantize_into(info: StreamInfo, spectra, channels, dc, coefficients) -> dict[int, np.ndarray]:
    """Quantize per-segment spectra (n, len(channels)) into ``dc``/``coefficients`` at ``channels``; returns the
    dequantized spectra (segment -> (n, len(channels)))."""
    rounding = info.settings.rounding
    dequantized = {}
    for segment, spectrum in enumerate(spectra):
        steps = steps_of(info, len(spectrum))[:, channels]
        mean = np.floor(spectrum[0] / steps[0] + 0.5)
        scaled = spectrum[1:] / steps[1:]
        ac = np.sign(scaled) * np.floor(np.abs(scaled) + rounding)
        dc[segment, channels] = mean.astype(np.int64)
        coefficients[segment][:, channels] = ac.astype(np.int64)
        dequantized[segment] = np.concatenate([(mean * steps[0])[None], ac * steps[1:]])
    return dequantized


def _empty(info: StreamInfo) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    layout = info.layout
    dc = np.zeros((layout.num_segments, info.channels), dtype=np.int64)
    coefficients = {s: np.zeros((int(n) - 1, info.channels), dtype=np.int64) for s, n in enumerate(layout.lengths)}
    return dc, coefficients


def quantize(info: StreamInfo, spectra) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """Every channel quantized independently from its spectra (segment-ordered list of (n, C))."""
    dc, coefficients = _empty(info)
    _quantize_into(info, spectra, np.arange(info.channels), dc, coefficients)
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
        layout = info.layout
        dc, coefficients = _empty(info)
        axes = info.axes
        decoded = np.empty_like(self.globals)  # decoded global rotations, filled level by level
        for level, joints in enumerate(self.levels):
            if level == 0:
                targets = self.globals[:, joints]
            else:
                targets = quat.multiply(quat.conjugate(decoded[:, self.parents[joints]]), self.globals[:, joints])
            components = to_axes(self._rotvecs(info, targets, joints), axes[joints])  # (F, n, 3)
            channels = (3 + 3 * joints[:, None] + np.arange(3)).ravel()
            signal = components.reshape(len(components), -1)
            if level == 0:
                channels = np.concatenate([np.arange(3), channels])
                signal = np.concatenate([self.roots, signal], axis=1)
            dequantized = _quantize_into(info, forward(signal, layout), channels, dc, coefficients)
            # Each segment's signal (n, c) back from its spectrum (the DCT runs along the last axis).
            rebuilt = np.concatenate([inverse(dequantized[s].T).T for s in range(layout.num_segments)])
            if level == 0:
                rebuilt = rebuilt[:, 3:]
            local = self._rotations(info, from_axes(rebuilt.reshape(-1, len(joints), 3), axes[joints]), joints)
            decoded[:, joints] = local if level == 0 else quat.multiply(decoded[:, self.parents[joints]], local)
        return dc, coefficients
