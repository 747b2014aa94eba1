"""Differentiable MVC in torch (cagekit_learn.coords) against the NumPy/numba core.

D is the cage's bounding-box diagonal. What is tested:
* float64 parity with :func:`cagekit.coords.mean_value_coordinates` to 1e-10 inside, outside
  (within 2 D), near faces, edges and vertices (1e-6 .. 1e-3 D away) and exactly on them;
* the exact limit values on vertices, edges and faces;
* gradcheck (float64) w.r.t. points and cage, and finite gradients everywhere, on the cage
  included; the identities d(w @ V)/dx = I and d(w @ V)/dV = 0 off the cage;
* chunking (same result, little memory saved for backward), float32, the API and errors;
* hypothesis properties: partition of unity, linear precision, parity, finite gradients.

Single weights of a point lying *outside* a face close to that face's plane (distance h) are
ill-conditioned, for the core as for this module (about 1e-16 D / h, see
:mod:`cagekit.coords.mvc`); the random-point parity checks allow for it (``parity_tol``).
"""

import numpy as np
import pytest
import torch
from builders import diag, outside_plane_distance, unit_normals
from hypothesis import given, settings
from hypothesis import strategies as st

from cagekit.cage import cage_topology
from cagekit.cage.fitting import template_cage
from cagekit.cage.shapes import box_cage, icosphere_cage
from cagekit.coords import mean_value_coordinates as core_mvc
from cagekit.coords import mean_value_coordinates_textbook
from cagekit.errors import CageError, InputError
from cagekit_learn.coords import (
    DEFAULT_SNAP,
    CageBinding,
    bind,
    deform,
    mean_value_coordinates,
)

F64 = torch.float64
F32 = torch.float32


def star_cage(seed=0, subdivisions=1, spread=0.4):
    """A non-convex cage: an icosphere with random radii (and a random rotation/shift)."""
    v, f = icosphere_cage(subdivisions)
    rng = np.random.default_rng(seed)
    r = rng.uniform(1 - spread, 1 + spread, len(v))
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return (v * r[:, None]) @ q.T * np.array([1.3, 0.8, 1.0]) + rng.normal(size=3), f


CAGES = {
    "box": box_cage(),
    "box2": box_cage(2, half_extent=(1.5, 1.0, 0.5)),   # coplanar faces
    "ico2": icosphere_cage(2, radius=0.7),
    "template": template_cage(),
    "star": star_cage(),
}


def edges_of(f):
    return cage_topology(f).edges


def torch_w(p, v, f, dtype=F64, **kw):
    return mean_value_coordinates(torch.as_tensor(p, dtype=dtype), torch.as_tensor(v, dtype=dtype),
                                  f, **kw)


def parity_tol(p, v, f):
    """1e-10, plus the conditioning allowance 1e-12 D / h of points near a face's plane.

    The worst measured disagreement is about 2000 eps D / h for points outside the cage
    (up to 2 D away), and both implementations are equally far from a long-double
    evaluation there (test_ill_conditioned_points_as_accurate_as_the_core)."""
    with np.errstate(divide="ignore"):
        return 1e-10 + 1e-12 * diag(v) / outside_plane_distance(p, v, f)


