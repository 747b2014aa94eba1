"""Tests of writing a deformed shape as a copy of its source file (cagekit.io.assets)."""

import shutil
import warnings

import numpy as np
import pytest
import trimesh
from PIL import Image
from scipy.spatial.transform import Rotation

from cagekit.errors import InputError, MeshFileWarning
from cagekit.io import (
    asset_contents,
    kept_extension,
    load_mesh,
    move_deformed,
    remove_deformed,
    save_deformed,
    save_mesh,
)

R = Rotation.from_euler("xyz", [30, -50, 70], degrees=True).as_matrix()

CUBE_V = [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)]
CUBE_QUADS = [  # outward, 1-based, with each face's outward normal (flat shading)
    ((1, 2, 4, 3), 1), ((5, 7, 8, 6), 2), ((1, 5, 6, 2), 3),
    ((3, 4, 8, 7), 4), ((1, 3, 7, 5), 5), ((2, 6, 8, 4), 6),
]
CUBE_N = [(-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1)]


@pytest.fixture
def textured_obj(tmp_path):
    """A flat-shaded cube of quads with vertex colours, UVs, two objects, two materials,
    its material file beside it and its texture in a subfolder."""
    folder = tmp_path / "source"
    (folder / "maps").mkdir(parents=True)
    Image.new("RGB", (8, 8), (200, 30, 30)).save(folder / "maps" / "wood.png")
    (folder / "cube.mtl").write_text(
        "newmtl wood\nKd 1 1 1\nmap_Kd maps/wood.png\n\n"
        "newmtl plain\nKd 0.5 0.5 0.5\nbump -bm 0.5 maps/wood.png\n")
    lines = ["# a test cube", "mtllib cube.mtl", "o box"]
    lines += [f"v {x} {y} {z} 0.25 0.5 0.75" for x, y, z in CUBE_V]
    lines += ["vt 0 0", "vt 1 0", "vt 1 1", "vt 0 1"]
    lines += [f"vn {x} {y} {z}" for x, y, z in CUBE_N]
    lines += ["usemtl wood", "g top_and_sides"]
    for k, (quad, n) in enumerate(CUBE_QUADS):
        if k == 4:
            lines += ["o lid", "usemtl plain", "s off"]
        lines.append("f " + " ".join(f"{v}/{t}/{n}" for v, t in zip(quad, (1, 2, 3, 4))))
    path = folder / "cube.obj"
    path.write_text("\n".join(lines) + "\n")
    return path


def _moved(V):
    return 2.0 * V @ R.T + [3.0, -1.0, 0.5]


def _records(path, key):
    return [line for line in path.read_text().splitlines() if line.split()[:1] == [key]]


def test_obj_keeps_uvs_materials_groups_colours_and_polygons(textured_obj, tmp_path):
    before = textured_obj.read_bytes()
    V, F = load_mesh(textured_obj)
    out = tmp_path / "results" / "moved.obj"
    out.parent.mkdir()
    save_deformed(out, _moved(V), F, textured_obj)
    assert textured_obj.read_bytes() == before  # the source is never written
    np.testing.assert_array_equal(load_mesh(out)[0], _moved(V))
    np.testing.assert_array_equal(load_mesh(out)[1], F)
    for key in ("vt", "usemtl", "g", "o", "s"):
        assert _records(out, key) == _records(textured_obj, key), key
    assert [len(f.split()) for f in _records(out, "f")] == [5] * 6  # quads stay quads
    assert all(line.split()[4:] == ["0.25", "0.5", "0.75"] for line in _records(out, "v"))
    # the material file is copied beside the output, its texture found from there
    assert _records(out, "mtllib") == ["mtllib moved.mtl"]
    copied = (out.parent / "moved.mtl").read_text()
    assert "map_Kd wood.png" in copied and "bump -bm 0.5 wood.png" in copied  # options kept
    assert (out.parent / "wood.png").read_bytes() == \
        (textured_obj.parent / "maps" / "wood.png").read_bytes()
    scene = trimesh.load(out)
    images = [g.visual.material.image for g in scene.geometry.values()
              if getattr(g.visual.material, "image", None) is not None]
    assert images and images[0].size == (8, 8)


