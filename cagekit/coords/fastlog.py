"""The logarithm of a ratio, fast and to full double precision, for numba kernels.

:func:`log_ratio` computes ``log(num / den)`` for positive normal ``num, den`` with one
division and a polynomial instead of a libm call (numba has no vector ``log`` without
SVML, so a loop calling ``np.log`` stays scalar). Both arguments are split into exponent
and mantissa by their bits (``2**a * u``, ``2**b * w`` with ``u, w`` in ``[1, 2)``); a
select doubles ``w`` or ``u`` so that ``u / w`` lies in ``[1/sqrt(2), sqrt(2)]``, where
``u - w`` is exact (Sterbenz); then ``log(u / w) = 2 atanh(z)`` with ``z = (u - w) / (u +
w)``, ``|z| <= 3 - 2 sqrt(2)``, evaluated as ``2 (z + z**3 Q(z**2))`` by Estrin's scheme with ``Q``
of degree 7, fitted by least squares on Chebyshev nodes against long double
(:func:`fit_log_polynomial`), and ``(a - b) log 2`` is added in two parts (Cody and
Waite). The tests check it against long double over the whole double range; it is within
about two units in the last place of the exact value. Everything is bit operations and
selects, no branches, so that loops calling it vectorise.
"""

from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from cagekit.coords.fastangle import chebyshev_fit

__all__ = ["log_ratio", "fit_log_polynomial", "LOG_COEFFICIENTS"]

_SQRT2 = float(np.sqrt(2.0))
_TOP = float((3.0 - 2.0 * np.sqrt(2.0)) ** 2)  # the largest z**2
#: log 2 in two parts (fdlibm's): the first has 32 significant bits, so that k * it is exact
_LN2_HI = 0.6931471803691238
_LN2_LO = 1.9082149293851713e-10
_MANTISSA = 0x000FFFFFFFFFFFFF
_ONE = 0x3FF0000000000000  # the bits of 1.0
_TWO52 = 0x4330000000000000  # the bits of 2**52
_TINY = float(np.finfo(np.float64).tiny)
_HUGE = float(np.finfo(np.float64).max)


def fit_log_polynomial(degree: int = 7, nodes: int = 400) -> np.ndarray:
    """Coefficients ``a_i`` with ``atanh(z) ~= z + z**3 * sum_i a_i z**(2 i)`` on ``z**2 <=
    (3 - 2 sqrt(2))**2``.

    Parameters
    ----------
    degree : int, default 7
        Degree of the polynomial in ``z**2``.
    nodes : int, default 400
        Chebyshev nodes of the least-squares fit (:func:`cagekit.coords.fastangle.chebyshev_fit`).

    Returns
    -------
    (degree + 1,) float64
        Coefficients in increasing powers of ``z**2``.
    """
    def atanh_series(t):
        z = np.sqrt(t)
        safe = np.where(z > 0, z, 1)
        return np.where(z > 0, (np.arctanh(safe) / safe - 1) / np.where(z > 0, t, 1),
                        np.longdouble(1) / 3)

    return chebyshev_fit(atanh_series, _TOP, degree, nodes)


LOG_COEFFICIENTS = fit_log_polynomial()
_C = LOG_COEFFICIENTS


@intrinsic
def _bits(typingctx, x):
    """The bits of a float64 as an int64 (a bit cast: free, and vectorisable)."""
    if x != types.float64:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return types.int64(types.float64), codegen


@intrinsic
def _from_bits(typingctx, b):
    """The float64 of these bits (the inverse of :func:`_bits`)."""
    if b != types.int64:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return types.float64(types.int64), codegen


@numba.njit(cache=True, error_model="numpy", inline="always")
def _split(x):
    """``x = 2**e * u`` for positive normal ``x``: ``e + 2**52`` (a float64: int64 to
    float64 conversion does not vectorise on AVX2) and ``u`` in ``[1, 2)``."""
    b = _bits(x)
    e = _from_bits((b >> 52) | _TWO52)
    return e, _from_bits((b & _MANTISSA) | _ONE)


@numba.njit(cache=True, error_model="numpy", inline="always")
def atanh_small(z):
    """``atanh(z)`` for ``z**2 <= (3 - 2 sqrt(2))**2``: ``z + z**3 Q(z**2)``, ``Q`` by
    Estrin's scheme (the correction is under 1% of ``z``: its rounding hardly shows)."""
    t = z * z
    t2 = t * t
    t4 = t2 * t2
    q0 = (_C[0] + _C[1] * t) + (_C[2] + _C[3] * t) * t2
    q1 = (_C[4] + _C[5] * t) + (_C[6] + _C[7] * t) * t2
    return z + z * (t * (q0 + q1 * t4))


@numba.njit(cache=True, error_model="numpy", inline="always")
def log_ratio(num: float, den: float) -> float:
    """``log(num / den)`` for positive normal floats; NaN where either is zero, negative,
    subnormal, infinite or NaN (the caller treats a non-finite result as a failure).

    Parameters
    ----------
    num, den : float

    Returns
    -------
    float
    """
    en, u = _split(num)
    ed, w = _split(den)
    k = en - ed  # exact: both are 2**52 plus a small integer
    up = u > _SQRT2 * w
    down = _SQRT2 * u < w
    w = w + w if up else w
    u = u + u if down else u
    k = k + 1.0 if up else (k - 1.0 if down else k)
    r = k * _LN2_HI + (k * _LN2_LO + 2.0 * atanh_small((u - w) / (u + w)))
    ok = (num >= _TINY) & (num <= _HUGE) & (den >= _TINY) & (den <= _HUGE)
    return r if ok else np.nan
