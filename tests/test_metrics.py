"""Tests of cagekit.metrics against known answers (docs/architecture.md, "Metrics")."""

import igl
import numpy as np
import pytest
import trimesh
from builders import SEEDS, grid, icosphere
from hypothesis import given, settings
from scipy.spatial.transform import Rotation

from cagekit.errors import InputError
from cagekit.geometry import cotangent_laplacian
from cagekit.geometry.frame import Frame
from cagekit.geometry.sampling import sample_surface
from cagekit.metrics import (
    chamfer,
    chamfers_to,
    dcotlap,
    evaluate,
    part_nonaffinity,
    planarity,
    point_chamfer,
    symmetry_error,
)


def ellipsoid(axes=(1.0, 2.0, 0.5), offset=(0.0, 0.0, 0.0)):
    V, F = icosphere()
    return V * np.asarray(axes) + np.asarray(offset), F


def lattice(n=6, spacing=1.0):
    g = np.arange(n, dtype=float) * spacing
    return np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)


def bend(V, amount=0.3):
    """Non-rigid deformation: bend along x."""
    out = V.copy()
    out[:, 2] += amount * V[:, 0] ** 2
    return out


# ------------------------------------------------------------------------ Chamfer


def test_point_chamfer_identical_sets_is_zero():
    P = np.random.default_rng(0).normal(size=(500, 3))
    assert point_chamfer(P, P) == 0.0
    assert point_chamfer(P, P[::-1]) == 0.0


def test_point_chamfer_translated_copy_is_twice_squared_shift():
    P = lattice()
    t = np.array(
        [0.01, -0.02, 0.015]
    )  # |t| << spacing 1: each point's nearest is its copy
    cd = point_chamfer(P, P + t)
    assert cd == pytest.approx(2 * t @ t, rel=1e-12)


def test_point_chamfer_known_asymmetric_sets_and_symmetry():
    P = np.array([[0.0, 0, 0], [1, 0, 0]])
    Q = np.array([[0.0, 0, 0], [1, 0, 0], [5, 0, 0]])
    # P -> Q: 0; Q -> P: (0 + 0 + 16) / 3. Summed, not halved.
    assert point_chamfer(P, Q) == pytest.approx(16 / 3, rel=1e-15)
    assert point_chamfer(P, Q) == point_chamfer(Q, P)
    rng = np.random.default_rng(1)
    A, B = rng.normal(size=(300, 3)), rng.normal(size=(200, 3)) + 0.5
    assert point_chamfer(A, B) == point_chamfer(B, A)


def test_point_chamfer_rejects_bad_input():
    with pytest.raises(InputError, match="NaN"):
        point_chamfer([[0, 0, np.nan]], [[0, 0, 0]])
    with pytest.raises(InputError, match="no points"):
        point_chamfer(np.zeros((0, 3)), [[0, 0, 0]])
    with pytest.raises(InputError, match="shape"):
        point_chamfer([[0, 0]], [[0, 0, 0]])


def test_sample_surface_mesh_and_clouds():
    V, F = ellipsoid()
    S = sample_surface(V, F, n=1000, seed=3)
    assert S.shape == (1000, 3)
    np.testing.assert_array_equal(S, sample_surface(V, F, n=1000, seed=3))
    # a small cloud is used as it is
    np.testing.assert_array_equal(sample_surface(V, None, n=5000), V)
    np.testing.assert_array_equal(
        sample_surface(V, np.zeros((0, 3), int), n=len(V)), V
    )
    # a large cloud: a seeded subset of distinct points, in their original order
    sub = sample_surface(V, None, n=50, seed=4)
    assert sub.shape == (50, 3)
    np.testing.assert_array_equal(sub, sample_surface(V, None, n=50, seed=4))
    rows = [int(np.flatnonzero((V == p).all(1))[0]) for p in sub]
    assert len(set(rows)) == 50 and rows == sorted(rows)