def test_obj_normals_are_carried_and_hard_edges_stay_hard(textured_obj, tmp_path):
    V, F = load_mesh(textured_obj)
    out = tmp_path / "moved.obj"
    save_deformed(out, _moved(V), F, textured_obj)
    normals = np.array([[float(x) for x in line.split()[1:]] for line in _records(out, "vn")])
    assert len(normals) == 24  # one per (vertex, normal) pair: 6 faces x 4 corners
    for face in _records(out, "f"):
        corner_normals = normals[[int(t.split("/")[2]) - 1 for t in face.split()[1:]]]
        n = CUBE_N[CUBE_QUADS[_records(out, "f").index(face)][1] - 1]
        np.testing.assert_allclose(corner_normals, np.tile(R @ n, (4, 1)), atol=1e-12)


def test_obj_written_beside_the_source_uses_its_material_file(textured_obj):
    V, F = load_mesh(textured_obj)
    out = textured_obj.parent / "cube_moved.obj"
    save_deformed(out, _moved(V), F, textured_obj)
    assert "map_Kd maps/wood.png" in (out.parent / "cube_moved.mtl").read_text()
    assert not (out.parent / "wood.png").exists()  # reachable already: not copied


def test_a_linked_source_takes_its_material_file_from_the_file_linked_to(textured_obj,
                                                                         tmp_path):
    link = tmp_path / "links" / "chair.obj"
    link.parent.mkdir()
    link.symlink_to(textured_obj)
    V, F = load_mesh(link)
    out = tmp_path / "links" / "moved.obj"
    save_deformed(out, _moved(V), F, link)
    assert _records(out, "mtllib") == ["mtllib moved.mtl"]
    assert "map_Kd wood.png" in (out.parent / "moved.mtl").read_text()
    assert (out.parent / "wood.png").read_bytes() == \
        (textured_obj.parent / "maps" / "wood.png").read_bytes()
    # a material file whose name has a space, beside the file linked to only
    folder = tmp_path / "spaced"
    shutil.copytree(textured_obj.parent / "maps", folder / "maps")
    (folder / "my cube.mtl").write_text((textured_obj.parent / "cube.mtl").read_text())
    spaced = folder / "spaced.obj"
    spaced.write_text(textured_obj.read_text().replace("mtllib cube.mtl",
                                                       "mtllib my cube.mtl"))
    link = tmp_path / "links" / "spaced.obj"
    link.symlink_to(spaced)
    out = tmp_path / "links" / "spaced_moved.obj"
    save_deformed(out, _moved(V), F, link)
    assert _records(out, "mtllib") == ["mtllib spaced_moved.mtl"]
    assert "map_Kd wood.png" in (out.parent / "spaced_moved.mtl").read_text()


@pytest.mark.parametrize("encoding", ["binary", "ascii"])
def test_ply_keeps_colours_and_carries_normals(tmp_path, encoding):
    mesh = trimesh.creation.icosphere(subdivisions=2)
    colours = np.random.default_rng(0).integers(0, 256, (len(mesh.vertices), 4))
    mesh.visual.vertex_colors = colours
    source = tmp_path / "ball.ply"
    source.write_bytes(trimesh.exchange.ply.export_ply(mesh, encoding=encoding,
                                                       vertex_normal=True))
    assert set(asset_contents(source)) == {"normals", "vertex colours"}
    V, F = load_mesh(source)
    out = tmp_path / "moved.ply"
    save_deformed(out, _moved(V), F, source)
    back = trimesh.load(out, process=False)
    np.testing.assert_allclose(back.vertices, _moved(V), atol=1e-5)  # the file's float32
    np.testing.assert_array_equal(back.visual.vertex_colors, colours)
    rest = trimesh.load(source, process=False).vertex_normals
    np.testing.assert_allclose(back.vertex_normals, rest @ R.T, atol=1e-5)


