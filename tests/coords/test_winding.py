"""The batched winding-number kernel against libigl's, cage by cage."""

import igl
import numpy as np
import pytest
from builders import icosphere
from hypothesis import given, settings
from hypothesis import strategies as st

from cagekit.cage import box_cage
from cagekit.coords.winding import batched_winding_numbers
from cagekit.errors import InputError


def _igl(P, V, F):
    return np.stack([igl.winding_number(np.ascontiguousarray(V[b]), F, np.ascontiguousarray(P[b]))
                     for b in range(len(P))])


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 70), batch=st.integers(1, 3),
       spread=st.sampled_from([0.01, 0.5, 3.0]))
def test_batched_winding_numbers_match_libigl_away_from_the_surface(seed, n, batch, spread):
    rng = np.random.default_rng(seed)
    v, f = icosphere(1)
    # each batch item its own bumpy, stretched cage: non-convex, faces of unequal size
    V = np.stack([v * rng.uniform(0.3, 2.0, 3) * rng.uniform(0.8, 1.2, (len(v), 1))
                  for _ in range(batch)])
    P = rng.normal(scale=spread, size=(batch, n, 3))
    w = batched_winding_numbers(P, V, f)
    ref = _igl(P, V, f)
    assert w.shape == (batch, n)
    assert np.abs(w - ref).max() < 1e-12
    assert np.array_equal(w >= 0.5, ref >= 0.5)


def test_batched_winding_numbers_count_how_often_a_cage_wraps_a_point():
    v, f = box_cage()
    twice = np.concatenate([v, v * 2.0])  # two nested boxes, both outward: 2 inside both
    faces = np.concatenate([f, f + len(v)])
    P = np.array([[[0.0, 0, 0], [1.5, 0, 0], [5, 0, 0]]])
    assert batched_winding_numbers(P, twice[None], faces).round(9).tolist() == [[2.0, 1.0, 0.0]]
    inward = batched_winding_numbers(P, v[None], f[:, ::-1])
    assert inward.round(9).tolist() == [[-1.0, 0.0, 0.0]]


def test_batched_winding_numbers_take_no_points_and_refuse_bad_input():
    v, f = box_cage()
    assert batched_winding_numbers(np.zeros((2, 0, 3)), np.stack([v, v]), f).shape == (2, 0)
    with pytest.raises(InputError, match="cages must have shape"):
        batched_winding_numbers(np.zeros((2, 4, 3)), v[None], f)
    with pytest.raises(InputError, match="indices"):
        batched_winding_numbers(np.zeros((1, 4, 3)), v[None], f + len(v))
    with pytest.raises(InputError, match="finite"):
        batched_winding_numbers(np.full((1, 4, 3), np.nan), v[None], f)
    with pytest.raises(InputError, match="points must have shape"):
        batched_winding_numbers(np.zeros((4, 3)), v[None], f)
