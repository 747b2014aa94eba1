"""A mesh bound to a cage that folds between touching parts (cagekit.transfer.surface_binding)."""

import numpy as np
import pytest
from builders import random_rotation

from cagekit.cage import check_cage
from cagekit.cage.shapes import box_cage
from cagekit.coords import bind
from cagekit.errors import CageFitError, CagekitWarning, InputError
from cagekit.transfer.surface_binding import (
    FREE_MASS,
    MAX_COUPLED,
    SurfaceBinding,
    bind_surface,
    check_coupling,
    coupled_share,
    negative_mass,
)


def _slot_cage(gap):
    """A U: a box with a slot ``gap`` wide cut from its top (z = 1) down to z = 0, the slot
    between the planes x = -gap/2 and x = gap/2 (closed, outward, extruded along y)."""
    g = gap / 2
    ring = [(-1, -1), (1, -1), (1, 1), (g, 1), (g, 0), (-g, 0), (-g, 1), (-1, 1)]
    V = np.array([(a, y, c) for y in (-1.0, 1.0) for a, c in ring])
    cap = np.array([(0, 1, 4), (0, 4, 5), (1, 2, 3), (1, 3, 4), (0, 5, 6), (0, 6, 7)])
    sides = [(i, i + 8, (i + 1) % 8 + 8, (i + 1) % 8) for i in range(8)]
    F = np.vstack([cap, cap[:, ::-1] + 8] + [[(a, b, c), (a, c, d)] for a, b, c, d in sides])
    return V, check_cage(V, F)


def _sheet(gap, nx=12, nz=10):
    """A flat grid mesh inside the slot cage's left prong, from its outer wall to 0.01
    from the slot (the "limb" that touches the "body" across the slot)."""
    x = np.linspace(-0.95, -gap / 2 - 0.01, nx)
    z = np.linspace(0.1, 0.9, nz)
    X, Z = np.meshgrid(x, z, indexing="ij")
    V = np.column_stack([X.ravel(), np.zeros(X.size), Z.ravel()])
    idx = np.arange(X.size).reshape(nx, nz)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return V, np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])


def _prong_moved(V, shift):
    moved = V.copy()
    moved[(V[:, 0] < 0) & (V[:, 2] > 0.5), 0] -= shift
    return moved


def test_a_thin_slot_binds_one_wall_through_the_other():
    # points in the left prong, 0.05 from the slot; the prong moved out by 0.5: with a
    # slot 0.02 wide they overshoot it (negative mass above 1), with a wide one they don't
    for gap, coupled in ((1.0, False), (0.02, True)):
        V, F = _slot_cage(gap)
        points = np.array([[-gap / 2 - 0.05, 0.0, z] for z in np.linspace(0.1, 0.8, 8)])
        W = bind(points, V, F).weights
        shift = np.abs((W @ _prong_moved(V, 0.5) - points)[:, 0])
        if coupled:
            assert coupled_share(W) > 0.5 and shift.max() > 0.5 + 1e-3
        else:
            assert coupled_share(W) == 0.0 and shift.max() <= 0.5


def test_the_mended_binding_overshoots_the_limb_less():
    cage_v, cage_f = _slot_cage(0.02)
    V, F = _sheet(0.02)
    mvc = bind(V, cage_v, cage_f).weights
    b = bind_surface(V, F, cage_v, cage_f)
    assert b.mended.any() and not b.mended.all()
    assert b.coupled == coupled_share(mvc) > 0
    moved = _prong_moved(cage_v, 0.5)
    shift_mvc = np.abs((mvc @ moved - V)[:, 0])
    shift = np.abs((b.deform(moved, refine=False) - V)[:, 0])
    # the sheet's edge by the slot flies past the prong (moved by 0.5); mended, it lags
    # within the range of the points left alone, less far past
    assert shift_mvc.max() > 0.7
    assert shift.max() < shift_mvc.max() - 0.08
    assert shift[b.mended].max() - 0.5 < 0.6 * (shift_mvc[b.mended].max() - 0.5)
    # points far from the slot keep their mean value coordinates exactly
    np.testing.assert_array_equal(b.weights[~b.mended], mvc[~b.mended])
    assert (negative_mass(mvc)[~b.mended] <= FREE_MASS).all()
    np.testing.assert_allclose(b.weights.sum(axis=1), 1.0, atol=1e-12)


