"""CPython's float arithmetic inside numba kernels, to the last bit.

A kernel that replaces scalar Python must round as Python did, or a closed loop flown by it
drifts away from the one flown before by the chaos of its own feedback. Most of :mod:`math`
is the C library's in both (``atan2``, ``asin``, ``sin``, ...) and Python's float ``%`` is what
numba compiles; two are not:

* ``math.hypot`` is CPython's own correctly rounded vector norm (``vector_norm`` of
  ``Modules/mathmodule.c``: lossless scaling by a power of two, exact squares, compensated sums
  and a differential correction of the square root), not the C library's ``hypot``, which differs
  in the last bit for about 0.6 % of arguments: :func:`py_hypot` is that algorithm.
* ``x ** 2.0`` is the C library's ``pow``, which LLVM folds into ``x * x`` when the exponent is
  a constant of the kernel (different in about 0.1 % of cases): :func:`py_pow` takes its
  exponent from memory, where no compiler can see it.
"""

from __future__ import annotations

import math

import numpy as np

from navsim.foundations.compiled import njit

_SPLIT = 134217729.0                  #: 2**27 + 1, Veltkamp's splitter for doubles
_DBL_MIN = 2.2250738585072014e-308    #: the smallest normal double


@njit(cache=True)
def _two_product(x: float, y: float) -> tuple:
    """``x * y`` and its exact rounding error (Dekker's product, for arguments below 2**996)."""
    z = x * y
    c = _SPLIT * x
    xh = c - (c - x)
    xl = x - xh
    c = _SPLIT * y
    yh = c - (c - y)
    yl = y - yh
    return z, ((xh * yh - z) + xh * yl + xl * yh) + xl * yl


@njit(cache=True)
def _norm2(a: float, b: float, big: float) -> float:
    """CPython's ``vector_norm`` of the two non-negative, finite ``a``, ``b`` (``big``: the larger)."""
    e = math.frexp(big)[1]
    scale = math.ldexp(1.0, -e)
    csum, frac1, frac2 = 1.0, 0.0, 0.0
    for v in (a, b):
        x = v * scale
        hi, lo = _two_product(x, x)
        s = csum + hi
        frac2 += (csum - s) + hi
        csum = s
        frac1 += lo
    h = math.sqrt(csum - 1.0 + (frac1 + frac2))
    hi, lo = _two_product(-h, h)
    s = csum + hi
    frac2 += (csum - s) + hi
    csum = s
    frac1 += lo
    x = csum - 1.0 + (frac1 + frac2)
    h += x / (2.0 * h)
    return h / scale


@njit(cache=True)
def py_hypot(x: float, y: float) -> float:
    """``math.hypot(x, y)`` as CPython computes it, bit for bit for normal and special
    arguments (below 2**-1024 CPython 3.11 scales otherwise: the last bit of such a norm may
    differ)."""
    a, b = abs(x), abs(y)
    big = 0.0
    for v in (a, b):                         # a NaN is never the larger
        if v > big:
            big = v
    if math.isinf(big):
        return big
    if math.isnan(a) or math.isnan(b):
        return math.nan
    if big == 0.0:
        return big
    if math.frexp(big)[1] < -1023:           # deep subnormal: lifted to normals first, as CPython does
        return _DBL_MIN * _norm2(a / _DBL_MIN, b / _DBL_MIN, big / _DBL_MIN)
    return _norm2(a, b, big)


@njit(cache=True)
def py_pow(x: float, exponent: np.ndarray) -> float:
    """``x ** exponent[0]`` as CPython computes it (the C library's ``pow``), the exponent read
    at run time so that no constant folding replaces the call."""
    return x ** exponent[0]


__all__ = ["py_hypot", "py_pow"]
