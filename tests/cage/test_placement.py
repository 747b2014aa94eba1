"""Why a shape lies outside its cage (issue 33, item 3): the units or origin hint of
:func:`cagekit.cage.placement.placement_hint`, and :func:`cagekit.coords.binding.warn_outside`
giving it and refusing above ``refuse_above``."""

import warnings

import numpy as np
import pytest

from cagekit.cage.placement import placement_hint
from cagekit.cage.shapes import box_cage
from cagekit.coords.binding import warn_outside
from cagekit.errors import OutsideCageError, OutsideCageWarning

V, F = box_cage()
#: a shape a little smaller than its cage (as a fitted cage leaves it)
SHAPE = np.random.default_rng(0).uniform(-0.9, 0.9, (500, 3))


@pytest.mark.parametrize("scale, units", [
    (10.0, "(the shape in mm, the cage in cm?)"),
    (100.0, "(the shape in cm, the cage in m?)"),
    (1000.0, "(the shape in mm, the cage in m?)"),
    (2.54, "(the shape in cm, the cage in inches?)"),
    (25.4, "(the shape in mm, the cage in inches?)"),
])
def test_a_unit_ratio_is_named(scale, units):
    hint = placement_hint(SHAPE * scale, V)
    assert hint is not None and hint.endswith(f"different units {units}")
    assert hint.startswith("the shape is ")


def test_a_cage_in_smaller_units_is_named_the_other_way():
    hint = placement_hint(SHAPE, V * 10, shape="m.obj", cage="c.obj")
    assert hint == ("c.obj is 11.2x the size of m.obj: different units (c.obj in mm, m.obj "
                    "in cm?)")


def test_a_ratio_far_from_any_unit_is_a_scale():
    hint = placement_hint(SHAPE * 5.5, V)  # the shape's box is 0.9 of the cage's
    assert hint == ("the shape is 4.93x the size of the cage: a different scale or "
                    "different units?")


def test_an_offset_is_measured_in_cage_diagonals():
    shift = 3 * 2 * 3**0.5  # three cage diagonals along x
    hint = placement_hint(SHAPE + [shift, 0, 0], V)
    assert hint is not None and "offset from the cage by 3" in hint
    assert "a different origin?" in hint


@pytest.mark.parametrize("points", [SHAPE, SHAPE * 1.5, SHAPE + [0.5, 0, 0], np.zeros((1, 3)),
                                    np.zeros((0, 3))])
def test_boxes_that_agree_give_no_hint(points):
    assert placement_hint(points, V) is None


def test_warn_outside_refuses_above_its_limit_with_the_hint():
    with pytest.raises(OutsideCageError, match=r"100% of s.obj .* lies outside c.obj: s.obj "
                                               r"is .*x the size of c.obj: different units"):
        warn_outside(SHAPE * 10, V, F, shape="s.obj", cage="c.obj", refuse_above=0.5)


def test_warn_outside_warns_with_the_hint_when_allowed():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        share = warn_outside(SHAPE + [20.0, 0, 0], V, F)
    assert share == 1.0
    (warning,) = caught
    assert issubclass(warning.category, OutsideCageWarning)
    assert "extrapolated" in str(warning.message)
    assert "a different origin?" in str(warning.message)


def test_a_few_points_outside_warn_as_before_without_a_hint():
    points = np.vstack([SHAPE, [[0.0, 0.0, 1.5]]])  # one point pokes out
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        share = warn_outside(points, V, F, refuse_above=0.5)
    assert 0 < share < 0.01
    assert str(caught[0].message) == ("0.2% of the shape (1 of 501 points) lies outside the "
                                      "cage: extrapolated")
