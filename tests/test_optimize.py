"""L-BFGS with restarts (cagekit.optimize)."""

import numpy as np
import pytest

from cagekit.optimize import minimise


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
