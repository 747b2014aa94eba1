"""The part-affinity term of the learned mode (issue 32): each sample's part from the source
mesh's components, the torch term equal to ``cagekit deform``'s NumPy term (value and
gradient), and training with it (and old runs resuming without it)."""

import csv

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from builders import TINY_MODEL, icosphere  # noqa: E402

from cagekit.deformation import terms as npl  # noqa: E402
from cagekit.errors import InputError  # noqa: E402
from cagekit.io import save_mesh  # noqa: E402
from cagekit_learn import data, losses  # noqa: E402
from cagekit_learn.data import ShapeCollection, make_batch, sample_parts  # noqa: E402
from cagekit_learn.train import (  # noqa: E402
    ALPHA_PARTS,
    TERMS,
    TrainConfig,
    training_loss,
)

MIN = losses.MIN_PART_POINTS


# ------------------------------------------------------------------------------- helpers


def parted(seed, sizes, flat=()):
    """Random rest points in parts of the given sizes (labels 0, 1, ...; a label in
    ``flat`` lies in a plane) and their labels, shuffled together."""
    rng = np.random.default_rng(seed)
    points, labels = [], []
    for label, size in enumerate(sizes):
        P = rng.normal(size=(size, 3)) * rng.uniform(0.2, 1.0, 3) + rng.uniform(-1, 1, 3)
        if label in flat:
            P[:, 2] = 0.3
        points.append(P)
        labels.append(np.full(size, label))
    order = rng.permutation(sum(sizes))
    return np.concatenate(points)[order], np.concatenate(labels)[order]


def per_part_affine(X, labels, seed):
    """``X`` with a random affine map applied to each part."""
    rng = np.random.default_rng(seed)
    Y = X.copy()
    for label in np.unique(labels):
        rows = labels == label
        Y[rows] = X[rows] @ rng.normal(size=(3, 3)) + rng.normal(size=3)
    return Y


# ------------------------------------------------------------------------------- the term


def test_the_torch_term_is_the_core_term_value_and_gradient():
    # two batch items, different parts: the second has a part too small to count and
    # unlabelled points, which both forms leave out
    shapes = [parted(0, [40, 25, 30]), parted(1, [50, MIN - 1, 95 - 50 - (MIN - 1)])]
    shapes[1][1][:5] = -1
    rest = np.stack([X for X, _ in shapes])
    labels = np.stack([lab for _, lab in shapes])
    moved = rest + 0.1 * np.random.default_rng(2).normal(size=rest.shape)
    ref = losses.part_reference(torch.tensor(rest), labels)
    X = torch.tensor(moved, requires_grad=True)
    values = losses.part_affinity_loss(X, ref)
    values.sum().backward()
    for b in range(2):
        value, grad = npl.part_affinity_loss(moved[b], npl.part_bases(rest[b], labels[b], MIN))
        assert values[b].item() == pytest.approx(value, rel=1e-12)
        np.testing.assert_allclose(X.grad[b].numpy(), grad, rtol=0, atol=1e-12 * abs(grad).max())
    assert (ref.ids[1][labels[1] == 1] == -1).all()  # the small part is no part


def test_any_affine_map_of_each_part_costs_nothing():
    X, labels = parted(3, [30, 40, 20], flat=(1,))  # a flat part spans 3 affine functions
    ref = losses.part_reference(torch.tensor(X)[None], labels[None])
    moved = torch.tensor(per_part_affine(X, labels, seed=4))[None]
    assert losses.part_affinity_loss(moved, ref).item() < 1e-20
    bent = moved.clone()
    bent[0, :3] += 0.5
    assert losses.part_affinity_loss(bent, ref).item() > 1e-3


def test_the_gradient_passes_gradcheck():
    X, labels = parted(5, [12, 15, 10])
    ref = losses.part_reference(torch.tensor(X)[None], labels[None])
    moved = torch.tensor(X + 0.2 * np.random.default_rng(6).normal(size=X.shape))[None]
    assert torch.autograd.gradcheck(lambda Y: losses.part_affinity_loss(Y, ref),
                                    (moved.requires_grad_(True),))


@pytest.mark.parametrize("labels", [np.zeros(40, int), np.full(40, -1),
                                    np.repeat([0, 1], [40 - MIN + 1, MIN - 1])],
                         ids=["one part", "no labels", "one part and a small one"])
def test_a_source_of_fewer_than_two_parts_costs_nothing(labels):
    X = np.random.default_rng(7).normal(size=(40, 3))
    ref = losses.part_reference(torch.tensor(X)[None], labels[None])
    Y = torch.tensor(X + np.random.default_rng(8).normal(size=X.shape))[None]
    Y.requires_grad_(True)
    value = losses.part_affinity_loss(Y, ref)
    value.sum().backward()
    assert value.item() == 0.0 and not Y.grad.any()


