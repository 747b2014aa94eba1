"""The winding numbers :func:`cagekit.coords.mvc.mvc_and_winding` computes beside the
weights: libigl's off the cage, 0.5 on it, 0 far out; the weights unchanged; and their use
by ``bind(..., winding=True)`` and ``warn_outside``."""

import warnings

import igl
import numpy as np
import pytest
from builders import CAGES, diag, star_cage
from hypothesis import given, settings
from hypothesis import strategies as st

from cagekit import InputError
from cagekit.coords import bind, mean_value_coordinates
from cagekit.coords.binding import warn_outside
from cagekit.coords.mvc import mvc_and_winding


def _off_cage(v, f, p, margin=1e-6):
    """The points of ``p`` at least ``margin`` cage diagonals from the cage."""
    dist = np.sqrt(igl.point_mesh_squared_distance(p, v, f)[0])
    return p[dist >= margin * diag(v)]


@pytest.mark.parametrize("name", sorted(CAGES))
def test_winding_is_libigls_off_the_cage_and_the_weights_are_unchanged(name):
    v, f = CAGES[name]
    rng = np.random.default_rng(3)
    lo, hi = v.min(axis=0), v.max(axis=0)
    p = _off_cage(v, f, rng.uniform(lo - 0.3 * (hi - lo), hi + 0.3 * (hi - lo), (3000, 3)))
    weights, winding = mvc_and_winding(p, v, f)
    assert np.array_equal(weights, mean_value_coordinates(p, v, f))
    np.testing.assert_allclose(winding, igl.winding_number(v, f, p), atol=1e-9)
    assert 0 < (winding > 0.5).sum() < len(p)  # both sides were tested


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), spread=st.floats(0.0, 0.6))
def test_winding_property_on_star_cages(seed, spread):
    v, f = star_cage(seed, spread=spread)
    rng = np.random.default_rng(seed)
    p = _off_cage(v, f, rng.uniform(-1.6, 1.6, (400, 3)))
    winding = mvc_and_winding(p, v, f).winding
    np.testing.assert_allclose(winding, igl.winding_number(v, f, p), atol=1e-9)


def test_winding_is_one_half_on_the_cage_and_zero_far_away():
    v, f = CAGES["star"]
    on = np.vstack([v[:5], v[f[:5]].mean(axis=1), v[f[:5, :2]].mean(axis=1)])
    far = np.array([[50.0, 0, 0], [1e9, -3e9, 2e9]]) * diag(v)
    winding = mvc_and_winding(np.vstack([on, far]), v, f).winding
    assert winding.tolist() == [0.5] * len(on) + [0.0, 0.0]


@pytest.mark.parametrize("method", ["mvc", "green"])
def test_bind_keeps_the_winding_numbers_when_asked(method):
    v, f = CAGES["star"]
    p = np.random.default_rng(4).uniform(-1.2, 1.2, (500, 3))
    plain = bind(p, v, f, method=method)
    kept = bind(p, v, f, method=method, winding=True)
    assert plain.winding is None
    np.testing.assert_allclose(kept.winding, igl.winding_number(v, f, p), atol=1e-9)
    np.testing.assert_allclose(kept.deform(2 * v), plain.deform(2 * v), atol=1e-12)


def test_warn_outside_with_known_winding_numbers_warns_as_without():
    v, f = CAGES["star"]
    p = np.random.default_rng(5).uniform(-1.2, 1.2, (500, 3))
    messages = []
    for winding in (None, bind(p, v, f, winding=True).winding):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            share = warn_outside(p, v, f, winding=winding)
        messages.append((share, [str(w.message) for w in caught]))
    assert messages[0] == messages[1] and messages[0][0] > 0
    with pytest.raises(InputError, match="winding numbers of shape"):
        warn_outside(p, v, f, winding=np.zeros(3))


def test_green_on_the_cage_counts_as_inside():
    v, f = CAGES["star"]
    on = np.vstack([v[:5], v[f[:5]].mean(axis=1)])
    winding = bind(on, v, f, method="green", winding=True).winding
    assert np.all(winding > 0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert warn_outside(on, v, f, winding=winding) == 0.0
