"""Carrying an asset's own normals through a deformation of its vertices.

A deformed asset keeps its authored shading (hard edges, smoothing groups, custom normals)
when every normal is mapped by the inverse transpose of the deformation gradient of the
triangles it shades, instead of being recomputed from the new faces (which would smooth
every hard edge). The gradient of triangle ``f`` is ``J = D1 D0^-1`` with ``D = [e1, e2,
s n]``: its two edges and its unit normal scaled by ``s = sqrt(2 * area)`` (so a uniform
scaling of the triangle scales ``J`` uniformly). A normal ``n`` shading ``f`` becomes ``J^-T
n``, normalised: the new face normal for ``n`` the old face normal, and a rotation's own
rotation of ``n`` for a rigid motion. A normal shared by several triangles (a smooth vertex)
is the area-weighted mean of its images, normalised.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cagekit.errors import InputError

__all__ = ["transported_normals"]


def transported_normals(V0: ArrayLike, V1: ArrayLike, F: ArrayLike, corner_normals: ArrayLike,
                        corner_groups: ArrayLike, n_groups: int | None = None) -> np.ndarray:
    """Carry normals given at triangle corners through the motion ``V0 -> V1``.

    Parameters
    ----------
    V0, V1 : (n, 3) array_like of float
        Vertices before and after the deformation (same count and order).
    F : (m, 3) array_like of int
        Triangles indexing the vertices.
    corner_normals : (m, 3, 3) array_like of float
        The normal at each corner of each triangle before the deformation (need not be
        unit length; a zero normal stays zero).
    corner_groups : (m, 3) array_like of int
        Which output normal each corner belongs to (for example the index of a
        ``(vertex, normal)`` pair of an OBJ file), in ``[0, k)``; -1 for a corner that has
        no normal. Corners of one group get one normal: the area-weighted mean of their
        carried normals.
    n_groups : int, optional
        ``k``, the number of groups (default ``corner_groups.max() + 1``); groups no
        corner belongs to (an unreferenced vertex's) come back as zero vectors.

    Returns
    -------
    (k, 3) float64 ndarray
        One unit normal per group. A group whose triangles are all degenerate (before or
        after) keeps its first corner's normal, normalised; a group with no corner is 0.

    Raises
    ------
    InputError
        Mismatched shapes or groups out of range.

    Examples
    --------
    >>> V0 = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    >>> V1 = V0 * [2.0, 1.0, 1.0]  # stretch along x: the face normal stays +z
    >>> n = np.tile([0.0, 0.0, 1.0], (1, 3, 1))
    >>> (transported_normals(V0, V1, [[0, 1, 2]], n, [[0, 0, 0]]).round(6) + 0.0).tolist()
    [[0.0, 0.0, 1.0]]
    """
    V0, V1, F, N, G = _checked(V0, V1, F, corner_normals, corner_groups)
    k = (int(G.max()) + 1 if G.size else 0) if n_groups is None else int(n_groups)
    if G.size and G.max() >= k:
        raise InputError(f"corner_groups reach group {int(G.max())}; n_groups is {k}")
    carried, area = _carry(V0, V1, F, N)
    out = np.zeros((k, 3))
    has = G >= 0
    np.add.at(out, G[has], (carried * area[:, None, None])[has])
    length = np.linalg.norm(out, axis=1)
    used = np.bincount(G[has], minlength=k) > 0
    lost = (length <= 1e-300) & used
    if lost.any():  # every triangle of the group degenerate: keep the old normal
        first = np.full(k, -1)
        flat_groups, flat_normals = G[has], N[has]
        first[flat_groups[::-1]] = np.arange(len(flat_groups))[::-1]
        out[lost] = flat_normals[first[lost]]
        length = np.linalg.norm(out, axis=1)
    return out / np.where(length > 1e-300, length, 1.0)[:, None]


def _checked(V0, V1, F, N, G):
    V0 = np.asarray(V0, dtype=np.float64)
    V1 = np.asarray(V1, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    N = np.asarray(N, dtype=np.float64).reshape(-1, 3, 3)
    G = np.asarray(G, dtype=np.int64).reshape(-1, 3)
    if V0.shape != V1.shape or V0.ndim != 2 or V0.shape[1] != 3:
        raise InputError(f"V0 {V0.shape} and V1 {V1.shape} must both be (n, 3)")
    if len(N) != len(F) or len(G) != len(F):
        raise InputError(f"corner_normals ({len(N)}) and corner_groups ({len(G)}) need one "
                         f"row per triangle ({len(F)})")
    if len(F) and (F.min() < 0 or F.max() >= len(V0)):
        raise InputError("F indexes vertices out of range")
    if G.size and G.min() < -1:
        raise InputError("corner_groups must be >= -1")
    return V0, V1, F, N, G


def _carry(V0, V1, F, N):
    """Each corner normal mapped by its triangle's J^-T, unit length, and the triangle's rest
    area (0 where the triangle is degenerate before or after, so it does not count)."""
    D0, area0 = _frames(V0, F)
    D1, area1 = _frames(V1, F)
    good = (area0 > 0) & (area1 > 0)
    carried = np.zeros_like(N)
    if good.any():
        # J^-T n = D1^-T D0^T n: solve D1^T x = D0^T n for the three corners at once
        rhs = np.einsum("mji,mcj->mic", D0[good], N[good])
        x = np.linalg.solve(np.transpose(D1[good], (0, 2, 1)), rhs)
        carried[good] = np.transpose(x, (0, 2, 1))
    length = np.linalg.norm(carried, axis=2, keepdims=True)
    carried = carried / np.where(length > 1e-300, length, 1.0)
    return carried, np.where(good, area0, 0.0)


def _frames(V, F):
    """``D = [e1, e2, sqrt(2 area) n]`` as columns, (m, 3, 3), and the triangle areas."""
    e1 = V[F[:, 1]] - V[F[:, 0]]
    e2 = V[F[:, 2]] - V[F[:, 0]]
    cross = np.cross(e1, e2)
    double_area = np.linalg.norm(cross, axis=1)
    size = np.maximum(np.linalg.norm(e1, axis=1), np.linalg.norm(e2, axis=1))
    degenerate = double_area <= 1e-12 * np.maximum(size, 1e-300) ** 2
    unit = cross / np.where(double_area > 0, double_area, 1.0)[:, None]
    D = np.stack([e1, e2, unit * np.sqrt(double_area)[:, None]], axis=2)
    return D, np.where(degenerate, 0.0, 0.5 * double_area)
