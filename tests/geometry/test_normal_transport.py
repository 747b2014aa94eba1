"""Tests of carrying normals through a deformation (cagekit.geometry.normal_transport)."""

import numpy as np
import pytest
from builders import SEEDS
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from cagekit.errors import InputError
from cagekit.geometry.normal_transport import transported_normals


def _soup(rng, n=20, m=30):
    V = rng.normal(size=(n, 3))
    F = np.array([rng.choice(n, 3, replace=False) for _ in range(m)])
    return V, F


def _unit(X):
    return X / np.linalg.norm(X, axis=-1, keepdims=True)


@settings(max_examples=30, deadline=None)
@given(seed=SEEDS, scale=st.floats(0.01, 100.0))
def test_a_similarity_rotates_every_normal(seed, scale):
    rng = np.random.default_rng(seed)
    V0, F = _soup(rng)
    R = Rotation.random(random_state=seed % 2**32).as_matrix()
    V1 = scale * V0 @ R.T + rng.normal(size=3)
    N = rng.normal(size=(len(F), 3, 3))
    groups = np.arange(3 * len(F)).reshape(-1, 3)
    out = transported_normals(V0, V1, F, N, groups)
    np.testing.assert_allclose(out, _unit(N.reshape(-1, 3) @ R.T), atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(seed=SEEDS)
def test_a_face_normal_becomes_the_new_face_normal_under_any_linear_map(seed):
    rng = np.random.default_rng(seed)
    V0, F = _soup(rng)
    A = rng.normal(size=(3, 3))
    if abs(np.linalg.det(A)) < 1e-2:
        A += 2 * np.eye(3)
    V1 = V0 @ A.T
    before = np.cross(V0[F[:, 1]] - V0[F[:, 0]], V0[F[:, 2]] - V0[F[:, 0]])
    after = np.cross(V1[F[:, 1]] - V1[F[:, 0]], V1[F[:, 2]] - V1[F[:, 0]])
    groups = np.repeat(np.arange(len(F))[:, None], 3, axis=1)  # flat shading: one a face
    out = transported_normals(V0, V1, F, np.repeat(before[:, None], 3, axis=1), groups)
    np.testing.assert_allclose(out, _unit(after), atol=1e-8)


def test_a_shared_normal_is_the_area_weighted_mean_and_degenerate_faces_do_not_count():
    V0 = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [2, 0, 0]])
    F = np.array([[0, 1, 2], [0, 2, 3], [0, 1, 4]])  # the last one has no area
    V1 = V0.copy()
    N = np.tile(_unit(np.array([1.0, 0.0, 1.0])), (3, 3, 1))
    groups = np.zeros((3, 3), dtype=int)
    # at rest every image is the normal itself: the mean is that normal
    np.testing.assert_allclose(transported_normals(V0, V1, F, N, groups)[0], N[0, 0],
                               atol=1e-12)
    # a group of degenerate triangles only keeps its first normal, normalised
    lone = transported_normals(V0, V1, F[2:], 3 * N[2:], [[0, 0, 0]])
    np.testing.assert_allclose(lone[0], N[0, 0], atol=1e-12)


def test_corners_without_a_normal_are_skipped():
    V0 = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    N = np.array([[[0.0, 0, 1], [0, 0, 0], [0, 0, 0]]])
    out = transported_normals(V0, V0 * 2, [[0, 1, 2]], N, [[0, -1, -1]])
    np.testing.assert_allclose(out, [[0.0, 0.0, 1.0]], atol=1e-12)


def test_bad_input_is_refused():
    V = np.eye(3)
    with pytest.raises(InputError):
        transported_normals(V, V[:2], [[0, 1, 2]], np.zeros((1, 3, 3)), [[0, 0, 0]])
    with pytest.raises(InputError):
        transported_normals(V, V, [[0, 1, 3]], np.zeros((1, 3, 3)), [[0, 0, 0]])
    with pytest.raises(InputError):
        transported_normals(V, V, [[0, 1, 2]], np.zeros((2, 3, 3)), [[0, 0, 0]])
    with pytest.raises(InputError):
        transported_normals(V, V, [[0, 1, 2]], np.zeros((1, 3, 3)), [[0, -2, 0]])


def test_smooth_normals_of_a_stretched_sphere_become_the_ellipsoid_s():
    # a unit sphere's smooth normals (its points) carried through x -> 2x: the result is
    # the ellipsoid's true normal (x / 4, y, z), normalised, to the mesh's resolution;
    # the untouched normals would be off by up to 19 degrees (recomputed ones: 0.3)
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=4)
    V0, F = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    V1 = V0 * [2.0, 1.0, 1.0]
    out = transported_normals(V0, V1, F, V0[F], F)
    truth = _unit(V1 * [0.25, 1.0, 1.0])
    angle = np.degrees(np.arccos(np.clip((out * truth).sum(axis=1), -1, 1)))
    before = np.degrees(np.arccos(np.clip((V0 * truth).sum(axis=1), -1, 1)))
    assert angle.max() < 1.0 and before.max() > 15.0
