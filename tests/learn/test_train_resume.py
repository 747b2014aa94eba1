"""``cagekit train --resume``: the command line's DATA_DIR is read, an option given again
that contradicts the checkpoint is refused (the others come from it), and the checkpoint
is validated as ``deform --model`` validates it before anything is trained."""

import shutil

import numpy as np
import pytest

torch = pytest.importorskip("torch")
trimesh = pytest.importorskip("trimesh")

from cagekit import io  # noqa: E402
from cagekit.cli import main  # noqa: E402
from cagekit.datasets import synthetic  # noqa: E402
from cagekit_learn.checkpoint import load_checkpoint, save_checkpoint  # noqa: E402
from cagekit_learn.threads import one_thread  # noqa: E402

# a small, quick run: 6 synthetic vases, 128 points each
TINY_ARGS = ["--points", "128", "--bottleneck", "16", "--batch-size", "2", "--seed", "3"]
DATA = "synthetic:vases:6"


@pytest.fixture(autouse=True)
def torch_on_one_thread():
    with one_thread():
        yield


def _cli(args, capsys):
    code = main([str(a) for a in args], standalone_mode=False)
    out, err = capsys.readouterr()
    return code, out, err


def _one_line_error(code, err, *names):
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for name in names:
        assert str(name) in lines[0], (name, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def stopped(tmp_path_factory):
    """A run stopped after one step (6 vases, 128 points, bottleneck 16)."""
    run = tmp_path_factory.mktemp("stopped") / "run"
    with one_thread():
        code = main(["train", DATA, *TINY_ARGS, "-o", str(run), "--max-steps", "1"],
                    standalone_mode=False)
    assert code == 0
    return run


@pytest.fixture
def run(stopped, tmp_path):
    """A copy of the stopped run, for one test to resume or damage."""
    copy = tmp_path / "run"
    shutil.copytree(stopped, copy)
    return copy


# ------------------------------------------------------------------------ the options


@pytest.mark.parametrize("given, stored", [
    (["--bottleneck", "32"], "16"),
    (["--points", "64"], "128"),
    (["--coords", "green"], "mvc"),
    (["--nc", "identity"], "learned"),
    (["--batch-size", "3"], "2"),
    (["--lr", "0.01"], "0.001"),
    (["--seed", "4"], "3"),
    (["--symmetry", "x"], "none"),
    (["--align", "l2"], "chamfer"),
])
def test_an_option_that_contradicts_the_checkpoint_is_refused(run, capsys, given, stored):
    before = (run / "checkpoint.pt").read_bytes()
    code, _, err = _cli(["train", DATA, "-o", run, "--resume", "--max-steps", "2", *given],
                        capsys)
    line = _one_line_error(code, err, run / "checkpoint.pt")
    assert line.endswith(f"checkpoint.pt: {given[0]} {given[1]} contradicts the "
                         f"checkpoint's {stored}"), line
    assert (run / "checkpoint.pt").read_bytes() == before  # nothing was trained


@pytest.mark.parametrize("flag, setting", [("--no-augment", "augment=True"),
                                           ("--no-box-align", "box_align=True")])
def test_a_flag_that_contradicts_the_checkpoint_is_refused(run, capsys, flag, setting):
    code, _, err = _cli(["train", DATA, "-o", run, "--resume", "--max-steps", "2", flag],
                        capsys)
    _one_line_error(code, err, run / "checkpoint.pt", flag, setting, "contradicts")
    assert load_checkpoint(run)["step"] == 1


def test_options_given_again_with_the_checkpoints_values_are_accepted(run, capsys):
    code, _, err = _cli(["train", DATA, *TINY_ARGS, "-o", run, "--resume", "--max-steps",
                         "2", "--symmetry", "none", "--coords", "mvc"], capsys)
    assert code == 0, err
    assert load_checkpoint(run)["step"] == 2


def test_options_not_given_take_the_checkpoints_values(run, capsys):
    code, _, err = _cli(["train", DATA, "-o", run, "--resume", "--max-steps", "2"], capsys)
    assert code == 0, err
    payload = load_checkpoint(run)
    assert payload["step"] == 2
    assert payload["config"]["points"] == 128 and payload["config"]["batch_size"] == 2
    assert payload["model_config"]["bottleneck"] == 16


# --------------------------------------------------------------------------- the data


def _mesh_folder(path, seeds):
    path.mkdir()
    for seed in seeds:
        io.save_mesh(path / f"vase{seed}.obj", *synthetic.vase(seed, resolution=0.5))
    return path


def test_resume_reads_the_data_dir_given_not_the_stored_one(tmp_path, capsys):
    first = _mesh_folder(tmp_path / "first", range(4))
    run = tmp_path / "run"
    args = ["--points", "64", "--bottleneck", "8", "--batch-size", "2"]
    code, _, err = _cli(["train", first, *args, "-o", run, "--max-steps", "1"], capsys)
    assert code == 0, err
    moved = tmp_path / "moved"
    shutil.copytree(first, moved, ignore=shutil.ignore_patterns(".cagekit-cache"))
    shutil.rmtree(first / ".cagekit-cache")
    code, _, err = _cli(["train", moved, "-o", run, "--resume", "--max-steps", "2"], capsys)
    assert code == 0, err
    assert (moved / ".cagekit-cache").is_dir()  # read (and cached) where it was told
    assert not (first / ".cagekit-cache").exists()  # the stored folder was not read
    assert load_checkpoint(run)["config"]["data"] == str(moved)
    nowhere = tmp_path / "nowhere"
    code, _, err = _cli(["train", nowhere, "-o", run, "--resume", "--max-steps", "3"],
                        capsys)
    _one_line_error(code, err, nowhere)
    assert load_checkpoint(run)["step"] == 2


# -------------------------------------------------------------------- the checkpoint


def _damage(run, change):
    payload = load_checkpoint(run)
    change(payload)
    save_checkpoint(run / "checkpoint.pt", payload)


@pytest.mark.parametrize("change", [
    lambda p: p["model_config"].update(bottleneck=32),  # the weights are of 16
    lambda p: p["config"]["model"].update(bottleneck=32),
    lambda p: p["model_config"].update(coords="green"),  # config and model_config differ
    lambda p: p["model"].pop("nd_decoder.layers.0.weight"),
], ids=["model_config", "config", "disagree", "missing-weight"])
def test_a_checkpoint_whose_config_does_not_match_its_weights_is_refused(run, capsys,
                                                                         change):
    _damage(run, change)
    before = (run / "checkpoint.pt").read_bytes()
    code, _, err = _cli(["train", DATA, "-o", run, "--resume", "--max-steps", "3"], capsys)
    _one_line_error(code, err, run / "checkpoint.pt")
    assert (run / "checkpoint.pt").read_bytes() == before


@pytest.mark.parametrize("name, value", [("step", "x"), ("step", -4), ("step", 2.0),
                                         ("step", True), ("skipped", -1),
                                         ("world_size", 0)])
def test_a_bad_stored_counter_is_refused_naming_the_file(run, capsys, name, value):
    _damage(run, lambda p: p.update({name: value}))
    code, _, err = _cli(["train", DATA, "-o", run, "--resume", "--max-steps", "3"], capsys)
    _one_line_error(code, err, run / "checkpoint.pt", name)


def test_the_library_validates_a_resumed_checkpoint_too(run):
    from cagekit.errors import InputError
    from cagekit_learn.train import TrainConfig, train

    _damage(run, lambda p: p.update(step=-4))
    config = TrainConfig(data=DATA, run_dir=str(run), max_steps=3)
    with pytest.raises(InputError, match="step") as caught:
        train(config, resume=True, progress=False)
    assert caught.value.path == str(run / "checkpoint.pt")


# ---------------------------------------------------------------- a fixed source, cage


@pytest.fixture(scope="module")
def template_run(tmp_path_factory):
    """A one-step run with a fixed source and a fixed source cage (own frame)."""
    root = tmp_path_factory.mktemp("template")
    ico = trimesh.creation.icosphere(subdivisions=2)
    V, F = np.asarray(ico.vertices) * [1.2, 1.0, 0.8] * 3 + [1, 2, 3], np.asarray(ico.faces)
    poses = root / "poses"
    poses.mkdir()
    for i, stretch in enumerate(([1.3, 1, 1], [1, 0.7, 1.1], [1, 1, 1.4], [0.8, 1, 1])):
        io.save_mesh(poses / f"pose{i}.obj", V * stretch, F)
    io.save_mesh(root / "template.obj", V, F)
    io.save_mesh(root / "other.obj", V * [1.5, 1, 1], F)
    coarse = trimesh.creation.icosphere(subdivisions=1)
    cage_v = np.asarray(coarse.vertices) * [1.2, 1.0, 0.8] * 3 * 1.4 + [1, 2, 3]
    io.save_mesh(root / "cage.obj", cage_v, np.asarray(coarse.faces))
    io.save_mesh(root / "big_cage.obj", cage_v * 1.1, np.asarray(coarse.faces))
    args = ["--points", "64", "--bottleneck", "8", "--batch-size", "2", "--fixed-source",
            root / "template.obj", "--source-cage", root / "cage.obj"]
    with one_thread():
        code = main(["train", str(poses), *map(str, args), "-o", str(root / "run"),
                     "--max-steps", "1"], standalone_mode=False)
    assert code == 0
    return root


def test_a_fixed_source_or_cage_given_again_must_be_the_checkpoints(template_run, tmp_path,
                                                                   capsys):
    run = tmp_path / "run"
    shutil.copytree(template_run / "run", run)
    common = ["train", template_run / "poses", "-o", run, "--resume"]
    code, _, err = _cli([*common, "--source-cage", template_run / "big_cage.obj",
                         "--fixed-source", template_run / "template.obj"], capsys)
    _one_line_error(code, err, run / "checkpoint.pt", "--source-cage",
                    template_run / "big_cage.obj", "contradicts")
    code, _, err = _cli([*common, "--fixed-source", template_run / "other.obj"], capsys)
    _one_line_error(code, err, run / "checkpoint.pt", "--fixed-source",
                    template_run / "other.obj", "contradicts")
    assert load_checkpoint(run)["step"] == 1
    code, _, err = _cli([*common, "--source-cage", template_run / "cage.obj",
                         "--fixed-source", template_run / "template.obj",
                         "--max-steps", "2"], capsys)
    assert code == 0, err
    assert load_checkpoint(run)["step"] == 2


def test_a_fixed_source_or_cage_on_a_run_without_one_is_refused(run, template_run, capsys):
    for option, path in (("--fixed-source", template_run / "template.obj"),
                         ("--source-cage", template_run / "cage.obj")):
        code, _, err = _cli(["train", DATA, "-o", run, "--resume", option, path], capsys)
        _one_line_error(code, err, run / "checkpoint.pt", option, path, "contradicts")
