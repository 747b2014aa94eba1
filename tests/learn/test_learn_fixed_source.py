"""Training with a fixed source (`cagekit train --fixed-source`): one template is the
source of every pair, its poses (in correspondence) are the targets, with the L2 loss."""

import csv
import warnings

import numpy as np
import pytest

torch = pytest.importorskip("torch")
trimesh = pytest.importorskip("trimesh")

from builders import TINY_MODEL, invoke, states_equal  # noqa: E402

from cagekit import io  # noqa: E402
from cagekit.errors import InputError  # noqa: E402
from cagekit.geometry.frame import Frame  # noqa: E402
from cagekit_learn.checkpoint import load_checkpoint  # noqa: E402
from cagekit_learn.data import (  # noqa: E402
    FIXED_SOURCE,
    ShapeCollection,
    corresponding_rows,
    fixed_source_pairs,
    make_batch,
    shard,
)
from cagekit_learn.inference import deform_with_model, predict_fixed_source  # noqa: E402
from cagekit_learn.networks import ModelConfig, NeuralCages  # noqa: E402
from cagekit_learn.threads import one_thread  # noqa: E402
from cagekit_learn.train import TrainConfig, load_model, train  # noqa: E402

POINTS = 128  # of the 162 vertices of icosphere(2)
SEED = 1
# the template's own frame: an ellipsoid away from the origin, not of unit size
STRETCH = np.array([1.2, 1.0, 0.8])
SCALE, SHIFT = 3.0, np.array([1.0, 2.0, 3.0])


def _unit(V):
    """V in its own unit frame."""
    return Frame.of(V).to_unit(V)


def _place(V):
    return V * STRETCH * SCALE + SHIFT


@pytest.fixture(autouse=True)
def torch_on_one_thread():
    """Per test, since numba's OpenMP layer (cagekit.bind) resets the OpenMP thread count
    that torch reads too."""
    with one_thread():
        yield


def _poses(V):
    """Six smooth deformations of the unit sphere's vertices (consistent vertex order)."""
    x, y, z = V.T
    angle = 0.6 * z
    return [
        V * [1.3, 1.0, 1.0],
        V * [1.0, 0.7, 1.1],
        np.stack([x + 0.4 * y**2, y, z], axis=1),  # bent
        np.stack([x * np.cos(angle) - y * np.sin(angle),
                  x * np.sin(angle) + y * np.cos(angle), z], axis=1),  # twisted
        np.stack([x * (1 + 0.3 * z), y * (1 + 0.3 * z), z], axis=1),  # tapered
        np.stack([x + 0.3 * z**2, 0.8 * y, 1.2 * z], axis=1),
    ]


@pytest.fixture(scope="module")
def shapes(tmp_path_factory):
    """A folder of six poses, the rest-pose template and a cage around it (own frame)."""
    root = tmp_path_factory.mktemp("human")
    sphere = trimesh.creation.icosphere(subdivisions=2)
    V0, F = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    data = root / "poses"
    data.mkdir()
    for i, V in enumerate(_poses(V0)):
        io.save_mesh(data / f"pose{i}.obj", _place(V), F)
    template = root / "template.obj"
    io.save_mesh(template, _place(V0), F)
    ico = trimesh.creation.icosphere(subdivisions=1)
    cage = root / "template_cage.obj"
    io.save_mesh(cage, _place(1.4 * np.asarray(ico.vertices)), np.asarray(ico.faces))
    other = root / "coarse.obj"  # another vertex count
    io.save_mesh(other, _place(np.asarray(ico.vertices)), np.asarray(ico.faces))
    return {"data": data, "template": template, "cage": cage, "coarse": other}


def _train_args(shapes, run, *extra):
    return ["train", shapes["data"], "-o", run, "--fixed-source", shapes["template"],
            "--align", "l2", "--points", POINTS, "--bottleneck", 16, "--batch-size", 2,
            "--seed", SEED, *extra]


@pytest.fixture(scope="module")
def run_dir(shapes, tmp_path_factory):
    """Three steps with the template as fixed source and its cage (through the CLI)."""
    run = tmp_path_factory.mktemp("fixed") / "run"
    with one_thread():
        result = invoke(*_train_args(shapes, run, "--source-cage", shapes["cage"],
                                     "--max-steps", 3))
    assert result.exit_code == 0, result.output
    return run


