"""Streams written before the decoders were rewritten to hold less memory still decode to what they decoded to.

``tests/fixtures/golden_decode/`` holds streams and a summary of their decode made at commit 43518b0 (before the
rewrite; ``make_golden.py`` there says how): ``mcb-linf`` with the shipped model over two DCT windows and a
partial one, with a cut between two takes, and untrained (bone vectors, band tables) on a 15-joint rig; ``svd``,
``quant-rot-zstd`` and ``pga-ik``. The ``mcb-rot-*`` streams were made at e15a012 in payload format 3 (a cut with
the shell bound, a 15-joint rig, a spinning joint with principal axes and re-referenced segments), the
``mcb-rot4-*`` ones in format 4, the ``mcb-rot5-*`` ones in format 5 (a cut with the shell bound over chunks of
several segments, the spinning joint) and the ``mcb-rot6-*`` ones in format 6 (the native runtime's layout; also a
rig with short segments in long chunks): later formats must keep decoding them, in whole and in part. The sums and 256 sampled values of the positions (and quaternions)
must agree.

Tolerance: 1e-9 cm (1e-12 for quaternions). The block-wise decoders run the same arithmetic on every element
except the PCA inverse of ``mcb-linf``, a matrix product per DCT window instead of one over the clip, where the
BLAS kernel may round the last bit differently (measured 2e-13 cm); ``mcb-linf``'s refinement keeps a margin of
``1e-6 eps`` for such rounding, so the guaranteed bound of an old stream still holds. A misplaced coefficient, a
wrong step or class would move values by far more.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from mocapbench.codecs import create

GOLDEN = Path(__file__).resolve().parents[1] / "fixtures" / "golden_decode"
CASES = sorted(path.stem for path in GOLDEN.glob("*.mcb"))


def _check(summary: dict, array: np.ndarray, atol: float) -> None:
    flat = array.ravel()
    np.testing.assert_allclose(flat[summary["index"]], summary["values"], rtol=0, atol=atol)
    assert abs(float(flat.sum()) - summary["sum"]) <= atol * flat.size


def test_every_golden_case_is_there():
    assert CASES == ["mcb-linf-bands", "mcb-linf-cut", "mcb-linf-sphere", "mcb-linf-trained", "mcb-rot-cut-shell", "mcb-rot-rig",
                     "mcb-rot-spin", "mcb-rot4-cut-shell", "mcb-rot4-spin", "mcb-rot5-cut-shell", "mcb-rot5-spin",
                     "mcb-rot6-cut-shell", "mcb-rot6-rig", "mcb-rot6-spin",
                     "pga-ik", "quant-rot-zstd", "svd"]


@pytest.mark.parametrize("case", CASES)
def test_a_stream_written_before_decodes_as_it_did(case):
    data = (GOLDEN / f"{case}.mcb").read_bytes()
    record = json.loads((GOLDEN / f"{case}.json").read_text())
    assert hashlib.sha256(data).hexdigest() == record["sha256"]
    decoded = create(record["codec"]).decode(data)
    assert decoded.positions.shape[0] == record["frames"]
    _check(record["positions"], decoded.positions, 1e-9)
    if "rotations" in record:
        _check(record["rotations"], decoded.motion.rotations, 1e-12)


def test_the_comparison_sees_a_misplaced_coefficient():
    """One coefficient off by one step (a misplaced or misread value) moves the positions far past the tolerance."""
    import mocapbench.codecs.mcb_linf.codec as mcb_linf

    data = (GOLDEN / "mcb-linf-trained.mcb").read_bytes()
    record = json.loads((GOLDEN / "mcb-linf-trained.json").read_text())
    original = mcb_linf.base_positions_into

    def shifted(out, coefficients, *args):
        coefficients = coefficients.copy()
        coefficients[0] += 1
        return original(out, coefficients, *args)

    mcb_linf.base_positions_into = shifted
    try:
        positions = create("mcb-linf").decode(data).positions
    finally:
        mcb_linf.base_positions_into = original
    with pytest.raises(AssertionError):
        _check(record["positions"], positions, 1e-9)


@pytest.mark.parametrize("case", [c for c in CASES if c.startswith("mcb-rot")])
def test_an_old_mcb_rot_stream_decodes_in_part_as_in_whole(case):
    """Each stream stays in the format its name says (3 for ``mcb-rot-*``, so the cases above test the old
    layouts), and random access over it returns the frames of the whole decode (a frame, and a longer range)."""
    from mocapbench.codecs import container

    data = (GOLDEN / f"{case}.mcb").read_bytes()
    header, payload = container.unpack(data, "mcb-rot")
    assert payload[0] == {"rot": 3, "rot4": 4, "rot5": 5, "rot6": 6}[case.split("-")[1]]
    codec = create("mcb-rot")
    whole = codec.decode(data)
    third = header.num_frames // 3
    for start, stop in ((third, third + 150), (third + 70, third + 71)):
        part = codec.decode_frames(data, start, stop)
        np.testing.assert_allclose(part.positions, whole.positions[start:stop], rtol=0, atol=1e-9)
        np.testing.assert_allclose(part.motion.rotations, whole.motion.rotations[start:stop], rtol=0, atol=1e-12)