def _textured_box(size, uv_seed):
    box = trimesh.creation.box(extents=size)
    uv = np.random.default_rng(uv_seed).random((len(box.vertices), 2))
    image = Image.new("RGB", (4, 4), (10, 200, 10))
    box.visual = trimesh.visual.TextureVisuals(uv=uv, image=image)
    return box


def test_glb_keeps_textures_scene_transforms_and_vertex_order(tmp_path):
    scene = trimesh.Scene()
    scene.add_geometry(_textured_box([1, 2, 3], 0), node_name="body", geom_name="body")
    moved = np.eye(4)
    moved[:3, :3] = R
    moved[:3, 3] = [5, 0, 0]
    scene.add_geometry(_textured_box([1, 1, 1], 1), node_name="arm", geom_name="arm",
                       parent_node_name="body", transform=moved)
    scene.add_geometry(trimesh.creation.icosphere(1), node_name="head", geom_name="head")
    source = tmp_path / "scene.glb"
    source.write_bytes(trimesh.exchange.gltf.export_glb(scene))
    V, F = load_mesh(source)
    out = tmp_path / "moved.glb"
    save_deformed(out, _moved(V), F, source)
    V2, F2 = load_mesh(out)
    np.testing.assert_allclose(V2, _moved(V), atol=1e-5 * np.abs(_moved(V)).max())
    np.testing.assert_array_equal(F2, F)
    back = trimesh.load(out)
    textured = [g for g in back.geometry.values() if isinstance(g.visual,
                                                                 trimesh.visual.TextureVisuals)]
    assert len(textured) == 2 and all(g.visual.uv is not None for g in textured)


def test_another_format_warns_what_it_drops(textured_obj, tmp_path):
    V, F = load_mesh(textured_obj)
    with pytest.warns(MeshFileWarning, match="UVs.*write OBJ to keep them"):
        save_deformed(tmp_path / "moved.off", _moved(V), F, textured_obj)
    np.testing.assert_allclose(load_mesh(tmp_path / "moved.off")[0], _moved(V))


def test_a_plain_source_is_written_plainly_without_a_warning(tmp_path):
    source = tmp_path / "plain.obj"
    save_mesh(source, np.array(CUBE_V, dtype=float), [[0, 1, 2], [1, 3, 2]])
    assert asset_contents(source) == []
    V, F = load_mesh(source)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        save_deformed(tmp_path / "moved.ply", _moved(V), F, source)
    np.testing.assert_array_equal(load_mesh(tmp_path / "moved.ply")[0], _moved(V))


def test_a_result_with_another_vertex_count_is_refused(textured_obj, tmp_path):
    V, F = load_mesh(textured_obj)
    with pytest.raises(InputError, match="keeps the source's vertices"):
        save_deformed(tmp_path / "moved.obj", V[:-1], F[:2], textured_obj)
    assert not (tmp_path / "moved.obj").exists()


def test_ply_normals_of_unused_vertices_are_kept_and_the_others_carried(tmp_path):
    source = tmp_path / "loose.ply"
    rows = ["0 0 0 0 0 1", "9 9 9 1 0 0", "1 0 0 0 0 1", "0 1 0 0 0 1", "5 5 5 0 1 0"]
    source.write_text("ply\nformat ascii 1.0\nelement vertex 5\nproperty double x\n"
                      "property double y\nproperty double z\nproperty float nx\n"
                      "property float ny\nproperty float nz\nelement face 1\n"
                      "property list uchar int vertex_indices\nend_header\n"
                      + "\n".join(rows) + "\n3 0 2 3\n")
    V, F = load_mesh(source)
    save_deformed(tmp_path / "moved.ply", _moved(V), F, source)
    back = trimesh.load(tmp_path / "moved.ply", process=False)
    np.testing.assert_allclose(back.vertex_normals[[0, 2, 3]], np.tile(R @ [0, 0, 1], (3, 1)),
                               atol=1e-6)
    np.testing.assert_allclose(back.vertex_normals[[1, 4]], [[1, 0, 0], [0, 1, 0]], atol=1e-6)


