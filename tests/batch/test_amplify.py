"""Tests of cagekit.batch.amplify, cagekit.batch.collection and ``cagekit amplify``: plans, outputs,
resume after SIGKILL, isolation of broken files, the filter, determinism across worker
counts and a real local Dask cluster."""

import csv
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from builders import ROOT, cagekit

from cagekit.batch.amplify import amplify, plan_pairs
from cagekit.batch.collection import find_shapes
from cagekit.datasets import synthetic
from cagekit.errors import InputError, MeshFileWarning
from cagekit.io import load_mesh, save_mesh

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "io"))
from test_pmd import POSITIONS, pmd_bytes  # noqa: E402


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """Three small procedural chairs (two in tall/, one in low/) and a broken file."""
    root = tmp_path_factory.mktemp("collection")
    for name, seed in (("tall/a", 0), ("tall/b", 1), ("low/c", 2)):
        os.makedirs(root / os.path.dirname(name), exist_ok=True)
        save_mesh(root / f"{name}.obj", *synthetic.chair(seed=seed, resolution=0.5))
    (root / "low" / "broken.obj").write_text("v 0 0 0\nf 1 2 3\n")
    return root


def rows_of(out):
    with open(os.path.join(out, "manifest.csv"), newline="") as fh:
        return list(csv.DictReader(fh))


# ------------------------------------------------------------------------------ planning


def test_collection_names_categories_and_fingerprints(folder):
    shapes = find_shapes(str(folder))
    assert [s.name for s in shapes] == ["low/broken", "low/c", "tall/a", "tall/b"]
    assert [s.category for s in shapes] == ["low", "low", "tall", "tall"]
    assert len({s.fingerprint for s in shapes}) == 4 and shapes[2].stem == "tall-a"
    with pytest.raises(InputError, match="not a folder"):
        find_shapes(str(folder / "missing"))
    with pytest.raises(InputError, match="synthetic:<family>:<count>"):
        find_shapes("synthetic:sofas:3")


def test_plans_are_seeded_distinct_and_never_self_pairs():
    shapes = find_shapes("synthetic:vases:6")
    plan = plan_pairs(shapes, variations=30, seed=3)  # all 30 ordered pairs
    assert len(set((a.name, b.name) for a, b in plan)) == 30
    assert all(a.name != b.name for a, b in plan)
    assert plan_pairs(shapes, variations=7, seed=3) == plan_pairs(shapes, variations=7, seed=3)
    assert plan_pairs(shapes, variations=7, seed=3) != plan_pairs(shapes, variations=7, seed=4)
    with pytest.raises(InputError, match="between 1 and 30"):
        plan_pairs(shapes, variations=31)


def test_pairs_within_a_folder_only(folder):
    plan = plan_pairs(find_shapes(str(folder)), pairs="all", category_by="folder")
    assert sorted((a.name, b.name) for a, b in plan) == [
        ("low/broken", "low/c"), ("low/c", "low/broken"), ("tall/a", "tall/b"),
        ("tall/b", "tall/a")]


def test_pairs_file_with_unknown_names_exits_2_naming_them(folder, tmp_path):
    listed = tmp_path / "pairs.csv"
    listed.write_text("source,target\ntall/a,tall/b\ntall/a,nope\nghost,tall/b\n")
    result = cagekit("amplify", folder, "-o", tmp_path / "out", "--pairs", listed)
    assert result.returncode == 2
    assert "2 name(s) not in the collection: ghost, nope" in result.stderr
    assert "low/broken, low/c, tall/a ..." in result.stderr  # what a name looks like
    assert len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_a_pairs_file_may_use_the_short_names_the_outputs_take(folder, tmp_path):
    listed = tmp_path / "pairs.csv"
    # outputs a__b.obj, c__a.obj; the first pair listed again under its full names
    listed.write_text("source,target\na,tall/b\nc,a\ntall/a,tall/b\n")
    plan = plan_pairs(find_shapes(str(folder)), pairs=str(listed))
    assert [(a.name, b.name) for a, b in plan] == [("tall/a", "tall/b"), ("low/c", "tall/a")]
    # x/chair and y/chair keep both parts, and their files say x-chair: both spellings
    alike = tmp_path / "alike"
    for name in ("x/chair", "y/chair", "y/table"):
        (alike / name).parent.mkdir(parents=True, exist_ok=True)
        save_mesh(alike / f"{name}.obj", *synthetic.vase(seed=0, resolution=0.5))
    listed.write_text("x-chair,table\ny/chair,x-chair\n")
    plan = plan_pairs(find_shapes(str(alike)), pairs=str(listed))
    assert [(a.name, b.name) for a, b in plan] == [("x/chair", "y/table"),
                                                   ("y/chair", "x/chair")]