def test_chamfer_samples_the_two_shapes_independently():
    # Identical shapes get independent samples: CD is the sampling resolution, not 0.
    # For n uniform samples on an area A, E[min |a - b|^2] = A / (pi n) per direction.
    V, F = ellipsoid()
    n = 2000
    expected = 2 * trimesh.Trimesh(V, F, process=False).area / (np.pi * n)
    for seed in range(3):
        cd = chamfer(V, F, V, F, n_samples=n, seed=seed)
        assert 0.7 * expected < cd < 1.3 * expected
    # a barely moved copy (same faces) scores the same resolution, not its tiny shift
    assert chamfer(V, F, bend(V, 1e-4), F, n_samples=n) > 0.7 * expected


def test_chamfer_is_deterministic_per_seed():
    Va, Fa = ellipsoid()
    Vb, Fb = ellipsoid(axes=(1.1, 1.9, 0.6), offset=(0.05, 0, 0))
    ab = chamfer(Va, Fa, Vb, Fb, n_samples=2000, seed=5)
    assert ab > 0
    assert ab == chamfer(Va, Fa, Vb, Fb, n_samples=2000, seed=5)
    assert ab == chamfer(Va.tolist(), Fa, Vb, Fb, n_samples=2000, seed=np.int64(5))
    assert ab != chamfer(Va, Fa, Vb, Fb, n_samples=2000, seed=6)
    # swapping the shapes swaps their streams: equal in distribution, not bit for bit
    assert chamfer(Vb, Fb, Va, Fa, n_samples=2000, seed=5) == pytest.approx(ab, rel=0.1)
    # a mesh against a cloud of its own vertices: small but not zero
    assert 0 < chamfer(Va, Fa, Va, None, n_samples=2000) < 0.05
    for seed in (-1, 1.5, True, None):
        with pytest.raises(InputError, match="seed"):
            chamfer(Va, Fa, Vb, Fb, n_samples=10, seed=seed)


@settings(max_examples=25, deadline=None)
@given(SEEDS, SEEDS)
def test_chamfers_to_is_chamfer_of_each_version(seed, shape_seed):
    """One target sampled once gives each version's chamfer bit for bit (a cloud too)."""
    rng = np.random.default_rng(shape_seed)
    Va, Fa = ellipsoid()
    Vb, Fb = ellipsoid(axes=(1.1, 1.9, 0.6), offset=(0.05, 0, 0))
    versions = [Va, Va * rng.uniform(0.5, 2.0, 3), Va + rng.normal(0, 0.1, Va.shape)]
    for target_faces in (Fb, None):
        got = chamfers_to(versions, Fa, Vb, target_faces, n_samples=300, seed=seed % 1000)
        assert got == [chamfer(V, Fa, Vb, target_faces, n_samples=300, seed=seed % 1000)
                       for V in versions]
    with pytest.raises(InputError, match="seed"):
        chamfers_to(versions, Fa, Vb, Fb, seed=-1)


def test_chamfer_of_translated_plane_adds_twice_squared_shift():
    # A square moved along its normal by t: every nearest neighbour is t away out of the
    # plane plus its in-plane distance, so CD = CD(identical) + 2 t^2 (same streams).
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)
    F = np.array([[0, 1, 2], [1, 3, 2]])
    n = 2000
    same = chamfer(V, F, V, F, n_samples=n, seed=7)
    assert same > 0
    for t in (0.1, 0.5, 2.0):  # sample spacing ~ (1 / n) ** 0.5 = 0.022
        moved = V + [0.0, 0.0, t]
        cd = chamfer(V, F, moved, F, n_samples=n, seed=7)
        assert cd == pytest.approx(same + 2 * t * t, rel=1e-9)


def test_chamfer_decreases_as_the_shape_approaches_the_target():
    Vs, F = ellipsoid()
    Vt, _ = ellipsoid(axes=(1.4, 1.5, 0.9), offset=(0.3, 0.0, 0.0))
    cds = [
        chamfer((1 - s) * Vs + s * Vt, F, Vt, F, n_samples=2000, seed=1)
        for s in (0.0, 0.25, 0.5, 0.75, 1.0)
    ]
    assert all(a > b for a, b in zip(cds, cds[1:])), cds
    assert 0 < cds[-1] < 0.1 * cds[0]


# ----------------------------------------------------------------------- dCotLap


def test_dcotlap_translation_is_zero():
    V, F = ellipsoid()
    assert dcotlap(V, F, V) == 0.0
    assert dcotlap(V, F, V + [3.0, -1.0, 0.25]) <= 1e-20