def _config(tmp_path, shapes, **overrides):
    values = {"data": str(shapes["data"]), "run_dir": str(tmp_path / "run"),
              "points": POINTS, "batch_size": 2, "seed": SEED, "model": TINY_MODEL,
              "align": "l2", "fixed_source": str(shapes["template"]), "checkpoint_every": 2}
    return TrainConfig(**{**values, **overrides})


# ------------------------------------------------------------------------------ pairs


def test_fixed_source_pairs_visit_every_target_once_per_epoch():
    first = fixed_source_pairs(7, epoch=0, seed=2)
    assert first.shape == (7, 2) and first.dtype == np.int64
    assert (first[:, 0] == FIXED_SOURCE).all()
    assert sorted(first[:, 1].tolist()) == list(range(7))
    assert np.array_equal(first, fixed_source_pairs(7, epoch=0, seed=2))
    later = [fixed_source_pairs(7, epoch=e, seed=2) for e in range(1, 4)]
    for pairs in later:
        assert sorted(pairs[:, 1].tolist()) == list(range(7))
    assert any(not np.array_equal(first, p) for p in later)  # the order changes
    assert not np.array_equal(first, fixed_source_pairs(7, epoch=0, seed=3))
    # sharded like epoch_pairs: disjoint shares of the same targets
    a, b = shard(first, 0, 2), shard(first, 1, 2)
    assert len(a) == len(b) == 3 and not set(a[:, 1]) & set(b[:, 1])
    points = np.random.default_rng(0).random((3, 4, 3))
    with pytest.raises(InputError, match="needs source_points"):
        make_batch(points, [[FIXED_SOURCE, 0]], epoch=0, step=0)
    with pytest.raises(InputError, match="source index must be"):
        make_batch(points, [[1, 0]], epoch=0, step=0, source_points=points[2])


# --------------------------------------------------------------------------- training


def test_cli_stores_the_template_samples_and_its_cage_in_the_template_frame(run_dir, shapes):
    payload = load_checkpoint(run_dir)
    mc, config = payload["model_config"], payload["config"]
    assert payload["step"] == 3
    assert config["fixed_source"] == str(shapes["template"]) and config["align"] == "l2"
    Vt, _ = io.load_mesh(shapes["template"])
    frame = Frame.of(Vt)
    Vn, center, scale = frame.to_unit(Vt), frame.centre, frame.scale
    # the cage file is in the template's frame; the model holds it normalised with it
    cage_v, cage_f = io.load_mesh(shapes["cage"])
    assert np.allclose(mc["fixed_cage_v"], (cage_v - center) / scale, atol=1e-6)
    assert np.array_equal(mc["fixed_cage_f"], cage_f)
    rows = np.asarray(mc["fixed_source_rows"])
    assert rows.shape == (POINTS,) and len(set(rows.tolist())) == POINTS
    collection = ShapeCollection.corresponding(shapes["data"], points=POINTS, seed=SEED)
    assert np.array_equal(rows, collection.rows)
    assert np.array_equal(rows, corresponding_rows(len(Vt), POINTS, SEED))
    assert np.allclose(mc["fixed_source_points"], Vn[rows], atol=1e-6)
    assert mc["fixed_source_vertex_count"] == len(Vt) == 162
    assert np.allclose(mc["fixed_source_center"], center) and mc["fixed_source_scale"] == scale
    model, _ = load_model(run_dir)
    assert torch.equal(model.fixed_source, torch.tensor(Vn[rows], dtype=torch.float32))
    assert "fixed_source" not in model.state_dict()  # configs carry it, not the weights