# ------------------------------------------------------------------------------- a batch


def test_batch_outputs_broken_file_filter_and_json(folder, tmp_path):
    out = tmp_path / "out"
    sheet = tmp_path / "sheet.png"
    result = cagekit("amplify", folder, "-o", out, "--pairs", "all", "--category-by",
                     "folder", "--method", "scale", "--workers", "1", "--contact-sheet",
                     sheet, "--json")
    assert result.returncode == 3, result.stderr  # the broken file's items failed
    report = json.loads(result.stdout)
    assert report["items"] == 4 and report["failed"] == 2
    rows = {(r["source"], r["target"]): r for r in rows_of(out)}
    assert rows[("low/broken", "low/c")]["status"] == "failed"
    assert "source" in rows[("low/broken", "low/c")]["error"]
    assert "broken.obj" in rows[("low/c", "low/broken")]["error"]
    good = rows[("tall/a", "tall/b")]
    assert good["status"] == "ok" and float(good["cd"]) > 0
    V, F = load_mesh(out / "variations" / "a__b.obj")
    source = load_mesh(folder / "tall" / "a.obj")
    assert V.shape == source[0].shape and np.array_equal(F, source[1])
    # the two finished pairs side by side, source, target and variation each
    from matplotlib.image import imread

    assert imread(sheet).shape[:2] == (270, 2 * 300)  # two tiles on one line
    # a filter that rejects everything moves the kept meshes to rejected/, redoing nothing
    again = cagekit("amplify", folder, "-o", out, "--pairs", "all", "--category-by",
                    "folder", "--method", "scale", "--workers", "1", "--max-cd", "0",
                    "--contact-sheet", tmp_path / "again.png")
    assert again.returncode == 3
    assert again.stdout.strip() == (f"4 items: 0 ok, 2 rejected, 2 failed; manifest "
                                    f"{out / 'manifest.csv'}; contact sheet "
                                    f"{tmp_path / 'again.png'}")
    rows = {(r["source"], r["target"]): r for r in rows_of(out)}
    assert rows[("tall/a", "tall/b")]["status"] == "rejected"
    assert rows[("tall/a", "tall/b")]["seconds"] == good["seconds"]  # not redone
    assert (out / "rejected" / "a__b.obj").exists()
    assert not (out / "variations" / "a__b.obj").exists()


def test_multi_part_variations_bent_beyond_the_threshold_are_rejected(tmp_path):
    rows = amplify("synthetic:chairs:3", str(tmp_path), pairs="all", method="scale",
                   workers=1, max_nonaffinity=0.0)
    # box scaling keeps every part exactly affine (non-affinity ~1e-15): only a threshold
    # of 0 rejects it, and then every multi-part variation is rejected
    assert {r["status"] for r in rows} == {"rejected"}
    assert all(r["parts"] >= 2 and r["part_nonaffinity_worst"] < 1e-9 for r in rows)
    kept = amplify("synthetic:chairs:3", str(tmp_path), pairs="all", method="scale",
                   workers=1, drop_rejected=True, max_nonaffinity=0.0)
    assert not os.listdir(tmp_path / "rejected") and len(kept) == 6


