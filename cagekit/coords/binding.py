"""Binding points to a cage: compute coordinates once, deform many times."""

from __future__ import annotations

import numba
import numpy as np

from cagekit.cage import cage_encloses, check_cage
from cagekit.errors import InputError

__all__ = ["CageBinding", "bind", "METHODS"]

METHODS = ("mvc",)


@numba.njit(parallel=True, cache=True)
def _weights_times_vertices(weights, vertices):
    """``weights @ vertices`` for (n, k) x (k, 3): a row-parallel loop, about twice as fast
    as BLAS for this tall-skinny shape, and the same sum order for every row."""
    n, k = weights.shape
    out = np.empty((n, 3))
    for i in numba.prange(n):
        x = 0.0
        y = 0.0
        z = 0.0
        for j in range(k):
            w = weights[i, j]
            x += w * vertices[j, 0]
            y += w * vertices[j, 1]
            z += w * vertices[j, 2]
        out[i, 0] = x
        out[i, 1] = y
        out[i, 2] = z
    return out


class CageBinding:
    """Points written as generalised barycentric coordinates of a cage's vertices.

    Attributes
    ----------
    weights : (n, k) float64
        Row ``i`` holds the coordinates of point ``i``; rows sum to one.
    cage_v : (k, 3) float64
        The cage the points were bound to.
    cage_f : (m, 3) int64
        Its faces, oriented outward.
    method : str
        The coordinates used (``"mvc"``).
    """

    def __init__(self, weights: np.ndarray, cage_v: np.ndarray, cage_f: np.ndarray, method: str):
        self.weights = weights
        self.cage_v = cage_v
        self.cage_f = cage_f
        self.method = method

    @property
    def n_points(self) -> int:
        """Number of bound points."""
        return self.weights.shape[0]

    def deform(self, new_cage_v) -> np.ndarray:
        """Positions of the bound points for moved cage vertices.

        Parameters
        ----------
        new_cage_v : (k, 3) array_like of float
            The cage's vertices after moving them, in the same order.

        Returns
        -------
        (n, 3) float64
            ``weights @ new_cage_v``.

        Examples
        --------
        >>> from cagekit.shapes import box_cage
        >>> v, f = box_cage()
        >>> b = bind([[0.5, 0.0, 0.0]], v, f)
        >>> b.deform(2 * v).round(12).tolist()
        [[1.0, 0.0, 0.0]]
        """
        new = np.asarray(new_cage_v, dtype=np.float64)
        if new.shape != self.cage_v.shape:
            raise InputError(f"deformed cage has shape {new.shape}, the bound cage has "
                             f"{self.cage_v.shape}: vertex counts must match")
        if not np.all(np.isfinite(new)):
            raise InputError("deformed cage has NaN or inf coordinates")
        return _weights_times_vertices(self.weights, np.ascontiguousarray(new))

    def encloses(self, points) -> bool:
        """Whether the given points (usually the bound ones) all lie inside the cage."""
        return cage_encloses(points, self.cage_v, self.cage_f)


def bind(points, cage_v, cage_f, method: str = "mvc", chunk_size: int | None = None
         ) -> CageBinding:
    """Compute the coordinates of points with respect to a cage.

    Parameters
    ----------
    points : (n, 3) array_like of float
        Points to bind (mesh vertices or a point cloud). They may lie outside the cage:
        MVC is defined everywhere off the cage (weights may then be negative); see
        :func:`cagekit.cage_encloses` to check.
    cage_v : (k, 3) array_like of float
        Cage vertices.
    cage_f : (m, 3) array_like of int
        Cage faces: closed and 2-manifold. A consistently inward cage is flipped; an open,
        non-manifold or inconsistently oriented one raises :class:`cagekit.CageError`.
    method : {"mvc"}, default "mvc"
        Mean value coordinates (Ju, Schaefer & Warren 2005). Green coordinates are not
        available yet.
    chunk_size : int, optional
        Unused by MVC, whose scratch memory is already independent of ``n``; accepted so
        callers can pass it uniformly.

    Returns
    -------
    CageBinding

    Examples
    --------
    >>> from cagekit.shapes import box_cage
    >>> v, f = box_cage()
    >>> b = bind(np.zeros((1, 3)), v, f)
    >>> b.weights.shape, round(float(b.weights.sum()), 12)
    ((1, 8), 1.0)
    """
    from cagekit.coords.mvc import mean_value_coordinates

    if method not in METHODS:
        raise InputError(f"unknown coordinates {method!r}; available: {', '.join(METHODS)}")
    v = np.ascontiguousarray(cage_v, dtype=np.float64)
    faces = check_cage(v, cage_f)
    weights = mean_value_coordinates(points, v, faces, check=False)
    return CageBinding(weights, v, faces, method)
