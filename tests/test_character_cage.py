"""Fitting the template cage to a novel character by landmarks (cagekit.character_cage)."""

import numpy as np
import pytest
from builders import SEEDS, random_rotation
from hypothesis import given, settings

from cagekit.alignment import Similarity, box_alignment, similarity_alignment
from cagekit.cage import self_intersecting_faces, winding_numbers
from cagekit.character_cage import cage_checks, fit_character_cage
from cagekit.datasets import characters, humanoid
from cagekit.datasets.humanoid_cage import humanoid_cage
from cagekit.errors import CageFitError, InputError
from cagekit.shapes import box_cage


@settings(max_examples=20, deadline=None)
@given(SEEDS)
def test_a_similar_copy_gets_the_similar_cage(seed):
    rng = np.random.default_rng(seed)
    v, f = box_cage()
    p = rng.uniform(-0.8, 0.8, (10, 3))
    A = Similarity(float(rng.uniform(0.1, 10)), random_rotation(seed), rng.normal(size=3))
    q = A.apply(p)
    fit = fit_character_cage(v, f, p, q, q, alignment=similarity_alignment(p, q))
    np.testing.assert_allclose(fit.cage_v, A.apply(v), atol=1e-7 * A.scale)
    assert fit.checks["valid"] and fit.landmark_errors.max() < 1e-7 * A.scale
    assert fit.consistency < 1e-12


@pytest.fixture(scope="module")
def template():
    rig = humanoid.rig("template", resolution=0.5)
    return rig, humanoid_cage(rig)


def _marks(rig, vertices=None):
    V = rig.vertices if vertices is None else vertices
    return {name: V[rig.landmarks[name]] for name in humanoid.LANDMARK_NAMES[::2]}


def test_a_character_in_another_rest_pose_gets_a_valid_cage_whose_arms_hang(template):
    rig, (cage_v, cage_f) = template
    char = characters.character("relaxed", labels=humanoid.LANDMARK_NAMES[::2])
    marks_c = {m.label: np.array(m.position) for m in char.landmarks}
    marks_t = _marks(rig)
    shared = [k for k in marks_t if k in marks_c]
    P = np.array([marks_t[k] for k in shared])
    Q = np.array([marks_c[k] for k in shared])
    fit = fit_character_cage(cage_v, cage_f, P, Q, char.vertices,
                             alignment=box_alignment(rig.vertices, char.vertices))
    assert fit.checks["valid"] and fit.checks["self_intersecting_faces"] == 0
    assert winding_numbers(char.vertices, fit.cage_v, fit.cage_f).min() >= 0.5
    assert not self_intersecting_faces(fit.cage_v, fit.cage_f).any()
    # the landmarks are reproduced to within a few percent of the height
    assert np.median(fit.landmark_errors) < 0.02 * np.ptp(char.vertices[:, 1])
    # the left hand's cage went down with the arm (60 degrees below the T)
    hand = np.argmax(cage_v[:, 0])
    assert fit.cage_v[hand, 1] < cage_v[hand, 1] - 0.3
    assert fit.consistency < fit.initial_consistency


def test_a_cage_that_must_fold_is_refused_naming_what_failed():
    # landmarks mirrored through the centre: only a reflected (inside-out) cage fits them
    v, f = box_cage()
    p = np.random.default_rng(0).uniform(-0.8, 0.8, (12, 3))
    q = p * np.array([-1.0, 1.0, 1.0])
    with pytest.raises(CageFitError, match="no valid character cage") as error:
        fit_character_cage(v, f, p, q, q, alignment=Similarity.identity(),
                           landmark_weight=1e4, repair_rounds=1)
    rejected_v, rejected_f = error.value.cage
    assert rejected_v.shape == v.shape and np.array_equal(rejected_f, f)


def test_cage_checks_see_each_problem():
    v, f = box_cage()
    assert cage_checks(np.zeros((3, 3)), v, f)["valid"]
    folded = v.copy()
    folded[0] = [1.5, 1.5, 1.5]  # a corner pushed through the opposite corner
    checks = cage_checks(np.zeros((1, 3)), folded, f)
    assert checks["self_intersecting_faces"] > 0 and not checks["valid"]
    inverted = cage_checks(np.zeros((1, 3)), v, f[:, ::-1])
    assert inverted["volume"] < 0 and any("inverted" in p for p in inverted["problems"])
    outside = cage_checks(np.array([[0.0, 0, 0], [3.0, 0, 0]]), v, f)
    assert outside["outside"] == 0.5 and outside["min_winding"] < 0.5


@pytest.mark.parametrize("kwargs, message", [
    ({"source_landmarks": np.zeros((3, 3)), "target_landmarks": np.zeros((3, 3))},
     "at least 4"),
    ({"target_landmarks": np.zeros((5, 3))}, "one to one"),
    ({"margin": 0.0}, "margin must be a positive number"),
    ({"landmark_weight": np.nan}, "landmark_weight must be a positive number"),
])
def test_bad_arguments(kwargs, message):
    v, f = box_cage()
    p = np.random.default_rng(1).uniform(-0.5, 0.5, (6, 3))
    args = {"cage_v": v, "cage_f": f, "source_landmarks": p, "target_landmarks": p,
            "character_v": p, "alignment": Similarity.identity(), **kwargs}
    with pytest.raises(InputError, match=message):
        fit_character_cage(**args)


def test_limbs_may_thicken_as_similar_as_possible():
    # no alignment: the character is the template 1.3 times larger about its centre; a
    # rigid (ARAP) fit could not grow the cage, a scale per vertex does
    v, f = box_cage()
    p = np.random.default_rng(4).uniform(-0.7, 0.7, (12, 3))
    fit = fit_character_cage(v, f, p, 1.3 * p, 1.3 * p, alignment=Similarity.identity(),
                             iterations=300)
    assert np.median(fit.landmark_errors) < 2e-3
    np.testing.assert_allclose(fit.cage_v, 1.3 * v, atol=0.02)


def test_the_repair_rounds_are_what_makes_the_open_boxes_cage_valid():
    # robot_boxes (25 open boxes): the fit needs repair rounds; without them it is refused
    rig = humanoid.rig("template")
    cage_v, cage_f = humanoid_cage(rig)
    char = characters.character("robot_boxes")
    marks_c = {m.label: np.array(m.position) for m in char.landmarks}
    shared = [k for k in humanoid.LANDMARK_NAMES if k in marks_c]
    P = np.array([rig.vertices[rig.landmarks[k]] for k in shared])
    Q = np.array([marks_c[k] for k in shared])
    A = box_alignment(rig.vertices, char.vertices)
    fit = fit_character_cage(cage_v, cage_f, P, Q, char.vertices, alignment=A)
    assert fit.checks["valid"] and fit.repairs >= 1
    with pytest.raises(CageFitError):
        fit_character_cage(cage_v, cage_f, P, Q, char.vertices, alignment=A,
                           repair_rounds=0)


def test_landmarks_on_one_line_and_unused_cage_vertices_are_refused():
    v, f = box_cage()
    line = np.outer(np.linspace(-0.5, 0.5, 6), [1.0, 0.5, 0.2])
    with pytest.raises(InputError, match="one line"):
        fit_character_cage(v, f, np.random.default_rng(0).uniform(-0.5, 0.5, (6, 3)), line,
                           line, alignment=Similarity.identity())
    p = np.random.default_rng(1).uniform(-0.5, 0.5, (6, 3))
    with pytest.raises(InputError, match="used by no face"):
        fit_character_cage(np.vstack([v, [[5.0, 5, 5]]]), f, p, p, p,
                           alignment=Similarity.identity())
