"""Mean value coordinates: the identities and bounds of issue 2, on nasty inputs.

D is the cage's bounding-box diagonal. Bounds tested:
* partition of unity everywhere;
* linear precision <= 1e-9 D inside, at least 1e-4 D from the cage;
* linear precision <= 1e-6 D near faces, edges and vertices (1e-12 D .. 1e-4 D away, both
  sides) and outside within 2 D of the centre;
* exact interpolation <= 1e-12 D on vertices, edges (coplanar ones too) and faces;
* finite output and unit row sums far outside; beyond 10 D the blend into the affine
  extension: the rest cage reproduces points to 1e-12 of their distance at any distance,
  weights continuous across the blend, far points moved by the cage's affine fit;
* affine invariance, agreement with the independently derived textbook formula.
"""

import igl
import numpy as np
import pytest
from builders import CAGES, diag, sliver_cage, star_cage, unit_normals
from hypothesis import given
from hypothesis import strategies as st

from cagekit import CageError, InputError
from cagekit.cage import cage_encloses
from cagekit.cage.shapes import box_cage
from cagekit.coords import bind, mean_value_coordinates, mean_value_coordinates_textbook


def lin_err(w, v, p):
    return np.linalg.norm(w @ v - p, axis=1)


@pytest.mark.parametrize("name", sorted(CAGES))
def test_interior_partition_of_unity_and_linear_precision(name):
    v, f = CAGES[name]
    D = diag(v)
    rng = np.random.default_rng(1)
    p = rng.uniform(v.min(axis=0), v.max(axis=0), (4000, 3))
    dist = np.sqrt(igl.point_mesh_squared_distance(p, v, f)[0])
    wn = igl.winding_number(v, f, p)
    p = p[(wn > 0.5) & (dist >= 1e-4 * D)]
    assert len(p) > 100
    w = mean_value_coordinates(p, v, f)
    assert np.abs(w.sum(axis=1) - 1).max() <= 1e-13
    assert lin_err(w, v, p).max() <= 1e-9 * D


@pytest.mark.parametrize("name", sorted(set(CAGES) - {"sliver"}))
def test_matches_textbook_formula_inside(name):
    """The textbook formula, in long double, as an independent reference. (Not on the
    sliver cage: there the textbook's tolerance skips the sliver and its own linear
    precision error is 1e-10, while ours stays at 1e-16.)"""
    v, f = CAGES[name]
    D = diag(v)
    rng = np.random.default_rng(2)
    p = rng.uniform(v.min(axis=0), v.max(axis=0), (600, 3))
    dist = np.sqrt(igl.point_mesh_squared_distance(p, v, f)[0])
    p = p[(igl.winding_number(v, f, p) > 0.5) & (dist >= 1e-3 * D)]
    w = mean_value_coordinates(p, v, f)
    ref = mean_value_coordinates_textbook(p, v, f, dtype=np.longdouble)
    assert np.abs(w - ref).max() <= 1e-11


def _near_points(v, f, region, rng, n, lo=-12, hi=-4):
    D = diag(v)
    normals = unit_normals(v, f)
    pts = []
    for _ in range(n):
        fi = rng.integers(len(f))
        a, b, c = v[f[fi]]
        if region == "face":
            base = rng.dirichlet([1, 1, 1]) @ v[f[fi]]
            direction = normals[fi]
        else:
            t = rng.uniform()
            base = (1 - t) * a + t * b if region == "edge" else a
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
        offset = 10 ** rng.uniform(lo, hi) * D * rng.choice([-1.0, 1.0])
        pts.append(base + offset * direction)
    return np.array(pts)


@pytest.mark.parametrize("name", sorted(CAGES))
@pytest.mark.parametrize("region", ["face", "edge", "vertex"])
def test_near_cage_linear_precision(name, region):
    v, f = CAGES[name]
    D = diag(v)
    p = _near_points(v, f, region, np.random.default_rng(3), 1500)
    w = mean_value_coordinates(p, v, f)
    assert np.all(np.isfinite(w))
    assert np.abs(w.sum(axis=1) - 1).max() <= 1e-12
    assert lin_err(w, v, p).max() <= 1e-6 * D


