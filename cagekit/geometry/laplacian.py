"""Face areas and Laplacians of a mesh.

:func:`cotangent_laplacian` is ``igl.cotmatrix`` as CSR, with the convention of
docs/architecture.md ("Metrics"): ``L_ij = (cot a + cot b) / 2`` off the diagonal,
``L_ii = -sum_j L_ij`` (negative semi-definite, symmetric, rows summing to 0, no mass
matrix); zero-area faces are refused rather than turned into inf and NaN.
:func:`uniform_laplacian` is the graph Laplacian of an edge list.
"""

from __future__ import annotations

import igl
import numpy as np
import scipy.sparse
from numpy.typing import ArrayLike

from cagekit.errors import InputError
from cagekit.geometry.checks import as_faces, as_vertices, remove_duplicate_faces

__all__ = ["SLIVER", "cotangent_laplacian", "face_areas", "surface_laplacian",
           "uniform_laplacian"]


def face_areas(V: ArrayLike, F: ArrayLike) -> np.ndarray:
    """Area of each triangle.

    Parameters
    ----------
    V : array_like, shape (n, 3), float
        Vertex positions.
    F : array_like, shape (m, 3), int
        Triangles.

    Returns
    -------
    areas : numpy.ndarray, shape (m,), float64
        Finite and non-negative.

    Raises
    ------
    InputError
        An area is not finite in float64 (coordinates too large: from about 1e77 on
        the intermediate squares overflow), or bad input.

    Examples
    --------
    >>> face_areas([[0, 0, 0], [2, 0, 0], [0, 1, 0]], [[0, 1, 2]]).tolist()
    [1.0]
    """
    V = as_vertices(V)
    F = as_faces(F, len(V))
    with np.errstate(over="ignore", invalid="ignore"):
        cross = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
        areas = 0.5 * np.linalg.norm(cross, axis=1)
    if not np.isfinite(areas).all():
        raise InputError("coordinates too large: face areas overflow")
    return areas


def cotangent_laplacian(V: ArrayLike, F: ArrayLike) -> scipy.sparse.csr_matrix:
    """Cotangent Laplacian without mass matrix (``igl.cotmatrix``).

    ``L_ij = (cot a_ij + cot b_ij) / 2`` for each edge ``ij`` (``a``, ``b`` the angles
    opposite the edge; one term on a boundary edge) and ``L_ii = -sum_j L_ij``: symmetric,
    negative semi-definite, rows summing to 0. Vertices in no face get an empty row.

    Parameters
    ----------
    V : array_like, shape (n, 3), float
        Vertex positions.
    F : array_like, shape (m, 3), int
        Triangles, ``m >= 1``; none may have zero area.

    Returns
    -------
    L : scipy.sparse.csr_matrix, shape (n, n), float64

    Raises
    ------
    InputError
        No faces, a face of zero area (its cotangents are infinite), or face areas that
        overflow (coordinates too large).

    Examples
    --------
    Two right isosceles triangles forming the unit square:

    >>> V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
    >>> cotangent_laplacian(V, [[0, 1, 2], [1, 3, 2]]).toarray()[0].tolist()
    [-1.0, 0.5, 0.5, 0.0]
    """
    V = as_vertices(V)
    F = as_faces(F, len(V))
    if len(F) == 0:
        raise InputError(
            "the cotangent Laplacian needs a mesh with faces, got a point cloud"
        )
    n_flat = int(np.count_nonzero(face_areas(V, F) == 0.0))
    if n_flat:
        raise InputError(
            f"{n_flat} face(s) have zero area; their cotangent weights are infinite "
            "(remove degenerate faces first)"
        )
    L = scipy.sparse.csr_matrix(igl.cotmatrix(V, F), dtype=np.float64)
    if not np.isfinite(L.data).all():
        raise InputError(
            "cotangent weights are not finite: the mesh has near-degenerate faces"
        )
    return L


#: a face whose height is under this share of its longest edge is a sliver: libigl's
#: cotangents of it come from its edge lengths, whose rounding leaves them 0.1% off at
#: 1e-7 and without a correct digit (or infinite) from about 1e-9 down, whichever way the
#: face is drawn; :func:`surface_laplacian` drops such faces
SLIVER = 1e-7


def surface_laplacian(V: ArrayLike, F: ArrayLike) -> scipy.sparse.csr_matrix:
    """:func:`cotangent_laplacian` of a real-world mesh: duplicate faces
    (:func:`remove_duplicate_faces`), faces of zero area and slivers dropped first.

    A sliver is a face whose height is under :data:`SLIVER` times its longest edge
    (``2 area / longest^2``): numerically collinear, its cotangents in float64 are
    rounding noise (or infinite), and like a face of zero area it adds nothing to the
    surface. Real meshes carry them: 30 of 400 sweethome3d-furniture models, one of them
    a seat (a sofa whose deformations could not be measured before). Every other face
    keeps its weights as libigl gives them.

    Parameters
    ----------
    V : array_like, shape (n, 3), float
    F : array_like, shape (m, 3), int

    Returns
    -------
    L : scipy.sparse.csr_matrix, shape (n, n), float64
        Finite.

    Raises
    ------
    InputError
        No faces, or none of positive area that is not a sliver.

    Examples
    --------
    >>> V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
    >>> L = surface_laplacian(V, [[0, 1, 2], [1, 3, 2], [1, 3, 2], [0, 0, 1]])
    >>> L.toarray()[0].round(6).tolist()
    [-1.0, 0.5, 0.5, 0.0]

    A sliver whose third vertex lies 1e-12 off its longest edge is dropped:

    >>> V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.3, 1e-12, 0]]
    >>> L = surface_laplacian(V, [[0, 1, 2], [0, 1, 3]])
    >>> L.toarray()[0].round(6).tolist()
    [-1.0, 0.5, 0.5, 0.0]
    """
    V = as_vertices(V)
    faces = remove_duplicate_faces(as_faces(F, len(V)))
    if len(faces) == 0:
        raise InputError("the cotangent Laplacian needs a mesh with faces, got a point cloud")
    kept = faces[~_slivers(V, faces)]
    if len(kept) == 0:
        raise InputError("the cotangent Laplacian needs faces of positive area; all the "
                         "faces have zero area or are slivers (numerically collinear)")
    return cotangent_laplacian(V, kept)


def _slivers(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """``(m,)`` bool: faces of zero area, or of height under :data:`SLIVER` times their
    longest edge."""
    edges = V[F[:, [1, 2, 0]]] - V[F]
    longest = np.square(edges).sum(axis=2).max(axis=1)
    return ~(2.0 * face_areas(V, F) > SLIVER * longest)


def uniform_laplacian(n: int, edges: ArrayLike) -> scipy.sparse.csr_matrix:
    """The graph Laplacian ``D - A`` of ``n`` vertices joined by ``edges`` (unit weights).

    Parameters
    ----------
    n : int
    edges : (e, 2) array_like of int
        Undirected edges, each once.

    Returns
    -------
    (n, n) scipy.sparse.csr_matrix of float64
        Symmetric, rows summing to 0 (a vertex on no edge has an empty row).

    Examples
    --------
    >>> uniform_laplacian(3, np.array([[0, 1], [1, 2]])).toarray().tolist()
    [[1.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]]
    """
    E = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    i, j = np.concatenate([E[:, 0], E[:, 1]]), np.concatenate([E[:, 1], E[:, 0]])
    A = scipy.sparse.csr_matrix((np.ones(len(i)), (i, j)), shape=(n, n))
    return (scipy.sparse.diags(np.asarray(A.sum(axis=1)).ravel()) - A).tocsr()
