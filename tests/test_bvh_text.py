"""BVH text edge cases: a UTF-8 byte-order mark is read, a control character in a joint name is refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mocapbench.io.bvh import read_bvh
from mocapbench.motion import MotionFormatError

CHAIN = Path(__file__).parent / "fixtures" / "chain3.bvh"


def test_a_utf8_byte_order_mark_is_accepted(tmp_path):
    path = tmp_path / "bom.bvh"
    path.write_bytes(b"\xef\xbb\xbf" + CHAIN.read_bytes())
    with_mark, without = read_bvh(path), read_bvh(CHAIN)
    assert with_mark.skeleton.names == without.skeleton.names
    np.testing.assert_array_equal(with_mark.positions(), without.positions())


def test_a_byte_order_mark_after_the_first_line_is_not_skipped(tmp_path):
    text = CHAIN.read_bytes()
    path = tmp_path / "late.bvh"
    path.write_bytes(text.replace(b"ROOT A", b"ROOT \xef\xbb\xbfA", 1))
    # Not a BOM there: a joint name that starts with U+FEFF is text, kept as it is.
    assert read_bvh(path).skeleton.names[0] == "\ufeffA"


@pytest.mark.parametrize("character", [b"\x00", b"\x01", b"\x1b", b"\x7f"])
def test_a_control_character_in_a_joint_name_is_refused_naming_the_line(tmp_path, character):
    text = CHAIN.read_bytes()
    assert b"JOINT B" in text
    path = tmp_path / "nul.bvh"
    path.write_bytes(text.replace(b"JOINT B", b"JOINT B" + character + b"x", 1))
    line = text[: text.index(b"JOINT B")].count(b"\n") + 1
    with pytest.raises(MotionFormatError, match=rf"line {line}: joint name .* holds a control character") as error:
        read_bvh(path)
    assert "\n" not in str(error.value)
