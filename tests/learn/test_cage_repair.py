"""A predicted cage is judged before use: kept, grown to enclose, or refused (issue 32)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cagekit.cage import self_intersecting_faces, winding_numbers
from cagekit.cage.shapes import box_cage
from cagekit_learn.cage_repair import GROWTH_STEP, MAX_GROWTH, check_predicted_cage


def _inside(points, cage_v, cage_f):
    return winding_numbers(points, cage_v, cage_f) >= 0.5 - 1e-9


def test_a_valid_cage_is_kept_as_it_is():
    v, f = box_cage()
    points = np.random.default_rng(0).uniform(-0.9, 0.9, (200, 3))
    checked = check_predicted_cage(points, v, 2 * v, f)
    assert checked.valid and checked.growth == 1.0
    assert checked.outside_share == 0 and checked.crossing_faces == 0
    assert np.array_equal(checked.cage_v, v) and np.array_equal(checked.deformed_v, 2 * v)


def test_a_cage_that_leaves_points_out_is_grown_just_enough_to_take_them_in():
    v, f = box_cage()
    points = np.random.default_rng(1).uniform(-0.9, 0.9, (200, 3))
    points[:5, 0] = 1.1  # a leg tip out of the predicted cage
    checked = check_predicted_cage(points, v, v, f)
    assert checked.valid and checked.outside_share == pytest.approx(5 / 200)
    assert 1.0 < checked.growth <= MAX_GROWTH
    assert _inside(points, checked.cage_v, f).all()
    # the least growth to the bisection's step: a little less leaves a point out
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    smaller = centre + (checked.growth - 2 * GROWTH_STEP) * (v - centre)
    assert not _inside(points, smaller, f).all()


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-1.5, 1.5), min_size=12, max_size=12),
       st.floats(1.01, 1.2))
def test_growing_keeps_an_affine_predicted_motion_exactly(coefficients, reach):
    v, f = box_cage()
    A = np.eye(3) + 0.3 * np.reshape(coefficients[:9], (3, 3))
    b = np.asarray(coefficients[9:])
    points = np.vstack([np.random.default_rng(2).uniform(-0.8, 0.8, (50, 3)),
                        [[reach, 0.0, 0.0]]])
    checked = check_predicted_cage(points, v, v @ A.T + b, f)
    assert checked.valid and checked.growth > 1
    assert np.allclose(checked.deformed_v, checked.cage_v @ A.T + b, atol=1e-9)


def test_a_cage_that_intersects_itself_is_refused_not_grown():
    v, f = box_cage()
    folded = v.copy()
    folded[0] = -2.0 * v[0]  # a corner pushed through the opposite side
    assert self_intersecting_faces(folded, f).any()
    checked = check_predicted_cage(np.zeros((1, 3)), folded, folded, f)
    assert not checked.valid and checked.crossing_faces > 0
    assert "intersects itself" in checked.problem and checked.growth == 1.0


def test_a_cage_too_small_for_its_points_is_refused():
    v, f = box_cage()
    points = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
    checked = check_predicted_cage(points, v, v, f)
    assert not checked.valid and checked.outside_share == 0.5
    assert "outside" in checked.problem and f"{MAX_GROWTH:g}x" in checked.problem


def test_max_growth_below_one_is_refused():
    v, f = box_cage()
    with pytest.raises(ValueError, match="at least 1"):
        check_predicted_cage(np.zeros((1, 3)), v, v, f, max_growth=0.5)
