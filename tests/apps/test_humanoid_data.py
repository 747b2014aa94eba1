"""The humanoid data set with ground truth (apps.humanoid_data)."""

import numpy as np
import pytest
from builders import small_humanoid_data

from apps import humanoid_data
from cagekit import io
from cagekit.cage import cage_encloses, check_cage
from cagekit.datasets import characters, humanoid
from cagekit.errors import InputError
from cagekit.io.landmarks import load_landmarks


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """A small data set: template, cage, one novel body, two poses with ground truth."""
    out = tmp_path_factory.mktemp("humanoid")
    return out, small_humanoid_data(out)


def test_data_set_is_consistent(data):
    out, summary = data
    Vt, Ft = io.load_mesh(out / "template.obj")
    Vc, Fc = io.load_mesh(out / "characters" / "stocky.obj")
    V0, F0 = io.load_mesh(out / "poses" / "pose_000.obj")
    G0, _ = io.load_mesh(out / "truth" / "stocky" / "pose_000.obj")
    assert np.array_equal(Ft, Fc) and np.array_equal(Ft, F0)
    assert len(Vt) == len(Vc) == len(V0) == len(G0) == summary["template_vertices"]
    assert not np.allclose(V0, Vt) and not np.allclose(G0, Vc)
    # the ground truth is the character posed with the test pose's rotations
    pose = humanoid.random_pose(humanoid_data.TEST_POSE_SEED)
    np.testing.assert_allclose(G0, humanoid.rig("stocky", resolution=0.5).pose(pose),
                               atol=1e-9)
    marks = load_landmarks(out / "template_landmarks.json")
    assert len(marks) == 40
    rig = humanoid.rig("template", resolution=0.5)
    for label, xyz in marks.items():
        np.testing.assert_allclose(xyz, rig.vertices[rig.landmarks[label]], atol=1e-12)
    assert len(list((out / "train").iterdir())) == 2
    cage_v, cage_f = io.load_mesh(out / "template_cage.obj")
    assert cage_encloses(Vt, cage_v, cage_f) and summary["cage"] == "artist"


def test_novel_characters_and_reverse_examples(data):
    out, summary = data
    assert summary["characters"] == ["a_pose"]
    char = characters.character("a_pose", labels=humanoid_data.landmark_names(40))
    V, F = io.load_mesh(out / "characters" / "a_pose.obj")
    np.testing.assert_allclose(V, char.vertices, atol=1e-12)
    marks = load_landmarks(out / "characters" / "a_pose.picked")
    assert "l_heel" in humanoid_data.landmark_names(40)
    assert "L_heel" in marks and "l_heel" not in marks  # misspelt, as real files are
    truth, _ = io.load_mesh(out / "truth" / "a_pose" / "pose_001.obj")
    pose = humanoid.random_pose(humanoid_data.TEST_POSE_SEED + 1)
    np.testing.assert_allclose(truth, char.truth(pose), atol=1e-9)
    t_pose, _ = io.load_mesh(out / "truth" / "a_pose" / "t_pose.obj")
    np.testing.assert_allclose(t_pose, char.truth({}), atol=1e-9)
    # each reverse example: the template in a rest-like pose, its skinned cage (valid,
    # enclosing it) and its landmarks moved with it
    rig = humanoid.rig("template", resolution=0.5)
    assert summary["reverse_poses"] == len(humanoid_data.REVERSE_POSES)
    for i, angles in enumerate(humanoid_data.REVERSE_POSES):
        stem = out / "reverse" / f"pose_{i:02d}"
        Vp, _ = io.load_mesh(f"{stem}.obj")
        cage_v, cage_f = io.load_mesh(f"{stem}_cage.obj")
        check_cage(cage_v, cage_f)
        assert cage_encloses(Vp, cage_v, cage_f)
        posed = load_landmarks(f"{stem}_landmarks.json")
        for label, xyz in posed.items():
            np.testing.assert_allclose(xyz, Vp[rig.landmarks[label]], atol=1e-12)
        np.testing.assert_allclose(Vp, rig.pose(characters.rest_pose(**angles)), atol=1e-9)


