"""A valid cage: check_cage, self-intersections, winding numbers and the enclosure test.

A cage is a closed, 2-manifold triangle mesh with consistently oriented, outward faces
(positive signed volume), and its vertex order is its identity: nothing here reorders,
merges or drops cage vertices. :func:`check_cage` is the gate every cage passes before
coordinates are computed. It raises :class:`cagekit.CageError` for an open or non-manifold
edge, a non-manifold vertex (parts of the cage touching at one vertex only), inconsistent
orientation, a face that repeats a vertex or has zero area (twice its
area below ``1e-24 D**2``, ``D`` the bounding-box diagonal), an index out of range,
non-finite coordinates and, by default, faces that cross one another. Slivers are fine, a
consistently inward cage is flipped rather than refused, several closed components are each
checked and oriented by their own volume, and unreferenced vertices keep their index and
get zero weight. See docs/architecture.md.
"""

from __future__ import annotations

import threading
import warnings

import numpy as np
from numpy.typing import ArrayLike

from cagekit.cage.topology import cage_topology, face_components, signed_volume
from cagekit.errors import CageError, CagekitWarning, InputError
from cagekit.typed import Bools, Faces, Floats, Ints

__all__ = ["check_cage", "self_intersecting_faces", "warn_self_intersecting",
           "cage_encloses", "winding_numbers", "distance_in_diagonals"]