@given(seed=st.integers(0, 2**32 - 1), exponent=st.floats(-12, -4),
       region=st.sampled_from(["face", "edge", "vertex"]), cage=st.sampled_from(sorted(CAGES)))
def test_near_cage_property(seed, exponent, region, cage):
    v, f = CAGES[cage]
    D = diag(v)
    rng = np.random.default_rng(seed)
    p = _near_points(v, f, region, rng, 8, lo=exponent, hi=exponent)
    w = mean_value_coordinates(p, v, f)
    assert np.all(np.isfinite(w))
    assert lin_err(w, v, p).max() <= 1e-6 * D


@pytest.mark.parametrize("name", sorted(CAGES))
def test_exact_on_vertices_edges_faces(name):
    v, f = CAGES[name]
    D = diag(v)
    rng = np.random.default_rng(4)
    # every vertex, a point on every edge, a point on every face
    edges = np.unique(np.sort(np.vstack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1),
                      axis=0)
    t = rng.uniform(0.01, 0.99, (len(edges), 1))
    on_edges = (1 - t) * v[edges[:, 0]] + t * v[edges[:, 1]]
    bary = rng.dirichlet([1, 1, 1], len(f))
    on_faces = np.einsum("fi,fic->fc", bary, v[f])
    for p in (v, on_edges, on_faces):
        w = mean_value_coordinates(p, v, f)
        assert lin_err(w, v, p).max() <= 1e-12 * D
        assert np.abs(w.sum(axis=1) - 1).max() <= 1e-14
    # interpolation, not just precision: weights live on the vertex / edge / face only
    w = mean_value_coordinates(v, v, f)
    assert np.array_equal(w, np.eye(len(v)))
    w = mean_value_coordinates(on_edges, v, f)
    support = w.copy()
    support[np.arange(len(edges)), edges[:, 0]] = 0
    support[np.arange(len(edges)), edges[:, 1]] = 0
    assert np.abs(support).max() == 0.0
    assert np.abs(w[np.arange(len(edges)), edges[:, 1]] - t[:, 0]).max() <= 1e-12


def test_coplanar_edges_interpolate():
    """Edges between coplanar faces (VTK's failure case): grid edges and diagonals of a box."""
    v, f = box_cage(3)
    D = diag(v)
    normals = unit_normals(v, f)
    edges = {}
    for fi, face in enumerate(f):
        for a, b in ((face[0], face[1]), (face[1], face[2]), (face[2], face[0])):
            edges.setdefault((min(a, b), max(a, b)), []).append(fi)
    coplanar = [e for e, fs in edges.items() if np.dot(normals[fs[0]], normals[fs[1]]) > 1 - 1e-12]
    assert len(coplanar) > 50
    e = np.array(coplanar)
    for t in (1e-9, 0.25, 0.5, 0.9):
        p = (1 - t) * v[e[:, 0]] + t * v[e[:, 1]]
        w = mean_value_coordinates(p, v, f)
        assert lin_err(w, v, p).max() <= 1e-12 * D
        assert np.abs(w[np.arange(len(e)), e[:, 1]] - t).max() <= 1e-12


