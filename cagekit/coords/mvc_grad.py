"""The vector-Jacobian product of mean value coordinates, for a differentiable MVC layer.

Batched MVC (``B`` cages, ``n`` points each) and, for an upstream gradient ``G = dL/dW``
of the normalised weights, the exact ``dL/dx`` and ``dL/dV``, in numba kernels with no
torch: the compiled core of :mod:`cagekit_learn.coords`' autograd function.

The forward pass is :mod:`cagekit.coords.mvc`'s vector form, written as the torch twin
writes it: with ``u_j = (v_j - x) / d_j``, every undirected edge ``(a, b)`` has
``X = u_a x u_b`` and ``g = atan2(|X|, u_a . u_b) / (2 |X|)``; with ``Y_r`` the cross product
of the edge opposite corner ``r`` of face ``(a, b, c)``, signed along the face, the face's
mean vector is ``m = sum_r g_r Y_r``, ``det = u_a . Y_0`` and
``w_{v_r} += (m . Y_r) / det / d_{v_r}``; the coordinates are ``W = w / sum(w)``. The
reverse pass is this chain derived by hand, in reverse: the normalisation
(``dL/dw = (G - G . W) / sum(w)``), the faces (``m``, ``det``, ``1 / d``), the edges
(``dg/d|X|^2`` by a series below ``|X|^2 < 0.01 (u_a . u_b)^2``, where the closed form
cancels, and ``dg/d(u_a . u_b) = -1 / (2 (|X|^2 + (u_a . u_b)^2))``), the cross and dot
products, then the unit vectors (``dL/dA = (G_u - u (u . G_u)) / d - G_{1/d} u / d^2``) and
``A = v_j - x``. Kernels run :data:`LANES` points at a time, one per SIMD lane, blocks of
points in parallel (``numba.prange``); each thread sums its ``dL/dV`` and the threads' sums
are added at the end. The backward pass recomputes the forward one per block, so nothing
of size ``n x faces`` is stored.

Rows that need the limit rules of :mod:`cagekit.coords.mvc` are not computed here but
*flagged* (their weights and gradients are zero) for the caller to compute otherwise:
points within ``snap`` (relative to the cage's bounding-box diagonal) of a face's plane
(the vertex, edge and face switch-over and the skipped in-plane faces), faces with
``|det| <= det_tol``, edge terms that are neither direct nor Taylor (a point on an edge's
line), and weight sums that cannot be resolved (the closest-point fallback). The far-point
blend into the affine extension is not applied either. Everything is float64. See
docs/architecture.md.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import ArrayLike

from cagekit.cage import cage_topology
from cagekit.coords.fastangle import half_angle_over_sin
from cagekit.coords.lanes import aligned_empty, cross
from cagekit.errors import InputError
from cagekit.typed import Bools, Floats

__all__ = ["mvc_weights_flagged", "mvc_vjp", "LANES", "DET_TOL", "RESOLVE_TOL"]

#: points per block (one per SIMD lane)
LANES = 32
#: default ``det_tol``: faces with ``|u_a . (u_b x u_c)|`` at most this flag their rows
DET_TOL = float(np.finfo(np.float64).tiny) ** 0.4
#: rows whose weight sum is at most this times the sum of the weights' magnitudes are flagged
RESOLVE_TOL = 1e-15
# the torch twin's Taylor branch of g: c > 0 and s2 < _TAYLOR_T c^2
_TAYLOR_T = 1e-6
# below s2 < _SERIES_T c^2 (c > 0) dg/ds2 is taken from its series
_SERIES_T = 1e-2


@numba.njit(cache=True, error_model="numpy", fastmath={"contract"})
def _forward_lanes(P, V, faces, edges, face_edges, face_signs, nrm, off, snap_d, thr_s2,
                   det_tol, VERT, EDGE, FACE, LAM, W, bad):
    """Unnormalised MVC of ``LANES`` points ``P`` (3, L), intermediates kept for the reverse.

    Writes ``VERT`` (4, k, L): the unit vectors ``u`` and the inverse distances; ``EDGE``
    (7, e, L): the cross products ``X``, ``|X|^2``, ``u_a . u_b``, ``g`` and a 0/1 flag for
    an unresolved edge term; ``FACE`` (4, m, L): the mean vectors and ``1 / det`` (0 for a face
    too close to its plane or with ``|det| <= det_tol``); ``LAM`` (3, m, L): the face's
    three terms ``lambda_r / d_r``; ``W`` (k, L): the unnormalised weights; ``bad`` (L,): > 0
    for the lanes to flag. Each loop is branch-free over the lanes and writes one array, at
    most four rows of it, so that LLVM vectorises it (it checks at run time that the arrays
    do not overlap, and gives up when there are too many checks).
    """
    k = V.shape[0]
    L = P.shape[1]
    e = edges.shape[0]
    m = faces.shape[0]
    for j in range(k):
        for lane in range(L):
            ax = V[j, 0] - P[0, lane]
            ay = V[j, 1] - P[1, lane]
            az = V[j, 2] - P[2, lane]
            inv = 1.0 / np.sqrt(ax * ax + ay * ay + az * az)
            VERT[3, j, lane] = inv
            VERT[0, j, lane] = ax * inv
            VERT[1, j, lane] = ay * inv
            VERT[2, j, lane] = az * inv
    for ed in range(e):
        a = edges[ed, 0]
        b = edges[ed, 1]
        for lane in range(L):
            uax = VERT[0, a, lane]
            uay = VERT[1, a, lane]
            uaz = VERT[2, a, lane]
            ubx = VERT[0, b, lane]
            uby = VERT[1, b, lane]
            ubz = VERT[2, b, lane]
            cx, cy, cz = cross(uax, uay, uaz, ubx, uby, ubz)
            s2 = cx * cx + cy * cy + cz * cz
            c = uax * ubx + uay * uby + uaz * ubz
            taylor = c > 0.0 and s2 < _TAYLOR_T * c * c
            EDGE[0, ed, lane] = cx
            EDGE[1, ed, lane] = cy
            EDGE[2, ed, lane] = cz
            EDGE[3, ed, lane] = s2
            EDGE[4, ed, lane] = c
            EDGE[5, ed, lane] = half_angle_over_sin(np.sqrt(s2), c)
            EDGE[6, ed, lane] = 0.0 if taylor or s2 > thr_s2 else 1.0
    # (each loop writes at most four rows: LLVM gives up vectorising loops that write more
    # rows than that, for all the run-time overlap checks they would need)
    for f in range(m):
        ia = faces[f, 0]
        nx = nrm[f, 0]
        ny = nrm[f, 1]
        nz = nrm[f, 2]
        of = off[f]
        e_ab = face_edges[f, 0]
        e_bc = face_edges[f, 1]
        e_ca = face_edges[f, 2]
        s_ab = face_signs[f, 0]
        s_bc = face_signs[f, 1]
        s_ca = face_signs[f, 2]
        for lane in range(L):
            h = P[0, lane] * nx + P[1, lane] * ny + P[2, lane] * nz - of
            ya0 = s_bc * EDGE[0, e_bc, lane]
            ya1 = s_bc * EDGE[1, e_bc, lane]
            ya2 = s_bc * EDGE[2, e_bc, lane]
            ga = EDGE[5, e_bc, lane]
            gb = s_ca * EDGE[5, e_ca, lane]
            gc = s_ab * EDGE[5, e_ab, lane]
            det = VERT[0, ia, lane] * ya0 + VERT[1, ia, lane] * ya1 + VERT[2, ia, lane] * ya2
            ok = (abs(h) > snap_d) & (abs(det) > det_tol)
            inv = 1.0 / (det if ok else 1.0)
            FACE[0, f, lane] = ga * ya0 + gb * EDGE[0, e_ca, lane] + gc * EDGE[0, e_ab, lane]
            FACE[1, f, lane] = ga * ya1 + gb * EDGE[1, e_ca, lane] + gc * EDGE[1, e_ab, lane]
            FACE[2, f, lane] = ga * ya2 + gb * EDGE[2, e_ca, lane] + gc * EDGE[2, e_ab, lane]
            FACE[3, f, lane] = inv if ok else 0.0
    for f in range(m):
        ia = faces[f, 0]
        ib = faces[f, 1]
        ic = faces[f, 2]
        e_ab = face_edges[f, 0]
        e_bc = face_edges[f, 1]
        e_ca = face_edges[f, 2]
        s_ab = face_signs[f, 0]
        s_bc = face_signs[f, 1]
        s_ca = face_signs[f, 2]
        for lane in range(L):
            m0 = FACE[0, f, lane]
            m1 = FACE[1, f, lane]
            m2 = FACE[2, f, lane]
            inv = FACE[3, f, lane]
            LAM[0, f, lane] = s_bc * (m0 * EDGE[0, e_bc, lane] + m1 * EDGE[1, e_bc, lane]
                                      + m2 * EDGE[2, e_bc, lane]) * inv * VERT[3, ia, lane]
            LAM[1, f, lane] = s_ca * (m0 * EDGE[0, e_ca, lane] + m1 * EDGE[1, e_ca, lane]
                                      + m2 * EDGE[2, e_ca, lane]) * inv * VERT[3, ib, lane]
            LAM[2, f, lane] = s_ab * (m0 * EDGE[0, e_ab, lane] + m1 * EDGE[1, e_ab, lane]
                                      + m2 * EDGE[2, e_ab, lane]) * inv * VERT[3, ic, lane]
    for lane in range(L):
        bad[lane] = 0.0
    for ed in range(e):
        for lane in range(L):
            bad[lane] += EDGE[6, ed, lane]
    for f in range(m):
        for lane in range(L):
            bad[lane] += 1.0 if FACE[3, f, lane] == 0.0 else 0.0
    for j in range(k):
        for lane in range(L):
            W[j, lane] = 0.0
    for f in range(m):
        for r in range(3):
            j = faces[f, r]
            for lane in range(L):
                W[j, lane] += LAM[r, f, lane]


@numba.njit(cache=True, error_model="numpy")
def _lane_sum(W, lane):
    """Compensated sum and magnitude of one lane's weights; (sum, resolvable)."""
    total = 0.0
    comp = 0.0
    magnitude = 0.0
    for j in range(W.shape[0]):
        x = W[j, lane]
        t = total + x
        if abs(total) >= abs(x):
            comp += (total - t) + x
        else:
            comp += (x - t) + total
        total = t
        magnitude += abs(x)
    total += comp
    return total, abs(total) > RESOLVE_TOL * magnitude and np.isfinite(magnitude)


