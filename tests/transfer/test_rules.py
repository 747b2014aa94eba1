"""Carrying a template cage's motion to a character's cage (cagekit.transfer.rules)."""

import numpy as np
import pytest
from builders import SEEDS, random_rotation
from hypothesis import given, settings

from cagekit.cage.shapes import box_cage
from cagekit.errors import InputError
from cagekit.geometry.alignment import Similarity
from cagekit.transfer.rules import (
    PART_ANGLE,
    SHAPE_NOISE,
    face_gradients,
    has_rotation,
    polar,
    root_weights,
    shape_rotations,
    transfer_cage,
    transfer_offsets,
    transfer_pose,
)


def _limb():
    """A box cage 4 long in x, split into 4 sections: a limb with its root at x = 0."""
    v, f = box_cage()
    v = v * np.array([2.0, 0.5, 0.5]) + np.array([2.0, 0.0, 0.0])
    return v, f


def _rotate_about(V, R, centre):
    return (V - centre) @ R.T + centre


def test_a_rigidly_rotated_limb_gets_the_rotation_not_the_offset():
    # the template's limb swings 30 degrees about its root; the character's limb starts
    # 40 degrees further down: the pose rule puts it where the template's went (pose
    # transfer), the offsets rule pushes it past by the character's own 40 degrees
    v, f = _limb()
    root = np.zeros(3)

    def about_z(degrees):
        a = np.radians(degrees)
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    moved = _rotate_about(v, about_z(30), root)
    character = _rotate_about(v, about_z(-40), root)
    pose = transfer_pose(v, moved, character, f, Similarity.identity())
    # the shape and orientation of the template's moved limb (the translation follows
    # the offsets rule at the root, which the character placed elsewhere)
    np.testing.assert_allclose(pose - pose.mean(0), moved - moved.mean(0), atol=1e-9)
    offsets = transfer_offsets(v, moved, character, Similarity.identity())
    assert np.abs((offsets - offsets.mean(0)) - (moved - moved.mean(0))).max() > 0.5
    # its place: the root, the point the template moves least, is at the limb's root (it
    # turns about x = 0), and there the character's limb stays
    w = root_weights(v, moved, f)
    assert np.linalg.norm(w @ v - root) < 0.3  # the grid's first cells: x = 0.08 on
    assert np.linalg.norm(w @ pose - root) < 0.3


@settings(max_examples=25, deadline=None)
@given(SEEDS)
def test_a_similar_character_moves_as_the_template_does(seed):
    # C_c = A(C_s): the character's cage is the template's mapped by the alignment, so
    # both rules give A(C_st) exactly, whatever C_st
    rng = np.random.default_rng(seed)
    v, f = box_cage()
    A = Similarity(float(rng.uniform(0.2, 5)), random_rotation(seed), rng.normal(size=3))
    moved = v @ random_rotation(seed + 1).T * rng.uniform(0.5, 2) + rng.normal(size=(8, 3)) * 0.1
    for rule in ("pose", "offsets"):
        out = transfer_cage(rule, v, moved, A.apply(v), f, A)
        np.testing.assert_allclose(out, A.apply(moved), atol=1e-8 * A.scale)


@settings(max_examples=25, deadline=None)
@given(SEEDS)
def test_polar_decomposition_reconstructs_with_a_rotation_and_a_symmetric_stretch(seed):
    rng = np.random.default_rng(seed)
    T = rng.normal(size=(6, 3, 3))
    R, S = polar(T)
    np.testing.assert_allclose(R @ S, T, atol=1e-10)
    np.testing.assert_allclose(np.swapaxes(R, 1, 2) @ R, np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-10)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-10)
    np.testing.assert_allclose(S, np.swapaxes(S, 1, 2), atol=1e-10)


