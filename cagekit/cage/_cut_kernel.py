"""numba kernel of the cage-input cut test's broad phase
(:func:`cagekit.cage.fitting._cut_faces`)."""

from __future__ import annotations

from cagekit._numba_setup import configure as _configure_numba

_configure_numba()  # before any kernel is defined (numba's cache folder, threading layer)

import numba  # noqa: E402
import numpy as np  # noqa: E402

#: slack of the plane test, relative to the coordinates' size
SLACK = 1e-9


@numba.njit(cache=True, inline="always")
def _one_side(A, B):
    """Whether B's three corners lie strictly on one side of A's plane (beyond the slack)."""
    e1x, e1y, e1z = A[1, 0] - A[0, 0], A[1, 1] - A[0, 1], A[1, 2] - A[0, 2]
    e2x, e2y, e2z = A[2, 0] - A[0, 0], A[2, 1] - A[0, 1], A[2, 2] - A[0, 2]
    nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
    size = 0.0
    for k in range(3):
        for c in range(3):
            size = max(size, abs(A[k, c]), abs(B[k, c] - A[0, c]))
    slack = SLACK * np.sqrt(nx * nx + ny * ny + nz * nz) * 2.0 * size
    above = 0
    below = 0
    for k in range(3):
        d = (nx * (B[k, 0] - A[0, 0]) + ny * (B[k, 1] - A[0, 1])
             + nz * (B[k, 2] - A[0, 2]))
        if d > slack:
            above += 1
        elif d < -slack:
            below += 1
    return above == 3 or below == 3


@numba.njit(cache=True)
def candidate_pairs(C: np.ndarray, T: np.ndarray,
                    skip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(cage faces, input faces) of the pairs that may intersect; see
    :func:`cagekit.cage.fitting._candidate_pairs`. ``C`` (c, 3, 3), ``T`` (m, 3, 3)."""
    c = C.shape[0]
    lo = np.empty((c, 3))
    hi = np.empty((c, 3))
    for j in range(c):
        for d in range(3):
            lo[j, d] = min(C[j, 0, d], C[j, 1, d], C[j, 2, d])
            hi[j, d] = max(C[j, 0, d], C[j, 1, d], C[j, 2, d])
    cj = []
    ti = []
    for i in range(T.shape[0]):
        t = T[i]
        tlx, thx = min(t[0, 0], t[1, 0], t[2, 0]), max(t[0, 0], t[1, 0], t[2, 0])
        tly, thy = min(t[0, 1], t[1, 1], t[2, 1]), max(t[0, 1], t[1, 1], t[2, 1])
        tlz, thz = min(t[0, 2], t[1, 2], t[2, 2]), max(t[0, 2], t[1, 2], t[2, 2])
        for j in range(c):
            if (skip[j] or tlx > hi[j, 0] or thx < lo[j, 0] or tly > hi[j, 1]
                    or thy < lo[j, 1] or tlz > hi[j, 2] or thz < lo[j, 2]):
                continue
            if _one_side(C[j], t) or _one_side(t, C[j]):
                continue
            cj.append(j)
            ti.append(i)
    return np.array(cj, dtype=np.int64), np.array(ti, dtype=np.int64)
