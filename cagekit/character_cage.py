"""Fit a template's cage to a novel character from matching landmarks: a valid cage or none.

The cage ``C_s`` encloses the template; the character shares some landmark labels with it.
The character's cage ``C_c`` keeps ``C_s``'s faces and satisfies, as far as it can, the
landmark reproduction ``sum_j phi_j(p; C_s) c_j = q``: each template landmark, written in
the template's mean value coordinates, lands on its character landmark. The paper's MVC
consistency ``phi(q; C_c) = phi(p; C_s)`` implies it, and unlike that one it is linear in
``C_c``, so no torch and no MVC derivative is needed. In the template's frame (the character
mapped back by ``alignment``), local/global iterations (Sorkine & Alexa 2007) minimise

- as-similar-as-possible on the cage's edges (a rotation and a bounded scale per vertex,
  uniform edge weights): limbs turn and thicken, they do not shear, so a character whose
  arms hang lower than the template's gets a cage whose arms hang too;
- the landmark reproduction, weight ``landmark_weight``;
- enclosure contacts, after a first fit to the landmarks alone (contacts taken while the
  limbs still swing would pull the wrong part of the cage, a hand's faces to the hip):
  every character vertex found outside (winding number below 0.5) pulls its nearest cage
  point to ``margin`` beyond itself, for as long as it is outside or less than ``margin``
  inside.

Then the checks (:func:`cage_checks`): closed by construction (the template's faces), no
self-intersection, every character vertex inside. Each repair round smooths the
neighbourhood of the crossing faces (umbrella rows, weight doubling) and raises the contact
weight while vertices are outside, then iterates again; a cage still invalid after
``repair_rounds`` raises :class:`~cagekit.errors.CageFitError` naming what failed. The
paper's ``L_consistency`` (MVC term) is reported beside the landmark errors. See
docs/architecture.md.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from cagekit.alignment import Similarity
from cagekit.cage import (
    check_cage,
    self_intersecting_faces,
    signed_volume,
    unique_edges,
    winding_numbers,
)
from cagekit.coords import bind
from cagekit.errors import CageError, CageFitError, InputError
from cagekit.frame import Frame
from cagekit.geometry import as_vertices, polar

__all__ = ["CharacterCageFit", "fit_character_cage", "cage_checks", "LANDMARK_WEIGHT",
           "MARGIN"]

#: weight of the landmark reproduction against the edges' rigidity (sums of squares)
LANDMARK_WEIGHT = 4.0
#: how far outside a character vertex its cage is pushed, in cage diagonals
MARGIN = 0.002
#: starting weight of one enclosure contact (x4 each repair round that finds points outside)
CONTACT_WEIGHT = 4.0
#: bounds of the per-vertex scale of the as-similar-as-possible step
SCALE_RANGE = (0.67, 1.5)
#: the largest template cage the fit takes (its solves are dense)
MAX_CAGE_VERTICES = 5000
#: iterations between two searches for character vertices outside (winding numbers)
OUTSIDE_EVERY = 4
#: starting weight of the smoothing rows of the repair (x2 each round)
SMOOTH_WEIGHT = 0.5


@dataclass
class CharacterCageFit:
    """What :func:`fit_character_cage` returns.

    Attributes
    ----------
    cage_v : (k, 3) float64
        ``C_c`` in the character's frame (the template cage's faces and vertex order).
    cage_f : (m, 3) int64
    alignment : Similarity
        Template frame -> character frame.
    landmark_errors : (L,) float64
        ``|sum_j phi_j(p; C_s) c_j - q|`` per landmark, in the character's units.
    consistency : float
        The paper's MVC term ``sum |phi(p; C_s) - phi(q; C_c)|^2`` at the result.
    initial_consistency : float
        The same for ``C_s`` mapped by the alignment (the start).
    checks : dict
        :func:`cage_checks` of the result (``valid`` True).
    iterations, repairs, contacts : int
        Local/global iterations, repair rounds and enclosure contacts used.
    seconds : float
    """

    cage_v: np.ndarray
    cage_f: np.ndarray
    alignment: Similarity
    landmark_errors: np.ndarray
    consistency: float
    initial_consistency: float
    checks: dict = field(default_factory=dict)
    iterations: int = 0
    repairs: int = 0
    contacts: int = 0
    seconds: float = 0.0


def cage_checks(points, cage_v, cage_f) -> dict:
    """Is a cage fit to deform ``points``?

    Parameters
    ----------
    points : (n, 3) array_like of float
    cage_v : (k, 3) array_like of float
    cage_f : (m, 3) array_like of int
        Closed and outward (as :func:`cagekit.cage.check_cage` returns).

    Returns
    -------
    dict
        ``volume`` (signed), ``self_intersecting_faces`` (count), ``outside`` (share of
        the points with winding number below 0.5), ``min_winding``, ``problems`` (one
        line each) and ``valid`` (no problem).

    Examples
    --------
    >>> from cagekit.shapes import box_cage
    >>> v, f = box_cage()
    >>> c = cage_checks(np.zeros((1, 3)), v, f)
    >>> c["valid"], c["outside"]
    (True, 0.0)
    >>> cage_checks(np.full((1, 3), 5.0), v, f)["problems"]
    ['leaves 100.00% of the points outside (1 of 1)']
    """
    V = as_vertices(cage_v, "cage_v")
    F = np.asarray(cage_f, dtype=np.int64)
    volume = float(signed_volume(V, F))
    crossing = int(self_intersecting_faces(V, F).sum())
    w = winding_numbers(points, V, F)
    outside = int(np.sum(w < 0.5))
    problems = []
    if volume <= 0:
        problems.append(f"is inverted (signed volume {volume:.3g})")
    if crossing:
        problems.append(f"intersects itself ({crossing} of {len(F)} faces)")
    if outside:
        problems.append(f"leaves {100 * outside / len(w):.2f}% of the points outside "
                        f"({outside} of {len(w)})")
    return {"volume": volume, "self_intersecting_faces": crossing,
            "outside": outside / len(w), "min_winding": float(w.min()),
            "problems": problems, "valid": not problems}


class _CageARAP:
    """Local/global as-similar-as-possible fitting of one cage with soft linear rows."""

    def __init__(self, rest_v, faces):
        self.edges = unique_edges(faces)
        k, E = len(rest_v), len(self.edges)
        D = np.zeros((E, k))
        D[np.arange(E), self.edges[:, 0]] = 1.0
        D[np.arange(E), self.edges[:, 1]] = -1.0
        self.D = D
        self.rest_edges = D @ rest_v
        lengths = (self.rest_edges ** 2).sum(axis=1)
        self.spread = np.bincount(self.edges.ravel(), np.repeat(lengths, 2), minlength=k)

    def similarities(self, C) -> np.ndarray:
        """(k, 3, 3): per vertex, the scaled rotation best taking its rest spokes to
        ``C``'s (as-similar-as-possible: a limb may thicken, it may not shear)."""
        cov = np.einsum("ei,ej->eij", self.rest_edges, self.D @ C)
        S = np.zeros((len(C), 3, 3))
        np.add.at(S, self.edges[:, 0], cov)
        np.add.at(S, self.edges[:, 1], cov)
        # S = sum r c^T; the rotation maximising tr(R S) is that of S^T's polar
        # decomposition, and the best scale is the trace of its stretch over sum |r|^2
        R, stretch = polar(np.swapaxes(S, 1, 2))
        scale = np.trace(stretch, axis1=1, axis2=2) / np.maximum(self.spread, 1e-300)
        return R * np.clip(scale, SCALE_RANGE[0], SCALE_RANGE[1])[:, None, None]

    def solve(self, C, rows, targets, weights) -> np.ndarray:
        """The global step: ``min sum_e |d_e C - R_e r_e|^2 + sum_r w_r |a_r C - t_r|^2``."""
        R = self.similarities(C)
        Re = 0.5 * (R[self.edges[:, 0]] + R[self.edges[:, 1]])
        goal = np.einsum("eij,ej->ei", Re, self.rest_edges)
        A = rows * np.sqrt(weights)[:, None]
        K = self.D.T @ self.D + A.T @ A
        rhs = self.D.T @ goal + A.T @ (targets * np.sqrt(weights)[:, None])
        return np.linalg.solve(K, rhs)