def test_face_gradients_of_an_affine_map_are_its_linear_part():
    v, f = box_cage()
    M = np.array([[1.2, 0.3, 0.0], [0.0, 0.8, 0.1], [0.2, 0.0, 1.1]])
    G = face_gradients(v, v @ M.T + 5.0, f)
    # the edges are mapped exactly; the scaled normal is mapped like one
    edges = v[f[:, 1]] - v[f[:, 0]]
    np.testing.assert_allclose(np.einsum("fij,fj->fi", G, edges), edges @ M.T, atol=1e-12)
    np.testing.assert_allclose(face_gradients(v, v + 1.0, f),
                               np.broadcast_to(np.eye(3), G.shape), atol=1e-12)


def test_bad_rule_and_mismatched_cages_are_refused():
    v, f = box_cage()
    with pytest.raises(InputError, match="rule must be one of"):
        transfer_cage("twist", v, v, v, f, Similarity.identity())
    with pytest.raises(InputError, match="same vertex count"):
        transfer_pose(v, v, v[:6], f, Similarity.identity())


def test_the_template_stretch_comes_after_the_characters():
    # a global linear case, so each face's gradient is the map itself: the template's
    # motion R_t S_t (a turn after a stretch along a diagonal) applied after the
    # character's stretch S_c (along x); the other order would differ (S_t, S_c do not
    # commute)
    v, f = box_cage()
    diagonal = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    S_t = np.eye(3) + 0.5 * np.outer(diagonal, diagonal)
    S_c = np.diag([1.8, 1.0, 1.0])
    R_t = random_rotation(7)
    out = transfer_pose(v, v @ (R_t @ S_t).T, v @ S_c.T, f, Similarity.identity())
    expected = v @ (R_t @ S_t @ S_c).T
    np.testing.assert_allclose(out - out.mean(0), expected - expected.mean(0), atol=1e-9)
    wrong = v @ (R_t @ S_c @ S_t).T
    assert np.abs((out - out.mean(0)) - (wrong - wrong.mean(0))).max() > 0.05


def test_the_translation_follows_the_root_of_the_motion():
    # a character that is the template moved by t: whatever the example, both rules give
    # the example moved by t (the root carries the translation)
    v, f = _limb()
    a = np.radians(35)
    turn = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    moved = _rotate_about(v, turn, np.zeros(3)) + np.array([0.0, 0.2, 0.0])
    t = np.array([5.0, -3.0, 1.0])
    for rule in ("pose", "offsets"):
        np.testing.assert_allclose(transfer_cage(rule, v, moved, v + t, f,
                                                 Similarity.identity()), moved + t,
                                   atol=1e-9)


def test_the_root_is_the_pivot_of_a_turn_and_the_centre_of_a_translation():
    # a limb bent about a point a quarter along it is pinned there; twisted about its own
    # axis (every point of the axis still), at its centre; carried along, at its centre
    v, f = _limb()  # 4 long in x, from x = 0
    pivot, centre = np.array([1.0, 0.0, 0.0]), np.array([2.0, 0.0, 0.0])
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    bend = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    w = root_weights(v, _rotate_about(v, bend, pivot), f)
    assert np.linalg.norm(w @ v - pivot) < 0.1
    twist = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    w = root_weights(v, _rotate_about(v, twist, pivot), f)
    assert np.linalg.norm(w @ v - centre) < 0.05
    w = root_weights(v, v + np.array([0.3, -2.0, 1.0]), f)
    assert np.linalg.norm(w @ v - centre) < 0.05
    np.testing.assert_allclose(w.sum(), 1.0, atol=1e-12)


