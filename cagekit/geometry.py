"""Mesh and point-cloud geometry shared by the rest of cagekit.

Vertices are ``(n, 3)`` float64 and faces ``(m, 3)`` int64, as libigl; a point cloud is a
mesh with no faces (``F`` is ``None`` or has zero rows). Every function checks its input and
raises :class:`cagekit.errors.InputError` for non-finite coordinates, wrong shapes,
out-of-range indices and empty input; none returns NaN. :func:`cotangent_laplacian` is
``igl.cotmatrix`` as CSR, with the convention of docs/architecture.md ("Metrics"):
``L_ij = (cot a + cot b) / 2`` off the diagonal, ``L_ii = -sum_j L_ij`` (negative
semi-definite, symmetric, rows summing to 0, no mass matrix); zero-area faces are refused
rather than turned into inf and NaN. Neighbourhoods are a :class:`Neighborhoods` pair of
padded ``(n, m)`` arrays ``(index, mask)`` (row ``i`` lists ``i`` itself, then its
neighbours), so planes are re-evaluated on moved vertices by one fancy-indexing step
(:func:`pca_planes`). :func:`orient_normals` signs PCA normals by the area-weighted vertex
normal, or, for clouds and vertices on no face of positive area, away from the centroid (a
heuristic that may be wrong in concave regions). A degenerate neighbourhood (fewer than 3
points, or collinear) gets some unit normal orthogonal to its span, with distance 0.
"""

from __future__ import annotations

from typing import NamedTuple

import igl
import numpy as np
import scipy.sparse
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from cagekit.errors import InputError

__all__ = [
    "Neighborhoods",
    "as_count",
    "as_faces",
    "as_shape",
    "as_vertices",
    "cotangent_laplacian",
    "face_areas",
    "orient_normals",
    "vertex_rotations",
    "polar",
    "pca_normals",
    "pca_planes",
    "point_to_plane",
    "remove_duplicate_faces",
    "surface_laplacian",
    "uniform_laplacian",
    "vertex_neighborhoods",
]

_PLANE_CHUNK = 65536  # rows of neighbourhoods processed at once by pca_planes


# --------------------------------------------------------------------------- validation