def check_cage(cage_v: ArrayLike, cage_f: ArrayLike, name: str | None = None, *,
               intersections: bool = True) -> Faces:
    """Validate a cage and return its faces oriented outward.

    Parameters
    ----------
    cage_v : (k, 3) array_like of float
        Cage vertices; must be finite.
    cage_f : (m, 3) array_like of int
        Triangle faces.
    name : str, optional
        File name (or other label) put in front of error messages.
    intersections : bool, default True
        Also refuse a cage that intersects itself (:func:`self_intersecting_faces`, an
        exact test costing about a millisecond per 100 faces). Coordinates are defined for
        such a cage, but they fold the space: a point inside two sheets moves with both.
        False skips the test, for cages known to be free of it (a fitted cage, the
        template) or moved on purpose (a network's prediction during training).

    Returns
    -------
    faces : (m, 3) int64
        The faces, with every component whose volume was negative flipped so that all
        normals point outward.

    Raises
    ------
    CageError
        Non-finite vertices, bad face array, an index out of range, a face repeating a
        vertex or of zero area, a boundary (open cage), a non-manifold edge or vertex,
        inconsistent orientation, a component of zero volume, or (``intersections``)
        faces that cross one another.

    Examples
    --------
    >>> import cagekit.cage.shapes as shapes
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

    # areas and volumes in a frame of unit extent: no underflow for tiny cages
    lo = v.min(axis=0)
    with np.errstate(over="ignore"):
        largest = float(np.max(v.max(axis=0) - lo))
    if not np.isfinite(largest):
        raise CageError("cage extent overflows float64 (coordinates too large)", name)
    vs = (v - lo) / largest if largest > 0 else v - lo
    twice_area = np.linalg.norm(np.cross(vs[f[:, 1]] - vs[f[:, 0]], vs[f[:, 2]] - vs[f[:, 0]]),
                                axis=1)
    diagonal = np.linalg.norm(vs.max(axis=0) - vs.min(axis=0))
    if np.any(twice_area <= 1e-24 * diagonal**2):
        raise CageError(f"cage face {int(np.argmin(twice_area))} has zero area", name)

    labels = _closed_manifold_components(f, len(v), name)
    out = f.copy()
    for label in np.unique(labels):
        sel = labels == label
        vol = signed_volume(vs, f[sel])
        scale = np.ptp(vs[np.unique(f[sel])], axis=0).max()
        if abs(vol) <= 1e-12 * scale**3:
            raise CageError("cage (or one of its components) encloses zero volume", name)
        if vol < 0:
            out[sel] = f[sel][:, ::-1]
    if intersections:
        crossing = int(self_intersecting_faces(v, out).sum())
        if crossing:
            raise CageError(f"the cage intersects itself ({crossing} of its {len(out)} faces "
                            "cross another face); a cage must be free of self-intersection "
                            "(cagekit fit-cage builds one that is)", name)
    return out


def _check_manifold_vertices(faces, name):
    """Refuse a vertex whose faces form more than one fan (parts of the cage that touch
    there only), by libigl's ``is_vertex_manifold``; vertices on no face are not judged.

    Parameters
    ----------
    faces : (m, 3) int64
        Faces whose edges are already known to be manifold.
    name : str or None
        Put in front of the error message.

    Raises
    ------
    CageError
        Naming the first non-manifold vertex and how many there are.
    """
    import igl

    manifold = np.asarray(igl.is_vertex_manifold(np.ascontiguousarray(faces)), dtype=bool)
    used = np.zeros(len(manifold), dtype=bool)
    used[faces.ravel()] = True
    bad = np.flatnonzero(used & ~manifold)
    if len(bad):
        more = f", and {len(bad) - 1} more" if len(bad) > 1 else ""
        raise CageError(f"cage is not 2-manifold: vertex {bad[0]} is non-manifold (parts of "
                        f"the cage touch only there{more}); a cage must be a closed "
                        "2-manifold surface", name)


def self_intersecting_faces(cage_v: ArrayLike, cage_f: ArrayLike) -> Bools:
    """Which faces of a triangle mesh intersect another of its faces (exact test).

    Faces that only share a vertex or an edge do not count. Uses pymeshlab's
    ``compute_selection_by_self_intersections_per_face`` (exact predicates), on the
    vertices scaled to unit extent, so that very large or small cages are judged alike.

    Parameters
    ----------
    cage_v : (k, 3) array_like of float
    cage_f : (m, 3) array_like of int
        Faces of positive area (:func:`check_cage` refuses zero-area faces first).

    Returns
    -------
    (m,) bool

    Examples
    --------
    >>> import cagekit.cage.shapes as shapes
    >>> v, f = shapes.box_cage()
    >>> int(self_intersecting_faces(v, f).sum())
    0
    """
    import pymeshlab

    v = np.ascontiguousarray(cage_v, dtype=np.float64)
    f = np.ascontiguousarray(cage_f, dtype=np.int64)
    lo = v.min(axis=0)
    largest = float(np.max(v.max(axis=0) - lo))
    if largest > 0 and np.isfinite(largest):
        v = np.ascontiguousarray((v - lo) / largest)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(v, f))
    ms.compute_selection_by_self_intersections_per_face()
    return np.asarray(ms.current_mesh().face_selection_array(), dtype=bool)


def warn_self_intersecting(cage_v: ArrayLike, cage_f: ArrayLike, name: str = "the cage") -> int:
    """Warn when a (moved) cage intersects itself: the shape it carries may fold there.

    A deformed cage is not refused for it (the coordinates are still defined; the user
    moved it so), but the motion folds the space between the crossing sheets, and a shape
    reaching into it folds with it; where the shape keeps clear of the crossing it comes
    out whole. Uses the exact test of :func:`check_cage`, :func:`self_intersecting_faces`.

    Parameters
    ----------
    cage_v : (k, 3) array_like of float
    cage_f : (m, 3) array_like of int
    name : str, default "the cage"
        How the message names the cage (its file name on the command line).

    Returns
    -------
    int
        The number of faces that cross another face; when it is not 0 one
        :class:`~cagekit.errors.CagekitWarning` line was issued.

    Examples
    --------
    >>> import cagekit.cage.shapes as shapes
    >>> v, f = shapes.box_cage()
    >>> warn_self_intersecting(v, f)
    0
    """
    crossing_faces = self_intersecting_faces(cage_v, cage_f)  # one flag per face
    crossing = int(crossing_faces.sum())
    if crossing:
        warnings.warn(CagekitWarning(
            f"{name}: the cage intersects itself ({crossing} of its {len(crossing_faces)} faces "
            "cross another face); the shape it carries folds where it reaches between "
            "the crossing faces"), stacklevel=2)
    return crossing


def _closed_manifold_components(f: np.ndarray, n_vertices: int, name: str | None) -> Ints:
    """Each face's component, after checking that the faces are closed, 2-manifold and
    consistently oriented (raises :class:`CageError` naming the first offending edge).

    These depend on the faces alone, so the labels of the last :data:`_CACHED_CHECKS`
    face arrays that passed are kept: a training step checks the same cage faces again
    every step (0.7 ms of a 5 ms forward pass). Failures are never kept.
    """
    key = (n_vertices, f.shape, f.tobytes()) if len(f) <= 20_000 else None
    with _CHECKS_LOCK:
        known = _CHECKED.get(key) if key is not None else None
    if known is not None:
        return known
    topo = cage_topology(f)
    uses = np.bincount(topo.face_edges.ravel(), minlength=len(topo.edges))
    if np.any(uses == 1):
        a, b = topo.edges[np.argmax(uses == 1)]
        raise CageError(f"cage is open: edge ({a}, {b}) has only one face; a closed cage is "
                        "required", name)
    if np.any(uses > 2):
        a, b = topo.edges[np.argmax(uses > 2)]
        raise CageError(f"cage is not 2-manifold: edge ({a}, {b}) has {uses.max()} faces", name)
    _check_manifold_vertices(f, name)
    signed_uses = np.zeros(len(topo.edges))
    np.add.at(signed_uses, topo.face_edges.ravel(), topo.face_edge_signs.ravel())
    if np.any(signed_uses != 0):
        a, b = topo.edges[np.argmax(signed_uses != 0)]
        raise CageError(f"cage faces are not consistently oriented (edge ({a}, {b}))", name)
    labels = face_components(n_vertices, f)
    labels.flags.writeable = False
    if key is not None:
        with _CHECKS_LOCK:
            while len(_CHECKED) >= _CACHED_CHECKS:
                _CHECKED.pop(next(iter(_CHECKED)))  # the oldest
            _CHECKED[key] = labels
    return labels


_CACHED_CHECKS = 64
_CHECKED: dict[tuple, np.ndarray] = {}
_CHECKS_LOCK = threading.Lock()


def winding_numbers(points: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike) -> Floats:
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


def cage_encloses(points: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike,
                  threshold: float = 0.5) -> bool:
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

    Raises
    ------
    InputError
        A point or cage vertex is NaN or infinite (naming the first).

    Examples
    --------
    >>> import cagekit.cage.shapes as shapes
    >>> v, f = shapes.box_cage()
    >>> cage_encloses([[0.0, 0.0, 0.0]], v, f), cage_encloses([[3.0, 0.0, 0.0]], v, f)
    (True, False)
    """
    points = _finite_rows(points, "point")
    cage_v = _finite_rows(cage_v, "cage vertex")
    wn = winding_numbers(points, cage_v, cage_f)
    return bool(np.all(wn >= threshold - 1e-9))


