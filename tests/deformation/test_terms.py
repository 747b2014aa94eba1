"""Tests of cagekit.deformation.terms: exact gradients (finite differences) and identities
of every term."""

import warnings

import numpy as np
import pytest
import scipy.sparse
from builders import SEEDS, deformed, icosphere, nn_margin
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from cagekit.deformation.terms import (
    ShapeReference,
    cage_symmetry_loss,
    chamfer_loss,
    detail_loss,
    detail_matrix,
    landmark_loss,
    laplacian_loss,
    mirror,
    mirror_partners,
    mvc_loss,
    normal_loss,
    p2f_loss,
    part_affinity_loss,
    part_affinity_matrix,
    part_bases,
    partial_chamfer_loss,
    shape_losses,
    shape_reference,
    symmetry_loss,
)
from cagekit.errors import InputError
from cagekit.geometry import cotangent_laplacian, vertex_neighborhoods
from cagekit.metrics import dcotlap, point_chamfer

H = 1e-6  # finite-difference step
RTOL = 1e-6  # allowed error, relative to max |grad|


def numeric_grad(f, X, h=H):
    """Central finite differences of the scalar ``f`` at every entry of ``X``."""
    X = np.array(X, dtype=np.float64)
    G = np.zeros_like(X)
    for i in np.ndindex(X.shape):
        old = X[i]
        X[i] = old + h
        up = f(X)
        X[i] = old - h
        down = f(X)
        X[i] = old
        G[i] = (up - down) / (2 * h)
    return G


def assert_grad(loss, X, h=H, rtol=RTOL):
    """``loss(X) -> (value, grad)``: the analytic gradient matches finite differences."""
    value, grad = loss(np.array(X))
    assert isinstance(value, float) and np.isfinite(value)
    assert grad.shape == np.shape(X) and grad.dtype == np.float64
    num = numeric_grad(lambda Y: loss(Y)[0], X, h)
    scale = np.abs(grad).max()
    assert scale > 0, "degenerate check: zero gradient"
    err = np.abs(num - grad).max()
    assert err <= rtol * scale, f"gradient error {err:.3g} vs max |grad| {scale:.3g}"
    return value, grad


def rest_shape(seed=0, subdivisions=2):
    """Noisy, anisotropically scaled icosphere: (rest positions, faces)."""
    V, F = icosphere(subdivisions)
    rng = np.random.default_rng(seed)
    return V * [1.0, 0.7, 1.4] + 0.02 * rng.standard_normal(V.shape), F


def one_ring_ref(X0, F):
    nb = vertex_neighborhoods(X0, F)
    return shape_reference(X0, own=np.arange(len(X0)), index=nb.index, mask=nb.mask)


def knn_ref(X0, k=8):
    nb = vertex_neighborhoods(X0, None, k=k)
    return shape_reference(X0, own=np.arange(len(X0)), index=nb.index, mask=nb.mask)


def subset_ref(X0, F, seed=3, rows=25):
    nb = vertex_neighborhoods(X0, F)
    own = np.sort(np.random.default_rng(seed).choice(len(X0), rows, replace=False))
    return shape_reference(X0, own=own, index=nb.index[own], mask=nb.mask[own])


def shape_refs():
    """(name, rest positions, reference) for the three kinds of neighbourhood."""
    X0, F = rest_shape()
    return [
        ("one-ring", X0, one_ring_ref(X0, F)),
        ("knn", X0, knn_ref(X0)),
        ("subset", X0, subset_ref(X0, F)),
    ]


SHAPE_REFS = shape_refs()
SHAPE_IDS = [name for name, _, _ in SHAPE_REFS]


# ------------------------------------------------------------------------------ Chamfer


@settings(max_examples=30)
@given(seed=SEEDS, s=st.integers(1, 12), t=st.integers(1, 12))
def test_chamfer_gradient_matches_finite_differences(seed, s, t):
    rng = np.random.default_rng(seed)
    P = rng.uniform(-1, 1, (s, 3))
    Q = rng.uniform(-1, 1, (t, 3))
    assume(nn_margin(P, Q) > 1e-4)  # away from nearest-neighbour ties
    assert_grad(lambda X: chamfer_loss(X, Q), P)