def test_several_material_files_beside_the_source_never_replace_its_own(textured_obj):
    folder = textured_obj.parent
    (folder / "extra.mtl").write_text("newmtl extra\nKd 0 1 0\n")
    text = textured_obj.read_text().replace("mtllib cube.mtl", "mtllib moved.mtl extra.mtl")
    (folder / "moved.mtl").write_text("newmtl mine\nKd 1 0 0\n")  # the source's own
    source = folder / "two.obj"
    source.write_text(text)
    before = {p.name: p.read_bytes() for p in folder.glob("*.mtl")}
    V, F = load_mesh(source)
    save_deformed(folder / "moved.obj", _moved(V), F, source)
    assert {p.name: p.read_bytes() for p in folder.glob("*.mtl") if p.name in before} == before
    assert _records(folder / "moved.obj", "mtllib") == ["mtllib moved.mtl moved_2.mtl"]
    assert "newmtl extra" in (folder / "moved_2.mtl").read_text()


def test_a_texture_named_like_another_gets_its_content_hash(textured_obj, tmp_path):
    out = tmp_path / "results"
    out.mkdir()
    Image.new("RGB", (8, 8), (0, 0, 255)).save(out / "wood.png")  # another wood.png there
    V, F = load_mesh(textured_obj)
    save_deformed(out / "moved.obj", _moved(V), F, textured_obj)
    maps = [line.split()[-1] for line in (out / "moved.mtl").read_text().splitlines()
            if line.startswith("map_Kd")]
    assert len(maps) == 1 and maps[0].startswith("wood-") and maps[0].endswith(".png")
    assert (out / maps[0]).read_bytes() == (textured_obj.parent / "maps/wood.png").read_bytes()
    save_deformed(out / "again.obj", _moved(V), F, textured_obj)  # reused, not copied again
    assert sorted(p.name for p in out.glob("wood*.png")) == sorted(["wood.png", maps[0]])


def test_a_result_moved_or_removed_takes_its_material_file_along(textured_obj, tmp_path):
    first, second = tmp_path / "variations", tmp_path / "rejected"
    first.mkdir()
    second.mkdir()
    V, F = load_mesh(textured_obj)
    save_deformed(first / "a__b.obj", _moved(V), F, textured_obj)
    move_deformed(first / "a__b.obj", second / "a__b.obj")
    assert not (first / "a__b.mtl").exists() and (first / "wood.png").exists()
    scene = trimesh.load(second / "a__b.obj")
    assert any(getattr(g.visual.material, "image", None) is not None
               for g in scene.geometry.values())
    remove_deformed(second / "a__b.obj")
    assert sorted(p.name for p in second.iterdir()) == ["wood.png"]


def test_obj_normals_listed_after_the_faces_and_latin1_names_round_trip(tmp_path):
    folder = tmp_path / "src"
    folder.mkdir()
    (folder / "bo\xeete.mtl".encode("latin-1").decode("utf-8", "surrogateescape")).write_bytes(
        b"newmtl m\nKd 1 1 1\n")
    body = (b"mtllib bo\xeete.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\n"
            b"f 1//1 2//1 3//1\nvn 0 0 1\n")
    source = folder / "tri.obj"
    source.write_bytes(body)
    V, F = load_mesh(source)
    out = tmp_path / "moved.obj"
    save_deformed(out, _moved(V), F, source)
    written = out.read_bytes()
    assert b"f 1//1 2//2 3//3" in written  # one normal per (vertex, normal) pair
    normals = [[float(x) for x in line.split()[1:]]
               for line in written.decode().splitlines() if line.startswith("vn ")]
    np.testing.assert_allclose(normals, np.tile(R @ [0, 0, 1], (3, 1)), atol=1e-12)
    assert (tmp_path / "moved.mtl").read_bytes() == b"newmtl m\nKd 1 1 1\n"


