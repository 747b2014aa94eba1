"""The angle between two unit vectors, fast and to full double precision, for numba kernels.

:func:`angle_from_sin_cos` computes ``atan2(s, c)`` for ``s >= 0`` with one division and a
polynomial instead of a libm call, the costliest part of the MVC edge term otherwise: it
reduces to ``y = min(s, |c|) / max(s, |c|)`` in ``[0, 1]`` (``atan(z) = pi/2 - atan(1/z)``),
then to ``[-tan(pi/8), tan(pi/8)]`` (``atan(y) = pi/4 + atan((lo - hi) / (lo + hi))``),
evaluates ``atan(y) = y * P(y**2)`` by Estrin's scheme with ``P`` of degree 11, fitted by
least squares on Chebyshev nodes against long double (:func:`fit_atan_polynomial`), and
undoes the reductions, with ``pi - angle`` for ``c < 0``. The tests check it against long
double over ``[0, pi]``; it is within a few units in the last place of ``np.arctan2``.
"""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np

from cagekit.typed import Floats

__all__ = ["angle_from_sin_cos", "half_angle_over_sin", "fit_atan_polynomial", "chebyshev_fit",
           "ATAN_COEFFICIENTS"]

_TAN_PI_8 = float(np.tan(np.pi / 8))


def chebyshev_fit(target: Callable[[np.ndarray], np.ndarray], top: float, degree: int,
                  nodes: int) -> Floats:
    """Coefficients ``c_i`` with ``sum_i c_i t**i ~= target(t)`` on ``0 <= t <= top``.

    Least squares on ``nodes`` Chebyshev nodes, refined four times with residuals in long
    double (the polynomials of this module and of :mod:`cagekit.coords.fastlog`).

    Parameters
    ----------
    target : callable
        ``target(t)``: (nodes,) long double -> (nodes,) long double.
    top : float
    degree : int
    nodes : int

    Returns
    -------
    (degree + 1,) float64
        Coefficients in increasing powers of ``t``.

    Examples
    --------
    >>> chebyshev_fit(lambda t: 1 + 2 * t, 0.5, 1, 8).round(12).tolist()
    [1.0, 2.0]
    """
    k = np.arange(nodes)
    t = (np.cos((2 * k + 1) * np.pi / (2 * nodes)) + 1) / 2 * top
    t_long = t.astype(np.longdouble)
    values = target(t_long)
    basis = np.vander(t / top, degree + 1, increasing=True)
    basis_long = np.vander(t_long / np.longdouble(top), degree + 1, increasing=True)
    coef = np.zeros(degree + 1)
    for _ in range(4):  # iterative refinement with long double residuals
        residual = (values - basis_long @ coef.astype(np.longdouble)).astype(np.float64)
        coef = coef + np.linalg.lstsq(basis, residual, rcond=None)[0]
    return coef / top ** np.arange(degree + 1)


def fit_atan_polynomial(degree: int = 11, nodes: int = 400) -> np.ndarray:
    """Coefficients ``a_i`` with ``atan(y) ~= y * sum_i a_i y**(2 i)`` on ``|y| <= tan(pi/8)``.

    Parameters
    ----------
    degree : int, default 11
        Degree of the polynomial in ``y**2``.
    nodes : int, default 400
        Chebyshev nodes of the least-squares fit (:func:`chebyshev_fit`).

    Returns
    -------
    (degree + 1,) float64
        Coefficients in increasing powers of ``y**2``.
    """
    def atan_over_y(t):
        y = np.sqrt(t)
        safe = np.where(y > 0, y, 1)
        return np.where(y > 0, np.arctan(safe) / safe, 1)

    return chebyshev_fit(atan_over_y, _TAN_PI_8**2, degree, nodes)


ATAN_COEFFICIENTS = fit_atan_polynomial()
_C = ATAN_COEFFICIENTS


@numba.njit(cache=True, error_model="numpy", inline="always")
def atan_small(y):
    """``atan(y)`` for ``|y| <= tan(pi/8)``: ``y * P(y**2)`` by Estrin's scheme.

    Estrin's scheme evaluates the degree-11 polynomial with a dependency chain of depth 5
    instead of Horner's 11, which is what limits speed once the loop is vectorised.
    """
    t = y * y
    t2 = t * t
    t4 = t2 * t2
    t8 = t4 * t4
    p01 = _C[0] + _C[1] * t
    p23 = _C[2] + _C[3] * t
    p45 = _C[4] + _C[5] * t
    p67 = _C[6] + _C[7] * t
    p89 = _C[8] + _C[9] * t
    p1011 = _C[10] + _C[11] * t
    q0 = p01 + p23 * t2
    q1 = p45 + p67 * t2
    q2 = p89 + p1011 * t2
    return y * ((q0 + q1 * t4) + q2 * t8)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _reduce(s, c):
    """Steps 1-2: numerator and denominator of the reduced argument, and the flags."""
    a = abs(c)
    lo = min(s, a)
    hi = max(s, a)
    big = lo > _TAN_PI_8 * hi
    num = lo - hi if big else lo
    den = lo + hi if big else hi
    return num, den, big, s > a, c < 0.0


@numba.njit(cache=True, error_model="numpy", inline="always")
def _unreduce(r, big, swapped, negative):
    """Step 4: undo the reductions of :func:`_reduce` on ``r = atan(num / den)``."""
    r = r + 0.7853981633974483 if big else r
    r = 1.5707963267948966 - r if swapped else r
    return 3.141592653589793 - r if negative else r


@numba.njit(cache=True, error_model="numpy", inline="always")
def angle_from_sin_cos(s: float, c: float) -> float:
    """``atan2(s, c)`` for ``s >= 0`` (an angle in ``[0, pi]``); 0 when both are 0.

    Written with selects only (no branches) so that loops calling it vectorise.

    Parameters
    ----------
    s : float
        Non-negative sine-like value (for example ``|u x v|``).
    c : float
        Cosine-like value (for example ``u . v``).

    Returns
    -------
    float
    """
    num, den, big, swapped, negative = _reduce(s, c)
    return _unreduce(atan_small(num / (den if den > 0.0 else 1.0)), big, swapped, negative)


@numba.njit(cache=True, error_model="numpy", inline="always")
def half_angle_over_sin(s: float, c: float) -> float:
    """``atan2(s, c) / (2 s)`` for ``s >= 0``, and 0 where ``s == 0``.

    The MVC edge term ``beta / 2 * (u x v) / |u x v|`` needs this ratio; computing it with
    one division (``1 / (den * s)`` serves both ``num / den`` and ``1 / s``) instead of two
    makes the MVC kernel about twice as fast.

    Parameters
    ----------
    s : float
        ``|u x v|`` (non-negative).
    c : float
        ``u . v``.

    Returns
    -------
    float
    """
    num, den, big, swapped, negative = _reduce(s, c)
    sd = den * s
    pos = sd > 0.0
    inv = 1.0 / (sd if pos else 1.0)
    r = _unreduce(atan_small(num * (s * inv)), big, swapped, negative)
    return 0.5 * r * (den * inv) if pos else 0.0
