"""Tests for cagekit.io: mesh and point-cloud files (reading, writing, bad files)."""

import os
import struct

import numpy as np
import pytest
import trimesh
from builders import bits, expect_error, write
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from cagekit.errors import InputError, MeshFileError, MeshFileWarning
from cagekit.io import landmarks as clm
from cagekit.io import meshes as cio

# A tetrahedron whose vertex order is deliberately not sorted in any way.
TET_V = np.array([[0.5, 0.25, 1.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
TET_F = np.array([[1, 3, 2], [1, 2, 0], [2, 3, 0], [3, 1, 0]])


def binary_ply(V, polygons, endian="<", vtype=("double", "d"), extra=b""):
    header = (
        f"ply\nformat binary_{'little' if endian == '<' else 'big'}_endian 1.0\n"
        f"element vertex {len(V)}\n"
        + "".join(f"property {vtype[0]} {a}\n" for a in "xyz")
        + f"element face {len(polygons)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    body = np.asarray(V).astype(endian + vtype[1]).tobytes()
    for poly in polygons:
        body += struct.pack(f"{endian}B{len(poly)}i", len(poly), *poly)
    return header.encode() + body + extra


# ----------------------------------------------------------------------------- round trips


@pytest.mark.parametrize("ext", [".obj", ".ply", ".off"])
def test_mesh_round_trip_is_bit_exact(tmp_path, ext):
    rng = np.random.default_rng(1)
    V = rng.standard_normal((50, 3)) * 10.0 ** rng.integers(-30, 30, (50, 1))
    V[0] = [-0.0, 5e-324, 1.7976931348623157e308]
    F = rng.integers(0, 50, (80, 3))
    path = tmp_path / f"mesh{ext}"
    cio.save_mesh(path, V, F)
    V2, F2 = cio.load_mesh(path)
    assert np.array_equal(bits(V2), bits(V))
    assert np.array_equal(F2, F)
    assert V2.dtype == np.float64 and F2.dtype == np.int64
    assert V2.flags.c_contiguous and V2.shape == (50, 3) and F2.shape == (80, 3)


@pytest.mark.parametrize("ext", [".stl", ".glb"])
def test_float32_mesh_formats_round_trip(tmp_path, ext):
    # Values exactly representable in float32; the faces first use the vertices in order,
    # so even STL (which stores no shared vertices) gives the same indexed mesh back.
    path = tmp_path / f"tet{ext}"
    cio.save_mesh(path, TET_V, TET_F)
    V, F = cio.load_mesh(path)
    if ext == ".stl":
        order = list(dict.fromkeys(TET_F.ravel()))
        assert np.array_equal(V, TET_V[order])
        assert np.array_equal(V[F], TET_V[TET_F])
    else:
        assert np.array_equal(V, TET_V) and np.array_equal(F, TET_F)


@pytest.mark.parametrize("ext", [".ply", ".xyz", ".txt", ".pts", ".npy"])
def test_point_round_trip_is_bit_exact(tmp_path, ext):
    P = np.random.default_rng(2).standard_normal((40, 3)) * 1e-7
    P[3] = [-0.0, 0.1, 1 / 3]
    path = tmp_path / f"cloud{ext}"
    cio.save_points(path, P)
    V, F = cio.load_shape(path)
    assert np.array_equal(bits(V), bits(P))
    assert F.shape == (0, 3) and F.dtype == np.int64
    assert np.array_equal(cio.load_points(path), P)


def test_written_files_are_what_the_docs_say(tmp_path):
    cio.save_mesh(tmp_path / "a.obj", TET_V, TET_F)
    text = (tmp_path / "a.obj").read_text()
    assert "v 0.5 0.25 1\n" in text and "f 2 4 3\n" in text
    cio.save_mesh(tmp_path / "a.ply", TET_V, TET_F)
    head = (tmp_path / "a.ply").read_bytes()[:200]
    assert b"binary_little_endian" in head and b"property double x" in head
    cio.save_points(tmp_path / "a.pts", TET_V)
    assert (tmp_path / "a.pts").read_text().splitlines()[0] == "4"


@given(
    arrays(
        np.float64,
        st.tuples(st.integers(3, 20), st.just(3)),
        elements=st.floats(allow_nan=False, allow_infinity=False),
    ),
    st.sampled_from(["obj", "ply-mesh", "ply-points", "npy"]),
)
def test_round_trip_property(tmp_path_factory, V, kind):
    folder = tmp_path_factory.mktemp("prop")
    F = np.array([[0, 1, 2], [len(V) - 1, 0, 1]])
    if kind in ("obj", "ply-mesh"):
        path = folder / f"m.{kind[:3]}"
        cio.save_mesh(path, V, F)
        V2, F2 = cio.load_mesh(path)
        assert np.array_equal(F2, F)
    else:
        path = folder / f"p.{kind[:3]}"
        cio.save_points(path, V)
        V2 = cio.load_points(path)
    assert np.array_equal(bits(V2), bits(V))


# ----------------------------------------------------------------------------- vertex identity


def test_obj_keeps_vertex_order_unreferenced_and_duplicates(tmp_path):
    path = write(
        tmp_path / "cage.obj",
        "# vertices in no particular order\n"
        "v 3 3 3\nv 0 0 0\nv 9 9 9\nv 1 0 0\nv 0 0 0\nv 0 1 0\n"
        "f 2 4 6\nf 5 4 1\n",
    )
    V, F = cio.load_mesh(path)
    assert V.tolist() == [[3, 3, 3], [0, 0, 0], [9, 9, 9], [1, 0, 0], [0, 0, 0], [0, 1, 0]]
    assert F.tolist() == [[1, 3, 5], [4, 3, 0]]


def test_obj_with_materials_texture_and_normals_keeps_vertices(tmp_path):
    # trimesh 5.2 repeats every vertex once per material here; we must not.
    path = write(
        tmp_path / "shapenet.obj",
        "mtllib model.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 7 7 7\n"
        "vt 0 0\nvt 1 0\nvt 0 1\nvt 0.5 0.5\nvn 0 0 1\n"
        "g part\nusemtl red\nf 1/1/1 2/2/1 3/3/1\nusemtl blue\nf 2/2/1 4/4/1 3/4/1\n"
        "usemtl red\nf 4//1 2//1 1//1\nl 1 2\np 5\n",
    )
    with pytest.warns(MeshFileWarning, match=r"1 line element\(s\) \(the first at line 19\)"):
        V, F = cio.load_mesh(path)
    assert len(V) == 5 and V[4].tolist() == [7, 7, 7]
    assert F.tolist() == [[0, 1, 2], [1, 3, 2], [3, 1, 0]]


def test_obj_relative_indices_extra_columns_and_continuations(tmp_path):
    path = write(
        tmp_path / "rel.obj",
        "v 0 0 0 1\nv 1 0 0 0.5 0.5 0.5\nv 0 1 0\nf -3 -2 -1\nv 0 0 1\nf -4 \\\n -3 -1\n",
    )
    V, F = cio.load_mesh(path)
    assert V.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
    assert F.tolist() == [[0, 1, 2], [0, 1, 3]]


def test_obj_comments_after_statements_are_ignored(tmp_path):
    path = write(
        tmp_path / "comments.obj",
        "# a tetrahedron\nv 0 0 0 # origin\nv 1 0 0#x\nv 0 1 0\nv 0 0 1 # \\\n"
        "f 1 2 3 # bottom\nf 1 2 4#side\nf -4 -3 \\ # continued\n -1 # the end\n"
        "f 1 2 3 4 # a quad\n",
    )
    V, F = cio.load_mesh(path)
    assert V.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
    assert F.tolist() == [[0, 1, 2], [0, 1, 3], [0, 1, 3], [0, 1, 2], [0, 2, 3]]


def test_ply_and_off_keep_vertex_order(tmp_path):
    V = np.array([[5.0, 5, 5], [0, 0, 0], [0, 0, 0], [1, 0, 0], [0, 1, 0]])
    off = write(
        tmp_path / "a.off", "OFF\n# comment\n5 1 0\n" + "".join(f"{a} {b} {c}\n" for a, b, c in V)
        + "3 4 3 1\n",
    )
    ply = write(tmp_path / "a.ply", binary_ply(V, [[4, 3, 1]], endian=">", vtype=("float", "f")))
    for path in (off, ply):
        V2, F2 = cio.load_mesh(path)
        assert np.array_equal(V2, V) and F2.tolist() == [[4, 3, 1]]


# ----------------------------------------------------------------------------- polygons


SQUARE_AND_HOUSE = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 1.5 0\n"
FANS = [[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 4], [0, 4, 3], [1, 2, 4]]


def test_obj_polygons_are_fan_triangulated_in_order(tmp_path):
    path = write(tmp_path / "poly.obj", SQUARE_AND_HOUSE + "f 1 2 3 4\nf 1 2 3 5 4\nf 2 3 5\n")
    assert cio.load_mesh(path)[1].tolist() == FANS


def test_off_polygons_are_fan_triangulated_in_order(tmp_path):
    body = SQUARE_AND_HOUSE.replace("v ", "")
    path = write(tmp_path / "poly.off",
                 f"OFF 5 3 0\n{body}4 0 1 2 3\n5 0 1 2 4 3 255 0 0\n3 1 2 4\n")
    assert cio.load_mesh(path)[1].tolist() == FANS


@pytest.mark.parametrize("encoding", ["ascii", "binary"])
def test_ply_polygons_are_fan_triangulated_in_order(tmp_path, encoding):
    V = np.loadtxt(SQUARE_AND_HOUSE.replace("v ", "").splitlines())
    polygons = [[0, 1, 2, 3], [0, 1, 2, 4, 3], [1, 2, 4]]
    if encoding == "binary":
        content = binary_ply(V, polygons)
    else:
        content = (
            "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 5\n"
            "property float x\nproperty float y\nproperty float z\nproperty uchar red\n"
            "element face 3\nproperty list uchar int vertex_indices\nend_header\n"
            + "".join(f"{a} {b} {c} 200\n" for a, b, c in V)
            + "".join(f"{len(p)} {' '.join(map(str, p))}\n" for p in polygons)
        )
    path = write(tmp_path / f"poly_{encoding}.ply", content)
    V2, F = cio.load_mesh(path)
    assert np.array_equal(V2, V) and F.tolist() == FANS


# ----------------------------------------------------------------------------- scenes and STL


def test_glb_scene_with_two_meshes_is_flattened_with_transforms(tmp_path):
    a = trimesh.Trimesh(TET_V, TET_F, process=False)
    b = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 0, 1]], [[0, 2, 1]], process=False)
    scene = trimesh.Scene()
    scene.add_geometry(a, node_name="a", geom_name="A")
    scene.add_geometry(b, node_name="b", geom_name="B", transform=trimesh.transformations
                       .translation_matrix([10, 0, 0]))
    path = write(tmp_path / "scene.glb", scene.export(file_type="glb"))
    V, F = cio.load_mesh(path)
    assert V.shape == (7, 3) and F.shape == (5, 3)
    triangles = {tuple(map(tuple, t)) for t in V[F].tolist()}
    expected = {tuple(map(tuple, t)) for t in TET_V[TET_F].tolist()}
    expected.add(((10.0, 0.0, 0.0), (10.0, 0.0, 1.0), (11.0, 0.0, 0.0)))
    assert triangles == expected


def test_gltf_with_external_buffers(tmp_path):
    files = trimesh.Trimesh(TET_V, TET_F, process=False).export(file_type="gltf")
    for name, data in files.items():
        write(tmp_path / name, data)
    V, F = cio.load_mesh(tmp_path / "model.gltf")
    assert np.array_equal(V, TET_V) and np.array_equal(F, TET_F)


def test_stl_triangle_soup_is_merged_in_order_of_first_appearance(tmp_path):
    soup = trimesh.Trimesh(TET_V[TET_F].reshape(-1, 3), np.arange(12).reshape(4, 3), process=False)
    path = write(tmp_path / "soup.stl", trimesh.exchange.stl.export_stl_ascii(soup))
    V, F = cio.load_mesh(path)
    assert len(V) == 4
    assert np.array_equal(V[F], TET_V[TET_F])


# ----------------------------------------------------------------------------- point clouds


def test_text_point_clouds(tmp_path):
    xyz = write(tmp_path / "a.xyz", "# scan\n\n1 2 3\n4\t5 6 0.5 0.5 0.5\n// note\n7 8 9\n")
    csv_like = write(tmp_path / "a.txt", "1,2,3\n4, 5, 6, 255\n7,8,9\n")
    pts = write(tmp_path / "a.pts", "3\n1 2 3 -1200 255 0 0\n4 5 6 10 0 0 0\n7 8 9 0 1 1 1\n")
    for path in (xyz, csv_like, pts):
        V, F = cio.load_shape(path)
        assert V.tolist() == [[1, 2, 3], [4, 5, 6], [7, 8, 9]] and F.shape == (0, 3)


def test_npy_and_ply_point_clouds(tmp_path):
    wide = np.arange(15, dtype=np.int32).reshape(3, 5)
    np.save(tmp_path / "wide.npy", wide)
    assert cio.load_points(tmp_path / "wide.npy").tolist() == wide[:, :3].tolist()
    ply = write(
        tmp_path / "cloud.ply",
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\n"
        "property double z\nproperty double nx\nend_header\n1 2 3 0\n4 5 6 1\n",
    )
    V, F = cio.load_shape(ply)
    assert V.tolist() == [[1, 2, 3], [4, 5, 6]] and F.shape == (0, 3)


def test_point_cloud_and_faceless_files_are_not_meshes(tmp_path):
    np.save(tmp_path / "p.npy", TET_V)
    expect_error(tmp_path / "p.npy", loader=cio.load_mesh, match="point-cloud format")
    for name, text in [("v.obj", "v 0 0 0\nv 1 0 0\n"), ("v.off", "OFF\n1 0 0\n0 0 0\n")]:
        path = write(tmp_path / name, text)
        expect_error(path, loader=cio.load_mesh, match="has no faces")
        assert cio.load_shape(path)[1].shape == (0, 3)


def test_load_points_of_a_mesh_gives_its_vertices(tmp_path):
    cio.save_mesh(tmp_path / "m.off", TET_V, TET_F)
    assert np.array_equal(cio.load_points(tmp_path / "m.off"), TET_V)


# ----------------------------------------------------------------------------- bad files


OBJ_HEAD = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
PLY_HEAD = (
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
    "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
)
BAD_FILES = [
    ("empty.obj", "", "is empty"),
    ("blank.obj", "  \n\n", "is empty"),
    ("empty.ply", "", "is empty"),
    ("empty.stl", b"", "is empty"),
    ("empty.glb", b"", "is empty"),
    ("empty.npy", b"", "is empty"),
    ("empty.xyz", "", "is empty"),
    ("words.obj", "hello world\n", "no vertices"),
    ("letters.obj", "v a b c\nf 1 2 3\n", "'a' is not a number"),
    ("nan.obj", OBJ_HEAD.replace("1 0 0", "1 nan 0") + "f 1 2 3\n", "not finite"),
    ("inf.obj", OBJ_HEAD.replace("1 0 0", "1 1e999 0") + "f 1 2 3\n", "not finite"),
    ("range.obj", OBJ_HEAD + "f 1 2 7\n", "vertex index 7 is out of range"),
    ("zero.obj", OBJ_HEAD + "f 0 1 2\n", "index 0"),
    ("before.obj", OBJ_HEAD + "f -1 -2 -4\n", "before the first vertex"),
    ("twocoords.obj", "v 1 2\n", "3 coordinates"),
    ("junkindex.obj", OBJ_HEAD + "f 1 2 x\n", "not a vertex index"),
    ("garbage.ply", "this is not a ply file\n", "not a PLY file"),
    ("header.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty blob x\nend_header\n",
     "invalid PLY header"),
    ("format.ply", "ply\nformat ebcdic 1.0\nend_header\n", "unknown PLY format"),
    ("short.ply", PLY_HEAD + "0 0 0\n1 0 0\n", "truncated"),
    ("noface.ply", PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n", "truncated"),
    ("range.ply", PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "out of range"),
    ("negative.ply", PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n", "out of range"),
    ("nan.ply", PLY_HEAD + "0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n", "not finite"),
    ("noxyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
     "x, y, z"),
    ("binary.ply", binary_ply(TET_V, TET_F)[:-5], "truncated"),
    ("garbage.off", "OFF\nthree vertices\n", "vertex_count"),
    ("short.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n", "data lines"),
    ("range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "out of range"),
    ("negative.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 -1\n", "out of range"),
    ("count.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", "declares 4"),
    ("nan.off", "OFF\n3 1 0\n0 0 0\n1 0 inf\n0 1 0\n3 0 1 2\n", "not finite"),
    ("variant.off", "4OFF\n1 0 0\n0 0 0 0\n", "unsupported OFF variant"),
    ("garbage.stl", "solid nothing\nthis is not stl\n", "no vertices"),
    ("renamed.stl", "# a chair\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
     "(it looks like an OBJ file: rename it .obj)"),
    ("short.stl", b"\x00" * 80 + (2).to_bytes(4, "little") + b"\x00" * 50,
     "is not an STL file: neither ASCII"),
    ("garbage.glb", b"glTF\x02\x00\x00\x00 garbage", "cannot be read as GLB"),
    ("garbage.gltf", "{not json", "cannot be read as GLTF"),
    ("garbage.npy", "not an npy file", "cannot be read as NPY"),
    ("columns.xyz", "1 2 3\n4 5\n", "line 2: expected 3 coordinates"),
    ("letters.xyz", "1 2 3\n4 five 6\n", "line 2: coordinate 'five' is not a number"),
    ("nan.txt", "1 2 3\nnan 2 3\n", "not finite"),
    ("count.pts", "3\n1 2 3\n", "says 3 points but 1 follow"),
    ("comments.xyz", "# nothing\n// here\n", "no vertices"),
    ("mesh.foo", "v 0 0 0\n", "unknown extension"),
    ("noextension", "v 0 0 0\n", "unknown extension"),
]


SHORT_FACES = [
    ("lines.obj", OBJ_HEAD + "v 1 1 0\nf 1 2 3\nf 1 2\nl 2 3\nf 3\nf 2 4 3\nf 4 1\n",
     "dropped 3 face(s) with fewer than 3 vertices (the first at line 6) and 1 line "
     "element(s) (the first at line 7); kept 2 face(s)"),
    ("lines.off", "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n2 0 1\n"
     "3 1 3 2\n1 3\n", "dropped 2 face(s) with fewer than 3 vertices (the first at line 8)"),
    ("lines.ply", PLY_HEAD.replace("element face 1", "element face 2") + "0 0 0\n1 0 0\n"
     "0 1 0\n2 0 1\n3 0 1 2\n", "dropped 1 face(s) with fewer than 3 vertices (the first "
     "at face 0)"),
]


@pytest.mark.parametrize("name, content, match", SHORT_FACES, ids=[c[0] for c in SHORT_FACES])
def test_faces_with_fewer_than_3_vertices_are_dropped_with_one_warning(tmp_path, name, content,
                                                                       match):
    # real files carry edges and points in their face lists: the rest of the file loads
    path = write(tmp_path / name, content)
    with pytest.warns(MeshFileWarning) as caught:
        V, F = cio.load_mesh(path)
    messages = [str(w.message) for w in caught if issubclass(w.category, MeshFileWarning)]
    assert len(messages) == 1 and match in messages[0] and os.fspath(path) in messages[0]
    assert len(V) == (3 if name.endswith(".ply") else 4)  # every vertex, in order
    assert np.array_equal(V[1], [1, 0, 0])
    assert F.tolist() == ([[0, 1, 2]] if name.endswith(".ply") else [[0, 1, 2], [1, 3, 2]])


def test_a_file_whose_faces_are_all_lines_is_a_point_cloud_or_no_mesh(tmp_path):
    path = write(tmp_path / "edges.obj", OBJ_HEAD + "f 1 2\nf 2 3\n")
    with pytest.warns(MeshFileWarning, match="dropped 2"):
        V, F = cio.load_shape(path)
    assert len(V) == 3 and F.shape == (0, 3)
    with pytest.warns(MeshFileWarning), pytest.raises(MeshFileError, match="no faces"):
        cio.load_mesh(path)


def _file_warnings(load, path):
    """Call ``load(path)``; return its result and the MeshFileWarning messages it issued."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = load(path)
    return result, [str(w.message) for w in caught if issubclass(w.category, MeshFileWarning)]


def test_a_file_of_only_line_elements_warns_once_with_their_count(tmp_path):
    # a wireframe: OBJ ``l`` records (a polyline counts once), no faces
    path = write(tmp_path / "wire.obj", OBJ_HEAD + "l 1 2\n# a comment\nl 2 3 1\n")
    (V, F), messages = _file_warnings(cio.load_shape, path)
    assert messages == [f"{path}: dropped 2 line element(s) (the first at line 4); "
                        "kept 0 face(s)"]
    assert V.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]] and F.shape == (0, 3)
    with pytest.warns(MeshFileWarning, match="2 line element"), \
            pytest.raises(MeshFileError, match="no faces"):
        cio.load_mesh(path)


def test_line_elements_and_short_faces_are_counted_in_one_warning(tmp_path):
    path = write(tmp_path / "mixed.obj", OBJ_HEAD + "f 1 2 3\nl 1 2\nf 2 3\nl 3 1\n")
    (V, F), messages = _file_warnings(cio.load_mesh, path)
    assert messages == [f"{path}: dropped 1 face(s) with fewer than 3 vertices (the first at "
                        "line 6) and 2 line element(s) (the first at line 5); kept 1 face(s)"]
    assert F.tolist() == [[0, 1, 2]] and len(V) == 3


def test_a_file_without_dropped_elements_loads_without_warning(tmp_path):
    path = write(tmp_path / "tri.obj", OBJ_HEAD + "f 1 2 3\n")
    assert _file_warnings(cio.load_mesh, path)[1] == []


@pytest.mark.parametrize("name, content, match", BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_bad_files_raise_one_line_naming_the_file(tmp_path, name, content, match):
    path = write(tmp_path / name, content)
    message = expect_error(path, match=match)
    assert message.startswith(os.fspath(path))


@pytest.mark.parametrize(
    "array, match",
    [
        (np.zeros((4, 2)), "shape (4, 2)"),
        (np.zeros(4), "shape (4,)"),
        (np.array([[1, 2, np.nan]]), "not finite"),
        (np.zeros((2, 3), dtype=complex), "complex128"),
        (np.zeros((0, 3)), "no vertices"),
        (np.array([{"a": 1}], dtype=object), "cannot be read as NPY"),
    ],
)
def test_bad_npy_arrays(tmp_path, array, match):
    path = tmp_path / "bad.npy"
    np.save(path, array, allow_pickle=True)
    expect_error(path, match=match)


def test_missing_file_directory_and_mesh_only_errors(tmp_path):
    expect_error(tmp_path / "missing.obj", match="no such file")
    (tmp_path / "folder.obj").mkdir()
    expect_error(tmp_path / "folder.obj", match="is a directory")
    expect_error(write(tmp_path / "m.xyz", "1 2 3\n"), loader=cio.load_mesh, match="point-cloud")
    expect_error(write(tmp_path / "m.abc", "1 2 3\n"), loader=cio.load_mesh, match="not known")
    expect_error(tmp_path / "missing.npy", loader=cio.load_points, match="no such file")


def test_trimesh_failures_print_nothing(tmp_path, capfd):
    path = write(tmp_path / "broken.stl",
                 "solid x\nfacet normal 0 0 zz\nouter loop\nvertex 0 0 0\n")
    with pytest.raises(MeshFileError):
        cio.load_mesh(path)
    assert capfd.readouterr().err == ""


SEED_FILES = {
    "m.obj": OBJ_HEAD + "v 1 1 0\nvt 0 0\nf 1/1 2/1 3/1 4/1\nf -1 -2 -3\n",
    "m.off": "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 1\n3 0 1 2\n4 0 1 3 2\n",
    "m.ply": binary_ply(TET_V, [[0, 1, 2], [0, 1, 2, 3]]),
    "a.ply": PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
    "p.xyz": "1 2 3\n4 5 6\n",
    "p.pts": "2\n1,2,3\n4,5,6\n",
    "l.picked": "2\nPicked 1 0.2 0.3 0.5 a 1 2 3\nPicked 2 1 0 0 b 4 5 6 7\n",
    "l.json": '{"a": [1, 2, 3], "b": [4, 5, 6]}',
    "l.csv": "label,x,y,z\na,1,2,3\n\"b, c\",4,5,6\n",
}


@pytest.mark.filterwarnings("ignore::cagekit.errors.MeshFileWarning")
@given(
    st.sampled_from(sorted(SEED_FILES)),
    st.lists(st.tuples(st.floats(0, 1), st.integers(0, 12), st.binary(max_size=6)), max_size=4),
)
def test_mutated_files_load_or_raise_input_errors(tmp_path_factory, name, edits):
    data = SEED_FILES[name]
    data = bytearray(data.encode() if isinstance(data, str) else data)
    for where, cut, insert in edits:
        i = int(where * len(data))
        data[i : i + cut] = insert
    path = write(tmp_path_factory.mktemp("fuzz") / name, bytes(data))
    loader = clm.load_landmarks if name.startswith("l.") else cio.load_shape
    try:
        loader(path)
    except InputError as exc:
        assert name in str(exc) and "\n" not in str(exc)


def test_errors_are_input_errors(tmp_path):
    with pytest.raises(InputError):
        cio.load_mesh(tmp_path / "missing.ply")
    with pytest.raises(ValueError):
        clm.load_landmarks(tmp_path / "missing.json")


# ----------------------------------------------------------------------------- writing


@pytest.mark.parametrize(
    "V, F, match",
    [
        (np.zeros((3, 2)), [[0, 1, 2]], "shape (n, 3)"),
        ([[0, 0, 0], [1, 0, 0], [0, np.inf, 0]], [[0, 1, 2]], "vertex 2 is not finite"),
        ([["a", "b", "c"]], [[0, 0, 0]], "numeric"),
        (TET_V, [[0, 1, 4]], "face 0 refers to vertices [0, 1, 4]"),
        (TET_V, [[0, 1, -1]], "face 0"),
        (TET_V, np.array([[0.0, 1.0, 2.0]]), "integer (m, 3)"),
        (TET_V, np.empty((0, 3), int), "save_points"),
        (TET_V, [[0, 1, 2, 3]], "integer (m, 3)"),
    ],
)
def test_save_mesh_validates_arrays(tmp_path, V, F, match):
    path = tmp_path / "out.obj"
    with pytest.raises(InputError, match=match.replace("(", r"\(").replace(")", r"\)")
                       .replace("[", r"\[").replace("]", r"\]")):
        cio.save_mesh(path, V, F)
    assert not path.exists() and os.listdir(tmp_path) == []


def test_save_rejects_unsupported_destinations(tmp_path):
    with pytest.raises(InputError, match="cannot write meshes as '.gltf'"):
        cio.save_mesh(tmp_path / "m.gltf", TET_V, TET_F)
    with pytest.raises(InputError, match="cannot write point clouds as '.obj'"):
        cio.save_points(tmp_path / "p.obj", TET_V)
    with pytest.raises(InputError, match="does not exist"):
        cio.save_mesh(tmp_path / "no" / "such" / "m.obj", TET_V, TET_F)
    (tmp_path / "d.obj").mkdir()
    with pytest.raises(InputError, match="is a directory"):
        cio.save_mesh(tmp_path / "d.obj", TET_V, TET_F)
    with pytest.raises(InputError, match="not finite"):
        cio.save_points(tmp_path / "p.xyz", [[0, 0, np.nan]])


def test_failed_save_leaves_existing_file_untouched(tmp_path, monkeypatch):
    target = write(tmp_path / "m.obj", "precious")

    def broken(tmp, V, F):
        write(tmp, "partial")
        raise OSError("disk full")

    monkeypatch.setitem(cio._MESH_WRITERS, ".obj", broken)
    with pytest.raises(OSError, match="disk full"):
        cio.save_mesh(target, TET_V, TET_F)
    assert target.read_text() == "precious" and os.listdir(tmp_path) == ["m.obj"]


def test_supported_extension_tuples():
    assert set(cio.SUPPORTED_MESH_EXTENSIONS) == {".obj", ".ply", ".off", ".stl", ".glb", ".gltf",
                                                ".pmd"}
    assert set(cio.SUPPORTED_POINT_EXTENSIONS) == {".ply", ".xyz", ".pts", ".txt", ".npy"}