def test_float32_agrees_with_float64():
    X, labels = parted(9, [200, 300, 150])
    moved = X + 0.05 * np.random.default_rng(10).normal(size=X.shape)
    v = {dtype: losses.part_affinity_loss(
        torch.tensor(moved, dtype=dtype)[None],
        losses.part_reference(torch.tensor(X, dtype=dtype)[None], labels[None])).item()
        for dtype in (torch.float32, torch.float64)}
    assert v[torch.float32] == pytest.approx(v[torch.float64], rel=1e-4)


def test_bad_labels_are_refused():
    with pytest.raises(InputError, match="part labels"):
        losses.part_reference(torch.zeros(1, 10, 3), np.zeros((1, 9), int))
    with pytest.raises(InputError, match="part labels"):
        ShapeCollection.from_arrays(["a", "b"], np.zeros((2, 8, 3)), np.zeros((2, 7), int))


# ------------------------------------------------------------------------------- the data


def two_spheres_and_a_crumb():
    """Two icospheres (42 vertices each: parts) and one stray triangle (no part)."""
    V, F = icosphere(1)
    crumb = np.array([[3.0, 0, 0], [3.2, 0, 0], [3.0, 0.2, 0]])
    Vs = np.concatenate([V, V + [2.5, 0, 0], crumb])
    Fs = np.concatenate([F, F + len(V), [[2 * len(V), 2 * len(V) + 1, 2 * len(V) + 2]]])
    return Vs, Fs