def test_chamfer_gradient_with_shared_tree_and_many_to_one():
    # many P points share one nearest Q point (and vice versa): the bincount paths
    rng = np.random.default_rng(11)
    P = rng.uniform(-1, 1, (25, 3))
    Q = rng.uniform(-0.3, 0.3, (4, 3)) + [2.0, 0, 0]
    tree = cKDTree(Q)
    assert nn_margin(P, Q) > 1e-4
    value, grad = assert_grad(lambda X: chamfer_loss(X, Q, tree), P)
    assert value == pytest.approx(chamfer_loss(P, Q)[0], rel=1e-14)
    np.testing.assert_allclose(grad, chamfer_loss(P, Q)[1], rtol=1e-14, atol=0)


def test_chamfer_known_value():
    value, grad = chamfer_loss(np.array([[0.0, 0, 0]]), np.array([[0.0, 0, 2]]))
    assert value == pytest.approx(8.0, rel=1e-15)
    np.testing.assert_allclose(grad, [[0.0, 0.0, -8.0]], rtol=1e-15, atol=1e-15)
    # two P points, one Q point: mean over P of 1 and 9 -> 5; Q's nearest (x=1) -> 1
    P = np.array([[1.0, 0, 0], [3.0, 0, 0]])
    value, grad = chamfer_loss(P, np.zeros((1, 3)))
    assert value == pytest.approx(6.0)
    np.testing.assert_allclose(grad, [[1.0 + 2.0, 0, 0], [3.0, 0, 0]])


def test_chamfer_of_a_set_with_itself_is_zero():
    P = np.random.default_rng(2).uniform(-1, 1, (40, 3))
    value, grad = chamfer_loss(P, P.copy())
    assert value == 0.0
    np.testing.assert_array_equal(grad, 0.0)


@settings(max_examples=20)
@given(seed=SEEDS, s=st.integers(1, 30), t=st.integers(1, 30))
def test_chamfer_equals_metric(seed, s, t):
    rng = np.random.default_rng(seed)
    P = rng.normal(size=(s, 3))
    Q = rng.normal(size=(t, 3)) + 0.5
    value, _ = chamfer_loss(P, Q)
    assert value == pytest.approx(point_chamfer(P, Q), rel=1e-12)
    assert value == pytest.approx(chamfer_loss(Q, P)[0], rel=1e-12)  # symmetric


# ----------------------------------------------------------------------------- landmarks


def test_landmark_hand_computation():
    P = np.array([[0.0, 0, 0], [1, 2, 3], [-1, 0, 1]])
    T = np.array([[1.0, 0, 0], [1, 2, 3], [1, 1, -1]])
    value, grad = landmark_loss(P, T)
    assert value == pytest.approx((1.0 + 0.0 + (4 + 1 + 4)) / 3)
    np.testing.assert_allclose(grad, 2.0 * (P - T) / 3)
    assert landmark_loss(T, T) == (0.0, pytest.approx(np.zeros((3, 3))))


def test_landmark_gradient():
    rng = np.random.default_rng(4)
    T = rng.normal(size=(7, 3))
    assert_grad(lambda X: landmark_loss(X, T), rng.normal(size=(7, 3)))


# ------------------------------------------------------------------------------ symmetry


def test_mirror_is_an_involution_and_flips_one_axis():
    P = np.random.default_rng(6).normal(size=(10, 3))
    before = P.copy()
    for a, axis in enumerate("xyz"):
        M = mirror(P, axis)
        np.testing.assert_array_equal(mirror(M, axis), P)
        np.testing.assert_array_equal(M[:, a], -P[:, a])
        np.testing.assert_array_equal(np.delete(M, a, axis=1), np.delete(P, a, axis=1))
    np.testing.assert_array_equal(P, before)  # input not modified


@pytest.mark.parametrize("axis", ["w", "X", "", 0, None])
def test_mirror_rejects_bad_axis(axis):
    P = np.zeros((2, 3))
    with pytest.raises(InputError):
        mirror(P, axis)
    with pytest.raises(InputError):
        symmetry_loss(P, axis)