def test_results_do_not_depend_on_workers_or_a_dask_cluster(tmp_path):
    runs = {}
    for name, options in (("one", {"workers": 1}), ("two", {"workers": 2})):
        runs[name] = amplify("synthetic:vases:3", str(tmp_path / name), variations=4,
                             seed=5, **options)
    # a real local Dask cluster of two worker processes, through the command line
    result = cagekit("amplify", "synthetic:vases:3", "-o", tmp_path / "dask", "--variations",
                     "4", "--seed", "5", "--cluster", "local", "--workers", "2")
    assert result.returncode == 0, result.stderr
    # pymeshlab first imported in a worker's task thread corrupted the heap at exit
    assert "malloc" not in result.stderr, result.stderr
    runs["dask"] = json.loads((tmp_path / "dask" / "manifest.json").read_text())["items"]
    for name in ("two", "dask"):
        for a, b in zip(runs["one"], runs[name]):
            assert (a["source"], a["target"], a["status"]) == (b["source"], b["target"],
                                                                b["status"])
            assert a["cd"] == b["cd"] and a["dcotlap"] == b["dcotlap"]
            files = [load_mesh(tmp_path / run / "variations" / a["output"])[0]
                     if a["status"] == "ok" else None for run in ("one", name)]
            if files[0] is not None:
                np.testing.assert_array_equal(*files)
    # one cage per source, fitted once and reused: sources of several pairs fit once
    sources = [r["source"] for r in runs["one"]]
    fitted = [r["source"] for r in runs["one"] if r["cage_seconds"] > 0]
    assert sorted(fitted) == sorted(set(sources))
    assert len(os.listdir(tmp_path / "one" / "cages")) == len(set(sources))


def test_resume_after_sigkill_redoes_nothing_and_loses_nothing(tmp_path):
    out = tmp_path / "out"
    args = [sys.executable, "-m", "cagekit.cli", "amplify", "synthetic:vases:3", "-o",
            str(out), "--variations", "5", "--workers", "1"]
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    process = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    manifest = out / "manifest.json"
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline:
        if manifest.exists() and len(json.loads(manifest.read_text())["items"]) >= 2:
            break
        time.sleep(0.05)
    process.send_signal(signal.SIGKILL)
    process.wait()
    before = {(r["source"], r["target"]): r for r in json.loads(manifest.read_text())["items"]}
    assert 2 <= len(before) < 5
    result = cagekit("amplify", "synthetic:vases:3", "-o", out, "--variations", "5",
                     "--workers", "1", "--json")
    assert result.returncode == 0, result.stderr
    after = {(r["source"], r["target"]): r for r in json.loads(manifest.read_text())["items"]}
    assert len(after) == 5
    for key, row in before.items():
        assert after[key] == row  # kept as it was: not done twice
    assert not [f for f in os.listdir(out / "variations") if f.startswith(".")]
    # a finished batch: a rerun does nothing
    start = time.perf_counter()
    assert cagekit("amplify", "synthetic:vases:3", "-o", out, "--variations", "5").returncode \
        == 0
    assert json.loads(manifest.read_text())["items"] == list(after.values())
    assert time.perf_counter() - start < 60


def test_a_changed_input_redoes_its_items_only(tmp_path):
    collection = tmp_path / "shapes"
    collection.mkdir()
    for i in range(3):
        save_mesh(collection / f"v{i}.obj", *synthetic.vase(seed=i, resolution=0.5))
    out = str(tmp_path / "out")
    first = amplify(str(collection), out, pairs="all", method="scale", workers=1)
    save_mesh(collection / "v2.obj", *synthetic.vase(seed=7, resolution=0.5))
    second = amplify(str(collection), out, pairs="all", method="scale", workers=1)
    for a, b in zip(first, second):
        changed = "v2" in (a["source"], a["target"])
        assert (a["target_hash"] != b["target_hash"] or a["source_hash"] != b["source_hash"]
                ) == changed
        if not changed:
            assert a == b


def test_a_dead_worker_s_item_is_redone_an_item_s_own_failure_kept(tmp_path):
    collection = tmp_path / "shapes"
    collection.mkdir()
    for i in range(2):
        save_mesh(collection / f"v{i}.obj", *synthetic.vase(seed=i, resolution=0.5))
    out = tmp_path / "out"
    first = amplify(str(collection), str(out), pairs="all", method="scale", workers=1)
    manifest = json.loads((out / "manifest.json").read_text())
    errors = ["the worker failed: A process in the process pool was terminated abruptly",
              "source v0: contains no vertices"]
    for row, error in zip(manifest["items"], errors):
        row.update(status="failed", error=error)
    (out / "manifest.json").write_text(json.dumps(manifest))
    again = amplify(str(collection), str(out), pairs="all", method="scale", workers=1)
    assert again[0]["status"] == "ok" and again[0]["cd"] == first[0]["cd"]  # redone
    assert again[1]["status"] == "failed" and again[1]["error"] == errors[1]  # kept


