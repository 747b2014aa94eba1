"""Training data of the learned mode (cagekit_learn.data): folders, cache, pairs, batches."""

import json
import os
import pathlib
import subprocess
import sys
import warnings

import numpy as np
import pytest

from cagekit.cage.shapes import box_cage, icosphere_cage
from cagekit.errors import CagekitWarning, InputError
from cagekit.io import save_mesh, save_points
from cagekit_learn import data
from cagekit_learn.data import (
    MESH_EXTENSIONS,
    ShapeCollection,
    augment,
    epoch_pairs,
    find_meshes,
    make_batch,
    shard,
)

P = 256


def box(half=(2.0, 1.0, 0.5), offset=(0.0, 0.0, 0.0)):
    V, F = box_cage(divisions=2, half_extent=half)
    return V + np.asarray(offset), F


def sphere(radius=1.0, offset=(0.0, 0.0, 0.0)):
    V, F = icosphere_cage(subdivisions=1, radius=radius)
    return V + np.asarray(offset), F


@pytest.fixture
def folder(tmp_path):
    """Three small meshes in two formats, one in a ShapeNet-like layout."""
    root = tmp_path / "shapes"
    (root / "03001627" / "aaa" / "models").mkdir(parents=True)
    (root / "misc").mkdir()
    save_mesh(root / "03001627" / "aaa" / "models" / "model_normalized.obj",
              *box((3.0, 1.0, 2.0), (5.0, -2.0, 1.0)))
    save_mesh(root / "misc" / "ball.ply", *sphere(4.0, (1.0, 1.0, 1.0)))
    save_mesh(root / "misc" / "brick.off", *box((0.2, 0.6, 0.1), (-3.0, 0.0, 0.0)))
    return root


def names_loaded(monkeypatch):
    """Record the files the module loads."""
    loaded = []
    real = data.load_shape

    def spy(path):
        loaded.append(pathlib.Path(path).name)
        return real(path)

    monkeypatch.setattr(data, "load_shape", spy)
    return loaded


def bump_mtime(path, ns=10**9):
    st = os.stat(path)
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + ns))


# ------------------------------------------------------------------------ find_meshes


def test_find_meshes_layouts_hidden_and_case(tmp_path):
    V, F = box()
    files = [
        "03001627/b2/model.obj",
        "03001627/a1/models/model_normalized.obj",
        "02871439/c3/model.obj",
        "other/UPPER.PLY",
        "other/thing.off",
        "other/x.stl",
        "top.glb",
    ]
    for rel in files:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        save_mesh(tmp_path / rel, V, F)
    # not meshes, hidden, or cache
    (tmp_path / "03001627" / "a1" / "models" / "model_normalized.json").write_text("{}")
    (tmp_path / "03001627" / "b2" / "model.mtl").write_text("newmtl x\n")
    (tmp_path / "notes.txt").write_text("1 2 3\n")
    (tmp_path / "dir.obj").mkdir()  # a folder with a mesh extension
    (tmp_path / ".cagekit-cache").mkdir()
    save_mesh(tmp_path / ".cagekit-cache" / "bad.obj", V, F)
    (tmp_path / ".git" / "sub").mkdir(parents=True)
    save_mesh(tmp_path / ".git" / "sub" / "bad.obj", V, F)
    save_mesh(tmp_path / "other" / ".hidden.obj", V, F)

    found = find_meshes(tmp_path)
    rel = [p.relative_to(tmp_path).as_posix() for p in found]
    assert rel == sorted(files)
    assert all(isinstance(p, pathlib.Path) and p.is_file() for p in found)
    assert find_meshes(str(tmp_path)) == found
    assert set(MESH_EXTENSIONS) >= {".obj", ".ply", ".off", ".stl", ".glb", ".gltf"}


