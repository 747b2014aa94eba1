"""Cage validation, orientation, topology and the enclosure test."""

import numpy as np
import pytest

from cagekit import CageError
from cagekit.cage import cage_encloses, cage_topology, check_cage, signed_volume, winding_numbers
from cagekit.cage.shapes import box_cage, icosphere_cage


def test_topology_edges_and_signs():
    v, f = box_cage(2)
    t = cage_topology(f)
    assert len(t.edges) == 3 * len(f) // 2  # closed triangle mesh: e = 3m/2
    assert np.all(t.edges[:, 0] < t.edges[:, 1])
    # each face's directed edges map back to its vertices with the recorded signs
    for face, idx, sgn in zip(f, t.face_edges, t.face_edge_signs):
        for r in range(3):
            a, b = face[r], face[(r + 1) % 3]
            lo, hi = t.edges[idx[r]]
            assert (lo, hi) == (min(a, b), max(a, b))
            assert sgn[r] == (1.0 if a < b else -1.0)


@pytest.mark.parametrize("cage", [box_cage(1), box_cage(3), icosphere_cage(2)])
def test_primitives_are_valid_and_outward(cage):
    v, f = cage
    assert signed_volume(v, f) > 0
    assert np.array_equal(check_cage(v, f), f)
    assert np.array_equal(check_cage(v, f[:, ::-1]), f)


def test_box_volume():
    v, f = box_cage(2, half_extent=(1.0, 2.0, 0.5))
    assert signed_volume(v, f) == pytest.approx(8.0)
    assert signed_volume(v, f[:, ::-1]) == pytest.approx(-8.0)


def test_two_components_oriented_separately():
    v1, f1 = box_cage(1)
    v2, f2 = icosphere_cage(1)
    v = np.vstack([v1, v2 * 0.5 + [5.0, 0, 0]])
    f = np.vstack([f1, f2[:, ::-1] + len(v1)])  # second component inward
    out = check_cage(v, f)
    assert np.array_equal(out[: len(f1)], f1)
    assert np.array_equal(out[len(f1):], f2 + len(v1))


@pytest.mark.parametrize("breaker, message", [
    (lambda v, f: (v, f[:-1]), "open"),
    (lambda v, f: (v, np.vstack([f, f[:2]])), "manifold"),
    (lambda v, f: (v, np.vstack([f[:1, ::-1], f[1:]])), "oriented"),
    (lambda v, f: (v, np.vstack([[[0, 0, 1]], f[1:]])), "repeats a vertex"),
    (lambda v, f: (v, f - 1), "out of range"),
    (lambda v, f: (v * [1, 1, 0], f), "zero area"),
    (lambda v, f: (np.vstack([v, v[:1]]), np.vstack([f, [[0, 8, 1]], [[8, 0, 2]]])), "zero area"),
    (lambda v, f: (np.where(v == 1.0, np.nan, v), f), "non-finite"),
    (lambda v, f: (v[:, :2], f), "(k, 3)"),
    (lambda v, f: (v, f.astype(float)), "integer"),
])
def test_invalid_cages_raise(breaker, message):
    v, f = box_cage(1)
    bv, bf = breaker(v, f)
    with pytest.raises(CageError, match=message.replace("(", r"\(").replace(")", r"\)")) as err:
        check_cage(bv, bf, name="mycage.obj")
    assert str(err.value).startswith("mycage.obj: ")


def test_winding_numbers_and_enclosure():
    v, f = icosphere_cage(2)
    p = np.array([[0.0, 0, 0], [0.5, 0.1, 0], [2.0, 0, 0], [0, 0, -1.5]])
    wn = winding_numbers(p, v, f)
    np.testing.assert_allclose(wn, [1, 1, 0, 0], atol=1e-9)
    assert cage_encloses(p[:2], v, f)
    assert not cage_encloses(p, v, f)
    # a vertex of the cage counts as enclosed (on the surface)
    assert cage_encloses(v[:1] * 0.999999, v, f)


def _folded_box():
    """A box with one vertex pushed through the opposite face: its faces cross."""
    v, f = box_cage(1)
    v = v.copy()
    v[0] = -1.5 * v[0]
    return v, f