def _finite_rows(rows, what: str) -> np.ndarray:
    """``rows`` as an (n, 3) float64 array, or :class:`InputError` naming the first row
    that is not finite (``"{what} {i} is not finite: [...]"``)."""
    a = np.asarray(rows, dtype=np.float64).reshape(-1, 3)
    bad = ~np.isfinite(a).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"{what} {i} is not finite: {a[i].tolist()}")
    return a


def distance_in_diagonals(points: ArrayLike, cage_v: ArrayLike) -> Floats:
    """Distance of each point from the centre of the cage's bounding box, in diagonals.

    Computed without overflow (``hypot``), so that points at 1e300 get a finite value.

    Parameters
    ----------
    points : (n, 3) array_like of float
    cage_v : (k, 3) array_like of float

    Returns
    -------
    (n,) float64

    Examples
    --------
    >>> import cagekit.cage.shapes as shapes
    >>> v, f = shapes.box_cage()  # the cube [-1, 1]^3, diagonal 2 sqrt 3
    >>> distance_in_diagonals([[0.0, 0.0, 0.0], [0.0, 0.0, 2 * 3**0.5]], v).tolist()
    [0.0, 1.0]
    """
    v = np.asarray(cage_v, dtype=np.float64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    centre, diag = 0.5 * (lo + hi), float(np.linalg.norm(hi - lo))
    with np.errstate(over="ignore"):
        q = (np.asarray(points, dtype=np.float64).reshape(-1, 3) - centre) / diag
    return np.hypot(np.hypot(q[:, 0], q[:, 1]), q[:, 2])
