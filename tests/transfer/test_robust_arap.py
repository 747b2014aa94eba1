"""A deformed mesh made as rigid as possible, trusting a proposal where it agrees
(cagekit.transfer.robust_arap)."""

import numpy as np
import pytest
from builders import SEEDS, bumpy_blob, grid, random_rotation
from hypothesis import given, settings
from hypothesis import strategies as st

from cagekit.errors import InputError
from cagekit.transfer.robust_arap import robust_arap, strain_trust


@settings(max_examples=25, deadline=None)
@given(seed=SEEDS, scale=st.floats(0.2, 5.0))
def test_a_similar_proposal_comes_back_unchanged(seed, scale):
    V, F = bumpy_blob(subdivisions=2)
    R = random_rotation(seed)
    t = np.random.default_rng(seed).normal(size=3)
    P = scale * V @ R.T + t
    out = robust_arap(V, F, P, sigma=0.01, scale=scale)
    np.testing.assert_allclose(out.vertices, P, atol=1e-9 * max(scale, 1.0))
    np.testing.assert_allclose(out.trust, 1.0, atol=1e-12)


def test_a_patch_that_follows_the_wrong_part_rejoins_its_neighbours():
    # a sheet turned 30 degrees; a 3 x 3 patch of it proposed 2 units away (it followed
    # another part): the result turns the patch with the sheet and stops trusting it
    V, F, _ = grid(12, 10)
    a = np.radians(30)
    R = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    truth = V @ R.T
    patch = (np.abs(V[:, 0] - 5) <= 1) & (np.abs(V[:, 1] - 4) <= 1)
    P = truth.copy()
    P[patch] += [0.0, 0.0, 2.0]
    out = robust_arap(V, F, P, sigma=0.1, iterations=20)
    assert np.linalg.norm(out.vertices - truth, axis=1).max() < 0.1
    # the ring around the patch shares its torn edges and stays doubted too (strain_trust)
    ring = np.zeros(len(V), bool)
    for a, b in F[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2):
        ring[a] |= patch[b]
        ring[b] |= patch[a]
    assert out.trust[patch].max() < 0.05 and out.trust[~patch & ~ring].min() > 0.5
    # trusted without reweighting (sigma huge), the patch would stay lifted
    plain = robust_arap(V, F, P, sigma=1e6, iterations=20)
    assert plain.vertices[patch, 2].mean() > 0.5


@pytest.mark.parametrize("half, lift, most", [(0, 0.5, 0.1), (1, 2.0, 1.0)])
def test_a_trusted_shard_among_doubted_points_is_not_followed(half, lift, most):
    # a doubted patch of a sheet (a mended region) whose proposal stays with the sheet, but
    # a point (or a 3 x 3 group) of it fully trusted (its own coordinates looked ordinary)
    # proposed off the sheet: followed by full trust, it agrees with its proposal, keeps
    # the trust and draws its doubted neighbours out into a spike (without strain_trust:
    # 0.25 of the 0.5 for the point, 1.9 of the 2 for the group); its torn edges doubt it
    V, F, _ = grid(12, 10)
    patch = (np.abs(V[:, 0] - 5) <= 3) & (np.abs(V[:, 1] - 4) <= 3)
    shard = (np.abs(V[:, 0] - 5) <= half) & (np.abs(V[:, 1] - 4) <= half)
    P = V.copy()
    P[shard, 2] += lift
    out = robust_arap(V, F, P, sigma=0.1, confidence=np.where(patch & ~shard, 0.05, 1.0))
    assert np.abs(out.vertices[:, 2]).max() < most


