"""Mean value coordinates in float32 lanes, for ``mean_value_coordinates(dtype=np.float32)``.

The same vector form as :mod:`cagekit.coords.mvc` (edge terms ``beta_ij n_ij`` once per
undirected edge, Cramer's rule per face), computed in float32, ``_LANES32`` points at a time
so that a vector register holds twice as many points as the float64 kernel's; the angle is
``atan`` by a degree-5 polynomial (:data:`ATAN32_COEFFICIENTS`, fitted like
:mod:`cagekit.coords.fastangle`'s, within one unit in float32's last place).

float32 is not accurate everywhere MVC is defined, so every row carries an estimate of its
rounding error and the rows that cannot be trusted are left to the float64 kernel:

- each face's terms are off by about ``eps * max(1 / d) / |det|`` (``eps`` float32's
  machine epsilon, ``d`` the distances to the face's vertices, ``det`` the triple product
  of Cramer's rule, small near the plane of a face the point lies outside of), as the
  float32 torch layer estimates it (which counts only the faces whose plane's foot point
  lies outside the triangle, with a threshold of 1e-6);
- divided by the weight sum, the largest of these over the faces estimates the error of the
  row's normalised weights; rows above :data:`FLOAT32_TOLERANCE`, rows within
  :data:`FLOAT32_SNAP` of a face's plane (the switch-over zone of float32) and rows whose
  sum is not finite are flagged for float64.

The differences from each point to the cage's vertices, and its distances to the faces'
planes, are taken in float64 and then rounded, so that rounding the points themselves to
float32 costs nothing (on a 10 x 1 x 0.02 box it would cost 2e-5).

On star cages of 200, 216 and 1,000 faces the rows it accepted were at most 7e-6 from the
float64 weights (points inside, and 1e-2 to 3e-5 diagonals from edges and faces), with
1-8% of the points inside flagged. A mesh's vertices in its tight fitted cage are another
matter: float32 is off by up to 1e-3 there (the bundled source chair, 200 faces), and 62%
of its rows are flagged; outside a cage, or in a cage with a sliver face, float32 MVC is
off by O(1) and every row is flagged. float32 gains nothing in those cases
(docs/benchmarks.md, "MVC in float32 on request").

:func:`mvc_float32` returns the float32 rows and the flags;
:func:`cagekit.coords.mvc.mean_value_coordinates` recomputes the flagged rows in float64 and
rounds them to float32.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from cagekit.coords.fastangle import fit_atan_polynomial
from cagekit.coords.lanes import ALIGNMENT, aligned_empty, cross, load_lanes

__all__ = ["mvc_float32", "Float32Rows", "FLOAT32_TOLERANCE", "FLOAT32_SNAP",
           "ATAN32_COEFFICIENTS"]

#: rows whose estimated weight error exceeds this are recomputed in float64
FLOAT32_TOLERANCE = 5e-6
#: rows of points within this distance (in cage diagonals) of a face's plane go to float64
FLOAT32_SNAP = 1e-5

#: ``atan(y) ~= y * sum_i a_i y**(2 i)`` on ``|y| <= tan(pi/8)``, in float32
ATAN32_COEFFICIENTS = fit_atan_polynomial(degree=5).astype(np.float32)
_C = ATAN32_COEFFICIENTS

_F = np.float32
_ZERO = _F(0.0)
_HALF = _F(0.5)
_ONE = _F(1.0)
_NAN = _F(np.nan)
_TAN_PI_8 = _F(np.tan(np.pi / 8))
_PI_4 = _F(np.pi / 4)
_PI_2 = _F(np.pi / 2)
_PI = _F(np.pi)
_EPS = float(np.finfo(np.float32).eps)

#: points a block: 16 float32 a 512-bit register, interleaved 4 deep by LLVM
_LANES32 = 64


@numba.njit(cache=True, inline="always")
def _aligned_empty32(shape: tuple) -> np.ndarray:
    """``np.empty(shape, np.float32)`` starting on a 64-byte boundary (numba)."""
    size = 1
    for s in shape:
        size *= s
    buffer = np.empty(size + ALIGNMENT // 4, dtype=np.float32)
    skip = (ALIGNMENT - buffer.ctypes.data % ALIGNMENT) % ALIGNMENT // 4
    return buffer[skip:skip + size].reshape(shape)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _half_angle_over_sin32(s, c):
    """``atan2(s, c) / (2 s)`` for ``s >= 0`` in float32, 0 where ``s == 0`` (selects only;
    the float32 twin of :func:`cagekit.coords.fastangle.half_angle_over_sin`)."""
    a = abs(c)
    lo = min(s, a)
    hi = max(s, a)
    big = lo > _TAN_PI_8 * hi
    num = lo - hi if big else lo
    den = lo + hi if big else hi
    sd = den * s
    pos = sd > _ZERO
    inv = _ONE / (sd if pos else _ONE)
    y = num * (s * inv)
    t = y * y
    t2 = t * t
    p = (_C[0] + _C[1] * t) + (_C[2] + _C[3] * t) * t2 + (_C[4] + _C[5] * t) * (t2 * t2)
    r = y * p
    r = r + _PI_4 if big else r
    r = _PI_2 - r if s > a else r
    r = _PI - r if c < _ZERO else r
    return _HALF * r * (den * inv) if pos else _ZERO


@numba.njit(cache=True, error_model="numpy", fastmath={"contract"})
def _mvc_lanes32(P, cage_v, faces, edges, face_edges, face_signs, face_n, face_off, snap,
                 U, inv_d, G, X, lam, acc, amp):
    """Unnormalised MVC of ``_LANES32`` points in float32, and each lane's error factor.

    As :func:`cagekit.coords.mvc._mvc_lanes` in its first pass (a point within ``snap`` of a
    face's plane gets NaN weights). ``P`` (3, L), ``cage_v``, ``face_n`` and ``face_off``
    are float64 (differences and plane distances are taken in float64, then rounded);
    everything else is float32. ``amp`` (L,) receives
    ``max_f max(1 / d) / |det|`` over the faces (module docstring).
    """
    k = cage_v.shape[0]
    for j in range(k):
        for lane in range(_LANES32):
            ax = _F(cage_v[j, 0] - P[0, lane])
            ay = _F(cage_v[j, 1] - P[1, lane])
            az = _F(cage_v[j, 2] - P[2, lane])
            inv = _ONE / np.sqrt(ax * ax + ay * ay + az * az)
            inv_d[j, lane] = inv
            U[0, j, lane] = ax * inv
            U[1, j, lane] = ay * inv
            U[2, j, lane] = az * inv
    for e in range(edges.shape[0]):
        a = edges[e, 0]
        b = edges[e, 1]
        for lane in range(_LANES32):
            cx, cy, cz = cross(U[0, a, lane], U[1, a, lane], U[2, a, lane],
                               U[0, b, lane], U[1, b, lane], U[2, b, lane])
            s = np.sqrt(cx * cx + cy * cy + cz * cz)
            c = U[0, a, lane] * U[0, b, lane] + U[1, a, lane] * U[1, b, lane] \
                + U[2, a, lane] * U[2, b, lane]
            g = _half_angle_over_sin32(s, c)
            X[0, e, lane] = cx
            X[1, e, lane] = cy
            X[2, e, lane] = cz
            G[0, e, lane] = g * cx
            G[1, e, lane] = g * cy
            G[2, e, lane] = g * cz
    for lane in range(_LANES32):
        amp[lane] = _ZERO
    for f in range(faces.shape[0]):
        ia = faces[f, 0]
        ib = faces[f, 1]
        ic = faces[f, 2]
        nx = face_n[f, 0]
        ny = face_n[f, 1]
        nz = face_n[f, 2]
        off = face_off[f]
        e_ab = face_edges[f, 0]
        e_bc = face_edges[f, 1]
        e_ca = face_edges[f, 2]
        s_ab = face_signs[f, 0]
        s_bc = face_signs[f, 1]
        s_ca = face_signs[f, 2]
        for lane in range(_LANES32):
            h = _F(P[0, lane] * nx + P[1, lane] * ny + P[2, lane] * nz - off)
            mx = s_ab * G[0, e_ab, lane] + s_bc * G[0, e_bc, lane] + s_ca * G[0, e_ca, lane]
            my = s_ab * G[1, e_ab, lane] + s_bc * G[1, e_bc, lane] + s_ca * G[1, e_ca, lane]
            mz = s_ab * G[2, e_ab, lane] + s_bc * G[2, e_bc, lane] + s_ca * G[2, e_ca, lane]
            xa0 = s_bc * X[0, e_bc, lane]
            xa1 = s_bc * X[1, e_bc, lane]
            xa2 = s_bc * X[2, e_bc, lane]
            det = U[0, ia, lane] * xa0 + U[1, ia, lane] * xa1 + U[2, ia, lane] * xa2
            ok = abs(h) > snap and det != _ZERO
            inv = _ONE / (det if ok else _ONE)
            inv = inv if ok else _NAN
            da = inv_d[ia, lane]
            db = inv_d[ib, lane]
            dc = inv_d[ic, lane]
            lam[0, f, lane] = (mx * xa0 + my * xa1 + mz * xa2) * inv * da
            lam[1, f, lane] = s_ca * (mx * X[0, e_ca, lane] + my * X[1, e_ca, lane]
                                      + mz * X[2, e_ca, lane]) * inv * db
            lam[2, f, lane] = s_ab * (mx * X[0, e_ab, lane] + my * X[1, e_ab, lane]
                                      + mz * X[2, e_ab, lane]) * inv * dc
            factor = max(da, max(db, dc)) * abs(inv)
            amp[lane] = max(amp[lane], factor)
    for j in range(k):
        for lane in range(_LANES32):
            acc[j, lane] = _ZERO
    for f in range(faces.shape[0]):
        for r in range(3):
            j = faces[f, r]
            for lane in range(_LANES32):
                acc[j, lane] += lam[r, f, lane]


@numba.njit(parallel=True, cache=True, error_model="numpy")
def _mvc32_kernel(points, cage_v, faces, edges, face_edges, face_signs, face_n, face_off,
                  snap, tolerance, n_chunks, out, flagged):
    """float32 MVC of all points into ``out`` (n, k); ``flagged`` (n,) marks the rows left
    for float64 (their ``out`` rows are not written)."""
    n = points.shape[0]
    k = cage_v.shape[0]
    e = edges.shape[0]
    m = faces.shape[0]
    L = _LANES32
    n_blocks = (n + L - 1) // L
    n_chunks = max(1, min(n_blocks, n_chunks))
    for chunk in numba.prange(n_chunks):
        P = aligned_empty((3, L))
        U = _aligned_empty32((3, k, L))
        inv_d = _aligned_empty32((k, L))
        G = _aligned_empty32((3, e, L))
        X = _aligned_empty32((3, e, L))
        lam = _aligned_empty32((3, m, L))
        acc = _aligned_empty32((k, L))
        amp = _aligned_empty32((L,))
        for blk in range(chunk * n_blocks // n_chunks, (chunk + 1) * n_blocks // n_chunks):
            start = blk * L
            stop = min(start + L, n)
            load_lanes(points, start, P)
            _mvc_lanes32(P, cage_v, faces, edges, face_edges, face_signs, face_n, face_off,
                         snap, U, inv_d, G, X, lam, acc, amp)
            for i in range(start, stop):
                lane = i - start
                total = 0.0
                for j in range(k):
                    total += float(acc[j, lane])
                error = _EPS * float(amp[lane]) / abs(total)
                if not (error <= tolerance):  # NaN (the switch-over zone) included
                    flagged[i] = True
                    continue
                flagged[i] = False
                inv = 1.0 / total
                for j in range(k):
                    out[i, j] = float(acc[j, lane]) * inv


class Float32Rows(NamedTuple):
    """What :func:`mvc_float32` returns."""

    weights: np.ndarray  #: (n, k) float32; rows not flagged are normalised MVC
    flagged: np.ndarray  #: (n,) bool; rows to recompute in float64 (their weights unset)


def mvc_float32(points: np.ndarray, cage_v: np.ndarray, faces: np.ndarray, edges: np.ndarray,
                face_edges: np.ndarray, face_signs: np.ndarray, face_n: np.ndarray,
                face_off: np.ndarray, n_chunks: int,
                snap: float = FLOAT32_SNAP) -> Float32Rows:
    """float32 MVC of points in the cage's normalised frame, with the rows float32 cannot
    resolve flagged.

    Parameters
    ----------
    points : (n, 3) float64
        Points relative to the cage's bounding-box centre, in its diagonals.
    cage_v : (k, 3) float64
        Cage vertices in the same frame.
    faces : (m, 3) int64
    edges, face_edges, face_signs
        The cage's topology (:func:`cagekit.cage.cage_topology`).
    face_n : (m, 3) float64
        Unit face normals.
    face_off : (m,) float64
        ``face_n . v`` of each face's first vertex.
    n_chunks : int
        Parallel chunks.
    snap : float, default :data:`FLOAT32_SNAP`
        Rows of points within this distance of a face's plane are flagged; a smaller value
        is raised to :data:`FLOAT32_SNAP`.

    Returns
    -------
    Float32Rows
    """
    f32 = np.float32
    n, k = len(points), len(cage_v)
    out = np.empty((n, k), dtype=f32)
    flagged = np.empty(n, dtype=np.bool_)
    if n:
        _mvc32_kernel(np.ascontiguousarray(points, dtype=np.float64),
                      np.ascontiguousarray(cage_v, dtype=np.float64),
                      np.ascontiguousarray(faces),
                      edges, face_edges, np.ascontiguousarray(face_signs, dtype=f32),
                      np.ascontiguousarray(face_n),
                      np.ascontiguousarray(face_off), f32(max(snap, FLOAT32_SNAP)),
                      FLOAT32_TOLERANCE, n_chunks, out, flagged)
    return Float32Rows(out, flagged)
