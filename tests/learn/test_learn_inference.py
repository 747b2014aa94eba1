"""Inference from a checkpoint (`cagekit deform --model`, `--refine`) and `cagekit train`."""

import json
import subprocess
import sys
import warnings

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from builders import REPOSITORY as ROOT  # noqa: E402

from cagekit import bind, io  # noqa: E402
from cagekit.cli import main  # noqa: E402
from cagekit.datasets import synthetic  # noqa: E402
from cagekit.deformation import CageProblem, DeformOptions, solve  # noqa: E402
from cagekit.errors import InputError  # noqa: E402
from cagekit.geometry.frame import Frame  # noqa: E402
from cagekit.geometry.sampling import sample_surface  # noqa: E402
from cagekit.metrics import evaluate  # noqa: E402
from cagekit_learn.cage_repair import check_predicted_cage  # noqa: E402
from cagekit_learn.inference import (  # noqa: E402
    POLISH_EVALUATIONS,
    POLISH_SAMPLES,
    REFINE_CAGE_WEIGHT,
    ModelDeformer,
    deform_with_model,
    predict,
)
from cagekit_learn.train import load_model  # noqa: E402


def _cli(args, capsys):
    code = main(list(args), standalone_mode=False)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A model trained for a few steps on synthetic vases (through the command line)."""
    run = tmp_path_factory.mktemp("learn") / "run"
    code = main(["train", "synthetic:vases:6", "-o", str(run), "--points", "256",
                 "--bottleneck", "32", "--batch-size", "2", "--max-steps", "12",
                 "--lr", "3e-3", "--json"], standalone_mode=False)
    assert code == 0
    return run


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pair")
    paths = []
    for name, seed in (("source", 11), ("target", 12)):
        V, F = synthetic.vase(seed)
        path = folder / f"{name}.obj"
        # the target in other units and place: results must come back in its frame
        scale, shift = (1.0, 0.0) if name == "source" else (40.0, 7.0)
        io.save_mesh(path, V * scale + shift, F)
        paths.append(path)
    return paths


def test_train_command_writes_checkpoint_and_log(run_dir):
    assert (run_dir / "checkpoint.pt").is_file()
    assert len((run_dir / "log.csv").read_text().splitlines()) == 13


# a few steps of training: its result is worse than box scaling (warned)
@pytest.mark.filterwarnings("ignore:the model's result is further:UserWarning")
def test_prediction_deforms_the_full_mesh_with_the_core_binding(run_dir, pair):
    model, payload = load_model(run_dir)
    src, tgt = io.load_shape(pair[0]), io.load_shape(pair[1])
    result = deform_with_model(model, *src, *tgt, points=256, seed=5,
                               scaling_fallback=False, polish=0)
    assert result.method == "learned"
    assert result.vertices.shape == src[0].shape and np.isfinite(result.vertices).all()
    # the same thing by hand: samples, one forward pass, the core's float64 MVC
    frame = Frame.of(src[0])
    Vs_n, cs, ss = frame.to_unit(src[0]), frame.centre, frame.scale
    frame = Frame.of(tgt[0])
    Vt_n, ct, st = frame.to_unit(tgt[0]), frame.centre, frame.scale
    cage, deformed = predict(model, sample_surface(Vs_n, src[1], 256, seed=5),
                             sample_surface(Vt_n, tgt[1], 256, seed=6))
    # ... checked (and grown if it left the source out) before use
    checked = check_predicted_cage(Vs_n, cage, deformed, model.cage_f.numpy())
    assert checked.valid
    cage, deformed = checked.cage_v, checked.deformed_v
    expected = bind(Vs_n, cage, model.cage_f.numpy()).deform(deformed) * st + ct
    assert np.allclose(result.vertices, expected, atol=1e-9)
    assert np.allclose(result.cage_v, cage * ss + cs)
    assert np.allclose(result.deformed_cage_v, deformed * st + ct)


@pytest.mark.filterwarnings("ignore:the model's result is further:UserWarning")
def test_polish_is_the_refinement_energy_a_few_steps_from_the_prediction(run_dir, pair):
    model, _ = load_model(run_dir)
    src, tgt = io.load_shape(pair[0]), io.load_shape(pair[1])
    raw = deform_with_model(model, *src, *tgt, points=256, seed=5, scaling_fallback=False,
                            polish=0)
    polished = deform_with_model(model, *src, *tgt, points=256, seed=5,
                                 scaling_fallback=False)  # POLISH_EVALUATIONS by default
    assert polished.method == "learned"
    np.testing.assert_allclose(polished.cage_v, raw.cage_v)
    # by hand: the refinement's problem on POLISH_SAMPLES samples, solved from the prediction
    frame_s, frame_t = Frame.of(src[0]), Frame.of(tgt[0])
    Vs_n, Vt_n = frame_s.to_unit(src[0]), frame_t.to_unit(tgt[0])
    options = DeformOptions(samples=POLISH_SAMPLES, seed=5,
                            weights={"cage": REFINE_CAGE_WEIGHT})
    problem = CageProblem.create(Vs_n, src[1], Vt_n, tgt[1], frame_s.to_unit(raw.cage_v),
                                 raw.cage_f, options)
    start = frame_t.to_unit(raw.deformed_cage_v)
    solution = solve(problem, start, max_evaluations=POLISH_EVALUATIONS)
    # (the cage's trip through the world frame moves its last bits: not bit for bit)
    np.testing.assert_allclose(frame_t.to_unit(polished.deformed_cage_v),
                               solution.deformed_cage, atol=1e-6)
    np.testing.assert_allclose(frame_t.to_unit(polished.vertices), solution.vertices,
                               atol=1e-6)
    assert solution.energy < problem.energy(start)[0]  # it moved, downhill
    # the polish's evaluations and energy are reported (--json prints them)
    assert polished.iterations == solution.evaluations > 1
    assert polished.energy == pytest.approx(solution.energy, rel=1e-6)
    assert "chamfer" in polished.losses and polished.weights["cage"] == REFINE_CAGE_WEIGHT
    for bad in (-1, 2.5, True, 10**20):
        with pytest.raises(InputError, match="polish"):
            deform_with_model(model, *src, *tgt, points=256, polish=bad)
        with pytest.raises(InputError, match="polish"):
            ModelDeformer(str(run_dir), polish=bad)
    with pytest.raises(InputError, match="polish applies without refine"):
        deform_with_model(model, *src, *tgt, points=256, refine=True, polish=3)
    with pytest.raises(InputError, match="polish applies without refine"):
        ModelDeformer(str(run_dir), refine=True, polish=3)


# a few steps of training: its result is worse than box scaling (warned)
@pytest.mark.filterwarnings("ignore:the model's result is further:UserWarning")
def test_refine_starts_from_the_prediction_and_improves_it(run_dir, pair):
    model, _ = load_model(run_dir)
    src, tgt = io.load_shape(pair[0]), io.load_shape(pair[1])
    learned = deform_with_model(model, *src, *tgt, points=256, scaling_fallback=False,
                                polish=0)
    assert learned.method == "learned"
    refined = deform_with_model(model, *src, *tgt, points=256, refine=True,
                                options=DeformOptions(max_evaluations=30))
    assert refined.method == "learned+refine"
    assert np.allclose(refined.cage_v, learned.cage_v)
    cd_learned = evaluate(*src, *tgt, learned.vertices).cd
    cd_refined = evaluate(*src, *tgt, refined.vertices).cd
    assert cd_refined < cd_learned
    assert refined.energy <= refined.initial_energy


def test_deform_model_command(run_dir, pair, tmp_path, capsys):
    out = tmp_path / "out.obj"
    code, stdout, stderr = _cli(["deform", str(pair[0]), str(pair[1]), "--model",
                                 str(run_dir / "checkpoint.pt"), "-o", str(out), "--save-cage",
                                 str(tmp_path / "cage.obj"), "--json", "--polish", "0"],
                                capsys)
    assert code == 0
    figures = json.loads(stdout)
    # a few steps of training do worse than box scaling: the command hands that on, saying so
    assert figures["method"] == "scale" and figures["cd"] > 0
    assert "the scaling is returned instead" in stderr
    V, F = io.load_mesh(out)
    code, _, _ = _cli(["deform", str(pair[0]), str(pair[1]), "--method", "scale", "-o",
                       str(tmp_path / "scaled.obj")], capsys)
    assert code == 0  # in the target's frame and units (it is 40x larger, shifted by 7)
    np.testing.assert_allclose(V, io.load_mesh(tmp_path / "scaled.obj")[0], atol=1e-4)
    cage_v, cage_f = io.load_mesh(tmp_path / "cage.obj")
    assert cage_v.shape == (42, 3)
    # the deformed cage written beside it moves the source there
    moved_cage = io.load_mesh(tmp_path / "cage_deformed.obj")[0]
    np.testing.assert_allclose(bind(io.load_shape(pair[0])[0], cage_v, cage_f)
                               .deform(moved_cage), V, atol=1e-3)
    # --keep-prediction writes the network's own result (and still warns)
    code, stdout, stderr = _cli(["deform", str(pair[0]), str(pair[1]), "--model", str(run_dir),
                                 "--keep-prediction", "-o", str(tmp_path / "kept.obj"),
                                 "--json", "--polish", "0"], capsys)
    assert code == 0 and json.loads(stdout)["method"] == "learned"
    assert "the result is kept" in stderr
    network = json.loads(stdout)["cd"]
    assert network > figures["cd"]
    # polished by default: nearer the target than the network's own result
    code, stdout, _ = _cli(["deform", str(pair[0]), str(pair[1]), "--model", str(run_dir),
                            "--keep-prediction", "-o", str(tmp_path / "polished.obj"),
                            "--json"], capsys)
    assert code == 0 and json.loads(stdout)["method"] == "learned"
    assert json.loads(stdout)["cd"] < network
    code, stdout, _ = _cli(["deform", str(pair[0]), str(pair[1]), "--model", str(run_dir),
                            "--refine", "-o", str(tmp_path / "refined.obj"), "--json"],
                           capsys)
    assert code == 0
    refined = json.loads(stdout)
    assert refined["method"] == "learned+refine" and refined["cd"] < figures["cd"]


@pytest.mark.parametrize("args, message", [
    (["--model", "{bad}"], "not a readable checkpoint (torch's safe loader refused it"),
    (["--model", "{text}"], "not a readable checkpoint (torch's safe loader refused it"),
    (["--model", "{empty}"], "not a readable checkpoint (torch's safe loader refused it"),
    (["--model", "{missing}"], "no such checkpoint"),
    (["--refine"], "needs --model"),
    (["--model", "{run}", "--method", "scale"], "apply to --method cage only"),
    (["--model", "{run}", "--symmetry", "x"], "need --refine"),
    (["--model", "{run}", "--coords", "green"], "--coords green applies"),
    (["--keep-prediction"], "--keep-prediction applies to --model without --refine"),
    (["--model", "{run}", "--refine", "--keep-prediction"], "--keep-prediction applies"),
    (["--polish", "5"], "--polish polishes a prediction: it needs --model"),
    (["--model", "{run}", "--refine", "--polish", "5"], "--polish applies to --model without"),
    (["--model", "{run}", "--polish", "99999999999999999999"], "0<=x<=10000"),
    (["--model", "{hollow}"], "not a usable cagekit checkpoint"),
])
def test_deform_model_bad_input_exits_2_with_one_line(run_dir, pair, tmp_path, capsys,
                                                      args, message):
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"\x00junk")
    hollow = tmp_path / "hollow.pt"  # readable, but not what a model needs
    torch.save({"format": 1, "model": {}, "model_config": {"nc": "bogus"}}, hollow)
    text = tmp_path / "text.pt"  # torch's legacy reader fails on it with a bare KeyError
    text.write_text("junk\n")
    empty = tmp_path / "empty.pt"  # an EOFError without a message
    empty.write_bytes(b"")
    names = {"bad": bad, "missing": tmp_path / "missing.pt", "run": run_dir,
             "hollow": hollow, "text": text, "empty": empty}
    args = [a.format(**names) for a in args]
    code, _, err = _cli(["deform", str(pair[0]), str(pair[1]), "-o",
                         str(tmp_path / "o.obj"), *args], capsys)
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and message in err
    assert not (tmp_path / "o.obj").exists()


def test_an_interrupted_train_without_a_checkpoint_leaves_no_run_folder(tmp_path, capsys,
                                                                         monkeypatch):
    import cagekit_learn.train as training

    def interrupted(config, resume=False, progress=False):
        (tmp_path / "runs" / "r" / "log.csv").write_text("step,loss\n")  # its first row
        if config.max_steps == 2:  # the second case: a checkpoint written first
            (tmp_path / "runs" / "r" / "checkpoint.pt").write_bytes(b"kept")
        raise KeyboardInterrupt

    monkeypatch.setattr(training, "train", interrupted)
    args = ["train", "synthetic:vases:4", "-o", str(tmp_path / "runs" / "r")]
    code, _, err = _cli(args, capsys)
    assert code == 130 and "interrupted" in err
    assert not (tmp_path / "runs").exists()  # nor the parent the run made
    code, _, _ = _cli([*args, "--max-steps", "2"], capsys)
    assert code == 130
    assert (tmp_path / "runs" / "r" / "checkpoint.pt").read_bytes() == b"kept"
    # a folder that was there before keeps what the run wrote (its log)
    (tmp_path / "there").mkdir()
    there = ["train", "synthetic:vases:4", "-o", str(tmp_path / "there")]
    monkeypatch.setattr(training, "train", lambda config, **kw: (
        (tmp_path / "there" / "log.csv").write_text("step\n"), _interrupt()))
    assert _cli(there, capsys)[0] == 130 and (tmp_path / "there" / "log.csv").exists()

    # what another run wrote meanwhile into a parent this run made is never removed
    def beside(config, resume=False, progress=False):
        (tmp_path / "new" / "b").mkdir()
        (tmp_path / "new" / "b" / "checkpoint.pt").write_bytes(b"other run")
        (tmp_path / "new" / "a" / "log.csv").write_text("step\n")
        raise KeyboardInterrupt

    monkeypatch.setattr(training, "train", beside)
    assert _cli(["train", "synthetic:vases:4", "-o", str(tmp_path / "new" / "a")],
                capsys)[0] == 130
    assert not (tmp_path / "new" / "a").exists()
    assert (tmp_path / "new" / "b" / "checkpoint.pt").read_bytes() == b"other run"


def _interrupt():
    raise KeyboardInterrupt


def test_train_says_which_batch_size_a_small_collection_allows(tmp_path, capsys):
    code, _, err = _cli(["train", "synthetic:vases:3", "-o", str(tmp_path / "r"),
                         "--points", "256"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "3 shapes give 3 pair(s) an epoch, not a full batch of 8: use " \
           "--batch-size 3 or lower" in err
    assert not (tmp_path / "r").exists()


def test_train_command_refuses_to_overwrite_a_run_and_bad_data(run_dir, tmp_path, capsys):
    code, _, err = _cli(["train", "synthetic:vases:4", "-o", str(run_dir)], capsys)
    assert code == 2 and "--resume" in err and len(err.strip().splitlines()) == 1
    code, _, err = _cli(["train", str(tmp_path / "nowhere"), "-o", str(tmp_path / "r")],
                        capsys)
    assert code == 2 and "nowhere" in err
    code, _, err = _cli(["train", "synthetic:spoons:4", "-o", str(tmp_path / "r")], capsys)
    assert code == 2 and "synthetic:FAMILY" in err
    assert not (tmp_path / "r").exists()  # a failed run leaves no empty run folder


def test_a_checkpoint_with_nan_weights_is_blamed_on_the_checkpoint(run_dir, pair, tmp_path,
                                                                   capsys):
    from cagekit_learn.checkpoint import load_checkpoint, save_checkpoint

    payload = load_checkpoint(run_dir)
    name = next(k for k, t in payload["model"].items() if t.is_floating_point())
    payload["model"][name] = torch.full_like(payload["model"][name], float("nan"))
    bad = tmp_path / "nan.pt"
    save_checkpoint(bad, payload)
    code, _, err = _cli(["deform", str(pair[0]), str(pair[1]), "-o", str(tmp_path / "o.obj"),
                         "--model", str(bad)], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert str(bad) in err and "NaN" in err and str(pair[0]) not in err
    assert not (tmp_path / "o.obj").exists()


def test_cagekit_deform_without_model_never_imports_torch(pair, tmp_path):
    code = (
        "import sys\nfrom cagekit.cli import main\n"
        f"main(['deform', {str(pair[0])!r}, {str(pair[1])!r}, '-o', "
        f"{str(tmp_path / 'x.obj')!r}, '--method', 'scale'], standalone_mode=False)\n"
        "print('torch' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT)
    assert out.stdout.strip().splitlines()[-1] == "False"


def test_amplify_with_a_model_on_two_workers_matches_one_worker(run_dir, tmp_path, capsys):
    # the model travels to the workers as its path (ModelDeformer), each loads it once
    runs = {}
    for workers in ("1", "2"):
        out = tmp_path / f"w{workers}"
        code, stdout, _ = _cli(["amplify", "synthetic:vases:3", "-o", str(out),
                                "--variations", "3", "--method", "model", "--model",
                                str(run_dir), "--workers", workers, "--json"], capsys)
        assert code == 0
        assert json.loads(stdout)["items"] == 3
        runs[workers] = json.loads((out / "manifest.json").read_text())["items"]
    for a, b in zip(runs["1"], runs["2"]):
        assert a["method"] == "model" and a["status"] in ("ok", "rejected")
        assert a["cd"] == pytest.approx(b["cd"], rel=1e-9) and a["cd"] > 0
        V1 = io.load_mesh(tmp_path / "w1" / ("variations" if a["status"] == "ok"
                                              else "rejected") / a["output"])[0]
        V2 = io.load_mesh(tmp_path / "w2" / ("variations" if b["status"] == "ok"
                                              else "rejected") / b["output"])[0]
        np.testing.assert_allclose(V1, V2, rtol=0, atol=1e-9)
    code, _, err = _cli(["amplify", "synthetic:vases:3", "-o", str(tmp_path / "x"),
                         "--variations", "1", "--method", "model"], capsys)
    assert code == 2 and "--model" in err
    # --polish 0: the network's own results, which the default polish moved
    code, _, err = _cli(["amplify", "synthetic:vases:3", "-o", str(tmp_path / "raw"),
                         "--variations", "3", "--method", "model", "--model", str(run_dir),
                         "--workers", "1", "--polish", "0"], capsys)
    assert code == 0
    # a few steps of training: scaling is handed on, and each warning names its pair
    handed = [line for line in err.splitlines() if "the scaling is returned instead" in line]
    assert handed and all(" -> " in line.split(": the model's result")[0] for line in handed)
    raw = json.loads((tmp_path / "raw" / "manifest.json").read_text())["items"]
    assert [r["cd"] for r in raw] != pytest.approx([r["cd"] for r in runs["1"]], rel=1e-6)
    code, _, err = _cli(["amplify", "synthetic:vases:3", "-o", str(tmp_path / "y"),
                         "--variations", "1", "--polish", "3"], capsys)
    assert code == 2 and "it needs --method model" in err


def test_a_model_trained_with_green_coordinates_deforms_with_them(tmp_path, pair, capsys):
    run = tmp_path / "green"
    code, stdout, _ = _cli(["train", "synthetic:vases:4", "-o", str(run), "--points", "128",
                            "--bottleneck", "16", "--batch-size", "2", "--max-steps", "3",
                            "--coords", "green", "--json"], capsys)
    assert code == 0
    model, _ = load_model(str(run))
    assert model.config.coords == "green"
    result = deform_with_model(model, *io.load_shape(pair[0]), *io.load_shape(pair[1]),
                               points=128, scaling_fallback=False)
    assert result.method == "learned" and np.isfinite(result.vertices).all()
    # the full mesh follows the predicted cages under Green coordinates, as the core does
    Vs, Fs = io.load_shape(pair[0])
    source_n = result.source_frame.to_unit(Vs)
    cage_n = result.source_frame.to_unit(result.cage_v)
    moved_n = result.target_frame.to_unit(result.deformed_cage_v)
    expected = bind(source_n, cage_n, result.cage_f, method="green").deform(moved_n)
    np.testing.assert_allclose(result.target_frame.to_unit(result.vertices), expected,
                               atol=1e-9)
    # --refine optimises under the model's coordinates (the options' coords are ignored)
    refined = deform_with_model(model, *io.load_shape(pair[0]), *io.load_shape(pair[1]),
                                points=128, refine=True,
                                options=DeformOptions(coords="mvc", max_evaluations=5))
    assert refined.method == "learned+refine" and np.isfinite(refined.vertices).all()
    # handed on as a scaling (256 samples: further than it), the result is what its cages
    # give under Green coordinates, which keep angles: near the box scaling, not on it
    from cagekit import deform
    from cagekit.errors import CagekitWarning

    with pytest.warns(CagekitWarning, match="the scaling is returned instead"):
        scaled = deform_with_model(model, Vs, Fs, *io.load_shape(pair[1]), points=256,
                                   polish=0)
    assert scaled.method == "scale"
    same = bind(Vs, scaled.cage_v, scaled.cage_f, method="green").deform(scaled.deformed_cage_v)
    np.testing.assert_allclose(scaled.vertices, same, atol=1e-6)  # target 40x larger
    box = deform(Vs, Fs, *io.load_shape(pair[1]), options=DeformOptions(method="scale"))
    off = np.abs(scaled.vertices - box.vertices).max() / np.ptp(box.vertices, axis=0).max()
    assert 1e-6 < off < 0.2


def _predicting(monkeypatch, change):
    """Make deform_with_model's prediction pass through ``change(Vs_n, cage, deformed)``."""
    from cagekit_learn import inference

    real = inference._predicted

    def predicted(*args, **kwargs):
        fs, ft, Vs_n, Vt_n, cage_n, deformed_n = real(*args, **kwargs)
        return (fs, ft, Vs_n, Vt_n, *change(Vs_n, cage_n, deformed_n))

    monkeypatch.setattr(inference, "_predicted", predicted)


