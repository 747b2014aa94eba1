"""A predicted cage checked before it is used: valid, grown until it encloses, or refused.

A network's source cage is a guess: it may leave parts of the source outside (a leg
tip, a sofa's arm) or fold through itself. Neither may reach the user silently, so
:func:`check_predicted_cage` judges every prediction:

- **valid**: no face crosses another (the exact test of
  :func:`cagekit.cage.self_intersecting_faces`) and every source point lies inside or on
  it (generalised winding number at least 0.5; the compiled
  :func:`cagekit.coords.winding.batched_winding_numbers`, libigl's numbers to 1e-12 away
  from the cage's surface, where both are ill-defined, and 10x faster on a 6,000-vertex
  chair and the 80-face template);
- **repaired**: a cage that crosses nothing but leaves points outside is grown about the
  points' bounding-box centre by the least factor, up to :data:`MAX_GROWTH`, that takes
  them all in (bisection to :data:`GROWTH_STEP`); its deformed cage is the predicted
  deformation evaluated at the grown cage's vertices (the predicted cage's mean value
  coordinates applied to the predicted deformed cage), so an affine predicted motion
  stays exactly that motion;
- **invalid** otherwise (crossing faces, or points outside even at :data:`MAX_GROWTH`):
  ``problem`` says why and the caller does not use the cage
  (:func:`cagekit_learn.inference.deform_with_model` falls back to a fitted cage).

Growth cannot undo a fold, which is why crossing faces are refused, not repaired.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cagekit.cage import self_intersecting_faces
from cagekit.coords import bind
from cagekit.coords.winding import batched_winding_numbers
from cagekit.errors import OutsideCageWarning
from cagekit.typed import Vertices

__all__ = ["MAX_GROWTH", "GROWTH_STEP", "CheckedCage", "check_predicted_cage"]

#: the largest growth a repair may apply (beyond it the prediction is too far off)
MAX_GROWTH = 1.3
#: the bisection's resolution of the growth factor
GROWTH_STEP = 2e-3


@dataclass(frozen=True)
class CheckedCage:
    """What :func:`check_predicted_cage` found, and the cage to use.

    Attributes
    ----------
    cage_v, deformed_v : (k, 3) float64
        The source cage and its deformation to use: the predicted ones, or grown ones
        (``growth > 1``).
    growth : float
        1.0 when the prediction was used as it is.
    outside_share : float
        The share of points the *predicted* cage left outside (before any growth).
    crossing_faces : int
        Faces of the predicted cage that cross another face.
    problem : str or None
        None when the cage is usable; otherwise why not, as a message fragment.
    """

    cage_v: Vertices
    deformed_v: Vertices
    growth: float
    outside_share: float
    crossing_faces: int
    problem: str | None

    @property
    def valid(self) -> bool:
        """Whether the cage (as repaired) may be used."""
        return self.problem is None


def _outside(points: np.ndarray, cage_v: np.ndarray, cage_f: np.ndarray) -> np.ndarray:
    return batched_winding_numbers(points[None], cage_v[None], cage_f)[0] < 0.5 - 1e-9


def check_predicted_cage(points: ArrayLike, cage_v: ArrayLike, deformed_v: ArrayLike,
                         cage_f: ArrayLike, *, max_growth: float = MAX_GROWTH) -> CheckedCage:
    """Judge a predicted cage against the points it must carry, and repair it if it can.

    Parameters
    ----------
    points : (n, 3) array_like of float
        The source's points (its vertices), in the cage's frame.
    cage_v, deformed_v : (k, 3) array_like of float
        The predicted source cage and deformed cage.
    cage_f : (m, 3) array_like of int
        Their faces, closed, 2-manifold and outward (:func:`cagekit.check_cage`).
    max_growth : float, default :data:`MAX_GROWTH`
        At least 1.

    Returns
    -------
    CheckedCage

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> points = [[-1.05, 0, 0], [1.05, 0, 0], [0, 0.5, 0], [0, -0.5, 0]]
    >>> checked = check_predicted_cage(points, v, 2 * v, f)
    >>> checked.valid, round(checked.growth, 2), round(checked.outside_share, 2)
    (True, 1.05, 0.5)
    >>> bool(np.allclose(checked.deformed_v, 2 * checked.cage_v))  # an affine motion kept
    True
    """
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    C = np.asarray(cage_v, dtype=np.float64)
    D = np.asarray(deformed_v, dtype=np.float64)
    F = np.asarray(cage_f, dtype=np.int64)
    if max_growth < 1:
        raise ValueError(f"max_growth must be at least 1, got {max_growth}")
    crossing = int(self_intersecting_faces(C, F).sum())
    outside = _outside(P, C, F)
    share = float(outside.mean()) if len(P) else 0.0

    def result(cage, deformed, growth, problem=None):
        return CheckedCage(cage, deformed, growth, share, crossing, problem)

    if crossing:
        return result(C, D, 1.0, f"it intersects itself ({crossing} of {len(F)} faces)")
    if not outside.any():
        return result(C, D, 1.0)
    centre = 0.5 * (P.min(axis=0) + P.max(axis=0))
    growth = _least_growth(P[outside], C, F, centre, max_growth)  # the stray points first
    if growth is not None and _outside(P, centre + growth * (C - centre), F).any():
        growth = _least_growth(P, C, F, centre, max_growth)  # a cage not star-shaped
    if growth is None:                                        # about the centre lost some
        return result(C, D, 1.0, f"it leaves {100 * share:.3g}% of the source outside, "
                                 f"some still out when grown {max_growth:g}x")
    grown = centre + growth * (C - centre)
    with warnings.catch_warnings():  # the grown vertices lie just outside C, by design
        warnings.simplefilter("ignore", OutsideCageWarning)
        moved = bind(grown, C, F, method="mvc", check=False).deform(D)
    return result(grown, moved, growth)


def _least_growth(points, cage_v, cage_f, centre, max_growth) -> float | None:
    """The least factor (to :data:`GROWTH_STEP`) about ``centre`` that encloses the
    points, or None when :data:`MAX_GROWTH` does not."""

    def encloses(s):
        return not _outside(points, centre + s * (cage_v - centre), cage_f).any()

    if not encloses(max_growth):
        return None
    lo, hi = 1.0, float(max_growth)
    while hi - lo > GROWTH_STEP:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if encloses(mid) else (mid, hi)
    return hi
