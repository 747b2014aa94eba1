"""Edge topology and connected components of a triangle mesh (a cage or any surface).

Nothing here reorders, merges or drops vertices: a cage's vertex order is its identity.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cagekit.typed import Ints

__all__ = ["CageTopology", "cage_topology", "unique_edges", "face_components",
           "vertex_components", "signed_volume"]


@dataclass(frozen=True)
class CageTopology:
    """Undirected edges of a closed triangle mesh and how its faces use them.

    Attributes
    ----------
    edges : (e, 2) int64
        Unique undirected edges, each stored with ``edges[i, 0] < edges[i, 1]``.
    face_edges : (m, 3) int64
        For face ``(a, b, c)`` the indices of its directed edges ``a->b``, ``b->c``, ``c->a``.
    face_edge_signs : (m, 3) float64
        +1 where the face traverses the edge from its lower to its higher vertex, else -1.
    """

    edges: np.ndarray
    face_edges: np.ndarray
    face_edge_signs: np.ndarray


def cage_topology(cage_f: np.ndarray) -> CageTopology:
    """Unique edges of a triangle mesh and the signed edge indices of each face.

    Parameters
    ----------
    cage_f : (m, 3) int64
        Triangle faces.

    Returns
    -------
    CageTopology
        See :class:`CageTopology`. Its arrays are read-only: the topologies of the last 64
        face arrays of up to 20,000 faces are kept and handed out again (a training step
        asks for its cage's five times).

    Examples
    --------
    >>> t = cage_topology(np.array([[0, 1, 2], [0, 2, 3]]))
    >>> t.edges.tolist()
    [[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]
    """
    faces = np.asarray(cage_f, dtype=np.int64)
    key = None
    if faces.ndim == 2 and len(faces) <= _CACHED_FACES:
        key = (faces.shape, faces.tobytes())
        known = _TOPOLOGIES.get(key)
        if known is not None:
            return known
    topology = _topology(faces)
    if key is not None:
        with _TOPOLOGIES_LOCK:
            while len(_TOPOLOGIES) >= _CACHED_TOPOLOGIES:
                _TOPOLOGIES.pop(next(iter(_TOPOLOGIES)))  # the oldest
            _TOPOLOGIES[key] = topology
    return topology


#: cages of up to this many faces have their topology kept (a training step asks the same
#: cage's topology five times, 0.1 ms each); the last :data:`_CACHED_TOPOLOGIES` of them
_CACHED_FACES = 20_000
_CACHED_TOPOLOGIES = 64
_TOPOLOGIES: dict[tuple, CageTopology] = {}
_TOPOLOGIES_LOCK = threading.Lock()


def _topology(faces: np.ndarray) -> CageTopology:
    """:func:`cage_topology` computed, its arrays read-only (they may be shared)."""
    directed = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)
    lo = directed.min(axis=1)
    hi = directed.max(axis=1)
    edges, inverse = np.unique(np.stack([lo, hi], axis=1), axis=0, return_inverse=True)
    signs = np.where(directed[:, 0] < directed[:, 1], 1.0, -1.0)
    topology = CageTopology(
        edges=np.ascontiguousarray(edges, dtype=np.int64),
        face_edges=np.ascontiguousarray(inverse.reshape(-1, 3), dtype=np.int64),
        face_edge_signs=np.ascontiguousarray(signs.reshape(-1, 3)),
    )
    for array in (topology.edges, topology.face_edges, topology.face_edge_signs):
        array.flags.writeable = False
    return topology


def unique_edges(faces: ArrayLike) -> Ints:
    """Undirected edges of a triangle mesh, each once: ``cage_topology(faces).edges``.

    Parameters
    ----------
    faces : (m, 3) array_like of int
        May be empty.

    Returns
    -------
    (e, 2) int64
        Sorted pairs ``(i, j)`` with ``i < j``, in lexicographic order.

    Examples
    --------
    >>> unique_edges(np.array([[0, 1, 2], [0, 2, 3]])).tolist()
    [[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]
    """
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if not len(faces):
        return np.zeros((0, 2), dtype=np.int64)
    return cage_topology(faces).edges.copy()  # the cached one is shared and read-only


def signed_volume(cage_v: np.ndarray, cage_f: np.ndarray) -> float:
    """Signed volume enclosed by a closed triangle mesh (positive for outward normals).

    Parameters
    ----------
    cage_v : (k, 3) float64
    cage_f : (m, 3) int64

    Returns
    -------
    float
    """
    v = np.asarray(cage_v, dtype=np.float64)
    f = np.asarray(cage_f, dtype=np.int64)
    centre = v.mean(axis=0)
    a, b, c = (v[f[:, i]] - centre for i in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def face_components(n_vertices: int, faces: np.ndarray) -> np.ndarray:
    """Connected-component label of each face (faces sharing a vertex are connected).

    Parameters
    ----------
    n_vertices : int
    faces : (m, 3) int64

    Returns
    -------
    (m,) int labels, ``0 .. components - 1``

    Examples
    --------
    >>> face_components(6, np.array([[0, 1, 2], [3, 4, 5], [0, 2, 1]])).tolist()
    [0, 1, 0]
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = len(faces)
    rows = np.repeat(np.arange(m), 3)
    graph = coo_matrix((np.ones(3 * m), (rows, faces.ravel())), shape=(m, n_vertices)).tocsr()
    _, labels = connected_components(graph @ graph.T, directed=False)
    return labels


def vertex_components(n_vertices: int, faces: np.ndarray) -> np.ndarray:
    """The connected component of each vertex through the faces (:func:`face_components`).

    Returns
    -------
    (n,) int labels, ``0 .. components - 1``; -1 for a vertex on no face

    Examples
    --------
    >>> vertex_components(7, np.array([[0, 1, 2], [3, 4, 5]])).tolist()
    [0, 0, 0, 1, 1, 1, -1]
    """
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    labels = np.full(n_vertices, -1)
    labels[faces.ravel()] = np.repeat(face_components(n_vertices, faces), 3)
    return labels
