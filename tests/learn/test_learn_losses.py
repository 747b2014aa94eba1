"""Tests of cagekit_learn.losses: each torch term is the NumPy term of cagekit.deformation.terms.

Values are compared to 1e-12 (relative) and autograd gradients to the NumPy analytic
gradients to 1e-10 (relative to the largest gradient entry), batch element by batch
element, on random float64 inputs; then gradcheck, degenerate neighbourhoods, float32 and
identities.
"""

import numpy as np
import pytest
import torch
from builders import SEEDS, deformed, icosphere, nn_margin
from hypothesis import given, settings
from hypothesis import strategies as st

from cagekit.deformation import terms as npl
from cagekit.errors import InputError
from cagekit.geometry import vertex_neighborhoods
from cagekit_learn import losses as tl

VALUE_RTOL = 1e-12
GRAD_RTOL = 1e-10


# ------------------------------------------------------------------------------- helpers


def leaf(a, dtype=torch.float64):
    """A float tensor that requires grad."""
    return torch.tensor(np.asarray(a), dtype=dtype).requires_grad_(True)


def backward_sum(values):
    """Backward of the batch sum: element b's gradient is the gradient of values[b]."""
    assert values.ndim == 1
    values.sum().backward()


def assert_value(value_t, value_np):
    assert np.isfinite(value_t)
    assert value_t == pytest.approx(value_np, rel=VALUE_RTOL, abs=1e-300)


def assert_normal_term(value_t, value_np):
    """The normal term is a mean of 1 - |cos| in [0, 1]: for small motions it is a difference
    of nearly equal numbers, so its rounding is absolute (a few ulp of 1), not relative."""
    assert np.isfinite(value_t)
    assert value_t == pytest.approx(value_np, rel=VALUE_RTOL, abs=1e-14)


def assert_grad(grad_t, grad_np):
    grad_t = grad_t.detach().numpy()
    assert grad_t.shape == grad_np.shape
    assert np.isfinite(grad_t).all()
    scale = max(np.abs(grad_np).max(), 1e-300)
    err = np.abs(grad_t - grad_np).max()
    assert err <= GRAD_RTOL * scale, f"gradient error {err:.3g} vs max |grad| {scale:.3g}"


def rest_shapes(B=3, subdivisions=2):
    """B noisy, anisotropically scaled icospheres (same faces): (B, n, 3), faces."""
    V, F = icosphere(subdivisions)
    rng = np.random.default_rng(0)
    X0 = np.stack([V * rng.uniform(0.6, 1.5, 3) + 0.02 * rng.standard_normal(V.shape)
                   for _ in range(B)])
    return X0, F


# ------------------------------------------------------------------------------ Chamfer


def test_chamfer_equals_numpy_values_and_both_gradients():
    rng = np.random.default_rng(1)
    P = rng.uniform(-1, 1, (3, 40, 3))
    Q = rng.normal(size=(3, 30, 3)) * 0.7 + 0.2
    Pt, Qt = leaf(P), leaf(Q)
    values = tl.chamfer_loss(Pt, Qt)
    assert values.shape == (3,) and values.dtype == torch.float64
    backward_sum(values)
    for b in range(3):
        assert nn_margin(P[b], Q[b]) > 1e-6
        value, grad_P = npl.chamfer_loss(P[b], Q[b])
        assert_value(values[b].item(), value)
        assert_grad(Pt.grad[b], grad_P)
        # Chamfer is symmetric: the gradient with respect to Q is chamfer_loss(Q, P)'s
        assert_grad(Qt.grad[b], npl.chamfer_loss(Q[b], P[b])[1])


@pytest.mark.parametrize("max_elements", [1, 7, 50, 10**9])
def test_chamfer_chunks_give_identical_results(max_elements):
    # many P points share one nearest Q point (and vice versa): the scatter paths
    rng = np.random.default_rng(11)
    P = rng.uniform(-1, 1, (2, 25, 3))
    Q = rng.uniform(-0.3, 0.3, (2, 4, 3)) + [2.0, 0, 0]
    ref_P, ref_Q = leaf(P), leaf(Q)
    backward_sum(reference := tl.chamfer_loss(ref_P, ref_Q))
    Pt, Qt = leaf(P), leaf(Q)
    backward_sum(values := tl.chamfer_loss(Pt, Qt, max_elements=max_elements))
    torch.testing.assert_close(values, reference, rtol=0, atol=0)
    torch.testing.assert_close(Pt.grad, ref_P.grad, rtol=0, atol=0)
    torch.testing.assert_close(Qt.grad, ref_Q.grad, rtol=0, atol=0)
    for b in range(2):
        assert_grad(Pt.grad[b], npl.chamfer_loss(P[b], Q[b])[1])


