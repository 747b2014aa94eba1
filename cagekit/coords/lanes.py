"""Blocks of points for the vectorised coordinate kernels (:mod:`.mvc`, :mod:`.mvc_grad`,
:mod:`~.coords.green`).

The kernels evaluate a block of points at a time, one point per lane, so that LLVM
vectorises their loops over the lanes; this loads a block, and holds the small vector
algebra their lane loops share.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["load_lanes", "cross"]


@numba.njit(cache=True, inline="always")
def load_lanes(points: np.ndarray, start: int, P: np.ndarray) -> None:
    """Copy ``points[start:start + L]`` into the columns of ``P`` (3, L), repeating the last
    point for the lanes past its end (their results are not read)."""
    last = points.shape[0] - 1
    for lane in range(P.shape[1]):
        src = min(start + lane, last)
        P[0, lane] = points[src, 0]
        P[1, lane] = points[src, 1]
        P[2, lane] = points[src, 2]


@numba.njit(cache=True, error_model="numpy", inline="always")
def cross(ax: float, ay: float, az: float, bx: float, by: float,
          bz: float) -> tuple[float, float, float]:
    """The cross product ``a x b`` of two vectors given by their components (numba)."""
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
