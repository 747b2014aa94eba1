"""Procedural shape families (cagekit.datasets.synthetic) and ``cagekit synth``."""

import json
import os

import numpy as np
import pytest
import trimesh
from builders import ROOT, invoke
from scipy.spatial import cKDTree

import cagekit
from cagekit.cli.synth import FAMILIES as SYNTH_FAMILIES
from cagekit.datasets import synthetic
from cagekit.datasets.synthetic import FAMILIES, chair, family, table, vase
from cagekit.io import load_mesh

SEEDS = range(6)
MAKERS = [chair, table, vase]


def triangle_stats(V, F):
    """Areas and aspect ratios (longest edge / its altitude) of every triangle."""
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    longest = np.max([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                      np.linalg.norm(a - c, axis=1)], axis=0)
    return area, longest ** 2 / (2 * area)


@pytest.fixture(scope="module", params=[(m, s) for m in MAKERS for s in SEEDS],
                ids=lambda p: f"{p[0].__name__}{p[1]}")
def shape(request):
    make, seed = request.param
    return make(seed=seed)


# --------------------------------------------------------------------------- meshes


def test_arrays(shape):
    V, F = shape
    assert V.dtype == np.float64 and F.dtype == np.int64
    assert V.ndim == 2 and V.shape[1] == 3 and F.ndim == 2 and F.shape[1] == 3
    assert V.flags.c_contiguous and F.flags.c_contiguous
    assert np.isfinite(V).all()
    assert F.min() == 0 and F.max() == len(V) - 1
    assert 2000 <= len(V) <= 8000


def test_frame(shape):
    """y up, standing on y = 0, centred and mirror-symmetric about x = 0."""
    V, _ = shape
    assert V[:, 1].min() == 0.0
    size = V.max(axis=0) - V.min(axis=0)
    assert 0.15 < size[1] < 1.2 and (size < 2.0).all()
    assert abs(V[:, 0].max() + V[:, 0].min()) < 1e-9
    distance, _ = cKDTree(V).query(V * [-1.0, 1.0, 1.0])
    assert distance.max() < 1e-9


def test_triangle_quality(shape):
    V, F = shape
    area, aspect = triangle_stats(V, F)
    diagonal = np.linalg.norm(V.max(axis=0) - V.min(axis=0))
    assert area.min() > 1e-6 * diagonal ** 2
    assert aspect.max() < 6.0


def test_components_closed_and_outward(shape):
    V, F = shape
    mesh = trimesh.Trimesh(V, F, process=False)
    assert mesh.is_winding_consistent
    parts = mesh.split(only_watertight=False)
    assert sum(len(p.faces) for p in parts) == len(F)
    for part in parts:
        assert part.is_watertight and part.is_winding_consistent
        assert part.volume > 0
    assert fans_per_vertex(F, len(V)) == 1


