"""Checked shapes: vertices ``(n, 3)`` float64, faces ``(m, 3)`` int64 (libigl's layout).

A point cloud is a mesh with no faces (``F`` is ``None`` or has zero rows). The ``as_*``
functions raise :class:`cagekit.errors.InputError` for non-finite coordinates, wrong shapes,
out-of-range indices and empty input.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cagekit.errors import InputError
from cagekit.typed import Faces, Ints, Vertices

__all__ = ["as_count", "as_faces", "as_shape", "as_vertices", "remove_duplicate_faces",
           "unique_rows"]


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


def as_shape(shape: object, faces: ArrayLike | None = None,
             name: str = "shape") -> tuple[Vertices, Faces]:
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


def as_count(n: object, name: str, minimum: int = 0) -> int:
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
    first, _ = unique_rows(key)
    keep = np.zeros(len(F), dtype=bool)
    keep[first] = True
    return F[keep & proper]


def unique_rows(rows: ArrayLike) -> tuple[Ints, Ints]:
    """``np.unique(rows, axis=0, return_index=True, return_inverse=True)[1:]`` of
    non-negative integer rows, by one integer key a row.

    numpy compares whole rows as records, which is slow (12 ms for the 25,000 edges of a
    4,000-vertex chair); the rows are numbered here by ``sum_j row_j * base^(c - 1 - j)``
    (``base`` one more than the largest entry), which orders them as numpy does, so the
    results are numpy's exactly. Rows whose key would not fit in 62 bits, and rows with a
    negative entry, take numpy's way. Empty rows are accepted.

    Parameters
    ----------
    rows : (m, c) array_like of int
        Non-negative entries.

    Returns
    -------
    first : (u,) int64 ndarray
        The index of each distinct row's first occurrence, distinct rows in lexicographic
        order.
    inverse : (m,) int64 ndarray
        The distinct row of each row: ``rows[first][inverse]`` is ``rows``.

    Examples
    --------
    >>> first, inverse = unique_rows([[1, 2], [0, 5], [1, 2]])
    >>> first.tolist(), inverse.tolist()
    ([1, 0], [1, 0, 1])
    """
    R = np.asarray(rows)
    if R.ndim != 2 or (R.size and not np.issubdtype(R.dtype, np.integer)):
        raise InputError(f"rows must be an (m, c) integer array, got shape {R.shape}")
    top = int(R.max()) if R.size else 0
    if R.size and (int(R.min()) < 0 or R.shape[1] * np.log2(top + 1) >= 62):
        _, first, inverse = np.unique(R, axis=0, return_index=True, return_inverse=True)
        return first.astype(np.int64), inverse.reshape(-1).astype(np.int64)
    R, base = R.astype(np.int64), top + 1
    key = np.zeros(len(R), dtype=np.int64)
    for column in R.T:
        key = key * base + column
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    return first.astype(np.int64), inverse.astype(np.int64)
