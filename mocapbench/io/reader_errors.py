"""The last guard of a reader of hostile files: arithmetic on absurd values ends in one line, never a traceback.

A reader checks what it can name (a missing node, a count, a type) and says so in its own words. Some failures have
no single field to blame: static values near 1e308 that pass every per-value check overflow when the transforms
of a chain are multiplied, a product degenerates to a zero determinant, a quaternion built from them has no norm.
:func:`one_line_errors` wraps a reader so that such a failure, a ``ValueError`` or ``ArithmeticError`` raised by
numpy or scipy, becomes the reader's :class:`~mocapbench.motion.MotionFormatError` naming the file and the
problem, and runs it with numpy's floating-point warnings off (an overflow is refused as the non-finite result it
makes, not printed as a warning the user cannot act on).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import TypeVar

import numpy as np

from mocapbench.motion import MotionFormatError

__all__ = ["one_line_errors"]

Reader = TypeVar("Reader", bound=Callable)


def one_line_errors(read: Reader) -> Reader:
    """Decorate ``read(path, ...)`` as the module docstring says."""

    @functools.wraps(read)
    def guarded(path, *args, **kwargs):
        try:
            with np.errstate(all="ignore"):
                return read(path, *args, **kwargs)
        except MotionFormatError:
            raise
        except (ValueError, ArithmeticError) as problem:
            detail = str(problem).splitlines()[0].rstrip(".") if str(problem) else type(problem).__name__
            raise MotionFormatError(f"{path}: the file's values do not make a motion ({detail}).") from None

    return guarded  # type: ignore[return-value]