@settings(max_examples=25)
@given(seed=SEEDS, s=st.integers(1, 12), axis=st.sampled_from("xyz"))
def test_symmetry_gradient_matches_finite_differences(seed, s, axis):
    P = np.random.default_rng(seed).uniform(-1, 1, (s, 3))
    assume(nn_margin(P, mirror(P, axis)) > 1e-4)
    assert_grad(lambda X: symmetry_loss(X, axis), P)


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_symmetry_gradient_each_axis(axis):
    P = np.random.default_rng({"x": 7, "y": 8, "z": 9}[axis]).uniform(-1, 1, (15, 3))
    assert nn_margin(P, mirror(P, axis)) > 1e-4
    value, _ = assert_grad(lambda X: symmetry_loss(X, axis), P)
    assert value == pytest.approx(point_chamfer(P, mirror(P, axis)), rel=1e-12)


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_symmetry_zero_for_mirror_symmetric_set(axis):
    P = np.random.default_rng(8).uniform(-1, 1, (20, 3))
    S = np.concatenate([P, mirror(P, axis)])
    value, grad = symmetry_loss(S, axis)
    assert value == 0.0
    np.testing.assert_array_equal(grad, 0.0)
    assert symmetry_loss(P, axis)[0] > 1e-3  # not symmetric
    # symmetric about x is generally not symmetric about the other axes
    other = "y" if axis != "y" else "z"
    assert symmetry_loss(S, other)[0] > 1e-3


def test_cage_symmetry_gradient_and_zero_for_symmetric_motion():
    rng = np.random.default_rng(9)
    half = rng.uniform(0.1, 1, (6, 3))
    C_ref = np.concatenate([half, mirror(half, "x")])
    partner, offset = mirror_partners(C_ref, "x")
    np.testing.assert_array_equal(partner, np.r_[np.arange(6, 12), np.arange(6)])
    np.testing.assert_allclose(offset, 0.0, atol=1e-15)
    # a symmetric motion (a scale along y) costs nothing; a random one does
    value, grad = cage_symmetry_loss(C_ref * [1, 2, 1], partner, offset, "x")
    assert value == pytest.approx(0.0, abs=1e-28)
    np.testing.assert_allclose(grad, 0.0, atol=1e-14)
    C = C_ref + 0.1 * rng.normal(size=C_ref.shape)
    assert_grad(lambda X: cage_symmetry_loss(X, partner, offset, "x"), C)


# ----------------------------------------------------------------------------- Laplacian


@pytest.fixture(scope="module")
def cage_laplacian():
    V, F = icosphere(1)
    V = V * [1.0, 0.8, 1.2]
    return V, cotangent_laplacian(V, F)


def test_laplacian_gradient(cage_laplacian):
    C_ref, L = cage_laplacian
    assert scipy.sparse.issparse(L)
    C = C_ref + 0.1 * np.random.default_rng(10).normal(size=C_ref.shape)
    assert_grad(lambda X: laplacian_loss(X, L, C_ref), C)


def test_laplacian_zero_for_translation_positive_otherwise(cage_laplacian):
    C_ref, L = cage_laplacian
    value, grad = laplacian_loss(C_ref + [0.3, -2.0, 5.0], L, C_ref)
    assert value == pytest.approx(0.0, abs=1e-24)
    np.testing.assert_allclose(grad, 0.0, atol=1e-12)
    assert laplacian_loss(C_ref, L, C_ref) == (0.0, pytest.approx(np.zeros_like(C_ref)))
    bumped = C_ref.copy()
    bumped[3] *= 1.2  # non-affine
    assert laplacian_loss(bumped, L, C_ref)[0] > 1e-6
    noisy = C_ref + 0.05 * np.random.default_rng(12).normal(size=C_ref.shape)
    assert laplacian_loss(noisy, L, C_ref)[0] > 1e-6


def test_laplacian_known_value():
    L = scipy.sparse.csr_matrix([[-1.0, 1.0], [1.0, -1.0]])
    C = np.array([[1.0, 0, 0], [0, 0, 0]])
    value, grad = laplacian_loss(C, L, np.zeros((2, 3)))
    # L C = [[-1, 0, 0], [1, 0, 0]]: mean over 6 entries of squares = 2/6
    assert value == pytest.approx(1 / 3)
    np.testing.assert_allclose(grad, 2.0 * (L.T @ (L @ C)) / 6)