def test_chamfer_known_value_and_identical_sets():
    value = tl.chamfer_loss(torch.zeros(1, 1, 3), torch.tensor([[[0.0, 0, 2]]]))
    assert value.tolist() == [8.0]
    P = leaf(np.random.default_rng(2).uniform(-1, 1, (2, 40, 3)))
    values = tl.chamfer_loss(P, P.detach().clone())
    backward_sum(values)
    assert values.tolist() == [0.0, 0.0]
    assert (P.grad == 0).all()


@settings(max_examples=15, deadline=None)
@given(seed=SEEDS, s=st.integers(1, 15), t=st.integers(1, 15), B=st.integers(1, 3))
def test_chamfer_property_equals_numpy(seed, s, t, B):
    rng = np.random.default_rng(seed)
    P = rng.uniform(-1, 1, (B, s, 3))
    Q = rng.normal(size=(B, t, 3))
    Pt = leaf(P)
    values = tl.chamfer_loss(Pt, torch.tensor(Q), max_elements=int(rng.integers(1, 200)))
    backward_sum(values)
    for b in range(B):
        value, grad = npl.chamfer_loss(P[b], Q[b])
        assert_value(values[b].item(), value)
        if nn_margin(P[b], Q[b]) > 1e-9:  # the gradient is defined away from ties
            assert_grad(Pt.grad[b], grad)


# ---------------------------------------------------------------------- landmarks, mirror


def test_landmark_equals_numpy():
    rng = np.random.default_rng(4)
    P, T = rng.normal(size=(3, 7, 3)), rng.normal(size=(3, 7, 3))
    Pt = leaf(P)
    backward_sum(values := tl.landmark_loss(Pt, torch.tensor(T)))
    for b in range(3):
        value, grad = npl.landmark_loss(P[b], T[b])
        assert_value(values[b].item(), value)
        assert_grad(Pt.grad[b], grad)
    # shared targets (l, 3) broadcast over the batch
    shared = tl.landmark_loss(torch.tensor(P), torch.tensor(T[0]))
    assert shared[2].item() == pytest.approx(npl.landmark_loss(P[2], T[0])[0], rel=1e-12)


def test_mirror_matches_numpy_and_rejects_bad_axis():
    P = np.random.default_rng(6).normal(size=(2, 10, 3))
    Pt = torch.tensor(P)
    for axis in "xyz":
        np.testing.assert_array_equal(tl.mirror(Pt, axis)[1].numpy(), npl.mirror(P[1], axis))
    np.testing.assert_array_equal(Pt.numpy(), P)  # not modified
    for axis in ["w", "X", "", 0, None]:
        with pytest.raises(InputError):
            tl.mirror(Pt, axis)
        with pytest.raises(InputError):
            tl.symmetry_loss(Pt, axis)


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_symmetry_equals_numpy(axis):
    P = np.random.default_rng({"x": 7, "y": 8, "z": 9}[axis]).uniform(-1, 1, (3, 15, 3))
    Pt = leaf(P)
    backward_sum(values := tl.symmetry_loss(Pt, axis))
    for b in range(3):
        assert nn_margin(P[b], npl.mirror(P[b], axis)) > 1e-6
        value, grad = npl.symmetry_loss(P[b], axis)
        assert_value(values[b].item(), value)
        assert_grad(Pt.grad[b], grad)


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_symmetry_zero_for_symmetric_set(axis):
    half = np.random.default_rng(8).uniform(-1, 1, (2, 20, 3))
    S = leaf(np.concatenate([half, npl.mirror(half.reshape(-1, 3), axis).reshape(half.shape)],
                            axis=1))
    backward_sum(values := tl.symmetry_loss(S, axis))
    assert values.tolist() == [0.0, 0.0]
    assert (S.grad == 0).all()
    assert (tl.symmetry_loss(torch.tensor(half), axis) > 1e-3).all()


