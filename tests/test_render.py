"""Tests of cagekit.render and of the bundled example in data/example."""

import os

import numpy as np
import pytest
from builders import EXAMPLE, ROOT
from matplotlib.image import imread

from cagekit.cage import unique_edges
from cagekit.render import MAX_FACES, render_grid, render_meshes


def read_obj(path):
    """Minimal OBJ reader for the tests (vertices and triangle faces only)."""
    V, F = [], []
    with open(path) as fh:
        for line in fh:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                V.append([float(x) for x in parts[1:4]])
            elif parts[0] == "f":
                F.append([int(x.split("/")[0]) - 1 for x in parts[1:4]])
    return np.array(V, dtype=np.float64), np.array(F, dtype=np.int64)


def octahedron(scale=1.0):
    V = scale * np.array(
        [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float
    )
    F = np.array(
        [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    )
    return V, F


def sphere(n_theta=40, n_phi=20):
    """A UV sphere (closed, outward) with 2 * n_theta * (n_phi - 1) faces."""
    import trimesh

    m = trimesh.creation.uv_sphere(count=[n_phi, n_theta])
    return np.asarray(m.vertices), np.asarray(m.faces, dtype=np.int64)


def image(path):
    img = imread(path)
    assert img.ndim == 3
    return img[..., :3]


def test_png_written_with_requested_size(tmp_path):
    out = tmp_path / "a.png"
    ret = render_meshes([octahedron(), octahedron(2.0)], out, size=(200, 150),
                        views=((20, -60), (90, 0)))
    assert ret == str(out)
    img = image(out)
    assert img.shape[:2] == (2 * 150, 2 * 200)  # rows = views, columns = shapes
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 10  # not one flat colour
    assert [p for p in os.listdir(tmp_path) if ".tmp" in p] == []  # no temporary left


def test_cage_wireframe_changes_the_image(tmp_path):
    shape = octahedron()
    cage = octahedron(1.6)
    render_meshes([shape], tmp_path / "plain.png", size=(160, 160))
    render_meshes([shape], tmp_path / "caged.png", cages=[cage], size=(160, 160))
    plain, caged = image(tmp_path / "plain.png"), image(tmp_path / "caged.png")
    assert plain.shape == caged.shape
    assert np.abs(plain - caged).max() > 0.2
    # the cage's orange shows up only in the caged picture
    orange = (caged[..., 0] > 0.7) & (caged[..., 2] < 0.35)
    assert orange.sum() > 50
    assert ((plain[..., 0] > 0.7) & (plain[..., 2] < 0.35)).sum() == 0


def test_frame_cages_false_frames_the_shape_and_cuts_a_loose_cage(tmp_path):
    shape, loose = octahedron(), octahedron(4.0)
    render_meshes([shape], tmp_path / "all.png", cages=[loose], size=(160, 160))
    render_meshes([shape], tmp_path / "shape.png", cages=[loose], size=(160, 160),
                  frame_cages=False)
    render_meshes([shape], tmp_path / "plain.png", size=(160, 160))

    def blueish(img):
        return int((img[..., 2] > img[..., 0] + 0.05).sum())

    framed, cut, plain = (image(tmp_path / f"{n}.png") for n in ("all", "shape", "plain"))
    # framed on the shape, it fills its panel as without the cage (not a 16th of it)
    assert blueish(cut) > 8 * blueish(framed)
    assert blueish(cut) > 0.8 * blueish(plain)
    # the cage is still drawn, cut at the panel's edges
    assert ((cut[..., 0] > 0.7) & (cut[..., 2] < 0.35)).sum() > 50


def test_shading_shows_faces(tmp_path):
    """Faces at different angles to the light get different shades."""
    render_meshes([octahedron()], tmp_path / "o.png", size=(160, 160))
    img = image(tmp_path / "o.png")
    blueish = img[(img[..., 2] > img[..., 0] + 0.05)]
    assert len(blueish) > 100
    assert blueish[:, 2].max() - blueish[:, 2].min() > 0.2


def test_point_cloud_titles_caption(tmp_path):
    V, _ = sphere()
    out = tmp_path / "cloud.png"
    render_meshes([(V, None), (V, np.zeros((0, 3), int))], out, titles=["a", "b"],
                  caption="two clouds", size=(120, 120))
    img = image(out)
    assert img.shape[:2] == (120, 240)
    assert (img.sum(axis=-1) < 2.0).sum() > 100  # dots (and text) were drawn


def test_dollar_signs_in_titles_and_caption_are_text(tmp_path):
    # "$x^$" is not valid mathtext: matplotlib would fail when drawing it as math
    out = tmp_path / "dollars.png"
    render_meshes([octahedron(), octahedron()], out, titles=["$x^$", "cost $5"],
                  caption="$x^$ and $", size=(120, 120))
    assert image(out).shape[:2] == (120, 240)


@pytest.mark.parametrize("scale", [2.0**600, 2.0**-600, 1e200, 1e-200],
                         ids=["2**600", "2**-600", "1e200", "1e-200"])
def test_very_large_or_small_coordinates_draw_the_same_picture(tmp_path, scale):
    V, F = octahedron()
    cage = octahedron(1.6)
    render_meshes([(V, F), (V, None)], tmp_path / "ref.png", cages=[cage, None],
                  size=(100, 100))
    render_meshes([(V * scale, F), (V * scale, None)], tmp_path / "scaled.png",
                  cages=[(cage[0] * scale, cage[1]), None], size=(100, 100))
    ref, scaled = image(tmp_path / "ref.png"), image(tmp_path / "scaled.png")
    if np.log2(scale) % 1 == 0:  # a power of two: the same picture, bit for bit
        assert np.array_equal(ref, scaled)
    else:
        assert np.abs(ref - scaled).mean() < 0.01


def test_large_mesh_is_reduced_before_drawing(tmp_path, monkeypatch):
    """What keeps a big mesh fast to draw: at most MAX_FACES polygons reach matplotlib."""
    import cagekit.render as render

    drawn = []
    real = render.Poly3DCollection

    def counting(verts, *args, **kwargs):
        drawn.append(len(verts))
        return real(verts, *args, **kwargs)

    monkeypatch.setattr(render, "Poly3DCollection", counting)
    V, F = sphere(n_theta=400, n_phi=100)  # ~79k faces
    assert len(F) > 2 * MAX_FACES
    render_meshes([(V, F)], tmp_path / "big.png", size=(200, 200))
    assert len(drawn) == 1 and 0.2 * MAX_FACES < drawn[0] <= MAX_FACES, drawn
    img = image(tmp_path / "big.png")
    # the reduced sphere still looks solid: no white holes in the middle of the disc
    centre = img[80:120, 80:120]
    assert (centre.min(axis=-1) > 0.97).sum() == 0


def test_render_is_deterministic(tmp_path):
    V, F = sphere(n_theta=300, n_phi=80)
    render_meshes([(V, F)], tmp_path / "a.png", size=(100, 100))
    render_meshes([(V, F)], tmp_path / "b.png", size=(100, 100))
    assert np.array_equal(image(tmp_path / "a.png"), image(tmp_path / "b.png"))


def test_unique_edges():
    _, F = octahedron()
    E = unique_edges(F)
    assert E.shape == (12, 2)
    assert np.all(E[:, 0] < E[:, 1])


@pytest.mark.parametrize(
    "kwargs",
    [
        {"meshes": []},
        {"meshes": [(np.zeros((3, 2)), None)]},
        {"meshes": [octahedron()], "cages": [None, None]},
        {"meshes": [octahedron()], "titles": ["a", "b"]},
        {"meshes": [(octahedron()[0], np.array([[0, 1, 9]]))]},
        {"meshes": [octahedron()], "up": "w"},
    ],
)
def test_bad_arguments_raise(tmp_path, kwargs):
    with pytest.raises(ValueError):
        render_meshes(path=tmp_path / "x.png", **kwargs)
    assert not os.listdir(tmp_path)


def test_unwritable_destination_raises(tmp_path):
    from cagekit.errors import InputError

    with pytest.raises((OSError, InputError)):
        render_meshes([octahedron()], tmp_path / "missing-folder" / "x.png")
    (tmp_path / "folder.png").mkdir()
    with pytest.raises((OSError, InputError)):
        render_meshes([octahedron()], tmp_path / "folder.png")
    assert os.listdir(tmp_path) == ["folder.png"]


# --- the bundled example ----------------------------------------------------------------


def _closed_oriented(F):
    """Each directed edge exactly once and its reverse present."""
    directed = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    as_set = {tuple(e) for e in directed.tolist()}
    return len(as_set) == len(directed) and all((b, a) in as_set for a, b in as_set)


def _signed_volume(V, F):
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def test_example_files_are_valid():
    import igl

    shape = read_obj(os.path.join(EXAMPLE, "shape.obj"))
    cage = read_obj(os.path.join(EXAMPLE, "cage.obj"))
    deformed = read_obj(os.path.join(EXAMPLE, "cage_deformed.obj"))
    assert 5_000 <= len(shape[1]) <= 20_000
    assert 50 <= len(cage[1]) <= 150
    for V, F in (shape, cage, deformed):
        assert np.all(np.isfinite(V))
        assert _closed_oriented(F)
        assert _signed_volume(V, F) > 0  # outward normals
    assert np.array_equal(cage[1], deformed[1])
    assert cage[0].shape == deformed[0].shape
    assert np.abs(cage[0] - deformed[0]).max() > 0.2  # an obvious deformation
    w = igl.winding_number(cage[0], cage[1], shape[0])
    assert np.all(np.abs(w - 1.0) < 1e-6)


def test_example_script_reproduces_the_files(tmp_path):
    """The script makes the bundled files again: same faces, coordinates equal to 1e-9 of
    the extent (the last digits may differ between CPUs: SIMD sin/cos, FMA)."""
    import subprocess
    import sys

    script = os.path.join(ROOT, "data", "make_example.py")
    subprocess.run([sys.executable, script, "--out", str(tmp_path), "--no-check"],
                   check=True, capture_output=True)
    for name in ("shape.obj", "cage.obj", "cage_deformed.obj"):
        V, F = read_obj(tmp_path / name)
        V_ref, F_ref = read_obj(os.path.join(EXAMPLE, name))
        assert np.array_equal(F, F_ref), name
        assert V.shape == V_ref.shape, name
        extent = np.ptp(V_ref, axis=0).max()
        assert np.abs(V - V_ref).max() <= 1e-9 * extent, name


def test_grid_places_rows_side_by_side(tmp_path):
    # five rows of two shapes, two to a line: three lines, the last half white
    out = tmp_path / "grid.png"
    render_grid(out, [[octahedron(), octahedron(2.0)]] * 5, size=(100, 120), columns=2,
                captions=["first line\nsecond line"] * 5)
    img = image(out)
    assert img.shape[:2] == (3 * 120, 2 * 2 * 100)
    assert (img[2 * 120:, 2 * 100:] == 1.0).all()  # nothing where the sixth row would be
    assert (img[2 * 120:, :2 * 100] < 1.0).any()  # the fifth row is drawn


# ------------------------------------------------------------ panel titles (issue 33, item 6)


@pytest.mark.parametrize("paths, expected", [
    (["a/girl/pose_003.obj", "a/suit/pose_003.obj", "b/male/pose_003.obj"],
     ["girl/pose_003.obj", "suit/pose_003.obj", "male/pose_003.obj"]),
    (["x/chair.obj", "y/table.obj"], ["chair.obj", "table.obj"]),
    (["p/q/s.obj", "r/q/s.obj", "t.obj"], ["p/q/s.obj", "r/q/s.obj", "t.obj"]),
    (["./x/s.obj", "s.obj"], ["x/s.obj", "s.obj"]),
    (["d/s.obj", "d/./s.obj", "e/s.obj"], ["d/s.obj", "d/s.obj", "e/s.obj"]),  # one file twice
])
def test_shortest_unique_names(paths, expected):
    from cagekit.render import shortest_unique_names

    assert shortest_unique_names(paths) == expected


def test_render_command_titles_panels_by_their_unique_paths(tmp_path, monkeypatch):
    import shutil

    from builders import invoke

    import cagekit.render

    for folder in ("girl", "suit"):
        (tmp_path / folder).mkdir()
        shutil.copy(os.path.join(EXAMPLE, "shape.obj"), tmp_path / folder / "pose_003.obj")
    seen = {}
    monkeypatch.setattr(cagekit.render, "render_meshes",
                        lambda shapes, out, **kw: seen.update(kw))
    result = invoke("render", tmp_path / "girl" / "pose_003.obj",
                    tmp_path / "suit" / "pose_003.obj", "-o", tmp_path / "x.png")
    assert result.exit_code == 0, result.output
    assert seen["titles"] == ["girl/pose_003.obj", "suit/pose_003.obj"]