@pytest.mark.parametrize("name", sorted(CAGES))
def test_outside_within_two_diagonals(name):
    v, f = CAGES[name]
    D = diag(v)
    centre = (v.max(axis=0) + v.min(axis=0)) / 2
    rng = np.random.default_rng(5)
    d = rng.normal(size=(3000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    p = centre + d * rng.uniform(0, 2 * D, (3000, 1))
    w = mean_value_coordinates(p, v, f)
    assert np.all(np.isfinite(w))
    assert np.abs(w.sum(axis=1) - 1).max() <= 1e-12
    assert lin_err(w, v, p).max() <= 1e-6 * D


def test_far_outside_is_finite_and_sums_to_one():
    v, f = star_cage(1)
    rng = np.random.default_rng(6)
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    p = d * 10.0 ** rng.uniform(1, 30, (200, 1))
    w = mean_value_coordinates(p, v, f)
    assert np.all(np.isfinite(w))
    # far away single weights grow like R / D and cancel: the sum is one to rounding of them
    scale = np.abs(w).sum(axis=1)
    assert np.all(np.abs(w.sum(axis=1) - 1) <= 1e-13 * scale)


@given(seed=st.integers(0, 2**32 - 1))
def test_affine_invariance_of_the_deformation(seed):
    """An affine map of the cage moves the bound points by the same map (any affine map)."""
    rng = np.random.default_rng(seed)
    v, f = star_cage(seed % 7)
    p = rng.uniform(-0.4, 0.4, (50, 3))
    A = rng.normal(size=(3, 3)) + 3 * np.eye(3)
    t = rng.normal(size=3) * 10
    b = bind(p, v, f)
    scale = np.abs(A).sum() + np.abs(t).sum()
    assert np.abs(b.deform(v @ A.T + t) - (p @ A.T + t)).max() <= 1e-12 * scale


@given(seed=st.integers(0, 2**32 - 1))
def test_similarity_invariance_of_the_weights(seed):
    """The weights themselves are invariant under rotations, uniform scaling and translation
    (MVC, unlike Wachspress coordinates, are not invariant under general affine maps)."""
    rng = np.random.default_rng(seed)
    v, f = star_cage(seed % 7)
    p = rng.uniform(-0.4, 0.4, (50, 3))
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    s = 10 ** rng.uniform(-3, 3)
    t = rng.normal(size=3) * 10 * s
    w = mean_value_coordinates(p, v, f)
    w2 = mean_value_coordinates(s * p @ q.T + t, s * v @ q.T + t, f)
    # a point at distance h from the plane of a face it lies outside of has single weights
    # accurate to about eps * D / h (the error leaves linear precision intact; see the
    # module docstring of cagekit.coords.mvc)
    normals = unit_normals(v, f)
    h = np.abs(np.einsum("pfc,fc->pf", p[:, None, :] - v[f[:, 0]][None], normals)).min(axis=1)
    tol = 1e-11 + 1e-14 * diag(v) / h
    assert np.all(np.abs(w - w2).max(axis=1) <= tol)


def test_mirrored_cage_is_reoriented():
    v, f = star_cage(3)
    p = np.random.default_rng(7).uniform(-0.4, 0.4, (100, 3))
    mirror = np.array([-1.0, 1.0, 1.0])
    w = mean_value_coordinates(p, v, f)
    w2 = mean_value_coordinates(p * mirror, v * mirror, f)  # faces now point inward
    assert np.abs(w - w2).max() <= 1e-12


@pytest.mark.parametrize("cage", ["inward", "outward"])
def test_inward_cage_gives_same_weights(cage):
    v, f = box_cage(2)
    p = np.random.default_rng(8).uniform(-0.9, 0.9, (200, 3))
    faces = f[:, ::-1] if cage == "inward" else f
    w = mean_value_coordinates(p, v, faces)
    assert np.abs(w - mean_value_coordinates(p, v, f)).max() == 0.0


def test_near_degenerate_faces():
    v, f = sliver_cage()
    D = diag(v)
    rng = np.random.default_rng(9)
    p = rng.uniform(-0.99, 0.99, (2000, 3))
    p = np.vstack([p, _near_points(v, f, "edge", rng, 500), _near_points(v, f, "face", rng, 500),
                   v])
    w = mean_value_coordinates(p, v, f)
    assert np.all(np.isfinite(w))
    assert lin_err(w, v, p).max() <= 1e-6 * D


def test_cage_not_enclosing_the_shape():
    v, f = box_cage(1)
    p = np.array([[0.0, 0.0, 0.0], [1.5, 0.2, 0.1], [0.5, -3.0, 0.0]])
    b = bind(p, v, f)
    assert not cage_encloses(p, v, f)
    assert cage_encloses(p[:1], v, f)
    assert not b.encloses(p)
    assert b.weights.min() < 0
    assert lin_err(b.weights, v, p).max() <= 1e-12


def test_bind_deform():
    v, f = star_cage(4)
    p = np.random.default_rng(10).uniform(-0.4, 0.4, (300, 3))
    b = bind(p, v, f)
    assert b.weights.shape == (300, len(v))
    np.testing.assert_allclose(b.deform(v), p, atol=1e-12)
    A = np.array([[1.2, 0.1, 0.0], [0.0, 0.9, 0.3], [0.0, 0.0, 1.1]])
    np.testing.assert_allclose(b.deform(v @ A.T + 1.0), p @ A.T + 1.0, atol=1e-11)
    with pytest.raises(InputError, match="vertex counts"):
        b.deform(v[:-1])
    with pytest.raises(InputError, match="NaN"):
        b.deform(np.full_like(v, np.nan))


def test_bad_inputs():
    v, f = box_cage(1)
    with pytest.raises(InputError, match="NaN"):
        bind([[np.nan, 0, 0]], v, f)
    with pytest.raises(InputError, match=r"\(n, 3\)"):
        bind(np.zeros((3, 2)), v, f)
    with pytest.raises(InputError, match="unknown coordinates"):
        bind(np.zeros((1, 3)), v, f, method="harmonic")
    with pytest.raises(CageError, match="open"):
        bind(np.zeros((1, 3)), v, f[:-1])
    bad = f.copy()
    bad[0] = bad[0, ::-1]
    with pytest.raises(CageError, match="oriented"):
        bind(np.zeros((1, 3)), v, bad)
    with pytest.raises(CageError, match="manifold"):
        bind(np.zeros((1, 3)), v, np.vstack([f, f[:1], f[:1, ::-1]]))
    with pytest.raises(CageError, match="out of range"):
        bind(np.zeros((1, 3)), v, f + 1)
    with pytest.raises(CageError, match="non-finite"):
        bind(np.zeros((1, 3)), np.where(np.arange(8)[:, None] == 0, np.inf, v), f)


def test_empty_points():
    v, f = box_cage(1)
    assert bind(np.zeros((0, 3)), v, f).weights.shape == (0, 8)


# --------------------------------------------------------------------------- far outside


def _directions(n, seed):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@pytest.mark.parametrize("name", ["box1", "star", "flat-box"])
def test_far_points_are_reproduced_at_any_distance(name):
    """Linear precision to rounding of |p| from 10 D to 1e290 D (it used to give a cage
    vertex or the origin from about 1e15 D on)."""
    v, f = CAGES[name]
    D = diag(v)
    centre = (v.min(axis=0) + v.max(axis=0)) / 2
    p = centre + _directions(400, 3) * D * 10.0 ** np.random.default_rng(4).uniform(
        1, 290, (400, 1))
    w = mean_value_coordinates(p, v, f)
    assert np.all(np.isfinite(w))
    R = np.abs(p).max(axis=1)
    assert np.all(np.abs(w @ v - p).max(axis=1) <= 1e-12 * R)
    assert np.all(np.abs(w.sum(axis=1) - 1) <= 1e-13 * np.abs(w).sum(axis=1))


def test_weights_are_continuous_across_the_far_blend():
    from cagekit.coords.mvc import FAR_BLEND

    v, f = CAGES["star"]
    D = diag(v)
    centre = (v.min(axis=0) + v.max(axis=0)) / 2
    d = _directions(20, 5)
    for r in FAR_BLEND:
        inner = mean_value_coordinates(centre + d * D * r * (1 - 1e-9), v, f)
        outer = mean_value_coordinates(centre + d * D * r * (1 + 1e-9), v, f)
        assert np.abs(inner - outer).max() <= 1e-6 * np.abs(inner).max()


def test_far_points_move_by_the_affine_fit_of_the_cage():
    from cagekit.coords.mvc import FAR_BLEND, affine_extension_weights

    v, f = CAGES["star"]
    D = diag(v)
    p = _directions(30, 6) * D * 2 * FAR_BLEND[1]
    moved = v + np.random.default_rng(7).normal(scale=0.1, size=v.shape)
    b = bind(p, v, f)
    # the least-squares affine map of the cage's motion
    H = np.hstack([v, np.ones((len(v), 1))])
    At = np.linalg.lstsq(H, moved, rcond=None)[0]
    expected = np.hstack([p, np.ones((len(p), 1))]) @ At
    assert np.abs(b.deform(moved) - expected).max() <= 1e-9 * D * 2 * FAR_BLEND[1]
    assert np.allclose(affine_extension_weights(p, v, f), b.weights, atol=1e-12)


def test_points_whose_weights_overflow_are_refused():
    v, f = box_cage()
    with pytest.raises(InputError, match="overflow"):
        bind([[1e300, 0.0, 0.0]], v * 1e-100, f)
