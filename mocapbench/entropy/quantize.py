"""Uniform scalar quantizers: step-based (unbounded integer indices) and range-based (fixed bit width).

Both are vectorized over numpy arrays of any shape and deterministic, so that an encoder and a decoder that agree on
``step`` (or on ``bits``, ``lo`` and ``hi``) reconstruct exactly the same values.

Error guarantee
---------------
For finite input, ``|x - dequantize(quantize(x, step), step)| <= step / 2`` up to floating-point rounding of the
division and the multiplication (a few ulp of ``x`` and of ``step``); the same holds for the range quantizer with
``step = (hi - lo) / (2**bits - 1)``. The tests check the bound with a tolerance of ``4 * spacing(|x|)``.

The quantizers only produce integers; laying them out as bits is the job of :mod:`mocapbench.entropy.bitio` and
:mod:`mocapbench.entropy.huffman`. A codec that stores ``lo``/``hi`` must store them exactly (float64) or quantize
with the values it stores (e.g. after rounding them to float32), otherwise the decoder uses a different grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "MAX_RANGE_BITS",
    "MIN_RANGE_BITS",
    "RangeQuantizer",
    "dequantize",
    "dequantize_range",
    "quantize",
    "quantize_range",
]

#: Smallest and largest bit width of the range quantizer. 24 bits keep every index exactly representable in float32
#: as well as float64, and the indices fit in ``uint32``.
MIN_RANGE_BITS = 1
MAX_RANGE_BITS = 24

# |values / step| must stay below this so that the rounded index fits in int64 with room for zigzag coding.
_MAX_INDEX_MAGNITUDE = 2.0**62


def _as_finite_float_array(values, name: str) -> np.ndarray:
    """Return ``values`` as a float64 array; raise ValueError naming ``name`` if it holds NaN/inf or non-numbers."""
    try:
        arr = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"`{name}` must be an array of real numbers, got {type(values).__name__}: {exc}") from None
    if arr.size and not np.isfinite(arr).all():
        bad = np.argwhere(~np.isfinite(arr))[0]
        where = tuple(int(i) for i in bad)
        raise ValueError(f"`{name}` must be finite, found {float(arr[where])} at index {where}")
    return arr


def _check_step(step) -> float:
    """Validate a quantization step: a finite real number > 0."""
    try:
        value = float(step)
    except (TypeError, ValueError):
        raise ValueError(f"`step` must be a finite number > 0, got {step!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"`step` must be a finite number > 0, got {step!r}")
    return value


def _check_bits(bits) -> int:
    """Validate a range-quantizer bit width: an int in [MIN_RANGE_BITS, MAX_RANGE_BITS]."""
    if isinstance(bits, bool) or not isinstance(bits, (int, np.integer)):
        raise ValueError(f"`bits` must be an int in [{MIN_RANGE_BITS}, {MAX_RANGE_BITS}], got {bits!r}")
    if not MIN_RANGE_BITS <= bits <= MAX_RANGE_BITS:
        raise ValueError(f"`bits` must be in [{MIN_RANGE_BITS}, {MAX_RANGE_BITS}], got {bits}")
    return int(bits)


def quantize(values, step) -> np.ndarray:
    """Quantize to the nearest multiple of ``step`` (uniform mid-tread quantizer).

    Parameters
    ----------
    values : array_like of float, any shape, unit U
        Finite values.
    step : float, unit U
        Quantization step, finite and > 0.

    Returns
    -------
    indices : ndarray of int64, same shape as ``values``
        ``np.rint(values / step)``; ties round to even.

    Raises
    ------
    ValueError
        If ``step`` is not finite and > 0, if ``values`` holds NaN/inf, or if an index would not fit in
        ``|index| < 2**62`` (``step`` far too small for the values).

    Examples
    --------
    >>> quantize([0.24, -0.26, 1.0], 0.5)
    array([ 0, -1,  2])
    """
    step = _check_step(step)
    arr = _as_finite_float_array(values, "values")
    scaled = arr / step
    if scaled.size and np.abs(scaled).max() >= _MAX_INDEX_MAGNITUDE:
        raise ValueError(
            f"`step` {step!r} is too small for `values` with max |value| {float(np.abs(arr).max())!r}: "
            f"indices must stay below 2**62 in magnitude"
        )
    return np.rint(scaled).astype(np.int64)


def dequantize(indices, step) -> np.ndarray:
    """Reconstruct values from :func:`quantize` indices.

    Parameters
    ----------
    indices : array_like of int, any shape
    step : float, unit U
        The step used by :func:`quantize`, finite and > 0.

    Returns
    -------
    values : ndarray of float64, same shape as ``indices``, unit U
        ``indices * step``.

    Raises
    ------
    ValueError
        If ``step`` is not finite and > 0 or ``indices`` are not integers.
    """
    step = _check_step(step)
    arr = np.asarray(indices)
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"`indices` must be integers, got dtype {arr.dtype}")
    return arr.astype(np.float64) * step


@dataclass(frozen=True)
class RangeQuantizer:
    """Map ``[lo, hi]`` uniformly onto the integers ``0 .. 2**bits - 1``.

    ``lo`` maps to 0 and ``hi`` to ``2**bits - 1``, both reconstructed exactly. When ``lo == hi`` (constant input)
    the step is 0, every index is 0 and the reconstruction is exact.

    Parameters
    ----------
    bits : int
        Bit width, in [1, 24].
    lo, hi : float, unit U
        Finite range with ``lo <= hi`` and ``hi - lo`` finite.
    """

    bits: int
    lo: float
    hi: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "bits", _check_bits(self.bits))
        for name in ("lo", "hi"):
            value = getattr(self, name)
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"`{name}` must be a finite number, got {value!r}") from None
            if not math.isfinite(value):
                raise ValueError(f"`{name}` must be a finite number, got {value!r}")
            object.__setattr__(self, name, value)
        if self.lo > self.hi:
            raise ValueError(f"`lo` must be <= `hi`, got lo={self.lo!r} > hi={self.hi!r}")
        if not math.isfinite(self.hi - self.lo):
            raise ValueError(f"range hi - lo must be finite, got lo={self.lo!r}, hi={self.hi!r}")

    @classmethod
    def from_values(cls, values, bits: int) -> RangeQuantizer:
        """The quantizer whose range is ``[min(values), max(values)]``.

        Raises ValueError if ``values`` is empty or holds NaN/inf.
        """
        arr = _as_finite_float_array(values, "values")
        if arr.size == 0:
            raise ValueError("`values` must not be empty when the range is taken from it")
        return cls(bits, float(arr.min()), float(arr.max()))

    @property
    def max_index(self) -> int:
        """Largest index, ``2**bits - 1``."""
        return (1 << self.bits) - 1

    @property
    def step(self) -> float:
        """Distance between reconstruction levels, ``(hi - lo) / (2**bits - 1)``; 0 when ``lo == hi``."""
        return (self.hi - self.lo) / self.max_index

    def quantize(self, values) -> np.ndarray:
        """Indices of the nearest levels.

        Parameters
        ----------
        values : array_like of float, any shape, unit U
            Finite values inside ``[lo, hi]``.

        Returns
        -------
        indices : ndarray of uint32, same shape, in ``[0, 2**bits - 1]``

        Raises
        ------
        ValueError
            If a value is NaN/inf or outside ``[lo, hi]``.
        """
        arr = _as_finite_float_array(values, "values")
        if arr.size and (arr.min() < self.lo or arr.max() > self.hi):
            raise ValueError(
                f"`values` must lie in [lo, hi] = [{self.lo!r}, {self.hi!r}], "
                f"got min {float(arr.min())!r} and max {float(arr.max())!r}"
            )
        step = self.step
        if step == 0.0:
            return np.zeros(arr.shape, dtype=np.uint32)
        # Clip guards the last half-ulp of rounding at the ends of the range.
        scaled = np.rint((arr - self.lo) / step)
        return np.clip(scaled, 0, self.max_index).astype(np.uint32)

    def dequantize(self, indices) -> np.ndarray:
        """Reconstruction levels of ``indices``.

        Parameters
        ----------
        indices : array_like of int, any shape, in ``[0, 2**bits - 1]``

        Returns
        -------
        values : ndarray of float64, same shape, unit U
            ``lo + indices * step``; index ``2**bits - 1`` gives exactly ``hi``.

        Raises
        ------
        ValueError
            If ``indices`` are not integers or lie outside ``[0, 2**bits - 1]``.
        """
        arr = np.asarray(indices)
        if arr.size == 0:
            return np.zeros(arr.shape, dtype=np.float64)
        if not np.issubdtype(arr.dtype, np.integer):
            raise ValueError(f"`indices` must be integers, got dtype {arr.dtype}")
        if arr.min() < 0 or arr.max() > self.max_index:
            raise ValueError(
                f"`indices` must lie in [0, {self.max_index}] for bits={self.bits}, "
                f"got min {arr.min()} and max {arr.max()}"
            )
        out = self.lo + arr.astype(np.float64) * self.step
        # lo + max_index * step can miss hi by an ulp; pin the top level so that hi round-trips exactly.
        return np.where(arr == self.max_index, self.hi, out)


def quantize_range(values, bits: int) -> tuple[np.ndarray, float, float]:
    """Quantize ``values`` onto ``bits``-bit indices spanning their own ``[min, max]``.

    Parameters
    ----------
    values : array_like of float, any shape, unit U
        Finite, non-empty.
    bits : int
        Bit width, in [1, 24].

    Returns
    -------
    indices : ndarray of uint32, same shape as ``values``, in ``[0, 2**bits - 1]``
    lo, hi : float, unit U
        The range; store both (float64) for :func:`dequantize_range`.

    Raises
    ------
    ValueError
        If ``bits`` is outside [1, 24] or ``values`` is empty or holds NaN/inf.
    """
    quantizer = RangeQuantizer.from_values(values, _check_bits(bits))
    return quantizer.quantize(values), quantizer.lo, quantizer.hi


def dequantize_range(indices, bits: int, lo: float, hi: float) -> np.ndarray:
    """Inverse of :func:`quantize_range`: ``lo + indices * (hi - lo) / (2**bits - 1)``, float64, unit U."""
    return RangeQuantizer(bits, lo, hi).dequantize(indices)
