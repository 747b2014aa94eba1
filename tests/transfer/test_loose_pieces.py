"""Loose pieces of a character's mesh follow what they touch (cagekit.transfer.loose_pieces)."""

import numpy as np
import pytest
import trimesh

from cagekit.errors import InputError
from cagekit.transfer import loose_pieces as lp
from cagekit.transfer.loose_pieces import find_loose_pieces


def _box(centre):
    """A unit box cut in 16 squares a side: 98 vertices."""
    box = trimesh.creation.box().subdivide().subdivide()
    return np.asarray(box.vertices) + centre, np.asarray(box.faces)


def _mesh(*pieces):
    """Pieces (V, F) joined into one mesh, and each piece's vertex indices."""
    V, F, index, start = [], [], [], 0
    for v, f in pieces:
        V.append(v)
        F.append(f + start)
        index.append(np.arange(start, start + len(v)))
        start += len(v)
    return np.vstack(V), np.vstack(F), index


def _triangle(corner):
    """A triangle 0.001 off three vertices of a box face at x = corner[0] - 0.001."""
    return (np.array([[0.0, 0.0, 0.0], [0.0, 0.25, 0.0], [0.0, 0.0, 0.25]]) + corner,
            np.array([[0, 1, 2]]))


def test_a_loose_piece_follows_the_well_bound_piece_it_touched():
    V, F, (box, tri) = _mesh(_box([0, 0, 0]), _triangle([0.501, 0, 0]))
    mended = np.isin(np.arange(len(V)), tri)
    loose = find_loose_pieces(V, F, mended)
    assert [p.tolist() for p in loose.pieces] == [tri.tolist()]
    # the cage turns the box a little and lifts it; it leaves the triangle behind, turned
    a = np.radians(10)
    turn = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    moved = V.copy()
    moved[box] = V[box] @ turn.T + [0.0, 3.0, 0.0]
    moved[tri] = V[tri] @ turn.T
    out = loose.reattach(V, moved)
    np.testing.assert_array_equal(out[box], moved[box])
    # translated (the cage's turn of it kept) back against the box: the touched vertices'
    # rest offsets restored in the median
    shift = out[tri] - moved[tri]
    np.testing.assert_allclose(shift, shift[[0]].repeat(3, 0), atol=1e-12)
    gaps = np.linalg.norm(out[tri] - out[loose.touched[0]], axis=1)
    assert np.median(gaps) < 0.01 < np.median(np.linalg.norm(moved[tri] - moved[loose.touched[0]],
                                                            axis=1))


def test_a_hand_on_the_hip_follows_the_wrist_not_the_hip():
    # the hand touches the hip (pelvis) and the wrist (forearm) at rest; the arm rises, the
    # cage leaves the hand at the hip: with the parts it follows the wrist alone
    hip, wrist = _box([0, 0, 0]), _box([0, 1.25, 0])
    hand = (np.array([[0.501, 0.25, 0.0], [0.501, 0.5, 0.0], [0.501, 0.25, 0.25],
                      [0.501, 0.75, 0.0], [0.501, 1.0, 0.0], [0.501, 0.75, 0.25]]),
            np.array([[0, 1, 2], [1, 3, 4], [3, 4, 5]]))
    V, F, (hip_i, wrist_i, hand_i) = _mesh(hip, wrist, hand)
    mended = np.isin(np.arange(len(V)), hand_i)
    parts = np.full(len(V), "pelvis", dtype="<U16")
    parts[wrist_i] = "r_forearm"
    parts[hand_i] = "r_hand"
    moved = V.copy()
    moved[wrist_i] += [0.0, 2.0, 0.0]
    out = find_loose_pieces(V, F, mended, parts).reattach(V, moved)
    np.testing.assert_allclose(out[hand_i] - V[hand_i], [[0.0, 2.0, 0.0]] * 6, atol=1e-12)
    # without the parts it takes the median of both: not where either is
    both = find_loose_pieces(V, F, mended).reattach(V, moved)
    assert np.abs(both[hand_i, 1] - out[hand_i, 1]).max() > 0.5