def test_dcotlap_rotation_is_not_zero_and_matches_definition():
    # L (R V + t - V) = L V (R^T - I): dCotLap is translation- but not rotation-invariant
    V, F = ellipsoid()
    R = Rotation.from_euler("z", 30, degrees=True).as_matrix()
    out = V @ R.T + [0.5, 0.0, -0.2]
    L = cotangent_laplacian(V, F)
    expected = np.mean(((L @ V) @ (R.T - np.eye(3))) ** 2)
    assert dcotlap(V, F, out) == pytest.approx(expected, rel=1e-10)
    assert dcotlap(V, F, out) > 1e-6


def test_dcotlap_nonrigid_bend_is_positive_and_quadratic():
    V, F = ellipsoid()
    d1 = dcotlap(V, F, bend(V, 0.1))
    d2 = dcotlap(V, F, bend(V, 0.2))
    assert d1 > 1e-6
    assert d2 == pytest.approx(4 * d1, rel=1e-10)  # quadratic in the displacement
    D = bend(V, 0.1) - V
    assert dcotlap(V, F, V + D) == pytest.approx(dcotlap(V, F, V - D), rel=1e-12)


def test_dcotlap_ignores_duplicate_faces_and_known_value():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)
    F = np.array([[0, 1, 2], [1, 3, 2]])
    F_dup = np.vstack([F, F[:, ::-1], [[1, 2, 0]]])
    out = V.copy()
    out[0, 2] = 1.0  # lift vertex 0: L @ (out - V) has z-column (-1, .5, .5, 0)
    expected = (1 + 0.25 + 0.25) / 12
    assert dcotlap(V, F, out) == pytest.approx(expected, rel=1e-14)
    assert dcotlap(V, F_dup, out) == dcotlap(V, F, out)


def test_dcotlap_ignores_zero_area_faces():
    # vertex 4 is on the line through vertices 0 and 1: face (0, 1, 4) has zero area
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 0, 0]], dtype=float)
    F = np.array([[0, 1, 2], [1, 3, 2]])
    out = V.copy()
    out[0, 2] = 1.0
    expected = (1 + 0.25 + 0.25) / 15  # vertex 4 is in no face: an empty row of L
    assert dcotlap(V, F, out) == pytest.approx(expected, rel=1e-14)
    assert dcotlap(V, np.vstack([F, [[0, 1, 4]]]), out) == dcotlap(V, F, out)
    assert dcotlap(V, np.vstack([[[4, 1, 0]], F]), out) == dcotlap(V, F, out)
    with pytest.raises(InputError, match="zero area"):
        dcotlap(V, [[0, 1, 4]], out)
    with pytest.raises(InputError, match="zero area"):  # direct callers: still strict
        cotangent_laplacian(V, np.vstack([F, [[0, 1, 4]]]))


@pytest.mark.parametrize("height", [1e-9, 1e-12, 1e-16])
def test_dcotlap_ignores_numerically_collinear_faces(height):
    # vertex 4 lies `height` off the edge (0, 1): the face (0, 1, 4) has a positive area
    # by its cross product, but libigl's cotangents of it are not finite (a real sofa of
    # sweethome3d-furniture has such a face; its deformations could not be measured)
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.3, -height, 0]])
    F = np.array([[0, 1, 2], [1, 3, 2]])
    sliver = np.vstack([F, [[0, 4, 1]]])
    out = V.copy()
    out[0, 2] = 1.0
    assert dcotlap(V, sliver, out) == dcotlap(V, F, out)
    with pytest.raises(InputError, match="not finite"):  # direct callers: still strict
        cotangent_laplacian(V, sliver)