@pytest.mark.parametrize("batched_offset", [False, True])
def test_cage_symmetry_equals_numpy(batched_offset):
    rng = np.random.default_rng(9)
    half = rng.uniform(0.1, 1, (6, 3))
    # a rest cage that is not quite symmetric: non-zero offsets
    C_ref = np.concatenate([half, npl.mirror(half, "x")]) + 0.02 * rng.normal(size=(12, 3))
    partner, offset = npl.mirror_partners(C_ref, "x")
    assert np.abs(offset).max() > 1e-3
    C = C_ref + 0.1 * rng.normal(size=(3, 12, 3))
    Ct = leaf(C)
    off = np.broadcast_to(offset, C.shape).copy() if batched_offset else offset
    backward_sum(values := tl.cage_symmetry_loss(Ct, torch.tensor(partner), off, "x"))
    for b in range(3):
        value, grad = npl.cage_symmetry_loss(C[b], partner, offset, "x")
        assert_value(values[b].item(), value)
        assert_grad(Ct.grad[b], grad)
    # a symmetric motion of a symmetric cage costs nothing
    S = np.concatenate([half, npl.mirror(half, "x")])
    partner, offset = npl.mirror_partners(S, "x")
    zero = tl.cage_symmetry_loss(torch.tensor(S * [1, 2, 1])[None], partner, offset, "x")
    assert zero.item() == pytest.approx(0.0, abs=1e-28)


# ------------------------------------------------------------------------------------ MVC


def test_mvc_equals_numpy():
    rng = np.random.default_rng(10)
    W = rng.normal(0.1, 0.3, (3, 20, 12))
    Wt = leaf(W)
    backward_sum(values := tl.mvc_loss(Wt))
    assert values.shape == (3,)
    for b in range(3):
        value, grad = npl.mvc_loss(W[b])
        assert value > 0
        assert_value(values[b].item(), value)
        assert_grad(Wt.grad[b], grad)


def test_mvc_zero_for_non_negative_weights():
    W = leaf(np.abs(np.random.default_rng(12).normal(size=(2, 5, 4))))
    with torch.no_grad():
        W[0, 0, 0] = 0.0
    backward_sum(values := tl.mvc_loss(W))
    assert values.tolist() == [0.0, 0.0]
    assert (W.grad == 0).all()
    with pytest.raises(InputError):
        tl.mvc_loss(torch.zeros(2, 0, 4))


# ------------------------------------------------------------------ neighbourhoods, shape


def test_knn_neighborhoods_match_numpy_and_put_self_first():
    X = np.random.default_rng(13).normal(size=(2, 60, 3))
    for k in (1, 8, 100):
        index = tl.knn_neighborhoods(torch.tensor(X), k=k)
        assert index.dtype == torch.long and index.shape == (2, 60, min(k, 60))
        chunked = tl.knn_neighborhoods(torch.tensor(X), k=k, max_elements=100)
        assert torch.equal(index, chunked)
        for b in range(2):
            nb = vertex_neighborhoods(X[b], None, k=k)
            np.testing.assert_array_equal(index[b].numpy(), nb.index)
    # coincident points: each point is still its own first member
    D = torch.zeros(1, 5, 3)
    np.testing.assert_array_equal(tl.knn_neighborhoods(D, k=3)[0, :, 0].numpy(), np.arange(5))
    with pytest.raises(InputError):
        tl.knn_neighborhoods(D, k=0)


def one_ring_case(B=3):
    """Shared one-ring index (r, m) of a mesh, every vertex its own row."""
    X0, F = rest_shapes(B)
    nb = vertex_neighborhoods(X0[0], F)
    return X0, nb.index, nb.mask, None


def knn_case(B=3):
    """Per-element k-nearest neighbourhoods (B, r, m) from knn_neighborhoods."""
    X0, _ = rest_shapes(B)
    return X0, tl.knn_neighborhoods(torch.tensor(X0), k=8).numpy(), None, None


def subset_case(B=3):
    """A random subset of the one-ring rows, with their own vertices."""
    X0, F = rest_shapes(B)
    nb = vertex_neighborhoods(X0[0], F)
    own = np.sort(np.random.default_rng(3).choice(len(X0[0]), 25, replace=False))
    return X0, nb.index[own], nb.mask[own], own


CASES = {"one-ring": one_ring_case, "knn": knn_case, "subset": subset_case}


def numpy_ref(X0b, index, mask, own, b):
    index = index if index.ndim == 2 else index[b]
    mask = np.ones(index.shape, dtype=bool) if mask is None else mask
    own = np.arange(len(index)) if own is None else own
    return npl.shape_reference(X0b, own, index, mask)