def test_find_meshes_errors(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        find_meshes(tmp_path / "missing")
    (tmp_path / "f.obj").write_text("")
    with pytest.raises(InputError, match="not a folder"):
        find_meshes(tmp_path / "f.obj")
    assert find_meshes(tmp_path) == [tmp_path / "f.obj"]


# ------------------------------------------------------------------------ from_folder


def test_from_folder_normalised_samples(folder):
    c = ShapeCollection.from_folder(folder, points=P)
    assert c.names == ["03001627/aaa/models/model_normalized.obj", "misc/ball.ply",
                       "misc/brick.off"]
    assert len(c) == 3
    assert c.points.shape == (3, P, 3) and c.points.dtype == np.float32
    assert np.abs(c.points).max() <= 1.0 + 1e-6
    # longest axis: x for the first box, y for the brick, any for the sphere
    assert np.allclose(np.abs(c.points[0, :, 0]).max(), 1.0, atol=1e-6)
    assert np.allclose(np.abs(c.points[2, :, 1]).max(), 1.0, atol=1e-6)
    assert np.abs(c.points[1]).max() > 0.9
    # bbox centred: a box's samples reach both faces of the longest axis
    for i, axis in [(0, 0), (2, 1)]:
        assert c.points[i, :, axis].min() == pytest.approx(-1.0, abs=1e-6)
    # the other axes keep the box's proportions (3 : 1 : 2 -> 1 : 1/3 : 2/3)
    assert np.abs(c.points[0]).max(axis=0) == pytest.approx([1, 1 / 3, 2 / 3], abs=1e-6)


def test_from_folder_deterministic_and_seeded(folder, tmp_path):
    a = ShapeCollection.from_folder(folder, points=P, cache_dir=False)
    b = ShapeCollection.from_folder(folder, points=P, cache_dir=False)
    assert np.array_equal(a.points, b.points)
    other = ShapeCollection.from_folder(folder, points=P, seed=1, cache_dir=False)
    assert not np.array_equal(a.points[0], other.points[0])
    assert not (folder / ".cagekit-cache").exists()
    # adding a file does not change other shapes' samples
    save_mesh(folder / "misc" / "another.obj", *sphere(2.0))
    c = ShapeCollection.from_folder(folder, points=P, cache_dir=False)
    assert len(c) == 4
    for i, name in enumerate(a.names):
        assert np.array_equal(c.points[c.names.index(name)], a.points[i])


def test_cache_hit_reads_no_mesh(folder, monkeypatch):
    first = ShapeCollection.from_folder(folder, points=P)
    cache = folder / ".cagekit-cache"
    assert (cache / "samples.npz").is_file() and (cache / "manifest.json").is_file()
    assert not [p for p in cache.iterdir() if ".tmp-" in p.name]
    manifest_mtime = (cache / "manifest.json").stat().st_mtime_ns

    def fail(path):
        raise AssertionError(f"mesh read on a cache hit: {path}")

    monkeypatch.setattr(data, "load_shape", fail)
    monkeypatch.setattr(data, "sample_surface", fail)
    second = ShapeCollection.from_folder(folder, points=P)
    assert second.names == first.names
    assert np.array_equal(second.points, first.points)
    assert (cache / "manifest.json").stat().st_mtime_ns == manifest_mtime  # not rewritten


def test_manifest_content(folder):
    ShapeCollection.from_folder(folder, points=P, seed=3)
    manifest = json.loads((folder / ".cagekit-cache" / "manifest.json").read_text())
    assert manifest["format"] == data.CACHE_FORMAT
    assert manifest["points"] == P and manifest["seed"] == 3
    assert manifest["skipped"] == []
    files = manifest["files"]
    assert [f["name"] for f in files] == [p.relative_to(folder).as_posix()
                                          for p in find_meshes(folder)]
    for f in files:
        st = (folder / f["name"]).stat()
        assert f["size"] == st.st_size and f["mtime_ns"] == st.st_mtime_ns
    with np.load(folder / ".cagekit-cache" / "samples.npz") as npz:
        assert npz["names"].tolist() == [f["name"] for f in files]
        assert npz["points"].shape == (3, P, 3)


def test_partial_resampling(folder, monkeypatch):
    first = ShapeCollection.from_folder(folder, points=P)
    # change one file, add one, remove one
    save_mesh(folder / "misc" / "ball.ply", *box((1.0, 1.0, 3.0)))
    bump_mtime(folder / "misc" / "ball.ply")
    save_mesh(folder / "new.obj", *sphere(0.5))
    os.remove(folder / "misc" / "brick.off")
    loaded = names_loaded(monkeypatch)
    second = ShapeCollection.from_folder(folder, points=P)
    assert sorted(loaded) == ["ball.ply", "new.obj"]
    assert second.names == ["03001627/aaa/models/model_normalized.obj", "misc/ball.ply",
                            "new.obj"]
    assert np.array_equal(second.points[0], first.points[0])
    assert not np.array_equal(second.points[1], first.points[1])
    # the box now has its longest axis along z
    assert np.abs(second.points[1, :, 2]).max() == pytest.approx(1.0, abs=1e-6)
    # and all of it is cached again
    loaded.clear()
    third = ShapeCollection.from_folder(folder, points=P)
    assert loaded == [] and np.array_equal(third.points, second.points)


def test_points_or_seed_change_resamples_all(folder, monkeypatch):
    ShapeCollection.from_folder(folder, points=P)
    loaded = names_loaded(monkeypatch)
    c = ShapeCollection.from_folder(folder, points=P // 2)
    assert len(loaded) == 3 and c.points.shape == (3, P // 2, 3)
    loaded.clear()
    ShapeCollection.from_folder(folder, points=P // 2, seed=5)
    assert len(loaded) == 3
    loaded.clear()
    ShapeCollection.from_folder(folder, points=P // 2, seed=5)
    assert loaded == []


def test_broken_file_skipped_with_warning(folder, monkeypatch):
    (folder / "misc" / "broken.obj").write_text("v 0 0 0\nf 1 2 3\n")
    with pytest.warns(CagekitWarning, match=r"broken\.obj") as record:
        c = ShapeCollection.from_folder(folder, points=P)
    assert len(c) == 3 and "misc/broken.obj" not in c.names
    message = str([w.message for w in record if "broken.obj" in str(w.message)][0])
    assert message.startswith("skipping ") and str(folder / "misc" / "broken.obj") in message
    manifest = json.loads((folder / ".cagekit-cache" / "manifest.json").read_text())
    assert [s["name"] for s in manifest["skipped"]] == ["misc/broken.obj"]
    assert manifest["skipped"][0]["problem"]
    # remembered: warned again without reading it
    loaded = names_loaded(monkeypatch)
    with pytest.warns(UserWarning, match=r"broken\.obj"):
        ShapeCollection.from_folder(folder, points=P)
    assert loaded == []


def test_degenerate_shape_skipped(folder):
    save_mesh(folder / "flat.obj", [[0, 0, 0], [0, 0, 0], [0, 0, 0]], [[0, 1, 2]])
    with pytest.warns(UserWarning, match=r"flat\.obj.*coincide"):
        c = ShapeCollection.from_folder(folder, points=P, cache_dir=False)
    assert len(c) == 3


def test_point_cloud_file(folder):
    rng = np.random.default_rng(0)
    save_points(folder / "cloud.ply", rng.normal(size=(100, 3)) * [1, 2, 3])
    c = ShapeCollection.from_folder(folder, points=P, cache_dir=False)
    cloud = c.points[c.names.index("cloud.ply")]
    assert cloud.shape == (P, 3) and np.abs(cloud).max() <= 1.0 + 1e-6


def test_empty_and_too_small_folders(tmp_path):
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(InputError, match="no mesh") as info:
        ShapeCollection.from_folder(tmp_path)
    assert str(tmp_path) in str(info.value)
    save_mesh(tmp_path / "one.obj", *box())
    with pytest.raises(InputError, match="at least 2") as info:
        ShapeCollection.from_folder(tmp_path, points=P)
    assert str(tmp_path) in str(info.value)
    (tmp_path / "two.obj").write_text("garbage\n")
    with pytest.warns(UserWarning, match=r"two\.obj"), pytest.raises(InputError,
                                                                      match="at least 2"):
        ShapeCollection.from_folder(tmp_path, points=P)


@pytest.mark.skipif(os.name != "posix", reason="needs a POSIX read-only folder")
def test_read_only_root_falls_back(folder, read_only):
    expected = ShapeCollection.from_folder(folder, points=P, cache_dir=False)
    with read_only(folder):
        with pytest.warns(UserWarning, match="not caching"):
            c = ShapeCollection.from_folder(folder, points=P)
        assert np.array_equal(c.points, expected.points)
        assert not (folder / ".cagekit-cache").exists()


def test_explicit_cache_dir_and_corrupt_cache(folder, tmp_path, monkeypatch):
    cache = tmp_path / "elsewhere" / "cache"
    first = ShapeCollection.from_folder(folder, points=P, cache_dir=cache)
    assert (cache / "manifest.json").is_file() and not (folder / ".cagekit-cache").exists()
    (cache / "samples.npz").write_bytes(b"not a zip")
    loaded = names_loaded(monkeypatch)
    with pytest.warns(UserWarning, match="unreadable cache"):
        again = ShapeCollection.from_folder(folder, points=P, cache_dir=cache)
    assert len(loaded) == 3 and np.array_equal(again.points, first.points)


def test_mismatched_cache_files_rebuild(folder, monkeypatch):
    ShapeCollection.from_folder(folder, points=P)
    cache = folder / ".cagekit-cache"
    manifest = json.loads((cache / "manifest.json").read_text())
    manifest["token"] = "0" * 16  # as if the samples were written by another run
    (cache / "manifest.json").write_text(json.dumps(manifest))
    loaded = names_loaded(monkeypatch)
    ShapeCollection.from_folder(folder, points=P)
    assert len(loaded) == 3


def test_progress_bar(folder, capsys):
    ShapeCollection.from_folder(folder, points=P, cache_dir=False, progress=True)
    assert "3/3" in capsys.readouterr().err


# -------------------------------------------------------------------------- synthetic


def test_synthetic_collection():
    c = ShapeCollection.synthetic("vases", n=3, seed=2, points=128, resolution=0.5)
    assert c.names == ["vases/0000", "vases/0001", "vases/0002"]
    assert c.points.shape == (3, 128, 3) and c.points.dtype == np.float32
    assert np.abs(c.points).max() <= 1.0 + 1e-6
    assert (np.abs(c.points).max(axis=(1, 2)) > 0.95).all()
    again = ShapeCollection.synthetic("vases", n=3, seed=2, points=128, resolution=0.5)
    assert np.array_equal(c.points, again.points)
    shifted = ShapeCollection.synthetic("vases", n=2, seed=3, points=128, resolution=0.5)
    assert not np.array_equal(shifted.points[0], c.points[1])  # other sampling seed
    with pytest.raises(InputError, match="unknown family"):
        ShapeCollection.synthetic("sofas", n=2)


# ------------------------------------------------------------------- arrays and split


def test_from_arrays_and_validation():
    pts = np.random.default_rng(0).random((4, 8, 3))
    c = ShapeCollection.from_arrays(["a", "b", "c", "d"], pts)
    assert c.points.dtype == np.float32 and np.allclose(c.points, pts)
    pts[0] = 5.0
    assert not np.allclose(c.points[0], 5.0)  # copied
    with pytest.raises(InputError):
        ShapeCollection.from_arrays(["a"], pts)
    with pytest.raises(InputError):
        ShapeCollection.from_arrays(["a", "a", "b", "c"], pts)
    with pytest.raises(InputError):
        ShapeCollection.from_arrays(["a"], np.zeros((1, 8, 2)))
    with pytest.raises(InputError):
        ShapeCollection.from_arrays(["a"], np.full((1, 8, 3), np.nan))


# ----------------------------------------------------------------------------- pairs


@pytest.mark.parametrize("n", [2, 3, 17, 300])
def test_epoch_pairs(n):
    p = epoch_pairs(n, epoch=4, seed=7)
    assert p.shape == (n, 2) and p.dtype == np.int64
    assert sorted(p[:, 0].tolist()) == list(range(n))
    assert (p[:, 0] != p[:, 1]).all()
    assert ((0 <= p[:, 1]) & (p[:, 1] < n)).all()
    assert np.array_equal(p, epoch_pairs(n, epoch=4, seed=7))
    if n > 2:
        assert not np.array_equal(p, epoch_pairs(n, epoch=5, seed=7))
        assert not np.array_equal(p, epoch_pairs(n, epoch=4, seed=8))


def test_epoch_pairs_targets_cover_others():
    counts = np.zeros((5, 5), int)
    for epoch in range(400):
        for s, t in epoch_pairs(5, epoch):
            counts[s, t] += 1
    assert (np.diag(counts) == 0).all()
    off = counts[~np.eye(5, dtype=bool)]
    assert off.min() > 60  # ~100 each when uniform


def test_epoch_pairs_errors():
    with pytest.raises(InputError):
        epoch_pairs(1, 0)
    with pytest.raises(InputError):
        epoch_pairs(5, -1)


@pytest.mark.parametrize("n, world", [(10, 1), (10, 3), (12, 4), (7, 7)])
def test_shard(n, world):
    pairs = epoch_pairs(n, epoch=0)
    shares = [shard(pairs, r, world) for r in range(world)]
    used = n // world * world
    assert {len(s) for s in shares} == {n // world}
    rows = np.concatenate(shares)
    assert sorted(map(tuple, rows.tolist())) == sorted(map(tuple, pairs[:used].tolist()))
    assert len({tuple(r) for r in rows.tolist()}) == used  # disjoint
    assert shares[0].dtype == np.int64


def test_shard_errors():
    pairs = epoch_pairs(4, 0)
    with pytest.raises(InputError):
        shard(pairs, 2, 2)
    with pytest.raises(InputError):
        shard(pairs, 0, 0)
    with pytest.raises(InputError):
        shard(pairs, 0, 5)


# ------------------------------------------------------------------------ augmentation


def test_augment_ranges_and_normalisation():
    rng = np.random.default_rng(0)
    base = np.random.default_rng(1).uniform(-1, 1, (200, 3)) * [1.0, 0.6, 0.3]
    base = (base - 0.5 * (base.max(0) + base.min(0))) / (0.5 * np.ptp(base, 0).max())
    extent = np.ptp(base, axis=0)
    ratios = []
    for _ in range(200):
        out = augment(base, rng)
        assert out.shape == base.shape and out.dtype == np.float32
        lo, hi = out.min(0), out.max(0)
        assert np.allclose(lo + hi, 0, atol=1e-6)
        assert (hi - lo).max() == pytest.approx(2.0, abs=1e-5)
        r = (hi - lo) / extent
        ratios.append(r / r[0])
    ratios = np.array(ratios)[:, 1:]
    assert ratios.min() >= 0.75 / 1.25 - 1e-5 and ratios.max() <= 1.25 / 0.75 + 1e-5
    assert ratios.min() < 0.75 and ratios.max() > 1.3  # the range is used
    narrow = augment(base, 0, low=1.0, high=1.0)
    assert np.allclose(narrow, base, atol=1e-6)
    with pytest.raises(InputError):
        augment(base, rng, low=1.2, high=1.0)


# ----------------------------------------------------------------------------- batches


def test_make_batch():
    torch = pytest.importorskip("torch")
    c = ShapeCollection.synthetic("vases", n=4, points=64, resolution=0.5)
    pairs = epoch_pairs(4, epoch=2)[:3]
    b = make_batch(c, pairs, epoch=2, step=5)
    assert b["source"].shape == (3, 64, 3) and b["source"].dtype == torch.float32
    assert b["target"].shape == (3, 64, 3)
    assert b["source_index"].dtype == torch.long
    assert b["source_index"].tolist() == pairs[:, 0].tolist()
    assert b["target_index"].tolist() == pairs[:, 1].tolist()
    same = make_batch(c, pairs, epoch=2, step=5)
    for key in b:
        assert torch.equal(b[key], same[key])
    other = make_batch(c, pairs, epoch=2, step=6)
    assert not torch.equal(b["source"], other["source"])
    assert not torch.equal(b["source"], make_batch(c, pairs, epoch=3, step=5)["source"])
    assert not torch.equal(b["source"], make_batch(c, pairs, epoch=2, step=5,
                                                   seed=1)["source"])
    # augmented and re-normalised, independently for source and target
    assert not torch.equal(b["source"][0], torch.from_numpy(c.points[pairs[0, 0]]))
    extent = b["source"].amax(1) - b["source"].amin(1)
    assert torch.allclose(extent.amax(1), torch.full((3,), 2.0), atol=1e-5)
    self_pair = make_batch(c, [[1, 1]], epoch=0, step=0)
    assert not torch.equal(self_pair["source"], self_pair["target"])
    plain = make_batch(c, pairs, epoch=2, step=5, augmentation=False, dtype=torch.float64)
    assert plain["source"].dtype == torch.float64
    assert np.array_equal(plain["target"].numpy(), c.points[pairs[:, 1]])
    with pytest.raises(InputError):
        make_batch(c, [[0, 4]], epoch=0, step=0)


def test_import_without_torch():
    code = ("import sys, cagekit_learn.data as d; "
            "d.ShapeCollection.synthetic('vases', 2, points=8, resolution=0.5); "
            "print('torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=pathlib.Path(__file__).parents[2])
    assert out.stdout.strip() == "False"


def test_no_warning_on_clean_folder(folder):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ShapeCollection.from_folder(folder, points=P)
        ShapeCollection.from_folder(folder, points=P)


def test_unwritable_default_cache_falls_back(folder):
    """Works as root too: the cache folder's name is taken by a file."""
    (folder / ".cagekit-cache").write_text("not a folder")
    expected = ShapeCollection.from_folder(folder, points=P, cache_dir=False)
    with pytest.warns(UserWarning, match="not caching"):
        c = ShapeCollection.from_folder(folder, points=P)
    assert np.array_equal(c.points, expected.points)
    assert (folder / ".cagekit-cache").read_text() == "not a folder"
    with pytest.raises(InputError, match="cache"):
        ShapeCollection.from_folder(folder, points=P, cache_dir=folder / ".cagekit-cache")