def test_the_refined_deformation_stretches_the_sheet_less():
    # the prong's top moves out by 0.5 and drags half the sheet; the cage's result
    # stretches and squeezes its edges (0.13x to 1.9x), the refinement keeps them near
    # their length
    cage_v, cage_f = _slot_cage(0.02)
    V, F = _sheet(0.02)
    b = bind_surface(V, F, cage_v, cage_f)
    moved = _prong_moved(cage_v, 0.5)
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])

    def stretch(X):
        return (np.linalg.norm(X[E[:, 0]] - X[E[:, 1]], axis=1)
                / np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1))

    raw, refined = stretch(b.deform(moved, refine=False)), stretch(b.deform(moved))
    assert raw.min() < 0.2 and raw.max() > 1.8
    assert refined.min() > 0.5 and refined.max() < 1.4


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rest_and_similar_cages_give_the_mesh_back_and_moved_alike(seed):
    cage_v, cage_f = _slot_cage(0.02)
    V, F = _sheet(0.02)
    b = bind_surface(V, F, cage_v, cage_f)
    R = random_rotation(seed)
    t = np.random.default_rng(seed).normal(size=3)
    for refine in (False, True):
        np.testing.assert_allclose(b.deform(cage_v, refine=refine), V, atol=1e-9)
        np.testing.assert_allclose(b.deform(2.5 * cage_v @ R.T + t, refine=refine),
                                   2.5 * V @ R.T + t, atol=1e-8)


@pytest.mark.parametrize("seed", [0, 1])
def test_green_binding_reproduces_is_similarity_exact_and_green_where_not_mended(seed):
    cage_v, cage_f = _slot_cage(0.02)
    V, F = _sheet(0.02)
    b = bind_surface(V, F, cage_v, cage_f, coords="green")
    mvc = bind_surface(V, F, cage_v, cage_f)
    assert b.green is not None and b.green.n_points == int((~b.mended).sum())
    np.testing.assert_array_equal(b.mended, mvc.mended)  # the mending is MVC's either way
    R = random_rotation(seed)
    for refine in (False, True):
        np.testing.assert_allclose(b.deform(cage_v, refine=refine), V, atol=1e-9)
        np.testing.assert_allclose(b.deform(2.5 * cage_v @ R.T + 1.0, refine=refine),
                                   2.5 * V @ R.T + 1.0, atol=1e-8)
    # a stretch: the free points follow Green coordinates (not the affine map MVC gives),
    # the mended ones the same MVC blend as before, their detail turned with their ring
    stretched = cage_v * [2.0, 1.0, 0.5]
    out = b.deform(stretched, refine=False)
    green = bind(V[~b.mended], cage_v, cage_f, method="green").deform(stretched)
    np.testing.assert_allclose(out[~b.mended], green, atol=1e-12)
    assert np.abs(green - mvc.deform(stretched, refine=False)[~b.mended]).max() > 1e-3
    detail = out[b.mended] - (mvc.weights @ stretched)[b.mended]
    scale = np.sqrt(((stretched - stretched.mean(0)) ** 2).sum(1).mean()
                    / ((cage_v - cage_v.mean(0)) ** 2).sum(1).mean())
    np.testing.assert_allclose(np.linalg.norm(detail, axis=1),
                               scale * np.linalg.norm(mvc.offsets[b.mended], axis=1),
                               atol=1e-12)


def test_unknown_coordinates_are_refused():
    cage_v, cage_f = box_cage()
    with pytest.raises(InputError, match="unknown coordinates 'harmonic'"):
        bind_surface(np.zeros((1, 3)), np.zeros((0, 3), int), cage_v, cage_f,
                     coords="harmonic")


def test_a_point_cloud_or_an_open_cage_keeps_its_mean_value_coordinates():
    cage_v, cage_f = box_cage()
    points = np.random.default_rng(3).uniform(-0.8, 0.8, (20, 3))
    b = bind_surface(points, np.zeros((0, 3), int), cage_v, cage_f)
    assert not b.mended.any() and b.coupled == 0.0
    np.testing.assert_array_equal(b.weights, bind(points, cage_v, cage_f).weights)
    np.testing.assert_allclose(b.deform(cage_v * [2.0, 1.0, 0.5]), points * [2.0, 1.0, 0.5],
                               atol=1e-12)


def _binding(coupled):
    return SurfaceBinding(weights=np.eye(2), offsets=np.zeros((2, 3)),
                          mended=np.zeros(2, bool), coupled=coupled,
                          edges=np.zeros((0, 2), int), rest_base=np.zeros((2, 3)),
                          rest_cage=np.eye(2, 3), rest_vertices=np.zeros((2, 3)),
                          faces=np.zeros((0, 3), int))


def test_check_coupling_is_silent_warns_or_refuses_by_the_share():
    assert check_coupling(_binding(0.0)) == 0.0
    with pytest.warns(CagekitWarning, match="5.0% of the character's vertices"):
        check_coupling(_binding(0.05))
    with pytest.raises(CageFitError, match="folds so thinly between touching parts"):
        check_coupling(_binding(MAX_COUPLED + 0.01))


def test_the_warning_names_one_quantity_by_one_word_and_states_its_limit():
    # issue 33: the share bound through folds (refused above MAX_COUPLED) was called
    # "bound along the mesh", the words of the other share (mended)
    with pytest.warns(CagekitWarning) as caught:
        check_coupling(_binding(0.082))
    message = str(caught[0].message)
    assert "8.2% of the character's vertices are bound through folds" in message
    assert f"refused above {100 * MAX_COUPLED:.0f}%" in message
    assert "bound along" not in message and "mended along the mesh" in message
