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
one ``atan2`` as the argument of a product (:func:`_excess`). Reproduction holds to
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

from cagekit.frame import bounding_box_diagonal

__all__ = ["green_coordinates", "evaluation_plan", "EvaluationPlan", "FaceTerms", "stretch_factors",
           "unit_normals", "SNAP", "INSET"]

#: points closer than this to the cage (in cage diagonals) are evaluated INSET from it
SNAP = 3e-11
#: how far inside such points are evaluated (cage diagonals): reproduction's error there
INSET = 3e-11

_INV_FOUR_PI = 1.0 / (4.0 * np.pi)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _corner(ax, ay, az, bx, by, bz):
    """Cosine and sine of the angle between two unit vectors (the sine from the cross
    product's length: accurate at every angle)."""
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    return ax * bx + ay * by + az * bz, np.sqrt(cx * cx + cy * cy + cz * cz)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _excess(c0, s0, c1, s1, c2, s2, foot_inside):
    """``|Omega| = 2 pi - (a_0 + a_1 + a_2)`` from the corners' cosines and sines.

    One ``atan2``: the argument of the product of the ``cos a + i sin a`` is the angle sum
    (in [0, 2 pi]) modulo 2 pi, ambiguous only near 0, between ``|Omega|`` near 0 and
    near 2 pi. Near 2 pi needs the point's foot inside the face (from outside it the face
    fills less than a hemisphere); only then are the three angles summed one by one.
    """
    re = c0 * c1 - s0 * s1
    im = c0 * s1 + s0 * c1
    re, im = re * c2 - im * s2, re * s2 + im * c2
    arg = np.arctan2(im, re)
    if abs(arg) >= 0.5 * np.pi:
        return 2.0 * np.pi - arg if arg > 0.0 else -arg
    if not foot_inside:
        return abs(arg)
    return 2.0 * np.pi - np.arctan2(s0, c0) - np.arctan2(s1, c1) - np.arctan2(s2, c2)


