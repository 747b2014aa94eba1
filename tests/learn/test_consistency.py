"""Cage fitting by MVC consistency (cagekit_learn.consistency)."""

import numpy as np
import pytest

pytest.importorskip("torch")

from builders import random_rotation  # noqa: E402

from cagekit.cage.shapes import icosphere_cage  # noqa: E402
from cagekit.errors import InputError  # noqa: E402
from cagekit.geometry.alignment import Similarity  # noqa: E402
from cagekit_learn.consistency import (  # noqa: E402
    _energy,
    consistency_loss,
    fit_cage_by_consistency,
)


@pytest.fixture(scope="module")
def setup():
    cage_v, cage_f = icosphere_cage(1, radius=1.3)
    rng = np.random.default_rng(0)
    p = rng.normal(size=(40, 3))
    p *= (rng.uniform(0.1, 0.9, size=40) / np.linalg.norm(p, axis=1))[:, None]
    return cage_v, cage_f, p


def test_similarity_copy_gets_the_similarity_of_the_cage_back(setup):
    cage_v, cage_f, p = setup
    A = Similarity(1.7, random_rotation(3), np.array([0.5, -2.0, 3.0]))
    fit = fit_cage_by_consistency(cage_v, cage_f, p, A.apply(p))
    np.testing.assert_allclose(fit.cage_v, A.apply(cage_v), atol=1e-9)
    assert fit.loss < 1e-20 and fit.converged
    assert fit.landmark_errors.max() < 1e-9
    assert fit.alignment.scale == pytest.approx(1.7)


def test_fit_recovers_the_similarity_from_a_perturbed_start(setup):
    cage_v, cage_f, p = setup
    A = Similarity(0.6, random_rotation(5), np.array([1.0, 0.0, -1.0]))
    noise = np.random.default_rng(1).normal(scale=0.05, size=cage_v.shape)
    init = A.apply(cage_v + noise)
    fit = fit_cage_by_consistency(cage_v, cage_f, p, A.apply(p), init=init,
                                  max_evaluations=150)
    assert fit.initial_loss > 1e-2  # the start is really off
    assert fit.converged and fit.loss < 1e-7
    assert fit.landmark_errors.max() < 1e-3 * 0.6
    # the cage comes back to the similarity of C_s, up to what the landmarks pin down
    assert np.abs(fit.cage_v - A.apply(cage_v)).mean() < np.abs(init - A.apply(cage_v)).mean() / 5


def test_translation_found_without_alignment(setup):
    cage_v, cage_f, p = setup
    t = np.array([0.2, -0.1, 0.15])
    fit = fit_cage_by_consistency(cage_v, cage_f, p, p + t, alignment="none",
                                  max_evaluations=150)
    assert fit.initial_loss > 1e-4
    assert fit.converged
    np.testing.assert_allclose(fit.cage_v, cage_v + t, atol=5e-3)


def test_non_similar_character_reduces_the_loss_and_reports_the_residual(setup):
    cage_v, cage_f, p = setup
    q = p * [1.4, 1.0, 0.8]
    q[:, 1] += 0.3 * q[:, 0] ** 2
    fit = fit_cage_by_consistency(cage_v, cage_f, p, q, max_evaluations=150)
    assert fit.loss < 0.5 * fit.initial_loss
    assert not fit.converged and fit.loss > fit.tolerance  # the residual is reported
    again = consistency_loss(cage_v, cage_f, p, fit.cage_v, q)
    # the aligned frame leaves the MVC term unchanged (similarity invariance)
    assert again["mvc_term"] == pytest.approx(fit.mvc_term, rel=1e-8)


def test_gradient_matches_finite_differences(setup):
    cage_v, cage_f, p = setup
    q = p * [1.2, 0.9, 1.0] + 0.05
    energy = _energy(cage_v, cage_f, p, q, 0.05)
    C = cage_v * 1.05
    f0, g = energy(C)
    d = np.random.default_rng(2).normal(size=C.shape)
    h = 1e-6
    fd = (energy.value(C + h * d)[0] - energy.value(C - h * d)[0]) / (2 * h)
    assert fd == pytest.approx(float((g * d).sum()), rel=1e-6)
    assert f0 == pytest.approx(energy.value(C)[0])


def test_consistency_loss_is_zero_for_the_template_itself(setup):
    cage_v, cage_f, p = setup
    assert consistency_loss(cage_v, cage_f, p, cage_v, p)["loss"] < 1e-28


@pytest.mark.parametrize("n, message", [(3, "at least 4"), (0, "no points")])
def test_too_few_landmarks(setup, n, message):
    cage_v, cage_f, p = setup
    with pytest.raises(InputError, match=message):
        fit_cage_by_consistency(cage_v, cage_f, p[:n], p[:n])


def test_bad_arguments(setup):
    cage_v, cage_f, p = setup
    with pytest.raises(InputError, match="one to one"):
        fit_cage_by_consistency(cage_v, cage_f, p, p[:-1])
    with pytest.raises(InputError, match="alignment"):
        fit_cage_by_consistency(cage_v, cage_f, p, p, alignment="boxy")
    bad = p.copy()
    bad[0, 0] = np.nan
    with pytest.raises(InputError):
        fit_cage_by_consistency(cage_v, cage_f, p, bad)
    with pytest.raises(InputError, match="init"):
        fit_cage_by_consistency(cage_v, cage_f, p, p, init=cage_v[:-1])