def test_glb_instances_under_a_moved_parent_each_get_their_own_copy(tmp_path):
    scene = trimesh.Scene()
    parent = np.eye(4)
    parent[:3, 3] = [0, 5, 0]
    scene.graph.update("parent", frame_from=scene.graph.base_frame, matrix=parent)
    box = trimesh.creation.box(extents=[1, 1, 1])
    for node, x in (("a", -2.0), ("b", 2.0)):
        placed = np.eye(4)
        placed[0, 3] = x
        scene.add_geometry(box, geom_name="box", node_name=node, parent_node_name="parent",
                           transform=placed)
    source = tmp_path / "instanced.glb"
    source.write_bytes(trimesh.exchange.gltf.export_glb(scene))
    V, F = load_mesh(source)
    assert len(V) == 16
    moved = V.copy()
    moved[:8] *= 1.5  # the two instances move differently
    save_deformed(tmp_path / "moved.glb", moved, F, source)
    np.testing.assert_allclose(load_mesh(tmp_path / "moved.glb")[0], moved, atol=1e-5)


def test_kept_extension_follows_the_formats_that_keep_an_asset():
    assert [kept_extension(n) for n in ("a.obj", "a.PLY", "a.gltf", "a.glb", "a.off")] == \
        [".obj", ".ply", ".glb", ".glb", ".obj"]


def test_a_material_file_of_another_model_beside_the_output_is_never_replaced(textured_obj,
                                                                                tmp_path):
    """An output named like another model's material file (a target's ``armchair.mtl``)
    gets ``<stem>_2.mtl``; writing the same output again replaces only its own."""
    V, F = load_mesh(textured_obj)
    out_folder = tmp_path / "out"
    out_folder.mkdir()
    theirs = out_folder / "armchair.mtl"
    theirs.write_text("newmtl fabric\nKd 0 0 1\n")
    (out_folder / "target.obj").write_text("mtllib armchair.mtl\nv 0 0 0\nv 1 0 0\n"
                                           "v 0 1 0\nusemtl fabric\nf 1 2 3\n")
    out = out_folder / "armchair.obj"
    for _ in range(2):
        save_deformed(out, _moved(V), F, textured_obj)
        assert theirs.read_text() == "newmtl fabric\nKd 0 0 1\n"
        assert _records(out, "mtllib") == ["mtllib armchair_2.mtl"]
        assert "newmtl wood" in (out_folder / "armchair_2.mtl").read_text()
    assert sorted(p.name for p in out_folder.glob("*.mtl")) == ["armchair.mtl",
                                                                "armchair_2.mtl"]


def test_what_a_source_file_lacks_is_not_warned_again_when_its_copy_is_written(tmp_path):
    source = tmp_path / "s.obj"
    source.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\n"  # UVs: copied
                      "f 1/1 2/1 3/1\nf 1/1 2/1\nf 1/1 3/1 4/1\n")
    with pytest.warns(MeshFileWarning, match="dropped 1 face"):
        V, F = load_mesh(source)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the dropped face was said when V was read
        save_deformed(tmp_path / "out.obj", _moved(V), F, source)
    written = [[float(x) for x in line.split()[1:4]]
               for line in (tmp_path / "out.obj").read_text().splitlines()
               if line.startswith("v ")]
    np.testing.assert_allclose(written, _moved(V))


def test_an_obj_result_replaces_an_empty_file_and_a_result_missing_its_material_file(
        textured_obj, tmp_path):
    V, F = load_mesh(textured_obj)
    out = tmp_path / "r.obj"
    out.write_text("")  # an empty file where the result goes
    save_deformed(out, _moved(V), F, textured_obj)
    assert _records(out, "mtllib") == ["mtllib r.mtl"]
    # a run stopped after the OBJ, before its material file: the next writes the same name
    (tmp_path / "r.mtl").unlink()
    save_deformed(out, _moved(V), F, textured_obj)
    assert _records(out, "mtllib") == ["mtllib r.mtl"] and (tmp_path / "r.mtl").is_file()
    assert sorted(p.name for p in tmp_path.glob("*.mtl")) == ["r.mtl"]