def test_the_root_moves_continuously_when_two_ends_take_turns_standing_still():
    # the left end lifted by t, the right by 1 - t (a walk's feet): the root goes from one
    # end to the other as t grows, without a jump at any step however fine
    v, f = box_cage()
    v = v * np.array([2.0, 0.5, 0.5])  # 4 long in x, centred
    left = v[:, 0] < 0

    def root_x(ts):
        moved = [v + np.outer(np.where(left, t, 1 - t), [0.0, 1.0, 0.0]) for t in ts]
        return np.array([(root_weights(v, m, f) @ v)[0] for m in moved])

    x = root_x([0.0, 1.0])
    assert x[0] < -1.5 and x[-1] > 1.5  # the still end, each time
    # zoom into the steepest step, 20 times finer each time: a continuous root's steps
    # shrink with the step (at the last zoom 0.05 of the one before; a hard choice of the
    # best points, piecewise constant, keeps jumping: 0.77)
    a, b, steepest = 0.0, 1.0, []
    for _ in range(4):
        ts = np.linspace(a, b, 21)
        steps = np.abs(np.diff(root_x(ts)))
        steepest.append(steps.max())
        a, b = ts[steps.argmax()], ts[steps.argmax() + 1]
    assert steepest[-1] < 0.2 * steepest[-2], steepest


def test_root_weights_refuses_what_has_no_root():
    v, f = box_cage()
    with pytest.raises(InputError, match="same vertex count"):
        root_weights(v, v[:-1], f)
    with pytest.raises(InputError, match="no face"):
        root_weights(v, v, f, part=[0, 1, 2])
    with pytest.raises(InputError, match="no extent"):
        root_weights(np.zeros((8, 3)), np.zeros((8, 3)), f)
    with pytest.raises(InputError, match="NaN"):
        root_weights(v, np.where(v > 0.4, np.nan, v), f)


def test_each_cage_component_keeps_its_own_translation():
    v, f = box_cage()
    V = np.vstack([v, v + np.array([4.0, 0, 0])])
    F = np.vstack([f, f + len(v)])
    moved = V.copy()
    moved[len(v):] += np.array([0.0, 1.0, 0.0])  # only the second box moves
    np.testing.assert_allclose(transfer_pose(V, moved, V, F, Similarity.identity()), moved,
                               atol=1e-9)


def test_a_vertex_no_face_uses_is_refused():
    v, f = box_cage()
    V = np.vstack([v, [[9.0, 9, 9]]])
    with pytest.raises(InputError, match="used by no face"):
        transfer_pose(V, V, V, f, Similarity.identity())


def _tapered():
    """A box cage with its faces cut in 4 (faces that tilt when tapered), the part's points
    (its vertices: symmetric about every axis, so the taper does not turn them), and the
    cage tapered: wider at the top."""
    import trimesh

    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0)).subdivide()
    v, f = np.asarray(box.vertices, float), np.asarray(box.faces)
    tapered = v * np.stack([1.0 + 0.8 * v[:, 1], np.ones(len(v)), np.ones(len(v))], 1)
    return v, f, v.copy(), tapered


def test_with_parts_a_character_keeps_its_shape_and_drops_only_its_pose():
    v, f, points, tapered = _tapered()
    still = Similarity.identity()
    # a rest example: with its part the character keeps its tapered shape exactly (the
    # taper turns the side faces; dropping those turns squares the character off)
    out = transfer_pose(v, v, tapered, f, still, parts=[(points, tapered)])
    np.testing.assert_allclose(out - out.mean(0), tapered - tapered.mean(0), rtol=0, atol=1e-7)
    without = transfer_pose(v, v, tapered, f, still)
    assert np.abs((without - without.mean(0)) - (tapered - tapered.mean(0))).max() > 0.05
    # the template turned as a whole: the character's own shape turned the same way
    R = random_rotation(3)
    out = transfer_pose(v, v @ R.T, tapered, f, still, parts=[(points, tapered)])
    expected = tapered @ R.T
    np.testing.assert_allclose(out - out.mean(0), expected - expected.mean(0), rtol=0, atol=1e-7)
    # the character turned 90 degrees at rest is posed otherwise: its turn is replaced as
    # without parts (a T-pose example gives a T-pose)
    turn = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    turned = tapered @ turn.T
    np.testing.assert_allclose(transfer_pose(v, v, turned, f, still, parts=[(points, turned)]),
                               transfer_pose(v, v, turned, f, still), rtol=0, atol=1e-7)


