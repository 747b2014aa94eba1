"""Tests of cagekit.geometry.sampling: seeded, area-uniform samples on the surface."""

import numpy as np
import pytest
from builders import SQUARE_F, SQUARE_V, grid, icosphere, tilt

from cagekit.errors import InputError
from cagekit.geometry.sampling import sample_surface


def test_sample_surface_is_seeded_and_leaves_global_state_alone():
    V, F = icosphere(2)
    np.random.seed(123)
    state = np.random.get_state()[1].copy()
    a = sample_surface(V, F, 500, seed=7)
    b = sample_surface(V, F, 500, seed=7)
    c = sample_surface(V, F, 500, seed=8)
    np.testing.assert_array_equal(np.random.get_state()[1], state)
    assert a.shape == (500, 3) and a.dtype == np.float64
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)


def test_sample_surface_points_lie_on_their_faces():
    V, F, _ = grid(4, 3, jitter=0.2)
    V, _ = tilt(V)
    P, fi = sample_surface(V, F, 2000, seed=0, return_faces=True)
    assert fi.dtype == np.int64 and fi.shape == (2000,)
    a, b, c = V[F[fi, 0]], V[F[fi, 1]], V[F[fi, 2]]
    # barycentric coordinates by least squares on the two edge vectors
    E = np.stack([b - a, c - a], axis=2)
    rhs = np.einsum("nki,nk->ni", E, P - a)[:, :, None]
    uv = np.linalg.solve(np.einsum("nki,nkj->nij", E, E), rhs)[:, :, 0]
    np.testing.assert_allclose(a + np.einsum("nij,nj->ni", E, uv), P, atol=1e-12)
    assert (uv >= -1e-12).all() and (uv.sum(axis=1) <= 1 + 1e-12).all()


def test_sample_surface_is_area_uniform():
    # triangle 0 has area 1.5, triangle 1 has area 0.5: ratio 3:1
    V = np.array(
        [[0, 0, 0], [3, 0, 0], [0, 1, 0], [10, 0, 0], [11, 0, 0], [10, 1, 0]], float
    )
    F = np.array([[0, 1, 2], [3, 4, 5]])
    P, fi = sample_surface(V, F, 40000, seed=0, return_faces=True)
    frac = np.mean(fi == 0)
    assert frac == pytest.approx(0.75, abs=0.01)  # binomial std is 0.002
    # uniform inside a triangle: the mean sample is the centroid
    np.testing.assert_allclose(P[fi == 0].mean(0), V[[0, 1, 2]].mean(0), atol=0.02)
    np.testing.assert_allclose(P[fi == 1].mean(0), V[[3, 4, 5]].mean(0), atol=0.01)


def test_sample_surface_rejects_bad_input():
    with pytest.raises(InputError, match="zero total area"):
        sample_surface([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]], 10)
    with pytest.raises(InputError, match="no faces to return"):
        sample_surface(SQUARE_V, None, 10, return_faces=True)
    with pytest.raises(InputError):
        sample_surface(SQUARE_V, SQUARE_F, -1)
    assert sample_surface(SQUARE_V, SQUARE_F, 0).shape == (0, 3)


@pytest.mark.parametrize("seed", [0, 7])
def test_sample_surface_draws_trimeshs_points_bit_for_bit(seed):
    """The sampler is written out to spare commands trimesh's import; its points and faces
    must stay trimesh's, or every fitted cage and deformation would move."""
    import trimesh

    rng = np.random.default_rng(seed)
    V, F = icosphere(2)
    V = V * rng.uniform(0.5, 3.0, size=3) + rng.normal(size=3)  # unequal face areas
    mesh = trimesh.Trimesh(vertices=V, faces=F, process=False, validate=False)
    expected, expected_faces = trimesh.sample.sample_surface(
        mesh, 3001, seed=np.random.default_rng(seed))
    points, faces = sample_surface(V, F, 3001, seed=seed, return_faces=True)
    assert np.array_equal(points, expected)
    assert np.array_equal(faces, expected_faces)