@numba.njit(cache=True, error_model="numpy")
def _green_row(x, cage_v, faces, edges, face_edges, face_signs, normals, face_off, edge_m,
               edge_off, grads, inv_twice, edge_len, D, R, N, I, phi, psi):
    """Raw Green coordinates of one point into ``phi`` (k,) and ``psi`` (m,); returns the
    point's distance to the cage, or -1 when it is too close for the integrals (a
    non-finite value).

    Per vertex: ``d = v - x`` and its length; per undirected edge: the unit normal of
    the plane through ``x`` and the edge (``d_p x d_q``, negated bit for bit in the face
    across) and ``I_e``; per face: the solid angle by the spherical excess of those
    normals, the foot's barycentrics and the two potentials. ``D, R, N, I`` are scratch.
    """
    k = cage_v.shape[0]
    nearest = np.inf
    for v in range(k):
        D[v, 0] = cage_v[v, 0] - x[0]
        D[v, 1] = cage_v[v, 1] - x[1]
        D[v, 2] = cage_v[v, 2] - x[2]
        R[v] = np.sqrt(D[v, 0] ** 2 + D[v, 1] ** 2 + D[v, 2] ** 2)
        nearest = min(nearest, R[v])
    for e in range(edges.shape[0]):
        p = edges[e, 0]
        q = edges[e, 1]
        cx = D[p, 1] * D[q, 2] - D[p, 2] * D[q, 1]
        cy = D[p, 2] * D[q, 0] - D[p, 0] * D[q, 2]
        cz = D[p, 0] * D[q, 1] - D[p, 1] * D[q, 0]
        cross2 = cx * cx + cy * cy + cz * cz
        norm = np.sqrt(cross2)
        # N holds the unnormalised cross product (barycentrics) and its unit version
        N[e, 0] = cx
        N[e, 1] = cy
        N[e, 2] = cz
        inv = 1.0 / norm
        N[e, 3] = cx * inv
        N[e, 4] = cy * inv
        N[e, 5] = cz * inv
        # integral of 1/r along the edge: log((R_p + R_q + L)^2 / (2 (R_p R_q + d_p.d_q)))
        dot = D[p, 0] * D[q, 0] + D[p, 1] * D[q, 1] + D[p, 2] * D[q, 2]
        # distance to the edge where the foot falls on it: |d_p x d_q| / L
        if R[p] * R[p] - dot >= 0.0 and R[q] * R[q] - dot >= 0.0:
            nearest = min(nearest, norm / edge_len[e])
        rr = R[p] * R[q]
        half = rr + dot if dot >= 0.0 else cross2 / (rr - dot)
        total = R[p] + R[q] + edge_len[e]
        I[e] = np.log(total * total / (2.0 * half))
    m = faces.shape[0]
    for j in range(m):
        nx, ny, nz = normals[j, 0], normals[j, 1], normals[j, 2]
        h = face_off[j] - (x[0] * nx + x[1] * ny + x[2] * nz)
        e0, e1, e2 = face_edges[j, 0], face_edges[j, 1], face_edges[j, 2]
        s0, s1, s2 = face_signs[j, 0], face_signs[j, 1], face_signs[j, 2]
        # the spherical triangle's angles, between the planes of consecutive edges
        # (flipping either normal flips the cosine and leaves the sine)
        c0, sn0 = _corner(N[e2, 3], N[e2, 4], N[e2, 5], N[e0, 3], N[e0, 4], N[e0, 5])
        c1, sn1 = _corner(N[e0, 3], N[e0, 4], N[e0, 5], N[e1, 3], N[e1, 4], N[e1, 5])
        c2, sn2 = _corner(N[e1, 3], N[e1, 4], N[e1, 5], N[e2, 3], N[e2, 4], N[e2, 5])
        c0 *= s2 * s0
        c1 *= s0 * s1
        c2 *= s1 * s2
        # the foot's barycentrics: (d1 x d2) . n, (d2 x d0) . n, (d0 x d1) . n over 2A
        gam0 = s1 * (N[e1, 0] * nx + N[e1, 1] * ny + N[e1, 2] * nz) * inv_twice[j]
        gam1 = s2 * (N[e2, 0] * nx + N[e2, 1] * ny + N[e2, 2] * nz) * inv_twice[j]
        gam2 = s0 * (N[e0, 0] * nx + N[e0, 1] * ny + N[e0, 2] * nz) * inv_twice[j]
        # generous (a sliver's barycentrics are rounded at ~eps / its area): a false
        # "inside" only costs the three-atan2 sum
        slack = -1e-3 - 1e-14 * inv_twice[j]
        foot_inside = gam0 >= slack and gam1 >= slack and gam2 >= slack
        if gam0 >= 0.0 and gam1 >= 0.0 and gam2 >= 0.0:
            nearest = min(nearest, abs(h))
        omega = _excess(c0, sn0, c1, sn1, c2, sn2, foot_inside)
        if h < 0.0:
            omega = -omega
        vx = 0.0
        vy = 0.0
        vz = 0.0
        single = 0.0
        for c in range(3):
            ie = I[face_edges[j, c]]
            mx, my, mz = edge_m[j, c, 0], edge_m[j, c, 1], edge_m[j, c, 2]
            vx += mx * ie
            vy += my * ie
            vz += mz * ie
            single += (edge_off[j, c] - (x[0] * mx + x[1] * my + x[2] * mz)) * ie
        psi[j] = (single - h * omega) * _INV_FOUR_PI
        for a in range(3):
            gam = gam0 if a == 0 else (gam1 if a == 1 else gam2)
            phi[faces[j, a]] += (gam * omega - h * (grads[j, a, 0] * vx + grads[j, a, 1] * vy
                                                    + grads[j, a, 2] * vz)) * _INV_FOUR_PI
    # one check at the end: a non-finite term anywhere reaches these sums
    total = 0.0
    for v in range(k):
        total += phi[v]
    for j in range(m):
        total += psi[j]
    return nearest if np.isfinite(total) else -1.0


