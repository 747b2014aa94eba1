"""The polynomial atan2 used by the MVC kernel agrees with a long-double reference."""

import numba
import numpy as np

from cagekit.coords.fastangle import (
    ATAN_COEFFICIENTS,
    angle_from_sin_cos,
    fit_atan_polynomial,
    half_angle_over_sin,
)


@numba.njit
def _angles(s, c):
    out = np.empty_like(s)
    for i in range(s.size):
        out[i] = angle_from_sin_cos(s[i], c[i])
    return out


def test_full_precision_over_the_whole_range():
    theta = np.concatenate([np.linspace(0, np.pi, 200_001), np.logspace(-300, 0, 500),
                            np.pi - np.logspace(-16, 0, 500)])
    s, c = np.sin(theta), np.cos(theta)
    exact = np.arctan2(s.astype(np.longdouble), c.astype(np.longdouble))
    rel = np.abs(_angles(s, c) - exact) / np.maximum(np.abs(exact), 1e-300)
    assert rel.max() <= 1e-15


def test_unnormalised_arguments_and_zero():
    rng = np.random.default_rng(0)
    s = np.abs(rng.normal(size=1000)) * 10.0 ** rng.uniform(-5, 5, 1000)
    c = rng.normal(size=1000) * 10.0 ** rng.uniform(-5, 5, 1000)
    np.testing.assert_allclose(_angles(s, c), np.arctan2(s, c), rtol=1e-15, atol=0)
    assert _angles(np.zeros(1), np.zeros(1))[0] == 0.0


def test_coefficients_are_reproducible_and_close_to_taylor():
    np.testing.assert_array_equal(fit_atan_polynomial(), ATAN_COEFFICIENTS)
    # atan(y) = y - y^3/3 + y^5/5 - ...: the low-order coefficients are the Taylor ones
    np.testing.assert_allclose(ATAN_COEFFICIENTS[:3], [1, -1 / 3, 1 / 5], rtol=1e-6)


@numba.njit
def _half_ratios(s, c):
    out = np.empty_like(s)
    for i in range(s.size):
        out[i] = half_angle_over_sin(s[i], c[i])
    return out


def test_half_angle_over_sin():
    theta = np.concatenate([np.linspace(1e-6, np.pi - 1e-6, 100_001), np.logspace(-300, -1, 300),
                            np.pi - np.logspace(-15, -1, 300)])
    s, c = np.sin(theta), np.cos(theta)
    exact = np.arctan2(s.astype(np.longdouble), c.astype(np.longdouble)) / (2 * s)
    got = _half_ratios(s, c)
    assert np.max(np.abs(got - exact) / exact) <= 2e-15
    assert _half_ratios(np.zeros(2), np.array([1.0, -1.0])).tolist() == [0.0, 0.0]