def _angles(R):
    return np.degrees(np.arccos(np.clip((np.trace(R, axis1=1, axis2=2) - 1) / 2, -1, 1)))


def test_shape_rotations_keep_in_proportion_to_the_part_s_turn():
    v, f, points, tapered = _tapered()
    Rc, _ = polar(face_gradients(v, tapered, f))
    kept = shape_rotations(v, tapered, f, [(points, tapered)])
    np.testing.assert_allclose(kept, Rc, rtol=0, atol=1e-9)  # the part is not turned: all kept
    assert _angles(Rc).max() > 5
    full = _angles(Rc)

    def kept_after_turn(degrees):  # about x: the taper's own turns are about z
        a = np.radians(degrees)
        turn = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        turned = tapered @ turn.T
        return shape_rotations(v, turned, f, [(points, turned)])

    # the part's turn is taken out (R_p^T R_c: the taper's own rotations, not turned ones),
    # then its shape kept: half of it at half PART_ANGLE (the blend of a rotation with the
    # identity halfway is the half rotation), more for less of a turn, none beyond
    half, _ = polar(0.5 * np.eye(3) + 0.5 * Rc)
    np.testing.assert_allclose(kept_after_turn(PART_ANGLE / 2), half, atol=1e-6)
    np.testing.assert_allclose(_angles(half), full / 2, atol=1e-4)
    quarter = _angles(kept_after_turn(PART_ANGLE / 4))
    assert np.all(quarter >= full / 2 - 1e-4) and np.all(quarter <= full + 1e-4)
    assert quarter.max() > full.max() / 2 + 1
    np.testing.assert_allclose(_angles(kept_after_turn(1.2 * PART_ANGLE)), 0, atol=1e-4)
    # a faint taper turns faces by less than the fit's noise: nothing is kept
    faint = v + 0.03 * (tapered - v)
    assert 0.5 < _angles(polar(face_gradients(v, faint, f))[0]).max() < SHAPE_NOISE[0]
    np.testing.assert_allclose(_angles(shape_rotations(v, faint, f, [(points, faint)])), 0,
                               atol=1e-4)
    # a taper in the noise band is kept in part: more than none, less than all
    light = v + 0.15 * (tapered - v)
    light_full = _angles(polar(face_gradients(v, light, f))[0])
    band = (light_full > SHAPE_NOISE[0] + 0.5) & (light_full < SHAPE_NOISE[1] - 0.5)
    assert band.sum() >= 4
    light_kept = _angles(shape_rotations(v, light, f, [(points, light)]))
    assert np.all(light_kept[band] > 0.05) and np.all(light_kept[band] < light_full[band] - 0.05)
    np.testing.assert_allclose(shape_rotations(v, tapered, f, []), np.eye(3)[None]
                               .repeat(len(f), 0))
    np.testing.assert_allclose(shape_rotations(v, tapered, f, iter([(points, tapered)])),
                               Rc, rtol=0, atol=1e-9)  # any iterable of pairs


def test_each_face_keeps_the_shape_of_the_part_nearest_it():
    # two parts, the bottom and the top of a tapered box; the character's top is posed
    # otherwise (its points turned 90 degrees): faces near the bottom keep their taper,
    # faces near the top drop it
    import trimesh

    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0)).subdivide().subdivide()
    v, f = np.asarray(box.vertices, float), np.asarray(box.faces)
    tapered = v * np.stack([1.0 + 0.8 * v[:, 1], np.ones(len(v)), np.ones(len(v))], 1)
    bottom, top = v[:, 1] < -0.99, v[:, 1] > 0.99
    turn = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])
    parts = [(v[bottom], tapered[bottom]), (v[top], tapered[top] @ turn.T)]
    kept = _angles(shape_rotations(v, tapered, f, parts))
    full = _angles(polar(face_gradients(v, tapered, f))[0])
    y = v[f, 1].max(axis=1), v[f, 1].min(axis=1)
    low, high = (y[0] <= -0.5) & (full > 1), (y[1] >= 0.5) & (full > 1)
    assert low.sum() >= 8 and high.sum() >= 8
    np.testing.assert_allclose(kept[low], full[low], atol=1e-6)
    np.testing.assert_allclose(kept[high], 0, atol=1e-6)