# --------------------------------------------------------------------------- shape terms


@pytest.mark.parametrize(("name", "X0", "ref"), SHAPE_REFS, ids=SHAPE_IDS)
def test_p2f_gradient(name, X0, ref):
    X = deformed(X0)
    value, _ = assert_grad(lambda Y: p2f_loss(Y, ref), X)
    assert value > 0


@pytest.mark.parametrize(("name", "X0", "ref"), SHAPE_REFS, ids=SHAPE_IDS)
def test_normal_gradient(name, X0, ref):
    X = deformed(X0)
    value, _ = assert_grad(lambda Y: normal_loss(Y, ref), X)
    assert 0 < value < 1


@pytest.mark.parametrize(("name", "X0", "ref"), SHAPE_REFS, ids=SHAPE_IDS)
def test_shape_losses_combined(name, X0, ref):
    X = deformed(X0, seed=13)
    wp, wn = 0.7, 2.5
    values, grad = shape_losses(X, ref, p2f_weight=wp, normal_weight=wn)
    vp, gp = p2f_loss(X, ref)
    vn, gn = normal_loss(X, ref)
    assert set(values) == {"p2f", "normal"}
    assert values["p2f"] == pytest.approx(vp, rel=1e-13)
    assert values["normal"] == pytest.approx(vn, rel=1e-13)
    np.testing.assert_allclose(grad, wp * gp + wn * gn, rtol=0, atol=1e-13 * np.abs(grad).max())

    def weighted(Y):
        v, g = shape_losses(Y, ref, p2f_weight=wp, normal_weight=wn)
        return wp * v["p2f"] + wn * v["normal"], g

    assert_grad(weighted, X)


def test_shape_losses_zero_weight_skips_term():
    _, X0, ref = SHAPE_REFS[0]
    X = deformed(X0)
    values, grad = shape_losses(X, ref, p2f_weight=0.0, normal_weight=0.0)
    assert values == {}
    np.testing.assert_array_equal(grad, 0.0)
    values, _ = shape_losses(X, ref, p2f_weight=3.0, normal_weight=0.0)
    assert set(values) == {"p2f"}  # value is unweighted
    assert values["p2f"] == pytest.approx(p2f_loss(X, ref)[0], rel=1e-13)


def test_shape_reference_fields():
    name, X0, ref = SHAPE_REFS[2]
    assert isinstance(ref, ShapeReference)
    r = len(ref.own)
    assert ref.index.shape[0] == ref.mask.shape[0] == r
    assert ref.normals.shape == (r, 3) and ref.distances.shape == (r,)
    np.testing.assert_allclose(np.linalg.norm(ref.normals, axis=1), 1.0, rtol=1e-12)
    # the rest normal of a sphere-like patch points (up to sign) roughly radially
    radial = X0[ref.own] / np.linalg.norm(X0[ref.own], axis=1, keepdims=True)
    assert np.abs(np.einsum("ri,ri->r", ref.normals, radial)).min() > 0.8


@pytest.mark.parametrize(("name", "X0", "ref"), SHAPE_REFS, ids=SHAPE_IDS)
def test_shape_terms_zero_at_rest(name, X0, ref):
    values, grad = shape_losses(X0, ref)
    assert values["p2f"] == pytest.approx(0.0, abs=1e-28)
    assert values["normal"] == pytest.approx(0.0, abs=1e-14)
    np.testing.assert_allclose(grad, 0.0, atol=1e-12)


@pytest.mark.parametrize(("name", "X0", "ref"), SHAPE_REFS, ids=SHAPE_IDS)
def test_shape_terms_translation_invariant(name, X0, ref):
    values, grad = shape_losses(X0 + [2.0, -1.0, 0.5], ref)
    assert values["p2f"] == pytest.approx(0.0, abs=1e-24)
    assert values["normal"] == pytest.approx(0.0, abs=1e-14)
    np.testing.assert_allclose(grad, 0.0, atol=1e-10)
    X = deformed(X0)
    shifted, grad_shifted = shape_losses(X + [2.0, -1.0, 0.5], ref)
    unshifted, grad_unshifted = shape_losses(X, ref)
    assert shifted == pytest.approx(unshifted, rel=1e-10)
    np.testing.assert_allclose(grad_shifted, grad_unshifted, atol=1e-10 * np.abs(grad).max())