@pytest.mark.parametrize("case", CASES)
def test_shape_reference_equals_numpy(case):
    X0, index, mask, own = CASES[case]()
    ref = tl.shape_reference(leaf(X0), index, mask, own)
    B, r = ref.distances.shape
    assert ref.own.shape == (B, r) and ref.index.shape[:2] == ref.mask.shape[:2] == (B, r)
    assert not any(t.requires_grad for t in ref)
    assert ref.planar.shape == (B, r)
    for b in range(B):
        expected = numpy_ref(X0[b], index, mask, own, b)
        kept = ref.planar[b].numpy()  # NumPy drops the rows without a plane
        np.testing.assert_array_equal(ref.own[b].numpy()[kept], expected.own)
        np.testing.assert_array_equal(ref.index[b].numpy()[kept], expected.index)
        np.testing.assert_array_equal(ref.mask[b].numpy()[kept], expected.mask)
        # the normal's sign is arbitrary; the signed distance flips with it
        normals, distances = ref.normals[b].numpy()[kept], ref.distances[b].numpy()[kept]
        sign = np.sign(np.einsum("ri,ri->r", normals, expected.normals))
        assert (sign != 0).all()
        np.testing.assert_allclose(normals * sign[:, None], expected.normals, rtol=0, atol=1e-12)
        np.testing.assert_allclose(distances * sign, expected.distances, rtol=0, atol=1e-12)


@pytest.mark.parametrize("case", CASES)
def test_shape_losses_equal_numpy(case):
    X0, index, mask, own = CASES[case]()
    ref = tl.shape_reference(torch.tensor(X0), index, mask, own)
    X = deformed(X0)
    for term in ("p2f", "normal"):
        Xt = leaf(X)
        values = tl.shape_losses(Xt, ref)
        assert set(values) == {"p2f", "normal"}
        backward_sum(values[term])
        single = {"p2f": tl.p2f_loss, "normal": tl.normal_loss}[term](torch.tensor(X), ref)
        torch.testing.assert_close(single, values[term].detach(), rtol=0, atol=0)
        for b in range(len(X)):
            np_ref = numpy_ref(X0[b], index, mask, own, b)
            np_values, _ = npl.shape_losses(X[b], np_ref)
            value, grad = {"p2f": npl.p2f_loss, "normal": npl.normal_loss}[term](X[b], np_ref)
            assert value > 0
            assert_value(values[term][b].item(), value)
            assert_value(values["p2f"][b].item(), np_values["p2f"])
            assert_normal_term(values["normal"][b].item(), np_values["normal"])
            assert_grad(Xt.grad[b], grad)


def test_shape_losses_with_numpy_reference_tensors():
    # a reference built by NumPy, stacked into tensors, gives the NumPy losses too
    X0, index, mask, _ = one_ring_case(2)
    refs = [npl.shape_reference(X0[b], np.arange(len(index)), index, mask) for b in range(2)]
    ref = tl.ShapeReference(*(torch.tensor(np.stack(f)) for f in zip(*refs)))
    X = deformed(X0, seed=13)
    Xt = leaf(X)
    values = tl.shape_losses(Xt, ref)
    backward_sum(0.7 * values["p2f"] + 2.5 * values["normal"])
    for b in range(2):
        np_values, grad = npl.shape_losses(X[b], refs[b], p2f_weight=0.7, normal_weight=2.5)
        assert_value(values["p2f"][b].item(), np_values["p2f"])
        assert_normal_term(values["normal"][b].item(), np_values["normal"])
        assert_grad(Xt.grad[b], grad)


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS, spread=st.floats(0.01, 1.0), k=st.integers(4, 10))
def test_shape_losses_property_equal_numpy(seed, spread, k):
    rng = np.random.default_rng(seed)
    X0 = rng.normal(size=(2, 30, 3))
    index = tl.knn_neighborhoods(torch.tensor(X0), k=k)
    ref = tl.shape_reference(torch.tensor(X0), index)
    X = X0 + spread * rng.normal(size=X0.shape)
    Xt = leaf(X)
    values = tl.shape_losses(Xt, ref)
    backward_sum(values["p2f"] + values["normal"])
    assert np.isfinite(Xt.grad.numpy()).all()
    for b in range(2):
        np_ref = npl.shape_reference(X0[b], np.arange(30), index[b].numpy(),
                                     np.ones((30, k), dtype=bool))
        np_values, grad = npl.shape_losses(X[b], np_ref)
        assert 0.0 <= values["normal"][b].item() <= 1.0
        assert_value(values["p2f"][b].item(), np_values["p2f"])
        assert_normal_term(values["normal"][b].item(), np_values["normal"])
        # random clouds can have nearly degenerate neighbourhoods, where rounding is
        # amplified by 1 / (eigenvalue gap): compare where the gradient is well posed
        gap = np.diff(np.linalg.eigvalsh(_covariances(X[b], index[b].numpy())), axis=1)[:, 0]
        if gap.min() > 1e-4:
            assert_grad(Xt.grad[b], grad)


