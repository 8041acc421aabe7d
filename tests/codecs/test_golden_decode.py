"""Streams written before the decoders were rewritten to hold less memory still decode to what they decoded to.

``tests/fixtures/golden_decode/`` holds streams and a summary of their decode made at commit 43518b0 (before the
rewrite; ``make_golden.py`` there says how): ``mcb-linf`` with the shipped model over two DCT windows and a
partial one, with a cut between two takes, and untrained (bone vectors, band tables) on a 15-joint rig; ``svd``,
``quant-rot-zstd`` and ``pga-ik``. The sums and 256 sampled values of the positions (and quaternions) must agree.

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
    assert CASES == ["mcb-linf-bands", "mcb-linf-cut", "mcb-linf-trained", "pga-ik", "quant-rot-zstd", "svd"]


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
    import mocapbench.codecs.mcb_linf as mcb_linf

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
