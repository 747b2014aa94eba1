"""End-to-end tests of ``cagekit deform`` (subprocess), its outputs and its bad-input errors."""

import json

import numpy as np
import pytest
from builders import assert_bad_input, bumpy_blob, cagekit, load_obj

from cagekit.io import save_mesh
from cagekit.io.landmarks import save_landmarks


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """A small symmetric blob and a non-affine variation of it, written as OBJ files."""
    folder = tmp_path_factory.mktemp("pair")
    V, F = bumpy_blob(subdivisions=2)
    Vt = V * 3.0 + 10.0
    Vt[V[:, 1] > 0] *= [1.2, 1.0, 1.0]
    source, target = folder / "source.obj", folder / "target.obj"
    save_mesh(source, V, F)
    save_mesh(target, Vt, F)
    return folder, source, target


def test_deform_writes_result_cages_preview_and_json(pair):
    folder, source, target = pair
    out, cage, preview = folder / "out.obj", folder / "cage.obj", folder / "preview.png"
    result = cagekit("deform", source, target, "-o", out, "--save-cage", cage,
                     "--preview", preview, "--symmetry", "x", "--faces", "80", "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["method"] == "cage" and report["cage_faces"] <= 80
    assert {"chamfer", "p2f", "normal", "symmetry", "cage", "detail"} == set(report["losses"])
    assert report["energy"] <= report["iterations"] * 1e9  # a number, not null
    assert report["cd"] > 0 and report["dcotlap"] >= 0
    assert preview.stat().st_size > 10_000
    # the written cages reproduce the output through `cagekit apply`
    deformed_cage = folder / "cage_deformed.obj"
    again = folder / "again.obj"
    applied = cagekit("apply", source, cage, deformed_cage, "-o", again)
    assert applied.returncode == 0, applied.stderr
    np.testing.assert_allclose(load_obj(again)[0], load_obj(out)[0], atol=1e-9)
    # `cagekit eval` measures the same figures
    evaluated = json.loads(cagekit("eval", source, target, out, "--json").stdout)
    assert evaluated["cd"] == pytest.approx(report["cd"])
    assert evaluated["dcotlap"] == pytest.approx(report["dcotlap"])


def test_deform_with_green_coordinates_and_apply_reproduces_it(pair, tmp_path):
    folder, source, target = pair
    out, cage = tmp_path / "green.obj", tmp_path / "cage.obj"
    result = cagekit("deform", source, target, "-o", out, "--coords", "green", "--faces",
                     "80", "--save-cage", cage, "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    scale = json.loads(cagekit("deform", source, target, "-o", tmp_path / "scale.obj",
                               "--method", "scale", "--json").stdout)
    assert 0 < report["cd"] < scale["cd"]
    # the saved cages give the same result through `cagekit apply --coords green`
    again = tmp_path / "again.obj"
    applied = cagekit("apply", source, cage, tmp_path / "cage_deformed.obj", "-o", again,
                      "--coords", "green")
    assert applied.returncode == 0, applied.stderr
    np.testing.assert_allclose(load_obj(again)[0], load_obj(out)[0], atol=1e-8)


