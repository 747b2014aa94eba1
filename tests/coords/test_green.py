"""Green coordinates (issue 19): reproduction, partition of unity, similarity invariance,
non-affinity, a quadrature reference, near and on the cage, outside, and ``cagekit apply``.

D is the cage's bounding-box diagonal. Bounds tested: reproduction <= 1e-10 D inside, near
faces, edges and vertices (1e-12 D .. 1e-4 D away, both sides), on them, and outside
within 2 D; similarities of the cage move the points by the same similarity to 1e-10 D.
"""

import igl
import numpy as np
import pytest
from builders import CAGE, CAGES, SHAPE, cagekit, diag, load_obj
from hypothesis import given, settings
from hypothesis import strategies as st
from test_mvc import _near_points

from cagekit import InputError, bind
from cagekit.cage.shapes import box_cage, icosphere_cage
from cagekit.coords.green import INSET, green_coordinates, stretch_factors, unit_normals


def reproduction_error(v, f, p):
    phi, psi = green_coordinates(p, v, f)
    assert np.isfinite(phi).all() and np.isfinite(psi).all()
    normals, _ = unit_normals(v, f)
    return np.linalg.norm(phi @ v + psi @ normals - p, axis=1), phi


def inside(v, f, n, seed, margin=1e-4):
    p = np.random.default_rng(seed).uniform(v.min(axis=0), v.max(axis=0), (n, 3))
    dist = np.sqrt(igl.point_mesh_squared_distance(p, v, f)[0])
    return p[(igl.winding_number(v, f, p) > 0.5) & (dist >= margin * diag(v))]


@pytest.mark.parametrize("name", sorted(CAGES))
def test_interior_reproduction_and_partition_of_unity(name):
    v, f = CAGES[name]
    p = inside(v, f, 3000, 1)
    assert len(p) > 100
    error, phi = reproduction_error(v, f, p)
    assert error.max() <= 1e-10 * diag(v)
    assert np.abs(phi.sum(axis=1) - 1).max() <= 1e-12


def _quadrature(x, v, f, levels=5):
    """phi and psi at one point by the midpoint rule on 4**levels sub-triangles a face:
    an independent reference, slow and accurate to ~1e-6 for points away from the cage."""
    k, m = len(v), len(f)
    phi, psi = np.zeros(k), np.zeros(m)
    # barycentric centroids and areas of a regular subdivision of the unit triangle
    s = 2**levels
    bary = []
    for i in range(s):
        for j in range(s - i):
            bary.append([(i + 1 / 3) / s, (j + 1 / 3) / s])  # upward triangles
            if i + j < s - 1:
                bary.append([(i + 2 / 3) / s, (j + 2 / 3) / s])  # downward ones
    bary = np.array(bary)
    lam = np.column_stack([1 - bary.sum(axis=1), bary])  # weights of vertices 0, 1, 2
    normals, twice = unit_normals(v, f)
    for j, face in enumerate(f):
        xi = lam @ v[face]
        r = xi - x
        dist = np.linalg.norm(r, axis=1)
        dA = 0.5 * twice[j] / len(bary)
        psi[j] = np.sum(dA / (4 * np.pi * dist))
        dgdn = (r @ normals[j]) / (4 * np.pi * dist**3)
        phi[face] += (lam * (dgdn * dA)[:, None]).sum(axis=0)
    return phi, psi


@pytest.mark.parametrize("name", ["box1", "ico1", "star"])
def test_matches_a_quadrature_of_the_potentials(name):
    v, f = CAGES[name]
    p = inside(v, f, 400, 2, margin=0.1)[:5]
    phi, psi = green_coordinates(p, v, f)
    for i, x in enumerate(p):
        ref_phi, ref_psi = _quadrature(x, v, f)
        assert np.abs(phi[i] - ref_phi).max() <= 2e-4
        assert np.abs(psi[i] - ref_psi).max() <= 2e-4 * diag(v)


