"""Parts that pass through each other in a variation but were apart in its source.

A deformation that keeps each part plausible (nearly affine, close to its target) can still
cross them: a four-legged chair deformed onto a pedestal chair brings its straight legs
together into a V under the seat. :func:`part_crossings` finds the pieces of surface that
pass through each other in the variation and were apart in the source: one exact
triangle-triangle test over the whole variation (libigl's CGAL
``remesh_self_intersections``, detection only, with its box-intersection prefilter) gives
the intersecting face pairs; a pair counts when its two faces did not intersect in the
source and were farther apart there than :data:`TOUCH_GAP` of the source's bounding-box
diagonal (exact triangle-to-triangle distance). Faces that touch in the source (a cushion
on a seat, a leg glued to a rail, two faces of one corner) never count, nor do two parts
that already pass through each other in the source (a leg pushed into its seat, which the
variation may push a little deeper). The counted pairs
are reported by part: the source's parts (:func:`cagekit.geometry.parts.face_parts`:
connected components through its faces, pieces split at seams joined), numbered in the
order of their first face; a part may cross itself (the front and back legs of one
side-frame brought together). :func:`cagekit.batch.amplify.amplify` rejects a variation
with crossing parts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cagekit.errors import InputError
from cagekit.geometry.parts import face_parts

__all__ = ["TOUCH_GAP", "Crossings", "part_crossings"]

#: two parts of a source closer than this (fraction of the source's bounding-box diagonal)
#: touch, and are not counted when they meet in the variation
TOUCH_GAP = 0.01


@dataclass(frozen=True)
class Crossings:
    """The parts of a variation that cross, as :func:`part_crossings` finds them.

    Attributes
    ----------
    pairs : tuple of (int, int)
        The crossing pairs of parts, ``(a, b)`` with ``a <= b`` (``a == b``: a part that
        crosses itself), in increasing order. Parts are numbered from 1 in the order of
        their first face in the source's face list.
    parts : int
        The number of parts of the source (:func:`cagekit.geometry.parts.face_parts`).
    """

    pairs: tuple[tuple[int, int], ...]
    parts: int

    @property
    def count(self) -> int:
        """The number of crossing pairs."""
        return len(self.pairs)

    def named(self, shown: int | None = None) -> str:
        """The crossing pairs in words (``""`` when none).

        Parameters
        ----------
        shown : int, optional
            Pairs named, the rest counted; None names them all.

        Returns
        -------
        str
            ``"2 and 3, 4 and 7 (+2 more)"``.

        Examples
        --------
        >>> Crossings(((2, 2), (2, 3), (4, 7)), parts=9).named(shown=2)
        '2 itself, 2 and 3 (+1 more)'
        """
        listed = self.pairs if shown is None else self.pairs[:shown]
        rest = len(self.pairs) - len(listed)
        return ", ".join(f"{a} and {b}" if a != b else f"{a} itself" for a, b in listed) + (
            f" (+{rest} more)" if rest > 0 else "")


def part_crossings(V_src: ArrayLike, F_src: ArrayLike, V_out: ArrayLike,
                   gap: float = TOUCH_GAP) -> Crossings:
    """The pairs of parts whose surfaces, apart in the source, intersect in the variation.

    Parameters
    ----------
    V_src : (n, 3) array_like of float
        The source's vertices.
    F_src : (m, 3) array_like of int
        Its faces (they define the parts: connected components).
    V_out : (n, 3) array_like of float
        The variation's vertices, in the source's order.
    gap : float, default :data:`TOUCH_GAP`
        Faces of the source closer than ``gap`` times its bounding-box diagonal touch: they
        never count.

    Returns
    -------
    Crossings

    Raises
    ------
    InputError
        Vertices that disagree in shape, faces out of range.

    Examples
    --------
    >>> import trimesh
    >>> box = trimesh.creation.box()
    >>> V = np.vstack([box.vertices, box.vertices + [2.0, 0, 0]])
    >>> F = np.vstack([box.faces, box.faces + 8])
    >>> moved = V.copy()
    >>> moved[8:] -= [1.5, 0, 0]  # the second box now half inside the first
    >>> part_crossings(V, F, moved).pairs, part_crossings(V, F, V).count
    (((1, 2),), 0)
    """
    Vs, Vo, F = _checked(V_src, F_src, V_out)
    labels = face_parts(Vs, F)
    parts = int(labels.max()) + 1 if len(labels) else 0
    if parts == 0:
        return Crossings((), parts)
    at_rest = _intersecting_faces(Vs, F)
    new = _intersecting_faces(Vo, F) - at_rest
    if not new:
        return Crossings((), parts)
    faces = np.array(sorted(new), dtype=np.int64).reshape(-1, 2)
    tolerance = gap * float(np.linalg.norm(np.ptp(Vs, axis=0)))
    apart = _triangle_distances(Vs[F[faces[:, 0]]], Vs[F[faces[:, 1]]]) > tolerance
    a, b = labels[faces[apart, 0]], labels[faces[apart, 1]]
    pairs = set(zip((np.minimum(a, b) + 1).tolist(), (np.maximum(a, b) + 1).tolist()))
    return Crossings(tuple(sorted(pairs - _joined_parts(at_rest, labels))), parts)


def _joined_parts(face_pairs, labels) -> set[tuple[int, int]]:
    """The pairs of distinct parts (numbered from 1) that already pass through each other
    in the source (a leg pushed into its seat): they touch, and pushing one deeper into
    the other is no crossing."""
    if not face_pairs:
        return set()
    faces = np.array(sorted(face_pairs), dtype=np.int64).reshape(-1, 2)
    a, b = labels[faces[:, 0]], labels[faces[:, 1]]
    distinct = a != b
    return set(zip((np.minimum(a, b)[distinct] + 1).tolist(),
                   (np.maximum(a, b)[distinct] + 1).tolist()))


def _checked(V_src, F_src, V_out):
    """The inputs as float64 (n, 3), float64 (n, 3) and int64 (m, 3) arrays, checked."""
    Vs = np.ascontiguousarray(V_src, dtype=np.float64)
    Vo = np.ascontiguousarray(V_out, dtype=np.float64)
    F = np.ascontiguousarray(np.asarray(F_src, dtype=np.int64).reshape(-1, 3))
    if Vs.ndim != 2 or Vs.shape[1] != 3 or Vs.shape != Vo.shape:
        raise InputError(f"source and variation vertices must both be (n, 3), got "
                         f"{Vs.shape} and {Vo.shape}")
    if len(F) and (F.min() < 0 or F.max() >= len(Vs)):
        raise InputError(f"face indices must lie in 0..{len(Vs) - 1}")
    return Vs, Vo, F


def _intersecting_faces(V, F) -> set[tuple[int, int]]:
    """The pairs ``(f, g)``, ``f < g``, of faces that intersect (or touch, other than at
    the vertices and edges they share): libigl's exact CGAL test, detection only, on the
    vertices scaled to unit extent."""
    from igl.copyleft.cgal import remesh_self_intersections

    lo = V.min(axis=0)
    scale = float(np.max(np.ptp(V, axis=0)))
    unit = (V - lo) / scale if scale > 0 and np.isfinite(scale) else V
    pairs = remesh_self_intersections(np.ascontiguousarray(unit), F, detect_only=True)[2]
    pairs = np.sort(np.asarray(pairs, dtype=np.int64).reshape(-1, 2), axis=1)
    return set(zip(pairs[:, 0].tolist(), pairs[:, 1].tolist()))


def _triangle_distances(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """The distance between triangles ``A[i]`` and ``B[i]``, (k, 3, 3) each, assumed not
    to intersect: the least of their vertices' distances to the other triangle and of
    their edges' distances to each other's edges, (k,)."""
    from trimesh.triangles import closest_point

    best = np.full(len(A), np.inf)
    for mine, theirs in ((A, B), (B, A)):
        for corner in range(3):
            gaps = mine[:, corner] - closest_point(theirs, mine[:, corner])
            best = np.minimum(best, np.linalg.norm(gaps, axis=1))
    for i in range(3):
        for j in range(3):
            best = np.minimum(best, _segment_distances(A[:, i], A[:, (i + 1) % 3],
                                                       B[:, j], B[:, (j + 1) % 3]))
    return best


def _segment_distances(p1, q1, p2, q2) -> np.ndarray:
    """The distance between segments ``p1[i] q1[i]`` and ``p2[i] q2[i]``, (k, 3) each
    (Ericson, Real-Time Collision Detection, 5.1.9), (k,)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    tiny = 1e-300
    denom = a * e - b * b
    s = np.where(denom > tiny, np.clip((b * f - c * e) / np.maximum(denom, tiny), 0, 1), 0.0)
    t = (b * s + f) / np.maximum(e, tiny)
    s = np.where(t < 0, np.clip(-c / np.maximum(a, tiny), 0, 1), s)
    s = np.where(t > 1, np.clip((b - c) / np.maximum(a, tiny), 0, 1), s)
    t = np.clip(t, 0, 1)
    s = np.where(a > tiny, s, 0.0)
    t = np.where(e > tiny, t, 0.0)
    gaps = (p1 + d1 * s[:, None]) - (p2 + d2 * t[:, None])
    return np.linalg.norm(gaps, axis=1)