def test_dcotlap_ignores_exactly_collinear_slivers_whatever_libigl_makes_of_them():
    # a vertex on an edge, as a modelling tool splits one: rounding gives libigl's
    # cotangents of the sliver inf for some and finite noise (about 7e7) for others
    V, F = icosphere(2)
    rng = np.random.default_rng(3)
    edges = F[rng.choice(len(F), 30, replace=False)][:, :2]
    t = rng.uniform(0.05, 0.95, (30, 1))
    V2 = np.vstack([V, t * V[edges[:, 0]] + (1 - t) * V[edges[:, 1]]])
    slivers = np.column_stack([edges[:, 0], len(V) + np.arange(30), edges[:, 1]])
    with np.errstate(divide="ignore", invalid="ignore"):
        finite = np.isfinite(igl.cotmatrix_entries(V2, slivers)).all(axis=1)
    assert 0 < finite.sum() < 30  # both kinds are here
    out = np.vstack([bend(V, 0.2), bend(V2[len(V):], 0.2)])
    plain = np.mean(np.square(cotangent_laplacian(V, F) @ (out[:len(V)] - V))) * len(V)
    assert dcotlap(V2, np.vstack([F, slivers]), out) == pytest.approx(plain / len(V2),
                                                                      rel=1e-12)


def test_dcotlap_keeps_a_thin_face_libigl_can_measure():
    # 1e-6 off the edge: cotangents near 1e5, finite and kept
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.3, -1e-6, 0]])
    F = np.array([[0, 1, 2], [1, 3, 2]])
    thin = np.vstack([F, [[0, 4, 1]]])
    out = V.copy()
    out[4, 2] = 1e-3
    assert np.abs(cotangent_laplacian(V, thin).data).max() > 1e4
    assert dcotlap(V, thin, out) == pytest.approx(
        np.mean(np.square(cotangent_laplacian(V, thin) @ (out - V))), rel=1e-12)
    assert dcotlap(V, thin, out) > 0
    assert dcotlap(V, F, out) == 0  # vertex 4 is in no face of F


def test_evaluate_ignores_a_zero_area_face():
    # a duplicated vertex (common in real meshes) and a face on it: zero area
    V, F = ellipsoid()
    V = np.vstack([V, V[:1]])
    j = next(int(v) for v in F[(F == 0).any(axis=1)][0] if v != 0)  # a neighbour of 0
    F_flat = np.vstack([F, [[0, len(V) - 1, j]]])
    tgt = ellipsoid(axes=(1.2, 1.8, 0.7))
    dfm = bend(V, 0.2)
    without = evaluate(V, F, *tgt, dfm, n_samples=1000)
    with_flat = evaluate(V, F_flat, *tgt, dfm, n_samples=1000)
    assert with_flat.dcotlap == pytest.approx(without.dcotlap, rel=1e-12)
    assert without.dcotlap > 0
    assert with_flat.cd == pytest.approx(without.cd, rel=1e-12)
    assert dcotlap(V, F_flat, dfm) == pytest.approx(dcotlap(V, F, dfm), rel=1e-12)


def test_dcotlap_rejects_bad_input():
    V, F = ellipsoid()
    with pytest.raises(InputError, match="vertices"):
        dcotlap(V, F, V[:-1])
    with pytest.raises(InputError, match="faces"):
        dcotlap(V, None, V)
    with pytest.raises(InputError, match="NaN"):
        dcotlap(V, F, np.full_like(V, np.nan))


# ---------------------------------------------------------------------- evaluate


def test_evaluate_keys_and_scaled_values():
    src = ellipsoid()
    tgt = ellipsoid(axes=(1.2, 1.8, 0.7), offset=(4.0, 0.0, 1.0))
    m = evaluate(*src, *tgt, bend(src[0], 0.2), n_samples=1000, seed=2)
    assert set(m.as_dict()) == {"cd", "dcotlap", "cd_x1e2", "dcotlap_x1e3", "n_samples", "seed",
                      "part_nonaffinity_median", "part_nonaffinity_worst", "parts",
                      "planarity_mean_deg", "planarity_p95_deg", "symmetry_axis",
                      "symmetry_error"}
    # the bent ellipsoid: one part, not affine; symmetric about x, and the bend (even in
    # x) keeps that symmetry
    assert m.parts == 1 and m.part_nonaffinity_worst > 1e-3
    assert m.symmetry_axis == "x" and m.symmetry_error < 1e-12
    assert isinstance(m.cd, float) and isinstance(m.dcotlap, float)
    assert m.cd_x1e2 == pytest.approx(m.cd * 100)
    assert m.dcotlap_x1e3 == pytest.approx(m.dcotlap * 1000)
    assert m.n_samples == 1000 and m.seed == 2
    assert m.cd > 0 and m.dcotlap > 0


