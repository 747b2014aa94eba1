"""Cages: validation, orientation, edge topology and the enclosure test.

A cage is a closed, 2-manifold triangle mesh with consistently oriented faces whose normals
point outward (positive signed volume). Its vertex order is its identity: nothing here ever
reorders, merges or drops cage vertices. :func:`check_cage` is the gate every cage passes
before coordinates are computed; it returns the faces, flipped if the cage was consistently
oriented inward, and raises :class:`cagekit.CageError` for anything it cannot fix.

Decisions
---------
* An open cage (a boundary edge), a non-manifold edge (shared by more than two faces), an
  inconsistently oriented pair of faces, a face repeating a vertex or of zero area (twice
  its area below 1e-24 D**2, D the bounding-box diagonal), an index out of range and
  non-finite coordinates are errors. Near-degenerate (sliver) faces are fine. A
  consistently *inward* cage is flipped, not refused.
* A cage with several closed components is accepted (each component is checked); its
  orientation is decided per component by the sign of the component's volume.
* Unreferenced vertices are allowed: they keep their index and get zero weight.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cagekit.errors import CageError

__all__ = ["CageTopology", "cage_topology", "check_cage", "signed_volume", "cage_encloses",
           "winding_numbers"]


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
        See :class:`CageTopology`.

    Examples
    --------
    >>> t = cage_topology(np.array([[0, 1, 2], [0, 2, 3]]))
    >>> t.edges.tolist()
    [[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]
    """
    faces = np.asarray(cage_f, dtype=np.int64)
    directed = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)
    lo = directed.min(axis=1)
    hi = directed.max(axis=1)
    edges, inverse = np.unique(np.stack([lo, hi], axis=1), axis=0, return_inverse=True)
    signs = np.where(directed[:, 0] < directed[:, 1], 1.0, -1.0)
    return CageTopology(
        edges=np.ascontiguousarray(edges, dtype=np.int64),
        face_edges=np.ascontiguousarray(inverse.reshape(-1, 3), dtype=np.int64),
        face_edge_signs=np.ascontiguousarray(signs.reshape(-1, 3)),
    )


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


def _components(n_vertices: int, faces: np.ndarray) -> np.ndarray:
    """Connected-component label of each face (faces sharing a vertex are connected)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = len(faces)
    rows = np.repeat(np.arange(m), 3)
    graph = coo_matrix((np.ones(3 * m), (rows, faces.ravel())), shape=(m, n_vertices)).tocsr()
    _, labels = connected_components(graph @ graph.T, directed=False)
    return labels


def check_cage(cage_v, cage_f, name: str | None = None) -> np.ndarray:
    """Validate a cage and return its faces oriented outward.

    Parameters
    ----------
    cage_v : (k, 3) array_like of float
        Cage vertices; must be finite.
    cage_f : (m, 3) array_like of int
        Triangle faces.
    name : str, optional
        File name (or other label) put in front of error messages.

    Returns
    -------
    faces : (m, 3) int64
        The faces, with every component whose volume was negative flipped so that all
        normals point outward.

    Raises
    ------
    CageError
        Non-finite vertices, bad face array, an index out of range, a face repeating a
        vertex or of zero area, a boundary (open cage), a non-manifold edge, inconsistent
        orientation or a component of zero volume.

    Examples
    --------
    >>> import cagekit.shapes as shapes
    >>> v, f = shapes.box_cage()
    >>> check_cage(v, f[:, ::-1]).tolist() == f.tolist()   # an inward cage is flipped
    True
    """
    v = np.asarray(cage_v, dtype=np.float64)
    f = np.asarray(cage_f)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 4:
        raise CageError(f"cage vertices must be a (k, 3) array with k >= 4, got {v.shape}", name)
    if not np.all(np.isfinite(v)):
        raise CageError("cage has non-finite (NaN or inf) vertex coordinates", name)
    if f.ndim != 2 or f.shape[1] != 3 or len(f) < 4 or not np.issubdtype(f.dtype, np.integer):
        raise CageError(f"cage faces must be an (m, 3) integer array with m >= 4, got {f.shape}",
                        name)
    f = f.astype(np.int64)
    if f.min() < 0 or f.max() >= len(v):
        raise CageError(f"cage face index out of range 0..{len(v) - 1}", name)
    if np.any((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0])):
        raise CageError("cage has a degenerate face that repeats a vertex", name)

    twice_area = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]),
                                axis=1)
    diagonal = np.linalg.norm(v.max(axis=0) - v.min(axis=0))
    if np.any(twice_area <= 1e-24 * diagonal**2):
        raise CageError(f"cage face {int(np.argmin(twice_area))} has zero area", name)

    topo = cage_topology(f)
    uses = np.bincount(topo.face_edges.ravel(), minlength=len(topo.edges))
    if np.any(uses == 1):
        a, b = topo.edges[np.argmax(uses == 1)]
        raise CageError(f"cage is open: edge ({a}, {b}) has only one face; a closed cage is "
                        "required", name)
    if np.any(uses > 2):
        a, b = topo.edges[np.argmax(uses > 2)]
        raise CageError(f"cage is not 2-manifold: edge ({a}, {b}) has {uses.max()} faces", name)
    signed_uses = np.zeros(len(topo.edges))
    np.add.at(signed_uses, topo.face_edges.ravel(), topo.face_edge_signs.ravel())
    if np.any(signed_uses != 0):
        a, b = topo.edges[np.argmax(signed_uses != 0)]
        raise CageError(f"cage faces are not consistently oriented (edge ({a}, {b}))", name)

    labels = _components(len(v), f)
    out = f.copy()
    for label in np.unique(labels):
        sel = labels == label
        vol = signed_volume(v, f[sel])
        scale = np.ptp(v[np.unique(f[sel])], axis=0).max()
        if abs(vol) <= 1e-12 * scale**3:
            raise CageError("cage (or one of its components) encloses zero volume", name)
        if vol < 0:
            out[sel] = f[sel][:, ::-1]
    return out


def winding_numbers(points, cage_v, cage_f) -> np.ndarray:
    """Generalised winding number of a closed cage at each point (libigl).

    Parameters
    ----------
    points : (n, 3) array_like of float
    cage_v : (k, 3) array_like of float
    cage_f : (m, 3) array_like of int
        Outward-oriented faces.

    Returns
    -------
    (n,) float64
        About 1 inside, 0 outside, 0.5 on the surface.
    """
    import igl

    p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    return np.asarray(igl.winding_number(np.ascontiguousarray(cage_v, dtype=np.float64),
                                         np.ascontiguousarray(cage_f, dtype=np.int64), p))


def cage_encloses(points, cage_v, cage_f, threshold: float = 0.5) -> bool:
    """Whether every point lies inside (or on) the cage.

    Uses libigl's generalised winding number: a point counts as enclosed when its winding
    number is at least ``threshold`` (0.5 is the value exactly on the surface).

    Parameters
    ----------
    points : (n, 3) array_like of float
    cage_v : (k, 3) array_like of float
    cage_f : (m, 3) array_like of int
        Faces oriented outward (see :func:`check_cage`).
    threshold : float, default 0.5

    Returns
    -------
    bool

    Examples
    --------
    >>> import cagekit.shapes as shapes
    >>> v, f = shapes.box_cage()
    >>> cage_encloses([[0.0, 0.0, 0.0]], v, f), cage_encloses([[3.0, 0.0, 0.0]], v, f)
    (True, False)
    """
    wn = winding_numbers(points, cage_v, cage_f)
    return bool(np.all(wn >= threshold - 1e-9))