def test_each_sample_gets_the_component_of_its_face():
    V, F = two_spheres_and_a_crumb()
    faces = np.array([0, len(F) // 2 + 1, len(F) - 1, 3])
    assert sample_parts(V, F, faces).tolist() == [0, 1, -1, 0]


def test_folder_samples_carry_their_parts_through_the_cache(tmp_path, monkeypatch):
    V, F = two_spheres_and_a_crumb()
    save_mesh(tmp_path / "two.obj", V, F)
    save_mesh(tmp_path / "one.obj", *icosphere(1))
    first = ShapeCollection.from_folder(tmp_path, points=256)
    two = first.parts[first.names.index("two.obj")]
    assert set(two.tolist()) <= {-1, 0, 1} and {0, 1} <= set(two.tolist())
    # the two spheres' samples lie on their own sphere
    x = first.points[first.names.index("two.obj"), :, 0]
    assert x[two == 0].max() < x[two == 1].min()
    assert set(first.parts[first.names.index("one.obj")].tolist()) == {0}

    def fail(*args, **kwargs):
        raise AssertionError("mesh read on a cache hit")

    monkeypatch.setattr(data, "load_shape", fail)
    second = ShapeCollection.from_folder(tmp_path, points=256)
    assert np.array_equal(second.parts, first.parts)


def test_a_cache_without_parts_is_rebuilt_with_the_same_samples(tmp_path):
    V, F = two_spheres_and_a_crumb()
    save_mesh(tmp_path / "a.obj", V, F)
    save_mesh(tmp_path / "b.obj", V * 2, F)
    first = ShapeCollection.from_folder(tmp_path, points=64)
    cache = tmp_path / data.CACHE_DIRNAME
    manifest = (cache / "manifest.json").read_text()
    # as the previous version wrote it: format 1, no parts
    assert f'"format": {data.CACHE_FORMAT}' in manifest
    (cache / "manifest.json").write_text(manifest.replace(f'"format": {data.CACHE_FORMAT}',
                                                          '"format": 1'))
    with np.load(cache / "samples.npz") as npz:
        old = {k: npz[k] for k in ("token", "names", "points")}
    np.savez(cache / "samples.npz", **old)
    again = ShapeCollection.from_folder(tmp_path, points=64)
    assert np.array_equal(again.points, first.points)
    assert np.array_equal(again.parts, first.parts)
    with np.load(cache / "samples.npz") as npz:
        assert "parts" in npz.files


def test_synthetic_chairs_have_parts_vases_one_and_batches_carry_them():
    chairs = ShapeCollection.synthetic("chairs", n=2, points=256, resolution=0.5)
    vases = ShapeCollection.synthetic("vases", n=2, points=64, resolution=0.5)
    assert all(len(set(p[p >= 0].tolist())) >= 5 for p in chairs.parts)
    assert all(set(p.tolist()) == {0} for p in vases.parts)
    batch = make_batch(chairs, [[1, 0]], epoch=0, step=0)
    assert batch["source_parts"].dtype == torch.long
    assert np.array_equal(batch["source_parts"][0].numpy(), chairs.parts[1])
    fixed = make_batch(chairs, [[data.FIXED_SOURCE, 0]], epoch=0, step=0,
                       source_points=chairs.points[0])
    assert (fixed["source_parts"] == -1).all()


def test_shapes_in_correspondence_take_their_vertices_parts(tmp_path):
    V, F = two_spheres_and_a_crumb()
    save_mesh(tmp_path / "a.obj", V, F)
    save_mesh(tmp_path / "b.obj", V * [1, 2, 1], F)
    c = ShapeCollection.corresponding(tmp_path, points=32)
    expected = np.where(c.rows < 42, 0, np.where(c.rows < 84, 1, -1))
    assert np.array_equal(c.parts[0], expected) and np.array_equal(c.parts[1], expected)


# --------------------------------------------------------------------------- training


@pytest.fixture(scope="module")
def chairs():
    return ShapeCollection.synthetic("chairs", n=4, seed=1, points=128, resolution=0.5)


def _net():
    from cagekit_learn.networks import ModelConfig, NeuralCages

    torch.manual_seed(0)
    net = NeuralCages(ModelConfig(**TINY_MODEL))
    for p in net.parameters():  # away from the untrained model's affine motion
        torch.nn.init.normal_(p, std=0.05)
    return net


def _config(tmp_path, **overrides):
    return TrainConfig(**{"data": "synthetic:chairs:4", "run_dir": str(tmp_path / "run"),
                          "points": 128, "batch_size": 2, "model": TINY_MODEL, **overrides})


def test_a_training_step_with_the_term_reports_it_and_counts_it(tmp_path, chairs):
    batch = make_batch(chairs, [[0, 1], [2, 3]], epoch=0, step=0)
    net = _net()
    args = (net, batch["source"], batch["target"])
    # a weight large enough that the term is a fair share of the float32 total: the
    # difference of two totals is exact only to a few of the total's ulps
    weight = 1e4
    total, terms = training_loss(*args, _config(tmp_path, alpha_parts=weight),
                                 source_parts=batch["source_parts"])
    assert np.isfinite(terms["parts"]) and terms["parts"] > 0
    off_total, off = training_loss(*args, _config(tmp_path, alpha_parts=0.0),
                                   source_parts=batch["source_parts"])
    assert "parts" not in off
    added = float((total - off_total).detach())
    ulps = 8 * float(np.finfo(np.float32).eps) * float(total.detach())
    assert added > 100 * ulps
    assert added == pytest.approx(weight * terms["parts"], rel=1e-4, abs=ulps)
    total.backward()
    assert all(torch.isfinite(p.grad).all() for p in net.parameters() if p.grad is not None)


def test_the_term_is_zero_on_a_single_part_source(tmp_path):
    vases = ShapeCollection.synthetic("vases", n=2, seed=1, points=128, resolution=0.5)
    batch = make_batch(vases, [[0, 1]], epoch=0, step=0)
    _, terms = training_loss(_net(), batch["source"], batch["target"], _config(tmp_path),
                             source_parts=batch["source_parts"])
    assert terms["parts"] == 0.0


def test_a_tiny_run_logs_the_term(tmp_path, chairs):
    from cagekit_learn.train import train

    result = train(_config(tmp_path, epochs=1, checkpoint_every=5), progress=False,
                   collection=chairs)
    with open(tmp_path / "run" / "log.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == result.step == 2
    assert all(np.isfinite(float(r["parts"])) for r in rows)
    assert "parts" in result.last_losses


def test_the_parts_weight_defaults_the_same_everywhere_and_old_runs_resume_without_it():
    from cagekit.cli.train import _STORED_OPTIONS
    from cagekit.cli.train import train as command

    option = next(p for p in command.params if p.name == "parts_weight")
    assert option.default == ALPHA_PARTS == TrainConfig(data="d", run_dir="r").alpha_parts
    assert _STORED_OPTIONS["parts_weight"] == "alpha_parts"
    stored = TrainConfig(data="d", run_dir="r").to_dict()
    del stored["alpha_parts"]  # a checkpoint written before the term
    assert TrainConfig.from_dict(stored).alpha_parts == 0.0


def test_an_old_log_without_the_column_is_kept_on_resume(tmp_path):
    from cagekit_learn.train import _Log

    old = ["step", "epoch", "loss", *[t for t in TERMS if t != "parts"], "skipped", "seconds"]
    with open(tmp_path / "log.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=old)
        writer.writeheader()
        for step in (1, 2, 3):
            writer.writerow({"step": step, "epoch": 0, "loss": 0.5, "align": 0.5,
                             "skipped": 0, "seconds": step})
    log = _Log(tmp_path, active=True, resume_step=2)
    log.write({"step": 3, "epoch": 0, "loss": 0.4, "align": 0.3, "parts": 0.001})
    log.close()
    with open(tmp_path / "log.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [r["step"] for r in rows] == ["1", "2", "3"]
    assert [r["parts"] for r in rows] == ["", "", "0.001"]