def test_evaluate_target_as_deformed_gives_sampling_resolution_cd():
    src = ellipsoid()
    tgt = ellipsoid(axes=(1.5, 1.0, 0.8), offset=(10.0, -3.0, 2.0))  # same topology
    m = evaluate(*src, *tgt, tgt[0], n_samples=2000)
    # same surface in the same frame, sampled with two streams: the resolution only
    Vt_n = Frame.of(tgt[0]).to_unit(tgt[0])
    assert m.cd == pytest.approx(chamfer(Vt_n, tgt[1], Vt_n, tgt[1], n_samples=2000),
                                 rel=1e-12)
    assert 0 < m.cd < 5e-3
    assert m.dcotlap > 0  # the target is a non-rigid deformation of the source


def test_evaluate_similar_copy_scores_zero_distortion():
    # deformed = uniformly scaled and translated source, used also as the target: both
    # frames normalise it back onto the normalised source
    src = ellipsoid()
    moved = (3.0 * src[0] + [5.0, -2.0, 7.0], src[1])
    m = evaluate(*src, *moved, moved[0], n_samples=2000)
    assert 0 < m.cd < 5e-3  # the sampling resolution only
    assert m.dcotlap <= 1e-20


def test_evaluate_pure_translation_has_zero_distortion():
    src = ellipsoid()
    shifted = (src[0] + [0.3, 0.0, 0.0], src[1])
    m = evaluate(*src, *src, shifted[0], n_samples=2000)
    assert m.dcotlap <= 1e-20
    # CD is computed in the target's frame: the shift is divided by the target's scale
    scale = Frame.of(src[0]).scale
    assert m.cd > 0.5 * (0.3 / scale) ** 2


def test_evaluate_uses_target_frame_for_deformed_and_own_frame_for_source():
    src = ellipsoid()
    tgt = ellipsoid(axes=(1.3, 1.7, 0.9), offset=(1.0, 1.0, 1.0))
    dfm = (bend(src[0], 0.2), src[1])
    base = evaluate(*src, *tgt, dfm[0], n_samples=1000)
    # moving and scaling the source alone changes nothing (it is normalised on its own)
    src2 = (2.5 * src[0] - 4.0, src[1])
    again = evaluate(*src2, *tgt, dfm[0], n_samples=1000)
    assert again.cd == pytest.approx(base.cd, rel=1e-12)
    assert again.dcotlap == pytest.approx(base.dcotlap, rel=1e-9)
    # the same similarity applied to target and deformed changes nothing
    s, t = 7.0, np.array([-2.0, 3.0, 0.5])
    sim = evaluate(
        *src, s * tgt[0] + t, tgt[1], s * dfm[0] + t, n_samples=1000
    )
    assert sim.cd == pytest.approx(base.cd, rel=1e-9)
    assert sim.dcotlap == pytest.approx(base.dcotlap, rel=1e-9)
    # scaling only the deformed shape changes both figures (it is not renormalised)
    big = evaluate(*src, *tgt, 3.0 * dfm[0], n_samples=1000)
    assert big.cd > 2 * base.cd and big.dcotlap > base.dcotlap


def test_evaluate_is_deterministic_and_seeded():
    src = ellipsoid()
    tgt = ellipsoid(axes=(1.2, 1.8, 0.7))
    dfm = (bend(src[0], 0.1), src[1])
    a = evaluate(*src, *tgt, dfm[0], n_samples=1000, seed=11)
    assert a == evaluate(*src, *tgt, dfm[0], n_samples=1000, seed=11)
    b = evaluate(*src, *tgt, dfm[0], n_samples=1000, seed=12)
    assert a.cd != b.cd and a.dcotlap == b.dcotlap