def _covariances(X, index):
    P = X[index]
    D = P - P.mean(axis=1, keepdims=True)
    return np.einsum("rji,rjk->rik", D, D) / index.shape[1]


def test_shape_reference_rejects_bad_input():
    X = torch.zeros(1, 4, 3)
    with pytest.raises(InputError):
        tl.shape_reference(X, [[0, 1, 2, 4]])  # out of range
    with pytest.raises(InputError):
        tl.shape_reference(X, [[0, 1]], mask=[[False, False]])  # no real member
    with pytest.raises(InputError):
        tl.shape_reference(X, [[0, 1]], own=[0, 1])  # wrong shape
    with pytest.raises(InputError):
        tl.shape_reference(X[0], [[0, 1]])  # not batched


# ------------------------------------------------------------------------------ gradcheck


def test_gradcheck_alignment_and_mvc():
    rng = np.random.default_rng(20)
    P = rng.uniform(-1, 1, (2, 6, 3))
    Q = rng.uniform(-1, 1, (2, 5, 3))
    assert all(nn_margin(P[b], Q[b]) > 1e-3 for b in range(2))
    assert all(nn_margin(P[b], npl.mirror(P[b], "y")) > 1e-3 for b in range(2))
    T = rng.normal(size=(2, 6, 3))
    C = rng.normal(size=(2, 6, 3))
    partner, offset = npl.mirror_partners(rng.normal(size=(6, 3)), "z")
    W = rng.normal(0, 1, (2, 4, 5))
    W[np.abs(W) < 1e-3] = 0.5  # away from the kink at 0
    checks = [
        (lambda p, q: tl.chamfer_loss(p, q), (P, Q)),
        (lambda p: tl.landmark_loss(p, torch.tensor(T)), (P,)),
        (lambda p: tl.symmetry_loss(p, "y"), (P,)),
        (lambda c: tl.cage_symmetry_loss(c, partner, offset, "z"), (C,)),
        (tl.mvc_loss, (W,)),
    ]
    for fn, args in checks:
        assert torch.autograd.gradcheck(fn, tuple(leaf(a) for a in args))


@pytest.mark.parametrize("case", ["one-ring", "knn"])
def test_gradcheck_shape_losses(case):
    X0, F = rest_shapes(1, subdivisions=0)  # 12 vertices
    if case == "one-ring":
        nb = vertex_neighborhoods(X0[0], F)
        ref = tl.shape_reference(torch.tensor(X0), nb.index, nb.mask)
    else:
        ref = tl.shape_reference(torch.tensor(X0), tl.knn_neighborhoods(torch.tensor(X0), 5))
    X = leaf(deformed(X0, amount=0.1))

    def both(Y):
        values = tl.shape_losses(Y, ref)
        return values["p2f"], values["normal"]

    assert torch.autograd.gradcheck(both, (X,))


# ------------------------------------------------------------------ degenerate neighbourhoods