@numba.njit(cache=True)
def _load_block(points, b, start, keep, P):
    """Lanes of points ``start:start + L`` of batch ``b`` into ``P`` (3, L); the lanes not
    kept (``keep`` (L,) bool) repeat the block's first kept point, so that every lane holds
    a point whose results are finite. Returns False if no lane is kept."""
    first = -1
    for lane in range(P.shape[1]):
        if keep[lane]:
            first = start + lane
            break
    if first < 0:
        return False
    for lane in range(P.shape[1]):
        src = start + lane if keep[lane] else first
        P[0, lane] = points[b, src, 0]
        P[1, lane] = points[b, src, 1]
        P[2, lane] = points[b, src, 2]
    return True


@numba.njit(cache=True)
def _keep_lanes(skip, b, start, stop, keep):
    """``keep[lane]``: the lane holds a point of the block not skipped by the caller."""
    for lane in range(keep.shape[0]):
        i = start + lane
        keep[lane] = i < stop and not skip[b, i]


@numba.njit(cache=True, inline="always")
def _forward_scratch(k, e, m):
    """A thread's buffers for :func:`_forward_lanes` (``k`` vertices, ``e`` edges, ``m``
    faces): ``P, VERT, EDGE, FACE, LAM, W, bad`` and the ``keep`` mask."""
    L = LANES
    return (aligned_empty((3, L)), aligned_empty((4, k, L)), aligned_empty((7, e, L)),
            aligned_empty((4, m, L)), aligned_empty((3, m, L)), aligned_empty((k, L)),
            aligned_empty((L,)), np.empty(L, dtype=np.bool_))