@pytest.mark.parametrize(("name", "X0", "ref"), SHAPE_REFS, ids=SHAPE_IDS)
@pytest.mark.parametrize("scale", [0.5, 3.0])
def test_uniform_scale(name, X0, ref, scale):
    X = scale * X0 + [0.3, 0.1, -0.2]
    value, grad = normal_loss(X, ref)
    assert value == pytest.approx(0.0, abs=1e-14)  # normals do not change
    np.testing.assert_allclose(grad, 0.0, atol=1e-12)
    # signed distances scale with the shape: p2f = (s - 1)^2 mean(d0^2)
    expected = (scale - 1) ** 2 * np.mean(ref.distances**2)
    assert expected > 0
    assert p2f_loss(X, ref)[0] == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize(("name", "X0", "ref"), SHAPE_REFS, ids=SHAPE_IDS)
def test_rotation(name, X0, ref):
    R = Rotation.from_rotvec([0.3, -0.4, 0.2]).as_matrix()  # about 31 degrees
    X = X0 @ R.T
    # normals rotate with the shape, n0 stays: the loss is the misalignment of R n0 with n0
    expected = np.mean(1 - np.abs(np.einsum("ri,ri->r", ref.normals @ R.T, ref.normals)))
    assert expected > 1e-3
    assert normal_loss(X, ref)[0] == pytest.approx(expected, rel=1e-9)
    # distances to the planes are unchanged (the rotation is < 90 degrees, signs agree)
    assert p2f_loss(X, ref)[0] == pytest.approx(0.0, abs=1e-24)


def test_p2f_known_value_and_bump_exaggeration():
    X = np.array([[0.0, 0, 1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]])
    ref = shape_reference(X, [0], [[0, 1, 2, 3, 4]], [[True] * 5])
    assert ref.distances[0] == pytest.approx(0.8)  # apex above the centroid (0, 0, 0.2)
    assert p2f_loss(X * [1, 1, 2], ref)[0] == pytest.approx(0.64)
    # while the apex stays the flattest direction (z variance < 0.4 for f < ~1.58) the
    # apex's distance scales with it: d = 0.8 f, p2f = 0.64 (f - 1)^2
    factors = np.array([1.0, 1.1, 1.3, 1.5])
    bumps = np.array([p2f_loss(X * [1, 1, f], ref)[0] for f in factors])
    np.testing.assert_allclose(bumps, 0.64 * (factors - 1) ** 2, rtol=1e-12, atol=1e-28)
    assert bumps[0] == 0.0 and np.all(np.diff(bumps) > 0)
    # past that the PCA plane turns vertical (the fan is taller than wide): d = 0, so
    # the 0.64 at f = 2 is (0 - 0.8)^2, not (1.6 - 0.8)^2
    assert normal_loss(X * [1, 1, 2], ref)[0] == pytest.approx(1.0)
    # as a rest shape the tall fan has no plane (its x and y spreads are equal): dropped
    tall = shape_reference(X * [1, 1, 2], [0], [[0, 1, 2, 3, 4]], [[True] * 5])
    assert len(tall.own) == 0


def test_p2f_grows_with_a_bump_on_the_sphere():
    X0, F = rest_shape()
    ref = one_ring_ref(X0, F)
    i = 17
    values = []
    for amount in (0.0, 0.03, 0.1, 0.2):
        X = X0.copy()
        X[i] *= 1 + amount
        values.append(p2f_loss(X, ref)[0])
    assert values[0] == pytest.approx(0.0, abs=1e-28)
    assert np.all(np.diff(values) > 0)


@settings(max_examples=20)
@given(seed=SEEDS, spread=st.floats(0.01, 10.0))
def test_normal_loss_in_unit_interval(seed, spread):
    rng = np.random.default_rng(seed)
    X0 = rng.normal(size=(30, 3))
    ref = knn_ref(X0, k=6)
    X = X0 + spread * rng.normal(size=X0.shape)
    value, grad = normal_loss(X, ref)
    assert 0.0 <= value <= 1.0
    assert np.isfinite(grad).all()
    assert 0.0 <= p2f_loss(X, ref)[0]