@pytest.mark.parametrize("method", ["scale", "nricp"])
def test_deform_baselines(pair, method):
    folder, source, target = pair
    out = folder / f"{method}.obj"
    result = cagekit("deform", source, target, "-o", out, "--method", method, "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["method"] == method and report["cage_faces"] is None
    assert load_obj(out)[0].shape == load_obj(source)[0].shape


def test_deform_with_landmarks_and_a_given_cage(pair, tmp_path):
    folder, source, target = pair
    V, _ = load_obj(source)
    Vt, _ = load_obj(target)
    save_landmarks(tmp_path / "src.json", {f"p{i}": V[i] for i in (0, 7, 50, 99)})
    save_landmarks(tmp_path / "tgt.json", {f"p{i}": Vt[i] for i in (0, 7, 50, 99)})
    cage_file = tmp_path / "cage.obj"
    assert cagekit("fit-cage", source, "-o", cage_file, "--faces", "80").returncode == 0
    out = tmp_path / "out.obj"
    result = cagekit("deform", source, target, "-o", out, "--cage", cage_file,
                     "--landmarks", tmp_path / "src.json", tmp_path / "tgt.json",
                     "--weight", "chamfer=1", "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["weights"]["chamfer"] == 1.0 and "landmarks" in report["losses"]


def test_deform_uses_the_shared_landmark_labels_and_warns_of_the_others(pair, tmp_path):
    folder, source, target = pair
    V, _ = load_obj(source)
    Vt, _ = load_obj(target)
    rows = (0, 7, 50, 99, 120)
    save_landmarks(tmp_path / "src.json", {**{f"p{i}": V[i] for i in rows}, "nose": V[3]})
    save_landmarks(tmp_path / "tgt.json", {**{f"p{i}": Vt[i] for i in rows}, "noze": Vt[3]})
    result = cagekit("deform", source, target, "-o", tmp_path / "out.obj", "--faces", "80",
                     "--landmarks", tmp_path / "src.json", tmp_path / "tgt.json", "--json")
    assert result.returncode == 0, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "warning" in lines[0], result.stderr
    assert "nose (only in" in lines[0] and "noze (only in" in lines[0]
    assert "src.json" in lines[0] and "tgt.json" in lines[0]
    assert "landmarks" in json.loads(result.stdout)["losses"]


def test_deform_bad_inputs_exit_2_with_one_line(pair, tmp_path):
    folder, source, target = pair
    before = source.read_bytes(), target.read_bytes()
    out = tmp_path / "out.obj"
    assert_bad_input(cagekit("deform", tmp_path / "missing.obj", target, "-o", out),
                     "missing.obj")
    broken = tmp_path / "broken.obj"
    broken.write_text("v 0 0 0\nv nan 1 0\nv 0 1 0\nf 1 2 3\n")
    assert_bad_input(cagekit("deform", source, broken, "-o", out), "broken.obj")
    assert_bad_input(cagekit("deform", source, target, "-o", target), str(target))
    assert_bad_input(cagekit("deform", source, target, "-o", out, "--cage", broken),
                     "broken.obj")
    save_landmarks(tmp_path / "a.json", {"nose": [0, 0, 0], "tail": [1, 0, 0]})
    save_landmarks(tmp_path / "b.json", {"nose": [0, 0, 0]})
    assert_bad_input(cagekit("deform", source, target, "-o", out, "--landmarks",
                             tmp_path / "a.json", tmp_path / "b.json"), "a.json", "b.json",
                     "share 1 landmark")
    assert_bad_input(cagekit("deform", source, target, "-o", out, "--weight", "smooth=1"),
                     "--weight", "smooth")
    assert_bad_input(cagekit("deform", source, target, "-o", out, "--weight", "cage=nan"),
                     "--weight")
    one_point = tmp_path / "one.xyz"
    one_point.write_text("0 0 0\n")
    result = cagekit("deform", source, one_point, "-o", out)
    assert_bad_input(result, "one.xyz")
    assert str(source) not in result.stderr  # the degenerate shape's file alone is named
    huge = tmp_path / "huge.xyz"
    huge.write_text("-1.7e308 0 0\n1.7e308 1 0\n0 0 1\n")
    assert_bad_input(cagekit("deform", source, huge, "-o", out, "--method", "scale"),
                     "huge.xyz")
    V, _ = load_obj(source)
    save_landmarks(tmp_path / "far.json", {f"p{i}": V[i] * 100 for i in range(4)})
    save_landmarks(tmp_path / "near.json", {f"p{i}": V[i] for i in range(4)})
    assert_bad_input(cagekit("deform", source, target, "-o", out, "--landmarks",
                             tmp_path / "far.json", tmp_path / "near.json"), "far.json")
    assert_bad_input(cagekit("deform", source, target, "-o", out, "--weight", "cage"))
    assert_bad_input(cagekit("deform", source, target, "-o", out, "--method", "scale",
                             "--symmetry", "x"))
    assert_bad_input(cagekit("deform", source, target, "-o", out, "--preview",
                             tmp_path / "p.jpg"), "p.jpg")
    assert not out.exists()
    assert (source.read_bytes(), target.read_bytes()) == before  # inputs untouched


# ------------------------------------------------- units, argument order (issue 33, item 3)


def test_deform_refuses_a_cage_in_other_units_with_the_hint(pair, tmp_path):
    folder, source, target = pair
    V, F = load_obj(source)
    cage_file = tmp_path / "cage.obj"
    assert cagekit("fit-cage", source, "-o", cage_file, "--faces", "80").returncode == 0
    in_mm = tmp_path / "source_mm.obj"
    save_mesh(in_mm, V * 10, F)  # the source in mm, its cage in cm
    out = tmp_path / "out.obj"
    result = cagekit("deform", in_mm, target, "-o", out, "--cage", cage_file)
    assert_bad_input(result, "source_mm.obj", "cage.obj", "lies outside",
                     "different units (", "in mm,", "in cm?)", "--allow-outside")
    assert not out.exists()
    assert_bad_input(cagekit("deform", source, target, "-o", out, "--allow-outside"),
                     "--allow-outside applies to a given --cage")
    for extra in (["--cage", cage_file], ["--method", "scale"]):
        assert_bad_input(cagekit("deform", source, target, "-o", out, "--faces", "80", *extra),
                         "--faces sets the fitted cage's budget: it does not apply")
    assert not out.exists()


def test_deform_suggests_o_for_an_output_given_as_a_positional(pair, tmp_path):
    folder, source, target = pair
    result = cagekit("deform", source, target, tmp_path / "out.obj")
    assert_bad_input(result, "Missing option '-o'", f"Did you mean `-o {tmp_path / 'out.obj'}`?")
    assert not (tmp_path / "out.obj").exists()
    # no guess when nothing was left over
    result = cagekit("deform", source, target)
    assert_bad_input(result, "Missing option '-o'")
    assert "Did you mean" not in result.stderr


def test_deform_names_the_argument_of_a_bad_file(pair, tmp_path):
    folder, source, target = pair
    result = cagekit("deform", source, tmp_path / "missing.obj", "-o", tmp_path / "out.obj")
    assert_bad_input(result, "TARGET (2nd argument) ", "missing.obj: ")


def test_the_preview_frames_shapes_alone_only_around_a_loose_cage():
    # a learned model's cage is about 3x its source: the preview frames the shapes alone
    import cagekit
    from cagekit.cli.deform import LOOSE_CAGE, _loose

    V, F = bumpy_blob(subdivisions=2)
    fitted = cagekit.fit_cage(V, F, faces=80).vertices
    assert not _loose(fitted, V)
    centre = V.mean(axis=0)
    assert _loose(centre + 3.0 * (fitted - centre), V)
    assert not _loose(centre + 0.9 * LOOSE_CAGE * (V - centre), V)


def test_deform_previews_a_loose_cage_cut_and_a_fitted_one_whole(pair, tmp_path, monkeypatch):
    from click.testing import CliRunner

    import cagekit
    import cagekit.render
    from cagekit.cli import main

    folder, source, target = pair
    V, F = load_obj(source)
    fitted = cagekit.fit_cage(V, F, faces=80)
    centre = V.mean(axis=0)
    framed = []
    monkeypatch.setattr(cagekit.render, "render_meshes",
                        lambda *a, **k: framed.append(k["frame_cages"]))
    for name, scale in (("fitted", 1.0), ("loose", 3.0)):
        cage = tmp_path / f"{name}.obj"
        save_mesh(cage, centre + scale * (fitted.vertices - centre), fitted.faces)
        result = CliRunner().invoke(main, [
            "deform", str(source), str(target), "--cage", str(cage), "-o",
            str(tmp_path / f"{name}_out.obj"), "--preview", str(tmp_path / f"{name}.png")])
        assert result.exit_code == 0, result.output
    assert framed == [True, False]