def test_a_shoe_follows_its_hem_after_the_hem_follows_the_leg():
    leg = _box([0, 0, 0])
    hem = (np.array([[0.501, 0.0, 0.0], [0.501, 0.25, 0.0], [0.501, 0.0, 0.25],
                     [0.7, 0.0, 0.0]]), np.array([[0, 1, 2], [0, 1, 3]]))
    shoe = (np.array([[0.7, 0.0, 0.001], [0.7, 0.0, 0.002], [0.9, 0.1, 0.0],
                      [0.7, 0.001, 0.0]]), np.array([[0, 1, 2], [1, 2, 3]]))
    V, F, (leg_i, hem_i, shoe_i) = _mesh(leg, hem, shoe)
    mended = np.isin(np.arange(len(V)), np.concatenate([hem_i, shoe_i]))
    loose = find_loose_pieces(V, F, mended)
    assert [p.tolist() for p in loose.pieces] == [hem_i.tolist(), shoe_i.tolist()]
    moved = V.copy()
    moved[leg_i] += [1.0, 0.0, 0.0]
    out = loose.reattach(V, moved)
    np.testing.assert_allclose(out[np.concatenate([hem_i, shoe_i])] - V[np.concatenate(
        [hem_i, shoe_i])], [[1.0, 0.0, 0.0]] * 8, atol=1e-12)


def test_well_bound_large_and_untouching_pieces_are_left_to_the_cage():
    box, tri = _box([0, 0, 0]), _triangle([0.501, 0, 0])
    far = _triangle([5.0, 0, 0])
    V, F, (box_i, tri_i, far_i) = _mesh(box, tri, far)
    # the triangle well bound (none mended), the far one loose but touching nothing
    mended = np.isin(np.arange(len(V)), far_i)
    assert find_loose_pieces(V, F, mended).pieces == ()
    # mended 1 of 3: watched, not loose
    loose = find_loose_pieces(V, F, mended | np.isin(np.arange(len(V)), tri_i[:1]))
    assert [p.tolist() for p in loose.pieces] == [tri_i.tolist()] and loose.watched == (True,)
    # a mended piece of more than a tenth of the vertices is never loose: two boxes
    V2, F2, (first, second) = _mesh(_box([0, 0, 0]), _box([1.001, 0, 0]))
    assert find_loose_pieces(V2, F2, np.isin(np.arange(len(V2)), second)).pieces == ()


def test_bad_input_is_refused():
    V, F, _ = _mesh(_box([0, 0, 0]), _triangle([0.501, 0, 0]))
    with pytest.raises(InputError, match="one flag per vertex"):
        find_loose_pieces(V, F, np.zeros(5, bool))
    with pytest.raises(InputError, match="one part per vertex"):
        find_loose_pieces(V, F, np.zeros(len(V), bool), ["pelvis"] * 3)
    with pytest.raises(InputError, match="'banana', which is no rigid part"):
        find_loose_pieces(V, F, np.zeros(len(V), bool), ["pelvis"] * 100 + ["banana"])
    with pytest.raises(InputError, match="faces"):
        find_loose_pieces(V, np.vstack([F, [[0, 1, 101]]]), np.zeros(len(V), bool))
    loose = find_loose_pieces(V, F, np.arange(len(V)) >= 98)
    with pytest.raises(InputError, match="a mesh of 101 vertices; rest_v has 101 and "
                                         "deformed_v 100"):
        loose.reattach(V, V[:100])
    with pytest.raises(InputError, match="rest_v has 102"):
        loose.reattach(np.vstack([V, V[:1]]), np.vstack([V, V[:1]]))
    with pytest.raises(InputError, match="NaN"):
        loose.reattach(V, np.where(V > 0.4, np.nan, V))