def test_sigint_stops_a_pool_batch_cleanly(tmp_path):
    out = tmp_path / "out"
    args = [sys.executable, "-m", "cagekit.cli", "amplify", "synthetic:vases:3", "-o",
            str(out), "--variations", "6", "--workers", "2"]
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    process = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, text=True)
    manifest = out / "manifest.json"
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline:
        if manifest.exists() and json.loads(manifest.read_text())["items"]:
            break
        time.sleep(0.05)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 130 and stderr.strip().endswith("interrupted")
    rows = json.loads(manifest.read_text())["items"]
    assert 1 <= len(rows) < 6 and all(r["status"] in ("ok", "rejected") for r in rows)
    result = cagekit("amplify", "synthetic:vases:3", "-o", out, "--variations", "6",
                     "--workers", "2")
    assert result.returncode == 0, result.stderr
    assert len(json.loads(manifest.read_text())["items"]) == 6


def test_green_coordinates_are_recorded_and_a_change_redoes_the_items(tmp_path):
    out = tmp_path / "out"
    result = cagekit("amplify", "synthetic:vases:3", "-o", out, "--variations", "2",
                     "--coords", "green", "--workers", "1", "--json")
    assert result.returncode == 0, result.stderr
    rows = json.loads((out / "manifest.json").read_text())["items"]
    assert [r["coords"] for r in rows] == ["green", "green"]
    assert all(r["status"] in ("ok", "rejected") and r["cd"] > 0 for r in rows)
    # the same command with mvc redoes both items; the cages are reused (not refitted)
    again = amplify("synthetic:vases:3", str(out), variations=2, seed=0, workers=1)
    assert [r["coords"] for r in again] == ["mvc", "mvc"]
    assert all(r["cage_seconds"] == 0 for r in again)
    assert any(a["cd"] != b["cd"] for a, b in zip(rows, again))
    refused = cagekit("amplify", "synthetic:vases:3", "-o", tmp_path / "x", "--variations",
                      "1", "--method", "scale", "--coords", "green")
    assert refused.returncode == 2 and "--coords green" in refused.stderr


def test_what_a_source_loses_in_its_variations_is_said_once_a_source(tmp_path):
    """A game model (PMD, not written) gives OBJ variations without its UVs: one warning
    for each source, not one for each of its variations."""
    collection = tmp_path / "game"
    collection.mkdir()
    for name, scale in (("a", 1.0), ("b", 1.5), ("c", 0.7)):
        (collection / f"{name}.pmd").write_bytes(pmd_bytes(V=POSITIONS * scale))
    with pytest.warns(MeshFileWarning) as caught:
        rows = amplify(str(collection), str(tmp_path / "out"), pairs="all", method="scale",
                       workers=1, max_cd=np.inf)
    assert len(rows) == 6 and {r["status"] for r in rows} == {"ok"}
    lost = sorted(str(w.message) for w in caught if "not kept" in str(w.message))
    assert lost == [f"UVs, normals and bones of {collection / name}.pmd are not kept in OBJ; "
                    "cagekit writes no PMD" for name in "abc"]


def test_the_contact_sheet_does_not_warn_again_about_its_own_variations(tmp_path):
    """A source with faces of two vertices: its variations copy its file, and reading them
    for the contact sheet would say it again, naming the output."""
    collection = tmp_path / "shapes"
    collection.mkdir()
    octa = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    faces = "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n"
    for name, scale in (("a", [1, 1, 1]), ("b", [1.5, 1, 1]), ("c", [1, 0.7, 1])):
        verts = "".join(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in octa * scale)
        (collection / f"{name}.obj").write_text("g seat\n" + verts + faces + "f 1 2\n")
    with pytest.warns(MeshFileWarning) as caught:
        rows = amplify(str(collection), str(tmp_path / "out"), pairs="all", method="scale",
                       workers=1, max_cd=np.inf, contact_sheet_path=str(tmp_path / "s.png"))
    assert len(rows) == 6 and {r["status"] for r in rows} == {"ok"}
    dropped = [str(w.message) for w in caught if "fewer than 3 vertices" in str(w.message)]
    assert dropped and all(str(collection) in m for m in dropped)
    assert not any("variations" in m for m in dropped)
