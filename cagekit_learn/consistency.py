"""Fit a cage to a novel character by MVC consistency of landmarks ("Neural Cages", 4.2).

Given the template's cage ``C_s`` and landmarks ``p`` and the novel character's matching
landmarks ``q``, the character's cage ``C'`` minimises

``L_consistency(C') = sum_(p,q) sum_j (phi_j(p; C_s) - phi_j(q; C'))**2
+ w_L * sum_j (|(L C_s)_j| - |(L C')_j|)**2``

with ``w_L = 0.05`` (the paper's) and one ``L``, the cotangent Laplacian of ``C_s``
(:func:`cagekit.geometry.cotangent_laplacian`), applied to both cages. Ours where the paper
is silent: the character is first mapped onto the template by a similarity (``"similarity"``,
Umeyama on the landmarks; or a given :class:`~cagekit.geometry.alignment.Similarity`, such as the
bounding-box one of :func:`cagekit.geometry.alignment.box_alignment`), the fit starts from ``C_s``
there and is mapped back, so a similar copy of the template gets that similarity of ``C_s``
at zero residual. nlopt's
L-BFGS uses the analytic gradient of :func:`cagekit_learn.coords.mean_value_coordinates`
(float64, torch on one thread) and stops at a relative improvement below 1e-9 or after
``max_evaluations`` (300). The result reports both terms and ``converged``
(``L_consistency < tolerance``): when proportions differ from the template's no cage fits
every landmark, and the residual is never hidden. See docs/architecture.md.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch
from numpy.typing import ArrayLike

from cagekit.cage import check_cage
from cagekit.coords import bind as bind_numpy
from cagekit.deformation.solver import minimise
from cagekit.errors import InputError
from cagekit.geometry import as_vertices, cotangent_laplacian
from cagekit.geometry.alignment import Similarity, similarity_alignment
from cagekit_learn.coords import mean_value_coordinates
from cagekit_learn.threads import one_thread

__all__ = ["ConsistencyFit", "consistency_loss", "fit_cage_by_consistency", "LAPLACIAN_WEIGHT"]

#: weight of the Laplacian-length term (the paper's 0.05)
LAPLACIAN_WEIGHT = 0.05


@dataclass
class ConsistencyFit:
    """What :func:`fit_cage_by_consistency` returns.

    Attributes
    ----------
    cage_v : (k, 3) float64
        The fitted cage ``C_s'`` in the novel character's frame (same faces and vertex
        order as the template cage).
    cage_f : (m, 3) int64
    loss : float
        ``L_consistency`` at the result (both terms, in the aligned frame).
    mvc_term, laplacian_term : float
        The two terms (the Laplacian term unweighted).
    initial_loss : float
        ``L_consistency`` at the start.
    converged : bool
        ``loss < tolerance``.
    tolerance : float
    landmark_errors : (L,) float64
        ``|sum_j phi_j(p; C_s) c'_j - q|`` per landmark, in the character's units: where
        the template's coordinates put each landmark in the fitted cage.
    coordinate_residuals : (L,) float64
        ``|phi(p; C_s) - phi(q; C')|`` per landmark (Euclidean over the k coordinates).
    alignment : Similarity
        Template frame -> character frame, used to start and to map back.
    evaluations : int
    seconds : float
    """

    cage_v: np.ndarray
    cage_f: np.ndarray
    loss: float
    mvc_term: float
    laplacian_term: float
    initial_loss: float
    converged: bool
    tolerance: float
    landmark_errors: np.ndarray
    coordinate_residuals: np.ndarray
    alignment: Similarity
    evaluations: int
    seconds: float


class _ConsistencyEnergy:
    """``L_consistency`` and its gradient for nlopt (for
    :func:`cagekit.deformation.solver.minimise`)."""

    def __init__(self, phi_p, Qa, cage_f, lap, lap_norms, weight):
        self.phi_p = torch.as_tensor(phi_p, dtype=torch.float64)
        self.Qa = torch.as_tensor(Qa, dtype=torch.float64)
        self.cage_f = cage_f
        self.lap = torch.as_tensor(lap, dtype=torch.float64)
        self.lap_norms = torch.as_tensor(lap_norms, dtype=torch.float64)
        self.weight = float(weight)

    def terms(self, C):
        W = mean_value_coordinates(self.Qa, C, self.cage_f)
        mvc = ((W - self.phi_p) ** 2).sum()
        LC = self.lap @ C
        norms = torch.sqrt((LC ** 2).sum(dim=1) + 1e-300)
        return mvc, ((norms - self.lap_norms) ** 2).sum()

    def value(self, C) -> tuple[float, float, float]:
        with torch.no_grad():
            mvc, lap = self.terms(torch.as_tensor(C, dtype=torch.float64))
        mvc, lap = float(mvc), float(lap)
        return mvc + self.weight * lap, mvc, lap

    def __call__(self, C):
        Ct = torch.tensor(np.asarray(C, dtype=np.float64), requires_grad=True)
        mvc, lap = self.terms(Ct)
        total = mvc + self.weight * lap
        total.backward()
        f, g = float(total.detach()), Ct.grad.numpy()
        if not (np.isfinite(f) and np.isfinite(g).all()):
            raise FloatingPointError("L_consistency or its gradient is not finite")
        return f, g


def consistency_loss(cage_v: ArrayLike, cage_f: ArrayLike, source_landmarks: ArrayLike,
                     fitted_cage_v: ArrayLike, target_landmarks: ArrayLike,
                     laplacian_weight: float = LAPLACIAN_WEIGHT) -> dict[str, float]:
    """``L_consistency`` of a given cage (no fitting, no alignment).

    Parameters
    ----------
    cage_v : (k, 3) array_like of float
        The template cage ``C_s``.
    cage_f : (m, 3) array_like of int
    source_landmarks, target_landmarks : (L, 3) array_like of float
        Matching landmarks ``p`` (template) and ``q`` (character).
    fitted_cage_v : (k, 3) array_like of float
        The character's cage ``C_s'``, in the frame of ``q``.
    laplacian_weight : float, default 0.05

    Returns
    -------
    dict
        ``loss``, ``mvc_term``, ``laplacian_term`` (floats).
    """
    energy = _energy(cage_v, cage_f, source_landmarks, target_landmarks, laplacian_weight)
    loss, mvc, lap = energy.value(as_vertices(fitted_cage_v, "fitted_cage_v"))
    return {"loss": loss, "mvc_term": mvc, "laplacian_term": lap}


def _energy(cage_v, cage_f, P, Qa, weight):
    cage_v = as_vertices(cage_v, "cage_v")
    cage_f = check_cage(cage_v, cage_f)
    P, Qa = as_vertices(P, "source_landmarks"), as_vertices(Qa, "target_landmarks")
    if P.shape != Qa.shape:
        raise InputError(f"source and target landmarks must match one to one, got "
                         f"{len(P)} and {len(Qa)}")
    phi_p = bind_numpy(P, cage_v, cage_f).weights
    lap = cotangent_laplacian(cage_v, cage_f).toarray()
    return _ConsistencyEnergy(phi_p, Qa, cage_f, lap,
                              np.linalg.norm(lap @ cage_v, axis=1), weight)


def fit_cage_by_consistency(cage_v: ArrayLike, cage_f: ArrayLike,
                            source_landmarks: ArrayLike, target_landmarks: ArrayLike, *,
                            alignment: str | Similarity = "similarity",
                            init: ArrayLike | None = None,
                            laplacian_weight: float = LAPLACIAN_WEIGHT,
                            tolerance: float = 1e-5,
                            max_evaluations: int = 300) -> ConsistencyFit:
    """Fit the template cage to a novel character by MVC consistency of landmarks.

    Parameters
    ----------
    cage_v : (k, 3) array_like of float
        The template cage ``C_s`` (closed, 2-manifold, outward).
    cage_f : (m, 3) array_like of int
    source_landmarks : (L, 3) array_like of float
        The template's landmarks ``p``, inside or near ``C_s``; L >= 4.
    target_landmarks : (L, 3) array_like of float
        The character's matching landmarks ``q`` (row i matches row i).
    alignment : {"similarity", "none"} or Similarity, default "similarity"
        Template frame -> character frame (see the module docstring); ``"none"`` is the
        identity. :func:`cagekit.geometry.alignment.box_alignment` gives the bounding-box-and-height
        alignment.
    init : (k, 3) array_like of float, optional
        Starting cage in the *character's* frame; default ``C_s`` mapped by the alignment.
    laplacian_weight : float, default 0.05
    tolerance : float, default 1e-5
        ``converged`` reports ``L_consistency < tolerance``.
    max_evaluations : int, default 300
        Energy and gradient evaluations at most (L-BFGS also stops when an iteration
        improves the objective by less than 1e-9 of its value).

    Returns
    -------
    ConsistencyFit

    Raises
    ------
    InputError
        Fewer than 4 landmarks, mismatched counts, NaN, a bad cage.
    FloatingPointError
        The energy became non-finite.

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> p = np.random.default_rng(0).uniform(-0.5, 0.5, (8, 3))
    >>> fit = fit_cage_by_consistency(v, f, p, 2 * p + 1)
    >>> bool(np.allclose(fit.cage_v, 2 * v + 1)), fit.converged
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
    if isinstance(alignment, Similarity):
        A = alignment
    elif alignment == "similarity":
        A = similarity_alignment(P, Q)
    elif alignment == "none":
        A = Similarity.identity()
    else:
        raise InputError(f"alignment must be 'similarity', 'none' or a Similarity, got "
                         f"{alignment!r}")
    if not (np.isfinite(tolerance) and tolerance > 0 and max_evaluations >= 1):
        raise InputError("tolerance must be > 0 and max_evaluations >= 1")
    cage_v = as_vertices(cage_v, "cage_v")
    energy = _energy(cage_v, cage_f, P, A.invert(Q), laplacian_weight)
    C0 = cage_v if init is None else A.invert(as_vertices(init, "init"))
    if C0.shape != cage_v.shape:
        raise InputError(f"init must have the cage's shape {cage_v.shape}, got {C0.shape}")
    with one_thread():
        initial = energy.value(C0)[0]
        evaluations = 0
        C = C0
        if initial != 0.0:
            minimum = minimise(energy, C0, int(max_evaluations), 1e-9)
            C, evaluations = minimum.x, minimum.evaluations
        loss, mvc, lap = energy.value(C)
    if loss > initial:  # never worse than the start
        C = C0
        loss, mvc, lap = energy.value(C0)
    cage_out = A.apply(C)
    # the fitted cage may fold; the caller checks it (deformation transfer reports it)
    phi_q = bind_numpy(energy.Qa.numpy(), C, energy.cage_f, check=False).weights
    return ConsistencyFit(
        cage_v=cage_out, cage_f=energy.cage_f, loss=loss, mvc_term=mvc, laplacian_term=lap,
        initial_loss=initial, converged=bool(loss < tolerance), tolerance=float(tolerance),
        landmark_errors=np.linalg.norm(energy.phi_p.numpy() @ cage_out - Q, axis=1),
        coordinate_residuals=np.linalg.norm(energy.phi_p.numpy() - phi_q, axis=1),
        alignment=A, evaluations=evaluations, seconds=time.perf_counter() - start)
