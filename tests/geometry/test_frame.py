"""Tests of cagekit.geometry.frame: the paper's normalisation and bounding boxes at any scale."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cagekit.errors import InputError
from cagekit.geometry.frame import Frame, check_no_stray_vertex


def test_frame_of_a_shape_and_round_trip():
    rng = np.random.default_rng(3)
    V = rng.normal(size=(200, 3)) * [3.0, 0.5, 1.0] + [10.0, -4.0, 2.0]
    frame = Frame.of(V)
    Vn, center, scale = frame.to_unit(V), frame.centre, frame.scale
    assert (
        center.shape == (3,) and center.dtype == np.float64 and isinstance(scale, float)
    )
    np.testing.assert_allclose(center, (V.min(0) + V.max(0)) / 2)
    assert scale == pytest.approx(np.max(V.max(0) - V.min(0)) / 2)
    assert np.abs(Vn).max() == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(Vn.min(0) + Vn.max(0), 0.0, atol=1e-15)
    longest = np.argmax(V.max(0) - V.min(0))
    assert Vn[:, longest].max() == pytest.approx(1.0, abs=1e-15)
    assert Vn[:, longest].min() == pytest.approx(-1.0, abs=1e-15)
    np.testing.assert_allclose(Frame(center, scale).to_world(Vn), V, rtol=0, atol=1e-13)


def test_frame_rejects_degenerate_input():
    with pytest.raises(InputError, match="zero extent"):
        Frame.of([[1.0, 2.0, 3.0]])
    with pytest.raises(InputError, match="zero extent"):
        Frame.of(np.ones((5, 3)))
    with pytest.raises(InputError, match="no points"):
        Frame.of(np.zeros((0, 3)))
    with pytest.raises(InputError, match="NaN"):
        Frame.of([[0, 0, 0], [np.nan, 1, 1]])
    with pytest.raises(InputError):
        Frame([0, 0, 0], 0.0)
    with pytest.raises(InputError):
        Frame([0, 0], 1.0)


@pytest.mark.parametrize("scale", [1e-290, 1e-150, 1.0, 1e150, 1e300])
def test_bounding_box_is_resolvable_at_any_scale(scale):
    from cagekit.geometry.frame import bounding_box, bounding_box_diagonal

    V = np.array([[0.0, 0, 0], [2.0, 1, 0], [1.0, 0, 1]]) * scale + 3.0 * scale
    center, extent = bounding_box(V)
    np.testing.assert_allclose(center / scale, [4.0, 3.5, 3.5], rtol=1e-15)
    np.testing.assert_allclose(extent / scale, [2.0, 1.0, 1.0], rtol=1e-15)
    assert bounding_box_diagonal(extent) / scale == pytest.approx(np.sqrt(6.0), rel=1e-15)
    assert np.abs(Frame.of(V).to_unit(V)).max() == pytest.approx(1.0)


def test_bounding_box_refuses_what_float64_cannot_resolve():
    from cagekit.geometry.frame import bounding_box

    with pytest.raises(InputError, match="too small to resolve"):
        bounding_box([[0.0, 0, 0], [1e-300, 0, 0]])
    with pytest.raises(InputError, match="overflows"):
        bounding_box([[-1e308, 0, 0], [1e308, 0, 0]])
    with pytest.raises(InputError, match="coincide"):
        bounding_box([[5.0, 5, 5], [5.0, 5, 5]])


def test_a_stray_vertex_is_refused_naming_it():
    V = np.random.default_rng(0).random((200, 3))
    check_no_stray_vertex(V)
    V[17] = [1e38, 0, 0]
    with pytest.raises(InputError, match=r"^the target: vertex 17 lies"):
        check_no_stray_vertex(V, name="the target")


@settings(max_examples=30, deadline=None)
@given(scale=st.floats(1e-200, 1e200), shift=st.floats(-1e3, 1e3), seed=st.integers(0, 99))
def test_the_stray_check_ignores_scale_and_position(scale, shift, seed):
    # a detailed head on a long thin pole (1e4 x its spread) is no stray; 1e7 is
    rng = np.random.default_rng(seed)
    V = rng.normal(size=(300, 3))
    V[0] = [1e4, 0, 0]
    check_no_stray_vertex(V * scale + shift * scale)
    V[0] = [1e7, 0, 0]
    with pytest.raises(InputError, match="vertex 0"):
        check_no_stray_vertex(V * scale + shift * scale)


@pytest.mark.parametrize("far", [1e150, 1e200, 1.7e308])
def test_a_stray_at_any_distance_is_refused(far):
    V = np.random.default_rng(1).random((50, 3))
    V[7] = [far, 0, 0]
    with pytest.raises(InputError, match="vertex 7"):
        check_no_stray_vertex(V)


def test_no_stray_when_most_vertices_coincide():
    V = np.zeros((10, 3))
    V[9] = 1e30
    check_no_stray_vertex(V)  # no typical distance: left to Frame.of and the callers