@pytest.mark.parametrize("name", sorted(CAGES))
@pytest.mark.parametrize("region", ["face", "edge", "vertex"])
def test_near_cage_reproduction(name, region):
    v, f = CAGES[name]
    p = _near_points(v, f, region, np.random.default_rng(3), 400)
    error, phi = reproduction_error(v, f, p)
    assert error.max() <= 1e-10 * diag(v)
    assert np.abs(phi.sum(axis=1) - 1).max() <= 1e-10


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), exponent=st.floats(-16, -4),
       region=st.sampled_from(["face", "edge", "vertex"]),
       cage=st.sampled_from(sorted(CAGES)))
def test_near_cage_property(seed, exponent, region, cage):
    v, f = CAGES[cage]
    p = _near_points(v, f, region, np.random.default_rng(seed), 20, exponent, exponent)
    error, _ = reproduction_error(v, f, p)
    # points nearer than INSET are evaluated INSET inside: the on-cage bound below applies
    # (a sliver's corner at 1e-11 from a face gave 1.03e-10 diagonals; failed at 1e-10)
    assert error.max() <= 5 * INSET * diag(v)


@pytest.mark.parametrize("name", sorted(CAGES))
def test_on_vertices_edges_and_faces(name):
    v, f = CAGES[name]
    rng = np.random.default_rng(4)
    on_faces = np.einsum("fi,fij->fj", rng.dirichlet([1, 1, 1], len(f)), v[f])
    on_edges = 0.3 * v[f[:, 0]] + 0.7 * v[f[:, 1]]
    p = np.vstack([v, on_edges, on_faces])
    error, _ = reproduction_error(v, f, p)
    # evaluated INSET diagonals inside, along the pseudo-normal (at a sliver's corner a
    # few INSET, the evaluation's own error there)
    assert error.max() <= 5 * INSET * diag(v)


@pytest.mark.parametrize("name", sorted(CAGES))
def test_outside_within_two_diagonals_reproduces(name):
    v, f = CAGES[name]
    rng = np.random.default_rng(5)
    centre, D = 0.5 * (v.min(axis=0) + v.max(axis=0)), diag(v)
    p = centre + rng.uniform(-D, D, (600, 3))
    p = p[igl.winding_number(v, f, p) < 0.5]
    error, phi = reproduction_error(v, f, p)
    assert error.max() <= 1e-10 * D
    assert np.abs(phi.sum(axis=1) - 1).max() <= 1e-10


def test_the_extension_is_continuous_across_the_exit_face():
    v, f = icosphere_cage(1)
    normals, _ = unit_normals(v, f)
    centre = v[f].mean(axis=1)
    moved = v + 0.1 * np.random.default_rng(6).normal(size=v.shape)
    for eps in (1e-3, 1e-6):
        a = bind(centre - eps * normals, v, f, method="green").deform(moved)
        b = bind(centre + eps * normals, v, f, method="green").deform(moved)
        # the map's slope is O(1): the two sides differ by O(eps), not O(1)
        assert np.linalg.norm(a - b, axis=1).max() <= 20 * eps * diag(v)


def _random_similarity(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    rotation = q * np.sign(np.diag(r))
    if np.linalg.det(rotation) < 0:
        rotation[:, 0] *= -1
    return rotation, 10 ** rng.uniform(-2, 2), rng.normal(size=3) * 5


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), cage=st.sampled_from(["box3", "star", "sliver"]))
def test_similarities_move_the_points_by_the_same_similarity(seed, cage):
    v, f = CAGES[cage]
    rng = np.random.default_rng(seed)
    p = inside(v, f, 300, seed % 1000)
    rotation, scale, shift = _random_similarity(rng)
    moved = scale * v @ rotation.T + shift
    result = bind(p, v, f, method="green").deform(moved)
    expected = scale * p @ rotation.T + shift
    assert np.abs(result - expected).max() <= 1e-10 * diag(moved)


