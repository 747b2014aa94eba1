"""Tests of cagekit.geometry: Laplacian, faces, neighbourhoods, PCA normals and planes."""

import numpy as np
import pytest
import scipy.sparse
from builders import SQUARE_F, SQUARE_V, grid, icosphere, tilt
from hypothesis import given, settings
from hypothesis import strategies as st

from cagekit import geometry
from cagekit.errors import InputError
from cagekit.geometry import (
    Neighborhoods,
    cotangent_laplacian,
    pca_normals,
    pca_planes,
    point_to_plane,
    remove_duplicate_faces,
    vertex_neighborhoods,
)

# ------------------------------------------------------------------ cotangent Laplacian


def test_laplacian_right_isoceles_pair_known_values():
    L = cotangent_laplacian(SQUARE_V, SQUARE_F)
    assert isinstance(L, scipy.sparse.csr_matrix) and L.dtype == np.float64
    # edges of the square have one 45-degree opposite angle: cot = 1, weight 1/2;
    # the diagonal 1-2 has two right opposite angles: weight 0.
    expected = np.array(
        [
            [-1.0, 0.5, 0.5, 0.0],
            [0.5, -1.0, 0.0, 0.5],
            [0.5, 0.0, -1.0, 0.5],
            [0.0, 0.5, 0.5, -1.0],
        ]
    )
    np.testing.assert_allclose(L.toarray(), expected, atol=1e-15)


def test_laplacian_equilateral_triangle():
    V = np.array([[0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0]])
    L = cotangent_laplacian(V, [[0, 1, 2]]).toarray()
    w = 0.5 / np.sqrt(3)  # cot(60 deg) / 2
    np.testing.assert_allclose(L, w * (np.ones((3, 3)) - 3 * np.eye(3)), atol=1e-15)


@pytest.mark.parametrize("tilted", [False, True])
def test_laplacian_symmetric_rows_sum_zero_and_linear_precision(tilted):
    V, F, interior = grid(jitter=0.25)
    if tilted:
        V, _ = tilt(V)
    L = cotangent_laplacian(V, F)
    A = L.toarray()
    np.testing.assert_allclose(A, A.T, atol=1e-14)
    np.testing.assert_allclose(A.sum(axis=1), 0.0, atol=1e-13)
    assert (
        np.diag(A) < 0
    ).all()  # negative semi-definite convention (as igl.cotmatrix)
    assert np.linalg.eigvalsh(A).max() < 1e-12
    # a linear function of the coordinates is harmonic at interior vertices of a flat mesh
    f = V @ np.array([0.3, -1.2, 2.0]) + 5.0
    np.testing.assert_allclose((L @ f)[interior], 0.0, atol=1e-12)
    np.testing.assert_allclose((L @ V)[interior], 0.0, atol=1e-12)
    assert np.abs((L @ V)[~interior]).max() > 0.1  # boundary vertices are not harmonic


def test_laplacian_unreferenced_vertex_has_empty_row():
    V = np.vstack([SQUARE_V, [[5, 5, 5]]])
    L = cotangent_laplacian(V, SQUARE_F)
    assert L.shape == (5, 5)
    assert L[4].nnz == 0 or np.all(L[4].toarray() == 0)


def test_laplacian_rejects_bad_input():
    with pytest.raises(InputError, match="zero area"):
        cotangent_laplacian([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]])
    with pytest.raises(InputError, match="faces"):
        cotangent_laplacian(SQUARE_V, np.zeros((0, 3), dtype=np.int64))
    with pytest.raises(InputError, match="NaN"):
        cotangent_laplacian(np.where(SQUARE_V == 1, np.nan, SQUARE_V), SQUARE_F)
    with pytest.raises(InputError, match="outside"):
        cotangent_laplacian(SQUARE_V, [[0, 1, 4]])
    with pytest.raises(InputError, match="shape"):
        cotangent_laplacian(SQUARE_V[:, :2], SQUARE_F)


# ------------------------------------------------------------------------ faces


def test_remove_duplicate_faces_keeps_first_occurrence_and_orientation():
    F = np.array(
        [[2, 1, 0], [0, 1, 2], [1, 2, 0], [3, 3, 1], [1, 2, 3], [4, 4, 4], [3, 2, 1]]
    )
    F2 = remove_duplicate_faces(F)
    assert F2.dtype == np.int64 and F2.shape == (2, 3)
    assert F2.tolist() == [[2, 1, 0], [1, 2, 3]]


