"""Box scaling and similarities (cagekit.geometry.alignment), and the torch twin of box_scale."""

import numpy as np
import pytest
from builders import random_rotation

from cagekit.errors import InputError
from cagekit.geometry.alignment import Similarity, box_alignment, box_scale, similarity_alignment


def test_box_scale_maps_half_extents_and_keeps_flat_axes():
    flat = np.array([[-1.0, -1, 0], [1, 1, 0]])
    np.testing.assert_allclose(box_scale(flat, flat * 2), [2.0, 2.0, 1.0])
    s = np.array([[-1.0, -0.5, 0.0], [1.0, 0.5, 0.0]])
    t = np.array([[-0.5, -1.0, -1.0], [0.5, 1.0, 1.0]])
    np.testing.assert_allclose(box_scale(s, t), [0.5, 2.0, 1.0])


def test_torch_box_scale_is_the_numpy_one_batched():
    torch = pytest.importorskip("torch")
    from cagekit_learn.alignment import box_scale as box_scale_torch

    rng = np.random.default_rng(3)
    s = rng.uniform(-1, 1, size=(4, 50, 3)) * [1.0, 0.5, 0.8]
    t = rng.uniform(-1, 1, size=(4, 60, 3)) * [0.3, 1.0, 0.7]
    s[2, :, 2] = 0.0  # a flat source keeps 1 on that axis
    got = box_scale_torch(torch.as_tensor(s), torch.as_tensor(t)).numpy()
    expected = np.stack([box_scale(a, b) for a, b in zip(s, t)])
    np.testing.assert_allclose(got, expected, rtol=1e-12)
    assert got[2, 2] == 1.0


def test_similarity_alignment_recovers_a_similarity_and_inverts():
    rng = np.random.default_rng(4)
    P = rng.normal(size=(10, 3))
    A = Similarity(2.5, random_rotation(7), np.array([1.0, 2.0, 3.0]))
    B = similarity_alignment(P, A.apply(P))
    np.testing.assert_allclose(B.rotation, A.rotation, atol=1e-12)
    np.testing.assert_allclose(B.apply(P), A.apply(P), atol=1e-12)
    np.testing.assert_allclose(B.invert(B.apply(P)), P, atol=1e-12)
    np.testing.assert_allclose(B.apply_vectors(P), A.apply(P) - A.translation, atol=1e-12)


def test_box_alignment_matches_centres_and_heights():
    S = np.array([[0, 0, 0], [1, 2, 1.0]])
    T = np.array([[5, 1, 0], [7, 5, 2.0]])
    box = box_alignment(S, T)
    assert box.scale == pytest.approx(2.0)
    np.testing.assert_allclose(box.apply([[0.5, 1, 0.5]]), [[6, 3, 1]])
    with pytest.raises(InputError, match="zero height"):
        box_alignment(S * [1, 0, 1], T)


def test_degenerate_landmarks_are_refused():
    with pytest.raises(InputError, match="one point"):
        similarity_alignment(np.zeros((5, 3)), np.ones((5, 3)))
    line = np.outer(np.arange(5.0), [1.0, 2.0, 0.5])
    with pytest.raises(InputError, match="collinear"):
        similarity_alignment(line, 2 * line)
