"""L-BFGS with an analytic gradient, robust to nlopt's line-search failures and to Ctrl-C.

Both cage optimisations (:func:`cagekit.deform` and
:func:`cagekit_learn.consistency.fit_cage_by_consistency`) minimise a smooth-almost-
everywhere energy of the cage vertices with nlopt's ``LD_LBFGS``. The Chamfer term is not
differentiable where a nearest neighbour switches, and nlopt then ends a run with an
exception; :func:`minimise` keeps the best point seen and restarts from it once.

nlopt calls the objective from native code, which must never see an exception other than
its own ``ForcedStop``: one it does not expect (a ``KeyboardInterrupt`` raised by the SIGINT
handler, say) leaves it running on with the exception set, and it comes out later as a
``SystemError`` ("returned a result with an exception set") or not at all. So an exception
of the objective is kept and the run forced to stop, and a SIGINT that arrives while nlopt
runs is handed to the installed handler at the start of the next evaluation (or once nlopt
has returned), where what the handler raises is kept the same way.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import nlopt
import numpy as np
from numpy.typing import ArrayLike

from cagekit.errors import exception_chain
from cagekit.interrupts import sigint_deferred
from cagekit.typed import Floats

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


def minimise(objective: Callable[[Floats], tuple[float, ArrayLike]], x0: ArrayLike,
             max_evaluations: int, tolerance: float,
             progress: Callable[[int, int], object] | None = None) -> Minimum:
    """Minimise ``objective`` by L-BFGS from ``x0``; restarted once when the search fails.

    Parameters
    ----------
    objective : callable
        ``objective(x) -> (value, gradient)``, ``x`` and ``gradient`` in the shape of
        ``x0``. An exception it raises (``KeyboardInterrupt`` included) is re-raised once
        nlopt has returned, and it is not called again (nlopt's own failures are not
        re-raised).
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

    Raises
    ------
    BaseException
        What ``objective`` or ``progress`` raised, or what the SIGINT handler raised for a
        SIGINT during the run (``KeyboardInterrupt`` by default).

    Examples
    --------
    >>> m = minimise(lambda x: (float((x ** 2).sum()), 2 * x), np.ones((2, 3)), 50, 1e-12)
    >>> bool(m.value < 1e-12), m.x.shape
    (True, (2, 3))
    """
    x0 = np.asarray(x0, dtype=np.float64)
    with sigint_deferred() as pending:
        search = _Search(objective, x0, max_evaluations, progress, pending)
        budget = max_evaluations
        for _ in range(2):
            start = search.calls
            if search.run(budget, tolerance):
                break  # converged (tolerance) or out of evaluations
            budget -= search.calls - start
            if budget <= 0:
                break
    return Minimum(search.best_x.reshape(x0.shape), float(search.best_f), search.calls)


class _Search:
    """The objective as nlopt calls it: the best point seen, the calls, and the exception
    that stopped the search (raised again once nlopt has returned)."""

    def __init__(self, objective: Callable[[Floats], tuple[float, ArrayLike]], x0: Floats,
                 max_evaluations: int, progress: Callable[[int, int], object] | None,
                 pending: Callable[[], object]) -> None:
        self.objective, self.shape = objective, x0.shape
        self.max_evaluations, self.progress, self.pending = max_evaluations, progress, pending
        self.best_f, self.best_x = np.inf, x0.ravel().copy()
        self.calls = 0
        self.failure: BaseException | None = None

    def __call__(self, x, grad):
        """nlopt's objective: never lets an exception but ``ForcedStop`` out."""
        try:
            if self.failure is None:
                self.pending()  # a deferred SIGINT: its handler runs here
                return self._evaluate(x, grad)
        except BaseException as exc:  # noqa: BLE001 - raised again once nlopt returns
            self.failure = exc
        raise nlopt.ForcedStop

    def _evaluate(self, x, grad):
        f, g = self.objective(x.reshape(self.shape))
        self.calls += 1
        if grad.size:
            grad[:] = np.asarray(g).ravel()
        if self.progress is not None:
            self.progress(self.calls, self.max_evaluations)
        if f < self.best_f:
            self.best_f, self.best_x = f, x.copy()
        return f

    def run(self, budget: int, tolerance: float) -> bool:
        """One L-BFGS run from the best point so far; True when it ended normally (converged
        or out of evaluations), False when nlopt failed (roundoff...). Raises what stopped
        it."""
        opt = nlopt.opt(nlopt.LD_LBFGS, self.best_x.size)
        opt.set_min_objective(self)
        opt.set_ftol_rel(tolerance)
        opt.set_maxeval(max(budget, 1))
        opt.set_vector_storage(10)
        try:
            opt.optimize(self.best_x.copy())
            ended = True
        except Exception as exc:  # noqa: BLE001 - nlopt's roundoff / failure: keep the best
            ended = False
            cause = _interrupt_in_chain(exc)
            if self.failure is None and cause is not None:
                self.failure = cause  # escaped our wrapper (it should not): never lose it
        self.pending()  # a SIGINT after the last evaluation
        if self.failure is not None:
            raise self.failure
        return ended


def _interrupt_in_chain(exc: BaseException) -> BaseException | None:
    """The first exception in ``exc``'s cause/context chain that is not an ``Exception``
    (``KeyboardInterrupt``, the command line's ``Interrupted``), or None."""
    return next((e for e in exception_chain(exc) if not isinstance(e, Exception)), None)
