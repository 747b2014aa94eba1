"""Rotations of 3x3 maps: the polar factor and ARAP's local step (per-vertex rotations)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cagekit.typed import Floats

__all__ = ["polar", "vertex_rotations"]


def polar(T: ArrayLike) -> tuple[Floats, Floats]:
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


def vertex_rotations(rest: ArrayLike, moved: ArrayLike, edges: ArrayLike) -> Floats:
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