def _strip(n, x=0.501):
    """``n`` vertices 0.001 off the box's side at x = 0.5, on its grid, joined by a strip
    of triangles into one piece: each touches one box vertex."""
    grid = np.array([[x, y, z] for y in (-0.5, -0.25, 0.0, 0.25, 0.5)
                     for z in (-0.5, -0.25, 0.0, 0.25, 0.5)])[:n]
    return grid, np.array([[k, k + 1, k + 2] for k in range(n - 2)])


def test_the_thresholds_are_the_documented_ones():
    from cagekit.transfer import loose_pieces as lp

    def loose_count(n, mended_share):
        V, F, (box, piece) = _mesh(_box([0, 0, 0]), _strip(n))
        mended = np.zeros(len(V), bool)
        mended[piece[:int(round(mended_share * n))]] = True
        return len(find_loose_pieces(V, F, mended).pieces)

    # half mended is loose, less is not
    assert loose_count(4, 0.5) == 1 and loose_count(4, 0.25) == 0
    # at most a tenth of the vertices: 10 of 108 is loose, 11 of 109 is not
    assert loose_count(10, 1.0) == 1 and loose_count(11, 1.0) == 0
    assert lp.LOOSE_MENDED == 0.5 and lp.LOOSE_SIZE == 0.1 and lp.CONTACT_PAIRS == 3


def test_a_piece_needs_three_touching_pairs_and_ignores_unused_vertices():
    box = _box([0, 0, 0])
    # a triangle touching the box at 2 vertices only (the third 0.1 away): not followed
    two = (np.array([[0.501, 0.0, 0.0], [0.501, 0.25, 0.0], [0.6, 0.0, 0.25]]),
           np.array([[0, 1, 2]]))
    V, F, (_, tri) = _mesh(box, two)
    assert find_loose_pieces(V, F, np.isin(np.arange(len(V)), tri)).pieces == ()
    # an unused vertex lying at the triangle is never what it follows
    V, F, (box_i, tri) = _mesh(box, _triangle([0.501, 0, 0]))
    V = np.vstack([V, V[tri[0]] + 0.0001])
    mended = np.isin(np.arange(len(V)), tri)
    loose = find_loose_pieces(V, F, mended)
    moved = V.copy()
    moved[box_i] += [0.0, 1.0, 0.0]
    moved[-1] += [0.0, 100.0, 0.0]
    np.testing.assert_allclose(loose.reattach(V, moved)[tri] - V[tri], [[0.0, 1.0, 0.0]] * 3,
                               atol=1e-12)


def test_the_median_ignores_a_touched_vertex_that_flew_off():
    V, F, (box, piece) = _mesh(_box([0, 0, 0]), _strip(5))
    loose = find_loose_pieces(V, F, np.isin(np.arange(len(V)), piece))
    moved = V.copy()
    moved[box] += [0.0, 0.0, 1.0]
    moved[loose.touched[0][0]] += [0.0, 0.0, 9.0]  # one touched vertex carried far off
    np.testing.assert_allclose(loose.reattach(V, moved)[piece] - V[piece],
                               [[0.0, 0.0, 1.0]] * 5, atol=1e-12)


def _forearm_and_hand():
    """A fine box (1538 vertices, 1/16 a square) and a hand of 27 vertices sticking out of
    its side at x = 0.5: a 3 x 3 ring 0.001 off the box's grid, fingers to x = 1.0."""
    box = trimesh.creation.box().subdivide().subdivide().subdivide().subdivide()
    grid = [(y, z) for y in (-0.125, 0.0, 0.125) for z in (-0.125, 0.0, 0.125)]
    hand = np.array([[x, y, z] for x in (0.501, 0.75, 1.0) for y, z in grid])
    strip = np.array([[k, k + 1, k + 2] for k in range(len(hand) - 2)])
    return _mesh((np.asarray(box.vertices), np.asarray(box.faces)), (hand, strip))


