"""The MVC kernels with their vector-Jacobian product (cagekit/coords/mvc_grad.py), no torch.

* weights equal :func:`cagekit.coords.mean_value_coordinates` to 1e-12 (well-conditioned
  points inside and near faces from inside; outside, away from the faces' planes, relative
  to the row's 1-norm), and to the conditioning allowance ``(1e-12 + 1e-13 D / h) |W|_1``
  anywhere off the cage;
* rows on or within ``snap`` of the cage, and rows the caller skips, are flagged and zero;
* the vector-Jacobian product matches central finite differences of the weights, with
  respect to the points and the cage vertices, in a batch of two different cages;
* the identities d(W @ V)/dx = I and d(sum W)/d(x, V) = 0.
"""

import numpy as np
import pytest
from builders import diag, outside_plane_distance, unit_normals

from cagekit.cage import cage_topology
from cagekit.cage.fitting import template_cage
from cagekit.cage.shapes import box_cage, icosphere_cage
from cagekit.coords import mean_value_coordinates as core_mvc
from cagekit.coords.mvc_grad import mvc_vjp, mvc_weights_flagged


def star_cage(seed=0, spread=0.35):
    """A non-convex icosphere cage with random radii, rotated and shifted."""
    v, f = icosphere_cage(1)
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    v = (v * rng.uniform(1 - spread, 1 + spread, (len(v), 1))) @ q.T + rng.normal(size=3)
    return v, f


def well_conditioned_points(v, f, rng, n=200, split=False):
    """Points inside (shrunk towards the centroid), near faces from inside (1e-4 D), and
    outside 1.5 .. 3 D from the centre; none within 0.05 D of the plane of a face it
    projects outside of (where single weights are ill-conditioned, for any formula).
    ``split``: the (inside and near, outside) pair."""
    D = diag(v)
    c = v.mean(axis=0)
    b = rng.dirichlet([1, 1, 1], len(f))
    on = np.einsum("fi,fic->fc", b, v[f])
    inside = c + rng.uniform(0.05, 0.9, (len(f), 1)) * (on - c)
    near = on - 1e-4 * D * unit_normals(v, f)
    d = rng.normal(size=(n, 3))
    outside = c + rng.uniform(1.5, 3.0, (n, 1)) * D * d / np.linalg.norm(d, axis=1, keepdims=True)
    sets = [q[outside_plane_distance(q, v, f) > 0.05 * D] for q in (np.vstack([inside, near]),
                                                                   outside)]
    return sets if split else np.vstack(sets)


@pytest.mark.parametrize("name", ["box", "template", "star"])
def test_weights_equal_the_core(name):
    """To 1e-12 inside; outside, where the weights' sum cancels, to 4e-12 of their 1-norm
    (the core and the kernels are then both about that far from a 40-digit evaluation)."""
    v, f = {"box": box_cage(), "template": template_cage(), "star": star_cage()}[name]
    inside, outside = well_conditioned_points(v, f, np.random.default_rng(1), split=True)
    for p, relative in ((inside, False), (outside, True)):
        w, flagged = mvc_weights_flagged(p[None], v[None], f)
        ref = core_mvc(p, v, f)
        assert not flagged.any()
        # outside: 4e-12 of the 1-norm (a CPU without FMA, make test-emulated, reaches
        # 1.2e-12; one with it, 1e-12)
        scale = 4 * np.abs(ref).sum(axis=1) if relative else 1.0
        assert (np.abs(w[0] - ref).max(axis=1) <= 1e-12 * scale).all()
        assert np.abs(w[0].sum(axis=1) - 1).max() <= 1e-13


def test_ill_conditioned_points_within_the_allowance():
    v, f = star_cage(8)
    rng = np.random.default_rng(9)
    p = v.mean(axis=0) + rng.uniform(-1.5, 1.5, (600, 3)) * diag(v)
    w, flagged = mvc_weights_flagged(p[None], v[None], f)
    assert not flagged.any()
    allowance = (1e-12 + 1e-13 * diag(v) / outside_plane_distance(p, v, f)) * np.abs(w[0]).sum(1)
    assert (np.abs(w[0] - core_mvc(p, v, f)).max(axis=1) <= allowance).all()


def test_rows_on_the_cage_and_skipped_rows_are_flagged():
    v, f = template_cage()
    e = cage_topology(f).edges
    on = np.vstack([v[:5], 0.5 * (v[e[:5, 0]] + v[e[:5, 1]]), v[f[:5]].mean(axis=1)])
    inside = np.random.default_rng(2).uniform(-0.3, 0.3, (7, 3))
    p = np.vstack([on, inside])[None]
    w, flagged = mvc_weights_flagged(p, v[None], f)
    assert flagged[0, :15].all() and not flagged[0, 15:].any()
    assert np.abs(w[0, :15]).max() == 0.0
    skip = np.zeros((1, len(p[0])), dtype=bool)
    skip[0, 16] = True
    w2, flagged2 = mvc_weights_flagged(p, v[None], f, skip=skip)
    assert flagged2[0, 16] and np.abs(w2[0, 16]).max() == 0.0
    assert np.abs(w2[0, 17:] - w[0, 17:]).max() <= 1e-15
    # and they get no gradient
    gx, _ = mvc_vjp(p, v[None], f, np.ones_like(w), skip=skip)
    assert np.abs(gx[0, :15]).max() == 0.0 and np.abs(gx[0, 16]).max() == 0.0


def test_vjp_matches_finite_differences():
    rng = np.random.default_rng(3)
    cages = [star_cage(4), star_cage(5)]
    f = cages[0][1]
    V = np.stack([c[0] for c in cages])
    P = np.stack([well_conditioned_points(c[0], f, rng, n=20)[::3][:12] for c in cages])
    G = rng.normal(size=(2, P.shape[1], V.shape[1]))
    gx, gv = mvc_vjp(P, V, f, G)

    def loss(P_, V_):
        w, flagged = mvc_weights_flagged(P_, V_, f)
        assert not flagged.any()
        return float((w * G).sum())

    h = 1e-6
    fd_x = np.zeros_like(P)
    for idx in np.ndindex(*P.shape):
        dp = np.zeros_like(P)
        dp[idx] = h
        fd_x[idx] = (loss(P + dp, V) - loss(P - dp, V)) / (2 * h)
    fd_v = np.zeros_like(V)
    for idx in np.ndindex(*V.shape):
        dv = np.zeros_like(V)
        dv[idx] = h
        fd_v[idx] = (loss(P, V + dv) - loss(P, V - dv)) / (2 * h)
    assert np.abs(gx - fd_x).max() <= 1e-6 * max(1.0, np.abs(fd_x).max())
    assert np.abs(gv - fd_v).max() <= 1e-6 * max(1.0, np.abs(fd_v).max())


def test_reproduction_identities():
    """W @ V = x for every x and V: d(W @ V)_c/dx = e_c, and W sums to 1: d(sum W) = 0."""
    v, f = star_cage(6)
    p = well_conditioned_points(v, f, np.random.default_rng(7), n=30)[None]
    for c in range(3):
        gx, gv = mvc_vjp(p, v[None], f, np.broadcast_to(v[:, c], (1, len(p[0]), len(v))))
        expected = np.zeros(3)
        expected[c] = 1.0
        assert np.abs(gx[0] - expected).max() <= 1e-9
    gx, gv = mvc_vjp(p, v[None], f, np.ones((1, len(p[0]), len(v))))
    assert np.abs(gx).max() <= 1e-9 and np.abs(gv).max() <= 1e-9