def test_remove_duplicate_faces_empty_and_clean_input():
    assert remove_duplicate_faces(np.zeros((0, 3), dtype=int)).shape == (0, 3)
    _, F, _ = grid()
    np.testing.assert_array_equal(remove_duplicate_faces(F), F)
    with pytest.raises(InputError):
        remove_duplicate_faces([[0, 1]])
    with pytest.raises(InputError):
        remove_duplicate_faces([[0, -1, 2]])


# ------------------------------------------------------------------ neighbourhoods


def test_mesh_neighborhoods_on_tiny_mesh():
    nb = vertex_neighborhoods(SQUARE_V, SQUARE_F)
    assert isinstance(nb, Neighborhoods)
    assert nb.index.dtype == np.int64 and nb.mask.dtype == bool
    assert nb.index.shape == nb.mask.shape == (4, 4)
    members = [set(row[m].tolist()) for row, m in zip(nb.index, nb.mask)]
    assert members == [{0, 1, 2}, {0, 1, 2, 3}, {0, 1, 2, 3}, {1, 2, 3}]
    np.testing.assert_array_equal(nb.index[:, 0], np.arange(4))  # itself first
    np.testing.assert_array_equal(
        nb.index[~nb.mask], np.array([0, 3])
    )  # padding = itself
    np.testing.assert_array_equal(nb.counts, [3, 4, 4, 3])


def test_mesh_neighborhoods_isolated_vertex_and_duplicate_faces():
    V = np.vstack([SQUARE_V, [[5, 5, 5]]])
    F = np.vstack([SQUARE_F, SQUARE_F[::-1, ::-1]])
    nb = vertex_neighborhoods(V, F)
    assert nb.counts.tolist() == [3, 4, 4, 3, 1]
    assert nb.index[4][nb.mask[4]].tolist() == [4]


def test_knn_neighborhoods():
    V = np.stack([np.arange(10.0) ** 1.1, np.zeros(10), np.zeros(10)], axis=1)
    nb = vertex_neighborhoods(V, None, k=3)
    assert nb.index.shape == (10, 3) and nb.mask.all()
    assert set(nb.index[0].tolist()) == {0, 1, 2}
    assert set(nb.index[5].tolist()) == {4, 5, 6}
    assert vertex_neighborhoods(V, np.zeros((0, 3), int), k=50).index.shape == (10, 10)
    # more coincident points than k: each neighbourhood still contains its own vertex
    same = np.zeros((6, 3))
    nb = vertex_neighborhoods(same, k=2)
    assert all(i in row for i, row in enumerate(nb.index.tolist()))
    with pytest.raises(InputError):
        vertex_neighborhoods(V, k=0)


# --------------------------------------------------------------------- PCA planes


@pytest.mark.parametrize("tilted", [False, True])
@pytest.mark.parametrize("with_faces", [True, False])
def test_plane_has_zero_point_to_plane_distance(tilted, with_faces):
    V, F, _ = grid(9, 8, jitter=0.3)
    normal = np.array([0.0, 0.0, 1.0])
    if tilted:
        V, R = tilt(V, seed=5)
        normal = R @ normal
    d = point_to_plane(V, F if with_faces else None, k=12)
    assert d.shape == (len(V),) and d.dtype == np.float64
    assert np.abs(d).max() <= 1e-12
    N = pca_normals(V, F if with_faces else None, k=12)
    np.testing.assert_allclose(np.abs(N @ normal), 1.0, atol=1e-12)
    if with_faces:  # faces are counter-clockwise seen from +normal
        np.testing.assert_allclose(N @ normal, 1.0, atol=1e-12)


def test_pca_normals_icosphere_radial_and_outward():
    V, F = icosphere(3)
    radial = V / np.linalg.norm(V, axis=1, keepdims=True)
    N = pca_normals(V, F)
    np.testing.assert_allclose(np.linalg.norm(N, axis=1), 1.0, atol=1e-12)
    assert (np.einsum("ij,ij->i", N, radial) > 0.999).all()
    # flipping the orientation of every face flips the normals
    N_flip = pca_normals(V, F[:, ::-1])
    np.testing.assert_allclose(N_flip, -N, atol=1e-12)
    # the one-ring centroid lies inside the sphere: positive distance along the normal
    assert (point_to_plane(V, F) > 0).all()