def test_evaluate_point_cloud_target():
    src = ellipsoid()
    tgt_mesh = ellipsoid(axes=(1.2, 1.8, 0.7))
    cloud = trimesh.Trimesh(*tgt_mesh, process=False).sample(3000, seed=0)
    dfm = (tgt_mesh[0], src[1])
    m_cloud = evaluate(*src, cloud, None, dfm[0], n_samples=3000)
    assert 0 < m_cloud.cd < 0.01  # same surface, different samples
    assert evaluate(*src, cloud, np.zeros((0, 3), int), dfm[0], n_samples=3000) == m_cloud


def test_evaluate_rejects_bad_input():
    src = ellipsoid()
    tgt = ellipsoid(axes=(1.2, 1.8, 0.7))
    with pytest.raises(InputError, match="vertices"):
        evaluate(*src, *tgt, src[0][:-1])
    with pytest.raises(InputError, match="faces"):
        evaluate(src[0], None, *tgt, src[0])
    with pytest.raises(InputError, match="zero extent"):
        evaluate(*src, np.ones((4, 3)), None, src[0])
    with pytest.raises(InputError, match="NaN"):
        evaluate(*src, *tgt, np.full_like(src[0], np.nan))


# -------------------------------------------------------------------- structure


def bar(n=41, length=4.0, width=0.2):
    """A closed box bar along x, ``n`` stations of 4 vertices each (ends capped)."""
    x = np.linspace(0.0, length, n)
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * width / 2
    V = np.array([[xi, y, z] for xi in x for y, z in corners])
    F = []
    for i in range(n - 1):
        for k in range(4):
            a, b = 4 * i + k, 4 * i + (k + 1) % 4
            F += [[a, b, b + 4], [a, b + 4, a + 4]]
    last = 4 * (n - 1)
    F += [[0, 2, 1], [0, 3, 2], [last, last + 1, last + 2], [last, last + 2, last + 3]]
    return V, np.array(F)


def two_parts():
    """A bar (164 vertices) and an icosahedral ball beside it (42): two components."""
    Vb, Fb = bar()
    Vi, Fi = icosphere(1)
    return np.vstack([Vb, Vi * 0.3 + [2.0, 2.0, 0.0]]), np.vstack([Fb, Fi + len(Vb)])


@settings(max_examples=25, deadline=None)
@given(seed=SEEDS)
def test_an_affine_map_keeps_every_part_affine_and_every_plane_planar(seed):
    V, F = two_parts()
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(3, 3))
    A += np.eye(3) * (abs(np.linalg.det(A)) ** (1 / 3) + 1.0)  # well conditioned
    out = V @ A.T + rng.normal(size=3)
    parts = part_nonaffinity(V, F, out)
    assert parts["parts"] == 2 and parts["worst"] < 1e-10
    flat = planarity(V, F, out)
    assert flat["pairs"] > 0 and flat["p95_deg"] < 1e-6


def test_each_part_moved_by_its_own_affine_map_scores_zero():
    V, F = two_parts()
    out = V.copy()
    ball = np.arange(len(V)) >= 164
    out[ball] = V[ball] @ np.diag([2.0, 0.5, 1.0]) + 3.0
    out[~ball] = V[~ball] @ Rotation.from_euler("z", 40, degrees=True).as_matrix().T
    assert part_nonaffinity(V, F, out)["worst"] < 1e-12


def test_parts_split_at_seams_are_measured_as_one():
    # every face with vertices of its own (a seam along every edge, as files with UVs
    # have): still two parts, each moved by an affine map of its own scores 0
    V, F = two_parts()
    out = V.copy()
    ball = np.arange(len(V)) >= 164
    out[ball] = V[ball] @ np.diag([2.0, 0.5, 1.0]) + 3.0
    Vs, Fs = V[F.ravel()], np.arange(3 * len(F)).reshape(-1, 3)
    split = part_nonaffinity(Vs, Fs, out[F.ravel()])
    assert split["parts"] == 2
    assert split["worst"] < 1e-12


