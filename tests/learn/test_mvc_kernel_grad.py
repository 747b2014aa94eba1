"""The compiled CPU kernels behind cagekit_learn.coords.mean_value_coordinates.

On CPU tensors the weights come from :mod:`cagekit.coords.mvc_grad` through one autograd
function, with the flagged rows (on or near the cage, far out) from the torch graph. Tested
against the torch graph alone (:func:`compiled_kernels(False)`, the reference and the CUDA
path) and the core:
* gradcheck (float64) w.r.t. points and cage, inside, outside and near faces, for rows the
  kernels compute (none flagged) and a batch mixing kernel rows with spliced snap rows;
* float64 gradient parity with the torch graph to 1e-9 (relative to the gradient's size)
  inside and on the cage; 1e-7 outside and far, where the weights' sum cancels and both are
  about 1e-8 from a 40-digit evaluation;
* values equal the core's to 1e-12 inside; rows on vertices, edges and faces and far rows
  equal the torch graph's;
* float32: weights and gradients at least as close to float64 as the torch graph's;
* hypothesis: random cages and points, values and gradients as the torch graph's.
"""

import numpy as np
import pytest
import torch
from builders import diag, outside_plane_distance, unit_normals
from hypothesis import given, settings
from hypothesis import strategies as st

from cagekit.cage import cage_topology
from cagekit.cage.fitting import template_cage
from cagekit.cage.shapes import icosphere_cage
from cagekit.coords import mean_value_coordinates as core_mvc
from cagekit.coords.mvc_grad import mvc_weights_flagged
from cagekit_learn.coords import compiled_kernels, mean_value_coordinates

F64 = torch.float64
F32 = torch.float32


def star_cage(seed=0, spread=0.35):
    """A non-convex icosphere cage with random radii, rotated and shifted."""
    v, f = icosphere_cage(1)
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    v = (v * rng.uniform(1 - spread, 1 + spread, (len(v), 1))) @ q.T + rng.normal(size=3)
    return v, f


def point_sets(v, f, rng, n=30):
    """Inside, outside (1.2 .. 2.5 D) and near faces (1e-4 D, both sides) of a cage."""
    D = diag(v)
    c = v.mean(axis=0)
    b = rng.dirichlet([1, 1, 1], len(f))
    on = np.einsum("fi,fic->fc", b, v[f])
    inside = (c + rng.uniform(0.05, 0.9, (len(f), 1)) * (on - c))[:n]
    d = rng.normal(size=(n, 3))
    outside = c + rng.uniform(1.2, 2.5, (n, 1)) * D * d / np.linalg.norm(d, axis=1, keepdims=True)
    near = (on + rng.choice([-1.0, 1.0], (len(f), 1)) * 1e-4 * D * unit_normals(v, f))[:n]
    return {"inside": inside, "outside": outside, "near": near}


def weights_and_grads(p, V, f, dtype, kernels, G=None, seed=0):
    """Weights and the gradients of sum(G * W) w.r.t. points and cage (float64 numpy)."""
    P = torch.tensor(p, dtype=dtype, requires_grad=True)
    C = torch.tensor(V, dtype=dtype, requires_grad=True)
    with compiled_kernels(kernels):
        w = mean_value_coordinates(P, C, f)
    if G is None:
        G = np.random.default_rng(seed).normal(size=tuple(w.shape))
    (w * torch.tensor(G, dtype=dtype)).sum().backward()
    return w.detach().double().numpy(), P.grad.double().numpy(), C.grad.double().numpy(), G


def assert_parity(a, b, tol):
    """Each array of ``a`` equals ``b``'s to ``tol`` times its largest magnitude."""
    for x, y in zip(a, b):
        assert np.abs(x - y).max() <= tol * max(1.0, np.abs(y).max()), np.abs(x - y).max()


# ------------------------------------------------------------------------------ gradcheck