def test_pca_normals_point_cloud_on_sphere_radial():
    P = np.random.default_rng(0).normal(size=(3000, 3))
    P /= np.linalg.norm(P, axis=1, keepdims=True)
    P = 2.0 * P + [1.0, 2.0, 3.0]
    radial = (P - [1.0, 2.0, 3.0]) / 2.0
    N = pca_normals(P, k=16)
    cos = np.einsum("ij,ij->i", N, radial)
    assert (np.abs(cos) > 0.99).all()
    assert (cos > 0).all()  # centroid heuristic points outward on a sphere


def test_pca_planes_reevaluated_on_moved_vertices():
    V, F = icosphere(2)
    nb = vertex_neighborhoods(V, F)
    A = V * [1.0, 2.0, 0.5] + [0.1, 0.2, 0.3]  # moved vertices, same topology
    normals, centroids = pca_planes(A, nb)
    normals2, centroids2 = pca_planes(A, vertex_neighborhoods(A, F))
    np.testing.assert_allclose(centroids, centroids2, atol=1e-15)
    np.testing.assert_allclose(
        np.abs(np.einsum("ij,ij->i", normals, normals2)), 1.0, atol=1e-12
    )
    expected = np.stack([A[row[m]].mean(0) for row, m in zip(nb.index, nb.mask)])
    np.testing.assert_allclose(centroids, expected, atol=1e-15)
    # the plain (index, mask) tuple works too
    n3, _ = pca_planes(A, (nb.index, nb.mask))
    np.testing.assert_array_equal(n3, normals)


def test_pca_planes_chunking_matches(monkeypatch):
    V, F = icosphere(2)
    nb = vertex_neighborhoods(V, F)
    full = pca_planes(V, nb)
    monkeypatch.setattr(geometry.normals, "_PLANE_CHUNK", 7)
    chunked = pca_planes(V, nb)
    # chunks change the shapes handed to BLAS, whose kernels may then sum in another order
    np.testing.assert_allclose(chunked[0], full[0], rtol=0, atol=1e-14)
    np.testing.assert_allclose(chunked[1], full[1], rtol=0, atol=1e-14)


def test_degenerate_neighbourhoods_are_finite():
    V = np.vstack([SQUARE_V, [[5, 5, 5]]])  # vertex 4 has only itself
    N = pca_normals(V, SQUARE_F)
    d = point_to_plane(V, SQUARE_F)
    assert np.isfinite(N).all() and np.isfinite(d).all()
    np.testing.assert_allclose(np.linalg.norm(N, axis=1), 1.0)
    assert d[4] == 0.0
    line = np.stack([np.arange(5.0), np.zeros(5), np.zeros(5)], axis=1)
    np.testing.assert_allclose(point_to_plane(line, k=3), 0.0, atol=1e-15)


def test_pca_planes_rejects_bad_neighborhoods():
    nb = vertex_neighborhoods(SQUARE_V, SQUARE_F)
    with pytest.raises(InputError):
        pca_planes(SQUARE_V[:3], nb)
    with pytest.raises(InputError):
        pca_planes(SQUARE_V, (nb.index + 10, nb.mask))
    with pytest.raises(InputError):
        pca_planes(SQUARE_V, (nb.index, np.zeros_like(nb.mask)))
    with pytest.raises(InputError):
        pca_planes(SQUARE_V, nb.index)
    with pytest.raises(InputError, match="NaN"):
        pca_normals(np.full((4, 3), np.nan))


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 40), st.integers(1, 4), st.sampled_from([1, 3, 50, 2**20, 2**40]),
       st.integers(0, 2**32 - 1))
def test_unique_rows_is_numpys_unique_by_rows(m, c, top, seed):
    """The same first indices and numbering as np.unique(axis=0), big entries included
    (which take numpy's own way)."""
    rows = np.random.default_rng(seed).integers(0, top, size=(m, c))
    first, inverse = geometry.unique_rows(rows)
    _, want_first, want_inverse = np.unique(rows, axis=0, return_index=True,
                                            return_inverse=True)
    np.testing.assert_array_equal(first, want_first)
    np.testing.assert_array_equal(inverse, want_inverse.reshape(-1))
    assert first.dtype == inverse.dtype == np.int64


def test_unique_rows_refuses_what_is_not_integer_rows():
    with pytest.raises(InputError, match="integer"):
        geometry.unique_rows([[0.5, 1.0]])
    with pytest.raises(InputError, match="integer"):
        geometry.unique_rows([1, 2, 3])