def test_a_bent_bar_scores_the_residual_of_its_parabola():
    # z += k x^2 on x in [0, 4]: the best affine fit leaves k (x^2 - linear fit), whose
    # RMS over the stations is computed directly here; over the bent bar's diagonal
    V, F = bar(n=401)
    k = 0.05
    out = V.copy()
    out[:, 2] += k * V[:, 0] ** 2
    x = V[:, 0]
    coeffs = np.polyfit(x, k * x ** 2, 1)
    rms = np.sqrt(np.mean((k * x ** 2 - np.polyval(coeffs, x)) ** 2))
    expected = rms / np.linalg.norm(np.ptp(out, axis=0))
    assert part_nonaffinity(V, F, out)["worst"] == pytest.approx(expected, rel=1e-9)
    # the continuous answer: k L^2 / (6 sqrt 5) for L = 4
    assert rms == pytest.approx(k * 16 / (6 * np.sqrt(5)), rel=0.01)


def test_the_median_is_weighted_by_part_size_and_small_parts_are_skipped():
    V, F = two_parts()
    out = V.copy()
    out[:164, 2] += 0.05 * V[:164, 0] ** 2           # the bar (164 vertices) bent
    bent = part_nonaffinity(V, F, out)
    assert bent["median"] == bent["worst"] > 1e-3    # the bar outweighs the ball (42)
    out2 = V.copy()
    out2[164:] += 0.05 * np.random.default_rng(0).normal(size=(42, 3))  # ball jittered
    jittered = part_nonaffinity(V, F, out2)
    assert jittered["median"] < 1e-12 < jittered["worst"]
    # with parts of 50 vertices or more only the bar counts
    only_bar = part_nonaffinity(V, F, out2, min_vertices=50)
    assert only_bar["parts"] == 1 and only_bar["worst"] < 1e-12


def test_a_folded_plate_turns_by_the_fold_angle_along_the_crease():
    # a flat 9 x 6 grid folded 30 degrees about the line x = 4: the face pairs across the
    # crease turn by 30, every other pair by 0
    V, F, _ = grid(9, 6)
    out = V.copy()
    right = V[:, 0] > 4
    a = np.radians(30)
    out[right, 0] = 4 + (V[right, 0] - 4) * np.cos(a)
    out[right, 2] = (V[right, 0] - 4) * np.sin(a)
    flat = planarity(V, F, out)
    crease = 5                                       # the grid's cells along x = 4
    assert flat["mean_deg"] * flat["pairs"] == pytest.approx(30 * crease, rel=1e-9)
    assert flat["p95_deg"] < 1e-9                    # 5 of 123 pairs turned


def test_planarity_ignores_regions_that_were_curved():
    V, F = icosphere(2)                               # no two faces coplanar
    assert planarity(V, F, bend(V))["pairs"] == 0


def test_symmetry_is_found_kept_by_axis_scaling_and_lost_by_a_bend():
    V, F = bar()
    V = V - [2.0, 0.0, 0.0]                           # symmetric about x = 0
    kept = symmetry_error(V, V * [2.0, 1.0, 3.0])
    assert kept["axis"] == "x" and kept["error"] < 1e-12
    lopsided = V.copy()
    lopsided[:, 2] += 0.1 * np.maximum(V[:, 0], 0) ** 2
    assert symmetry_error(V, lopsided)["error"] > 1e-2
    skew = V.copy()
    skew[V[:, 0] > 1.5, 1] += 0.3                     # one end offset along y: the x and
    assert symmetry_error(skew, skew)["axis"] == "z"  # y symmetries are gone, z's is not
    cloud = np.random.default_rng(1).normal(size=(50, 3))
    assert symmetry_error(cloud, cloud) is None


def test_conformal_distortion_known_answers():
    from cagekit.metrics import conformal_distortion

    V, F = icosphere()
    rng = np.random.default_rng(3)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    similar = 2.5 * V @ q.T + [1.0, -2.0, 3.0]
    assert conformal_distortion(V, F, similar)["max"] == pytest.approx(1.0, abs=1e-9)
    # a flat face stretched 3x along x: ratio 3 whatever its shape
    tri = np.array([[0, 0, 0], [1, 0.2, 0], [0.3, 1, 0.0]])
    one = np.array([[0, 1, 2]])
    assert conformal_distortion(tri, one, tri * [3.0, 1, 1])["mean"] == pytest.approx(3.0)
    flat = tri * [1.0, 0.0, 1.0]  # collapsed onto the x axis
    collapsed = conformal_distortion(tri, one, flat)
    assert collapsed["max"] == np.inf and collapsed["p95"] == np.inf  # not NaN