# a few steps of training: its result is worse than box scaling (warned)
@pytest.mark.filterwarnings("ignore:the model's result is further:UserWarning")
def test_a_predicted_cage_that_leaves_the_source_out_is_grown_before_use(run_dir, pair,
                                                                         monkeypatch):
    from cagekit.cage import winding_numbers

    model, _ = load_model(run_dir)
    src, tgt = io.load_shape(pair[0]), io.load_shape(pair[1])
    centre = {}

    def shrink(Vs_n, cage, deformed):  # 0.7x about the source's centre: parts stick out
        centre["c"] = 0.5 * (Vs_n.min(axis=0) + Vs_n.max(axis=0))
        return centre["c"] + 0.7 * (cage - centre["c"]), deformed

    _predicting(monkeypatch, shrink)
    result = deform_with_model(model, *src, *tgt, points=256, scaling_fallback=False)
    assert result.method == "learned"
    cage_n = result.source_frame.to_unit(result.cage_v)
    source_n = result.source_frame.to_unit(src[0])
    assert (winding_numbers(source_n, cage_n, result.cage_f) >= 0.5 - 1e-9).all()


def test_a_predicted_cage_that_folds_falls_back_to_a_fitted_cage_with_one_warning(
        run_dir, pair, monkeypatch):
    from cagekit.deformation import deform
    from cagekit.errors import CageError, CagekitWarning

    model, _ = load_model(run_dir)
    src, tgt = io.load_shape(pair[0]), io.load_shape(pair[1])

    def fold(Vs_n, cage, deformed):  # one cage vertex pushed through the far side
        cage = cage.copy()
        cage[0] = cage.mean(axis=0) - 2.0 * (cage[0] - cage.mean(axis=0))
        return cage, deformed

    _predicting(monkeypatch, fold)
    options = DeformOptions(max_evaluations=5)
    with pytest.warns(CagekitWarning, match="intersects itself.*per-pair optimisation") as w:
        result = deform_with_model(model, *src, *tgt, points=256, options=options)
    assert len([x for x in w if issubclass(x.category, CagekitWarning)]) == 1
    assert result.method == "cage" and len(result.cage_f) != len(model.cage_f)
    expected = deform(*src, *tgt, options=options)
    np.testing.assert_allclose(result.vertices, expected.vertices, atol=1e-9)
    with pytest.raises(CageError, match="cannot be used: it intersects itself"):
        deform_with_model(model, *src, *tgt, points=256, fallback=False)