@numba.njit(parallel=True, cache=True, error_model="numpy")
def _green_kernel(points, cage_v, faces, edges, face_edges, face_signs, normals, face_off,
                  edge_m, edge_off, grads, inv_twice, edge_len, n_chunks, phi, psi, dist):
    """:func:`_green_row` for every point, chunks of points in parallel (scratch once per
    chunk: O(k + e) memory); each point's distance to the cage into ``dist``."""
    n = points.shape[0]
    k = cage_v.shape[0]
    ne = edges.shape[0]
    n_chunks = max(1, min(n, n_chunks))
    for chunk in numba.prange(n_chunks):
        D = np.empty((k, 3))
        R = np.empty(k)
        N = np.empty((ne, 6))
        I = np.empty(ne)
        for i in range(chunk * n // n_chunks, (chunk + 1) * n // n_chunks):
            phi[i, :] = 0.0
            dist[i] = _green_row(points[i], cage_v, faces, edges, face_edges, face_signs,
                               normals, face_off, edge_m, edge_off, grads, inv_twice,
                               edge_len, D, R, N, I, phi[i], psi[i])


def _face_constants(cv, faces, normals, twice):
    """What does not depend on the point: the faces' offsets along their normals, their
    edges' outward in-plane normals and offsets along them, the hat functions' in-plane
    gradients ``n x (v_c - v_b) / 2A``, and the unique edges' lengths."""
    from cagekit.cage import cage_topology

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


def unit_normals(cage_v, cage_f) -> tuple[np.ndarray, np.ndarray]:
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


def stretch_factors(rest_v, new_v, cage_f) -> np.ndarray:
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
    >>> from cagekit.shapes import box_cage
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


def green_coordinates(points, cage_v, cage_f) -> tuple[np.ndarray, np.ndarray]:
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
    >>> from cagekit.shapes import box_cage
    >>> v, f = box_cage()
    >>> phi, psi = green_coordinates([[0.1, 0.2, -0.3]], v, f)
    >>> n, _ = unit_normals(v, f)
    >>> bool(np.allclose(phi @ v + psi @ n, [[0.1, 0.2, -0.3]])), round(float(phi.sum()), 12)
    (True, 1.0)
    """
    phi, psi, _ = _coordinates_and_plan(points, cage_v, cage_f)
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
    """

    evaluated: np.ndarray
    outside_rows: np.ndarray
    exit_faces: np.ndarray


def evaluation_plan(points, cage_v, cage_f) -> EvaluationPlan:
    """The :class:`EvaluationPlan` of :func:`green_coordinates` for these points (the
    torch twin, ``cagekit_learn.green``, evaluates and extends where the core does)."""
    return _coordinates_and_plan(points, cage_v, cage_f)[2]


def _coordinates_and_plan(points, cage_v, cage_f):
    """:func:`green_coordinates` and its :class:`EvaluationPlan`."""
    from cagekit.errors import InputError

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
        return phi, psi, EvaluationPlan(pts.copy(), no_rows, no_rows)
    dist = np.empty(n)
    _green_kernel(px, cv, faces, *constants[:3], normals, *constants[3:], chunks, phi, psi,
                  dist)
    # the solid angles sum to 4 pi inside and to 0 outside (the kernel's own winding number)
    outside = phi.sum(axis=1) < 0.5
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
        outside[near] = phi_near.sum(axis=1) < 0.5
    rows, exit_faces = np.flatnonzero(outside), no_rows
    if len(rows):
        exit_faces = _exit_faces(evaluated[rows], cv, faces, twice)
        _extend_outside(evaluated[rows], exit_faces, cv, faces, normals, rows, phi, psi)
    psi *= diag
    plan = EvaluationPlan(np.where(evaluated == px, pts, evaluated * diag + centre), rows,
                          exit_faces)
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
    >>> from cagekit.shapes import box_cage
    >>> v, f = box_cage()
    >>> terms = FaceTerms(v, f)
    >>> n, _ = unit_normals(v, f)
    >>> bool(np.allclose(terms(2.0 * v), 2.0 * n))
    True
    """

    def __init__(self, rest_v, cage_f):
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

    def __call__(self, C) -> np.ndarray:
        """``s_j n'_j`` of every face, (m, 3), for the moved cage ``C`` (k, 3)."""
        C = np.asarray(C, dtype=np.float64)
        _, _, cross, length = self._parts(C)
        return (stretch_factors(self.rest_v, C, self.faces) / length)[:, None] * cross

    def vjp(self, C, G) -> np.ndarray:
        """``d(sum G * face_terms(C)) / dC``, (k, 3), for ``G`` (m, 3)."""
        C = np.asarray(C, dtype=np.float64)
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
