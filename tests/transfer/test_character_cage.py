"""Fitting the template cage to a novel character by landmarks (cagekit.transfer.character_cage)."""

import os
import sys

import numpy as np
import pytest
from builders import REPOSITORY, SEEDS, random_rotation
from hypothesis import given, settings

from cagekit.cage import self_intersecting_faces, unique_edges, winding_numbers
from cagekit.cage.shapes import box_cage
from cagekit.coords import bind
from cagekit.datasets import characters, humanoid, sweethome3d
from cagekit.datasets.humanoid_cage import humanoid_cage
from cagekit.errors import CageFitError, CagekitWarning, InputError
from cagekit.geometry.alignment import Similarity, box_alignment, similarity_alignment
from cagekit.transfer.character_cage import cage_checks, fit_character_cage
from cagekit.transfer.rules import transfer_cage
from cagekit.transfer.surface_binding import MAX_COUPLED, negative_mass


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


def _character(rig, name):
    """A novel character with every other landmark label, and the matching landmark
    arrays (template, character): ``(character, P, Q)``."""
    char = characters.character(name, labels=humanoid.LANDMARK_NAMES[::2])
    marks_c = {m.label: np.array(m.position) for m in char.landmarks}
    shared = [k for k in humanoid.LANDMARK_NAMES[::2] if k in marks_c]
    P = np.array([rig.vertices[rig.landmarks[k]] for k in shared])
    Q = np.array([marks_c[k] for k in shared])
    return char, P, Q


def test_a_character_in_another_rest_pose_gets_a_valid_cage_whose_arms_hang(template):
    rig, (cage_v, cage_f) = template
    char, P, Q = _character(rig, "relaxed")
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


def test_landmarks_that_ask_for_a_fold_are_refused_naming_what_failed():
    # landmarks mirrored through the centre: only a reflected (inside-out) cage fits them;
    # the barrier keeps the cage from folding, so the landmarks are missed, and said so
    v, f = box_cage()
    p = np.random.default_rng(0).uniform(-0.8, 0.8, (12, 3))
    q = p * np.array([-1.0, 1.0, 1.0])
    with pytest.raises(CageFitError, match="no valid character cage.*misses 10% of its "
                                           "landmarks") as error:
        fit_character_cage(v, f, p, q, q, alignment=Similarity.identity(),
                           landmark_weight=1e4, rounds=1)
    rejected_v, rejected_f = error.value.cage
    assert rejected_v.shape == v.shape and np.array_equal(rejected_f, f)
    assert not self_intersecting_faces(rejected_v, rejected_f).any()


def test_a_refusal_names_the_landmarks_missed_and_the_parts_left_outside():
    v, f = box_cage()
    p = np.random.default_rng(0).uniform(-0.8, 0.8, (12, 3))
    q = p * np.array([-1.0, 1.0, 1.0])  # mirrored: only a folded cage reaches them
    labels = [f"mark_{i}" for i in range(len(p))]
    with pytest.raises(CageFitError, match="landmarks missed by over 0.05 diagonals: "
                                           r"mark_\d+ \(0\.\d\d\)") as error:
        fit_character_cage(v, f, p, q, q, alignment=Similarity.identity(),
                           landmark_weight=1e4, rounds=1, labels=labels)
    missed = error.value.missed
    assert missed and set(missed) <= set(labels) and len(missed) < len(labels)
    assert f"{missed[0]} (" in str(error.value)  # the worst first
    assert "the points outside lie nearest mark_" in str(error.value)
    assert sum(error.value.outside_near.values()) == 12  # every point is left outside
    with pytest.raises(InputError, match="labels must name each of the 12 landmarks"):
        fit_character_cage(v, f, p, q, q, alignment=Similarity.identity(), labels=["a"])


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