@numba.njit(cache=True, inline="always")
def _chunking(B, n, n_chunks):
    """For ``B`` items of ``n`` points: blocks an item, blocks in all, and the chunks the
    threads share (at most ``n_chunks``, at most one a block)."""
    nb = (n + LANES - 1) // LANES
    return nb, B * nb, max(1, min(B * nb, n_chunks))


@numba.njit(cache=True, inline="always")
def _block(blk, nb, n):
    """Block ``blk`` of a batch of ``nb`` blocks an item of ``n`` points: the item, the
    block's first point and the one past its last."""
    start = (blk % nb) * LANES
    return blk // nb, start, min(start + LANES, n)


@numba.njit(parallel=True, cache=True, error_model="numpy")
def _forward_kernel(points, cage_v, faces, edges, face_edges, face_signs, nrm, off, snap_d,
                    thr_s2, det_tol, skip, n_chunks, out, flagged):
    """Normalised MVC of all rows into ``out`` (B, n, k); ``flagged`` (B, n) rows zero."""
    B, n, _ = points.shape
    k = cage_v.shape[1]
    e = edges.shape[0]
    m = faces.shape[0]
    nb, total, n_chunks = _chunking(B, n, n_chunks)
    for chunk in numba.prange(n_chunks):
        P, VERT, EDGE, FACE, LAM, W, bad, keep = _forward_scratch(k, e, m)
        for blk in range(chunk * total // n_chunks, (chunk + 1) * total // n_chunks):
            b, start, stop = _block(blk, nb, n)
            _keep_lanes(skip, b, start, stop, keep)
            if not _load_block(points, b, start, keep, P):
                for i in range(start, stop):
                    flagged[b, i] = True
                    out[b, i, :] = 0.0
                continue
            _forward_lanes(P, cage_v[b], faces, edges, face_edges, face_signs, nrm[b], off[b],
                           snap_d[b], thr_s2, det_tol, VERT, EDGE, FACE, LAM, W, bad)
            for i in range(start, stop):
                lane = i - start
                total_w, ok = _lane_sum(W, lane)
                if not keep[lane] or bad[lane] > 0.0 or not ok:
                    flagged[b, i] = True
                    out[b, i, :] = 0.0
                    continue
                flagged[b, i] = False
                inv = 1.0 / total_w
                for j in range(k):
                    out[b, i, j] = W[j, lane] * inv


@numba.njit(cache=True, error_model="numpy", fastmath={"contract"}, inline="always")
def _dg(s2, c, g):
    """``dg/ds2`` and ``dg/dc`` of ``g = atan2(sqrt(s2), c) / (2 sqrt(s2))`` (one division).

    ``dg/dc = -1 / (2 q)`` with ``q = s2 + c^2`` (1 for unit vectors, to rounding), and
    ``dg/ds2 = (c / q - 2 g) / (4 s2)``, which cancels for ``s2 << c^2``; there (``c > 0``,
    ``t = s2 / c^2 < 0.01``) the series ``1 / (2 c^3) sum_{i>=1} (-1)^i i t^(i-1) / (2 i + 1)``
    to ``i = 9`` (next term below 1e-18).
    """
    q = s2 + c * c
    series = c > 0.0 and s2 < _SERIES_T * c * c
    cs = c if series else 1.0
    c3 = cs * cs * cs
    s2d = 1.0 if series else s2
    inv = 1.0 / (q * s2d * c3)              # 1 / (q s2 c^3) with the unused factor 1
    t = s2 * (q * s2d * cs) * inv           # s2 / c^2 (series only)
    p = (-1.0 / 3.0 + t * (2.0 / 5.0 + t * (-3.0 / 7.0 + t * (4.0 / 9.0 + t * (
        -5.0 / 11.0 + t * (6.0 / 13.0 + t * (-7.0 / 15.0 + t * (8.0 / 17.0
                                                             - t * (9.0 / 19.0)))))))))
    g_s2_series = 0.5 * p * (q * s2d) * inv
    g_s2_direct = (c * (s2d * c3) * inv - 2.0 * g) * (0.25 * q * c3) * inv
    return (g_s2_series if series else g_s2_direct), -0.5 * (s2d * c3) * inv


@numba.njit(cache=True, error_model="numpy", fastmath={"contract"})
def _reverse_lanes(faces, edges, face_edges, face_signs, VERT, EDGE, FACE, W, gW, FR, GE,
                   GV, ACC):
    """The reverse pass of :func:`_forward_lanes` for ``gW`` (k, L) = ``dL/dw``.

    ``W`` (k, L) are the lanes' unnormalised weights. Adds into ``ACC`` (3, k + 1, L)
    ``dL/dV_j`` per lane (first ``k`` columns) and ``dL/dx`` (last column). Scratch: ``FR``
    (7, m, L) the faces' terms (``dL/dm``, ``dL/ddet``, ``t_r``), ``GE`` (7, e, L) ``dL/dX``
    (then ``dL/du_a``), ``dL/du_b`` and ``dL/dg`` by edge, ``GV`` (3, k, L) ``dL/du`` by
    vertex.
    """
    k = VERT.shape[1]
    L = VERT.shape[2]
    e = edges.shape[0]
    m = faces.shape[0]
    # faces: m = sum_r g_r Y_r, det = u_a . Y_0, lambda_r / d_r = (m . Y_r) / det / d_r;
    # FR rows 0-2: dL/dm, 3: dL/ddet, 4-6: t_r = dL/d(m . Y_r)
    for f in range(m):
        ia = faces[f, 0]
        ib = faces[f, 1]
        ic = faces[f, 2]
        e_ab = face_edges[f, 0]
        e_bc = face_edges[f, 1]
        e_ca = face_edges[f, 2]
        s_ab = face_signs[f, 0]
        s_bc = face_signs[f, 1]
        s_ca = face_signs[f, 2]
        for lane in range(L):
            ya0 = s_bc * EDGE[0, e_bc, lane]
            ya1 = s_bc * EDGE[1, e_bc, lane]
            ya2 = s_bc * EDGE[2, e_bc, lane]
            yb0 = s_ca * EDGE[0, e_ca, lane]
            yb1 = s_ca * EDGE[1, e_ca, lane]
            yb2 = s_ca * EDGE[2, e_ca, lane]
            yc0 = s_ab * EDGE[0, e_ab, lane]
            yc1 = s_ab * EDGE[1, e_ab, lane]
            yc2 = s_ab * EDGE[2, e_ab, lane]
            m0 = FACE[0, f, lane]
            m1 = FACE[1, f, lane]
            m2 = FACE[2, f, lane]
            inv = FACE[3, f, lane]
            ta = gW[ia, lane] * VERT[3, ia, lane] * inv
            tb = gW[ib, lane] * VERT[3, ib, lane] * inv
            tc = gW[ic, lane] * VERT[3, ic, lane] * inv
            FR[0, f, lane] = ta * ya0 + tb * yb0 + tc * yc0
            FR[1, f, lane] = ta * ya1 + tb * yb1 + tc * yc1
            FR[2, f, lane] = ta * ya2 + tb * yb2 + tc * yc2
            FR[3, f, lane] = -(ta * (m0 * ya0 + m1 * ya1 + m2 * ya2)
                               + tb * (m0 * yb0 + m1 * yb1 + m2 * yb2)
                               + tc * (m0 * yc0 + m1 * yc1 + m2 * yc2)) * inv
    for f in range(m):
        ia = faces[f, 0]
        ib = faces[f, 1]
        ic = faces[f, 2]
        for lane in range(L):
            inv = FACE[3, f, lane]
            FR[4, f, lane] = gW[ia, lane] * VERT[3, ia, lane] * inv
            FR[5, f, lane] = gW[ib, lane] * VERT[3, ib, lane] * inv
            FR[6, f, lane] = gW[ic, lane] * VERT[3, ic, lane] * inv
    for ed in range(e):
        for c3 in range(7):
            for lane in range(L):
                GE[c3, ed, lane] = 0.0
    # onto edges, rows 0-2 dL/dX_r = s_r (t_r m + g_r dL/dm [+ dL/ddet u_a for r = 0]) and
    # row 6 dL/dg_r = s_r dL/dm . X_r (X = s Y; corner r is opposite edge r); few rows a
    # loop, so that they vectorise
    for f in range(m):
        ia = faces[f, 0]
        for r in range(3):
            ed = face_edges[f, (r + 1) % 3]
            sg = face_signs[f, (r + 1) % 3]
            corner = 1.0 if r == 0 else 0.0
            for lane in range(L):
                gm0 = FR[0, f, lane]
                gm1 = FR[1, f, lane]
                gm2 = FR[2, f, lane]
                t = FR[4 + r, f, lane]
                gg = EDGE[5, ed, lane]
                dd = corner * FR[3, f, lane]
                GE[0, ed, lane] += sg * (t * FACE[0, f, lane] + gg * gm0 + dd * VERT[0, ia, lane])
                GE[1, ed, lane] += sg * (t * FACE[1, f, lane] + gg * gm1 + dd * VERT[1, ia, lane])
                GE[2, ed, lane] += sg * (t * FACE[2, f, lane] + gg * gm2 + dd * VERT[2, ia, lane])
                GE[6, ed, lane] += sg * (gm0 * EDGE[0, ed, lane] + gm1 * EDGE[1, ed, lane]
                                         + gm2 * EDGE[2, ed, lane])
    # onto vertices: dL/du_a += dL/ddet Y_0 (dL/d(1/d_j) = sum over faces gW_j (m . Y_r) / det
    # = gW_j w_j d_j, as w_j is the sum of those terms times 1/d_j: see below)
    for j in range(k):
        for lane in range(L):
            GV[0, j, lane] = 0.0
            GV[1, j, lane] = 0.0
            GV[2, j, lane] = 0.0
    for f in range(m):
        ia = faces[f, 0]
        ed = face_edges[f, 1]
        sg = face_signs[f, 1]
        for lane in range(L):
            gd = sg * FR[3, f, lane]
            GV[0, ia, lane] += gd * EDGE[0, ed, lane]
            GV[1, ia, lane] += gd * EDGE[1, ed, lane]
            GV[2, ia, lane] += gd * EDGE[2, ed, lane]
    # edges: g(s2, c), s2 = X . X, X = u_a x u_b, c = u_a . u_b; dL/du_a replaces dL/dX
    # in GE[0:3] (read no more), dL/du_b goes to GE[3:6]
    for ed in range(e):
        a = edges[ed, 0]
        b = edges[ed, 1]
        for lane in range(L):
            g_s2, g_c = _dg(EDGE[3, ed, lane], EDGE[4, ed, lane], EDGE[5, ed, lane])
            gg = GE[6, ed, lane]
            two = 2.0 * gg * g_s2
            gc = gg * g_c
            q0 = GE[0, ed, lane] + two * EDGE[0, ed, lane]
            q1 = GE[1, ed, lane] + two * EDGE[1, ed, lane]
            q2 = GE[2, ed, lane] + two * EDGE[2, ed, lane]
            ua0 = VERT[0, a, lane]
            ua1 = VERT[1, a, lane]
            ua2 = VERT[2, a, lane]
            ub0 = VERT[0, b, lane]
            ub1 = VERT[1, b, lane]
            ub2 = VERT[2, b, lane]
            # d(a x b) . q = da . (b x q) + db . (q x a)
            GE[0, ed, lane] = ub1 * q2 - ub2 * q1 + gc * ub0
            GE[1, ed, lane] = ub2 * q0 - ub0 * q2 + gc * ub1
            GE[2, ed, lane] = ub0 * q1 - ub1 * q0 + gc * ub2
            GE[3, ed, lane] = q1 * ua2 - q2 * ua1 + gc * ua0
            GE[4, ed, lane] = q2 * ua0 - q0 * ua2 + gc * ua1
            GE[5, ed, lane] = q0 * ua1 - q1 * ua0 + gc * ua2
    for ed in range(e):
        a = edges[ed, 0]
        b = edges[ed, 1]
        for lane in range(L):
            GV[0, a, lane] += GE[0, ed, lane]
            GV[1, a, lane] += GE[1, ed, lane]
            GV[2, a, lane] += GE[2, ed, lane]
        for lane in range(L):
            GV[0, b, lane] += GE[3, ed, lane]
            GV[1, b, lane] += GE[4, ed, lane]
            GV[2, b, lane] += GE[5, ed, lane]
    # vertices: u = A / d, 1/d = (A . A)^(-1/2), A = v - x
    for j in range(k):
        for lane in range(L):
            iv = VERT[3, j, lane]
            u0 = VERT[0, j, lane]
            u1 = VERT[1, j, lane]
            u2 = VERT[2, j, lane]
            g0 = GV[0, j, lane]
            g1 = GV[1, j, lane]
            g2 = GV[2, j, lane]
            ug = u0 * g0 + u1 * g1 + u2 * g2
            gi = gW[j, lane] * W[j, lane]           # dL/d(1/d_j) / d_j
            a0 = iv * (g0 - u0 * ug - gi * u0)
            a1 = iv * (g1 - u1 * ug - gi * u1)
            a2 = iv * (g2 - u2 * ug - gi * u2)
            ACC[0, j, lane] += a0
            ACC[1, j, lane] += a1
            ACC[2, j, lane] += a2
            ACC[0, k, lane] -= a0
            ACC[1, k, lane] -= a1
            ACC[2, k, lane] -= a2


@numba.njit(parallel=True, cache=True, error_model="numpy")
def _vjp_kernel(points, cage_v, faces, edges, face_edges, face_signs, nrm, off, snap_d,
                thr_s2, det_tol, skip, grad, n_chunks, grad_p, grad_v_parts):
    """``dL/dx`` into ``grad_p`` (B, n, 3) and per-chunk ``dL/dV`` into ``grad_v_parts``
    (chunks, B, k, 3), for ``grad`` (B, n, k) = ``dL/dW``; ``skip`` rows get zero."""
    B, n, _ = points.shape
    k = cage_v.shape[1]
    e = edges.shape[0]
    m = faces.shape[0]
    L = LANES
    nb, total, n_chunks = _chunking(B, n, n_chunks)
    for chunk in numba.prange(n_chunks):
        P, VERT, EDGE, FACE, LAM, W, bad, keep = _forward_scratch(k, e, m)
        gW = aligned_empty((k, L))
        FR = aligned_empty((7, m, L))
        GE = aligned_empty((7, e, L))
        GV = aligned_empty((3, k, L))
        ACC = aligned_empty((3, k + 1, L))
        ACC[:] = 0.0
        inv_s = aligned_empty((L,))
        dot = aligned_empty((L,))
        for blk in range(chunk * total // n_chunks, (chunk + 1) * total // n_chunks):
            b, start, stop = _block(blk, nb, n)
            _keep_lanes(skip, b, start, stop, keep)
            for _ in range(2):  # once more if lanes were dropped
                kept = _load_block(points, b, start, keep, P)
                if not kept:
                    break
                _forward_lanes(P, cage_v[b], faces, edges, face_edges, face_signs, nrm[b],
                               off[b], snap_d[b], thr_s2, det_tol, VERT, EDGE, FACE, LAM, W,
                               bad)
                # rows the forward pass flags get no gradient; their lanes are reloaded
                # with a kept point (their values may be infinite, and 0 * inf is NaN)
                dropped = False
                for lane in range(L):
                    s, ok = _lane_sum(W, lane)
                    if keep[lane] and not (ok and bad[lane] == 0.0):
                        keep[lane] = False
                        dropped = True
                    inv_s[lane] = 1.0 / s if keep[lane] else 0.0
                if not dropped:
                    break
            if not kept:
                for i in range(start, stop):
                    grad_p[b, i, :] = 0.0
                continue
            # normalisation: dL/dw_j = (G_j - sum_i G_i W_i) / S, W = w / S
            for lane in range(L):
                i = start + lane
                acc = 0.0
                for j in range(k):
                    gj = grad[b, i, j] if keep[lane] else 0.0
                    gW[j, lane] = gj
                    acc += gj * W[j, lane]
                dot[lane] = acc * inv_s[lane]
            for j in range(k):
                for lane in range(L):
                    gW[j, lane] = (gW[j, lane] - dot[lane]) * inv_s[lane]
            for lane in range(L):
                ACC[0, k, lane] = 0.0
                ACC[1, k, lane] = 0.0
                ACC[2, k, lane] = 0.0
            _reverse_lanes(faces, edges, face_edges, face_signs, VERT, EDGE, FACE, W, gW, FR,
                           GE, GV, ACC)
            for i in range(start, stop):
                lane = i - start
                for c3 in range(3):
                    grad_p[b, i, c3] = ACC[c3, k, lane] if keep[lane] else 0.0
            # hand this thread's dL/dV over when the batch item changes or the chunk ends
            if blk + 1 == (chunk + 1) * total // n_chunks or (blk + 1) // nb != b:
                for j in range(k):
                    for c3 in range(3):
                        acc = 0.0
                        for lane in range(L):
                            acc += ACC[c3, j, lane]
                            ACC[c3, j, lane] = 0.0
                        grad_v_parts[chunk, b, j, c3] += acc


def _prepare(points, cage_v, faces, snap, skip):
    """Checked float64 arrays, the topology, the face planes, switch-over distances."""
    P = np.ascontiguousarray(points, dtype=np.float64)
    V = np.ascontiguousarray(cage_v, dtype=np.float64)
    F = np.ascontiguousarray(faces, dtype=np.int64)
    if P.ndim != 3 or P.shape[2] != 3 or V.ndim != 3 or V.shape[2] != 3 or V.shape[0] != P.shape[0]:
        raise InputError(f"points (B, n, 3) and cage_v (B, k, 3) expected, got {P.shape} "
                         f"and {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3 or not len(F):
        raise InputError(f"faces must be an (m, 3) array, got shape {F.shape}")
    if not (np.isfinite(P).all() and np.isfinite(V).all()):
        raise InputError("points or cage_v contain NaN or inf")
    B, n = P.shape[:2]
    if skip is None:
        skip = np.zeros((B, n), dtype=np.bool_)
    skip = np.ascontiguousarray(np.broadcast_to(np.asarray(skip, dtype=np.bool_), (B, n)))
    # work relative to each cage's bounding-box centre (MVC is translation invariant)
    lo, hi = V.min(axis=1), V.max(axis=1)
    centre = (0.5 * (lo + hi))[:, None]
    P = np.ascontiguousarray(P - centre)
    V = np.ascontiguousarray(V - centre)
    topo = cage_topology(F)
    nrm = np.cross(V[:, F[:, 1]] - V[:, F[:, 0]], V[:, F[:, 2]] - V[:, F[:, 0]])
    norm = np.sqrt(np.einsum("bmi,bmi->bm", nrm, nrm))[..., None]
    nrm = np.ascontiguousarray(np.divide(nrm, norm, out=np.zeros_like(nrm), where=norm > 0))
    off = np.ascontiguousarray(np.einsum("bmi,bmi->bm", V[:, F[:, 0]], nrm))
    snap_d = np.ascontiguousarray(snap * np.linalg.norm(hi - lo, axis=1))
    thr_s2 = (1e-3 * snap) ** 2
    return P, V, F, topo, nrm, off, snap_d, thr_s2, skip


def _chunks() -> int:
    return 8 * numba.get_num_threads()


def mvc_weights_flagged(points: ArrayLike, cage_v: ArrayLike, faces: ArrayLike,
                        snap: float = 1e-13, skip: ArrayLike | None = None,
                        det_tol: float = DET_TOL) -> tuple[Floats, Bools]:
    """Batched mean value coordinates, with the rows this module leaves to the limit rules.

    Parameters
    ----------
    points : (B, n, 3) array_like of float
        ``n`` points per batch item.
    cage_v : (B, k, 3) array_like of float
        One cage per batch item (same topology).
    faces : (m, 3) array_like of int
        Closed, 2-manifold, consistently oriented (outward) faces; not checked here.
    snap : float, default 1e-13
        Rows within ``snap`` cage diagonals of a face's plane are flagged.
    skip : (B, n) array_like of bool, optional
        Rows to flag whatever they are (the caller computes them otherwise).
    det_tol : float, default :data:`DET_TOL`
        Rows with a face of ``|det| <= det_tol`` are flagged.

    Returns
    -------
    weights : (B, n, k) float64
        Rows sum to one; flagged rows are zero.
    flagged : (B, n) bool
        The rows the caller must compute otherwise (module docstring).

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> w, flagged = mvc_weights_flagged([[[0.1, 0.2, -0.3], [1.0, 0.0, 0.0]]], v[None], f)
    >>> flagged.tolist(), round(float(w[0, 0].sum()), 12), float(w[0, 1].sum())
    ([[False, True]], 1.0, 0.0)
    >>> (np.round(w[0, :1] @ v, 12) + 0.0).tolist()
    [[0.1, 0.2, -0.3]]
    """
    P, V, F, topo, nrm, off, snap_d, thr_s2, skip = _prepare(points, cage_v, faces, snap, skip)
    B, n = P.shape[:2]
    out = np.empty((B, n, V.shape[1]))
    flagged = np.empty((B, n), dtype=np.bool_)
    if n:
        _forward_kernel(P, V, F, topo.edges, topo.face_edges, topo.face_edge_signs, nrm, off,
                        snap_d, thr_s2, det_tol, skip, _chunks(), out, flagged)
    return out, flagged


def mvc_vjp(points: ArrayLike, cage_v: ArrayLike, faces: ArrayLike, grad_weights: ArrayLike,
            snap: float = 1e-13, skip: ArrayLike | None = None,
            det_tol: float = DET_TOL) -> tuple[Floats, Floats]:
    """``dL/dx`` and ``dL/dV`` of the weights of :func:`mvc_weights_flagged` for ``dL/dW``.

    Parameters
    ----------
    points : (B, n, 3) array_like of float
    cage_v : (B, k, 3) array_like of float
    faces : (m, 3) array_like of int
        As for :func:`mvc_weights_flagged`.
    grad_weights : (B, n, k) array_like of float
        The upstream gradient ``dL/dW`` of the normalised weights.
    snap, skip, det_tol
        As for :func:`mvc_weights_flagged`; pass the same. Flagged rows contribute nothing
        (their ``dL/dx`` is zero and they add nothing to ``dL/dV``).

    Returns
    -------
    grad_points : (B, n, 3) float64
    grad_cage : (B, k, 3) float64

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> x = np.array([[[0.1, 0.2, -0.3]]])
    >>> gx, gv = mvc_vjp(x, v[None], f, v.T[None, :1])   # d(W @ v)_x / d(x, V)
    >>> (np.round(gx, 9) + 0.0).tolist()
    [[[1.0, 0.0, 0.0]]]
    >>> round(float(gv.sum()), 9) + 0.0   # dL/dV = -W_j e_x: sum_j W_j V_j = x for any V
    -1.0
    """
    P, V, F, topo, nrm, off, snap_d, thr_s2, skip = _prepare(points, cage_v, faces, snap, skip)
    B, n = P.shape[:2]
    G = np.ascontiguousarray(grad_weights, dtype=np.float64)
    if G.shape != (B, n, V.shape[1]):
        raise InputError(f"grad_weights has shape {G.shape}, expected {(B, n, V.shape[1])}")
    grad_p = np.zeros((B, n, 3))
    chunks = max(1, min(_chunks(), B * ((n + LANES - 1) // LANES)))
    parts = np.zeros((chunks, B, V.shape[1], 3))
    if n:
        _vjp_kernel(P, V, F, topo.edges, topo.face_edges, topo.face_edge_signs, nrm, off,
                    snap_d, thr_s2, det_tol, skip, G, chunks, grad_p, parts)
    return grad_p, parts.sum(axis=0)