# ------------------------------------------------------------------ degenerate neighbourhoods


def _degenerate_ref(X0):
    # rows: a single point; collinear members (with padding); a duplicated point
    own = [0, 1, 2]
    index = [[0, 0, 0, 0], [1, 2, 3, 1], [2, 2, 2, 2]]
    mask = [[True, False, False, False], [True, True, True, False], [True, True, True, True]]
    return shape_reference(X0, own, index, mask)


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("moved", ["collinear", "general"])
def test_degenerate_neighbourhoods_are_finite(moved):
    X0 = np.array([[0.5, 0.2, 0.1], [0.0, 0, 0], [1.0, 0, 0], [2.5, 0, 0]])
    with warnings.catch_warnings(), np.errstate(divide="raise", invalid="raise", over="raise"):
        warnings.simplefilter("error")
        ref = _degenerate_ref(X0)
        assert np.isfinite(ref.normals).all() and np.isfinite(ref.distances).all()
        if moved == "collinear":
            X = X0 * [1.3, 0, 0] + [0.1, 0.2, 0.3]  # still on a line
        else:
            X = X0 + 0.1 * np.random.default_rng(14).normal(size=X0.shape)
        for weights in [(1.0, 1.0), (1.0, 0.0), (0.0, 1.0)]:
            values, grad = shape_losses(X, ref, *weights)
            assert all(np.isfinite(v) for v in values.values())
            assert np.isfinite(grad).all()
        assert 0.0 <= normal_loss(X, ref)[0] <= 1.0


@pytest.mark.filterwarnings("error")
def test_degenerate_rows_do_not_spoil_the_others():
    # healthy rows are unchanged by degenerate rows mixed in
    X0, F = rest_shape(subdivisions=1)
    nb = vertex_neighborhoods(X0, F)
    m = nb.index.shape[1]
    healthy = shape_reference(X0, np.arange(5), nb.index[:5], nb.mask[:5])
    single = np.zeros((1, m), dtype=bool)
    single[0, 0] = True
    mixed = shape_reference(
        X0,
        np.r_[np.arange(5), 7],
        np.r_[nb.index[:5], nb.index[7:8]],
        np.r_[nb.mask[:5], single],
    )
    X = deformed(X0)
    v_h, g_h = shape_losses(X, healthy)
    v_m, g_m = shape_losses(X, mixed)
    # the single-point row has no plane: dropped, it changes nothing
    assert mixed.own.tolist() == list(range(5))
    assert v_m == pytest.approx(v_h, rel=1e-12)
    np.testing.assert_allclose(g_m, g_h, atol=1e-12 * np.abs(g_h).max())


# ---------------------------------------------------------------------- non-finite input


def test_landmark_nan_raises():
    P = np.zeros((3, 3))
    P[1, 2] = np.nan
    with pytest.raises(FloatingPointError):
        landmark_loss(P, np.ones((3, 3)))
    with pytest.raises(FloatingPointError):
        landmark_loss(np.ones((3, 3)), P)


def test_chamfer_overflow_raises():
    P = np.array([[1e200, 0, 0], [0, 0, 0]])
    with np.errstate(over="ignore"), pytest.raises(FloatingPointError):
        chamfer_loss(P, np.zeros((1, 3)))


def test_symmetry_nan_raises():
    P = np.random.default_rng(15).normal(size=(4, 3))
    P[2, 0] = np.nan
    with pytest.raises(FloatingPointError):
        symmetry_loss(P, "x")


@pytest.mark.parametrize("where", ["P", "Q"])
def test_chamfer_nan_raises_floating_point_error(where):
    P = np.random.default_rng(15).normal(size=(4, 3))
    Q = np.zeros((3, 3))
    (P if where == "P" else Q)[1, 1] = np.nan
    with pytest.raises(FloatingPointError):
        chamfer_loss(P, Q)


# ------------------------------------------------------------------------------------ MVC


def test_mvc_known_value():
    W = np.array([[1.5, -0.5, 0.0], [-1.0, 0.25, 0.0]])
    value, grad = mvc_loss(W)
    assert value == pytest.approx((0.25 + 1.0) / 6)
    np.testing.assert_allclose(grad, [[0.0, -1 / 6, 0.0], [-2 / 6, 0.0, 0.0]],
                               rtol=1e-15, atol=1e-16)


