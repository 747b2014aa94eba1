"""0 A.D.'s PMD reader: every version's layout, the records it keeps, and bad files."""

import struct

import numpy as np
import pytest
from builders import expect_error, write
from hypothesis import given, settings
from hypothesis import strategies as st

from cagekit.errors import MeshFileError, MeshFileWarning
from cagekit.io import load_mesh, read_pmd, save_deformed
from cagekit.io import meshes as cio

POSITIONS = np.array([[0.5, 0.25, 1.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
                     dtype=np.float32)
FACES = [(1, 3, 2), (1, 2, 0), (2, 3, 0), (3, 1, 0)]


def pmd_bytes(version=4, V=POSITIONS, faces=FACES, uv_sets=1, bones=None, rest=(),
              props=(), tail=b""):
    """A PMD file as the format's documentation lays it out."""
    n = len(V)
    body = struct.pack("<I", n) + (struct.pack("<I", uv_sets) if version >= 4 else b"")
    sets = uv_sets if version >= 4 else 1
    for i, p in enumerate(V):
        normal = (0.0, 0.0, 1.0)
        uv = [0.1 * i + 0.01 * k for k in range(2 * sets)]
        b = bones[i] if bones is not None else (255, 255, 255, 255)
        w = (1.0, 0.0, 0.0, 0.0) if bones is not None else (0.0,) * 4
        body += struct.pack(f"<6f{2 * sets}f4B4f", *p, *normal, *uv, *b, *w)
    body += struct.pack("<I", len(faces)) + b"".join(struct.pack("<3H", *f) for f in faces)
    body += struct.pack("<I", len(rest)) + b"".join(struct.pack("<7f", *r) for r in rest)
    if version >= 2:
        body += struct.pack("<I", len(props))
        for name, t, q, bone in props:
            body += struct.pack("<I", len(name)) + name + struct.pack("<7fB", *t, *q, bone)
    body += tail
    return b"PSMD" + struct.pack("<II", version, len(body)) + body


@pytest.mark.parametrize("version", [1, 3, 4])
def test_every_version_reads_the_same_vertices_and_faces(tmp_path, version):
    path = write(tmp_path / "m.pmd", pmd_bytes(version))
    model = read_pmd(path)
    assert model.version == version
    np.testing.assert_array_equal(model.vertices, POSITIONS.astype(np.float64))
    assert model.vertices.dtype == np.float64 and model.faces.dtype == np.int64
    assert model.faces.tolist() == [list(f) for f in FACES]
    V, F = load_mesh(path)  # load_mesh goes through the same reader
    np.testing.assert_array_equal(V, model.vertices)
    np.testing.assert_array_equal(F, model.faces)


def test_uv_sets_bones_rest_states_and_prop_points_are_kept(tmp_path):
    rest = [(1, 2, 3, 0, 0, 0, 1), (4, 5, 6, 0, 0, 1, 0)]
    props = [(b"prop_head", (0.5, 0.0, 2.0), (0, 0, 0, 1), 1),
             (b"root", (0, 0, 0), (0, 0, 0, 1), 255)]
    bones = [(0, 255, 255, 255), (1, 255, 255, 255), (0, 255, 255, 255), (1, 255, 255, 255)]
    model = read_pmd(write(tmp_path / "s.pmd", pmd_bytes(4, uv_sets=2, bones=bones,
                                                       rest=rest, props=props)))
    assert model.uv.shape == (4, 2, 2)
    np.testing.assert_allclose(model.uv[2], [[0.2, 0.21], [0.22, 0.23]], rtol=1e-6)
    assert model.bones[:, 0].tolist() == [0, 1, 0, 1] and (model.bones[:, 1:] == 255).all()
    np.testing.assert_array_equal(model.weights[:, 0], 1.0)
    np.testing.assert_array_equal(model.rest_translation, [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(model.rest_rotation, [[0, 0, 0, 1], [0, 0, 1, 0]])
    assert [p.name for p in model.prop_points] == ["prop_head", "root"]
    assert model.prop_points[0].bone == 1 and model.prop_points[1].bone == 255
    np.testing.assert_array_equal(model.prop_points[0].translation, [0.5, 0.0, 2.0])


@pytest.mark.parametrize("data, match", [
    (b"PSMX" + bytes(20), "not a PMD file"),
    (b"PSMD" + struct.pack("<II", 7, 0), "version 7"),
    (pmd_bytes()[:-5], "says"),
    (pmd_bytes(tail=b"\0\0"), "after its last PMD record"),
    (pmd_bytes(faces=[(0, 1, 4)]), "refers to vertices"),
    (pmd_bytes(V=np.array([[0, 0, np.nan], [1, 0, 0], [0, 1, 0]], np.float32),
               faces=[(0, 1, 2)]), "not finite"),
    (pmd_bytes(2, bones=[(0, 255, 255, 255)] * 4, rest=[(0,) * 7]), "version 2"),
    (pmd_bytes()[:16] + struct.pack("<I", 2**32 - 1) + pmd_bytes()[20:], "UV set"),
    (pmd_bytes(bones=[(2, 255, 255, 255)] * 4, rest=[(0,) * 7]), "names bones"),
    (pmd_bytes(rest=[(np.inf, 0, 0, 0, 0, 0, 1)]), "rest state of bone 0"),
    (pmd_bytes(props=[(b"p", (0, np.nan, 0), (0, 0, 0, 1), 255)]), "prop point 0"),
])
def test_bad_files_are_one_line_errors_naming_them(tmp_path, data, match):
    expect_error(write(tmp_path / "bad.pmd", data), loader=read_pmd, match=match)


def test_bad_skin_normals_and_uvs_are_refused_naming_the_vertex(tmp_path):
    good = pmd_bytes(uv_sets=2)
    offset = 12 + 8  # header, vertex and UV-set counts: vertex 0's record starts here
    cases = {offset + 12: ("normal of vertex 0", np.float32(np.nan)),
             offset + 24 + 8: ("texture coordinates of vertex 0", np.float32(np.inf)),
             offset + 24 + 16 + 4: ("bone weight of vertex 0", np.float32(np.nan)),
             offset + 24 + 16 + 8: ("negative bone weight", np.float32(-5.0))}
    for i, (at, (match, value)) in enumerate(cases.items()):
        data = good[:at] + value.tobytes() + good[at + 4:]
        expect_error(write(tmp_path / f"b{i}.pmd", data), loader=read_pmd, match=match)


def test_the_bind_shape_bone_index_is_accepted(tmp_path):
    """The format reserves the index equal to the bone count (two of the game's files)."""
    model = read_pmd(write(tmp_path / "b.pmd", pmd_bytes(bones=[(1, 255, 255, 255)] * 4,
                                                       rest=[(0, 0, 0, 0, 0, 0, 1)])))
    assert (model.bones[:, 0] == 1).all()


def test_a_truncated_body_whose_header_agrees_is_reported_as_truncated(tmp_path):
    data = pmd_bytes()
    cut = data[:40]
    cut = cut[:8] + struct.pack("<I", len(cut) - 12) + cut[12:]
    expect_error(write(tmp_path / "cut.pmd", cut), loader=read_pmd, match="truncated")


@settings(max_examples=60, deadline=None)
@given(st.binary(max_size=200))
def test_random_bytes_after_the_magic_never_crash(tmp_path_factory, junk):
    path = write(tmp_path_factory.mktemp("pmd") / "junk.pmd", b"PSMD" + junk)
    try:
        model = read_pmd(path)
    except MeshFileError as exc:
        assert "\n" not in str(exc)
    else:  # the rare bytes that make a valid file make a consistent one
        assert model.faces.size == 0 or model.faces.max() < len(model.vertices)


def test_pmd_is_read_but_never_written(tmp_path):
    assert ".pmd" in cio.SUPPORTED_MESH_EXTENSIONS
    assert set(cio.WRITTEN_MESH_EXTENSIONS) == set(cio._MESH_WRITERS)
    source = write(tmp_path / "m.pmd", pmd_bytes())
    V, F = load_mesh(source)
    with pytest.warns(MeshFileWarning, match="UVs, normals and bones .* cagekit writes no PMD"):
        save_deformed(tmp_path / "out.obj", V * 2, F, source)
    np.testing.assert_array_equal(load_mesh(tmp_path / "out.obj")[0], V * 2)
