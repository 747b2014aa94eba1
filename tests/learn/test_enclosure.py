"""The enclosure term of the learned cages: libigl's winding number and distances, gradients."""

import igl
import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from cagekit.cage.fitting import template_cage
from cagekit.errors import InputError
from cagekit_learn.coords import compiled_kernels
from cagekit_learn.enclosure import enclosure_loss, triangle_distances, winding_numbers


def _cage(seed=0, noise=0.15):
    v, f = template_cage()
    rng = np.random.default_rng(seed)
    return v * (1 + noise * rng.uniform(-1, 1, size=(len(v), 1))), f


def test_winding_numbers_are_libigl_s():
    v, f = _cage()
    P = np.random.default_rng(1).uniform(-1.6, 1.6, size=(300, 3))
    ours = winding_numbers(torch.as_tensor(P)[None], torch.as_tensor(v)[None], f)[0]
    theirs = igl.winding_number(v, f.astype(np.int64), P)
    np.testing.assert_allclose(ours.numpy(), theirs, atol=1e-9)
    assert 0 < (ours.numpy() > 0.5).sum() < len(P)  # both sides sampled


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_triangle_distances_are_libigl_s(seed):
    rng = np.random.default_rng(seed)
    v, f = _cage(seed, noise=0.4)
    v = v + rng.normal(scale=0.05, size=v.shape)  # skewed, slivers, any shape
    P = rng.normal(scale=1.5, size=(64, 3))
    P[:8] = v[f[:8, 0]] + 1e-9 * rng.normal(size=(8, 3))  # at and next to corners
    d2 = triangle_distances(torch.as_tensor(P)[None], torch.as_tensor(v)[None], f)[0]
    theirs, _, _ = igl.point_mesh_squared_distance(P, v, f.astype(np.int64))
    np.testing.assert_allclose(d2.min(dim=1).values.numpy(), theirs, rtol=1e-9, atol=1e-14)


def test_a_degenerate_face_measures_to_its_edges():
    V = torch.tensor([[[0.0, 0, 0], [1, 0, 0], [2, 0, 0]]], dtype=torch.float64)
    P = torch.tensor([[[1.0, 0, 1], [3.0, 0, 0]]], dtype=torch.float64)
    assert triangle_distances(P, V, [[0, 1, 2]])[0, :, 0].tolist() == [1.0, 1.0]


def test_the_loss_is_zero_deep_inside_and_grows_with_the_distance_outside():
    v, f = _cage()
    V = torch.as_tensor(v)[None]
    deep = torch.zeros(1, 5, 3, dtype=torch.float64)
    assert enclosure_loss(deep, V, f).item() == 0.0
    losses = [enclosure_loss(torch.tensor([[[x, 0.0, 0.0]]], dtype=torch.float64), V, f,
                             margin=0.1).item() for x in (0.5, 2.0, 3.0, 4.0)]
    assert losses[0] == 0.0 and 0 < losses[1] < losses[2] < losses[3]
    d = np.sqrt(igl.point_mesh_squared_distance(np.array([[3.0, 0, 0]]), v,
                                                f.astype(np.int64))[0][0])
    assert losses[2] == pytest.approx((0.1 + d) ** 2, rel=1e-9)


def test_a_point_just_inside_the_surface_is_pushed_deeper():
    v, f = _cage()
    V = torch.as_tensor(v)[None]
    centroid = v[f[0]].mean(axis=0)  # the cage is star-shaped about the origin
    P = torch.as_tensor(0.99 * centroid)[None, None]
    assert winding_numbers(P, V, f).item() > 0.5
    assert enclosure_loss(P, V, f, margin=0.2).item() > 0
    assert enclosure_loss(P, V, f, margin=0.0).item() == 0.0


def test_the_gradient_is_exact_and_grows_the_cage():
    v, f = _cage(3)
    rng = np.random.default_rng(4)
    P = torch.as_tensor(rng.uniform(-1.7, 1.7, size=(2, 40, 3)))
    V = torch.as_tensor(np.stack([v, 0.8 * v])).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda V: enclosure_loss(P, V, f, margin=0.05), (V,))
    # a step down the gradient takes more of the points in
    loss = enclosure_loss(P, V, f).sum()
    (g,) = torch.autograd.grad(loss, V)
    with torch.no_grad():
        moved = V - 0.2 * g / g.norm()
        before = (winding_numbers(P, V, f) > 0.5).sum()
        after = (winding_numbers(P, moved, f) > 0.5).sum()
    assert enclosure_loss(P, moved, f).sum() < loss and after >= before


def test_float32_agrees_with_float64():
    v, f = _cage(5)
    P = np.random.default_rng(6).uniform(-1.7, 1.7, size=(1, 200, 3))
    l64 = enclosure_loss(torch.as_tensor(P), torch.as_tensor(v)[None], f)
    l32 = enclosure_loss(torch.as_tensor(P).float(), torch.as_tensor(v).float()[None], f)
    assert l32.item() == pytest.approx(l64.item(), rel=1e-4)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), spread=st.sampled_from([0.5, 1.5, 3.0]),
       dtype=st.sampled_from([torch.float32, torch.float64]))
def test_libigl_s_side_and_nearest_face_give_the_torch_graph_s_loss_and_gradient(seed, spread,
                                                                                 dtype):
    # the CPU default finds the side and the nearest face with libigl, the graph (CUDA,
    # compiled_kernels(False)) with all point-face pairs; points on and near faces included
    v, f = _cage(seed % 7)
    rng = np.random.default_rng(seed)
    P = rng.uniform(-spread, spread, size=(2, 150, 3))
    corners = v[f[rng.integers(0, len(f), 40)]]
    w = rng.dirichlet([1, 1, 1], size=40)
    P[0, :40] = np.einsum("ni,nij->nj", w, corners) * (1 + rng.normal(0, 1e-3, (40, 1)))
    results = []
    for enabled in (True, False):
        V = torch.tensor(np.stack([v, v * 1.1]), dtype=dtype, requires_grad=True)
        with compiled_kernels(enabled):
            loss = enclosure_loss(torch.tensor(P, dtype=dtype), V, f)
        loss.sum().backward()
        results.append((loss.detach(), V.grad))
    (l_igl, g_igl), (l_graph, g_graph) = results
    tol = 1e-5 if dtype == torch.float32 else 1e-12
    assert torch.allclose(l_igl, l_graph, rtol=tol, atol=tol)
    if dtype == torch.float64:  # float32 may pick the other of two nearly equally near
        # faces (libigl decides in float64): the same loss, another face's gradient
        scale = float(g_graph.abs().max())
        assert torch.allclose(g_igl, g_graph, rtol=1e-10, atol=1e-10 * scale)
    assert float(l_graph.sum()) > 0  # points outside: the test is not of zeros


@pytest.mark.parametrize("bad", [
    dict(P=torch.zeros(2, 3, 3)),  # batch of 2 against one cage
    dict(P=torch.zeros(1, 3, 2)),
    dict(F=[[0, 1]]),
    dict(margin=float("nan")),
    dict(margin=-0.1),
])
def test_bad_input_is_refused(bad):
    v, f = _cage()
    args = dict(P=torch.zeros(1, 3, 3), V=torch.as_tensor(v).float()[None], F=f, margin=0.05)
    args.update(bad)
    with pytest.raises(InputError):
        enclosure_loss(args["P"], args["V"], args["F"], margin=args["margin"])