def test_mvc_gradient_matches_finite_differences():
    W = np.random.default_rng(16).normal(0.1, 0.5, (8, 5))
    W[np.abs(W) < 1e-3] = 0.5  # away from the kink at 0
    value, _ = assert_grad(mvc_loss, W)
    assert value > 0


def test_mvc_zero_for_non_negative_weights():
    W = np.abs(np.random.default_rng(17).normal(size=(10, 6)))
    W[0, 0] = 0.0
    value, grad = mvc_loss(W)
    assert value == 0.0
    np.testing.assert_array_equal(grad, 0.0)


@settings(max_examples=20)
@given(seed=SEEDS, n=st.integers(1, 20), k=st.integers(1, 12))
def test_mvc_matches_definition(seed, n, k):
    W = np.random.default_rng(seed).normal(0.1, 1.0, (n, k))
    value, grad = mvc_loss(W.tolist())  # array_like
    negative = np.minimum(W, 0.0)
    assert value == pytest.approx(np.mean(negative**2), rel=1e-12, abs=0)
    assert 0.0 <= value <= np.mean(W**2)
    np.testing.assert_allclose(grad, 2.0 * negative / W.size, rtol=1e-15, atol=0)


def test_mvc_bad_input_raises():
    W = np.zeros((3, 4))
    W[1, 2] = np.nan
    with pytest.raises(FloatingPointError):
        mvc_loss(W)
    with pytest.raises(InputError):
        mvc_loss(np.zeros((0, 4)))


# ------------------------------------------------------------------- part affinity


def _three_parts(seed):
    """60 points in three labelled parts (one flat), 5 unlabelled."""
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(65, 3))
    X[40:60, 2] = 0.0                                  # a flat part
    labels = np.repeat([0, 1, 2, -1], [20, 20, 20, 5])
    return X, labels


@settings(max_examples=20, deadline=None)
@given(seed=SEEDS)
def test_part_affinity_gradient_matches_finite_differences(seed):
    X, labels = _three_parts(seed)
    parts = part_bases(X, labels, min_points=10)
    moved = X + 0.2 * np.random.default_rng(seed + 1).normal(size=X.shape)
    assert_grad(lambda Y: part_affinity_loss(Y, parts), moved)


def test_part_affinity_is_zero_for_a_different_affine_map_per_part():
    X, labels = _three_parts(0)
    parts = part_bases(X, labels, min_points=10)
    assert [b.shape[1] for b in parts.bases] == [4, 4, 3]  # the flat part spans 3
    Y = X.copy()
    rng = np.random.default_rng(1)
    for label in range(3):
        rows = labels == label
        Y[rows] = X[rows] @ rng.normal(size=(3, 3)) + rng.normal(size=3)
    Y[labels < 0] += 5.0                               # unlabelled points are free
    value, grad = part_affinity_loss(Y, parts)
    assert value < 1e-20 and np.abs(grad).max() < 1e-10


def test_part_affinity_of_a_bend_is_its_mean_squared_residual():
    # one part, bent by z += x^2: the value is the mean of the squared residuals of the
    # least-squares affine fit of the bent points (computed here by lstsq)
    X, _ = _three_parts(2)
    Y = X.copy()
    Y[:, 2] += X[:, 0] ** 2
    parts = part_bases(X, np.zeros(len(X), int))
    A = np.column_stack([X, np.ones(len(X))])
    residual = Y - A @ np.linalg.lstsq(A, Y, rcond=None)[0]
    value, _ = part_affinity_loss(Y, parts)
    assert value == pytest.approx(np.sum(residual ** 2) / len(X), rel=1e-10)


def test_small_parts_are_left_out():
    X, labels = _three_parts(3)
    parts = part_bases(X, labels, min_points=30)
    assert parts.bases == () and part_affinity_loss(X * 2, parts)[0] == 0.0