def test_with_parts_the_template_s_stretch_and_turn_act_on_the_character_s_shape():
    # a global motion L of the template and a character of the template's pose but its own
    # shape (a taper). A turn: the result is the taper turned, exactly. A stretch: per-face
    # gradients are exact only in their faces' planes, so no order is exact; the rule's
    # (G = R_t S_t R_s S_c) misses L(taper) by 0.18, the shape before the stretch
    # (R_t R_s S_t S_c) by 0.225, dropping the shape by 0.68
    v, f, points, tapered = _tapered()
    still = Similarity.identity()

    def miss(L, parts):
        out = transfer_pose(v, v @ L.T, tapered, f, still, parts=parts)
        expected = tapered @ L.T
        return np.abs((out - out.mean(0)) - (expected - expected.mean(0))).max()

    turn = random_rotation(5)
    assert miss(turn, [(points, tapered)]) < 1e-7 and miss(turn, None) > 0.4
    stretch = turn @ np.diag([1.5, 1.0, 1.0])
    assert miss(stretch, [(points, tapered)]) < 0.2 and miss(stretch, None) > 0.6


def test_the_character_s_part_points_are_read_in_its_own_frame():
    # the character's cage and points in a frame turned 30 degrees, scaled and moved from
    # the template's: its parts are not turned, and a rest example gives it back as it is
    v, f, points, tapered = _tapered()
    a = np.radians(30)
    turn = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    frame = Similarity(1.7, turn, np.array([3.0, -1.0, 2.0]))
    character = frame.apply(tapered)
    out = transfer_pose(v, v, character, f, frame, parts=[(points, character)])
    np.testing.assert_allclose(out - out.mean(0), character - character.mean(0), rtol=0,
                               atol=1e-6)


def test_shape_rotations_refuse_parts_without_a_rotation():
    v, f, points, tapered = _tapered()
    part = (points, tapered)
    with pytest.raises(InputError, match=r"parts\[1\]: its 2 template points lie on a line"):
        shape_rotations(v, tapered, f, [part, (points[:2], tapered[:2])])
    line = np.outer(np.linspace(0, 0.5, 5), [1, 1, 0])
    nearly = line + np.array([0.0, 0.0, 0.01]) * np.array([[0], [1], [0], [1], [0]])
    with pytest.raises(InputError, match=r"parts\[0\]: its 5 template points lie on a line"):
        shape_rotations(v, tapered, f, [(nearly, nearly)])
    with pytest.raises(InputError, match=r"parts\[0\]: its 26 character points lie on a"):
        shape_rotations(v, tapered, f, [(points, np.zeros_like(points))])
    assert not has_rotation(nearly) and not has_rotation(points[:2])
    assert has_rotation(points) and has_rotation(tapered)
    with pytest.raises(InputError, match="NaN"):
        shape_rotations(v, tapered, f, [(points, np.where(tapered > 0.9, np.nan, tapered))])
    with pytest.raises(InputError, match="26 template points and 25 character points"):
        shape_rotations(v, tapered, f, [(points, tapered[:-1])])
    with pytest.raises(InputError, match="must be a pair"):
        transfer_pose(v, v, tapered, f, Similarity.identity(), parts=[points])
    with pytest.raises(InputError, match="same vertex count"):
        shape_rotations(v, tapered[:-1], f, [part])
