"""Generalised winding numbers of many points in a batch of cages, as a compiled kernel.

:func:`cagekit.cage.winding_numbers` (libigl) serves one cage; a training batch of the
learned mode asks the side of 8 x 1,024 points, each in its own batch item's cage, at every
step (:func:`cagekit_learn.enclosure.enclosure_loss`), where libigl's 2 ms a call was 11%
of the step. :func:`batched_winding_numbers` sums Van Oosterom and Strackee's solid angles,
``2 atan2(a . (b x c), |a||b||c| + (a . b)|c| + (b . c)|a| + (c . a)|b|)`` with ``a, b, c``
the face's corners relative to the point, over the faces, ``_LANES`` points at a time so
that LLVM vectorises the face loop (the ``atan2`` is :mod:`cagekit.coords.fastangle`'s
polynomial, within a few units in the last place), the batch's blocks in parallel.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import ArrayLike

from cagekit.coords.fastangle import angle_from_sin_cos
from cagekit.coords.lanes import aligned_empty, load_lanes
from cagekit.errors import InputError
from cagekit.typed import Floats

__all__ = ["batched_winding_numbers"]

_LANES = 32


@numba.njit(cache=True, error_model="numpy", fastmath={"contract"})
def _winding_lanes(P: np.ndarray, corners: np.ndarray, out: np.ndarray) -> None:
    """Winding numbers of the block ``P`` (3, L) in the triangles ``corners`` (m, 3, 3),
    written into ``out`` (L,)."""
    L = P.shape[1]
    for lane in range(L):
        out[lane] = 0.0
    for f in range(corners.shape[0]):
        ax0, ay0, az0 = corners[f, 0, 0], corners[f, 0, 1], corners[f, 0, 2]
        bx0, by0, bz0 = corners[f, 1, 0], corners[f, 1, 1], corners[f, 1, 2]
        cx0, cy0, cz0 = corners[f, 2, 0], corners[f, 2, 1], corners[f, 2, 2]
        for lane in range(L):
            px, py, pz = P[0, lane], P[1, lane], P[2, lane]
            ax, ay, az = ax0 - px, ay0 - py, az0 - pz
            bx, by, bz = bx0 - px, by0 - py, bz0 - pz
            cx, cy, cz = cx0 - px, cy0 - py, cz0 - pz
            la = np.sqrt(ax * ax + ay * ay + az * az)
            lb = np.sqrt(bx * bx + by * by + bz * bz)
            lc = np.sqrt(cx * cx + cy * cy + cz * cz)
            det = (ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz)
                   + az * (bx * cy - by * cx))
            den = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc
                   + (bx * cx + by * cy + bz * cz) * la + (cx * ax + cy * ay + cz * az) * lb)
            angle = angle_from_sin_cos(abs(det), den)
            out[lane] += angle if det >= 0.0 else -angle


@numba.njit(parallel=True, cache=True, error_model="numpy")
def _winding_kernel(points, corners, out):
    """``out[b, i]``: half the summed solid angle of ``points[b, i]`` in ``corners[b]``."""
    B, n = points.shape[0], points.shape[1]
    n_blocks = (n + _LANES - 1) // _LANES
    for job in numba.prange(B * n_blocks):
        b, blk = job // n_blocks, job % n_blocks
        P = aligned_empty((3, _LANES))
        acc = aligned_empty((_LANES,))
        start = blk * _LANES
        load_lanes(points[b], start, P)
        _winding_lanes(P, corners[b], acc)
        for i in range(start, min(start + _LANES, n)):
            out[b, i] = acc[i - start]


def batched_winding_numbers(points: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike) -> Floats:
    """Generalised winding number of each point in its batch item's cage (float64).

    Parameters
    ----------
    points : (B, n, 3) array_like of float
    cage_v : (B, k, 3) array_like of float
        One cage per batch item.
    cage_f : (m, 3) array_like of int
        Faces shared by the batch, outward-oriented.

    Returns
    -------
    (B, n) float64
        1 inside a closed cage, 0 outside, 1/2 on it (as libigl's ``winding_number``, to
        rounding: within 1e-12 of it away from the surface).

    Raises
    ------
    InputError
        Shapes that do not match, a face index out of range, or values not finite.

    Examples
    --------
    >>> from cagekit.cage import box_cage
    >>> v, f = box_cage()
    >>> w = batched_winding_numbers([[[0.0, 0, 0], [3, 0, 0]]], v[None], f)
    >>> w.round(9).tolist()
    [[1.0, 0.0]]
    """
    P = np.ascontiguousarray(points, dtype=np.float64)
    V = np.asarray(cage_v, dtype=np.float64)
    F = np.asarray(cage_f)
    if P.ndim != 3 or P.shape[2] != 3:
        raise InputError(f"points must have shape (B, n, 3), got {P.shape}")
    if V.ndim != 3 or V.shape[2] != 3 or V.shape[0] != P.shape[0]:
        raise InputError(f"cages must have shape ({P.shape[0]}, k, 3), got {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3 or not np.issubdtype(F.dtype, np.integer):
        raise InputError(f"cage faces must be an (m, 3) integer array, got {F.shape} {F.dtype}")
    if F.size and (F.min() < 0 or F.max() >= V.shape[1]):
        raise InputError(f"cage face indices must lie in [0, {V.shape[1]})")
    if not (np.isfinite(P).all() and np.isfinite(V).all()):
        raise InputError("points and cages must be finite")
    corners = np.ascontiguousarray(V[:, F])  # (B, m, 3, 3)
    out = np.empty(P.shape[:2])
    if P.shape[1]:
        _winding_kernel(P, corners, out)
    return out / (2.0 * np.pi)