def test_the_enclosure_rounds_are_what_makes_the_open_boxes_cage_valid():
    # robot_boxes (25 open boxes): the fit needs enclosure rounds; without them it is
    # refused
    rig = humanoid.rig("template")
    cage_v, cage_f = humanoid_cage(rig)
    char = characters.character("robot_boxes")
    marks_c = {m.label: np.array(m.position) for m in char.landmarks}
    shared = [k for k in humanoid.LANDMARK_NAMES if k in marks_c]
    P = np.array([rig.vertices[rig.landmarks[k]] for k in shared])
    Q = np.array([marks_c[k] for k in shared])
    A = box_alignment(rig.vertices, char.vertices)
    fit = fit_character_cage(cage_v, cage_f, P, Q, char.vertices, alignment=A)
    assert fit.checks["valid"] and fit.rounds >= 1
    with pytest.raises(CageFitError, match="outside"):
        fit_character_cage(cage_v, cage_f, P, Q, char.vertices, alignment=A, rounds=0)


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


def test_a_character_whose_hands_hang_by_its_hips_gets_a_valid_cage_and_the_pose(template):
    # arms_down: arms 76 degrees below the T, hands a few centimetres from the hips: the
    # arm tubes squeeze against the torso's without crossing it (the fit without the
    # barrier refused it: 49 crossing faces)
    rig, (cage_v, cage_f) = template
    char, P, Q = _character(rig, "arms_down")
    A = box_alignment(rig.vertices, char.vertices)
    fit = fit_character_cage(cage_v, cage_f, P, Q, char.vertices, alignment=A)
    assert fit.checks["valid"]
    assert not self_intersecting_faces(fit.cage_v, fit.cage_f).any()
    assert winding_numbers(char.vertices, fit.cage_v, fit.cage_f).min() >= 0.5
    W = bind(char.vertices, fit.cage_v, fit.cage_f).weights
    # a pose carried by the pose rule lands near the truth, far nearer than the rest pose
    pose = humanoid.random_pose(7)
    posed_cage = bind(rig.vertices, cage_v, cage_f).weights  # the template's own fit
    C = np.linalg.lstsq(posed_cage, rig.pose(pose), rcond=None)[0]
    out = W @ transfer_cage("pose", cage_v, C, fit.cage_v, fit.cage_f, A)
    truth = char.truth(pose)
    error = np.linalg.norm(out - truth, axis=1).mean()
    assert error < 0.25 * np.linalg.norm(char.vertices - truth, axis=1).mean()
    assert error < 0.05 * np.ptp(char.vertices[:, 1])


def test_a_long_limbed_wide_armed_character_gets_a_valid_cage(template):
    # the tree-like "Ent" of issue 30 (refused with a third of its points outside):
    # arms 1.7x the template's held 35 degrees up, legs 1.3x and apart, thin limbs
    rig, (cage_v, cage_f) = template
    char, P, Q = _character(rig, "long_limbed_wide")
    fit = fit_character_cage(cage_v, cage_f, P, Q, char.vertices,
                             alignment=box_alignment(rig.vertices, char.vertices))
    assert fit.checks["valid"] and fit.checks["volume"] > 0
    assert not self_intersecting_faces(fit.cage_v, fit.cage_f).any()
    assert winding_numbers(char.vertices, fit.cage_v, fit.cage_f).min() >= 0.5
    assert np.quantile(fit.landmark_errors, 0.9) < 0.02 * np.ptp(char.vertices[:, 1])
    # the left hand's cage went up with the arm
    hand = np.argmax(cage_v[:, 0])
    assert fit.cage_v[hand, 1] > fit.cage_v[:, 1].mean() + 0.2 * np.ptp(fit.cage_v[:, 1])


def _on_arm(label):
    return any(part in label for part in ("arm", "hand", "palm", "knuckle", "thumb", "index",
                                          "middle", "ring", "pinky"))


def test_arms_labelled_left_for_right_are_refused_naming_arm_landmarks(template):
    rig, (cage_v, cage_f) = template
    char, P, Q = _character(rig, "long_limbed_wide")
    shared = [k for k in humanoid.LANDMARK_NAMES[::2]
              if k in {m.label for m in char.landmarks}]
    swapped = Q.copy()
    for i, k in enumerate(shared):
        mirror = {"l": "r_", "r": "l_"}.get(k[0], "") + k[2:]
        if _on_arm(k) and mirror in shared:
            swapped[i] = Q[shared.index(mirror)]
    with pytest.raises(CageFitError, match="misses 10% of its landmarks") as error:
        fit_character_cage(cage_v, cage_f, P, swapped, char.vertices, labels=shared,
                           alignment=box_alignment(rig.vertices, char.vertices))
    assert error.value.missed and all(_on_arm(k) for k in error.value.missed[:5])
    assert error.value.missed[0] in str(error.value)


