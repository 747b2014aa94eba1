"""The paper's networks: PointNet encoder, N_c (three variants or a fixed cage) and N_d."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cagekit.cage.fitting import template_cage  # noqa: E402
from cagekit_learn.alignment import box_scale  # noqa: E402
from cagekit_learn.networks import (  # noqa: E402
    ModelConfig,
    NeuralCages,
    PointNetEncoder,
)


def _clouds(batch=3, points=200, seed=0):
    g = torch.Generator().manual_seed(seed)
    s = torch.rand(batch, points, 3, generator=g) * 2 - 1
    t = torch.rand(batch, points, 3, generator=g) * torch.tensor([1.0, 0.5, 0.8]) * 2 - 1
    return s, t


def test_encoder_is_conv_3_64_128_b_without_batch_norm_and_max_pools():
    enc = PointNetEncoder(32)
    convs = [m for m in enc.modules() if isinstance(m, torch.nn.Conv1d)]
    assert [(c.in_channels, c.out_channels) for c in convs] == [(3, 64), (64, 128), (128, 32)]
    assert not any(isinstance(m, torch.nn.modules.batchnorm._BatchNorm) for m in enc.modules())
    x = torch.rand(2, 50, 3)
    code = enc(x)
    assert code.shape == (2, 32)
    # a max-pool: the order of the points does not matter, and a batch of one is the same
    assert torch.allclose(enc(x[:, torch.randperm(50)]), code, atol=1e-6)
    assert torch.allclose(enc(x[:1]), code[:1], atol=1e-6)


def test_untrained_model_predicts_the_template_and_its_box_aligned_stretch():
    model = NeuralCages(ModelConfig(bottleneck=16))
    s, t = _clouds()
    out = model(s, t)
    v, f = template_cage()
    expected = torch.as_tensor(v * 1.5, dtype=torch.float32)
    assert torch.equal(model.cage_f, torch.as_tensor(f))
    assert torch.allclose(out["source_cage"], expected.expand(3, -1, -1))
    ratio = box_scale(s, t)
    assert torch.allclose(out["deformed_cage"], expected * ratio[:, None, :])
    plain = NeuralCages(ModelConfig(bottleneck=16, box_align=False))(s, t)
    assert torch.allclose(plain["deformed_cage"], plain["source_cage"])


def test_learned_nc_depends_on_the_source_and_nd_on_the_target():
    torch.manual_seed(0)
    model = NeuralCages(ModelConfig(bottleneck=16))
    for p in model.parameters():  # leave the zero start so outputs depend on the codes
        torch.nn.init.normal_(p, std=0.1)
    s, t = _clouds(batch=2)
    out = model(s, t)
    assert not torch.allclose(out["source_cage"][0], out["source_cage"][1])
    swapped = model(s, t.flip(0))
    assert torch.allclose(swapped["source_cage"], out["source_cage"])
    assert not torch.allclose(swapped["deformed_cage"], out["deformed_cage"])


def test_nc_variants_and_their_learning_rate_group():
    learned = NeuralCages(ModelConfig(bottleneck=8))
    identity = NeuralCages(ModelConfig(bottleneck=8, nc="identity"))
    invariant = NeuralCages(ModelConfig(bottleneck=8, nc="source-invariant"))
    assert len(learned.nc_parameters()) > 0
    assert identity.nc_parameters() == []
    assert [p.shape for p in invariant.nc_parameters()] == [torch.Size([42, 3])]
    s, t = _clouds(batch=2)
    with torch.no_grad():
        invariant.nc_offsets += torch.randn(42, 3) * 0.1
    cages = invariant(s, t)["source_cage"]
    assert torch.allclose(cages[0], cages[1]) and not torch.allclose(cages[0],
                                                                    invariant.template)
    assert torch.equal(identity(s, t)["source_cage"][0], identity.template)

    from cagekit_learn.train import TrainConfig, _optimizer

    opt = _optimizer(learned, TrainConfig(data="x", run_dir="y", lr=0.01))
    lrs = sorted(group["lr"] for group in opt.param_groups)
    assert lrs == pytest.approx([0.001, 0.01])
    assert sum(len(g["params"]) for g in opt.param_groups) == len(list(learned.parameters()))


def test_fixed_source_cage_replaces_nc():
    from cagekit.cage.shapes import box_cage

    v, f = box_cage()
    model = NeuralCages(ModelConfig(bottleneck=8, fixed_cage_v=(1.2 * v).tolist(),
                                    fixed_cage_f=f.tolist()))
    assert model.nc_parameters() == []
    s, t = _clouds(batch=2)
    out = model(s, t)
    assert out["source_cage"].shape == (2, 8, 3)
    assert np.allclose(out["source_cage"][1].numpy(), 1.2 * v)


def test_bad_variant_is_refused():
    with pytest.raises(ValueError, match="nc must be one of"):
        NeuralCages(ModelConfig(nc="guess"))


def test_config_round_trips_through_plain_values():
    config = ModelConfig(bottleneck=64, nc="identity", box_align=False)
    values = config.to_dict()
    assert all(isinstance(v, (int, float, str, bool, list, type(None))) for v in values.values())
    assert ModelConfig.from_dict({**values, "unknown": 1}) == config
