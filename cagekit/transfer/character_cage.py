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
  inside; each enclosure round raises their weight four-fold, and that of a vertex still
  outside four-fold more, until every vertex is in.

Each global step is Newton on that energy plus the cage's self-contact barrier
(:mod:`cagekit.cage.contact`), every step shortened to the part of its path along which no face
crosses another: the cage starts as the template's, free of self-intersection, and stays
so, however close the character's limbs hang to its body (walls of neighbouring tubes
squeeze together instead of crossing). Then the checks (:func:`cage_checks`): closed by
construction (the template's faces), no self-intersection, every character vertex inside,
and landmarks reached (misses above :data:`MAX_LANDMARK_ERROR` mean they asked for a fold);
otherwise :class:`~cagekit.errors.CageFitError` names what failed: the landmarks missed
most (by label) and the landmarks nearest the points left outside (the parts the cage
misses). The paper's ``L_consistency`` (MVC term) is reported beside the landmark errors. See
docs/architecture.md.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from cagekit.cage import (
    check_cage,
    self_intersecting_faces,
    signed_volume,
    unique_edges,
    winding_numbers,
)
from cagekit.cage.contact import DHAT, STIFFNESS, SelfContact, minimise_with_contact
from cagekit.coords import bind
from cagekit.errors import CageError, CageFitError, InputError
from cagekit.geometry import as_vertices, polar
from cagekit.geometry.alignment import Similarity
from cagekit.geometry.frame import Frame

__all__ = ["CharacterCageFit", "fit_character_cage", "cage_checks", "missed_landmarks",
           "nearest_landmarks", "LANDMARK_WEIGHT", "MARGIN"]

#: weight of the landmark reproduction against the edges' rigidity (sums of squares)
LANDMARK_WEIGHT = 4.0
#: how far outside a character vertex its cage is pushed, in cage diagonals
MARGIN = 0.001
#: starting weight of one enclosure contact (x4 each enclosure round)
CONTACT_WEIGHT = 4.0
#: bounds of the per-vertex scale of the as-similar-as-possible step
SCALE_RANGE = (0.67, 1.5)
#: the largest template cage the fit takes (its solves are dense)
MAX_CAGE_VERTICES = 5000
#: iterations between two searches for character vertices outside (winding numbers)
OUTSIDE_EVERY = 4
#: extra factor on the contact weight of a vertex still outside after a round (vertices
#: just inside the two walls of a thin fold push it both ways with equal weights; one
#: left in the fold must outweigh them to move it)
BOOST = 4.0
#: local/global iterations of the landmark stage and of each enclosure round
ITERATIONS = 30
#: enclosure rounds at most (each with four times the contact weight of the last)
ROUNDS = 12
#: Newton steps with the self-contact barrier per local/global iteration
NEWTON_STEPS = 2
#: the largest landmark miss accepted for 90% of the landmarks, in diagonals of the template
#: cage or of the character in the template's frame, whichever is larger (beyond it they
#: ask for a fold the barrier refuses: labels swapped left for right, say; the real
#: characters' fits stay below 0.025, labels mirrored left to right miss by 0.09; a
#: character far wider than the template, long arms held wide, misses by more in the
#: template cage's diagonals only because it is larger)
MAX_LANDMARK_ERROR = 0.05
#: how many labels a refusal names (landmarks missed most, parts left outside)
NAMED = 5


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
    iterations, rounds, contacts : int
        Local/global iterations, enclosure rounds and enclosure contacts used.
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
    rounds: int = 0
    contacts: int = 0
    seconds: float = 0.0


def cage_checks(points: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike) -> dict[str, Any]:
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
    >>> from cagekit.cage.shapes import box_cage
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

    def quadratic(self, C, rows, targets, weights):
        """The global step's energy ``sum_e |d_e X - R_e r_e|^2 + sum_r w_r |a_r X - t_r|^2``
        with the rotations ``R`` of ``C``, as ``tr(X^T H X) - 2 tr(X^T b) + c0``:
        ``(H (k, k), b (k, 3), c0)``."""
        R = self.similarities(C)
        Re = 0.5 * (R[self.edges[:, 0]] + R[self.edges[:, 1]])
        goal = np.einsum("eij,ej->ei", Re, self.rest_edges)
        A = rows * np.sqrt(weights)[:, None]
        T = targets * np.sqrt(weights)[:, None]
        H = self.D.T @ self.D + A.T @ A
        b = self.D.T @ goal + A.T @ T
        return H, b, float((goal ** 2).sum() + (T ** 2).sum())


def _face_frames(C, F):
    n = np.cross(C[F[:, 1]] - C[F[:, 0]], C[F[:, 2]] - C[F[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def _contact_rows(points, C, F, k, margin):
    """Rows ``(n', k)``, targets ``(n', 3)`` and the mask ``(n,)`` of the active contacts:
    each point outside the cage, or inside by less than ``margin``, pulls its nearest cage
    point to ``margin`` beyond itself, outwards (points deeper inside are let go)."""
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
    return rows, points + margin * direction, active


def fit_character_cage(cage_v: ArrayLike, cage_f: ArrayLike, source_landmarks: ArrayLike,
                       target_landmarks: ArrayLike, character_v: ArrayLike, *,
                       alignment: Similarity,
                       landmark_weight: float = LANDMARK_WEIGHT, margin: float = MARGIN,
                       iterations: int = ITERATIONS, rounds: int = ROUNDS,
                       labels: Sequence[str] | None = None) -> CharacterCageFit:
    """Fit the template cage to a character by landmarks, enclosing it, never folded.

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
        (:func:`cagekit.geometry.alignment.box_alignment`,
        :func:`~cagekit.geometry.alignment.similarity_alignment`).
    landmark_weight : float, default :data:`LANDMARK_WEIGHT`
    margin : float, default :data:`MARGIN`
        How far past each character vertex the enclosure contacts push the cage, in cage
        diagonals.
    iterations : int, default :data:`ITERATIONS`
        Local/global iterations of the landmark stage and of each enclosure round.
    rounds : int, default :data:`ROUNDS`
        Enclosure rounds at most (the contact weight x4 each).
    labels : sequence of str, optional
        The landmarks' names (L of them), for a refusal's message; by default
        ``landmark 0``, ``landmark 1`` ...

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
        No valid cage after the rounds, or landmarks the cage cannot reach without
        folding: the message names what failed, the landmarks missed most and those
        nearest the points left outside; its ``cage`` attribute holds the rejected
        ``(cage_v, cage_f)`` (to look at, never to use), ``missed`` the labels of the
        landmarks missed by more than :data:`MAX_LANDMARK_ERROR` and ``outside_near`` the
        labels nearest the points outside, with their counts.

    Examples
    --------
    >>> from cagekit.geometry.alignment import similarity_alignment
    >>> from cagekit.cage.shapes import box_cage
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
    labels = _landmark_labels(labels, len(P))
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
    fit = _Fit(Cs, F, phi, Qa, X, landmark_weight, margin)
    # the landmarks alone first: contacts taken while limbs still swing would pull the
    # wrong part of the cage (a hand's faces to the hip)
    C = fit.run(Cs, iterations, enclose=False)
    checks = cage_checks(X, C, F)
    # enclosure only pushes walls outwards: landmarks missed now stay missed
    miss = fit.landmark_miss(C)
    done = 0
    while checks["outside"] and done < rounds and miss <= MAX_LANDMARK_ERROR:
        C = fit.run(C, iterations, enclose=True)
        fit.contact_weight *= 4.0
        fit.boost_outside(C)
        done += 1
        checks = cage_checks(X, C, F)
        miss = fit.landmark_miss(C)
    if miss > MAX_LANDMARK_ERROR:
        checks["valid"] = False
        checks["problems"].append(
            f"misses 10% of its landmarks by more than {miss:.2f} diagonals (they "
            "cannot be reached without folding the cage: labels swapped?)")
    if not checks["valid"]:
        raise _refusal(fit, C, checks, labels, done, (alignment.apply(frame.to_world(C)), F))
    cage_out = alignment.apply(frame.to_world(C))
    return CharacterCageFit(
        cage_v=cage_out, cage_f=F, alignment=alignment,
        landmark_errors=np.linalg.norm(phi @ cage_out - Q, axis=1),
        consistency=_consistency(phi, Qa, C, F),
        initial_consistency=_consistency(phi, Qa, Cs, F),
        checks=checks, iterations=iterations * (done + 1), rounds=done,
        contacts=len(fit.contacts), seconds=time.perf_counter() - start)


class _Fit:
    """The energy of the fit (edges' similarity, landmark rows, enclosure contacts) and its
    minimisation with the cage's self-contact barrier."""

    def __init__(self, Cs, F, phi, Qa, X, landmark_weight, margin):
        self.F, self.phi, self.Qa, self.X = F, phi, Qa, X
        self.landmark_weight, self.contact_weight = landmark_weight, CONTACT_WEIGHT
        self.gap = margin * float(np.linalg.norm(np.ptp(Cs, axis=0)))
        # landmark misses are judged against the larger of the template cage (unit
        # diagonal) and the character: one far wider than the template misses by more
        self.unit = max(1.0, float(np.linalg.norm(np.ptp(X, axis=0))))
        self.solver = _CageARAP(Cs, F)
        # a barrier already pushing at the start would keep even a similar copy of the
        # template from getting the similar cage: it starts below the template's clearance
        self.contact = SelfContact(Cs, F)
        self.contact.dhat = min(DHAT, 0.9 * self.contact.clearance(Cs))
        self.stiffness = STIFFNESS * (DHAT / self.contact.dhat) ** 3
        self.contacts = np.zeros(0, dtype=np.int64)
        self.boost = np.ones(len(X))
        self._outside_of = (None, None)  # (cage, its outside mask): one search a cage

    def landmark_misses(self, C) -> np.ndarray:
        """(L,) float64: each landmark's miss, in units of :attr:`unit` (diagonals of the
        template cage or of the character, whichever is larger)."""
        return np.linalg.norm(self.phi @ C - self.Qa, axis=1) / self.unit

    def landmark_miss(self, C) -> float:
        """The 90th percentile of :meth:`landmark_misses`."""
        return float(np.quantile(self.landmark_misses(C), 0.9))

    def outside(self, C) -> np.ndarray:
        """(n,) bool: the character vertices outside cage ``C`` (winding number below 0.5),
        found once for a given array ``C``."""
        cage, mask = self._outside_of
        if cage is not C:
            mask = winding_numbers(self.X, C, self.F) < 0.5
            self._outside_of = (C, mask)
        return mask

    def boost_outside(self, C) -> None:
        """Raise the contact weight of every vertex still outside by :data:`BOOST`."""
        self.boost[self.outside(C)] *= BOOST

    def run(self, C, iterations: int, enclose: bool) -> np.ndarray:
        for i in range(iterations):
            if enclose and i % OUTSIDE_EVERY == 0:
                self.contacts = np.union1d(self.contacts, np.flatnonzero(self.outside(C)))
            rows, targets = [self.phi], [self.Qa]
            weights = [np.full(len(self.phi), self.landmark_weight)]
            if enclose and len(self.contacts):
                r, t, active = _contact_rows(self.X[self.contacts], C, self.F, len(C),
                                             self.gap)
                rows.append(r)
                targets.append(t)
                weights.append(self.contact_weight * self.boost[self.contacts[active]])
            H, b, c0 = self.solver.quadratic(C, np.vstack(rows), np.vstack(targets),
                                             np.concatenate(weights))
            C = minimise_with_contact(H, b, c0, C, self.contact, stiffness=self.stiffness,
                                      iterations=NEWTON_STEPS)
            if not np.isfinite(C).all():
                raise CageFitError("the character cage fit diverged (non-finite positions)")
        return C


def _landmark_labels(labels, count: int) -> list[str]:
    """``labels`` as a list of ``count`` strings (``landmark i`` when None)."""
    if labels is None:
        return [f"landmark {i}" for i in range(count)]
    _check_labels(labels, count)
    return [str(label) for label in labels]


def _check_labels(labels, count: int) -> None:
    """Refuse ``labels`` that do not name ``count`` landmarks one each."""
    if isinstance(labels, str) or len(labels) != count:
        raise InputError(f"labels must name each of the {count} landmarks, got "
                         f"{1 if isinstance(labels, str) else len(labels)}")


def _named(counts: dict, unit: str = "") -> str:
    """``a (3), b (1) and 2 more``: the first :data:`NAMED` of ``counts`` (label -> number,
    already ordered) with their numbers."""
    items = list(counts.items())
    shown = ", ".join(f"{label} ({value:{unit}})" for label, value in items[:NAMED])
    return shown + (f" and {len(items) - NAMED} more" if len(items) > NAMED else "")


def missed_landmarks(misses: ArrayLike, labels: Sequence[str],
                     limit: float = MAX_LANDMARK_ERROR) -> dict[str, float]:
    """The landmarks missed by more than ``limit``, the worst first.

    Parameters
    ----------
    misses : (L,) array_like of float
    labels : sequence of str
        L labels.
    limit : float, default :data:`MAX_LANDMARK_ERROR`

    Returns
    -------
    dict
        label -> miss (float), in decreasing order of miss.

    Examples
    --------
    >>> missed_landmarks([0.01, 0.2, 0.07], ["nose", "l_hand", "r_foot"])
    {'l_hand': 0.2, 'r_foot': 0.07}
    """
    misses = np.asarray(misses, dtype=np.float64).reshape(-1)
    _check_labels(labels, len(misses))
    if not np.isfinite(misses).all():
        raise InputError("missed_landmarks: a landmark's miss is NaN or inf")
    order = np.argsort(-misses, kind="stable")
    return {labels[i]: float(misses[i]) for i in order if misses[i] > limit}


def nearest_landmarks(points: ArrayLike, landmarks: ArrayLike,
                      labels: Sequence[str]) -> dict[str, int]:
    """For points (left outside a cage, say), the label of each one's nearest landmark,
    counted: which parts of the body they belong to.

    Parameters
    ----------
    points : (n, 3) array_like of float
    landmarks : (L, 3) array_like of float
    labels : sequence of str
        L labels.

    Returns
    -------
    dict
        label -> number of points (int), the most first; empty for no points.

    Examples
    --------
    >>> nearest_landmarks([[0, 0, 0.1], [2, 0, 0], [0, 0.2, 0]], [[0, 0, 0], [2, 0, 0]],
    ...                   ["head", "l_hand"])
    {'head': 2, 'l_hand': 1}
    """
    from scipy.spatial import cKDTree

    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    landmarks = np.asarray(landmarks, dtype=np.float64).reshape(-1, 3)
    _check_labels(labels, len(landmarks))
    if not (np.isfinite(points).all() and np.isfinite(landmarks).all()):
        raise InputError("nearest_landmarks: the points or the landmarks hold NaN or inf")
    if not len(points):
        return {}
    _, nearest = cKDTree(landmarks).query(points)
    counts = np.bincount(nearest, minlength=len(labels))
    order = np.argsort(-counts, kind="stable")
    return {labels[i]: int(counts[i]) for i in order if counts[i]}


def _refusal(fit: _Fit, C, checks: dict, labels, done: int, cage) -> CageFitError:
    """The :class:`CageFitError` of a refused fit: its problems, the landmarks missed most
    and the landmarks nearest the points left outside (unit frame ``C``)."""
    missed = missed_landmarks(fit.landmark_misses(C), labels)
    outside = nearest_landmarks(fit.X[fit.outside(C)], fit.Qa, labels)
    message = ("no valid character cage: the fitted cage " + "; it ".join(checks["problems"])
               + f" after {done} enclosure round(s)")
    if missed:
        message += (f"; landmarks missed by over {MAX_LANDMARK_ERROR} diagonals: "
                    + _named(missed, ".2f"))
    if outside:
        message += "; the points outside lie nearest " + _named(outside, "d")
    error = CageFitError(message)
    error.cage = cage  # to look at what went wrong
    error.missed, error.outside_near = list(missed), outside
    return error


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