def _about_z(degrees):
    a = np.radians(degrees)
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0, 0, 1.0]])


def test_a_bent_piece_is_restored_rigid_and_turned_with_the_part_it_touched():
    V, F, (box, hand) = _forearm_and_hand()
    loose = find_loose_pieces(V, F, np.isin(np.arange(len(V)), hand))
    assert [p.tolist() for p in loose.pieces] == [hand.tolist()]
    patch = loose.patches[0]
    assert len(patch) >= lp.PATCH_SIZE and np.isin(patch, box).all()
    # the forearm turns 40 degrees and moves; the cage bends the hand: the ring goes with
    # the forearm, the fingers stay behind (folded over)
    turn, shift = _about_z(40), np.array([0.3, 2.0, -0.1])
    moved = V.copy()
    moved[box] = V[box] @ turn.T + shift
    ring = hand[:9]
    moved[ring] = V[ring] @ turn.T + shift
    moved[hand[9:]] = V[hand[9:]] + [0.0, 0.5, 0.0]
    out = loose.reattach(V, moved)
    np.testing.assert_array_equal(out[box], moved[box])
    # the hand is its rest shape, turned and moved with the forearm exactly
    np.testing.assert_allclose(out[hand], V[hand] @ turn.T + shift, atol=1e-9)
    # the translation alone (today's rule for a piece the cage did not bend) could not
    # have: the fingers stay folded
    translated = moved[hand] + np.median(moved[loose.touched[0]] + V[loose.touching[0]]
                                         - V[loose.touched[0]] - moved[loose.touching[0]],
                                         axis=0)
    assert np.abs(translated - (V[hand] @ turn.T + shift)).max() > 0.2


def test_a_piece_the_cage_turned_rigidly_keeps_its_turn():
    # the cage turns the hand rigidly, 10 degrees more than the forearm: not bent, so it is
    # translated back to its contacts and keeps the cage's turn (the suit's shoes)
    V, F, (box, hand) = _forearm_and_hand()
    loose = find_loose_pieces(V, F, np.isin(np.arange(len(V)), hand))
    moved = V.copy()
    moved[box] = V[box] @ _about_z(40).T
    moved[hand] = V[hand] @ _about_z(50).T
    shift = loose.reattach(V, moved)[hand] - moved[hand]
    np.testing.assert_allclose(shift, shift[[0]].repeat(len(hand), 0), atol=1e-12)
    assert np.linalg.norm(shift[0]) > 1e-3


def test_a_piece_bent_like_the_surface_around_it_keeps_the_cage_s_shape():
    # the cage stretches everything across the arm (twice, in y and z): the patch around
    # the contacts deviates from rigid as much as the hand, which is only moved back (the
    # hem at the ankle, bent with the leg)
    V, F, (box, hand) = _forearm_and_hand()
    loose = find_loose_pieces(V, F, np.isin(np.arange(len(V)), hand))
    moved = V * [1.0, 2.0, 2.0]
    moved[hand] += [0.0, 0.0, 0.3]
    shift = loose.reattach(V, moved)[hand] - moved[hand]
    np.testing.assert_allclose(shift, shift[[0]].repeat(len(hand), 0), atol=1e-12)
    np.testing.assert_allclose(shift[0], [0.0, 0.0, -0.3], atol=1e-9)