def test_every_batch_has_the_template_as_source_and_augments_only_targets(
        tmp_path, shapes, monkeypatch):
    import cagekit_learn.train as trainer

    seen, losses_seen = [], []
    real_batch, real_loss = trainer.make_batch, trainer.training_loss

    def record_batch(collection, rows, **kwargs):
        batch = real_batch(collection, rows, **kwargs)
        seen.append((np.asarray(rows).copy(), collection.points, batch))
        return batch

    def record_loss(model, source, target, config, **kwargs):
        losses_seen.append(source.detach().clone())
        return real_loss(model, source, target, config, **kwargs)

    monkeypatch.setattr(trainer, "make_batch", record_batch)
    monkeypatch.setattr(trainer, "training_loss", record_loss)
    result = train(_config(tmp_path, shapes, max_steps=6), progress=False)  # two epochs
    assert result.step == 6 and len(seen) == 6
    template = torch.as_tensor(result.model.config.fixed_source_points, dtype=torch.float32)
    Vn = _unit(io.load_mesh(shapes["template"])[0])
    assert np.allclose(template.numpy(), Vn[result.model.config.fixed_source_rows], atol=1e-6)
    for (rows, points, batch), source in zip(seen, losses_seen):
        assert (rows[:, 0] == FIXED_SOURCE).all()
        for i, t in enumerate(rows[:, 1].tolist()):
            assert torch.equal(batch["source"][i], template)  # never augmented
            assert torch.equal(source[i], template)  # what the loss sees
            target = batch["target"][i].numpy()
            assert not np.allclose(target, points[t], atol=1e-3)  # augmented
            assert np.isclose(np.abs(target).max(), 1.0, atol=1e-5)  # and re-normalised
    for epoch in (seen[:3], seen[3:]):  # every target once per epoch
        assert sorted(np.concatenate([r[:, 1] for r, _, _ in epoch]).tolist()) == list(range(6))
    # without augmentation the targets are the collection's samples as they are
    plain = make_batch(seen[0][1], seen[0][0], epoch=0, step=0, augmentation=False,
                       source_points=template.numpy())
    assert torch.equal(plain["target"], torch.as_tensor(seen[0][1][seen[0][0][:, 1]]))
    with warnings.catch_warnings():  # a batch of one: writable arrays, no torch warning
        warnings.simplefilter("error")
        one = make_batch(seen[0][1], seen[0][0][:1], epoch=0, step=0,
                         source_points=template.numpy())
    assert torch.equal(one["source"][0], template)


def test_chamfer_fixed_source_is_surface_sampled_and_needs_no_vertex_order(tmp_path, shapes):
    config = _config(tmp_path, shapes, align="chamfer", fixed_source=str(shapes["coarse"]),
                     max_steps=2, augment=False)
    result = train(config, progress=False)
    mc = result.model.config
    assert result.step == 2 and mc.fixed_source_rows is None
    assert mc.fixed_source_vertex_count == 42 and len(mc.fixed_source_points) == POINTS
    V = _unit(io.load_mesh(shapes["coarse"])[0])
    assert np.abs(np.asarray(mc.fixed_source_points)).max() <= 1 + 1e-6
    assert not np.allclose(np.asarray(mc.fixed_source_points)[:42], V, atol=1e-3)


def test_l2_template_with_another_vertex_count_exits_2_naming_it(tmp_path, shapes):
    result = invoke(*_train_args(shapes, tmp_path / "run", "--max-steps", 1)[:5],
                    shapes["coarse"], "--align", "l2", "--points", POINTS)
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and str(shapes["coarse"]) in lines[0]
    assert "42 vertices" in lines[0] and "162" in lines[0]
    assert not (tmp_path / "run" / "checkpoint.pt").exists()


# -------------------------------------------------------------------------- inference


# a few steps of training: its result is worse than box scaling (warned)
@pytest.mark.filterwarnings("ignore:the model's result is further:UserWarning")
def test_predict_fixed_source_and_deform_with_model(run_dir, shapes):
    model, payload = load_model(run_dir)
    mc = payload["model_config"]
    rows = np.asarray(mc["fixed_source_rows"])
    Vp, Fp = io.load_mesh(shapes["data"] / "pose2.obj")
    frame = Frame.of(Vp)
    Vp_n, cp, sp = frame.to_unit(Vp), frame.centre, frame.scale
    source_cage, deformed_cage = predict_fixed_source(model, Vp_n[rows])
    assert source_cage.shape == deformed_cage.shape == (42, 3)
    assert np.allclose(source_cage, mc["fixed_cage_v"], atol=1e-6)
    assert np.isfinite(deformed_cage).all()
    with pytest.raises(InputError, match="fixed source"):
        predict_fixed_source(NeuralCages(ModelConfig(**TINY_MODEL)), Vp_n[rows])

    Vt, Ft = io.load_mesh(shapes["template"])
    result = deform_with_model(model, Vt, Ft, Vp, Fp, points=POINTS,
                               scaling_fallback=False)
    assert result.vertices.shape == Vt.shape and np.isfinite(result.vertices).all()
    # the source cage comes back in the template's own frame: the cage file
    assert np.allclose(result.cage_v, io.load_mesh(shapes["cage"])[0], atol=1e-4)
    # the stored template samples and the target's vertex rows were fed, as in training
    assert np.allclose(result.deformed_cage_v, deformed_cage * sp + cp, atol=1e-5)


