"""Green coordinates for closed triangle cages (Lipman, Levin & Cohen-Or 2008).

A point ``x`` inside a cage is written through the cage's vertices and its faces' normals,
``x = sum_i phi_i v_i + sum_j psi_j n_j``, by Green's third identity applied to the
coordinate functions: ``phi_i`` is the double-layer potential of vertex ``i``'s hat
function and ``psi_j`` the single-layer potential of face ``j`` (``G = -1 / (4 pi r)``).
A deformed cage moves the point to ``sum_i phi_i v'_i + sum_j psi_j s_j n'_j``, with
``n'_j`` the deformed face's unit normal and ``s_j`` its stretch factor (the paper's
3D formula): the map is exact for similarities and quasi-conformal otherwise, where mean
value coordinates are affine-invariant and shear details under stretch.

The integrals are not the paper's pseudo-code (its ``GCTriInt`` takes arccosines and
differences of nearly equal logarithms and loses digits near the cage). They are the
boundary-element closed forms: per face the signed solid angle ``Omega``, per edge ``I_e
= log((R_p + R_q + L) / (R_p + R_q - L))`` (the integral of ``1 / r`` along it) with the
denominator as ``2 (R_p R_q + d_p . d_q) / (R_p + R_q + L)`` and ``R_p R_q + d_p . d_q =
|d_p x d_q|^2 / (R_p R_q - d_p . d_q)`` where the two vectors point apart, so that the
logarithm stays exact as the point closes on the edge. Then ``psi = (sum_e d_e I_e - h
Omega) / 4 pi`` and ``phi_a += (Gamma_a(rho) Omega - h g_a . sum_e m_e I_e) / 4 pi``
(``h`` the point's height over the face, ``rho`` its foot, ``Gamma_a`` and ``g_a`` the
hat function's value there and its gradient, ``m_e`` and ``d_e`` each edge's outward
in-plane normal and the foot's distance to it). The solid angle is the spherical excess
of the angles between the planes through the point and each edge (normals ``d_p x
d_q``): the face across an edge sees the same normal negated bit for bit, so the part
that is ill-conditioned near the edge cancels between the two faces (Van Oosterom and
Strackee's one-``atan2`` formula loses ``eps / distance`` there); the three angles take
one ``atan2`` as the argument of a product (:func:`_excess`). The kernel runs
:data:`_LANES` points at a time, branch-free so that LLVM vectorises it (as mean value
coordinates' does): the logarithms by :func:`cagekit.coords.fastlog.log_ratio` and the
``atan2`` by :func:`cagekit.coords.fastangle.angle_from_sin_cos`, polynomials within a
few units in the last place of libm's (numba has no vector ``log`` or ``atan2`` without
SVML). Reproduction holds to
about ``1e-14 D`` (``D`` the cage's bounding-box diagonal) down to ``1e-11 D`` from the
cage (docs/benchmarks.md, "Green coordinates").

Points within :data:`SNAP` cage diagonals of the cage (where the integrands are singular)
are evaluated :data:`INSET` diagonals from it on their own side, on the ray from their
closest cage point through them (points on the cage: inward along the angle-weighted
pseudo-normal there), so reproduction there is off by at most about ``INSET * D``. Points
outside take the paper's extension across their exit face, taken to be the face closest
to them (a sliver's tie goes to a better-shaped neighbour that is as close): the raw
integrals vanish outside (the coordinates sum to zero), and the point's
affine coordinates in the frame of that face (its three vertices and its normal) are
added to the face's vertices and to its ``psi``. The map is then continuous across that
face and reproduces outside points exactly, but it is not continuous where the closest
face changes, so a point far from the cage is only as meaningful as that face's frame;
commands warn with the share outside.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike

from cagekit.cage import cage_topology
from cagekit.coords.fastangle import angle_from_sin_cos
from cagekit.coords.fastlog import log_ratio
from cagekit.coords.lanes import aligned_empty, cross, load_lanes
from cagekit.errors import InputError
from cagekit.geometry.frame import bounding_box_diagonal
from cagekit.typed import Floats, Ints, Vertices

__all__ = ["green_coordinates", "green_coordinates_and_plan", "evaluation_plan",
           "EvaluationPlan", "FaceTerms", "stretch_factors", "unit_normals", "SNAP", "INSET"]

#: points closer than this to the cage (in cage diagonals) are evaluated INSET from it
SNAP = 3e-11
#: how far inside such points are evaluated (cage diagonals): reproduction's error there
INSET = 3e-11

_INV_FOUR_PI = 1.0 / (4.0 * np.pi)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _corner(ax, ay, az, bx, by, bz):
    """Cosine and sine of the angle between two vectors, both times their lengths' product
    (the sine from the cross product's length: accurate at every angle)."""
    cx, cy, cz = cross(ax, ay, az, bx, by, bz)
    return ax * bx + ay * by + az * bz, np.sqrt(cx * cx + cy * cy + cz * cz)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _excess(c0, s0, c1, s1, c2, s2):
    """``|Omega| = 2 pi - (a_0 + a_1 + a_2)`` from the corners' cosines and sines (each
    pair may be scaled by its own positive factor).

    One ``atan2`` (:func:`~cagekit.coords.fastangle.angle_from_sin_cos`): the argument of
    the product of the ``cos a + i sin a`` is the angle sum (in [0, 2 pi]) modulo 2 pi,
    ambiguous only near 0, between ``|Omega|`` near 0 and near 2 pi. There the signs of
    the cosines decide: a sum under pi/4 has all three angles under pi/4 (cosines over
    0.7), one over 7 pi/4 has an angle over 7 pi/12 (cosine under -0.25). Selects only,
    so that the loop calling it vectorises.
    """
    re = c0 * c1 - s0 * s1
    im = c0 * s1 + s0 * c1
    re, im = re * c2 - im * s2, re * s2 + im * c2
    a = angle_from_sin_cos(abs(im), re)  # |arg|
    near_zero = (c0 > 0.0) & (c1 > 0.0) & (c2 > 0.0)
    wrapped = near_zero if a < 0.25 * np.pi else im > 0.0  # the sum is arg, not 2 pi + arg
    arg = a if im >= 0.0 else -a
    return 2.0 * np.pi - arg if wrapped else a


@numba.njit(cache=True, error_model="numpy", inline="always")
def _edge_log(rp, rq, dot, cross2, length):
    """``I_e = log((R_p + R_q + L) / (R_p + R_q - L))`` with the denominator as ``2 (R_p R_q
    + d_p . d_q) / (R_p + R_q + L)``, and that as ``|d_p x d_q|^2 / (R_p R_q - d_p . d_q)``
    where the two vectors point apart (:func:`~cagekit.coords.fastlog.log_ratio`)."""
    rr = rp * rq
    total = rp + rq + length
    acute = dot >= 0.0
    return log_ratio(total * total * (1.0 if acute else rr - dot),
                     2.0 * (rr + dot if acute else cross2))


#: points evaluated together: with 16, LLVM vectorises every lane loop (with 8 it leaves
#: them scalar, at half the speed; 32 is about 5% faster again, for twice the scratch)
_LANES = 32


@numba.njit(cache=True, error_model="numpy", fastmath={"contract"})
def _green_lanes(P, cage_v, faces, edges, face_edges, face_signs, normals, face_off, edge_m,
                 edge_off, grads, inv_twice, edge_len, inv_len2, V, E, F, acc, near):
    """Raw Green coordinates of ``_LANES`` points at once: ``F[3]`` (m, L) psi, ``acc``
    (k, L) phi, and each point's squared distance to the cage into ``near`` (L).

    The loops run over lanes (points) innermost, with no branches and one array written
    each (LLVM checks at run time that arrays do not overlap, and gives up past a few), so
    that LLVM vectorises them. Per vertex, into ``V`` (4, k, L): ``d = v - x`` and its
    length; per undirected edge, into ``E`` (5, e, L): the normal of the plane through
    ``x`` and the edge (``d_p x d_q``, unnormalised: the face across sees it negated bit for
    bit), ``I_e`` and the squared distance to the edge where the foot falls on it; per
    face, into ``F`` (5, m, L): the three vertices' terms (the solid angle by the spherical
    excess of those normals, the foot's barycentrics), psi, and the squared distance to
    the face where the foot falls in it. A point too close for the integrals gets a
    non-finite value somewhere. ``P`` (3, L) holds the points.
    """
    k = cage_v.shape[0]
    ne = edges.shape[0]
    m = faces.shape[0]
    for v in range(k):
        for lane in range(_LANES):
            dx = cage_v[v, 0] - P[0, lane]
            dy = cage_v[v, 1] - P[1, lane]
            dz = cage_v[v, 2] - P[2, lane]
            V[0, v, lane] = dx
            V[1, v, lane] = dy
            V[2, v, lane] = dz
            V[3, v, lane] = np.sqrt(dx * dx + dy * dy + dz * dz)
    for e in range(ne):
        p = edges[e, 0]
        q = edges[e, 1]
        length = edge_len[e]
        inv_l2 = inv_len2[e]
        for lane in range(_LANES):
            px, py, pz, rp = V[0, p, lane], V[1, p, lane], V[2, p, lane], V[3, p, lane]
            qx, qy, qz, rq = V[0, q, lane], V[1, q, lane], V[2, q, lane], V[3, q, lane]
            cx = py * qz - pz * qy
            cy = pz * qx - px * qz
            cz = px * qy - py * qx
            cross2 = cx * cx + cy * cy + cz * cz
            dot = px * qx + py * qy + pz * qz
            E[0, e, lane] = cx
            E[1, e, lane] = cy
            E[2, e, lane] = cz
            E[3, e, lane] = _edge_log(rp, rq, dot, cross2, length)
            # |d_p x d_q|^2 / L^2 where the foot falls on the edge
            on = (rp * rp - dot >= 0.0) & (rq * rq - dot >= 0.0)
            E[4, e, lane] = cross2 * inv_l2 if on else np.inf
    for j in range(m):
        nx, ny, nz = normals[j, 0], normals[j, 1], normals[j, 2]
        off = face_off[j]
        inv2a = inv_twice[j]
        e0, e1, e2 = face_edges[j, 0], face_edges[j, 1], face_edges[j, 2]
        s0, s1, s2 = face_signs[j, 0], face_signs[j, 1], face_signs[j, 2]
        # the edges' outward in-plane normals and offsets, the hat functions' gradients
        m0x, m0y, m0z = edge_m[j, 0, 0], edge_m[j, 0, 1], edge_m[j, 0, 2]
        m1x, m1y, m1z = edge_m[j, 1, 0], edge_m[j, 1, 1], edge_m[j, 1, 2]
        m2x, m2y, m2z = edge_m[j, 2, 0], edge_m[j, 2, 1], edge_m[j, 2, 2]
        o0, o1, o2 = edge_off[j, 0], edge_off[j, 1], edge_off[j, 2]
        g0x, g0y, g0z = grads[j, 0, 0], grads[j, 0, 1], grads[j, 0, 2]
        g1x, g1y, g1z = grads[j, 1, 0], grads[j, 1, 1], grads[j, 1, 2]
        g2x, g2y, g2z = grads[j, 2, 0], grads[j, 2, 1], grads[j, 2, 2]
        for lane in range(_LANES):
            x0, x1, x2 = P[0, lane], P[1, lane], P[2, lane]
            h = off - (x0 * nx + x1 * ny + x2 * nz)
            # the planes' normals as this face orients them
            ax, ay, az = s0 * E[0, e0, lane], s0 * E[1, e0, lane], s0 * E[2, e0, lane]
            bx, by, bz = s1 * E[0, e1, lane], s1 * E[1, e1, lane], s1 * E[2, e1, lane]
            cx, cy, cz = s2 * E[0, e2, lane], s2 * E[1, e2, lane], s2 * E[2, e2, lane]
            # the spherical triangle's angles, between the planes of consecutive edges
            c0, sn0 = _corner(cx, cy, cz, ax, ay, az)
            c1, sn1 = _corner(ax, ay, az, bx, by, bz)
            c2, sn2 = _corner(bx, by, bz, cx, cy, cz)
            omega = _excess(c0, sn0, c1, sn1, c2, sn2)
            omega = -omega if h < 0.0 else omega
            # the foot's barycentrics: (d1 x d2) . n, (d2 x d0) . n, (d0 x d1) . n over 2A
            gam0 = (bx * nx + by * ny + bz * nz) * inv2a
            gam1 = (cx * nx + cy * ny + cz * nz) * inv2a
            gam2 = (ax * nx + ay * ny + az * nz) * inv2a
            i0, i1, i2 = E[3, e0, lane], E[3, e1, lane], E[3, e2, lane]
            vx = m0x * i0 + m1x * i1 + m2x * i2
            vy = m0y * i0 + m1y * i1 + m2y * i2
            vz = m0z * i0 + m1z * i1 + m2z * i2
            single = ((o0 - (x0 * m0x + x1 * m0y + x2 * m0z)) * i0
                      + (o1 - (x0 * m1x + x1 * m1y + x2 * m1z)) * i1
                      + (o2 - (x0 * m2x + x1 * m2y + x2 * m2z)) * i2)
            F[0, j, lane] = (gam0 * omega - h * (g0x * vx + g0y * vy + g0z * vz)) * _INV_FOUR_PI
            F[1, j, lane] = (gam1 * omega - h * (g1x * vx + g1y * vy + g1z * vz)) * _INV_FOUR_PI
            F[2, j, lane] = (gam2 * omega - h * (g2x * vx + g2y * vy + g2z * vz)) * _INV_FOUR_PI
            F[3, j, lane] = (single - h * omega) * _INV_FOUR_PI
            foot_in = (gam0 >= 0.0) & (gam1 >= 0.0) & (gam2 >= 0.0)
            F[4, j, lane] = h * h if foot_in else np.inf
    for lane in range(_LANES):
        near[lane] = np.inf
    for v in range(k):
        for lane in range(_LANES):
            near[lane] = min(near[lane], V[3, v, lane] * V[3, v, lane])
    for e in range(ne):
        for lane in range(_LANES):
            near[lane] = min(near[lane], E[4, e, lane])
    for j in range(m):
        for lane in range(_LANES):
            near[lane] = min(near[lane], F[4, j, lane])
    for v in range(k):
        for lane in range(_LANES):
            acc[v, lane] = 0.0
    for j in range(m):
        for a in range(3):
            v = faces[j, a]
            for lane in range(_LANES):
                acc[v, lane] += F[a, j, lane]


@numba.njit(parallel=True, cache=True, error_model="numpy")
def _green_kernel(points, cage_v, faces, edges, face_edges, face_signs, normals, face_off,
                  edge_m, edge_off, grads, inv_twice, edge_len, n_chunks, phi, psi, dist):
    """:func:`_green_lanes` for every point, ``_LANES`` at a time, chunks of them in
    parallel (scratch once per chunk: O(k + e + m) memory); each point's distance to the
    cage into ``dist``, or -1 where a coordinate is not finite (too close to the cage)."""
    n = points.shape[0]
    k = cage_v.shape[0]
    ne = edges.shape[0]
    m = faces.shape[0]
    L = _LANES
    inv_len2 = 1.0 / (edge_len * edge_len)
    n_blocks = (n + L - 1) // L
    n_chunks = max(1, min(n_blocks, n_chunks))
    for chunk in numba.prange(n_chunks):
        P = aligned_empty((3, L))
        V = aligned_empty((4, k, L))
        E = aligned_empty((5, ne, L))
        F = aligned_empty((5, m, L))
        acc = aligned_empty((k, L))
        near = aligned_empty((L,))
        for blk in range(chunk * n_blocks // n_chunks, (chunk + 1) * n_blocks // n_chunks):
            start = blk * L
            stop = min(start + L, n)
            load_lanes(points, start, P)
            _green_lanes(P, cage_v, faces, edges, face_edges, face_signs, normals, face_off,
                         edge_m, edge_off, grads, inv_twice, edge_len, inv_len2, V, E, F,
                         acc, near)
            for i in range(start, stop):
                lane = i - start
                # one check: a non-finite term anywhere reaches these sums
                total = 0.0
                for v in range(k):
                    phi[i, v] = acc[v, lane]
                    total += acc[v, lane]
                for j in range(m):
                    psi[i, j] = F[3, j, lane]
                    total += F[3, j, lane]
                dist[i] = np.sqrt(near[lane]) if np.isfinite(total) else -1.0


def _face_constants(cv, faces, normals, twice):
    """What does not depend on the point: the faces' offsets along their normals, their
    edges' outward in-plane normals and offsets along them, the hat functions' in-plane
    gradients ``n x (v_c - v_b) / 2A``, and the unique edges' lengths."""

    topo = cage_topology(faces)
    corners = cv[faces]  # (m, 3, 3)
    ahead = np.roll(corners, -1, axis=1)  # each directed edge's end
    tangent = ahead - corners
    tangent /= np.linalg.norm(tangent, axis=2, keepdims=True)
    edge_m = np.cross(tangent, normals[:, None, :])
    edge_off = np.einsum("fci,fci->fc", corners, edge_m)
    face_off = np.einsum("fi,fi->f", corners[:, 0], normals)
    opposite = np.roll(corners, -2, axis=1) - np.roll(corners, -1, axis=1)  # v_c - v_b
    grads = np.cross(normals[:, None, :], opposite) / twice[:, None, None]
    edge_len = np.linalg.norm(cv[topo.edges[:, 1]] - cv[topo.edges[:, 0]], axis=1)
    return (topo.edges, topo.face_edges, topo.face_edge_signs, np.ascontiguousarray(face_off),
            np.ascontiguousarray(edge_m), np.ascontiguousarray(edge_off),
            np.ascontiguousarray(grads), np.ascontiguousarray(1.0 / twice), edge_len)


def unit_normals(cage_v: ArrayLike, cage_f: ArrayLike) -> tuple[Floats, Floats]:
    """Unit normals and twice the areas of a cage's faces.

    Parameters
    ----------
    cage_v : (k, 3) array_like of float
    cage_f : (m, 3) array_like of int

    Returns
    -------
    normals : (m, 3) float64
        Zero for a face of zero area.
    twice_area : (m,) float64
    """
    v = np.asarray(cage_v, dtype=np.float64)
    f = np.asarray(cage_f, dtype=np.int64)
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    twice = np.linalg.norm(cross, axis=1)
    normals = np.divide(cross, twice[:, None], out=np.zeros_like(cross),
                        where=twice[:, None] > 0)
    return normals, twice


def stretch_factors(rest_v: ArrayLike, new_v: ArrayLike, cage_f: ArrayLike) -> Floats:
    """Each face's stretch factor ``s_j`` of Green coordinates' deformation.

    ``s = sqrt(|u'_1|^2 |u_2|^2 - 2 (u'_1 . u'_2)(u_1 . u_2) + |u'_2|^2 |u_1|^2) /
    (sqrt(8) area)`` with ``u_1, u_2`` two edge vectors of the rest face and ``u'``
    the deformed ones: 1 under a rotation, ``c`` under a uniform scale by ``c``, and in
    between the face's mean stretch.

    Parameters
    ----------
    rest_v, new_v : (k, 3) array_like of float
        The cage at rest and deformed.
    cage_f : (m, 3) array_like of int

    Returns
    -------
    (m,) float64

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> bool(np.allclose(stretch_factors(v, 3.0 * v + 1.0, f), 3.0))
    True
    """
    v = np.asarray(rest_v, dtype=np.float64)
    w = np.asarray(new_v, dtype=np.float64)
    f = np.asarray(cage_f, dtype=np.int64)
    u1, u2 = v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]
    w1, w2 = w[f[:, 1]] - w[f[:, 0]], w[f[:, 2]] - w[f[:, 0]]

    # the same sum as two non-negative squares, so that a sliver's (whose three terms
    # cancel to its squared area) keeps its digits: with u_2 = a e_1 + b e_2 in the
    # face's frame (e_1 along u_1), it is |u_1|^2 |w_2 - (a / |u_1|) w_1|^2 + b^2 |w_1|^2
    len1 = np.linalg.norm(u1, axis=1)
    twice_area = np.linalg.norm(np.cross(u1, u2), axis=1)
    a = np.einsum("ij,ij->i", u1, u2) / len1
    b = twice_area / len1
    across = np.linalg.norm(w2 - (a / len1)[:, None] * w1, axis=1)
    inside = (len1 * across) ** 2 + (b * np.linalg.norm(w1, axis=1)) ** 2
    return np.sqrt(inside) / (np.sqrt(2.0) * twice_area)


def green_coordinates(points: ArrayLike, cage_v: ArrayLike,
                      cage_f: ArrayLike) -> tuple[Floats, Floats]:
    """Green coordinates of points with respect to a closed, outward triangle cage.

    Parameters
    ----------
    points : (n, 3) array_like of float
        Query points, inside the cage (outside ones take the extension across their
        closest face, see the module docstring).
    cage_v : (k, 3) array_like of float
    cage_f : (m, 3) array_like of int
        Closed, 2-manifold, outward (:func:`cagekit.check_cage`; not checked here), no
        face of zero area.

    Returns
    -------
    phi : (n, k) float64
        Vertex coordinates; rows sum to one.
    psi : (n, m) float64
        Face coordinates, in the cage's units.
        ``phi @ cage_v + psi @ normals`` reproduces the points.

    Raises
    ------
    InputError
        Points that are not an (n, 3) finite array, or a face of zero area.

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> phi, psi = green_coordinates([[0.1, 0.2, -0.3]], v, f)
    >>> n, _ = unit_normals(v, f)
    >>> bool(np.allclose(phi @ v + psi @ n, [[0.1, 0.2, -0.3]])), round(float(phi.sum()), 12)
    (True, 1.0)
    """
    phi, psi, _ = green_coordinates_and_plan(points, cage_v, cage_f)
    return phi, psi


@dataclass
class EvaluationPlan:
    """Where :func:`green_coordinates` evaluated each point, for its torch twin.

    Attributes
    ----------
    evaluated : (n, 3) float64
        Where the integrals were evaluated: the point itself (the same numbers), or
        (within :data:`SNAP` of the cage) :data:`INSET` from it.
    outside_rows : (p,) int64
        The points outside the cage, extended across ...
    exit_faces : (p,) int64
        ... these faces.
    winding : (n,) float64
        The cage's winding number where each point was evaluated: the sum of its vertex
        coordinates before the extension (the faces' solid angles over ``4 pi``). A point
        within :data:`SNAP` of the cage has the value of its evaluation point, about 1
        (inside) for a point on the cage.
    """

    evaluated: Vertices
    outside_rows: Ints
    exit_faces: Ints
    winding: Floats


def evaluation_plan(points: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike) -> EvaluationPlan:
    """The :class:`EvaluationPlan` of :func:`green_coordinates` for these points (the
    torch twin, ``cagekit_learn.green``, evaluates and extends where the core does)."""
    return green_coordinates_and_plan(points, cage_v, cage_f)[2]


def green_coordinates_and_plan(points: ArrayLike, cage_v: ArrayLike,
                               cage_f: ArrayLike) -> tuple[Floats, Floats, EvaluationPlan]:
    """:func:`green_coordinates` and its :class:`EvaluationPlan` (which holds the cage's
    winding numbers at the points, found on the way).

    Parameters
    ----------
    points, cage_v, cage_f
        As :func:`green_coordinates`.

    Returns
    -------
    phi : (n, k) float64
    psi : (n, m) float64
    plan : EvaluationPlan

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> phi, psi, plan = green_coordinates_and_plan([[0.1, 0.2, -0.3], [3.0, 0, 0]], v, f)
    >>> plan.winding.round(9).tolist(), plan.outside_rows.tolist()
    ([1.0, 0.0], [1])
    """
    return _coordinates_and_plan(points, cage_v, cage_f)


def _coordinates_and_plan(points, cage_v, cage_f):
    """:func:`green_coordinates_and_plan` (the numba kernels' calls left untyped)."""

    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InputError(f"points must be an (n, 3) array, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise InputError("points contain NaN or inf")
    cage_v = np.asarray(cage_v, dtype=np.float64)
    faces = np.ascontiguousarray(cage_f, dtype=np.int64)
    # relative to the box's centre in units of its diagonal, as mean value coordinates
    lo, hi = cage_v.min(axis=0), cage_v.max(axis=0)
    centre, diag = 0.5 * (lo + hi), bounding_box_diagonal(hi - lo)
    cv = np.ascontiguousarray((cage_v - centre) / diag)
    px = np.ascontiguousarray((pts - centre) / diag)
    normals, twice = unit_normals(cv, faces)
    if not np.all(twice > 1e-14):
        raise InputError("Green coordinates need cage faces of positive area")
    constants = _face_constants(cv, faces, normals, twice)
    chunks = 16 * numba.get_num_threads()
    n, k, m = len(px), len(cv), len(faces)
    phi, psi = np.empty((n, k)), np.empty((n, m))
    evaluated = px.copy()
    no_rows = np.zeros(0, dtype=np.int64)
    if not n:
        return phi, psi, EvaluationPlan(pts.copy(), no_rows, no_rows, np.zeros(0))
    dist = np.empty(n)
    _green_kernel(px, cv, faces, *constants[:3], normals, *constants[3:], chunks, phi, psi,
                  dist)
    # the solid angles sum to 4 pi inside and to 0 outside (the kernel's own winding number)
    winding = phi.sum(axis=1)
    near = np.flatnonzero(~(dist >= SNAP))  # too close, or not finite (dist -1)
    if len(near):
        query = np.ascontiguousarray(_moved_off(px[near], cv, faces))
        evaluated[near] = query
        dist_near = np.empty(len(near))
        phi_near, psi_near = np.empty((len(near), k)), np.empty((len(near), m))
        _green_kernel(query, cv, faces, *constants[:3], normals, *constants[3:], chunks,
                      phi_near, psi_near, dist_near)
        if not np.all(dist_near >= 0):
            raise FloatingPointError("Green coordinates are not finite at "
                                     f"{int((dist_near < 0).sum())} point(s)")
        phi[near], psi[near] = phi_near, psi_near
        winding[near] = phi_near.sum(axis=1)
    rows, exit_faces = np.flatnonzero(winding < 0.5), no_rows
    if len(rows):
        exit_faces = _exit_faces(evaluated[rows], cv, faces, twice)
        _extend_outside(evaluated[rows], exit_faces, cv, faces, normals, rows, phi, psi)
    psi *= diag
    plan = EvaluationPlan(np.where(evaluated == px, pts, evaluated * diag + centre), rows,
                          exit_faces, winding)
    return phi, psi, plan


def _moved_off(points, cv, faces) -> np.ndarray:
    """Points on or near the cage moved to :data:`INSET` from it: along the ray from
    their closest cage point through them (the open segment to the closest point never
    crosses the cage, so an inside point stays inside and an outside one outside), or,
    for a point on the cage, inward along the angle-weighted pseudo-normal there."""
    import igl

    result = igl.signed_distance(np.ascontiguousarray(points), cv, faces,
                                 igl.SignedDistanceType.SIGNED_DISTANCE_TYPE_PSEUDONORMAL)
    foot, pseudo = result[2], result[3]
    away = points - foot
    length = np.linalg.norm(away, axis=1, keepdims=True)
    norms = np.linalg.norm(pseudo, axis=1, keepdims=True)
    inward = -pseudo / np.where(norms > 0, norms, 1.0)
    direction = np.where(length > 1e-3 * INSET, away / np.where(length > 0, length, 1.0),
                         inward)
    return foot + INSET * direction


#: a face whose twice-area is below this times its longest edge squared is a sliver: as
#: an exit face its frame would cost digits (eps / this), so a tie goes to a neighbour
SLIVER = 1e-3


def _exit_faces(points, cv, faces, twice_area) -> np.ndarray:
    """Each outside point's exit face: its closest face, or, where that is a sliver and
    the closest cage point lies on its edge or corner, the best-shaped face around that
    corner that is as close (libigl breaks such ties arbitrarily)."""
    import igl

    dist2, closest = igl.point_mesh_squared_distance(np.ascontiguousarray(points), cv,
                                                     faces)[:2]
    distance = np.sqrt(dist2)
    edges = cv[np.roll(faces, -1, axis=1)] - cv[faces]
    longest = np.max(np.einsum("fij,fij->fi", edges, edges), axis=1)
    shape = twice_area / longest
    chosen = closest.copy()
    for i in np.flatnonzero(shape[closest] < SLIVER):
        ring = np.flatnonzero(np.isin(faces, faces[closest[i]]).any(axis=1))
        ring = ring[shape[ring] >= SLIVER]
        if not len(ring):
            continue
        d2 = np.array([igl.point_mesh_squared_distance(points[i:i + 1], cv,
                                                       faces[j:j + 1])[0][0] for j in ring])
        tied = np.sqrt(d2) <= distance[i] * (1 + 1e-9) + 1e-15
        if tied.any():
            chosen[i] = ring[tied][np.argmax(shape[ring[tied]])]
    return chosen


def _extend_outside(points, closest_faces, cv, faces, normals, rows, phi, psi):
    """The paper's extension: each outside point's coordinates in its exit face's frame
    ``x = a_0 v_0 + a_1 v_1 + a_2 v_2 + a_3 n`` (``a_0 + a_1 + a_2 = 1``) added on."""
    f = faces[closest_faces]
    v0, v1, v2 = cv[f[:, 0]], cv[f[:, 1]], cv[f[:, 2]]
    n = normals[closest_faces]
    A = np.stack([v1 - v0, v2 - v0, n], axis=2)  # (p, 3, 3): columns
    coef = np.linalg.solve(A, (points - v0)[:, :, None])[:, :, 0]
    a1, a2, a3 = coef[:, 0], coef[:, 1], coef[:, 2]
    np.add.at(phi, (rows, f[:, 0]), 1.0 - a1 - a2)
    np.add.at(phi, (rows, f[:, 1]), a1)
    np.add.at(phi, (rows, f[:, 2]), a2)
    np.add.at(psi, (rows, closest_faces), a3)


class FaceTerms:
    """The face terms ``s_j n'_j`` of a Green deformation as a function of the moved cage,
    with their vector-Jacobian product (for optimising a cage under Green coordinates).

    A Green deformation is linear in ``Z = [C; face_terms(C)]``: ``[phi psi] @ Z``.

    Parameters
    ----------
    rest_v : (k, 3) array_like of float
        The cage the points were bound to.
    cage_f : (m, 3) array_like of int

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> terms = FaceTerms(v, f)
    >>> n, _ = unit_normals(v, f)
    >>> bool(np.allclose(terms(2.0 * v), 2.0 * n))
    True
    """

    def __init__(self, rest_v: ArrayLike, cage_f: ArrayLike) -> None:
        self.rest_v = np.asarray(rest_v, dtype=np.float64)
        self.faces = np.asarray(cage_f, dtype=np.int64)
        u1 = self.rest_v[self.faces[:, 1]] - self.rest_v[self.faces[:, 0]]
        u2 = self.rest_v[self.faces[:, 2]] - self.rest_v[self.faces[:, 0]]
        self._u11 = np.einsum("ij,ij->i", u1, u1)
        self._u22 = np.einsum("ij,ij->i", u2, u2)
        self._u12 = np.einsum("ij,ij->i", u1, u2)
        self._twice = np.linalg.norm(np.cross(u1, u2), axis=1)

    def _parts(self, C):
        f = self.faces
        w1, w2 = C[f[:, 1]] - C[f[:, 0]], C[f[:, 2]] - C[f[:, 0]]
        cross = np.cross(w1, w2)
        length = np.linalg.norm(cross, axis=1)
        return w1, w2, cross, length

    def __call__(self, C: ArrayLike) -> Floats:
        """``s_j n'_j`` of every face, (m, 3), for the moved cage ``C`` (k, 3)."""
        C = np.asarray(C, dtype=np.float64)
        _, _, cross, length = self._parts(C)
        return (stretch_factors(self.rest_v, C, self.faces) / length)[:, None] * cross

    def vjp(self, C: ArrayLike, G: ArrayLike) -> Floats:
        """``d(sum G * face_terms(C)) / dC``, (k, 3), for ``G`` (m, 3)."""
        C = np.asarray(C, dtype=np.float64)
        G = np.asarray(G, dtype=np.float64)
        w1, w2, cross, length = self._parts(C)
        n = cross / length[:, None]
        s = stretch_factors(self.rest_v, C, self.faces)
        # s^2 = (|w1|^2 |u2|^2 - 2 (w1.w2)(u1.u2) + |w2|^2 |u1|^2) / (2 (2A)^2)
        denom = 2.0 * self._twice**2 * s
        ds_w1 = (self._u22[:, None] * w1 - self._u12[:, None] * w2) / denom[:, None]
        ds_w2 = (self._u11[:, None] * w2 - self._u12[:, None] * w1) / denom[:, None]
        gn = np.einsum("ij,ij->i", G, n)
        # s G . dn with dn = (I - n n^T) dc / |c| and dc = dw1 x w2 + w1 x dw2
        p = (s / length)[:, None] * (G - gn[:, None] * n)
        g1 = gn[:, None] * ds_w1 + np.cross(w2, p)
        g2 = gn[:, None] * ds_w2 + np.cross(p, w1)
        out = np.zeros_like(C)
        np.add.at(out, self.faces[:, 1], g1)
        np.add.at(out, self.faces[:, 2], g2)
        np.add.at(out, self.faces[:, 0], -(g1 + g2))
        return out