def as_vertices(V: ArrayLike, name: str = "V") -> np.ndarray:
    """Check and convert vertex positions.

    Parameters
    ----------
    V : array_like, shape (n, 3)
        Vertex positions, any real dtype; ``n >= 1``.
    name : str, optional
        Name of the argument, used in error messages.

    Returns
    -------
    V : numpy.ndarray, shape (n, 3), float64, C-contiguous
        A copy only when a conversion was needed.

    Raises
    ------
    InputError
        Wrong shape, no points, non-numeric values, NaN or infinite coordinates.

    Examples
    --------
    >>> as_vertices([[0, 0, 0], [1, 2, 3]]).dtype
    dtype('float64')
    """
    try:
        arr = np.ascontiguousarray(V, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a numeric (n, 3) array: {exc}") from None
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{name} must have shape (n, 3), got {arr.shape}")
    if arr.shape[0] == 0:
        raise InputError(f"{name} has no points")
    if not np.isfinite(arr).all():
        raise InputError(f"{name} contains NaN or infinite coordinates")
    return arr


def as_faces(F: ArrayLike | None, n_vertices: int, name: str = "F") -> np.ndarray:
    """Check and convert triangle indices; ``None`` means no faces (a point cloud).

    Parameters
    ----------
    F : array_like, shape (m, 3), or None
        Triangle vertex indices, integers in ``[0, n_vertices)``. Floats are accepted
        when every value is integral. ``None`` or an empty array give ``m = 0``.
    n_vertices : int
        Number of vertices the indices refer to.
    name : str, optional
        Name of the argument, used in error messages.

    Returns
    -------
    F : numpy.ndarray, shape (m, 3), int64, C-contiguous

    Raises
    ------
    InputError
        Wrong shape, non-integral values or indices out of range.

    Examples
    --------
    >>> as_faces(None, 4).shape
    (0, 3)
    >>> as_faces([[0, 1, 2]], 3).dtype
    dtype('int64')
    """
    if F is None:
        return np.zeros((0, 3), dtype=np.int64)
    arr = np.asarray(F)
    if arr.size == 0:
        return np.zeros((0, 3), dtype=np.int64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{name} must have shape (m, 3), got {arr.shape}")
    if arr.dtype.kind == "f":
        if not np.isfinite(arr).all() or (arr != np.round(arr)).any():
            raise InputError(f"{name} must hold integer vertex indices")
    elif arr.dtype.kind not in "iu":
        raise InputError(
            f"{name} must hold integer vertex indices, got dtype {arr.dtype}"
        )
    arr = np.ascontiguousarray(arr, dtype=np.int64)
    if arr.min() < 0 or arr.max() >= n_vertices:
        raise InputError(
            f"{name} has vertex indices outside [0, {n_vertices}): "
            f"min {arr.min()}, max {arr.max()}"
        )
    return arr


def as_shape(shape, faces=None, name: str = "shape") -> tuple[np.ndarray, np.ndarray]:
    """Check and convert a shape given in any of the accepted forms: ``(V, F)``.

    The one shape checker of cagekit: every function that takes a shape calls it.

    Parameters
    ----------
    shape : trimesh object, (V, F) pair, or (n, 3) array_like
        A ``trimesh.Trimesh`` or ``trimesh.PointCloud`` (anything with ``.vertices``), a
        ``(V, F)`` pair (tuple or list; ``F`` may be None), or bare vertices (a point
        cloud). A list of two points is a cloud, not a pair: a pair's first member is 2-D.
    faces : (m, 3) array_like of int, optional
        The faces, when ``shape`` is bare vertices (``fit_cage(V, F)``); giving both a
        mesh object or pair and ``faces`` is an error.
    name : str
        What the error messages call the shape.

    Returns
    -------
    V : (n, 3) float64, C-contiguous
    F : (m, 3) int64
        Empty (0, 3) for a point cloud.

    Raises
    ------
    InputError
        As :func:`as_vertices` and :func:`as_faces`.

    Examples
    --------
    >>> V, F = as_shape([[0.0, 0, 0], [1.0, 1, 1]])
    >>> V.shape, F.shape
    ((2, 3), (0, 3))
    """
    if hasattr(shape, "vertices"):
        V, F = shape.vertices, getattr(shape, "faces", None)
    elif (isinstance(shape, (tuple, list)) and len(shape) == 2 and np.ndim(shape[0]) == 2
            and (shape[1] is None or np.ndim(shape[1]) == 2)):
        V, F = shape
    else:
        V, F = shape, None
        if faces is not None:
            F, faces = faces, None
    if faces is not None:
        raise InputError(f"give the {name} as a mesh object or a (V, F) pair, or as "
                         "vertices and faces, not both")
    V = as_vertices(V, f"{name} vertices")
    return V, as_faces(F, len(V), f"{name} faces")


def as_count(n, name: str, minimum: int = 0) -> int:
    """``n`` as an int, or :class:`~cagekit.errors.InputError` if it is not an integer
    (bools are not) of at least ``minimum``.

    Examples
    --------
    >>> as_count(3, "points", 1)
    3
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}, got {n!r}")
    return int(n)


# ----------------------------------------------------------------------------- topology


def remove_duplicate_faces(F: ArrayLike) -> np.ndarray:
    """Drop repeated and degenerate faces, keeping the first occurrence of each.

    Two faces are duplicates when they use the same three vertices, in any order and with
    any orientation. A face that repeats a vertex index (``[i, i, j]``) is dropped too.

    Parameters
    ----------
    F : array_like, shape (m, 3), int
        Triangle vertex indices (non-negative).

    Returns
    -------
    F2 : numpy.ndarray, shape (m2, 3), int64
        The kept faces, rows unchanged and in their original order.

    Examples
    --------
    >>> remove_duplicate_faces([[0, 1, 2], [2, 1, 0], [1, 1, 3], [1, 2, 3]]).tolist()
    [[0, 1, 2], [1, 2, 3]]
    """
    F = as_faces(F, np.iinfo(np.int64).max)
    key = np.sort(F, axis=1)
    proper = (key[:, 0] != key[:, 1]) & (key[:, 1] != key[:, 2])
    _, first = np.unique(key, axis=0, return_index=True)
    keep = np.zeros(len(F), dtype=bool)
    keep[first] = True
    return F[keep & proper]


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


# ---------------------------------------------------------------------------- laplacian


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


def surface_laplacian(V: ArrayLike, F: ArrayLike) -> scipy.sparse.csr_matrix:
    """:func:`cotangent_laplacian` of a real-world mesh: duplicate faces
    (:func:`remove_duplicate_faces`) and faces of zero area dropped first.

    Parameters
    ----------
    V : array_like, shape (n, 3), float
    F : array_like, shape (m, 3), int

    Returns
    -------
    L : scipy.sparse.csr_matrix, shape (n, n), float64

    Raises
    ------
    InputError
        No faces, or none of positive area.

    Examples
    --------
    >>> V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
    >>> L = surface_laplacian(V, [[0, 1, 2], [1, 3, 2], [1, 3, 2], [0, 0, 1]])
    >>> L.toarray()[0].tolist()
    [-1.0, 0.5, 0.5, 0.0]
    """
    V = as_vertices(V)
    F = remove_duplicate_faces(as_faces(F, len(V)))
    if len(F) == 0:
        raise InputError("the cotangent Laplacian needs a mesh with faces, got a point cloud")
    F = F[face_areas(V, F) > 0.0]  # zero-area faces have undefined cotangents
    if len(F) == 0:
        raise InputError("the cotangent Laplacian needs faces of positive area; all the "
                         "faces have zero area")
    return cotangent_laplacian(V, F)


# ------------------------------------------------------------------------ neighbourhoods


class Neighborhoods(NamedTuple):
    """Fixed-size (padded) neighbourhood of every vertex.

    Attributes
    ----------
    index : numpy.ndarray, shape (n, m), int64
        ``index[i]`` lists vertex ``i`` itself and its neighbours; padding slots hold
        ``i`` again, so ``V[index]`` is always valid.
    mask : numpy.ndarray, shape (n, m), bool
        True for real members, False for padding.

    Notes
    -----
    Gather the members of all neighbourhoods of (possibly moved) vertices ``X`` with
    ``X[nb.index]`` (shape ``(n, m, 3)``) and weight by ``nb.mask``.
    """

    index: np.ndarray
    mask: np.ndarray

    @property
    def counts(self) -> np.ndarray:
        """Number of members of each neighbourhood, shape (n,), int64."""
        return self.mask.sum(axis=1).astype(np.int64)


def _one_ring(n: int, F: np.ndarray) -> Neighborhoods:
    """Vertex itself (column 0) plus its one-ring neighbours, sorted by index."""
    i = F[:, [0, 1, 2, 1, 2, 0]].ravel()
    j = F[:, [1, 2, 0, 0, 1, 2]].ravel()
    off = i != j
    A = scipy.sparse.coo_matrix(
        (np.ones(off.sum()), (i[off], j[off])), shape=(n, n)
    ).tocsr()
    A.sum_duplicates()
    A.sort_indices()
    degree = np.diff(A.indptr)
    rows = np.repeat(np.arange(n), degree)
    cols = 1 + np.arange(A.nnz) - A.indptr[rows]
    index = np.repeat(
        np.arange(n, dtype=np.int64)[:, None], 1 + degree.max(initial=0), axis=1
    )
    mask = np.zeros(index.shape, dtype=bool)
    mask[:, 0] = True
    index[rows, cols] = A.indices
    mask[rows, cols] = True
    return Neighborhoods(index, mask)


def _knn(V: np.ndarray, k: int) -> Neighborhoods:
    """The k nearest points of each point, always including the point itself."""
    k = min(k, len(V))
    _, index = cKDTree(V).query(V, k=k)
    index = np.asarray(index, dtype=np.int64).reshape(len(V), k)
    own = np.arange(len(V))
    missing = ~(index == own[:, None]).any(axis=1)  # only with > k coincident points
    index[missing, -1] = own[missing]
    return Neighborhoods(index, np.ones(index.shape, dtype=bool))


def vertex_neighborhoods(
    V: ArrayLike, F: ArrayLike | None = None, k: int = 16
) -> Neighborhoods:
    """Neighbourhood of each vertex: its one-ring on a mesh, its k nearest in a cloud.

    Parameters
    ----------
    V : array_like, shape (n, 3), float
        Vertex positions.
    F : array_like, shape (f, 3), int, or None
        Triangles. With faces, the neighbourhood of ``i`` is ``i`` plus every vertex
        sharing an edge with it (``k`` is ignored). Without faces (``None`` or empty) it
        is the ``min(k, n)`` nearest points, ``i`` included.
    k : int, optional
        Neighbourhood size for point clouds, ``k >= 1``.

    Returns
    -------
    Neighborhoods
        Padded ``(index, mask)`` arrays of shape ``(n, m)``; see :class:`Neighborhoods`.
        For meshes ``index[:, 0]`` is the vertex itself and the neighbours follow in
        increasing order; ``m`` is 1 + the largest vertex degree.

    Examples
    --------
    >>> V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
    >>> nb = vertex_neighborhoods(V, [[0, 1, 2], [1, 3, 2]])
    >>> nb.index[0].tolist(), nb.mask[0].tolist()
    ([0, 1, 2, 0], [True, True, True, False])
    """
    V = as_vertices(V)
    F = as_faces(F, len(V))
    if len(F):
        return _one_ring(len(V), F)
    return _knn(V, as_count(k, "k", 1))


def _as_neighborhoods(neighborhoods, n: int) -> Neighborhoods:
    """Validate an ``(index, mask)`` pair against ``n`` vertices."""
    try:
        index, mask = neighborhoods
    except (TypeError, ValueError):
        raise InputError("neighborhoods must be an (index, mask) pair") from None
    index = np.asarray(index)
    mask = np.asarray(mask, dtype=bool)
    if index.ndim != 2 or index.shape[0] != n or mask.shape != index.shape:
        raise InputError(
            f"neighborhoods must be (n, m) arrays with n = {n}, "
            f"got index {index.shape} and mask {mask.shape}"
        )
    if index.dtype.kind not in "iu" or index.min() < 0 or index.max() >= n:
        raise InputError(f"neighborhood indices must be integers in [0, {n})")
    if not mask.any(axis=1).all():
        raise InputError("every neighborhood must have at least one member")
    return Neighborhoods(index.astype(np.int64, copy=False), mask)


# ------------------------------------------------------------------------------ planes


def _planes_chunk(V: np.ndarray, index: np.ndarray, mask: np.ndarray):
    """PCA planes of one block of neighbourhoods; see :func:`pca_planes`."""
    w = mask[:, :, None].astype(np.float64)
    P = V[index]
    count = w.sum(axis=1)
    centroid = (P * w).sum(axis=1) / count
    D = (P - centroid[:, None, :]) * w
    cov = np.einsum("nki,nkj->nij", D, D) / count[:, :, None]
    _, vecs = np.linalg.eigh(cov)
    return vecs[:, :, 0], centroid


def pca_planes(V: ArrayLike, neighborhoods) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares plane of every neighbourhood, evaluated on the given positions.

    The plane of vertex ``i`` passes through the centroid of its neighbourhood and has
    as normal the eigenvector of the smallest eigenvalue of the neighbourhood's
    covariance (``numpy.linalg.eigh`` on a stack of 3x3 matrices). The neighbourhoods are
    only indices, so ``V`` may be moved vertices with neighbourhoods computed once on
    the rest shape.

    Parameters
    ----------
    V : array_like, shape (n, 3), float
        Vertex positions (rest or deformed).
    neighborhoods : Neighborhoods or (index, mask) pair of (n, m) arrays
        From :func:`vertex_neighborhoods`.

    Returns
    -------
    normals : numpy.ndarray, shape (n, 3), float64
        Unit normals with arbitrary sign (see :func:`orient_normals`).
    centroids : numpy.ndarray, shape (n, 3), float64
        Centroid of each neighbourhood.

    Examples
    --------
    >>> V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
    >>> nb = vertex_neighborhoods(V, k=4)
    >>> normals, centroids = pca_planes(V, nb)
    >>> abs(normals[:, 2]).tolist(), centroids[0].tolist()
    ([1.0, 1.0, 1.0, 1.0], [0.5, 0.5, 0.0])
    """
    V = as_vertices(V)
    nb = _as_neighborhoods(neighborhoods, len(V))
    normals = np.empty_like(V)
    centroids = np.empty_like(V)
    for start in range(0, len(V), _PLANE_CHUNK):
        rows = slice(start, start + _PLANE_CHUNK)
        normals[rows], centroids[rows] = _planes_chunk(V, nb.index[rows], nb.mask[rows])
    return normals, centroids


def orient_normals(
    normals: ArrayLike, V: ArrayLike, F: ArrayLike | None = None
) -> np.ndarray:
    """Flip normals to agree with the mesh's orientation, or to point away from the centroid.

    Parameters
    ----------
    normals : array_like, shape (n, 3), float
        Normals of arbitrary sign, one per vertex.
    V : array_like, shape (n, 3), float
        Vertex positions.
    F : array_like, shape (m, 3), int, or None
        Triangles. With faces, each normal is flipped when it points against the
        area-weighted vertex normal (``igl.per_vertex_normals``). Without faces, and for
        vertices touching no face of positive area, it is flipped when it points toward
        the centroid of ``V`` (a heuristic, right for star-shaped shapes).

    Returns
    -------
    oriented : numpy.ndarray, shape (n, 3), float64

    Examples
    --------
    >>> n = orient_normals([[0, 0, -1.0], [0, 0, 1.0]], [[0, 0, 1.0], [0, 0, -1.0]])
    >>> n[:, 2].tolist()
    [1.0, -1.0]
    """
    V = as_vertices(V)
    F = as_faces(F, len(V))
    normals = as_vertices(normals, "normals").copy()
    if normals.shape != V.shape:
        raise InputError(f"normals must have shape {V.shape}, got {normals.shape}")
    reference = V - V.mean(axis=0)
    if len(F):
        with np.errstate(invalid="ignore", divide="ignore"):
            mesh_normals = igl.per_vertex_normals(
                V, F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_AREA
            )
        good = np.isfinite(mesh_normals).all(axis=1)
        reference[good] = mesh_normals[good]
    flip = np.einsum("ij,ij->i", normals, reference) < 0.0
    normals[flip] *= -1.0
    return normals


def _oriented_planes(V, F, k, neighborhoods):
    """Shared body of :func:`pca_normals` and :func:`point_to_plane`."""
    V = as_vertices(V)
    F = as_faces(F, len(V))
    if neighborhoods is None:
        neighborhoods = vertex_neighborhoods(V, F, k)
    normals, centroids = pca_planes(V, neighborhoods)
    return V, orient_normals(normals, V, F), centroids


def pca_normals(
    V: ArrayLike, F: ArrayLike | None = None, k: int = 16, neighborhoods=None
) -> np.ndarray:
    """Unit normal of every vertex from PCA of its neighbourhood, consistently signed.

    Parameters
    ----------
    V : array_like, shape (n, 3), float
        Vertex positions.
    F : array_like, shape (m, 3), int, or None
        Triangles; defines the one-ring neighbourhoods and the sign (outward for a
        consistently oriented closed mesh). ``None`` or empty: a point cloud, k nearest
        neighbours and normals pointing away from the centroid (heuristic).
    k : int, optional
        Neighbourhood size for point clouds.
    neighborhoods : Neighborhoods, optional
        Precomputed neighbourhoods (then ``k`` is ignored and ``F`` only sets the sign).

    Returns
    -------
    normals : numpy.ndarray, shape (n, 3), float64
        Unit vectors.

    Examples
    --------
    >>> V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
    >>> pca_normals(V, [[0, 1, 2], [1, 3, 2]])[0].tolist()
    [0.0, 0.0, 1.0]
    """
    return _oriented_planes(V, F, k, neighborhoods)[1]


def point_to_plane(
    V: ArrayLike, F: ArrayLike | None = None, k: int = 16, neighborhoods=None
) -> np.ndarray:
    """Signed distance of every vertex to the PCA plane of its neighbourhood.

    The plane passes through the neighbourhood's centroid with the normal of
    :func:`pca_normals` (same sign convention); the distance is positive on the side the
    normal points to.

    Parameters
    ----------
    V : array_like, shape (n, 3), float
        Vertex positions.
    F : array_like, shape (m, 3), int, or None
        Triangles (one-ring neighbourhoods) or ``None`` for a point cloud.
    k : int, optional
        Neighbourhood size for point clouds.
    neighborhoods : Neighborhoods, optional
        Precomputed neighbourhoods.

    Returns
    -------
    distance : numpy.ndarray, shape (n,), float64

    Examples
    --------
    >>> V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
    >>> point_to_plane(V, [[0, 1, 2], [1, 3, 2]]).tolist()
    [0.0, 0.0, 0.0, 0.0]
    """
    V, normals, centroids = _oriented_planes(V, F, k, neighborhoods)
    return np.einsum("ij,ij->i", V - centroids, normals)


def polar(T) -> tuple[np.ndarray, np.ndarray]:
    """Polar decomposition ``T = R S`` of (m, 3, 3) matrices (SVD).

    Returns
    -------
    R : (m, 3, 3) float64
        Proper rotations (an inverted face keeps ``det R = +1``; its reflection goes
        into ``S``).
    S : (m, 3, 3) float64
        Symmetric.

    Examples
    --------
    >>> c, s = np.cos(0.3), np.sin(0.3)
    >>> R0 = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    >>> R, S = polar((R0 @ np.diag([2.0, 1.0, 0.5]))[None])
    >>> bool(np.allclose(R[0], R0)), bool(np.allclose(S[0], np.diag([2.0, 1.0, 0.5])))
    (True, True)
    """
    T = np.asarray(T, dtype=np.float64)
    U, sigma, Vt = np.linalg.svd(T)
    D = np.ones_like(sigma)
    D[:, 2] = np.where(np.linalg.det(U @ Vt) < 0, -1.0, 1.0)
    R = U @ (D[:, :, None] * Vt)
    S = np.swapaxes(Vt, 1, 2) @ ((D * sigma)[:, :, None] * Vt)
    return R, S


def vertex_rotations(rest, moved, edges) -> np.ndarray:
    """Per vertex, the rotation best turning its edges at rest into the moved ones.

    The polar factor of ``sum_j (x_i - x_j)(v_i - v_j)^T`` over the vertex's edges
    (the local step of as-rigid-as-possible, Sorkine & Alexa 2007, uniform weights).

    Parameters
    ----------
    rest, moved : (n, 3) array_like of float
        The vertices at rest and moved.
    edges : (e, 2) array_like of int
        Undirected edges, each once (:func:`cagekit.cage.unique_edges`).

    Returns
    -------
    (n, 3, 3) float64
        Proper rotations; the identity for a vertex on no edge.

    Examples
    --------
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    >>> E = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
    >>> c, s = np.cos(0.4), np.sin(0.4)
    >>> R0 = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    >>> bool(np.allclose(vertex_rotations(V, 2 * V @ R0.T, E), R0))
    True
    """
    V = np.asarray(rest, dtype=np.float64)
    X = np.asarray(moved, dtype=np.float64)
    E = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    n = len(V)
    i = np.concatenate([E[:, 0], E[:, 1]])
    j = np.concatenate([E[:, 1], E[:, 0]])
    outer = np.einsum("ea,eb->eab", X[i] - X[j], V[i] - V[j]).reshape(-1, 9)
    S = np.stack([np.bincount(i, outer[:, k], minlength=n) for k in range(9)], axis=1)
    R = polar(S.reshape(n, 3, 3))[0]
    R[np.bincount(i, minlength=n) == 0] = np.eye(3)
    return R


def uniform_laplacian(n: int, edges) -> scipy.sparse.csr_matrix:
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