@pytest.mark.parametrize("where", ["inside", "outside", "near"])
def test_gradcheck(where):
    v, f = template_cage()
    rng = np.random.default_rng(2)
    D = diag(v)
    fi = rng.integers(len(f), size=3)
    on = np.einsum("fi,fic->fc", rng.dirichlet([2, 2, 2], 3), v[f[fi]])
    p = {"inside": 0.6 * on,
         "outside": np.array([[1.3, 0.7, -0.9], [-1.5, 1.2, 0.4], [0.2, -1.9, 1.1]]),
         "near": on + np.array([[1e-3], [-1e-3], [1e-4]]) * D * unit_normals(v, f)[fi]}[where]
    _, flagged = mvc_weights_flagged(p[None], v[None], f)
    assert not flagged.any()              # the kernels' own rows, not the torch graph's
    P = torch.tensor(p, requires_grad=True)
    V = torch.tensor(v, requires_grad=True)
    assert torch.autograd.gradcheck(lambda a, b: mean_value_coordinates(a, b, f), (P, V),
                                    eps=1e-7, atol=1e-6, rtol=1e-4)


def test_gradcheck_batch_with_spliced_snap_rows():
    """A batch of two cages whose points include rows of the torch graph (within ``snap``
    of a face: its barycentric limit; near a face's plane outside it: that face skipped)
    beside kernel rows: the spliced result is differentiable."""
    v, f = star_cage(3)
    D = diag(v)
    n = unit_normals(v, f)
    V = np.stack([v, 1.1 * v + 0.05])
    on = v[f[:4]].mean(axis=1)
    inside = v.mean(axis=0) + 0.3 * (on - v.mean(axis=0))
    p = np.stack([np.vstack([on[0] - 2e-4 * D * n[0], inside[0], inside[1]]),
                  np.vstack([1.1 * on[1] + 0.05 + 3e-4 * D * n[1], inside[2] * 1.1 + 0.05,
                             inside[3] * 1.1 + 0.05])])
    _, flagged = mvc_weights_flagged(p, V, f, snap=1e-3)
    assert flagged[:, 0].all() and not flagged[:, 1:].any()
    P = torch.tensor(p, requires_grad=True)
    C = torch.tensor(V, requires_grad=True)
    assert torch.autograd.gradcheck(lambda a, b: mean_value_coordinates(a, b, f, snap=1e-3),
                                    (P, C), eps=1e-7, atol=1e-6, rtol=1e-5)


# ------------------------------------------------------------------------------ parity


@pytest.mark.parametrize("name", ["template", "star"])
def test_float64_parity_with_the_torch_graph(name):
    v, f = template_cage() if name == "template" else star_cage(4)
    rng = np.random.default_rng(5)
    sets = point_sets(v, f, rng)
    V = np.stack([v, v * [1.2, 0.9, 1.0] + 0.1])
    for label, tol in (("inside", 1e-9), ("outside", 1e-7)):
        # outside (1.2 .. 2.5 D), where the weights' sum cancels, the kernels and the torch
        # graph are both about 1e-8 (relative) from a 40-digit evaluation of the gradient
        p = sets[label][outside_plane_distance(sets[label], v, f) > 0.02 * diag(v)]
        P = np.stack([p, p])
        ker = weights_and_grads(P, V, f, F64, True)
        ref = weights_and_grads(P, V, f, F64, False, G=ker[3])
        assert_parity(ker[:3], ref[:3], tol)
    # values: the core's, to 1e-12 inside
    inside = sets["inside"][outside_plane_distance(sets["inside"], v, f) > 0.02 * diag(v)]
    w, *_ = weights_and_grads(inside, v, f, F64, True)
    assert np.abs(w - core_mvc(inside, v, f)).max() <= 1e-12


def test_shared_cage_and_unbatched_inputs():
    v, f = template_cage()
    rng = np.random.default_rng(6)
    p = rng.uniform(-0.5, 0.5, (3, 40, 3))
    # one (k, 3) cage shared by a batch: its gradient sums over the batch
    ker = weights_and_grads(p, v, f, F64, True)
    ref = weights_and_grads(p, v, f, F64, False, G=ker[3])
    assert ker[0].shape == (3, 40, 42) and ker[2].shape == (42, 3)
    assert_parity(ker[:3], ref[:3], 1e-9)
    ker = weights_and_grads(p[0], v, f, F64, True)
    ref = weights_and_grads(p[0], v, f, F64, False, G=ker[3])
    assert ker[0].shape == (40, 42)
    assert_parity(ker[:3], ref[:3], 1e-9)


