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
boundary-element closed forms, per face: the signed solid angle (Van Oosterom &
Strackee's ``atan2``), and per edge ``log((R_p + R_q + L) / (R_p + R_q - L))`` with the
denominator as ``2 (R_p R_q + d_p . d_q) / (R_p + R_q + L)`` and ``R_p R_q + d_p . d_q =
|d_p x d_q|^2 / (R_p R_q - d_p . d_q)`` where the two vectors point apart, so that the
logarithm stays exact as the point closes on the edge. Then ``psi = (sum_e d_e I_e - h
Omega) / 4 pi`` and ``phi_a += (Gamma_a(rho) Omega - h g_a . sum_e m_e I_e) / 4 pi``
(``h`` the point's height over the face, ``rho`` its foot, ``Gamma_a`` and ``g_a`` the
hat function's value there and its gradient, ``m_e`` and ``d_e`` each edge's outward
in-plane normal and the foot's distance to it).

Points within :data:`SNAP` cage diagonals of the cage (where the integrands are singular)
are evaluated :data:`INSET` diagonals inside it, along the angle-weighted pseudo-normal of
their closest cage point, so reproduction there is off by at most ``INSET * D``. Points
outside take the paper's extension across their exit face, taken to be the face closest
to them: the raw integrals vanish outside (the coordinates sum to zero), and the point's
affine coordinates in the frame of that face (its three vertices and its normal) are
added to the face's vertices and to its ``psi``. The map is then continuous across that
face and reproduces outside points exactly, but it is not continuous where the closest
face changes, so a point far from the cage is only as meaningful as that face's frame;
commands warn with the share outside.
"""

from __future__ import annotations

import numba
import numpy as np

from cagekit.frame import bounding_box_diagonal

__all__ = ["green_coordinates", "stretch_factors", "unit_normals", "SNAP", "INSET"]

#: points closer than this to the cage (in cage diagonals) are evaluated INSET inside it
SNAP = 1e-12
#: how far inside such points are evaluated (cage diagonals): reproduction's error there
INSET = 1e-12

_FOUR_PI = 4.0 * np.pi


@numba.njit(cache=True, error_model="numpy", inline="always")
def _edge_log(dpx, dpy, dpz, dqx, dqy, dqz, length):
    """``integral over the edge p->q of 1 / r``, seen from the origin, without cancellation;
    inf when the origin lies on the edge."""
    rp = np.sqrt(dpx * dpx + dpy * dpy + dpz * dpz)
    rq = np.sqrt(dqx * dqx + dqy * dqy + dqz * dqz)
    dot = dpx * dqx + dpy * dqy + dpz * dqz
    if dot >= 0.0:
        half = rp * rq + dot
    else:
        cx = dpy * dqz - dpz * dqy
        cy = dpz * dqx - dpx * dqz
        cz = dpx * dqy - dpy * dqx
        half = (cx * cx + cy * cy + cz * cz) / (rp * rq - dot)
    s = rp + rq + length
    return np.log(s * s / (2.0 * half))


@numba.njit(cache=True, error_model="numpy", inline="always")
def _angle(ax, ay, az, bx, by, bz):
    """The angle between two vectors, accurate at every angle (``atan2`` of the sine
    and the cosine)."""
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    return np.arctan2(np.sqrt(cx * cx + cy * cy + cz * cz), ax * bx + ay * by + az * bz)


@numba.njit(cache=True, error_model="numpy")
def _solid_angle(c01x, c01y, c01z, c12x, c12y, c12z, c20x, c20y, c20z, h):
    """Signed solid angle of a face from the origin by the spherical excess, from the
    normals ``d_p x d_q`` of the planes through the origin and each edge: the face's
    across an edge sees the same plane's normal negated, bit for bit, so the part that
    is ill-conditioned near the edge cancels between the two faces (the one-``atan2``
    formula loses ``eps / distance`` there)."""
    n01 = np.sqrt(c01x * c01x + c01y * c01y + c01z * c01z)
    n12 = np.sqrt(c12x * c12x + c12y * c12y + c12z * c12z)
    n20 = np.sqrt(c20x * c20x + c20y * c20y + c20z * c20z)
    # a plane through the origin and an edge is undefined only on that edge's line
    a0 = _angle(c20x / n20, c20y / n20, c20z / n20, c01x / n01, c01y / n01, c01z / n01)
    a1 = _angle(c01x / n01, c01y / n01, c01z / n01, c12x / n12, c12y / n12, c12z / n12)
    a2 = _angle(c12x / n12, c12y / n12, c12z / n12, c20x / n20, c20y / n20, c20z / n20)
    excess = 2.0 * np.pi - a0 - a1 - a2
    return -excess if h < 0.0 else excess


@numba.njit(cache=True, error_model="numpy")
def _green_row(x, cage_v, faces, normals, twice_area, edge_len, phi, psi):
    """Raw Green coordinates of one point into ``phi`` (k,) and ``psi`` (m,); False when
    the point is too close to the cage for the integrals (a non-finite value)."""
    phi[:] = 0.0
    m = faces.shape[0]
    d = np.empty((3, 3))
    for j in range(m):
        for c in range(3):
            v = faces[j, c]
            d[c, 0] = cage_v[v, 0] - x[0]
            d[c, 1] = cage_v[v, 1] - x[1]
            d[c, 2] = cage_v[v, 2] - x[2]
        nx, ny, nz = normals[j, 0], normals[j, 1], normals[j, 2]
        h = d[0, 0] * nx + d[0, 1] * ny + d[0, 2] * nz
        # d1 x d2, d2 x d0, d0 x d1: barycentrics of the foot (dotted with n) and solid angle
        c12x = d[1, 1] * d[2, 2] - d[1, 2] * d[2, 1]
        c12y = d[1, 2] * d[2, 0] - d[1, 0] * d[2, 2]
        c12z = d[1, 0] * d[2, 1] - d[1, 1] * d[2, 0]
        c20x = d[2, 1] * d[0, 2] - d[2, 2] * d[0, 1]
        c20y = d[2, 2] * d[0, 0] - d[2, 0] * d[0, 2]
        c20z = d[2, 0] * d[0, 1] - d[2, 1] * d[0, 0]
        c01x = d[0, 1] * d[1, 2] - d[0, 2] * d[1, 1]
        c01y = d[0, 2] * d[1, 0] - d[0, 0] * d[1, 2]
        c01z = d[0, 0] * d[1, 1] - d[0, 1] * d[1, 0]
        omega = _solid_angle(c01x, c01y, c01z, c12x, c12y, c12z, c20x, c20y, c20z, h)
        inv2a = 1.0 / twice_area[j]
        gam0 = (c12x * nx + c12y * ny + c12z * nz) * inv2a
        gam1 = (c20x * nx + c20y * ny + c20z * nz) * inv2a
        gam2 = (c01x * nx + c01y * ny + c01z * nz) * inv2a
        # edges 0->1, 1->2, 2->0: sum of m_e I_e and of d_e I_e
        vx = 0.0
        vy = 0.0
        vz = 0.0
        single = 0.0
        for e in range(3):
            p = e
            q = (e + 1) % 3
            length = edge_len[j, e]
            ie = _edge_log(d[p, 0], d[p, 1], d[p, 2], d[q, 0], d[q, 1], d[q, 2], length)
            tx = (d[q, 0] - d[p, 0]) / length
            ty = (d[q, 1] - d[p, 1]) / length
            tz = (d[q, 2] - d[p, 2]) / length
            mx = ty * nz - tz * ny  # t x n: the edge's outward in-plane normal
            my = tz * nx - tx * nz
            mz = tx * ny - ty * nx
            de = d[p, 0] * mx + d[p, 1] * my + d[p, 2] * mz
            vx += mx * ie
            vy += my * ie
            vz += mz * ie
            single += de * ie
        value = (single - h * omega) / _FOUR_PI
        if not np.isfinite(value):
            return False
        psi[j] = value
        # the hat functions' gradients g_a = n x (c - b) / 2A, for a = 0, 1, 2
        for a in range(3):
            b = (a + 1) % 3
            c = (a + 2) % 3
            ex = d[c, 0] - d[b, 0]
            ey = d[c, 1] - d[b, 1]
            ez = d[c, 2] - d[b, 2]
            gx = (ny * ez - nz * ey) * inv2a
            gy = (nz * ex - nx * ez) * inv2a
            gz = (nx * ey - ny * ex) * inv2a
            gam = gam0 if a == 0 else (gam1 if a == 1 else gam2)
            term = (gam * omega - h * (gx * vx + gy * vy + gz * vz)) / _FOUR_PI
            if not np.isfinite(term):
                return False
            phi[faces[j, a]] += term
    return True


@numba.njit(parallel=True, cache=True, error_model="numpy")
def _green_kernel(points, cage_v, faces, normals, twice_area, edge_len, phi, psi, ok):
    """:func:`_green_row` for every point, in parallel."""
    for i in numba.prange(points.shape[0]):
        ok[i] = _green_row(points[i], cage_v, faces, normals, twice_area, edge_len, phi[i],
                           psi[i])


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
    edge_len = np.linalg.norm(cv[np.roll(faces, -1, axis=1)] - cv[faces], axis=2)
    n, k, m = len(px), len(cv), len(faces)
    phi, psi = np.empty((n, k)), np.empty((n, m))
    if not n:
        return phi, psi
    import igl

    from cagekit.cage import winding_numbers

    sd = igl.signed_distance(px, cv, faces,
                             igl.SignedDistanceType.SIGNED_DISTANCE_TYPE_PSEUDONORMAL)
    distance, closest, foot, pseudo = np.abs(sd[0]), sd[1], sd[2], sd[3]
    inset = distance < SNAP
    outside = winding_numbers(px, cv, faces) < 0.5
    query = px.copy()
    query[inset] = _moved_inside(foot[inset], pseudo[inset])
    ok = np.empty(n, dtype=np.bool_)
    _green_kernel(query, cv, faces, normals, twice, edge_len, phi, psi, ok)
    if not ok.all():
        # a point the distance test let through: move it inside too, once
        bad = np.flatnonzero(~ok)
        query[bad] = _moved_inside(foot[bad], pseudo[bad])
        ok_bad = np.empty(len(bad), dtype=np.bool_)
        phi_bad, psi_bad = np.empty((len(bad), k)), np.empty((len(bad), m))
        _green_kernel(np.ascontiguousarray(query[bad]), cv, faces, normals, twice, edge_len,
                      phi_bad, psi_bad, ok_bad)
        if not ok_bad.all():
            raise FloatingPointError("Green coordinates are not finite at "
                                     f"{int((~ok_bad).sum())} point(s)")
        phi[bad], psi[bad] = phi_bad, psi_bad
    outside &= ~inset
    if outside.any():
        exit_faces = _exit_faces(px[outside], closest[outside], distance[outside], cv, faces,
                                 twice)
        _extend_outside(px[outside], exit_faces, cv, faces, normals,
                        np.flatnonzero(outside), phi, psi)
    psi *= diag
    return phi, psi


def _moved_inside(foot, pseudo) -> np.ndarray:
    """Closest cage points moved :data:`INSET` inside, along the angle-weighted
    pseudo-normals there."""
    norms = np.linalg.norm(pseudo, axis=1, keepdims=True)
    unit = pseudo / np.where(norms > 0, norms, 1.0)
    return foot - INSET * unit


#: a face whose twice-area is below this times its longest edge squared is a sliver: as
#: an exit face its frame would cost digits (eps / this), so a tie goes to a neighbour
SLIVER = 1e-3


def _exit_faces(points, closest, distance, cv, faces, twice_area) -> np.ndarray:
    """Each outside point's exit face: its closest face, or, where that is a sliver and
    the closest cage point lies on its edge or corner, the best-shaped face around that
    corner that is as close (libigl breaks such ties arbitrarily)."""
    edges = cv[np.roll(faces, -1, axis=1)] - cv[faces]
    longest = np.max(np.einsum("fij,fij->fi", edges, edges), axis=1)
    shape = twice_area / longest
    chosen = closest.copy()
    for i in np.flatnonzero(shape[closest] < SLIVER):
        ring = np.flatnonzero(np.isin(faces, faces[closest[i]]).any(axis=1))
        ring = ring[shape[ring] >= SLIVER]
        if not len(ring):
            continue
        import igl

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
