"""Neighbourhoods, PCA planes and normals, point-to-plane distances.

Neighbourhoods are a :class:`Neighborhoods` pair of padded ``(n, m)`` arrays
``(index, mask)`` (row ``i`` lists ``i`` itself, then its neighbours), so planes are
re-evaluated on moved vertices by one fancy-indexing step (:func:`pca_planes`).
:func:`orient_normals` signs PCA normals by the area-weighted vertex normal, or, for clouds
and vertices on no face of positive area, away from the centroid (a heuristic that may be
wrong in concave regions). A degenerate neighbourhood (fewer than 3 points, or collinear)
gets some unit normal orthogonal to its span, with distance 0.
"""

from __future__ import annotations

from typing import NamedTuple

import igl
import numpy as np
import scipy.sparse
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from cagekit.errors import InputError
from cagekit.geometry.checks import as_count, as_faces, as_vertices
from cagekit.typed import Floats, Vertices

__all__ = ["Neighborhoods", "orient_normals", "pca_normals", "pca_planes", "point_to_plane",
           "vertex_neighborhoods"]

_PLANE_CHUNK = 65536  # rows of neighbourhoods processed at once by pca_planes


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

    index: np.ndarray  # type: ignore[assignment]  # a field named as tuple.index, on purpose
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


def pca_planes(
    V: ArrayLike, neighborhoods: Neighborhoods | tuple[ArrayLike, ArrayLike]
) -> tuple[Vertices, Vertices]:
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
    V: ArrayLike, F: ArrayLike | None = None, k: int = 16,
    neighborhoods: Neighborhoods | tuple[ArrayLike, ArrayLike] | None = None,
) -> Vertices:
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
    V: ArrayLike, F: ArrayLike | None = None, k: int = 16,
    neighborhoods: Neighborhoods | tuple[ArrayLike, ArrayLike] | None = None,
) -> Floats:
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
