"""Small primitive cages used in examples, tests and benchmarks.

Every function returns ``(vertices (k, 3) float64, faces (m, 3) int64)`` for a closed,
2-manifold triangle mesh with outward normals.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cagekit.typed import Faces, Vertices

__all__ = ["box_cage", "icosphere_cage"]


def box_cage(divisions: int = 1, half_extent: ArrayLike = 1.0) -> tuple[Vertices, Faces]:
    """A box centred at the origin, each side split into ``divisions x divisions`` squares.

    Each square is cut into two triangles, so with ``divisions >= 1`` every diagonal edge lies
    between two coplanar faces, and with ``divisions >= 2`` so do the grid edges: the cases
    where textbook MVC code loses exactness.

    Parameters
    ----------
    divisions : int, default 1
        Squares per side of each face of the box; the cage has ``12 * divisions**2`` faces.
    half_extent : float or (3,) array_like, default 1.0
        Half the side length along x, y and z.

    Returns
    -------
    vertices : (k, 3) float64
    faces : (12 * divisions**2, 3) int64

    Examples
    --------
    >>> v, f = box_cage(2)
    >>> v.shape, f.shape
    ((26, 3), (48, 3))
    """
    n = int(divisions)
    if n < 1:
        raise ValueError("divisions must be >= 1")
    grid = np.linspace(-1.0, 1.0, n + 1)
    index: dict[tuple[int, int, int], int] = {}
    vertices: list[tuple[float, float, float]] = []

    def vid(i: int, j: int, k: int) -> int:
        key = (i, j, k)
        if key not in index:
            index[key] = len(vertices)
            vertices.append((grid[i], grid[j], grid[k]))
        return index[key]

    faces = []
    for axis in range(3):
        u_ax, v_ax = (axis + 1) % 3, (axis + 2) % 3
        for side, flip in ((0, True), (n, False)):
            for a in range(n):
                for b in range(n):
                    quad = []
                    for da, db in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        ijk = [0, 0, 0]
                        ijk[axis], ijk[u_ax], ijk[v_ax] = side, a + da, b + db
                        quad.append(vid(*ijk))
                    if flip:
                        quad = quad[::-1]
                    faces.append((quad[0], quad[1], quad[2]))
                    faces.append((quad[0], quad[2], quad[3]))
    v = np.asarray(vertices, dtype=np.float64) * np.asarray(half_extent, dtype=np.float64)
    return v, np.asarray(faces, dtype=np.int64)


def icosphere_cage(subdivisions: int = 1, radius: float = 1.0) -> tuple[Vertices, Faces]:
    """An icosphere (the paper's template cage is ``subdivisions=1``: 42 vertices, 80 faces).

    Parameters
    ----------
    subdivisions : int, default 1
    radius : float, default 1.0

    Returns
    -------
    vertices : (k, 3) float64
    faces : (m, 3) int64

    Examples
    --------
    >>> v, f = icosphere_cage(1)
    >>> v.shape, f.shape
    ((42, 3), (80, 3))
    """
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)