def fans_per_vertex(F, n):
    """Largest number of separate triangle fans around one vertex (1: vertex-manifold).

    Two corners at a vertex belong to one fan when their triangles share an edge through
    it; the mesh must be closed and edge-manifold (every directed edge has one twin).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = len(F)
    tail = F.ravel()                          # corner 3f + k sits at vertex F[f, k]
    head = F[:, [1, 2, 0]].ravel()            # half-edge from corner 3f + k: tail -> head
    keys = tail * n + head
    order = np.argsort(keys)
    twin = order[np.searchsorted(keys[order], head * n + tail)]
    assert np.array_equal(keys[twin], head * n + tail)
    # the twin (head -> tail) starts at the corner of `head`; the corner of `tail` in
    # that triangle is the next one
    nxt = 3 * (twin // 3) + (twin % 3 + 1) % 3
    graph = coo_matrix((np.ones(3 * m), (np.arange(3 * m), nxt)), shape=(3 * m, 3 * m))
    count, label = connected_components(graph, directed=False)
    fans = np.zeros(n, dtype=np.int64)
    np.add.at(fans, tail[np.unique(label, return_index=True)[1]], 1)
    return int(fans.max())


# ---------------------------------------------------------------------- determinism


@pytest.mark.parametrize("make", MAKERS)
def test_same_seed_identical(make):
    V1, F1 = make(seed=11)
    V2, F2 = make(seed=11)
    assert V1.tobytes() == V2.tobytes() and F1.tobytes() == F2.tobytes()


@pytest.mark.parametrize("make", MAKERS)
def test_different_seeds_differ(make):
    sizes = [np.ptp(make(seed=s)[0], axis=0) for s in range(4)]
    for i in range(4):
        for j in range(i):
            assert np.abs(sizes[i] - sizes[j]).max() > 1e-3


def test_family():
    shapes = list(family("tables", 3, seed=4))
    assert len(shapes) == 3
    for i, (V, F) in enumerate(shapes):
        V2, F2 = table(seed=4 + i)
        assert np.array_equal(V, V2) and np.array_equal(F, F2)
    assert set(FAMILIES) == {"chairs", "tables", "vases"}
    assert tuple(FAMILIES) == SYNTH_FAMILIES
    with pytest.raises(ValueError, match="sofas"):
        next(family("sofas", 1))


# ----------------------------------------------------------------------- parameters


def test_overrides():
    V, _ = chair(seed=3, height=1.1)
    assert np.ptp(V[:, 1]) == pytest.approx(1.1, abs=1e-9)
    V, _ = chair(seed=3, seat_width=0.5, seat_depth=0.45, seat_height=0.44, back_height=0.4)
    assert np.ptp(V, axis=0) == pytest.approx([0.5, 0.84, 0.45], abs=1e-9)
    V, _ = table(seed=3, width=1.2, depth=0.7, height=0.72)
    assert np.ptp(V, axis=0) == pytest.approx([1.2, 0.72, 0.7], abs=1e-9)
    V, _ = vase(seed=3, height=0.3)
    assert np.ptp(V[:, 1]) == pytest.approx(0.3, abs=1e-9)


def test_override_keeps_other_draws():
    """Fixing one parameter leaves the others as the seed drew them."""
    V1, _ = chair(seed=5, back_height=0.3)
    V2, _ = chair(seed=5, back_height=0.5)
    assert np.ptp(V1[:, [0, 2]], axis=0) == pytest.approx(np.ptp(V2[:, [0, 2]], axis=0))
    assert np.ptp(V2[:, 1]) - np.ptp(V1[:, 1]) == pytest.approx(0.2)


@pytest.mark.parametrize("style", ["slats", "spindles", "ladder"])
def test_chair_styles(style):
    V, F = chair(seed=0, back_style=style, back_count=5, leg_style="round")
    assert 2000 <= len(V) <= 8000
    assert triangle_stats(V, F)[1].max() < 6.0


@pytest.mark.parametrize("legs", ["square", "tapered", "turned"])
def test_table_styles(legs):
    V, F = table(seed=1, leg_style=legs, lower="stretchers")
    assert 2000 <= len(V) <= 8000
    assert triangle_stats(V, F)[1].max() < 6.0


def test_vase_options():
    V, F = vase(seed=2, flutes=12, handles=True, ridges=4)
    assert 2000 <= len(V) <= 8000
    assert len(trimesh.Trimesh(V, F, process=False).split(only_watertight=False)) == 3
    with pytest.raises(ValueError, match="even"):
        vase(seed=2, flutes=7)


def test_bad_parameters():
    with pytest.raises(TypeError, match="colour"):
        chair(seed=0, colour="red")
    with pytest.raises(ValueError, match="leg_style"):
        table(seed=0, leg_style="cabriole")
    with pytest.raises(ValueError, match="height"):
        vase(seed=0, height=-1)
    with pytest.raises(ValueError, match="resolution"):
        chair(seed=0, resolution=0)


def test_resolution():
    small = len(vase(seed=1, resolution=0.5)[0])
    large = len(vase(seed=1, resolution=1.5)[0])
    assert small < 2000 < len(vase(seed=1)[0]) < 8000 < large


@pytest.mark.parametrize("make", MAKERS)
def test_fit_cage(make):
    V, F = make(seed=0)
    cage_v, cage_f, _ = cagekit.fit_cage(V, F, faces=200)
    assert len(cage_f) <= 200
    assert cagekit.cage_encloses(V, cage_v, cage_f)


# ----------------------------------------------------------------------------- demo


def test_demo_pair(tmp_path):
    """The bundled pair is what the script makes (same faces, coordinates to 1e-9 of the
    extent: another CPU rounds sin/cos differently), and the two chairs differ clearly."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "make_demo_pair", os.path.join(ROOT, "data", "make_demo_pair.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main(["--out", str(tmp_path)]) == 0
    sizes = []
    for name in ("chair_source.obj", "chair_target.obj"):
        bundled = os.path.join(ROOT, "data", "example", name)
        assert os.path.getsize(bundled) < 500_000
        V, F = load_mesh(bundled)
        V_new, F_new = load_mesh(tmp_path / name)
        assert np.array_equal(F_new, F) and V_new.shape == V.shape
        assert np.abs(V_new - V).max() <= 1e-9 * np.ptp(V, axis=0).max()
        sizes.append(np.ptp(V, axis=0))
    source, target = sizes
    assert source[1] > target[1] + 0.2 and target[0] > source[0] + 0.1


# ------------------------------------------------------------------------------ CLI


def test_cli_writes_files(tmp_path):
    out = tmp_path / "new" / "chairs"
    result = invoke("synth", "chairs", "-n", 3, "-o", out, "--seed", 2)
    assert result.exit_code == 0, result.output
    assert sorted(os.listdir(out)) == ["chair_0000.obj", "chair_0001.obj", "chair_0002.obj"]
    V, F = load_mesh(out / "chair_0001.obj")
    V2, F2 = chair(seed=3)
    assert np.array_equal(V, V2) and np.array_equal(F, F2)


def test_cli_json(tmp_path):
    result = invoke("synth", "vases", "-n", 2, "-o", tmp_path, "--format", "ply", "--json")
    assert result.exit_code == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["family"] == "vases" and report["n"] == 2 and report["seed"] == 0
    assert [os.path.basename(f) for f in report["files"]] == ["vase_0000.ply",
                                                              "vase_0001.ply"]
    assert all(os.path.exists(f) for f in report["files"])


def test_cli_existing_file(tmp_path):
    (tmp_path / "table_0001.obj").write_text("keep me")
    result = invoke("synth", "tables", "-n", 2, "-o", tmp_path)
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "table_0001.obj" in lines[0] and "exists" in lines[0]
    assert result.stdout == ""
    assert (tmp_path / "table_0001.obj").read_text() == "keep me"
    assert not (tmp_path / "table_0000.obj").exists()


def test_cli_bad_input(tmp_path):
    result = invoke("synth", "sofas", "-o", tmp_path)
    assert result.exit_code == 2
    assert len(result.stderr.strip().splitlines()) == 1 and "sofas" in result.stderr
    target = tmp_path / "file.txt"
    target.write_text("")
    result = invoke("synth", "chairs", "-o", target)
    assert result.exit_code == 2
    assert len(result.stderr.strip().splitlines()) == 1 and "file.txt" in result.stderr


def test_module_listed():
    assert "synthetic" in dir(cagekit.datasets) and synthetic.TARGET_VERTICES == 4500
