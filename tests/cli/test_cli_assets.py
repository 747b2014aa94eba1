"""The command line keeps a source's asset (UVs, materials, groups, normals) in its results:
``deform``, ``apply`` and ``amplify`` write a deformed copy of the source file."""

import numpy as np
import pytest
import trimesh
from builders import bumpy_blob, cagekit
from PIL import Image

from cagekit.io import load_mesh, save_mesh


def _textured_obj(path, V, F):
    """``V, F`` as an OBJ with spherical UVs, smooth normals, a group and a textured
    material in ``<stem>.mtl`` beside it (texture ``<stem>.png``)."""
    stem = path.stem
    Image.new("RGB", (4, 4), (0, 90, 200)).save(path.parent / f"{stem}.png")
    (path.parent / f"{stem}.mtl").write_text(f"newmtl skin\nKd 1 1 1\nmap_Kd {stem}.png\n")
    unit = V / np.linalg.norm(V, axis=1, keepdims=True)
    uv = np.column_stack([0.5 + np.arctan2(unit[:, 1], unit[:, 0]) / (2 * np.pi),
                          0.5 + np.arcsin(np.clip(unit[:, 2], -1, 1)) / np.pi])
    normals = trimesh.Trimesh(V, F, process=False).vertex_normals
    lines = [f"mtllib {stem}.mtl", "o blob", "g body", "usemtl skin"]
    lines += [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in V]
    lines += [f"vt {u:.17g} {v:.17g}" for u, v in uv]
    lines += [f"vn {x:.17g} {y:.17g} {z:.17g}" for x, y, z in normals]
    lines += ["f " + " ".join(f"{i + 1}/{i + 1}/{i + 1}" for i in face) for face in F]
    path.write_text("\n".join(lines) + "\n")


@pytest.fixture(scope="module")
def textured(tmp_path_factory):
    folder = tmp_path_factory.mktemp("textured")
    V, F = bumpy_blob(subdivisions=2)
    source, target = folder / "blob.obj", folder / "wide.obj"
    _textured_obj(source, V, F)
    save_mesh(target, V * [1.6, 0.8, 1.0] + 5.0, F)
    return source, target


def _assert_keeps_the_asset(out, source):
    """``out`` has the source's UVs, group, material (found from its folder), normals."""
    def records(path, key):
        return [ln for ln in path.read_text().splitlines() if ln.split()[:1] == [key]]

    for key in ("vt", "o", "g", "usemtl"):
        assert records(out, key) == records(source, key), key
    assert len(records(out, "vn")) == len(records(source, "vn"))
    mesh = trimesh.load(out, force="mesh")
    assert isinstance(mesh.visual, trimesh.visual.TextureVisuals)
    assert mesh.visual.material.image is not None and mesh.visual.material.image.size == (4, 4)


def test_deform_keeps_uvs_materials_groups_and_normals(textured, tmp_path):
    source, target = textured
    out = tmp_path / "result" / "blob_wide.obj"
    out.parent.mkdir()
    result = cagekit("deform", source, target, "-o", out, "--method", "scale")
    assert result.returncode == 0, result.stderr
    _assert_keeps_the_asset(out, source)
    V, F = load_mesh(out)
    assert V.shape == load_mesh(source)[0].shape and np.ptp(V[:, 0]) > 1.5 * np.ptp(V[:, 1])


def test_apply_keeps_the_asset_and_a_point_format_says_what_it_drops(textured, tmp_path):
    source, _ = textured
    cage_v = np.array([[x, y, z] for x in (-2, 2) for y in (-2, 2) for z in (-2, 2)], float)
    box = trimesh.creation.box(extents=[4, 4, 4])
    order = [int(np.argmin(np.linalg.norm(cage_v - v, axis=1))) for v in box.vertices]
    cage_f = np.array(order)[box.faces]
    cage, moved = tmp_path / "cage.obj", tmp_path / "cage_moved.obj"
    save_mesh(cage, cage_v, cage_f)
    save_mesh(moved, cage_v * [2.0, 1.0, 1.0], cage_f)
    out = tmp_path / "applied.obj"
    result = cagekit("apply", source, cage, moved, "-o", out)
    assert result.returncode == 0, result.stderr
    _assert_keeps_the_asset(out, source)
    np.testing.assert_allclose(load_mesh(out)[0], load_mesh(source)[0] * [2.0, 1.0, 1.0],
                               atol=1e-9)
    plain = cagekit("apply", source, cage, moved, "-o", tmp_path / "applied.off")
    assert plain.returncode == 0 and "UVs" in plain.stderr and "write OBJ" in plain.stderr


def test_amplify_variations_keep_the_asset(textured, tmp_path):
    source, _ = textured
    folder = tmp_path / "collection"
    folder.mkdir()
    V, F = bumpy_blob(subdivisions=2)
    _textured_obj(folder / "a.obj", V, F)
    _textured_obj(folder / "b.obj", V * [1.5, 0.7, 1.0], F)
    out = tmp_path / "out"
    result = cagekit("amplify", folder, "-o", out, "--pairs", "all", "--method", "scale",
                     "--workers", "1")
    assert result.returncode == 0, result.stderr
    written = sorted((out / "variations").glob("*.obj"))
    assert len(written) == 2
    for path in written:  # named <source>__<target>.obj
        _assert_keeps_the_asset(path, folder / f"{path.stem.split('__')[0]}.obj")


def test_amplify_writes_a_ply_collection_as_ply_keeping_its_colours(tmp_path):
    folder = tmp_path / "collection"
    folder.mkdir()
    V, F = bumpy_blob(subdivisions=2)
    colours = np.random.default_rng(1).integers(0, 256, (len(V), 4), dtype=np.uint8)
    for name, stretch in (("a", [1.0, 1.0, 1.0]), ("b", [1.5, 0.7, 1.0])):
        mesh = trimesh.Trimesh(V * stretch, F, vertex_colors=colours, process=False)
        (folder / f"{name}.ply").write_bytes(trimesh.exchange.ply.export_ply(mesh))
    out = tmp_path / "out"
    result = cagekit("amplify", folder, "-o", out, "--pairs", "all", "--method", "scale",
                     "--workers", "1")
    assert result.returncode == 0, result.stderr
    assert "not kept" not in result.stderr
    written = sorted((out / "variations").iterdir())
    assert [p.name for p in written] == ["a__b.ply", "b__a.ply"]
    for path in written:
        back = trimesh.load(path, process=False)
        np.testing.assert_array_equal(back.visual.vertex_colors, colours)