def test_part_affinity_matrix_is_the_loss_as_a_quadratic_form():
    X, labels = _three_parts(4)
    parts = part_bases(X, labels, min_points=10)
    rng = np.random.default_rng(5)
    W = rng.random((len(X), 7))
    C = rng.normal(size=(7, 3))
    value, grad = part_affinity_loss(W @ C, parts)
    Q = part_affinity_matrix(W, parts)
    assert np.sum(C * (Q @ C)) == pytest.approx(value, rel=1e-10)
    np.testing.assert_allclose(2 * Q @ C, W.T @ grad, rtol=1e-9, atol=1e-12)


@settings(max_examples=30)
@given(seed=SEEDS, weight=st.floats(0.0, 2.0))
def test_partial_chamfer_gradient_and_full_weight_is_chamfer(seed, weight):
    rng = np.random.default_rng(seed)
    P = rng.uniform(-1, 1, (9, 3))
    Q = rng.uniform(-1, 1, (7, 3))
    assume(nn_margin(P, Q) > 1e-4)
    assert_grad(lambda X: partial_chamfer_loss(X, Q, source_weight=weight), P)
    full, grad = partial_chamfer_loss(P, Q, source_weight=1.0)
    assert full == pytest.approx(chamfer_loss(P, Q)[0])
    np.testing.assert_allclose(grad, chamfer_loss(P, Q)[1])


# --------------------------------------------------------------------------- detail


@settings(max_examples=20, deadline=None)
@given(seed=SEEDS)
def test_detail_loss_gradient_matches_finite_differences(seed):
    rng = np.random.default_rng(seed)
    Q = detail_matrix(rng.random((30, 6)), cotangent_laplacian(*icosphere(1))[:30, :30])
    C_ref = rng.normal(size=(6, 3))
    assert_grad(lambda C: detail_loss(C, Q, C_ref), C_ref + 0.3 * rng.normal(size=(6, 3)))


def test_detail_loss_is_dcotlap_of_the_deformed_points():
    # the points W C against W C_ref: the quadratic form is the metric itself
    V, F = icosphere(2)
    rng = np.random.default_rng(0)
    W = rng.random((len(V), 8))
    W /= W.sum(axis=1, keepdims=True)
    C_ref = np.linalg.lstsq(W, V, rcond=None)[0]
    C = C_ref + 0.05 * rng.normal(size=C_ref.shape)
    Q = detail_matrix(W, cotangent_laplacian(W @ C_ref, F))
    value, _ = detail_loss(C, Q, C_ref)
    assert value == pytest.approx(dcotlap(W @ C_ref, F, W @ C), rel=1e-9)
    assert detail_loss(C_ref + [1.0, 2.0, 3.0], Q, C_ref)[0] < 1e-12 * value  # translation


def test_neighbourhoods_without_a_plane_are_dropped():
    # 4 points on a line have no plane: their normal is arbitrary, so they are left out
    X = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [0, 1, 0], [1, 1, 0]])
    ref = shape_reference(X, [0, 1], [[0, 1, 2, 3], [0, 1, 4, 5]], [[True] * 4] * 2)
    assert ref.own.tolist() == [1]
    line = shape_reference(X, [0], [[0, 1, 2, 3]], [[True] * 4])
    values, grad = shape_losses(X + 1e-7, line)
    assert values == {"p2f": 0.0, "normal": 0.0} and not grad.any()


def test_padding_columns_do_not_change_the_shape_losses():
    # the optimiser drops the padding no chosen row needs (deformation._shape_rows):
    # the same rows with extra padded columns give the same values and gradient
    X0, F = rest_shape(seed=3)
    nb = vertex_neighborhoods(X0, F)
    rows = np.arange(0, len(X0), 3)
    ref = shape_reference(X0, rows, nb.index[rows], nb.mask[rows])
    pad = np.repeat(ref.own[:, None], 5, axis=1)
    padded = ref._replace(index=np.hstack([ref.index, pad]),
                          mask=np.hstack([ref.mask, np.zeros(pad.shape, bool)]))
    X = X0 + 0.05 * np.random.default_rng(3).normal(size=X0.shape)
    values, grad = shape_losses(X, ref)
    values_padded, grad_padded = shape_losses(X, padded)
    for name in values:
        assert values_padded[name] == pytest.approx(values[name], rel=1e-12)
    np.testing.assert_allclose(grad_padded, grad, rtol=1e-10, atol=1e-14 * abs(grad).max())
