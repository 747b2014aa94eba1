"""The torch twin of Green coordinates (issue 19, item 3): parity with the core in
float64, gradients checked against finite differences inside and near faces, the
deformation differentiable in the moved cage."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from builders import CAGES, diag  # noqa: E402

from cagekit.cage.shapes import box_cage  # noqa: E402
from cagekit.coords import bind  # noqa: E402
from cagekit.coords.green import green_coordinates as core_green  # noqa: E402
from cagekit.errors import InputError  # noqa: E402
from cagekit_learn.green import green_coordinates, green_deform, stretch_factors  # noqa: E402


def nasty_points(v, f, seed):
    """Inside and outside, near faces (1e-7 D), on vertices and on edges."""
    rng = np.random.default_rng(seed)
    D = diag(v)
    centre = v[f].mean(axis=1)
    normal = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    return np.vstack([rng.uniform(v.min(axis=0) - 0.2 * D, v.max(axis=0) + 0.2 * D, (200, 3)),
                      centre[:8] - 1e-7 * D * normal[:8], centre[:8] + 1e-7 * D * normal[:8],
                      v[:4], 0.5 * (v[f[:4, 0]] + v[f[:4, 1]])])


@pytest.mark.parametrize("name", sorted(set(CAGES) - {"sliver"}))
def test_coordinates_equal_the_core(name):
    v, f = CAGES[name]
    p = nasty_points(v, f, 1)
    phi, psi = core_green(p, v, f)
    tphi, tpsi = green_coordinates(torch.tensor(p), torch.tensor(v), f)
    np.testing.assert_allclose(tphi.numpy(), phi, rtol=0, atol=1e-10)
    np.testing.assert_allclose(tpsi.numpy(), psi, rtol=0, atol=1e-10 * diag(v))


def test_deformations_equal_the_core_on_the_sliver_cage():
    # a sliver's vertex coordinates carry rounding of ~eps / its aspect (1e-9) in both
    # implementations (the hat functions' gradients are 1e9 there); the rest cage does not
    # see it (reproduction holds to 1e-14 D), a motion that tears the sliver apart does:
    # 7e-9 D measured for a random motion of 0.05 D
    v, f = CAGES["sliver"]
    p = nasty_points(v, f, 2)
    moved = v + 0.05 * np.random.default_rng(3).normal(size=v.shape)
    expected = bind(p, v, f, method="green").deform(moved)
    tphi, tpsi = green_coordinates(torch.tensor(p), torch.tensor(v), f)
    result = green_deform(tphi, tpsi, torch.tensor(v), torch.tensor(moved), f)
    np.testing.assert_allclose(result.numpy(), expected, rtol=0, atol=3e-8 * diag(v))


def _small_case():
    v, f = box_cage(1)
    D = diag(v)
    points = np.array([[0.1, -0.2, 0.3], [-0.5, 0.4, 0.2],
                       [0.2, 0.1, 1.0 - 1e-4 * D],  # near a face, inside
                       [0.3, -0.4, 1.0 + 1e-3 * D]])  # outside, past that face
    return v, f, points


def test_gradients_in_points_and_cage_match_finite_differences():
    v, f, points = _small_case()
    X = torch.tensor(points, requires_grad=True)
    V = torch.tensor(v, requires_grad=True)
    weights = torch.linspace(0.3, 1.7, len(v) * len(points), dtype=torch.float64)

    def scalar(X, V):
        phi, psi = green_coordinates(X, V, f)
        return (phi.reshape(-1) * weights).sum() + 0.7 * psi.sum()

    assert torch.autograd.gradcheck(scalar, (X, V), eps=1e-6, atol=1e-6, rtol=1e-5)


def test_deformation_gradients_in_the_moved_cage():
    v, f, points = _small_case()
    phi, psi = green_coordinates(torch.tensor(points), torch.tensor(v), f)
    rest = torch.tensor(v)
    moved = (rest * torch.tensor([1.3, 0.8, 1.1], dtype=torch.float64)).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda W: green_deform(phi, psi, rest, W, f), (moved,),
                                    eps=1e-6, atol=1e-6, rtol=1e-5)


def test_stretch_factors_equal_the_core():
    from cagekit.coords.green import stretch_factors as core_stretch

    v, f = CAGES["sliver"]
    moved = v * [2.0, 1.0, 0.5] + 0.01 * np.random.default_rng(4).normal(size=v.shape)
    np.testing.assert_allclose(stretch_factors(torch.tensor(v), torch.tensor(moved), f).numpy(),
                               core_stretch(v, moved, f), rtol=1e-12)


def test_bad_inputs():
    v, f = box_cage(1)
    with pytest.raises(InputError, match="tensor"):
        green_coordinates(np.zeros((1, 3)), torch.tensor(v), f)
    with pytest.raises(InputError, match="dtype"):
        green_coordinates(torch.zeros((1, 3), dtype=torch.float32), torch.tensor(v), f)
    with pytest.raises(InputError, match="shape"):
        green_coordinates(torch.zeros((1, 2), dtype=torch.float64), torch.tensor(v), f)


# ------------------------------------------------- cagekit_learn.bind(..., method="green")


@pytest.mark.parametrize("name", ["box3", "ico1", "star"])
def test_bind_green_equals_the_core_binding(name):
    # issue 33, item 6: the learned mode's bind takes "green" and returns what the core's
    # bind returns for it, in float64, the faces flipped like the core's when inward
    import cagekit_learn
    from cagekit_learn.green import GreenBinding

    v, f = CAGES[name]
    p = nasty_points(v, f, 5)
    moved = v * [1.2, 0.9, 1.1] + 0.02 * diag(v) * np.random.default_rng(6).normal(
        size=v.shape)
    core = bind(p, v, f, method="green")
    for faces in (f, f[:, ::-1].copy()):
        b = cagekit_learn.bind(torch.tensor(p), torch.tensor(v), faces, method="green")
        assert isinstance(b, GreenBinding) and b.method == "green"
        assert b.n_points == len(p)
        np.testing.assert_allclose(b.phi.numpy(), core.phi, rtol=0, atol=1e-10)
        np.testing.assert_allclose(b.psi.numpy(), core.psi, rtol=0, atol=1e-10 * diag(v))
        np.testing.assert_allclose(b.deform(moved).numpy(), core.deform(moved), rtol=0,
                                   atol=1e-9 * diag(v))
        np.testing.assert_allclose(b.deform(torch.tensor(v)).numpy(), p, rtol=0,
                                   atol=1e-9 * diag(v))


def test_bind_green_is_differentiable_and_refuses_batches():
    import cagekit_learn

    v, f = box_cage(1)
    cage = torch.tensor(v, requires_grad=True)
    b = cagekit_learn.bind(torch.tensor([[0.1, 0.2, -0.3]], dtype=torch.float64), cage, f,
                           method="green")
    b.deform(2 * cage).sum().backward()
    assert bool(torch.isfinite(cage.grad).all()) and float(cage.grad.abs().sum()) > 0
    with pytest.raises(InputError, match="one cage at a time"):
        cagekit_learn.bind(torch.zeros(2, 4, 3, dtype=torch.float64), torch.tensor(v), f,
                           method="green")
    with pytest.raises(InputError, match="vertex counts"):
        b.deform(torch.zeros(3, 3, dtype=torch.float64))
    with pytest.raises(InputError, match="available: mvc, green"):
        cagekit_learn.bind(torch.zeros(1, 3, dtype=torch.float64), torch.tensor(v), f,
                           method="harmonic")


def test_dir_lists_the_lazy_names():
    # issue 33, item 6: the names loaded on first use are listed by dir()
    import cagekit_learn

    listed = dir(cagekit_learn)
    assert set(cagekit_learn.__all__) <= set(listed)
    assert {"bind", "GreenBinding", "load_model"} <= set(listed)
    for name in cagekit_learn.__all__:
        assert getattr(cagekit_learn, name) is not None