# ---------------------------------------------------------------------------- resume


def test_resume_with_a_fixed_source_is_exact_and_needs_no_template_file(tmp_path, shapes):
    import shutil

    template = tmp_path / "template.obj"
    shutil.copy(shapes["template"], template)
    whole = _config(tmp_path / "whole", shapes, fixed_source=str(template), max_steps=7)
    a = train(whole, progress=False)
    part = _config(tmp_path / "part", shapes, fixed_source=str(template), max_steps=4)
    train(part, progress=False)
    template.unlink()  # the checkpoint carries the template's samples
    part.max_steps = 7
    b = train(part, resume=True, progress=False)
    assert a.step == b.step == 7
    pa, pb = load_checkpoint(whole.run_dir), load_checkpoint(part.run_dir)
    assert states_equal(pa["model"], pb["model"])
    assert pb["config"]["fixed_source"] == str(template)
    assert pa["model_config"]["fixed_source_points"] == pb["model_config"]["fixed_source_points"]
    for sa, sb in zip(pa["optimizer"]["state"].values(), pb["optimizer"]["state"].values()):
        assert all(torch.equal(sa[k], sb[k]) for k in sa)


# -------------------------------------------------------------------------- learning


def test_a_short_fixed_source_run_lowers_the_l2_loss(tmp_path, shapes):
    run = tmp_path / "run"
    result = invoke(*_train_args(shapes, run, "--source-cage", shapes["cage"],
                                 "--max-steps", 150, "--no-augment", "--no-box-align",
                                 "--lr", "3e-3", "--checkpoint-every", 1000))
    assert result.exit_code == 0, result.output
    with open(run / "log.csv", newline="") as handle:
        align = [float(r["align"]) for r in csv.DictReader(handle)]
    assert len(align) == 150
    first, last = np.mean(align[:6]), np.mean(align[-6:])  # two epochs each
    assert last < 0.7 * first, (first, last)


# ------------------------------------------------------------------------------ cache


def test_cached_source_terms_equal_the_uncached_loss(run_dir, shapes, monkeypatch):
    from cagekit_learn import train as train_module
    from cagekit_learn.train import training_loss

    model, _ = load_model(run_dir)
    config = TrainConfig.from_dict(load_checkpoint(run_dir)["config"])
    config.alpha_shape = 0.1
    source = model.fixed_source[None].expand(3, -1, -1).contiguous()
    target = source * torch.tensor([1.1, 0.9, 1.0]) + 0.01
    cached, terms = training_loss(model, source, target, config)
    cached_again, _ = training_loss(model, source, target, config)
    assert len(model._fixed_source_terms) == 1  # computed once, reused
    monkeypatch.setattr(train_module, "_fixed_source_cache", lambda *args: None)
    plain, plain_terms = training_loss(model, source, target, config)
    assert torch.equal(cached, plain) and torch.equal(cached_again, plain)
    assert terms == plain_terms and terms["p2f"] > 0
    monkeypatch.undo()
    # a source that is not the fixed one is never served from the cache
    other = source + 0.01
    assert train_module._fixed_source_cache(model, other, 16) is None
    # a changed cage (load_state_dict, an edit) is noticed: the weights are recomputed
    W_before = train_module._fixed_source_cache(model, source, 16)[0]
    with torch.no_grad():
        model.template.mul_(1.05)
    W_after = train_module._fixed_source_cache(model, source, 16)[0]
    assert not torch.equal(W_before, W_after)