def _face_frames(C, F):
    n = np.cross(C[F[:, 1]] - C[F[:, 0]], C[F[:, 2]] - C[F[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def _contact_rows(points, C, F, k, margin):
    """Rows ``(n', k)`` and targets ``(n', 3)`` of the active contacts: each point outside
    the cage, or inside by less than ``margin``, pulls its nearest cage point to
    ``margin`` beyond itself, outwards (points deeper inside are let go)."""
    import igl

    _, face, nearest = igl.point_mesh_squared_distance(points, C, F)
    face = np.asarray(face, dtype=np.int64)
    away = points - nearest
    length = np.linalg.norm(away, axis=1, keepdims=True)
    inside = winding_numbers(points, C, F) >= 0.5
    active = ~inside | (length[:, 0] < margin)
    points, face, nearest = points[active], face[active], nearest[active]
    away, length, inside = away[active], length[active], inside[active]
    tri = F[face]
    bary = np.asarray(igl.barycentric_coordinates(
        np.ascontiguousarray(nearest), C[tri[:, 0]].copy(), C[tri[:, 1]].copy(),
        C[tri[:, 2]].copy()))
    rows = np.zeros((len(points), k))
    np.add.at(rows, (np.repeat(np.arange(len(points)), 3), tri.ravel()), bary.ravel())
    direction = np.where(inside[:, None], -away, away) / np.maximum(length, 1e-300)
    on_face = length[:, 0] <= 1e-9 * margin
    direction[on_face] = _face_frames(C, F)[face[on_face]]
    return rows, points + margin * direction


def _umbrella(k, edges) -> np.ndarray:
    """(k, k) uniform Laplacian rows: a vertex minus the mean of its neighbours."""
    A = np.zeros((k, k))
    A[edges[:, 0], edges[:, 1]] = A[edges[:, 1], edges[:, 0]] = 1.0
    return np.eye(k) - A / np.maximum(A.sum(axis=1, keepdims=True), 1.0)


def _grow(vertices, edges) -> np.ndarray:
    """``vertices`` and their one-ring neighbours."""
    touch = np.isin(edges, vertices).any(axis=1)
    return np.union1d(vertices, edges[touch].ravel())


def fit_character_cage(cage_v, cage_f, source_landmarks, target_landmarks, character_v, *,
                       alignment: Similarity,
                       landmark_weight: float = LANDMARK_WEIGHT, margin: float = MARGIN,
                       iterations: int = 40, repair_rounds: int = 6) -> CharacterCageFit:
    """Fit the template cage to a character by landmarks, enclosing it, without folds.

    Parameters
    ----------
    cage_v : (k, 3) array_like of float
        The template cage ``C_s``: closed, 2-manifold, free of self-intersection.
    cage_f : (m, 3) array_like of int
    source_landmarks, target_landmarks : (L, 3) array_like of float
        Matching landmarks ``p`` on the template and ``q`` on the character; L >= 4.
    character_v : (n, 3) array_like of float
        The character's vertices (any number of parts, open or closed: only the vertices
        must be enclosed).
    alignment : Similarity
        Template frame -> character frame
        (:func:`cagekit.alignment.box_alignment`, :func:`~cagekit.alignment.similarity_alignment`).
    landmark_weight : float, default :data:`LANDMARK_WEIGHT`
    margin : float, default :data:`MARGIN`
        How far past each character vertex the enclosure contacts push the cage, in cage
        diagonals.
    iterations : int, default 40
        Local/global iterations of the fit (and again after each repair).
    repair_rounds : int, default 6

    Returns
    -------
    CharacterCageFit
        With ``checks["valid"]`` True.

    Raises
    ------
    InputError
        Fewer than 4 landmarks, mismatched counts, NaN, landmarks on one line, a bad
        template cage (a vertex no face uses, more than :data:`MAX_CAGE_VERTICES`).
    CageFitError
        No valid cage after the repairs: the message names what failed; its ``cage``
        attribute holds the rejected ``(cage_v, cage_f)`` (to look at, never to use).

    Examples
    --------
    >>> from cagekit.alignment import similarity_alignment
    >>> from cagekit.shapes import box_cage
    >>> v, f = box_cage()
    >>> p = np.random.default_rng(0).uniform(-0.4, 0.4, (8, 3))
    >>> A = similarity_alignment(p, 2 * p + 1)
    >>> fit = fit_character_cage(v, f, p, 2 * p + 1, 2 * p + 1, alignment=A)
    >>> bool(np.allclose(fit.cage_v, 2 * v + 1)), fit.checks["valid"]
    (True, True)
    """
    start = time.perf_counter()
    P = as_vertices(source_landmarks, "source_landmarks")
    Q = as_vertices(target_landmarks, "target_landmarks")
    if len(P) != len(Q):
        raise InputError(f"source and target landmarks must match one to one, got "
                         f"{len(P)} and {len(Q)}")
    if len(P) < 4:
        raise InputError(f"need at least 4 matching landmarks, got {len(P)}")
    for name, value in (("landmark_weight", landmark_weight), ("margin", margin)):
        if not (np.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a positive number, got {value!r}")
    _check_spread(Q, "the character's")
    _check_spread(P, "the template's")
    Cs = as_vertices(cage_v, "cage_v")
    F = check_cage(Cs, cage_f)
    unused = np.setdiff1d(np.arange(len(Cs)), F)
    if len(unused):
        raise CageError(f"cage vertex {int(unused[0])} is used by no face")
    if len(Cs) > MAX_CAGE_VERTICES:
        raise InputError(f"the template cage has {len(Cs)} vertices; the character fit "
                         f"takes at most {MAX_CAGE_VERTICES} (a coarse cage, as an artist's)")
    phi = bind(P, Cs, F).weights
    # the template's frame, scaled to a unit diagonal: every tolerance is relative
    frame = Frame.of(Cs, unit="diagonal")
    X = frame.to_unit(alignment.invert(as_vertices(character_v, "character_v")))
    Qa = frame.to_unit(alignment.invert(Q))
    Cs = frame.to_unit(Cs)
    gap = margin * float(np.linalg.norm(np.ptp(Cs, axis=0)))
    solver = _CageARAP(Cs, F)
    umbrella = _umbrella(len(Cs), solver.edges)
    C = Cs.copy()
    contacts = np.zeros(0, dtype=np.int64)
    smoothed = np.zeros(0, dtype=np.int64)
    smooth_weight, contact_weight = 0.0, CONTACT_WEIGHT

    def run(C, contacts, enclose=True):
        for i in range(iterations):
            if enclose and i % OUTSIDE_EVERY == 0:
                outside = np.flatnonzero(winding_numbers(X, C, F) < 0.5)
                contacts = np.union1d(contacts, outside)
            rows, targets = [phi], [Qa]
            weights = [np.full(len(P), landmark_weight)]
            if len(contacts):
                r, t = _contact_rows(X[contacts], C, F, len(C), gap)
                rows.append(r), targets.append(t)
                weights.append(np.full(len(r), contact_weight))
            if len(smoothed):
                rows.append(umbrella[smoothed]), targets.append(np.zeros((len(smoothed), 3)))
                weights.append(np.full(len(smoothed), smooth_weight))
            C = solver.solve(C, np.vstack(rows), np.vstack(targets), np.concatenate(weights))
            if not np.isfinite(C).all():
                raise CageFitError("the character cage fit diverged (non-finite positions)")
        return C, contacts

    # the landmarks alone first: contacts taken while limbs still swing would pull the
    # wrong part of the cage (a hand's faces to the hip)
    C, _ = run(C, contacts, enclose=False)
    C, contacts = run(C, contacts)
    checks = cage_checks(X, C, F)
    repairs = 0
    while not checks["valid"] and repairs < repair_rounds:
        if not (checks["self_intersecting_faces"] or checks["outside"]):
            break  # inverted only: nothing a repair round changes
        repairs += 1
        if checks["self_intersecting_faces"]:
            crossing = np.unique(F[self_intersecting_faces(C, F)])
            smoothed = np.union1d(smoothed, _grow(crossing, solver.edges))
            smooth_weight = SMOOTH_WEIGHT * 2.0 ** repairs
        if checks["outside"]:
            contact_weight *= 4.0
        C, contacts = run(C, contacts)
        checks = cage_checks(X, C, F)
    if not checks["valid"]:
        error = CageFitError("no valid character cage: the fitted cage "
                             + "; it ".join(checks["problems"])
                             + f" after {repairs} repair round(s)")
        error.cage = (alignment.apply(frame.to_world(C)), F)  # to look at what went wrong
        raise error
    cage_out = alignment.apply(frame.to_world(C))
    consistency = _consistency(phi, Qa, C, F)
    return CharacterCageFit(
        cage_v=cage_out, cage_f=F, alignment=alignment,
        landmark_errors=np.linalg.norm(phi @ cage_out - Q, axis=1),
        consistency=consistency, initial_consistency=_consistency(phi, Qa, Cs, F),
        checks=checks, iterations=iterations * (repairs + 2), repairs=repairs,
        contacts=len(contacts), seconds=time.perf_counter() - start)


def _check_spread(points, whose) -> None:
    """Refuse landmarks that all lie on one line (no 3D cage can be placed by them)."""
    centred = points - points.mean(axis=0)
    spread = np.linalg.svd(centred, compute_uv=False)
    if spread[0] <= 0 or spread[1] <= 1e-9 * spread[0]:
        raise InputError(f"{whose} landmarks all lie on one line or at one point: they "
                         "cannot place a cage")


def _consistency(phi, Qa, C, F) -> float:
    """The paper's MVC term ``sum |phi(p; C_s) - phi(q; C)|^2`` (numpy coordinates)."""
    return float(((bind(Qa, C, F, check=False).weights - phi) ** 2).sum())
