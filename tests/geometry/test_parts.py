"""The parts of a shape (cagekit.geometry.parts): components with seams joined."""

import numpy as np
import pytest
import trimesh
from builders import icosphere
from hypothesis import given, settings
from hypothesis import strategies as st

from cagekit.cage import face_components, vertex_components
from cagekit.errors import InputError
from cagekit.geometry.parts import face_parts, vertex_parts


def split_at_every_edge(V, F):
    """Every face with vertices of its own, as a file with a seam along every edge has."""
    return V[F.ravel()], np.arange(3 * len(F)).reshape(-1, 3)


def partition(labels):
    """The labels as a set of frozensets of indices (independent of the numbering)."""
    return {frozenset(np.flatnonzero(labels == c).tolist()) for c in np.unique(labels)}


def two_boxes(gap=1.0):
    box = trimesh.creation.box()
    V = np.vstack([box.vertices, box.vertices + [1.0 + gap, 0, 0]])
    return V, np.vstack([box.faces, box.faces + 8])


def test_a_mesh_split_at_its_seams_is_one_part_per_piece():
    V, F = two_boxes()
    Vs, Fs = split_at_every_edge(V, F)
    assert len(np.unique(face_components(len(Vs), Fs))) == len(Fs)  # by index: 24 pieces
    assert face_parts(Vs, Fs).tolist() == [0] * 12 + [1] * 12
    assert face_parts(V, F).tolist() == [0] * 12 + [1] * 12


def test_pieces_that_touch_without_sharing_a_position_stay_apart():
    V, F = two_boxes(gap=0.0)  # face to face, no vertex of one on a vertex of the other
    V[8:] += [0.0, 0.25, 0.25]
    assert np.unique(face_parts(V, F)).tolist() == [0, 1]


def test_minus_zero_is_zero():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [-0.0, -0.0, -0.0], [1, -0.0, 0],
                  [0, -1, 0]])
    assert face_parts(V, [[0, 1, 2], [4, 3, 5]]).tolist() == [0, 0]


def test_pieces_that_share_a_position_but_no_edge_stay_apart():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0], [-1, 0, 0], [0, -1, 0]])
    assert face_parts(V, [[0, 1, 2], [3, 4, 5]]).tolist() == [0, 1]


def test_degenerate_faces_at_a_shared_point_do_not_join_pieces():
    # two pieces touching at the origin, each with a face of no area there
    V = [[0.0, 0, 0], [0, 0, 0], [1, 0, 0], [0, 0, 0], [0, 0, 0], [-1, 0, 0], [0, 1, 0],
         [0, -1, 0]]
    assert face_parts(V, [[0, 1, 2], [0, 2, 6], [3, 4, 5], [3, 5, 7]]).tolist() == [0, 0, 1, 1]


def test_parts_are_numbered_in_the_order_of_their_first_face():
    V, F = two_boxes()
    assert face_parts(V, np.vstack([F[12:], F[:12]])).tolist() == [0] * 12 + [1] * 12


def test_vertices_on_no_face():
    V, F = two_boxes()
    V = np.vstack([V, [[9.0, 9, 9], V[0]]])  # one far away, one on a vertex of the first box
    labels = vertex_parts(V, F)
    assert labels[:8].tolist() == [0] * 8 and labels[8:16].tolist() == [1] * 8
    assert labels[-2:].tolist() == [-1, -1]
    assert vertex_parts(V, np.zeros((0, 3), dtype=int)).tolist() == [-1] * len(V)


def test_bad_input_is_refused():
    with pytest.raises(InputError):
        face_parts([[0.0, 0, np.nan], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    with pytest.raises(InputError):
        vertex_parts([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 3]])


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), pieces=st.integers(1, 4))
def test_splitting_and_renumbering_never_change_the_parts(seed, pieces):
    """Seams at random edges and a random vertex order give the unsplit mesh's parts."""
    rng = np.random.default_rng(seed)
    V0, F0 = icosphere(1)
    V = np.vstack([V0 * rng.uniform(0.5, 2) + 5.0 * i for i in range(pieces)])
    F = np.vstack([F0 + len(V0) * i for i in range(pieces)])
    expected = partition(vertex_components(len(V), F)[F[:, 0]])
    Vs, Fs = split_at_every_edge(V, F)
    keep = rng.random(len(Vs)) < 0.5  # weld back about half the copies
    first = np.unique(F.ravel(), return_index=True)[1]
    target = np.where(keep, first[F.ravel()], np.arange(len(Vs)))
    Fs = target[Fs]
    order = rng.permutation(len(Vs))
    Vp, Fp = Vs[order], np.argsort(order)[Fs]
    assert partition(face_parts(Vp, Fp)) == expected
    labels = vertex_parts(Vp, Fp)
    used = np.zeros(len(Vp), dtype=bool)
    used[Fp.ravel()] = True
    assert (labels[used] >= 0).all() and len(np.unique(labels[used])) == pieces


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 60), st.integers(0, 2**32 - 1))
def test_positions_number_as_numpys_unique_rows(n, seed):
    """Repeated rows, signed zeros and ties in the first coordinates: numpy's numbering."""
    from cagekit.geometry.parts import _positions

    rng = np.random.default_rng(seed)
    pool = rng.choice([-1.0, -0.0, 0.0, 0.5, 1.0, 1e-300], size=(max(1, n // 3), 3))
    V = pool[rng.integers(0, len(pool), n)]
    want = np.unique(V + 0.0, axis=0, return_inverse=True)[1].reshape(-1)
    np.testing.assert_array_equal(_positions(V), want)
