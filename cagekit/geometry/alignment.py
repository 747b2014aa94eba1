"""Alignments between two shapes: per-axis box scaling and similarities.

The coarse stage of :func:`cagekit.deform` maps one bounding box onto the other
(:func:`box_scale`, the paper's scaling baseline); deformation transfer maps a novel
character onto the template by a :class:`Similarity`, fitted to landmarks
(:func:`similarity_alignment`) or to the bounding boxes (:func:`box_alignment`). The torch
twin of :func:`box_scale` is :func:`cagekit_learn.alignment.box_scale`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cagekit.errors import InputError
from cagekit.geometry import as_vertices
from cagekit.typed import Floats, Vertices

__all__ = ["box_scale", "partial_box_scale", "Similarity", "similarity_alignment",
           "box_alignment", "FLAT"]

#: an axis below this share of the largest half-extent is flat (its box factor stays 1)
FLAT = 1e-9


def box_scale(Vs_n: ArrayLike, Vt_n: ArrayLike) -> Floats:
    """Per-axis factors mapping the bounding box of one centred shape onto another's.

    Parameters
    ----------
    Vs_n, Vt_n : (n, 3) and (m, 3) float64
        Source and target, each normalised (bounding box centred at the origin).

    Returns
    -------
    (3,) float64
        ``half_extent(target) / half_extent(source)`` per axis; 1 on an axis where
        either shape is flat (below :data:`FLAT` of its largest extent).

    Examples
    --------
    >>> box_scale(np.array([[-1.0, -0.5, 0], [1, 0.5, 0]]), np.array([[-1.0, -1, 0], [1, 1, 0]]))
    array([1., 2., 1.])
    """
    hs = 0.5 * np.ptp(Vs_n, axis=0)
    ht = 0.5 * np.ptp(Vt_n, axis=0)
    flat = (hs < FLAT * hs.max()) | (ht < FLAT * ht.max())
    return np.where(flat, 1.0, ht / np.where(flat, 1.0, hs))


def partial_box_scale(Vs_n: ArrayLike, Vt_n: ArrayLike) -> Floats:
    """:func:`box_scale` onto a scan seen from one side: no factor below the median.

    A scan covers the target's extent across the view and only part of it along the
    view (a chair seen from behind is a flat backrest); that axis's factor comes out too
    small and would squash the source. Each factor is raised to at least the median of
    the three: the target is assumed to keep the source's proportion there.

    Parameters
    ----------
    Vs_n, Vt_n : (n, 3) and (m, 3) float64
        Source and scan, each normalised.

    Returns
    -------
    (3,) float64

    Examples
    --------
    >>> s = np.array([[-1.0, -1, -1], [1, 1, 1]])
    >>> partial_box_scale(s, np.array([[-2.0, -1, -0.2], [2, 1, 0.2]]))
    array([2., 1., 1.])
    """
    factors = box_scale(Vs_n, Vt_n)
    return np.maximum(factors, np.median(factors))


@dataclass(frozen=True)
class Similarity:
    """``x -> scale * rotation @ x + translation``.

    Attributes
    ----------
    scale : float
        Positive.
    rotation : (3, 3) float64
        A proper rotation.
    translation : (3,) float64
    """

    scale: float
    rotation: np.ndarray
    translation: np.ndarray

    @classmethod
    def identity(cls) -> Similarity:
        return cls(1.0, np.eye(3), np.zeros(3))

    def apply(self, X: ArrayLike) -> Vertices:
        """(n, 3) points -> (n, 3) mapped points (float64)."""
        return self.scale * np.asarray(X, dtype=np.float64) @ self.rotation.T + self.translation

    def invert(self, Y: ArrayLike) -> Vertices:
        """The inverse map: (n, 3) -> (n, 3)."""
        return (np.asarray(Y, dtype=np.float64) - self.translation) @ self.rotation / self.scale

    def apply_vectors(self, D: ArrayLike) -> Vertices:
        """Displacements mapped by the linear part only: (n, 3) -> (n, 3)."""
        return self.scale * np.asarray(D, dtype=np.float64) @ self.rotation.T

    def to_dict(self) -> dict:
        return {"scale": float(self.scale), "rotation": self.rotation.tolist(),
                "translation": self.translation.tolist()}


def similarity_alignment(P: ArrayLike, Q: ArrayLike) -> Similarity:
    """The similarity ``A`` minimising ``sum_i |A(p_i) - q_i|**2`` (Umeyama 1991).

    Parameters
    ----------
    P, Q : (n, 3) array_like of float
        Matching points, n >= 3, not all collinear.

    Returns
    -------
    Similarity
        ``Q ≈ A.apply(P)``; the rotation is proper (no reflection).

    Examples
    --------
    >>> P = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> A = similarity_alignment(P, 2 * P + 1)
    >>> round(A.scale, 12), A.translation.tolist()
    (2.0, [1.0, 1.0, 1.0])
    """
    P, Q = as_vertices(P, "P"), as_vertices(Q, "Q")
    if P.shape != Q.shape or len(P) < 3:
        raise InputError(f"need matching (n, 3) point sets with n >= 3, got {P.shape} "
                         f"and {Q.shape}")
    mp, mq = P.mean(axis=0), Q.mean(axis=0)
    Pc, Qc = P - mp, Q - mq
    var = float((Pc ** 2).sum())
    if var <= 0.0:
        raise InputError("the landmarks all lie at one point: no scale can be fitted")
    if np.linalg.svd(Pc, compute_uv=False)[1] <= 1e-9 * np.sqrt(var):
        raise InputError("the landmarks are collinear: the rotation about their line "
                         "cannot be fitted")
    U, S, Vt = np.linalg.svd(Qc.T @ Pc)
    D = np.eye(3)
    D[2, 2] = np.sign(np.linalg.det(U @ Vt)) or 1.0
    R = U @ D @ Vt
    scale = float((S * np.diag(D)).sum() / var)
    if scale <= 0.0:
        raise InputError("the target landmarks are degenerate: no similarity fits them")
    return Similarity(scale, R, mq - scale * R @ mp)


def box_alignment(source_v: ArrayLike, target_v: ArrayLike, up: int = 1) -> Similarity:
    """Match bounding-box centres and heights: no rotation.

    Parameters
    ----------
    source_v, target_v : (n, 3), (m, 3) array_like of float
        Vertices of the two rest-pose meshes.
    up : int, default 1
        The height axis (y).

    Returns
    -------
    Similarity
        Scale = target height / source height along ``up``; the source's bounding-box
        centre goes to the target's.
    """
    S, T = as_vertices(source_v, "source_v"), as_vertices(target_v, "target_v")
    hs = float(np.ptp(S[:, up]))
    ht = float(np.ptp(T[:, up]))
    if hs <= 0.0 or ht <= 0.0:
        raise InputError("a mesh has zero height: cannot align by height")
    scale = ht / hs
    cs = (S.min(axis=0) + S.max(axis=0)) / 2
    ct = (T.min(axis=0) + T.max(axis=0)) / 2
    return Similarity(scale, np.eye(3), ct - scale * cs)
