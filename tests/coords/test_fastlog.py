"""The polynomial log of a ratio used by the Green kernel agrees with a long-double reference."""

import numba
import numpy as np

from cagekit.coords.fastlog import LOG_COEFFICIENTS, fit_log_polynomial, log_ratio


@numba.njit(error_model="numpy")
def _logs(num, den):
    out = np.empty_like(num)
    for i in range(num.size):
        out[i] = log_ratio(num[i], den[i])
    return out


def _ulps(got, exact):
    return np.abs(got - exact) / np.spacing(np.abs(exact).astype(np.float64))


def test_full_precision_over_the_whole_range():
    rng = np.random.default_rng(0)
    num = 10.0 ** rng.uniform(-307, 307, 500_000) * rng.uniform(1, 2, 500_000)
    den = 10.0 ** rng.uniform(-307, 307, 500_000)
    # the long double ratio is within 6e-20 of the exact one: a reference where |log| > 0.01
    exact = np.log(num.astype(np.longdouble) / den.astype(np.longdouble))
    assert _ulps(_logs(num, den), exact)[np.abs(exact) > 0.01].max() <= 2.5


def test_full_precision_near_one():
    # ratios close to 1, across powers of two: the log of the ratio is small
    rng = np.random.default_rng(1)
    den = 2.0 ** rng.integers(-20, 20, 400_000) * rng.uniform(0.5, 2.0, 400_000)
    num = den * (1 + rng.normal(size=400_000) * 10.0 ** rng.uniform(-15, 0, 400_000))
    num = np.abs(num)
    exact = np.log1p((num.astype(np.longdouble) - den) / den)
    assert _ulps(_logs(num, den), exact).max() <= 2.5
    assert _logs(np.array([3.0]), np.array([3.0]))[0] == 0.0


def test_invalid_arguments_give_nan():
    num = np.array([0.0, 1.0, np.inf, np.nan, 1e-310, 1.0, -1.0, 1.0])
    den = np.array([1.0, 0.0, 1.0, 1.0, 1.0, -1.0, 1.0, np.inf])
    assert np.isnan(_logs(num, den)).all()


def test_coefficients_are_reproducible_and_close_to_taylor():
    np.testing.assert_array_equal(fit_log_polynomial(), LOG_COEFFICIENTS)
    # atanh(z) = z + z^3/3 + z^5/5 + ...: the low-order coefficients are the Taylor ones
    np.testing.assert_allclose(LOG_COEFFICIENTS[:3], [1 / 3, 1 / 5, 1 / 7], rtol=1e-8)