def degenerate_case():
    """Rows: a single point; collinear members (padded); one point repeated; a planar
    square, whose two largest eigenvalues coincide (torch.linalg.eigh's own backward
    divides by their zero gap)."""
    X0 = np.array([[0.5, 0.2, 0.1], [0.0, 0, 0], [1.0, 0, 0], [2.5, 0, 0],
                   [0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 1]])
    own = [0, 1, 2, 4]
    index = [[0, 0, 0, 0], [1, 2, 3, 1], [2, 2, 2, 2], [4, 5, 6, 7]]
    mask = [[True, False, False, False], [True, True, True, False], [True] * 4, [True] * 4]
    return X0, own, index, mask


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
@pytest.mark.parametrize("moved", ["rest", "collinear", "coincident", "planar", "general"])
def test_degenerate_neighbourhoods_have_finite_gradients(moved, dtype):
    X0, own, index, mask = degenerate_case()
    ref = tl.shape_reference(torch.tensor(X0, dtype=dtype)[None], index, mask, own)
    assert all(torch.isfinite(t).all() for t in (ref.normals, ref.distances))
    # only the square has a plane, as in NumPy, which drops the other rows
    assert ref.planar.tolist() == [[False, False, False, True]]
    assert npl.shape_reference(X0, own, index, mask).own.tolist() == [4]
    X = {
        "rest": X0,
        "collinear": X0 * [1.3, 0, 0] + [0.1, 0.2, 0.3],  # every point on one line
        "coincident": np.zeros_like(X0) + [0.3, -0.2, 0.1],  # every point the same
        "planar": X0 * [2.0, 2.0, 0.0],  # all in one plane
        "general": X0 + 0.1 * np.random.default_rng(14).normal(size=X0.shape),
    }[moved]
    Xt = leaf(X[None], dtype)
    values = tl.shape_losses(Xt, ref)
    backward_sum(values["p2f"] + values["normal"])
    assert all(torch.isfinite(v).all() for v in values.values())
    assert torch.isfinite(Xt.grad).all()
    assert 0.0 <= values["normal"].item() <= 1.0
    if dtype == torch.float64 and moved in ("rest", "planar", "general"):
        # where the rows' normals are defined (or have no gradient) it is the NumPy gradient
        np_ref = npl.shape_reference(X0, own, index, mask)
        np_values, grad = npl.shape_losses(X, np_ref)
        assert values["p2f"].item() == pytest.approx(np_values["p2f"], rel=1e-12, abs=1e-15)
        np.testing.assert_allclose(Xt.grad[0].numpy(), grad, rtol=0,
                                   atol=1e-10 * max(np.abs(grad).max(), 1.0))


def test_float32_gradients_on_collinear_neighbourhoods_stay_bounded():
    # float32 eigenvalues of a line's covariance differ by rounding noise (~1e-7 of the
    # trace): the float32 gap floor keeps that noise from becoming a huge gradient
    rng = np.random.default_rng(22)
    B = 300
    direction = rng.normal(size=(B, 1, 3))
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    line = rng.uniform(-1, 1, (B, 8, 1)) * direction + rng.normal(size=(B, 1, 3))
    X0 = rng.normal(size=(B, 8, 3))
    largest = {}
    for dtype in (torch.float32, torch.float64):
        ref = tl.shape_reference(torch.tensor(X0, dtype=dtype), [list(range(8))])
        X = leaf(line, dtype)
        values = tl.shape_losses(X, ref)
        backward_sum(values["p2f"] + values["normal"])
        assert torch.isfinite(X.grad).all()
        largest[dtype] = X.grad.abs().max().item()
    assert largest[torch.float32] < 2.0 * largest[torch.float64]


# ----------------------------------------------------------------------- float32, identities


def test_float32_is_close_to_float64():
    rng = np.random.default_rng(21)
    P = rng.uniform(-1, 1, (2, 30, 3))
    Q = rng.normal(size=(2, 25, 3))
    W = rng.normal(0.1, 0.3, (2, 10, 6))
    partner, offset = npl.mirror_partners(P[0, :8], "x")
    X0, index, mask, _ = one_ring_case(2)
    X = deformed(X0)
    results = {}
    for dtype in (torch.float32, torch.float64):
        Pt, Wt, Xt = leaf(P, dtype), leaf(W, dtype), leaf(X, dtype)
        ref = tl.shape_reference(torch.tensor(X0, dtype=dtype), index, mask)
        shape = tl.shape_losses(Xt, ref)
        terms = {
            "chamfer": tl.chamfer_loss(Pt, torch.tensor(Q, dtype=dtype)),
            "landmark": tl.landmark_loss(Pt, torch.tensor(P[::-1].copy(), dtype=dtype)),
            "symmetry": tl.symmetry_loss(Pt, "z"),
            "cage": tl.cage_symmetry_loss(Pt[:, :8], partner, offset, "x"),
            "mvc": tl.mvc_loss(Wt),
            "p2f": shape["p2f"],
            "normal": shape["normal"],
        }
        for name, value in terms.items():
            assert value.dtype == dtype and value.shape == (2,), name
        grads = torch.autograd.grad(sum(v.sum() for v in terms.values()), (Pt, Wt, Xt))
        results[dtype] = ({k: v.detach().double() for k, v in terms.items()},
                          [g.double() for g in grads])
    (v32, g32), (v64, g64) = results[torch.float32], results[torch.float64]
    for name in v64:
        torch.testing.assert_close(v32[name], v64[name], rtol=1e-4, atol=1e-7, msg=name)
    for a, b in zip(g32, g64):
        torch.testing.assert_close(a, b, rtol=0, atol=1e-4 * b.abs().max().item())