def test_landmark_names_spread_and_bounds():
    names = humanoid_data.landmark_names(80)
    assert len(set(names)) == 80 and set(names) <= set(humanoid.LANDMARK_NAMES)
    every = humanoid.LANDMARK_NAMES
    assert names[0] == every[0] and names[-1] == every[-1]  # the whole list is spanned
    assert humanoid_data.landmark_names(len(every)) == list(every)
    with pytest.raises(InputError):
        humanoid_data.landmark_names(3)


def test_only_what_the_transfer_recipe_reads_is_written(tmp_path):
    # issue 33: the README recipe wrote 810 MB (1,000 training poses, every character's
    # ground truth) to use 20 poses and one character
    summary = humanoid_data.write(tmp_path, poses=1, train_poses=0, landmarks=40,
                                  resolution=0.5, bodies=(), novel=("relaxed",),
                                  truth=False, reverse=False)
    written = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
    assert written == ["characters", "characters/relaxed.obj", "characters/relaxed.picked",
                       "manifest.json", "poses", "poses/pose_000.obj", "template.obj",
                       "template_cage.obj", "template_landmarks.json"]
    assert summary["truth"] is False and summary["train_poses"] == 0


def test_a_rerun_with_fewer_poses_leaves_none_of_the_earlier_run_s(tmp_path):
    run = dict(train_poses=2, landmarks=40, resolution=0.5, bodies=(), novel=("relaxed",),
               reverse=False)
    humanoid_data.write(tmp_path, poses=3, **run)
    (tmp_path / "poses" / "pose_9.obj").write_text("not ours\n")  # not named as ours
    (tmp_path / "poses" / "pose_1000.obj").write_text("v 0 0 0\n")  # a 1,001-pose run's
    humanoid_data.write(tmp_path, poses=2, **{**run, "train_poses": 1})
    assert sorted(p.name for p in (tmp_path / "poses").iterdir()) == [
        "pose_000.obj", "pose_001.obj", "pose_9.obj"]
    assert sorted(p.name for p in (tmp_path / "truth" / "relaxed").glob("pose_*")) == [
        "pose_000.obj", "pose_001.obj"]
    assert [p.name for p in (tmp_path / "train").iterdir()] == ["pose_0000.ply"]


def test_characters_are_chosen_by_name_and_unknown_names_refused():
    assert humanoid_data.choose_characters("relaxed, stocky,a_pose") == (
        ("stocky",), ("relaxed", "a_pose"))
    bodies, novel = humanoid_data.choose_characters(None)
    assert "stocky" in bodies and "relaxed" in novel
    with pytest.raises(InputError, match="unknown relaxd.*choose from"):
        humanoid_data.choose_characters("relaxed,relaxd")
    with pytest.raises(InputError, match="empty"):
        humanoid_data.choose_characters(" , ")


def test_the_command_line_takes_the_recipe_s_options(tmp_path):
    from click.testing import CliRunner

    result = CliRunner().invoke(humanoid_data.main, [
        str(tmp_path / "d"), "--characters", "relaxed", "--poses", "1", "--train-poses", "0",
        "--no-truth", "--no-reverse", "--resolution", "0.5", "--landmarks", "40"])
    assert result.exit_code == 0, result.output
    assert not (tmp_path / "d" / "truth").exists() and not (tmp_path / "d" / "reverse").exists()
    assert (tmp_path / "d" / "characters" / "relaxed.picked").exists()
    bad = CliRunner().invoke(humanoid_data.main, [str(tmp_path / "e"), "--characters", "x"])
    assert bad.exit_code == 2 and "unknown x" in bad.output


def test_an_interrupted_run_leaves_no_folder_or_file_it_made(tmp_path, monkeypatch):
    """Ctrl-C after the template is written: the template, the subfolders and the output
    folder go again (cagekit.io.files.all_or_nothing, output_folder)."""
    from click.testing import CliRunner

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(humanoid_data, "template_cage", interrupted)
    result = CliRunner().invoke(humanoid_data.main, [
        str(tmp_path / "d"), "--characters", "relaxed", "--poses", "1", "--train-poses", "0",
        "--no-truth", "--no-reverse", "--resolution", "0.5", "--landmarks", "40"])
    assert result.exit_code == 130, result.output
    assert list(tmp_path.iterdir()) == []
