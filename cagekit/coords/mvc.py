"""Mean value coordinates for closed triangle cages (Ju, Schaefer & Warren 2005).

This is the paper's vector form (its section 3.2), not the closed "c_i, s_i" form of its
pseudo-code and of VTK, which loses digits to cancellation close to the cage. With ``u_j``
the unit vectors from the point to the cage vertices, each undirected edge's term
``beta_ij n_ij`` (angles by :mod:`cagekit.coords.fastangle`) is computed once and enters its
two faces with opposite signs, so the faces' mean vectors sum to zero to rounding; each
face's ``lambda`` comes from Cramer's rule with the same cross products, ``w_j = sum_T
lambda_j^T / d_j``, and the coordinates are ``w / sum(w)``. Linear precision then holds to
about ``eps * D`` (``D`` the cage's bounding-box diagonal) down to the switch-over: points
within ``snap * D`` (:data:`DEFAULT_SNAP`) of a vertex, an edge or a face get MVC's limit
values there, and a face whose plane passes that close to a point outside it is skipped.
Single weights of a point at distance ``h`` from the plane of a face it lies outside of are
off by about ``eps * D / h``, in a direction that keeps partition of unity and linear
precision. Far out MVC is ill-conditioned whatever the formula: from ``10 D`` to ``20 D``
from the cage's centre rows blend into the affine extension (:data:`FAR_BLEND`,
:func:`affine_extension_weights`), used alone beyond; points whose coordinates would
overflow are refused; an unresolvable weight sum falls back to the closest cage point. The
numba kernel runs ``_LANES`` points at a time, branch-free so that LLVM vectorises it, and
redoes alone points near a face's plane; scratch is ``O(k + e + m)`` per chunk. With
``dtype=np.float32`` the weights come from float32 lanes (:mod:`cagekit.coords.mvc32`),
and the rows whose estimated rounding error is too large for float32 from this kernel. See
docs/architecture.md.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np
from numpy.typing import ArrayLike, DTypeLike, NDArray

from cagekit.cage import (
    CageTopology,
    cage_topology,
    check_cage,
    distance_in_diagonals,
    winding_numbers,
)
from cagekit.coords.fastangle import angle_from_sin_cos, half_angle_over_sin
from cagekit.coords.lanes import aligned_empty, cross, load_lanes
from cagekit.coords.mvc32 import mvc_float32
from cagekit.errors import InputError
from cagekit.geometry.frame import bounding_box_diagonal
from cagekit.typed import Floats

__all__ = ["mean_value_coordinates", "mvc_and_winding", "WeightsAndWinding",
           "affine_extension_weights", "affine_extension_matrix",
           "closest_point_weights", "DEFAULT_SNAP", "FAR_BLEND"]

DEFAULT_SNAP = 1e-13

#: distances from the centre of the cage's bounding box, in bounding-box diagonals, between
#: which MVC is blended into the affine extension; beyond the second, the extension alone
FAR_BLEND = (10.0, 20.0)


@numba.njit(cache=True, error_model="numpy")
def closest_point_weights(x: np.ndarray, cage_v: np.ndarray, faces: np.ndarray,
                          row: np.ndarray) -> None:
    """Barycentric weights of the cage point closest to ``x``, written into ``row`` (numba).

    The fallback for a point whose MVC weight sum cannot be resolved; the torch twin uses it
    too. ``x`` (3,) float64, ``cage_v`` (k, 3) float64, ``faces`` (m, 3) int64, ``row``
    (k,) float64 (overwritten: zero but for the closest face's three vertices).
    """
    best = np.inf
    best_f = 0
    best_b = np.zeros(3)
    for f in range(faces.shape[0]):
        a = cage_v[faces[f, 0]]
        b = cage_v[faces[f, 1]]
        c = cage_v[faces[f, 2]]
        # Closest point on triangle (Ericson, Real-Time Collision Detection, 5.1.5).
        ab = b - a
        ac = c - a
        ap = x - a
        d1 = ab @ ap
        d2 = ac @ ap
        bp = x - b
        d3 = ab @ bp
        d4 = ac @ bp
        cp = x - c
        d5 = ab @ cp
        d6 = ac @ cp
        va = d3 * d6 - d5 * d4
        vb = d5 * d2 - d1 * d6
        vc = d1 * d4 - d3 * d2
        if d1 <= 0.0 and d2 <= 0.0:
            bw = (1.0, 0.0, 0.0)
        elif d3 >= 0.0 and d4 <= d3:
            bw = (0.0, 1.0, 0.0)
        elif d6 >= 0.0 and d5 <= d6:
            bw = (0.0, 0.0, 1.0)
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            t = d1 / (d1 - d3)
            bw = (1.0 - t, t, 0.0)
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            t = d2 / (d2 - d6)
            bw = (1.0 - t, 0.0, t)
        elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
            t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
            bw = (0.0, 1.0 - t, t)
        else:
            s = 1.0 / (va + vb + vc)
            bw = (va * s, vb * s, 1.0 - (va + vb) * s)
        q = bw[0] * a + bw[1] * b + bw[2] * c
        dist = np.sum((q - x) ** 2)
        if dist < best:
            best = dist
            best_f = f
            best_b[0], best_b[1], best_b[2] = bw
    row[:] = 0.0
    for i in range(3):
        row[faces[best_f, i]] += best_b[i]


@numba.njit(cache=True, error_model="numpy")
def _snap_weights(x, cage_v, faces, edges, face_n, face_off, snap, row):
    """Exact limit weights if ``x`` is within ``snap`` of a vertex, an edge or a face.

    Writes ``row`` and returns True in that case (a vertex's unit weight, linear
    interpolation along the edge, barycentric coordinates on the face); returns False and
    leaves ``row`` alone otherwise.
    """
    for j in range(cage_v.shape[0]):
        d = cage_v[j] - x
        if np.sqrt(d @ d) <= snap:
            row[:] = 0.0
            row[j] = 1.0
            return True
    for e in range(edges.shape[0]):
        a = cage_v[edges[e, 0]]
        ab = cage_v[edges[e, 1]] - a
        t = min(max((x - a) @ ab / (ab @ ab), 0.0), 1.0)
        q = a + t * ab - x
        if np.sqrt(q @ q) <= snap:
            row[:] = 0.0
            row[edges[e, 0]] = 1.0 - t
            row[edges[e, 1]] = t
            return True
    for f in range(faces.shape[0]):
        n = face_n[f]
        if abs(x @ n - face_off[f]) > snap:
            continue
        # in the face's plane: twice the signed areas of the sub-triangles opposite each
        # vertex, measured along the face normal
        bary = np.zeros(3)
        for r in range(3):
            p0 = cage_v[faces[f, (r + 1) % 3]] - x
            p1 = cage_v[faces[f, (r + 2) % 3]] - x
            c0, c1, c2 = cross(p0[0], p0[1], p0[2], p1[0], p1[1], p1[2])
            bary[r] = c0 * n[0] + c1 * n[1] + c2 * n[2]
        total = bary.sum()
        if total > 0.0 and bary.min() >= -1e-12 * total:
            bary = np.maximum(bary, 0.0)
            row[:] = 0.0
            for r in range(3):
                row[faces[f, r]] = bary[r] / bary.sum()
            return True
    return False


_LANES = 32


@numba.njit(cache=True, error_model="numpy", fastmath={"contract"})
def _mvc_lanes(P, cage_v, faces, edges, face_edges, face_signs, face_n, face_off, snap,
               in_plane_value, U, inv_d, G, X, lam, acc, want_winding, cosines, winding):
    """Unnormalised MVC of ``_LANES`` points at once, for the points off the cage.

    The loops run over lanes (points) innermost, with no branches, so that LLVM vectorises
    them. Points that need the switch-over are not handled here: a point within ``snap``
    of a vertex, an edge or a face is within ``snap`` of that face's plane, and every such
    (point, face) pair multiplies the face's terms by ``in_plane_value``: NaN in the first
    pass, which poisons the point's weights so that the caller looks at it again (see
    :func:`_mvc_kernel`), and 0 in the second, which skips faces whose plane passes through
    a point that lies off them (their contribution tends to zero there).

    Parameters
    ----------
    P : (3, L) float64
        The points, coordinates by lane.
    in_plane_value : float
        NaN or 0, see above.
    U : (3, k, L), inv_d : (k, L), G, X : (3, e, L), lam : (3, m, L)
        Scratch.
    acc : (k, L) float64
        Receives the unnormalised weights ``w_j`` of each lane.
    want_winding : bool
        Also sum each lane's solid angles into ``winding``.
    cosines : (e, L) float64
        Scratch (used when ``want_winding``).
    winding : (L,) float64
        Receives each lane's winding number when ``want_winding``: the faces' signed solid
        angles over ``4 pi`` (Van Oosterom and Strackee's ``tan(Omega / 2) = det / (1 +
        u_a.u_b + u_b.u_c + u_c.u_a)``, from the unit vectors and triple product the
        weights already need).
    """
    k = cage_v.shape[0]
    for j in range(k):
        for lane in range(_LANES):
            ax = cage_v[j, 0] - P[0, lane]
            ay = cage_v[j, 1] - P[1, lane]
            az = cage_v[j, 2] - P[2, lane]
            inv = 1.0 / np.sqrt(ax * ax + ay * ay + az * az)
            inv_d[j, lane] = inv
            U[0, j, lane] = ax * inv
            U[1, j, lane] = ay * inv
            U[2, j, lane] = az * inv
    # Edge terms: X = u_lo x u_hi and G = beta / 2 * X / |X| (beta: cagekit.coords.fastangle)
    for e in range(edges.shape[0]):
        a = edges[e, 0]
        b = edges[e, 1]
        for lane in range(_LANES):
            uax = U[0, a, lane]
            uay = U[1, a, lane]
            uaz = U[2, a, lane]
            ubx = U[0, b, lane]
            uby = U[1, b, lane]
            ubz = U[2, b, lane]
            cx, cy, cz = cross(uax, uay, uaz, ubx, uby, ubz)
            s = np.sqrt(cx * cx + cy * cy + cz * cz)
            c = uax * ubx + uay * uby + uaz * ubz
            g = half_angle_over_sin(s, c)
            if want_winding:
                cosines[e, lane] = c
            X[0, e, lane] = cx
            X[1, e, lane] = cy
            X[2, e, lane] = cz
            G[0, e, lane] = g * cx
            G[1, e, lane] = g * cy
            G[2, e, lane] = g * cz
    # Face terms: mean vector, Cramer's rule; lam[:, f] = lambda / d of the face's vertices.
    if want_winding:
        for lane in range(_LANES):
            winding[lane] = 0.0
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
        for lane in range(_LANES):
            h = P[0, lane] * nx + P[1, lane] * ny + P[2, lane] * nz - off
            mx = s_ab * G[0, e_ab, lane] + s_bc * G[0, e_bc, lane] + s_ca * G[0, e_ca, lane]
            my = s_ab * G[1, e_ab, lane] + s_bc * G[1, e_bc, lane] + s_ca * G[1, e_ca, lane]
            mz = s_ab * G[2, e_ab, lane] + s_bc * G[2, e_bc, lane] + s_ca * G[2, e_ca, lane]
            xa0 = s_bc * X[0, e_bc, lane]
            xa1 = s_bc * X[1, e_bc, lane]
            xa2 = s_bc * X[2, e_bc, lane]
            det = U[0, ia, lane] * xa0 + U[1, ia, lane] * xa1 + U[2, ia, lane] * xa2
            ok = abs(h) > snap and det != 0.0
            inv = 1.0 / (det if ok else 1.0)
            inv = inv if ok else in_plane_value
            lam[0, f, lane] = (mx * xa0 + my * xa1 + mz * xa2) * inv * inv_d[ia, lane]
            lam[1, f, lane] = s_ca * (mx * X[0, e_ca, lane] + my * X[1, e_ca, lane]
                                      + mz * X[2, e_ca, lane]) * inv * inv_d[ib, lane]
            lam[2, f, lane] = s_ab * (mx * X[0, e_ab, lane] + my * X[1, e_ab, lane]
                                      + mz * X[2, e_ab, lane]) * inv * inv_d[ic, lane]
        if want_winding:  # the triple product again: kept out of the weights' lane loop
            for lane in range(_LANES):
                det = (U[0, ia, lane] * X[0, e_bc, lane] + U[1, ia, lane] * X[1, e_bc, lane]
                       + U[2, ia, lane] * X[2, e_bc, lane]) * s_bc
                den = 1.0 + cosines[e_ab, lane] + cosines[e_bc, lane] + cosines[e_ca, lane]
                half = angle_from_sin_cos(abs(det), den)
                winding[lane] += half if det >= 0.0 else -half
    if want_winding:
        for lane in range(_LANES):
            winding[lane] *= 1.0 / (2.0 * np.pi)  # sum of Omega / (4 pi), Omega = 2 half
    for j in range(k):
        for lane in range(_LANES):
            acc[j, lane] = 0.0
    for f in range(faces.shape[0]):
        for r in range(3):
            j = faces[f, r]
            for lane in range(_LANES):
                acc[j, lane] += lam[r, f, lane]


@numba.njit(cache=True, error_model="numpy")
def _normalise_row(row):
    """Divide a row of MVC weights by their (compensated) sum; False if it is unresolvable."""
    total = 0.0
    comp = 0.0
    magnitude = 0.0
    for j in range(row.shape[0]):
        t = total + row[j]
        if abs(total) >= abs(row[j]):
            comp += (total - t) + row[j]
        else:
            comp += (row[j] - t) + total
        total = t
        magnitude += abs(row[j])
    total += comp
    if not (abs(total) > 1e-15 * magnitude and np.isfinite(magnitude)):
        return False
    inv = 1.0 / total
    for j in range(row.shape[0]):
        row[j] *= inv
    return True


@numba.njit(parallel=True, cache=True, error_model="numpy")
def _mvc_kernel(points, cage_v, faces, edges, face_edges, face_signs, face_n, face_off, snap,
                n_chunks, out, want_winding, winding):
    """MVC of all points into ``out`` (n, k), ``_LANES`` points at a time, chunks in parallel,
    and, when ``want_winding``, their winding numbers into ``winding`` (n,): 0.5 for a point
    on the cage (within ``snap`` of it).

    A point whose first-pass weights are not finite (poisoned: it lies within ``snap`` of
    some face's plane) or whose weight sum cannot be resolved is looked at again, alone:
    exact limits on the cage (:func:`_snap_weights`), else the lane kernel with in-plane
    faces skipped, else the closest cage point's barycentric coordinates.
    """
    n = points.shape[0]
    k = cage_v.shape[0]
    e = edges.shape[0]
    m = faces.shape[0]
    L = _LANES
    n_blocks = (n + L - 1) // L
    n_chunks = max(1, min(n_blocks, n_chunks))
    for chunk in numba.prange(n_chunks):
        # scratch, once per chunk: O(k + e + m) memory, independent of n
        P = aligned_empty((3, L))
        U = aligned_empty((3, k, L))
        inv_d = aligned_empty((k, L))
        G = aligned_empty((3, e, L))
        X = aligned_empty((3, e, L))
        lam = aligned_empty((3, m, L))
        acc = aligned_empty((k, L))
        P1 = aligned_empty((3, L))
        acc1 = aligned_empty((k, L))
        cosines = aligned_empty((e, L))
        wind = aligned_empty((L,))
        for blk in range(chunk * n_blocks // n_chunks, (chunk + 1) * n_blocks // n_chunks):
            start = blk * L
            stop = min(start + L, n)
            load_lanes(points, start, P)
            # the flag as a constant: a compiled version each, no test in the lane loops
            if want_winding:
                _mvc_lanes(P, cage_v, faces, edges, face_edges, face_signs, face_n, face_off,
                           snap, np.nan, U, inv_d, G, X, lam, acc, True, cosines, wind)
            else:
                _mvc_lanes(P, cage_v, faces, edges, face_edges, face_signs, face_n, face_off,
                           snap, np.nan, U, inv_d, G, X, lam, acc, False, cosines, wind)
            for i in range(start, stop):
                if want_winding:
                    winding[i] = wind[i - start]
                row = out[i]
                for j in range(k):
                    row[j] = acc[j, i - start]
                if _normalise_row(row):
                    continue
                if _snap_weights(points[i], cage_v, faces, edges, face_n, face_off, snap, row):
                    if want_winding:
                        winding[i] = 0.5
                    continue
                # alone in its own lane block (acc still holds the block's other points)
                for lane in range(L):
                    P1[0, lane] = points[i, 0]
                    P1[1, lane] = points[i, 1]
                    P1[2, lane] = points[i, 2]
                _mvc_lanes(P1, cage_v, faces, edges, face_edges, face_signs, face_n, face_off,
                           snap, 0.0, U, inv_d, G, X, lam, acc1, False, cosines, wind)
                for j in range(k):
                    row[j] = acc1[j, 0]
                if not _normalise_row(row):
                    closest_point_weights(points[i], cage_v, faces, row)


def mean_value_coordinates(points: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike,
                           snap: float = DEFAULT_SNAP, check: bool = True,
                           dtype: DTypeLike = np.float64) -> NDArray[np.floating]:
    """Mean value coordinates of points with respect to a closed triangle cage.

    Parameters
    ----------
    points : (n, 3) array_like of float
        Query points; anywhere in space (inside, on, near or outside the cage).
    cage_v : (k, 3) array_like of float
        Cage vertices.
    cage_f : (m, 3) array_like of int
        Cage faces: closed, 2-manifold, consistently oriented. With ``check=True`` an inward
        cage is flipped and anything else invalid raises :class:`cagekit.CageError`.
    snap : float, default 1e-13
        Switch-over distance to the exact limits on vertices, edges and faces, relative to
        the cage's bounding-box diagonal (see the module docstring).
    check : bool, default True
        Validate the cage with :func:`cagekit.cage.check_cage`.
    dtype : {numpy.float64, numpy.float32}, default float64
        float32 computes the weights in float32 lanes (:mod:`cagekit.coords.mvc32`) and
        returns them as float32, each within about ``1e-5`` of the float64 weights (of
        their size, beyond about 100 diagonals, where weights exceed one). An estimate of
        each row's rounding error sends the rows where float32 cannot promise that to the
        float64 kernel, rounded afterwards: points near the plane of a face they lie
        outside of, within ``max(snap, 1e-5)`` of a face's plane, beyond :data:`FAR_BLEND`
        ``[0]`` diagonals. So it pays where points lie away from the cage (1.6-2.4x as fast
        for points inside a loose cage) and not for a mesh's own vertices in a tight
        fitted cage, where float32 is off by up to 1e-3 on some rows and half or more go
        to float64 (0.5-1.3x float64's speed), nor outside the cage or with a sliver face,
        where float32 MVC is wrong outright and every row goes to float64 (about 2x
        slower); docs/benchmarks.md, "MVC in float32 on request". Points whose weights
        overflow float32 are refused.

    Returns
    -------
    weights : (n, k) float64 or float32
        Rows sum to one; ``weights @ cage_v`` reproduces the points.

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> w = mean_value_coordinates([[0.1, 0.2, -0.3]], v, f)
    >>> bool(np.allclose(w.sum(axis=1), 1.0)), bool(np.allclose(w @ v, [[0.1, 0.2, -0.3]]))
    (True, True)
    >>> w32 = mean_value_coordinates([[0.1, 0.2, -0.3]], v, f, dtype=np.float32)
    >>> w32.dtype.name, bool(np.abs(w32 - w).max() < 1e-6)
    ('float32', True)
    """
    try:
        kind = np.dtype(dtype)
    except TypeError:
        kind = None
    if kind == np.float32:
        return _coordinates32(points, cage_v, cage_f, snap, check)
    if kind != np.float64:
        shown = repr(dtype) if kind is None else str(kind)
        raise InputError(f"dtype must be float64 or float32, got {shown}")
    return _coordinates(points, cage_v, cage_f, snap, check, False).weights


class WeightsAndWinding(NamedTuple):
    """What :func:`mvc_and_winding` returns."""

    #: (n, k) float64: the mean value coordinates, as :func:`mean_value_coordinates`
    weights: Floats
    #: (n,) float64: each point's winding number: about 1 inside, 0 outside, 0.5 on the cage
    winding: Floats


def mvc_and_winding(points: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike,
                    snap: float = DEFAULT_SNAP, check: bool = True) -> WeightsAndWinding:
    """Mean value coordinates and the cage's winding number at each point, in one pass.

    The winding number is the sum of the faces' signed solid angles over ``4 pi``; the
    kernel already has the unit vectors and triple products it needs. It agrees with
    :func:`cagekit.winding_numbers` (libigl) to about 1e-12 off the cage; points within
    ``snap`` of the cage get 0.5 (on it: libigl gives a vertex its solid angle's share
    instead), points beyond :data:`FAR_BLEND` ``[0]`` diagonals 0.

    Parameters
    ----------
    points, cage_v, cage_f, snap, check
        As :func:`mean_value_coordinates`.

    Returns
    -------
    WeightsAndWinding
        ``weights`` (n, k) and ``winding`` (n,), float64.

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> result = mvc_and_winding([[0.1, 0.2, -0.3], [3.0, 0.0, 0.0]], v, f)
    >>> result.weights.shape, result.winding.round(9).tolist()
    ((2, 8), [1.0, 0.0])
    """
    return _coordinates(points, cage_v, cage_f, snap, check, True)


class _Frame(NamedTuple):
    """Points and cage in the cage's normalised frame, with what the kernels need of it."""

    px: np.ndarray        # (n, 3) points relative to the box centre, in diagonals
    cv: np.ndarray        # (k, 3) cage vertices, likewise
    faces: np.ndarray     # (m, 3) int64
    topo: CageTopology
    normals: np.ndarray   # (m, 3) unit face normals
    face_off: np.ndarray  # (m,) normals . first vertex


def _frame(points, cage_v, cage_f, check) -> _Frame:
    """Validate the input and move it into the cage's normalised frame."""
    cage_v = np.asarray(cage_v, dtype=np.float64)
    faces = check_cage(cage_v, cage_f) if check else np.asarray(cage_f, dtype=np.int64)
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InputError(f"points must be an (n, 3) array, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise InputError("points contain NaN or inf")
    # Work relative to the cage's bounding-box centre, in units of its diagonal: the result
    # is similarity invariant, this keeps the relative vectors as accurate as the input
    # allows, and squares of tiny or huge coordinates neither underflow nor overflow.
    lo, hi = cage_v.min(axis=0), cage_v.max(axis=0)
    centre = 0.5 * (lo + hi)
    diag = bounding_box_diagonal(hi - lo)
    cv = np.ascontiguousarray((cage_v - centre) / diag)
    with np.errstate(over="ignore"):
        px = np.ascontiguousarray((pts - centre) / diag)
    normals = np.cross(cv[faces[:, 1]] - cv[faces[:, 0]], cv[faces[:, 2]] - cv[faces[:, 0]])
    norms = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, norms, out=np.zeros_like(normals), where=norms > 0)
    face_off = np.einsum("ij,ij->i", cv[faces[:, 0]], normals)
    return _Frame(px, cv, np.ascontiguousarray(faces), cage_topology(faces), normals, face_off)


def _float64_rows(fr: _Frame, px, snap, want_winding) -> WeightsAndWinding:
    """The float64 kernel on points ``px`` of the frame ``fr``, far rows blended."""
    n, k = len(px), len(fr.cv)
    out = np.empty((n, k), dtype=np.float64)
    winding = np.zeros(n if want_winding else 0)
    if n:
        _mvc_kernel(px, fr.cv, fr.faces, fr.topo.edges, fr.topo.face_edges,
                    fr.topo.face_edge_signs, fr.normals, fr.face_off, snap,
                    64 * numba.get_num_threads(), out, want_winding, winding)
        far = _blend_far_rows(px, fr.cv, fr.faces, out)
        if want_winding:
            winding[far] = 0.0  # far outside; solid angles there are rounding
            lost = np.flatnonzero(~np.isfinite(winding))  # none known; libigl's if any
            if len(lost):
                winding[lost] = winding_numbers(px[lost], fr.cv, fr.faces)
    return WeightsAndWinding(out, winding)


def _coordinates(points, cage_v, cage_f, snap, check, want_winding) -> WeightsAndWinding:
    """:func:`mvc_and_winding`; the winding numbers are an empty array unless wanted."""
    fr = _frame(points, cage_v, cage_f, check)
    return _float64_rows(fr, fr.px, snap, want_winding)


def _coordinates32(points, cage_v, cage_f, snap, check) -> NDArray[np.float32]:
    """:func:`mean_value_coordinates` with ``dtype=np.float32``."""
    fr = _frame(points, cage_v, cage_f, check)
    rows = mvc_float32(fr.px, fr.cv, fr.faces, fr.topo.edges, fr.topo.face_edges,
                       fr.topo.face_edge_signs, fr.normals, fr.face_off,
                       64 * numba.get_num_threads(), snap)
    redo = rows.flagged | ~(distance_in_diagonals(fr.px, fr.cv) <= FAR_BLEND[0])
    index = np.flatnonzero(redo)
    if len(index):
        with np.errstate(over="ignore"):  # weights beyond float32's range: refused below
            rows.weights[index] = _float64_rows(fr, fr.px[index], snap, False).weights
    lost = ~np.isfinite(rows.weights[index]).all(axis=1)
    if lost.any():
        raise InputError(f"{int(lost.sum())} points lie so far from the cage (about 1e38 "
                         "cage diagonals or more) that their coordinates overflow float32; "
                         "use float64")
    return rows.weights


#: far rows blended at a time: the blend's scratch memory stays a few (chunk, k) arrays
_FAR_CHUNK = 4096


def _blend_far_rows(px, cv, faces, out):
    """Rows of points beyond ``FAR_BLEND[0]`` diagonals: blend into the affine extension.
    Returns those rows' indices."""

    r = distance_in_diagonals(px, cv)  # px and cv are both centred on the cage's box
    far = np.flatnonzero(~(r <= FAR_BLEND[0]))
    if not len(far):
        return far
    lo, hi = FAR_BLEND
    centre, diag, M = affine_extension_matrix(cv, faces)
    for start in range(0, len(far), _FAR_CHUNK):
        rows = far[start:start + _FAR_CHUNK]
        t = np.clip((r[rows] - lo) / (hi - lo), 0.0, 1.0)
        s = (t * t * (3.0 - 2.0 * t))[:, None]
        with np.errstate(over="ignore", invalid="ignore"):
            affine = _homogeneous((px[rows] - centre) / diag) @ M
            block = np.where(s == 1.0, affine, (1.0 - s) * out[rows] + s * affine)
        if not np.isfinite(block).all():
            raise InputError(f"{int((~np.isfinite(block).all(axis=1)).sum())} points lie so "
                             "far from the cage (about 1e300 cage diagonals or more) that "
                             "their coordinates overflow float64")
        out[rows] = block
    return far


def _homogeneous(q):
    return np.hstack([q, np.ones((len(q), 1))])


def affine_extension_matrix(cage_v: ArrayLike,
                            cage_f: ArrayLike) -> tuple[Floats, float, Floats]:
    """The ``(4, k)`` matrix of the affine extension of a cage, in its normalised frame.

    Returns ``(centre, diag, M)``: the weights of a point ``p`` are ``[(p - centre) / diag,
    1] @ M``, with ``M = pinv(H)`` on the columns of the used vertices (``H = [(v_j - centre)
    / diag, 1]``, one row a used vertex; the pseudo-inverse, by SVD, does not square the
    condition number as the normal equations would), zero on unreferenced ones.
    """
    cv = np.asarray(cage_v, dtype=np.float64)
    used = np.unique(np.asarray(cage_f, dtype=np.int64))
    lo, hi = cv.min(axis=0), cv.max(axis=0)
    centre, diag = 0.5 * (lo + hi), bounding_box_diagonal(hi - lo)
    M = np.zeros((4, len(cv)))
    M[:, used] = np.linalg.pinv(_homogeneous((cv[used] - centre) / diag))
    return centre, diag, M


def affine_extension_weights(points: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike) -> Floats:
    """Coordinates that move points by the least-squares affine fit of a cage's motion.

    With ``H = [cage_v, 1]`` (the used vertices, homogeneous) the weights of ``p`` are
    ``pinv(H)^T [p, 1]``: ``w @ new_cage_v = A p + t`` where ``(A, t)`` minimises
    ``sum_j |A v_j + t - new_j|^2``. They sum to one and reproduce ``p`` (``w @ cage_v = p``)
    to rounding relative to ``|p|``; unlike MVC they are not local and not positive inside.
    MVC uses them far from the cage, where its own coordinates cannot be resolved (module
    docstring). Unreferenced cage vertices get zero weight.

    Parameters
    ----------
    points : (n, 3) array_like of float
    cage_v : (k, 3) array_like of float
        Vertices of a cage that encloses a volume (its used vertices are not coplanar).
    cage_f : (m, 3) array_like of int

    Returns
    -------
    (n, k) float64

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> w = affine_extension_weights([[1e6, 0.0, 0.0]], v, f)
    >>> ((w @ v).round(6) + 0.0).tolist(), round(float(w.sum()), 9)
    ([[1000000.0, 0.0, 0.0]], 1.0)
    """
    centre, diag, M = affine_extension_matrix(cage_v, cage_f)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return _homogeneous((pts - centre) / diag) @ M