def sample_sets(name, rng):
    """Named point sets: inside, outside, near faces/edges/vertices, on vertices/edges/faces."""
    v, f = CAGES[name]
    D = diag(v)
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    e = edges_of(f)
    n = unit_normals(v, f)
    fb = rng.dirichlet([1, 1, 1], len(f))
    on_faces = np.einsum("fi,fic->fc", fb, v[f])
    t = rng.uniform(0.02, 0.98, (len(e), 1))
    on_edges = (1 - t) * v[e[:, 0]] + t * v[e[:, 1]]
    sets = {"vertices": v, "edges": on_edges, "faces": on_faces}
    # inside: shrink face points towards the centroid of the (star-shaped) cage
    s = rng.uniform(0.05, 0.9, (len(f), 1))
    sets["inside"] = v.mean(axis=0) + s * (on_faces - v.mean(axis=0))
    direction = rng.normal(size=(300, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    sets["outside"] = centre + rng.uniform(0.6, 2.0, (300, 1)) * D * direction
    for eps in (1e-6, 1e-4, 1e-3):
        sign = rng.choice([-1.0, 1.0], (len(f), 1))
        sets[f"near-face-{eps:g}"] = on_faces + sign * eps * D * n
        d = rng.normal(size=on_edges.shape)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        sets[f"near-edge-{eps:g}"] = on_edges + eps * D * d
        d = rng.normal(size=v.shape)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        sets[f"near-vertex-{eps:g}"] = v + eps * D * d
    return sets


# ------------------------------------------------------------------------------ parity


@pytest.mark.parametrize("name", sorted(CAGES))
def test_float64_parity_with_core(name):
    v, f = CAGES[name]
    for label, p in sample_sets(name, np.random.default_rng(1)).items():
        w = torch_w(p, v, f).numpy()
        err = np.abs(w - core_mvc(p, v, f)).max(axis=1)
        if label == "outside":  # 1e-10 unless close to the plane of a face (conditioning)
            assert np.all(err <= parity_tol(p, v, f)), label
            assert np.all(err[outside_plane_distance(p, v, f) >= 1e-2 * diag(v)] <= 1e-10)
        else:
            assert err.max() <= 1e-10, (label, err.max())
        assert np.abs(w.sum(axis=1) - 1).max() <= 1e-13, label
        if not label.startswith("outside"):
            assert np.abs(w @ v - p).max() <= 1e-12 * diag(v), label


@pytest.mark.parametrize("name", ["box2", "template", "star"])
def test_exact_limits_on_the_cage(name):
    v, f = CAGES[name]
    rng = np.random.default_rng(2)
    # vertices: unit weight
    assert torch.equal(torch_w(v, v, f), torch.eye(len(v), dtype=F64))
    # edges: linear interpolation
    e = edges_of(f)
    t = rng.uniform(0.01, 0.99, len(e))
    p = (1 - t)[:, None] * v[e[:, 0]] + t[:, None] * v[e[:, 1]]
    w = torch_w(p, v, f).numpy()
    expect = np.zeros_like(w)
    expect[np.arange(len(e)), e[:, 0]] = 1 - t
    expect[np.arange(len(e)), e[:, 1]] = t
    assert np.abs(w - expect).max() <= 1e-12
    # faces: barycentric coordinates
    b = rng.dirichlet([2, 2, 2], len(f))
    p = np.einsum("fi,fic->fc", b, v[f])
    w = torch_w(p, v, f).numpy()
    expect = np.zeros_like(w)
    for r in range(3):
        expect[np.arange(len(f)), f[:, r]] += b[:, r]
    assert np.abs(w - expect).max() <= 1e-12


def test_in_plane_faces_skipped_like_the_core():
    """Points in the plane of faces they lie off (coplanar grid of box2, lines of edges)."""
    v, f = CAGES["box2"]
    rng = np.random.default_rng(3)
    # in the plane z = 0.5 of the top faces, outside the box; on the lines of edges outside
    p_plane = np.column_stack([rng.uniform(-4, 4, 50), rng.uniform(-4, 4, 50), np.full(50, 0.5)])
    p_plane = p_plane[np.abs(p_plane[:, :2]).max(axis=1) > 1.6]
    e = edges_of(f)
    t = rng.choice([-1.5, -0.3, 1.2, 2.5], len(e))
    p_line = (1 - t)[:, None] * v[e[:, 0]] + t[:, None] * v[e[:, 1]]
    for p in (p_plane, p_line):
        w = torch_w(p, v, f).numpy()
        assert np.abs(w - core_mvc(p, v, f)).max() <= 1e-10
        assert np.abs(w @ v - p).max() <= 1e-12 * diag(v)


@pytest.mark.parametrize("name", ["ico2", "star"])
def test_ill_conditioned_points_as_accurate_as_the_core(name):
    """Outside points closest to the plane of a face they lie off: the disagreement with the
    core is conditioning, not a bug -- both are within the conditioning bound of a
    long-double evaluation (the textbook formula, fine at these distances from the planes):
    each row within 5e3 eps D / h (measured: up to about 800 for either). A bound on the
    ratio of the two errors would test the CPU's rounding, not the code."""
    v, f = CAGES[name]
    D = diag(v)
    rng = np.random.default_rng(13)
    d = rng.normal(size=(3000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    p = 0.5 * (v.min(axis=0) + v.max(axis=0)) + rng.uniform(0.6, 2.0, (3000, 1)) * D * d
    h = outside_plane_distance(p, v, f)
    nearest = np.argsort(h)[:60]
    p, h = p[nearest], h[nearest]
    assert h.max() < 1e-3 * D
    ref = mean_value_coordinates_textbook(p, v, f, dtype=np.longdouble).astype(np.float64)
    bound = 5e3 * np.finfo(np.float64).eps * D / h
    err_core = np.abs(core_mvc(p, v, f) - ref).max(axis=1)
    err_torch = np.abs(torch_w(p, v, f).numpy() - ref).max(axis=1)
    assert np.all(err_core <= bound) and np.all(err_torch <= bound), (
        (err_core / bound).max(), (err_torch / bound).max())
    # float32 rows this ill-conditioned are recomputed in float64
    err32 = np.abs(torch_w(p, v, f, dtype=F32).double().numpy() - ref).max()
    assert err32 <= 1e-6


def test_template_snap_distance_default():
    assert DEFAULT_SNAP[F64] == 1e-13 and DEFAULT_SNAP[F32] == 1e-6
    v, f = CAGES["template"]
    D = diag(v)
    p = v[:1] + np.array([[0.5e-13 * D, 0, 0]])     # inside the float64 snap zone
    assert torch_w(p, v, f)[0, 0] == 1.0
    w = torch_w(v[:1] + 1e-9 * D, v, f, snap=1e-8)   # custom snap
    assert w[0, 0] == 1.0


# ---------------------------------------------------------------------------- gradients


def _gradcheck(p, v, f, eps=1e-7, atol=1e-6, rtol=1e-4):
    P = torch.tensor(p, dtype=F64, requires_grad=True)
    V = torch.tensor(v, dtype=F64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda a, b: mean_value_coordinates(a, b, f), (P, V),
                                    eps=eps, atol=atol, rtol=rtol)


def test_gradcheck_interior():
    v, f = CAGES["box"]
    p = np.random.default_rng(4).uniform(-0.8, 0.8, (3, 3))
    _gradcheck(p, v, f)


def test_gradcheck_template_interior_and_outside():
    v, f = CAGES["template"]
    _gradcheck(np.array([[0.1, -0.3, 0.2], [1.3, 0.7, -0.9]]), v, f)


@pytest.mark.parametrize("where", ["face", "edge"])
def test_gradcheck_near_face_and_edge(where):
    v, f = CAGES["star"]
    D = diag(v)
    rng = np.random.default_rng(5)
    fi = rng.integers(len(f), size=2)
    if where == "face":
        p = np.einsum("fi,fic->fc", rng.dirichlet([2, 2, 2], 2), v[f[fi]])
        p = p + np.array([[1e-3], [-1e-3]]) * D * unit_normals(v, f)[fi]
    else:
        p = 0.6 * v[f[fi, 0]] + 0.4 * v[f[fi, 1]] + 1e-3 * D * np.array([[0.6, 0.0, -0.8],
                                                                          [0.0, 1.0, 0.0]])
    _gradcheck(p, v, f)


def test_gradcheck_outside_far():
    v, f = CAGES["box"]
    _gradcheck(np.array([[2.5, 0.3, -1.1], [-3.0, 3.0, 2.0]]), v, f)


def test_gradcheck_batched_cages():
    v, f = CAGES["box"]
    rng = np.random.default_rng(6)
    cages = np.stack([v, v * np.array([1.2, 0.9, 1.1]) + rng.normal(scale=0.05, size=v.shape)])
    P = torch.tensor(rng.uniform(-0.7, 0.7, (2, 2, 3)), requires_grad=True)
    V = torch.tensor(cages, requires_grad=True)
    assert torch.autograd.gradcheck(lambda a, b: mean_value_coordinates(a, b, f), (P, V),
                                    eps=1e-7, atol=1e-6, rtol=1e-4)
    # a shared (k, 3) cage, broadcast over a batch of points
    V1 = torch.tensor(v, requires_grad=True)
    assert torch.autograd.gradcheck(lambda a, b: mean_value_coordinates(a, b, f), (P, V1),
                                    eps=1e-7, atol=1e-6, rtol=1e-4)


def degenerate_points(v, f, rng):
    """On vertices, edges and faces; in the planes of faces outside them; on edge lines
    outside the edges; at tiny distances from all of those."""
    D = diag(v)
    e = edges_of(f)
    fb = rng.dirichlet([1, 1, 1], len(f))
    on_faces = np.einsum("fi,fic->fc", fb, v[f])
    t = rng.uniform(0.05, 0.95, (len(e), 1))
    on_edges = (1 - t) * v[e[:, 0]] + t * v[e[:, 1]]
    tl = rng.choice([-2.0, -0.5, 1.5, 3.0], (len(e), 1))
    on_lines = (1 - tl) * v[e[:, 0]] + tl * v[e[:, 1]]
    # in the plane of a face, outside it (reflected barycentric point)
    fb2 = fb.copy()
    fb2[:, 0] = -fb2[:, 0] - 0.5
    fb2 /= fb2.sum(axis=1, keepdims=True)
    in_planes = np.einsum("fi,fic->fc", fb2, v[f])
    base = np.vstack([v, on_edges, on_faces, on_lines, in_planes])
    jitter = rng.normal(size=base.shape) * D * 10.0 ** rng.uniform(-16, -9, (len(base), 1))
    return np.vstack([base, base + jitter])


@pytest.mark.parametrize("name", ["box2", "template", "star"])
@pytest.mark.parametrize("dtype", [F64, F32])
def test_gradients_finite_everywhere(name, dtype):
    v, f = CAGES[name]
    p = degenerate_points(v, f, np.random.default_rng(7))
    P = torch.tensor(p, dtype=dtype, requires_grad=True)
    V = torch.tensor(v, dtype=dtype, requires_grad=True)
    w = mean_value_coordinates(P, V, f)
    assert torch.isfinite(w).all()
    assert torch.allclose(w.sum(-1), torch.ones((), dtype=dtype), atol=1e-5)
    g = torch.randn(w.shape, dtype=dtype, generator=torch.Generator().manual_seed(0))
    (w * g).sum().backward()
    assert torch.isfinite(P.grad).all() and torch.isfinite(V.grad).all()
    # and through the reproduction identity
    P.grad = V.grad = None
    (mean_value_coordinates(P, V, f) @ V).square().sum().backward()
    assert torch.isfinite(P.grad).all() and torch.isfinite(V.grad).all()


def test_reproduction_jacobians():
    """Off the cage w(x, V) @ V = x for all x and V: d/dx = I, d/dV = 0. On the cage the limit
    interpolants give: a face's orthogonal projector, an edge's line projector, 0 at a vertex."""
    v, f = CAGES["star"]
    rng = np.random.default_rng(8)
    V = torch.tensor(v, requires_grad=True)

    def jac(x):
        X = torch.tensor(x, requires_grad=True)
        rows = []
        for i in range(3):
            (gx, gv) = torch.autograd.grad((mean_value_coordinates(X, V, f) @ V)[0, i], (X, V))
            rows.append((gx[0].numpy(), gv.numpy()))
        return np.array([r[0] for r in rows]), np.array([r[1] for r in rows])

    for x in ([[0.05, 0.1, -0.2]], [[3.0, -1.0, 2.0]]):
        jx, jv = jac(np.array(x) + v.mean(axis=0))
        assert np.abs(jx - np.eye(3)).max() <= 1e-10
        assert np.abs(jv).max() <= 1e-10
    n = unit_normals(v, f)[0]
    jx, _ = jac(rng.dirichlet([2, 2, 2]) @ v[f[0]][None])
    assert np.abs(jx - (np.eye(3) - np.outer(n, n))).max() <= 1e-10
    a, b = v[f[0, 0]], v[f[0, 1]]
    d = (b - a) / np.linalg.norm(b - a)
    jx, _ = jac((0.3 * a + 0.7 * b)[None])
    assert np.abs(jx - np.outer(d, d)).max() <= 1e-10
    jx, _ = jac(v[3:4])
    assert np.abs(jx).max() == 0.0


# ------------------------------------------------------------------------ chunks, memory


def test_chunking_gives_the_same_result():
    v, f = CAGES["template"]
    rng = np.random.default_rng(9)
    p = torch.tensor(rng.uniform(-1.5, 1.5, (2, 700, 3)))
    p[0, :42] = torch.tensor(v)                               # snap rows in several chunks
    V = torch.tensor(v)
    a = mean_value_coordinates(p, V, f, chunk_size=64)
    b = mean_value_coordinates(p, V, f, chunk_size=100000)
    # different chunk sizes are different matrix sizes, which a BLAS may sum in other orders
    torch.testing.assert_close(a, b, rtol=0, atol=1e-13)
    # gradients too
    P1 = p.clone().requires_grad_()
    P2 = p.clone().requires_grad_()
    g = torch.randn(a.shape, dtype=F64, generator=torch.Generator().manual_seed(1))
    (mean_value_coordinates(P1, V, f, chunk_size=64) * g).sum().backward()
    (mean_value_coordinates(P2, V, f, chunk_size=100000) * g).sum().backward()
    torch.testing.assert_close(P1.grad, P2.grad, rtol=1e-9, atol=1e-12 * P2.grad.abs().max())


def test_memory_saved_for_backward_is_small():
    v, f = CAGES["template"]
    rng = np.random.default_rng(10)
    P = torch.tensor(rng.uniform(-0.6, 0.6, (2, 4096, 3)), requires_grad=True)
    V = torch.tensor(np.stack([v, 1.1 * v]), requires_grad=True)
    saved = []

    def pack(t):
        saved.append(t.numel() * t.element_size())
        return t

    with torch.autograd.graph.saved_tensors_hooks(pack, lambda t: t):
        w = mean_value_coordinates(P, V, f)
    out_bytes = w.numel() * w.element_size()
    assert sum(saved) < 4 * out_bytes, (sum(saved), out_bytes)
    (w @ V).sum().backward()
    assert torch.isfinite(P.grad).all() and torch.isfinite(V.grad).all()


# ------------------------------------------------------------------------------ float32


@pytest.mark.parametrize("name", ["box", "template", "star"])
def test_float32_close_to_float64(name):
    v, f = CAGES[name]
    sets = sample_sets(name, np.random.default_rng(11))
    for label in ("vertices", "edges", "faces", "inside", "outside", "near-face-0.0001",
                  "near-face-0.001", "near-edge-0.001", "near-vertex-0.001"):
        p = sets[label]
        w32 = torch_w(p, v, f, dtype=F32)
        assert w32.dtype == F32
        err = np.abs(w32.double().numpy() - core_mvc(p, v, f)).max()
        assert err <= 1e-5, (label, err)


def test_float32_recomputes_only_ill_conditioned_rows(monkeypatch):
    """Outside points go through float64 (else their weights would be off by up to ~1);
    points well inside the cage stay in float32; gradients of both kinds agree with
    float64 ones. (The torch graph's rule, what CUDA tensors use; the CPU kernels compute
    every row in float64: tests/learn/test_mvc_kernel_grad.py.)"""
    import cagekit_learn.coords as mod

    monkeypatch.setattr(mod, "_KERNELS", [False])
    v, f = CAGES["template"]
    calls = []
    original = mod._unnormalised

    def spy(P, *args, **kw):
        calls.append((P.dtype, P.shape[0] * P.shape[1]))
        return original(P, *args, **kw)

    monkeypatch.setattr(mod, "_unnormalised", spy)
    rng = np.random.default_rng(14)
    inside = rng.uniform(-0.45, 0.45, (200, 3))
    d = rng.normal(size=(50, 3))
    outside = 1.5 * d / np.linalg.norm(d, axis=1, keepdims=True)
    torch_w(inside, v, f, dtype=F32)
    assert calls == [(F32, 200)]
    calls.clear()
    torch_w(np.vstack([inside, outside]), v, f, dtype=F32)
    assert calls == [(F32, 250), (F64, 50)]
    p = np.vstack([inside[:20], outside[:20]])
    grads = []
    for dtype in (F32, F64):
        P = torch.tensor(p, dtype=dtype, requires_grad=True)
        V = torch.tensor(v, dtype=dtype, requires_grad=True)
        w = mean_value_coordinates(P, V, f)
        (w * torch.linspace(-1, 1, w.numel(), dtype=dtype).view(w.shape)).sum().backward()
        grads.append((P.grad.double(), V.grad.double()))
    for g32, g64 in zip(*grads):
        assert (g32 - g64).abs().max() <= 1e-4 * g64.abs().max()


# ------------------------------------------------------------------------------ the API


def test_shapes_broadcasting_and_binding():
    v, f = CAGES["box"]
    rng = np.random.default_rng(12)
    p = rng.uniform(-0.9, 0.9, (2, 5, 3))
    V = torch.tensor(v)
    w = mean_value_coordinates(torch.tensor(p[0]), V, f)
    assert w.shape == (5, 8) and w.dtype == F64
    wb = mean_value_coordinates(torch.tensor(p), V, f)              # (k, 3) cage broadcast
    assert wb.shape == (2, 5, 8)
    torch.testing.assert_close(wb[0], w, rtol=0, atol=1e-13)  # BLAS sizes differ
    cages = torch.stack([V, 2 * V])
    w2 = mean_value_coordinates(torch.tensor(p[0]), cages, f)        # points broadcast
    assert w2.shape == (2, 5, 8)
    torch.testing.assert_close(w2[1], mean_value_coordinates(torch.tensor(p[0]), 2 * V, f),
                               rtol=0, atol=1e-13)
    assert mean_value_coordinates(torch.zeros(2, 0, 3, dtype=F64), V, f).shape == (2, 0, 8)
    # bind / deform
    b = bind(torch.tensor(p), V, f)
    assert isinstance(b, CageBinding) and b.method == "mvc" and b.n_points == 5
    torch.testing.assert_close(b.deform(V), torch.tensor(p), rtol=0, atol=1e-13)
    torch.testing.assert_close(b.deform(cages), torch.tensor(p) * torch.tensor([1.0, 2.0])
                               .view(2, 1, 1), rtol=0, atol=1e-13)
    torch.testing.assert_close(deform(b.weights, 2 * V), 2 * torch.tensor(p), rtol=0,
                               atol=1e-13)
    assert deform(w, V).shape == (5, 3)
    # an inward cage is flipped; integer faces as a tensor work too
    wf = mean_value_coordinates(torch.tensor(p), V, torch.tensor(f[:, ::-1].copy()))
    torch.testing.assert_close(wf, wb, rtol=0, atol=1e-15)


def test_input_errors():
    v, f = CAGES["box"]
    V = torch.tensor(v)
    p = torch.zeros(4, 3, dtype=F64)
    bad = [
        (torch.zeros(4, 2, dtype=F64), V, f, "points"),
        (torch.zeros(2, 3, 4, 3, dtype=F64), V, f, "points"),
        (p, V[:, :2], f, "cage_v"),
        (p, V.float(), f, "dtype"),
        (p.int(), V, f, "float32 or float64"),
        (torch.full((4, 3), float("nan"), dtype=F64), V, f, "NaN"),
        (p, V.clone().index_fill_(0, torch.tensor([3]), float("inf")), f, "NaN or inf"),
        (torch.zeros(3, 4, 3, dtype=F64), torch.stack([V, V]), f, "batch"),
    ]
    for pts, cage, faces, words in bad:
        with pytest.raises(InputError, match=words):
            mean_value_coordinates(pts, cage, faces)
    with pytest.raises(CageError, match="open"):
        mean_value_coordinates(p, V, f[:-1])
    with pytest.raises(CageError):
        mean_value_coordinates(p, V, f + 100)
    with pytest.raises(InputError, match="snap"):
        mean_value_coordinates(p, V, f, snap=0.0)
    with pytest.raises(InputError, match="chunk_size"):
        mean_value_coordinates(p, V, f, chunk_size=0)
    with pytest.raises(InputError, match="unknown coordinates"):
        bind(p, V, f, method="harmonic")  # "green" is bound (tests/learn/test_learn_green.py)
    w = mean_value_coordinates(p, V, f)
    with pytest.raises(InputError, match="vertex counts"):
        deform(w, V[:5])
    with pytest.raises(InputError, match="NaN"):
        deform(w, torch.full_like(V, float("nan")))


# --------------------------------------------------------------------------- properties

PROP_CAGES = ["box2", "template", "star"]


@settings(max_examples=30, deadline=None)
@given(name=st.sampled_from(PROP_CAGES), seed=st.integers(0, 2**32 - 1),
       radius=st.floats(0.05, 2.0))
def test_property_random_points(name, seed, radius):
    """Partition of unity, linear precision and parity within 2 D of the centre."""
    v, f = CAGES[name]
    D = diag(v)
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(16, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    p = 0.5 * (v.min(axis=0) + v.max(axis=0)) + rng.uniform(0, radius, (16, 1)) * D * d
    w = torch_w(p, v, f).numpy()
    assert np.abs(w.sum(axis=1) - 1).max() <= 1e-13
    assert np.abs(w @ v - p).max() <= 1e-12 * D
    assert np.all(np.abs(w - core_mvc(p, v, f)).max(axis=1) <= parity_tol(p, v, f))


@settings(max_examples=30, deadline=None)
@given(name=st.sampled_from(PROP_CAGES), seed=st.integers(0, 2**32 - 1),
       where=st.sampled_from(["vertex", "edge", "face"]), exponent=st.floats(-17, -3))
def test_property_on_and_near_the_cage(name, seed, where, exponent):
    """Points on vertices/edges/faces, moved by 10**exponent D (snap zone and just beyond)."""
    v, f = CAGES[name]
    D = diag(v)
    rng = np.random.default_rng(seed)
    fi = rng.integers(len(f), size=8)
    if where == "vertex":
        base = v[f[fi, 0]]
    elif where == "edge":
        t = rng.uniform(0, 1, (8, 1))
        base = (1 - t) * v[f[fi, 0]] + t * v[f[fi, 1]]
    else:
        base = np.einsum("fi,fic->fc", rng.dirichlet([1, 1, 1], 8), v[f[fi]])
    d = rng.normal(size=(8, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    p = np.vstack([base, base + 10.0**exponent * D * d])
    P = torch.tensor(p, requires_grad=True)
    V = torch.tensor(v, requires_grad=True)
    W = mean_value_coordinates(P, V, f)
    w = W.detach().numpy()
    assert np.abs(w.sum(axis=1) - 1).max() <= 1e-13
    assert np.abs(w @ v - p).max() <= 1e-12 * D
    assert np.all(np.abs(w - core_mvc(p, v, f)).max(axis=1) <= parity_tol(p, v, f))
    (W * torch.linspace(-1, 1, W.numel(), dtype=F64).view(W.shape)).sum().backward()
    assert torch.isfinite(P.grad).all() and torch.isfinite(V.grad).all()


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), scale=st.floats(0.1, 10.0),
       dtype=st.sampled_from([F64, F32]))
def test_property_batched_cages_finite_gradients(seed, scale, dtype):
    """Random deformed template cages in a batch: finite weights and gradients, PoU."""
    v, f = CAGES["template"]
    rng = np.random.default_rng(seed)
    cages = scale * (v[None] + rng.normal(scale=0.08, size=(3, len(v), 3)))
    p = scale * rng.uniform(-1.3, 1.3, (3, 20, 3))
    p[:, :3] = cages[:, :3]                          # some points exactly on cage vertices
    P = torch.tensor(p, dtype=dtype, requires_grad=True)
    V = torch.tensor(cages, dtype=dtype, requires_grad=True)
    W = mean_value_coordinates(P, V, f)
    tol = 1e-12 if dtype == F64 else 1e-4
    assert torch.allclose(W.sum(-1), torch.ones((), dtype=dtype), atol=tol)
    (W @ V - P).square().sum().backward()
    assert torch.isfinite(P.grad).all() and torch.isfinite(V.grad).all()
    if dtype == F64:
        ref = np.stack([core_mvc(p[b], cages[b], f) for b in range(3)])
        assert np.all(np.abs(W.detach().numpy() - ref).max(-1)
                      <= np.stack([parity_tol(p[b], cages[b], f) for b in range(3)]))


# --------------------------------------------------------------------------- far outside


def _far_points(v, radii, seed=21):
    d = np.random.default_rng(seed).normal(size=(len(radii), 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    return centre + d * diag(v) * np.asarray(radii)[:, None]


@pytest.mark.parametrize("name", ["star", "box2"])
def test_far_points_follow_the_core_into_the_affine_extension(name):
    """From 10 D the core blends into the affine extension; the twin does the same. MVC
    itself is ill-conditioned out there (3e-10 D at 10 D), hence the looser bound inside the
    blend; beyond it both are the same affine weights."""
    v, f = CAGES[name]
    radii = [5, 9.9, 10.5, 15, 19.9, 30, 1e3, 1e6, 1e12]
    p = _far_points(v, radii)
    w = torch_w(p, v, f).numpy()
    ref = core_mvc(p, v, f)
    scale = np.abs(ref).max(axis=1)
    blend = np.asarray(radii) < 20
    assert np.all(np.abs(w - ref).max(axis=1)[blend] <= 1e-8 * scale[blend])
    assert np.all(np.abs(w - ref).max(axis=1)[~blend] <= 1e-12 * scale[~blend])
    assert np.all(np.abs(w @ v - p).max(axis=1) <= 1e-12 * np.abs(p).max(axis=1) + 1e-9)
    w32 = torch_w(p, v, f, dtype=F32).double().numpy()
    assert np.all(np.abs(w32 - ref).max(axis=1) <= 1e-5 * scale)


def test_gradcheck_in_the_far_blend():
    """MVC 10-20 D away carries rounding noise of ~1e-9 (its ill-conditioning): central
    differences with a step eps are off by noise / eps (measured: 2e-5 at eps 1e-3, 1e-3 at
    1e-5), so the step is large and the tolerance matches that noise."""
    v, f = CAGES["star"]  # no ties in its bounding box: the blend factor is differentiable
    _gradcheck(_far_points(v, [12.0, 16.0, 25.0]), v, f, eps=1e-3, atol=1e-4, rtol=1e-3)


def test_gradients_stay_finite_when_one_point_is_far():
    """A point at the cage's centre beside a far one: the far rule must not touch it."""
    v, f = CAGES["box"]
    P = torch.tensor([[0.0, 0.0, 0.5], [0.3, 0.2, 0.1], [100.0, 0.0, 0.0]], dtype=F64,
                     requires_grad=True)
    V = torch.tensor(v, requires_grad=True)
    (mean_value_coordinates(P, V, f) @ V).sum().backward()
    assert torch.isfinite(P.grad).all() and torch.isfinite(V.grad).all()
    # linear precision: d(sum W V)/dP = 1 for every coordinate
    torch.testing.assert_close(P.grad, torch.ones_like(P), rtol=0, atol=1e-9)


def test_a_kept_cage_does_not_follow_edits_of_a_binding_handed_out():
    """The layer keeps each cage's constants; a caller editing the faces a binding handed
    out must not reach them (the kept faces are the layer's own copy)."""
    v, f = box_cage()
    V = torch.tensor(v, dtype=torch.float64)
    x = torch.tensor(np.random.default_rng(0).uniform(-0.4, 0.4, (50, 3)))
    binding = bind(x, V, f)
    before = mean_value_coordinates(x, V, f)
    binding.cage_f[0] = binding.cage_f[0].flip(0).clone()  # edited in place
    after = mean_value_coordinates(x, V, f)
    assert torch.equal(after, before)