def test_strain_trust_doubts_the_ends_of_torn_edges_only():
    V, F = bumpy_blob(subdivisions=2)
    P = 2.0 * V @ random_rotation(2).T + 1.0
    E = np.unique(np.sort(F[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1), axis=0)
    np.testing.assert_allclose(strain_trust(V, P, E, sigma=0.01, scale=2.0), 1.0)
    P[7] += 1.0
    t = strain_trust(V, P, E, sigma=0.01, scale=2.0)
    ends = np.unique(E[(E == 7).any(axis=1)])
    assert t[ends].max() < 0.01 and np.allclose(np.delete(t, ends), 1.0)


def test_low_confidence_points_follow_their_neighbours():
    # the sheet's row y = 0 proposed 0.05 off the plane: trusted, it keeps most of that
    # (0.05 is within sigma); with little confidence it mostly returns to the sheet (the
    # edge can still bend a little at no cost to rigidity)
    V, F, _ = grid(8, 8)
    row = V[:, 1] == 0
    P = V.copy()
    P[row, 2] += 0.05
    trusted = robust_arap(V, F, P, sigma=0.1).vertices
    doubted = robust_arap(V, F, P, sigma=0.1,
                          confidence=np.where(row, 1e-3, 1.0)).vertices
    assert trusted[row, 2].mean() > 0.02
    assert np.abs(doubted[row, 2]).max() < 0.3 * trusted[row, 2].mean()


def test_separate_components_follow_their_own_proposals():
    V, F = bumpy_blob(subdivisions=1)
    n = len(V)
    V2 = np.vstack([V, V + [5.0, 0, 0]])
    F2 = np.vstack([F, F + n])
    P = np.vstack([V @ random_rotation(1).T, (V + [5.0, 0, 0]) + [0.0, 3.0, 0.0]])
    np.testing.assert_allclose(robust_arap(V2, F2, P, sigma=0.05).vertices, P, atol=1e-9)


def test_the_result_is_nearer_rigid_than_a_noisy_proposal():
    V, F = bumpy_blob(subdivisions=2)
    R = random_rotation(4)
    truth = V @ R.T
    P = truth + np.random.default_rng(4).normal(scale=0.01, size=V.shape)
    out = robust_arap(V, F, P, sigma=0.05).vertices

    def edge_error(X):
        e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
        return np.abs(np.linalg.norm(X[e[:, 0]] - X[e[:, 1]], axis=1)
                      - np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)).mean()

    assert edge_error(out) < 0.75 * edge_error(P)
    assert np.abs(out - truth).mean() < np.abs(P - truth).mean()


def test_a_point_cloud_is_returned_as_proposed():
    V = np.random.default_rng(0).normal(size=(10, 3))
    P = V + 1.0
    out = robust_arap(V, np.zeros((0, 3), int), P, sigma=0.1)
    np.testing.assert_array_equal(out.vertices, P)


@pytest.mark.parametrize("kwargs, match", [
    ({"proposal": np.zeros((3, 3))}, "proposal has shape"),
    ({"sigma": 0.0}, "must be positive"),
    ({"scale": -1.0}, "must be positive"),
    ({"confidence": np.zeros(4)}, "confidence must be"),
    ({"proposal": np.full((4, 3), np.nan)}, "proposal"),
])
def test_bad_arguments_are_refused(kwargs, match):
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    args = {"proposal": V, "sigma": 0.1, **kwargs}
    with pytest.raises(InputError, match=match):
        robust_arap(V, F, args.pop("proposal"), **args)


def test_strain_trust_refuses_bad_input():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    E = np.array([[0, 1], [1, 2]])
    for kwargs, problem in (({"sigma": 0.0}, "sigma must be a positive"),
                            ({"sigma": float("nan")}, "sigma must be a positive"),
                            ({"sigma": 1.0, "scale": -1.0}, "scale must be a positive")):
        with pytest.raises(InputError, match=problem):
            strain_trust(V, V, E, **kwargs)
    with pytest.raises(InputError, match="one shape"):
        strain_trust(V, V[:2], E, sigma=1.0)
    with pytest.raises(InputError, match="outside 0..2"):
        strain_trust(V, V, np.array([[0, 3]]), sigma=1.0)
