"""L-BFGS with an analytic gradient, robust to nlopt's line-search failures.

Both cage optimisations (:func:`cagekit.deform` and
:func:`cagekit_learn.consistency.fit_cage_by_consistency`) minimise a smooth-almost-
everywhere energy of the cage vertices with nlopt's ``LD_LBFGS``. The Chamfer term is not
differentiable where a nearest neighbour switches, and nlopt then ends a run with an
exception; :func:`minimise` keeps the best point seen and restarts from it once.
"""

from __future__ import annotations

from dataclasses import dataclass

import nlopt
import numpy as np

__all__ = ["Minimum", "minimise"]


@dataclass
class Minimum:
    """What :func:`minimise` returns.

    Attributes
    ----------
    x : ndarray of float64
        The best point seen, in the shape of ``x0``.
    value : float
        The objective there.
    evaluations : int
        Calls of the objective.
    """

    x: np.ndarray
    value: float
    evaluations: int


def minimise(objective, x0, max_evaluations: int, tolerance: float,
             progress=None) -> Minimum:
    """Minimise ``objective`` by L-BFGS from ``x0``; restarted once when the search fails.

    Parameters
    ----------
    objective : callable
        ``objective(x) -> (value, gradient)``, ``x`` and ``gradient`` in the shape of
        ``x0``. An exception it raises is re-raised (nlopt's own failures are not).
    x0 : ndarray of float64
        The start, any shape (a (k, 3) cage, typically).
    max_evaluations : int
        Calls of ``objective`` at most, over both runs.
    tolerance : float
        Relative change of the value that stops a run (nlopt's ``ftol_rel``).
    progress : callable, optional
        Called as ``progress(evaluations, max_evaluations)`` after each call.

    Returns
    -------
    Minimum

    Examples
    --------
    >>> m = minimise(lambda x: (float((x ** 2).sum()), 2 * x), np.ones((2, 3)), 50, 1e-12)
    >>> bool(m.value < 1e-12), m.x.shape
    (True, (2, 3))
    """
    x0 = np.asarray(x0, dtype=np.float64)
    shape = x0.shape
    best = {"f": np.inf, "x": x0.ravel().copy()}
    failure = []
    calls = [0]

    def wrapped(x, grad):
        try:
            f, g = objective(x.reshape(shape))
        except Exception as exc:  # noqa: BLE001 - handed back after nlopt returns
            failure.append(exc)
            raise nlopt.ForcedStop from exc
        calls[0] += 1
        if grad.size:
            grad[:] = np.asarray(g).ravel()
        if progress is not None:
            progress(calls[0], max_evaluations)
        if f < best["f"]:
            best["f"], best["x"] = f, x.copy()
        return f

    budget = max_evaluations
    for _ in range(2):
        start = calls[0]
        opt = nlopt.opt(nlopt.LD_LBFGS, x0.size)
        opt.set_min_objective(wrapped)
        opt.set_ftol_rel(tolerance)
        opt.set_maxeval(max(budget, 1))
        opt.set_vector_storage(10)
        try:
            opt.optimize(best["x"].copy())
            break  # converged (tolerance) or out of evaluations
        except Exception:  # noqa: BLE001 - nlopt's roundoff / failure: keep the best point
            if failure:
                raise failure[0] from None
        budget -= calls[0] - start
        if budget <= 0:
            break
    return Minimum(best["x"].reshape(shape), float(best["f"]), calls[0])
