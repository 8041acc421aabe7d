"""The Examples sections of the entropy modules run as written."""

from __future__ import annotations

import doctest
import importlib

import pytest

# By module path: ``mocapbench.entropy.quantize`` as an attribute is the function that the package re-exports.
MODULES = ["mocapbench.entropy.bitio", "mocapbench.entropy.huffman", "mocapbench.entropy.quantize"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0
    assert result.failed == 0
