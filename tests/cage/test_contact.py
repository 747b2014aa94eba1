"""A cage that cannot pass through itself (cagekit.cage.contact)."""

import numpy as np
import pytest
from builders import SEEDS
from hypothesis import given, settings

from cagekit.cage import self_intersecting_faces
from cagekit.cage.contact import SelfContact, minimise_with_contact
from cagekit.cage.shapes import box_cage


def test_the_gradient_is_that_of_the_energy_in_vertex_order():
    v, f = box_cage()
    contact = SelfContact(v, f, dhat=0.2)
    C = v * [1.0, 1.0, 0.06] + np.random.default_rng(0).normal(0, 0.005, v.shape)
    assert contact.energy(C) > 0
    g, H = contact.gradient_and_hessian(C)
    h = 1e-7
    numeric = np.zeros_like(C)
    for i in range(C.shape[0]):
        for j in range(3):
            d = np.zeros_like(C)
            d[i, j] = h
            numeric[i, j] = (contact.energy(C + d) - contact.energy(C - d)) / (2 * h)
    np.testing.assert_allclose(g, numeric, rtol=1e-4, atol=1e-6 * np.abs(numeric).max())
    assert H.shape == (24, 24)
    assert np.linalg.eigvalsh(H.toarray()).min() > -1e-9 * abs(H).max()  # projected PSD


def test_a_step_through_the_cage_is_cut_short_even_when_its_end_is_clean():
    # the top face moved down through the bottom and beyond: both ends are free of
    # intersection, the path is not
    v, f = box_cage()
    contact = SelfContact(v, f, dhat=0.01)
    through = v.copy()
    through[v[:, 2] > 0, 2] -= 4.0
    assert not self_intersecting_faces(through, f).any()
    assert contact.max_step(v, through) < 0.5
    assert contact.max_step(v, v * 1.5) == 1.0


def test_clearance_is_the_closest_approach_of_elements_that_share_nothing():
    v, f = box_cage()
    contact = SelfContact(v, f)
    assert contact.clearance(v * [1.0, 1.0, 0.001]) == pytest.approx(0.002, rel=1e-5)
    assert contact.clearance(v) > 1.0


@settings(max_examples=15, deadline=None)
@given(SEEDS)
def test_a_pull_that_would_fold_the_cage_never_makes_it_cross(seed):
    # each vertex pulled to a random point (a box turned inside out, crumpled): the
    # barrier gives way to none of it
    rng = np.random.default_rng(seed)
    v, f = box_cage()
    goal = rng.uniform(-1.0, 1.0, v.shape) * rng.choice([-1.0, 1.0], size=(1, 3))
    contact = SelfContact(v, f, dhat=0.05)
    C = minimise_with_contact(np.eye(len(v)), goal, float((goal ** 2).sum()), v, contact,
                              stiffness=1.0, iterations=25)
    assert np.isfinite(C).all()
    assert not self_intersecting_faces(C, f).any()
    assert contact.clearance(C) > 0
    # and it did move towards the pull
    assert np.linalg.norm(C - goal) < np.linalg.norm(v - goal)


def test_an_unconstrained_pull_is_reached_in_one_newton_step():
    v, f = box_cage()
    contact = SelfContact(v, f, dhat=0.01)
    goal = 1.3 * v + 0.2  # far from any contact: the barrier is zero all along
    C = minimise_with_contact(np.eye(8), goal, float((goal ** 2).sum()), v, contact,
                              iterations=1)
    np.testing.assert_allclose(C, goal, atol=1e-12)


def test_dhat_must_be_positive():
    v, f = box_cage()
    with pytest.raises(ValueError, match="dhat"):
        SelfContact(v, f, dhat=0.0)
