"""L-BFGS with restarts (cagekit.deformation.solver)."""

import signal

import numpy as np
import pytest

from cagekit.deformation.solver import minimise


def rosenbrock(x):
    a, b = x[..., 0], x[..., 1]
    value = float(((1 - a) ** 2 + 100 * (b - a ** 2) ** 2).sum())
    g = np.stack([-2 * (1 - a) - 400 * a * (b - a ** 2), 200 * (b - a ** 2)], axis=-1)
    return value, g


def test_minimise_finds_the_minimum_and_counts_its_calls():
    seen = []
    m = minimise(rosenbrock, np.zeros((3, 2)), 500, 1e-15,
                 progress=lambda done, total: seen.append((done, total)))
    np.testing.assert_allclose(m.x, np.ones((3, 2)), atol=1e-5)
    assert m.x.shape == (3, 2) and m.value == pytest.approx(rosenbrock(m.x)[0])
    assert m.evaluations == len(seen) and seen[-1] == (m.evaluations, 500)


def test_minimise_keeps_its_budget_and_the_best_point():
    m = minimise(rosenbrock, np.zeros((1, 2)), 5, 1e-15)
    assert m.evaluations <= 5 and m.value <= rosenbrock(np.zeros((1, 2)))[0]


def test_an_error_in_the_objective_is_raised():
    def broken(x):
        raise FloatingPointError("not finite")

    with pytest.raises(FloatingPointError, match="not finite"):
        minimise(broken, np.zeros(2), 10, 1e-9)


# ------------------------------------------------------------------ interrupts (issue 29)


class Stop(BaseException):
    """Like the command line's ``Interrupted``: a BaseException that is no Exception."""


def interrupted_at(k, interrupt, calls):
    """Rosenbrock's objective that raises ``interrupt`` at its ``k``-th call."""

    def objective(x):
        calls.append(len(calls) + 1)
        if len(calls) == k:
            raise interrupt()
        return rosenbrock(x)

    return objective


@pytest.mark.parametrize("interrupt", [KeyboardInterrupt, Stop])
def test_an_interrupt_in_the_objective_comes_out_of_minimise_as_itself(interrupt):
    """Raised inside nlopt's callback it used to come out as a SystemError ("returned a
    result with an exception set"), or not at all (the run went on)."""
    runs = minimise(rosenbrock, np.zeros((3, 2)), 500, 1e-15).evaluations  # 30 or so
    for k in range(1, runs + 1):  # at every evaluation of a whole run
        calls = []
        with pytest.raises(interrupt):
            minimise(interrupted_at(k, interrupt, calls), np.zeros((3, 2)), 500, 1e-15)
        assert calls[-1] == k  # and the objective is not called again after it


def test_sigint_during_minimise_reaches_the_handler_once_nlopt_has_returned():
    """A SIGINT while nlopt runs is handed to the installed handler where the handler's
    exception cannot land inside native code; the handler is back in place after."""

    def handler(signum, frame):
        raise Stop()

    previous = signal.signal(signal.SIGINT, handler)
    try:
        for k in (1, 2, 3, 8, 25):
            calls = []

            def objective(x, k=k, calls=calls):
                calls.append(1)
                if len(calls) == k:
                    signal.raise_signal(signal.SIGINT)
                return rosenbrock(x)

            with pytest.raises(Stop):
                minimise(objective, np.zeros((3, 2)), 500, 1e-15)
            assert len(calls) == k  # stopped at once: the objective is not called again
            assert signal.getsignal(signal.SIGINT) is handler
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_sigint_handler_that_does_not_raise_lets_minimise_finish():
    """A handler that only takes note of the signal is called, and the run goes on."""
    seen = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: seen.append(signum))
    try:
        calls = []

        def objective(x):
            calls.append(1)
            if len(calls) == 3:
                signal.raise_signal(signal.SIGINT)
            return rosenbrock(x)

        m = minimise(objective, np.zeros((3, 2)), 500, 1e-15)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert seen == [signal.SIGINT]
    np.testing.assert_allclose(m.x, np.ones((3, 2)), atol=1e-5)


def test_a_handler_that_replaces_itself_is_not_put_back():
    """The command line's handler ignores a second Ctrl-C while the first unwinds."""

    def handler(signum, frame):
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        raise Stop()

    def objective(x):
        calls.append(1)
        if len(calls) == 3:
            signal.raise_signal(signal.SIGINT)
        return rosenbrock(x)

    calls = []
    previous = signal.signal(signal.SIGINT, handler)
    try:
        with pytest.raises(Stop):
            minimise(objective, np.zeros((3, 2)), 500, 1e-15)
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)
