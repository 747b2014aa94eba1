"""The parts of a shape: its connected pieces of surface, seams joined.

A part is a connected component of the faces, where two faces are connected when they share
a vertex, **or an edge by position**: both of its ends at the same two positions. Artists'
files repeat the vertices of an edge wherever the texture coordinates or normals change
across it (a UV seam, a hard edge), so components by vertex index alone cut one seat into
as many pieces as it has seams: 426 "parts" for an armchair of ``sweethome3d-furniture``
that has 6. Positions are compared exactly (with ``-0.0`` read as ``0.0``), for the
labelling only: the mesh is not changed.

Pieces that touch without sharing an edge stay separate parts: a cushion resting on a seat,
a leg glued to a rail, or a rail pushed into a post that happens to have a vertex where the
post has one (procedural chairs have such rails). Every part-wise figure and term of cagekit
takes its parts from here: ``cagekit deform``'s part-affinity term, the learned mode's part
term, :func:`cagekit.metrics.part_nonaffinity` and the crossing test of ``cagekit amplify``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cagekit.geometry.checks import as_faces, as_vertices, unique_rows
from cagekit.typed import Ints

__all__ = ["face_parts", "vertex_parts"]


def face_parts(vertices: ArrayLike, faces: ArrayLike) -> Ints:
    """The part of each face: connected components through shared vertices and seams.

    Parameters
    ----------
    vertices : (n, 3) array_like of float
    faces : (m, 3) array_like of int

    Returns
    -------
    (m,) int64 ndarray
        Labels ``0 .. parts - 1``, numbered in the order of each part's first face.

    Raises
    ------
    InputError
        No vertices, non-finite vertices, faces out of range.

    Examples
    --------
    Two triangles that share an edge by position only (vertices 3 and 4 repeat 1 and 2),
    and a third triangle that touches them at one position only:

    >>> V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0],
    ...      [1, 1, 0], [2, 1, 0], [1, 2, 0]]
    >>> face_parts(V, [[0, 1, 2], [3, 5, 4], [6, 7, 8]]).tolist()
    [0, 0, 1]
    """
    V = as_vertices(vertices, "vertices")
    return _face_parts(V, as_faces(faces, len(V)))


def vertex_parts(vertices: ArrayLike, faces: ArrayLike) -> Ints:
    """The part of each vertex (the part of its faces, :func:`face_parts`); -1 on no face.

    Parameters
    ----------
    vertices : (n, 3) array_like of float
    faces : (m, 3) array_like of int

    Returns
    -------
    (n,) int64 ndarray
        Labels ``0 .. parts - 1`` as :func:`face_parts` numbers them, or -1.

    Raises
    ------
    InputError
        No vertices, non-finite vertices, faces out of range.

    Examples
    --------
    >>> V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [9, 9, 9]]
    >>> vertex_parts(V, [[0, 1, 2], [3, 5, 4]]).tolist()
    [0, 0, 0, 0, 0, 0, -1]
    """
    V = as_vertices(vertices, "vertices")
    F = as_faces(faces, len(V))
    labels = np.full(len(V), -1, dtype=np.int64)
    labels[F.ravel()] = np.repeat(_face_parts(V, F), 3)
    return labels


def _face_parts(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """:func:`face_parts` of checked arrays."""
    if not len(F):
        return np.zeros(0, dtype=np.int64)
    labels = _components(len(V), F, _seam_edges(V, F))
    _, first, compact = np.unique(labels, return_index=True, return_inverse=True)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[compact.reshape(-1)]


def _seam_edges(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(m, 3) int64: an index per face side, shared by the sides whose two ends are at the
    same two positions (the sides of one edge, across a seam or not)."""
    P = _positions(V)[F]
    ends = np.sort(np.stack([P, np.roll(P, -1, axis=1)], axis=-1).reshape(-1, 2), axis=1)
    side = unique_rows(ends)[1]  # numpy's np.unique(axis=0) numbering, 10x faster
    # a side of no length (a degenerate face's) is no edge: each is its own node, so two
    # pieces touching at one point with such faces there stay apart
    point = ends[:, 0] == ends[:, 1]
    side[point] = side.max() + 1 + np.arange(int(point.sum()))
    return side.reshape(-1, 3)


def _positions(V: np.ndarray) -> np.ndarray:
    """(n,) int64: the number of each vertex's position among the distinct positions in
    lexicographic order (``np.unique(V, axis=0, return_inverse=True)[1]``, 3x faster;
    ``-0.0`` read as ``0.0``)."""
    W = V + 0.0  # -0.0 becomes 0.0
    order = np.lexsort(W.T[::-1])  # the first coordinate first
    ranked = W[order]
    new = np.ones(len(W), dtype=bool)
    new[1:] = (ranked[1:] != ranked[:-1]).any(axis=1)
    position = np.empty(len(W), dtype=np.int64)
    position[order] = np.cumsum(new) - 1
    return position


def _components(n: int, F: np.ndarray, sides: np.ndarray) -> np.ndarray:
    """(m,) component labels of the faces in the graph that joins each face to its three
    vertices and its three sides."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = len(F)
    face = np.repeat(np.arange(m), 3)
    other = np.concatenate([m + F.ravel(), m + n + sides.ravel()])
    size = m + n + int(sides.max()) + 1
    graph = coo_matrix((np.ones(2 * len(face), dtype=np.int8),
                        (np.concatenate([face, face]), other)), shape=(size, size))
    return connected_components(graph, directed=False)[1][:m]