@pytest.mark.parametrize("scale", [0.5, 3.0])
def test_normals_invariant_under_uniform_scaling(scale):
    X0, index, mask, own = subset_case(2)
    ref = tl.shape_reference(torch.tensor(X0), index, mask, own)
    Xt = leaf(scale * X0 + [0.3, 0.1, -0.2])
    values = tl.shape_losses(Xt, ref)
    backward_sum(values["normal"])
    np.testing.assert_allclose(values["normal"].detach().numpy(), 0.0, atol=1e-14)
    np.testing.assert_allclose(Xt.grad.numpy(), 0.0, atol=1e-12)
    # signed distances scale with the shape: p2f = (s - 1)^2 mean(d0^2)
    expected = (scale - 1) ** 2 * ref.distances.square().mean(dim=1)
    torch.testing.assert_close(values["p2f"].detach(), expected, rtol=1e-9, atol=0)


@pytest.mark.parametrize("case", CASES)
def test_shape_terms_zero_at_rest(case):
    X0, index, mask, own = CASES[case]()
    Xt = leaf(X0)
    ref = tl.shape_reference(Xt, index, mask, own)
    values = tl.shape_losses(Xt, ref)
    backward_sum(values["p2f"] + values["normal"])
    np.testing.assert_allclose(values["p2f"].detach().numpy(), 0.0, atol=1e-28)
    np.testing.assert_allclose(values["normal"].detach().numpy(), 0.0, atol=1e-14)
    np.testing.assert_allclose(Xt.grad.numpy(), 0.0, atol=1e-12)


def test_paper_weights():
    assert tl.ALPHA_MVC == 1.0
    assert tl.ALPHA_SHAPE == 0.1


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), sizes=st.sampled_from([(1, 7), (40, 25), (300, 500)]),
       dtype=st.sampled_from([torch.float32, torch.float64]))
def test_the_k_d_trees_find_the_torch_graph_s_neighbours(seed, sizes, dtype):
    # CPU tensors take scipy's k-d trees for the neighbour searches, the graph (CUDA,
    # compiled_kernels(False)) takes cdist: the same Chamfer value and gradient, the same
    # neighbourhoods, each point first in its own (coincident points included)
    from cagekit_learn.coords import compiled_kernels

    rng = np.random.default_rng(seed)
    P = rng.normal(size=(2, sizes[0], 3))
    Q = rng.normal(size=(2, sizes[1], 3))
    P[1, : sizes[0] // 2] = P[1, 0]  # coincident points
    results = []
    for enabled in (True, False):
        Pt = torch.tensor(P, dtype=dtype, requires_grad=True)
        with compiled_kernels(enabled):
            value = tl.chamfer_loss(Pt, torch.tensor(Q, dtype=dtype))
            index = tl.knn_neighborhoods(Pt, k=6)
        value.sum().backward()
        results.append((value.detach(), Pt.grad, index))
    (v_kd, g_kd, i_kd), (v_graph, g_graph, i_graph) = results
    assert torch.allclose(v_kd, v_graph, rtol=1e-6, atol=0)
    assert torch.equal(i_kd[:, :, 0], torch.arange(sizes[0]).expand(2, -1))
    assert torch.equal(i_graph[:, :, 0], i_kd[:, :, 0])
    # neighbours beyond the first agree where there are no ties (item 0: no coincident points)
    d = lambda i: np.linalg.norm(P[0][i.numpy()] - P[0][:, None], axis=-1)  # noqa: E731
    np.testing.assert_allclose(d(i_kd[0]), d(i_graph[0]), rtol=1e-6, atol=1e-12)
    # the gradient of the items' Chamfer where no point ties for its nearest
    assert torch.allclose(g_kd[0], g_graph[0], rtol=1e-5, atol=1e-8)
