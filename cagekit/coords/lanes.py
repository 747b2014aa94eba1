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


#: bytes to which :func:`aligned_empty` aligns: one cache line, one AVX-512 register
ALIGNMENT = 64


@numba.njit(cache=True, inline="always")
def aligned_empty(shape: tuple) -> np.ndarray:
    """``np.empty(shape)`` of float64 starting on a 64-byte boundary (numba).

    numba aligns its arrays to 32 bytes only; a kernel whose loops vectorise at AVX-512's
    width then loads every other lane row across two cache lines, which made the MVC
    kernel up to 4x slower depending on where its scratch happened to land.
    """
    size = 1
    for s in shape:
        size *= s
    buffer = np.empty(size + ALIGNMENT // 8)
    skip = (ALIGNMENT - buffer.ctypes.data % ALIGNMENT) % ALIGNMENT // 8
    return buffer[skip:skip + size].reshape(shape)