def test_not_affine_invariant_and_nearly_conformal_where_mvc_shears():
    # a box stretched 2x along x: MVC moves points by the stretch itself; Green does not
    v, f = box_cage(3)
    stretch = np.array([2.0, 1.0, 1.0])
    p = inside(v, f, 2000, 7, margin=0.05)
    green = bind(p, v, f, method="green").deform(v * stretch)
    mvc = bind(p, v, f).deform(v * stretch)
    np.testing.assert_allclose(mvc, p * stretch, atol=1e-12)
    away = np.linalg.norm(green - p * stretch, axis=1) / diag(v)
    assert away.max() > 0.02  # measurably not the affine map (0.09 D at most, measured)
    # a small ball in the middle stays rounder (quasi-conformal: the Jacobian there has
    # singular values 1.67, 1.19, 1.19, measured), where MVC's stretch is 2, 1, 1
    ball = 0.01 * np.random.default_rng(8).normal(size=(200, 3))
    g = bind(ball, v, f, method="green").deform(v * stretch)
    m = bind(ball, v, f).deform(v * stretch)

    def anisotropy(moved):  # of the map's Jacobian there (a least-squares linear fit)
        J = np.linalg.lstsq(ball - ball.mean(axis=0), moved - moved.mean(axis=0),
                            rcond=None)[0]
        return np.linalg.cond(J)

    assert anisotropy(g) < 1.5
    assert anisotropy(m) == pytest.approx(2.0, rel=1e-9)


def test_stretch_factors():
    v, f = box_cage(1)
    rotation, _, _ = _random_similarity(np.random.default_rng(9))
    np.testing.assert_allclose(stretch_factors(v, v @ rotation.T, f), 1.0, rtol=1e-12)
    np.testing.assert_allclose(stretch_factors(v, 3 * v - 2, f), 3.0, rtol=1e-12)
    # a unit right triangle stretched 2x along one leg: the RMS of its two stretches
    tri_v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    tri_f = np.array([[0, 1, 2]])
    s = stretch_factors(tri_v, tri_v * [2.0, 1.0, 1.0], tri_f)
    assert s[0] == pytest.approx(np.sqrt((2**2 + 1**2) / 2), rel=1e-14)


def test_bind_green_and_its_errors():
    v, f = box_cage(2)
    b = bind([[0.1, 0.2, 0.3]], v, f, method="green")
    assert b.method == "green" and b.n_points == 1
    assert b.phi.shape == (1, len(v)) and b.psi.shape == (1, len(f))
    np.testing.assert_allclose(b.deform(v), [[0.1, 0.2, 0.3]], atol=1e-14)
    assert b.encloses([[0.1, 0.2, 0.3]])
    flat = v.copy()
    flat[:, 2] = 0.0  # every face of the top and bottom collapses onto z = 0
    with pytest.raises(InputError, match="zero area"):
        b.deform(flat)
    with pytest.raises(InputError, match="vertex counts"):
        b.deform(v[:-1])
    with pytest.raises(InputError, match="NaN"):
        b.deform(np.full_like(v, np.nan))
    with pytest.raises(InputError, match="green"):
        bind([[0.0, 0, 0]], v, f, method="harmonic")
    with pytest.raises(InputError, match="NaN"):
        green_coordinates([[np.nan, 0, 0]], v, f)
    phi, psi = green_coordinates(np.zeros((0, 3)), v, f)
    assert phi.shape == (0, len(v)) and psi.shape == (0, len(f))


def test_apply_with_green_coordinates_moves_by_a_similarity(tmp_path):
    from cagekit.io import save_mesh

    CV, CF = load_obj(CAGE)
    rotation, scale, shift = _random_similarity(np.random.default_rng(10))
    moved = tmp_path / "moved.obj"
    save_mesh(moved, scale * CV @ rotation.T + shift, CF)
    out = tmp_path / "out.obj"
    result = cagekit("apply", SHAPE, CAGE, moved, "-o", out, "--coords", "green", "--json")
    assert result.returncode == 0, result.stderr
    V, F = load_obj(SHAPE)
    OV, OF = load_obj(out)
    assert np.array_equal(OF, F)
    expected = scale * V @ rotation.T + shift
    assert np.abs(OV - expected).max() <= 1e-8 * diag(expected)