def test_rows_on_the_cage_and_far_rows_are_the_torch_graphs():
    v, f = template_cage()
    e = cage_topology(f).edges
    rng = np.random.default_rng(7)
    d = rng.normal(size=(6, 3))
    far = 15 * diag(v) * d / np.linalg.norm(d, axis=1, keepdims=True)   # in the far blend
    p = np.vstack([v[:6], 0.5 * (v[e[:6, 0]] + v[e[:6, 1]]), v[f[:6]].mean(axis=1),
                   v[f[6:9]].mean(axis=1) * (1 + 1e-15), far, rng.uniform(-0.3, 0.3, (6, 3))])
    ker = weights_and_grads(p, v, f, F64, True)
    ref = weights_and_grads(p, v, f, F64, False, G=ker[3])
    assert_parity(ker[:3], ref[:3], 1e-7)      # far rows: MVC is ill-conditioned there
    assert np.abs(ker[0][:18] - core_mvc(p[:18], v, f)).max() <= 1e-12
    near = np.r_[0:21, 27:33]
    assert_parity([ker[0][near], ker[1][near]], [ref[0][near], ref[1][near]], 1e-9)
    assert np.isfinite(ker[1]).all() and np.isfinite(ker[2]).all()


def test_float32_as_accurate_as_the_torch_graph():
    """The kernels compute float32 inputs in float64: weights within float32 rounding of the
    float64 ones, gradients at least as close to float64's as the torch graph's are."""
    v, f = template_cage()
    sets = point_sets(v, f, np.random.default_rng(8), n=80)
    p = np.vstack(list(sets.values()))
    exact = weights_and_grads(p, v, f, F64, True)
    ker = weights_and_grads(p, v, f, F32, True, G=exact[3])
    ref = weights_and_grads(p, v, f, F32, False, G=exact[3])
    # float32 inputs are float32 points: compare with float64 on the same rounded inputs
    p32 = p.astype(np.float32).astype(np.float64)
    v32 = v.astype(np.float32).astype(np.float64)
    exact = weights_and_grads(p32, v32, f, F64, True, G=exact[3])
    for i in range(3):
        err_kernel = np.abs(ker[i] - exact[i]).max()
        err_graph = np.abs(ref[i] - exact[i]).max()
        assert err_kernel <= max(err_graph, 4 * np.finfo(np.float32).eps * np.abs(exact[i]).max())
    assert np.abs(ker[0] - exact[0]).max() <= 1e-6


# ------------------------------------------------------------------------------ properties


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.floats(0.1, 10.0), spread=st.floats(0.0, 0.4))
def test_property_parity_with_the_torch_graph(seed, scale, spread):
    v, f = star_cage(seed, spread)
    v = v * scale
    rng = np.random.default_rng(seed)
    centre = v.mean(axis=0)
    p = centre + rng.uniform(-1.0, 1.0, (40, 3)) * diag(v)
    p = p[outside_plane_distance(p, v, f) > 0.02 * diag(v)]
    if not len(p):
        return
    ker = weights_and_grads(p, v, f, F64, True)
    ref = weights_and_grads(p, v, f, F64, False, G=ker[3])
    assert_parity(ker[:3], ref[:3], 1e-8)
    assert np.isfinite(ker[1]).all() and np.isfinite(ker[2]).all()


def test_the_kernels_leave_torch_on_the_users_thread_count():
    # numba's OpenMP layer shares the OpenMP thread count with torch; without the restore
    # torch ran on numba's count after the first kernel, and a resumed training run no longer
    # gave the weights of an uninterrupted one
    v, f = star_cage(3)
    cage = torch.tensor(v, requires_grad=True)
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        w = mean_value_coordinates(torch.tensor(v).mean(0, keepdim=True) * 0.9, cage, f)
        (w @ cage).sum().backward()
        assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(before)
    assert torch.isfinite(cage.grad).all()