def test_self_intersecting_cage_is_refused_unless_asked_not_to():
    from cagekit import bind
    from cagekit.cage import self_intersecting_faces

    v, f = _folded_box()
    crossing = self_intersecting_faces(v, f)
    assert crossing.shape == (len(f),) and crossing.sum() > 0
    assert not self_intersecting_faces(*box_cage(2)).any()  # shared edges do not count
    with pytest.raises(CageError, match=rf"intersects itself \({crossing.sum()} of its 12"):
        check_cage(v, f, name="folded.obj")
    with pytest.raises(CageError, match="intersects itself"):
        bind(np.zeros((1, 3)), v, f)
    assert np.array_equal(check_cage(v, f, intersections=False), f)
    w = bind(np.zeros((1, 3)), v, f, check=False).weights  # defined, if folded
    assert np.isfinite(w).all() and abs(w.sum() - 1) < 1e-12


@pytest.mark.parametrize("scale", [1e-120, 1e120])
def test_tiny_and_huge_cages_are_valid(scale):
    """Areas and volumes are judged scale-free: no underflow to 'zero area'."""
    v, f = box_cage(2)
    assert np.array_equal(check_cage(v * scale, f), f)


def test_distance_in_diagonals_does_not_overflow():
    from cagekit.cage import distance_in_diagonals

    v, _ = box_cage(1)  # diagonal 2 sqrt 3
    r = distance_in_diagonals([[1e300, 1e300, 0.0], [0.0, 0.0, 0.0]], v)
    assert r[0] == pytest.approx(np.sqrt(2) * 1e300 / (2 * np.sqrt(3))) and r[1] == 0.0


def _octahedron(centre=(0.0, 0.0, 0.0)):
    v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    f = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                  [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    return v + centre, f


def _glued_octahedra():
    """Two octahedra touching at one vertex (index 3, at the origin): every edge has two
    faces, consistently oriented, and nothing crosses, but vertex 3 is non-manifold."""
    a, f = _octahedron((0.0, 1.0, 0.0))  # its vertex 3 is (0, 0, 0)
    b, _ = _octahedron((0.0, -1.0, 0.0))  # its vertex 2 is (0, 0, 0)
    v = np.vstack([a, np.delete(b, 2, axis=0)])
    to_glued = np.array([6, 7, 3, 8, 9, 10])  # b's vertices in v (its vertex 2 is a's 3)
    return v, np.vstack([f, to_glued[f]])


def test_a_cage_with_a_non_manifold_vertex_is_refused():
    from cagekit import bind

    v, f = _glued_octahedra()
    assert np.array_equal(check_cage(*_octahedron()), _octahedron()[1])  # each part is fine
    with pytest.raises(CageError, match=r"^glued\.obj: .*vertex 3 is non-manifold"):
        check_cage(v, f, name="glued.obj")
    with pytest.raises(CageError, match="vertex 3 is non-manifold"):
        bind(np.array([[0.0, 1.0, 0.0]]), v, f)


def test_unreferenced_cage_vertices_are_still_accepted():
    v, f = box_cage(1)
    extra = np.vstack([v[:3], [[9.0, 9.0, 9.0]], v[3:]])  # vertex 3 is on no face
    faces = np.where(f >= 3, f + 1, f)
    assert np.array_equal(check_cage(extra, faces), faces)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_cage_encloses_refuses_non_finite_points(bad):
    from cagekit import InputError

    v, f = box_cage(1)
    with pytest.raises(InputError, match=r"point 1 is not finite"):
        cage_encloses([[0.0, 0.0, 0.0], [0.0, bad, 0.0]], v, f)
    moved = v.copy()
    moved[5, 2] = bad
    with pytest.raises(InputError, match=r"cage vertex 5 is not finite"):
        cage_encloses([[0.0, 0.0, 0.0]], moved, f)


def test_cage_topology_is_kept_read_only_and_follows_the_faces():
    _, f = box_cage()
    first, again = cage_topology(f), cage_topology(f.copy())
    assert again is first  # kept: the same faces, even in another array
    with pytest.raises(ValueError, match="read-only"):
        first.edges[0, 0] = 5
    other = cage_topology(f[:, ::-1])  # other faces: computed for them, not the kept one
    assert other is not first
    assert np.array_equal(np.sort(other.face_edge_signs, axis=1),  # each face reversed
                          np.sort(-first.face_edge_signs, axis=1))


def test_check_cage_orients_by_the_vertices_and_refuses_every_time_with_kept_faces():
    v, f = box_cage()
    assert np.array_equal(check_cage(v, f), f)
    mirrored = v * [-1.0, 1.0, 1.0]  # the same faces now point inward
    assert np.array_equal(check_cage(mirrored, f), f[:, ::-1])
    assert np.array_equal(check_cage(v, f), f)  # and back
    for _ in range(2):  # a failure is not kept as a pass
        with pytest.raises(CageError, match="open"):
            check_cage(v, f[1:])