@pytest.mark.slow
@pytest.mark.skipif(not os.path.isfile(os.path.join(sweethome3d.FURNITURE_DIR,
                                                    "KatorLegaz.sh3f")),
                    reason="needs Debian's sweethome3d-furniture")
@pytest.mark.parametrize("name", ["reallusion_male02", "reallusion_girl_standing",
                                  "katorlegaz_male_01_suit"])
def test_real_characters_get_valid_cages_and_are_bound_along_their_surface(name):
    # data/characters/: arms hanging against the body (legs together for two of them);
    # the cage is valid, folds between limbs and body, and the binding is mended there
    # (docs/benchmarks.md, "Real characters")
    from apps.humanoid_data import landmarks_of, template_cage
    from cagekit import io
    from cagekit.io.landmarks import load_landmarks
    from cagekit.transfer import character as dt

    sys.path.insert(0, os.path.join(REPOSITORY, "data"))
    from place_character_landmarks import CHARACTERS

    stem = next(s for _, s, n in CHARACTERS if n == name)
    model = next(m for m in sweethome3d.models()
                 if os.path.splitext(os.path.basename(m.path))[0] == stem)
    V, F = io.load_mesh(model.path)
    marks_c = load_landmarks(REPOSITORY / "data" / "characters" / f"{name}.picked")
    rig = humanoid.rig("template")
    cage_v, cage_f = template_cage(rig)
    marks_t = landmarks_of(rig, humanoid.LANDMARK_NAMES)
    P = np.array([marks_t[k] for k in marks_c if k in marks_t])
    Q = np.array([marks_c[k] for k in marks_c if k in marks_t])
    fit = fit_character_cage(cage_v, cage_f, P, Q, V,
                             alignment=box_alignment(rig.vertices, V))
    assert fit.checks["valid"]
    assert not self_intersecting_faces(fit.cage_v, fit.cage_f).any()
    assert winding_numbers(V, fit.cage_v, fit.cage_f).min() >= 0.5
    with pytest.warns(CagekitWarning, match="where its cage folds between touching parts"):
        char = dt.fit_character(rig.vertices, cage_v, cage_f, marks_t, V, F, marks_c)
    assert 0.01 < char.fit.checks["coupled"] <= MAX_COUPLED
    assert negative_mass(char.binding.weights).max() < 1.0
    np.testing.assert_allclose(char.binding.deform(char.cage_v), V,
                               atol=1e-9 * np.ptp(V[:, 1]))
    # carried into a test pose, the refined mesh keeps under 0.3% of its edges from
    # tearing (stretched over 4x and to over 2% of the height); the cage's own result tears
    # over 1% of them (docs/benchmarks.md: 5-53 per mille)
    from apps.humanoid_data import TEST_POSE_SEED

    pose = rig.pose(humanoid.random_pose(TEST_POSE_SEED + 1))
    C = dt.classical_fitter(rig.vertices, cage_v, cage_f)(pose)
    E = unique_edges(F)
    rest = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)

    def torn(X):
        now = np.linalg.norm(X[E[:, 0]] - X[E[:, 1]], axis=1)
        return np.mean((now > 4 * rest) & (now > 0.02 * np.ptp(V[:, 1])))

    assert torn(dt.transfer(char, C, refine=False)) > 0.01
    assert torn(dt.transfer(char, C)) < 0.003


def test_the_label_helpers_refuse_labels_that_do_not_fit():
    from cagekit.transfer.character_cage import missed_landmarks, nearest_landmarks

    with pytest.raises(InputError, match="name each of the 3 landmarks, got 2"):
        missed_landmarks([0.1, 0.2, 0.3], ["a", "b"])
    with pytest.raises(InputError, match="NaN"):
        missed_landmarks([0.1, np.nan], ["a", "b"])
    with pytest.raises(InputError, match="name each of the 2 landmarks"):
        nearest_landmarks([[0.0, 0, 0]], [[0.0, 0, 0], [1, 0, 0]], "ab")
    with pytest.raises(InputError, match="NaN"):
        nearest_landmarks([[np.nan, 0, 0]], [[0.0, 0, 0], [1, 0, 0]], ["a", "b"])