def test_refine_weighs_the_cage_term_lightly_unless_told(run_dir, pair):
    from cagekit_learn.inference import REFINE_CAGE_WEIGHT

    model, _ = load_model(run_dir)
    src, tgt = io.load_shape(pair[0]), io.load_shape(pair[1])
    light = deform_with_model(model, *src, *tgt, points=256, refine=True,
                              options=DeformOptions(max_evaluations=10))
    assert light.weights["cage"] == REFINE_CAGE_WEIGHT
    told = deform_with_model(model, *src, *tgt, points=256, refine=True,
                             options=DeformOptions(max_evaluations=10, weights={"cage": 0.3}))
    assert told.weights["cage"] == 0.3
    assert not np.allclose(light.vertices, told.vertices)
    source_ref = deform_with_model(model, *src, *tgt, points=256, refine=True,
                                   options=DeformOptions(max_evaluations=10, reference="source"))
    assert source_ref.weights["cage"] == 1.0


def test_a_result_worse_than_box_scaling_is_warned_about():
    from cagekit.cage.shapes import box_cage
    from cagekit.errors import CagekitWarning
    from cagekit_learn.inference import warn_if_worse_than_scaling

    V, F = box_cage(divisions=4)
    target = V * [1.0, 2.0, 1.0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning: the result is the scaled source
        assert not warn_if_worse_than_scaling(V, F, target, F, target)
    bent = target + np.c_[np.zeros(len(V)), np.zeros(len(V)), 0.3 * V[:, 1] ** 2]
    with pytest.warns(CagekitWarning,
                      match=r"bounding box .*Chamfer x1e2 of 2,048 samples [\d.]+ against"):
        assert warn_if_worse_than_scaling(V, F, target, F, bent)


def test_the_model_warns_on_a_pair_that_scaling_serves_better(run_dir):
    """A sphere onto one twice as tall: scaling is exact, the vase model is not."""
    from cagekit.cage.shapes import icosphere_cage
    from cagekit.errors import CagekitWarning

    V, F = icosphere_cage(2)
    model, _ = load_model(run_dir)
    with pytest.warns(CagekitWarning, match="unlike the shapes .* the result is kept"):
        kept = deform_with_model(model, V, F, V * [1.0, 2.0, 1.0], F, points=256,
                                 scaling_fallback=False, polish=0)
    assert kept.method == "learned"
    assert not np.allclose(kept.vertices, V * [1.0, 2.0, 1.0], atol=1e-3)
    # by default the scaling is handed on instead, and its cage moves the source there
    with pytest.warns(CagekitWarning, match="the scaling is returned instead"):
        result = deform_with_model(model, V, F, V * [1.0, 2.0, 1.0], F, points=256,
                                   polish=0)
    assert result.method == "scale"
    assert np.allclose(result.vertices, V * [1.0, 2.0, 1.0], atol=1e-12)
    assert np.allclose(result.cage_v, kept.cage_v)
    assert np.allclose(bind(V, result.cage_v, result.cage_f).deform(result.deformed_cage_v),
                       result.vertices, atol=1e-9)
    # the polished path: one evaluation leaves the network's result, which scaling beats
    with pytest.warns(CagekitWarning, match="the scaling is returned instead"):
        polished = deform_with_model(model, V, F, V * [1.0, 2.0, 1.0], F, points=256,
                                     polish=np.int64(1))
    assert polished.method == "scale" and polished.iterations == 1
    assert np.allclose(polished.vertices, V * [1.0, 2.0, 1.0], atol=1e-9)
    assert np.allclose(polished.cage_v, kept.cage_v)