def test_a_bent_piece_turns_with_its_own_part_not_the_hip():
    # the forearm's patch (r_forearm) turns; the same box's other half is labelled hip
    # (pelvis, not next to the hand along the skeleton) and turns the other way in the
    # motion: the hand's patch holds none of it, and the hand turns with the forearm
    V, F, (box, hand) = _forearm_and_hand()
    parts = np.full(len(V), "r_forearm", dtype="<U16")
    parts[hand] = "r_hand"
    hip = box[V[box, 2] < -0.03]  # the hand touches it, and it lies within the patch reach
    parts[hip] = "pelvis"
    loose = find_loose_pieces(V, F, np.isin(np.arange(len(V)), hand), parts)
    assert len(loose.patches[0]) >= lp.PATCH_SIZE
    assert not np.isin(loose.patches[0], hip).any()
    everything = find_loose_pieces(V, F, np.isin(np.arange(len(V)), hand))
    assert np.isin(everything.patches[0], hip).any()
    turn, shift = _about_z(40), np.array([0.0, 1.0, 0.0])
    moved = V @ turn.T + shift
    moved[hip] = V[hip] @ _about_z(-40).T
    moved[hand[9:]] = V[hand[9:]]  # the fingers left behind: bent
    np.testing.assert_allclose(loose.reattach(V, moved)[hand], V[hand] @ turn.T + shift,
                               atol=1e-9)
    assert np.abs(everything.reattach(V, moved)[hand] - (V[hand] @ turn.T + shift)).max() > 0.1


def _fine_box_and_strip(n, mended_count):
    """The fine box (1538 vertices) and a strip of ``n`` vertices 0.001 off its side, the
    first ``mended_count`` of them mended."""
    box = trimesh.creation.box().subdivide().subdivide().subdivide().subdivide()
    V, F, (box_i, strip) = _mesh((np.asarray(box.vertices), np.asarray(box.faces)), _strip(n))
    return V, F, box_i, strip, np.isin(np.arange(len(V)), strip[:mended_count])


def test_a_watched_piece_keeps_the_cage_s_motion_unless_taken_off():
    V, F, box, strip, mended = _fine_box_and_strip(8, 2)  # a quarter mended: watched
    loose = find_loose_pieces(V, F, mended)
    assert loose.watched == (True,)
    extent = float(np.ptp(V, axis=0).max())
    # the cage lifts the box and the strip with it, the strip a little off (under DETACHED):
    # the cage's result is kept as it is
    moved = V + [0.0, 1.0, 0.0]
    moved[strip] += [0.0, 0.0, 0.5 * lp.DETACHED * extent]
    np.testing.assert_array_equal(loose.reattach(V, moved), moved)
    # the cage leaves the strip behind (off by 1): it follows the box
    moved[strip] = V[strip]
    np.testing.assert_allclose(loose.reattach(V, moved)[strip], V[strip] + [0.0, 1.0, 0.0],
                               atol=1e-12)
    # under a quarter mended: not watched, left to the cage
    assert find_loose_pieces(V, F, np.isin(np.arange(len(V)), strip[:1])).pieces == ()


def test_a_piece_left_off_is_fitted_rigidly_to_contacts_that_spread():
    # a 5 x 5 patch lying on the box's side, all of it mended: every vertex a contact.
    # The box turns 30 degrees; the cage turns the patch 60 and lifts it off the side:
    # not bent, so translated, which leaves it off (turned wrong); its contacts spread, so
    # it is fitted to them: the patch turns with the box exactly
    V, F, box, strip, mended = _fine_box_and_strip(25, 25)
    loose = find_loose_pieces(V, F, mended)
    assert loose.watched == (False,)
    turn = _about_z(30)
    moved = V @ turn.T
    moved[strip] = V[strip] @ _about_z(60).T + [0.0, 0.0, 0.2]
    # (to the 0.001 rest offsets, which are not turned)
    out = loose.reattach(V, moved)[strip]
    np.testing.assert_allclose(out, V[strip] @ turn.T, atol=1e-3)
    assert np.abs(moved[strip] - V[strip] @ turn.T).max() > 0.2
    # the same patch with its contacts on one line (a thin cuff) keeps the translation
    line = V[strip, 2] == V[strip[0], 2]
    assert lp._spread(V[strip], V[strip]) and not lp._spread(V[strip], V[strip[line]])
