"""Decode memory (issue 17): a decoder needs at most twice what it returns plus a constant.

Measured with :mod:`tracemalloc` (which counts numpy's arrays), not with timings or the resident set, so the
figure is the same on every machine and under any load. "What it returns" is every decoded array: the positions
``(F, J, 3)``, and for the codecs that decode rotations the motion's quaternions ``(F, J, 4)`` and root positions
``(F, 3)`` too (:func:`mocapbench.fuzz.decoded_bytes`). The clip is 5,000 frames of :func:`memory_motion` (31
joints: 3.6 MB of positions, 8.8 MB with the motion), so a decoder that holds one more copy of its output, or a
whole-clip temporary as large as it, breaks the bound; the constant (1 MiB) is small beside the output.

The resident-memory table over every codec and long streams is ``python -m mocapbench.fuzz --memory-frames 60000``.
"""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench.codecs import CODECS, create
from mocapbench.codecs.baselines.codecs import RawZstdCodec
from mocapbench.fuzz import memory_motion, traced_decode_peak

FRAMES = 5000
CONSTANT_BYTES = 1 << 20

# The codecs held to the bound, with settings that keep the encode (and pga-ik's IK) short: the decoders'
# memory does not depend on them.
SETTINGS = {
    "raw-zstd": {},
    "quant-delta-zstd": {"step_cm": 0.1},
    "quant-rot-zstd": {"rotation_bits": 12},
    "svd": {"rank": 16},
    "mcb-linf": {"eps_cm": 0.5},
    "pga-ik": {"num_geodesics": 12, "lm_iterations": 1},
    "fourier-mlp-int": {"K": 4, "iterations_per_round": 1},
    "fourier-mlp-dct": {"K_max": 2, "iterations_per_round": 1, "threshold": 1e6, "threshold_unit": "cm"},
}
# fourier-mlp-* are registered only where torch is installed (the [neural] extra).
NAMES = [name for name in SETTINGS if name in CODECS]


@pytest.fixture(scope="module")
def motion():
    return memory_motion(FRAMES)


def _peak_and_output(codec, data: bytes) -> tuple[int, int]:
    codec.decode(data)  # a first decode: lazy imports and caches are loaded once, not per clip
    return traced_decode_peak(codec, data)


@pytest.mark.parametrize("name", NAMES)
def test_decode_memory_is_at_most_twice_the_output_plus_a_constant(name, motion):
    codec = create(name, **SETTINGS[name])
    data = codec.encode(motion)
    peak, output = _peak_and_output(codec, data)
    rotations = CODECS[name].codes_rotations
    assert output == FRAMES * 31 * (3 + (4 if rotations else 0)) * 8 + (FRAMES * 3 * 8 if rotations else 0)
    assert peak <= 2 * output + CONSTANT_BYTES, (
        f"{name}: decoding {FRAMES} frames peaked at {peak / 2**20:.2f} MB for {output / 2**20:.2f} MB of output "
        f"({peak / output:.2f}x; allowed 2x + {CONSTANT_BYTES / 2**20:.0f} MB)"
    )


class _CopyingRawZstd(RawZstdCodec):
    """raw-zstd with a decoder that keeps two whole-clip copies of its positions alive until it returns."""

    name = "raw-zstd"

    def decode_payload(self, header, payload):
        positions, motion = super().decode_payload(header, payload)
        copies = [positions.copy(), positions * 2.0]
        return positions + 0.0 * copies[0][0, 0, 0] + 0.0 * copies[1][0, 0, 0], motion


def test_the_bound_fails_a_decoder_that_copies_its_output(motion):
    """The measurement catches what the bound is for: a wasteful decoder peaks above 2x + the constant."""
    codec = _CopyingRawZstd()
    data = codec.encode(motion)
    peak, output = _peak_and_output(codec, data)
    assert peak > 2 * output + CONSTANT_BYTES
    honest_peak, honest_output = _peak_and_output(RawZstdCodec(), data)
    assert honest_output == output and honest_peak <= 2 * output + CONSTANT_BYTES
    np.testing.assert_array_equal(codec.decode(data).positions, RawZstdCodec().decode(data).positions)
