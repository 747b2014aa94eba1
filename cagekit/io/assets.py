"""Writing a deformed shape as a copy of its source file: the asset is kept, only the
vertices move.

A deformation moves vertices and nothing else, so a result keeps everything else its
source file carries: UVs, materials, groups and objects, vertex colours, polygons (quads
stay quads), comments; its normals are carried through the deformation
(:func:`cagekit.geometry.normal_transport.transported_normals`: hard edges stay hard).
:func:`save_deformed` does this when the output has the source's format:

- **OBJ**: the source's text with each ``v`` record's first three numbers replaced
  (colour columns kept), its ``vn`` records replaced by one carried normal per
  ``(vertex, normal)`` pair the faces use (faces rewritten to index them); each material
  file is copied beside the output as ``<output stem>.mtl`` with its texture paths made
  relative to the output's folder, so every reader finds them whether it resolves them
  from the OBJ's folder or the MTL's; a texture outside the output's folder is copied beside
  it once (reused by later outputs in that folder), as readers such as trimesh refuse paths that
  leave the model's folder. The output's folder is then self-contained.
- **PLY**: the source's bytes with the vertex element's ``x, y, z`` (and ``nx, ny, nz``)
  replaced, in the file's own types and encoding; colours, UVs and other properties and
  elements kept.
- **GLB/GLTF** (written as GLB): the source scene with each mesh's vertices replaced in its
  own frame and its normals carried, materials and textures embedded (trimesh).

Any other output format, or a source with nothing to keep (OFF, STL, plain OBJ or PLY), is
written by :func:`cagekit.io.save_mesh`; when that drops something the source carries, one
:class:`~cagekit.errors.MeshFileWarning` says what and which format keeps it.
"""

from __future__ import annotations

import filecmp
import hashlib
import json
import os
import shutil
import warnings

import numpy as np
from numpy.typing import ArrayLike

from cagekit.errors import InputError, MeshFileError, MeshFileWarning
from cagekit.io.files import atomic_output, extension, read_bytes
from cagekit.io.meshes import (
    load_mesh,
    ply_ascii_element,
    ply_binary_element,
    ply_header,
    save_mesh,
    valid_faces,
    valid_vertices,
)

__all__ = ["asset_contents", "kept_extension", "move_deformed", "remove_deformed",
           "save_deformed"]

_KEEPS = {".obj": (".obj",), ".ply": (".ply",), ".glb": (".glb",), ".gltf": (".glb",)}
"""Source extension -> output extensions that keep its asset."""


def save_deformed(path: str | os.PathLike, V: ArrayLike, F: ArrayLike,
                  source: str | os.PathLike) -> None:
    """Write ``V`` as the source file's vertices, keeping the rest of the source's asset.

    Parameters
    ----------
    path : str or os.PathLike
        The output; any extension :func:`cagekit.io.save_mesh` writes. The asset is kept
        for OBJ from OBJ, PLY from PLY, and GLB from GLB or GLTF.
    V : (n, 3) array_like of float
        The deformed vertices, in the order :func:`cagekit.io.load_mesh` reads ``source``.
    F : (m, 3) array_like of int
        The triangles :func:`cagekit.io.load_mesh` reads from ``source`` (written as they
        are when the asset cannot be kept).
    source : str or os.PathLike
        The mesh file that was deformed (never written to).

    Raises
    ------
    InputError
        ``V`` does not have one row per vertex of ``source``, or the output cannot be
        written.

    Examples
    --------
    >>> V, F = load_mesh("chair.obj")  # doctest: +SKIP
    >>> save_deformed("tall_chair.obj", V * [1, 1.5, 1], F, "chair.obj")  # doctest: +SKIP
    """
    V = valid_vertices(V, path)
    F = valid_faces(F, len(V), path)
    out_ext, src_ext = extension(path), extension(source)
    carried = asset_contents(source)
    if out_ext not in _KEEPS.get(src_ext, ()) or not carried:
        if carried:
            keeps = "/".join(e[1:].upper() for e in _KEEPS.get(src_ext, ()))
            advice = (f"write {keeps} to keep them" if keeps
                      else f"cagekit writes no {src_ext[1:].upper()}")
            warnings.warn(MeshFileWarning(
                f"{os.fspath(path)}: {', '.join(carried)} of {os.fspath(source)} are not kept "
                f"in {out_ext[1:].upper() or 'this format'}; {advice}"),
                stacklevel=2)
        save_mesh(path, V, F)
        return
    with warnings.catch_warnings():  # what the source's file lacks was said when V was read
        warnings.simplefilter("ignore", MeshFileWarning)
        V0, F0 = load_mesh(source)
    if V0.shape != V.shape:
        raise InputError(f"has {len(V)} vertices to write but {os.fspath(source)} has "
                         f"{len(V0)}; a deformed copy keeps the source's vertices", path)
    _WRITERS[src_ext](path, V, V0, F0, source)


def move_deformed(path: str | os.PathLike, dest: str | os.PathLike) -> None:
    """Move a result :func:`save_deformed` wrote, with the material files it wrote beside it.

    Each ``.mtl`` beside an OBJ result is copied next to ``dest`` with its texture paths
    valid from there (a texture is copied into ``dest``'s folder when it would be out of
    reach, as :func:`save_deformed` does), the result is moved over, then the old
    ``.mtl`` files are removed. Textures stay where they are: other results may use them.

    Parameters
    ----------
    path : str or os.PathLike
        The result (any format; only OBJ has material files).
    dest : str or os.PathLike
        Where it goes, in an existing folder; its ``mtllib`` names are kept, so ``dest``
        keeps ``path``'s file name stem.

    Examples
    --------
    >>> move_deformed("out/variations/a__b.obj", "out/rejected/a__b.obj")  # doctest: +SKIP
    """
    materials = _own_material_files(path)
    folder = os.path.dirname(os.path.abspath(os.fspath(dest)))
    for mtl in materials:
        _copy_mtl(mtl, os.path.join(folder, os.path.basename(mtl)))
    os.replace(path, dest)
    for mtl in materials:
        os.remove(mtl)


def remove_deformed(path: str | os.PathLike) -> None:
    """Remove a result :func:`save_deformed` wrote and the material files it wrote beside
    it (textures stay: other results may use them).

    Parameters
    ----------
    path : str or os.PathLike
        The result.

    Examples
    --------
    >>> remove_deformed("out/rejected/a__b.obj")  # doctest: +SKIP
    """
    materials = _own_material_files(path)
    os.remove(path)
    for mtl in materials:
        os.remove(mtl)


def _previous_material_files(path):
    """:func:`_own_material_files` of a file about to be replaced; none when there is no
    file there or it cannot be read as an OBJ (empty, binary, unreadable)."""
    try:
        return _own_material_files(path) if os.path.isfile(path) else []
    except (InputError, OSError, UnicodeError):
        return []


def _own_material_files(path):
    """The material files an OBJ names that lie beside it (plain names, no folder)."""
    if extension(path) != ".obj":
        return []
    folder, found = os.path.dirname(os.path.abspath(os.fspath(path))), []
    for line in _text(path).splitlines():
        if line.split()[:1] == ["mtllib"]:
            found += [os.path.join(folder, name) for name in _mtllib_names(line, folder)
                      if "/" not in name and os.path.isfile(os.path.join(folder, name))]
    return found


def kept_extension(source: str | os.PathLike) -> str:
    """The output extension that keeps ``source``'s asset: its own for OBJ and PLY, ``.glb``
    for GLB and GLTF, ``.obj`` for the rest (OFF, STL: nothing to keep).

    Parameters
    ----------
    source : str or os.PathLike
        A mesh file's name (not read).

    Returns
    -------
    str
        ``".obj"``, ``".ply"`` or ``".glb"``.

    Examples
    --------
    >>> kept_extension("robot.gltf"), kept_extension("chair.OBJ"), kept_extension("a.stl")
    ('.glb', '.obj', '.obj')
    """
    return _KEEPS.get(extension(source), (".obj",))[0]


def asset_contents(source: str | os.PathLike) -> list[str]:
    """What a mesh file carries besides vertices and faces, as words for a message.

    Parameters
    ----------
    source : str or os.PathLike
        A mesh file.

    Returns
    -------
    list of str
        For example ``["UVs", "normals", "materials"]``; empty for a file with only
        vertices and faces (or a format that carries nothing else: OFF, STL). A PMD
        file's UVs, normals and bones are named; no output keeps them.

    Examples
    --------
    >>> asset_contents("data/example/cage.obj")  # doctest: +SKIP
    []
    """
    ext = extension(source)
    if ext == ".obj":
        return _obj_contents(source)
    if ext == ".ply":
        return _ply_contents(source)
    if ext in (".glb", ".gltf"):
        return ["UVs, materials, normals and the scene"]
    if ext == ".pmd":
        return ["UVs, normals and bones"]
    return []


# ------------------------------------------------------------------------------------- OBJ


_OBJ_WORDS = {"vt": "UVs", "vn": "normals", "mtllib": "materials", "usemtl": "materials",
              "g": "groups", "o": "objects"}


def _obj_contents(source):
    found = []
    for line in _text(source).splitlines():
        parts = line.split(None, 1)
        word = _OBJ_WORDS.get(parts[0]) if parts else None
        if parts and parts[0] == "v" and len(line.split("#", 1)[0].split()) >= 7:
            word = "vertex colours"
        if word and word not in found:
            found.append(word)
    return found


def _text(path):
    """A text file's characters, every byte kept: bytes that are not UTF-8 (a Latin-1
    texture name) come back unchanged when written with ``errors="surrogateescape"``."""
    return read_bytes(path, MeshFileError).decode("utf-8", errors="surrogateescape")


def _obj_lines(source):
    """The source's logical lines (continuations joined), comments kept in place."""
    lines, pending = [], ""
    for line in _text(source).splitlines():
        body = line.split("#", 1)[0].rstrip()
        if body.endswith("\\"):
            pending += body[:-1] + " "
            continue
        lines.append(pending + line if pending else line)
        pending = ""
    if pending:
        lines.append(pending)
    return lines


def _write_obj(path, V, V0, F0, source):
    lines = _obj_lines(source)
    corners, normals = _obj_corners(lines, source)
    pairs, new_normals = _obj_carried_normals(V0, V, corners, normals)
    src_folder = _material_folder(source, lines)
    text, vertex, normals_written, face, materials, copies = [], 0, False, 0, [], []
    previous = set(_previous_material_files(path))  # read once, before it is replaced
    for line in lines:
        parts = line.split("#", 1)[0].split()
        key = parts[0] if parts else ""
        if key in ("vn", "f") and not normals_written:
            # every carried normal where the first normal, or else the first face, stood
            text += [f"vn {x:.17g} {y:.17g} {z:.17g}" for x, y, z in new_normals]
            normals_written = True
        if key == "v":
            text.append(" ".join(["v", *(f"{x:.17g}" for x in V[vertex]), *parts[4:]]))
            vertex += 1
        elif key == "f":
            text.append(_obj_face(parts, pairs[face]))
            face += 1
        elif key == "vn":
            pass  # replaced by the carried normals above
        elif key == "mtllib":
            text.append(_mtllib(line, src_folder, path, materials, copies, previous))
        else:
            text.append(line)
    with atomic_output(path) as tmp, open(tmp, "w", encoding="utf-8",
                                                   errors="surrogateescape") as handle:
        handle.write("\n".join(text) + "\n")
    for mtl, copy in copies:
        _copy_mtl(mtl, copy)


def _material_folder(source, lines):
    """Where the source's material files are looked for: beside the path given, or, for a
    symbolic link whose material files are not there, beside the file it finally points to
    (where the model's own files are; the links between are not searched)."""
    given = os.path.dirname(os.path.abspath(os.fspath(source)))
    real = os.path.dirname(os.path.realpath(os.fspath(source)))
    if real == given:
        return given
    mtllibs = [line for line in lines if line.split()[:1] == ["mtllib"]]

    def found(folder):  # names split as that folder's files read them (names with spaces)
        return sum(os.path.isfile(_beside(name, folder))
                   for line in mtllibs for name in _mtllib_names(line, folder))

    return real if found(real) > found(given) else given


def _mtllib(line, src_folder, out_path, written, copies, previous):
    """An ``mtllib`` line for the output: each material file that exists is copied beside
    the output (``<output stem>.mtl``, then ``<stem>_2.mtl``...) with its texture paths
    made relative to the output's folder, so readers that resolve textures from the OBJ's
    folder (trimesh) and those that resolve them from the MTL's (Blender) both find them;
    a missing one is named relative to the output's folder. A name with spaces is one path
    when a file of that name exists beside the source. ``written`` lists the material
    files the output names so far; ``copies`` gets the (material file, copy) pairs to
    write once the OBJ is written (a run stopped between the two leaves an OBJ whose
    material file is missing, which the next run writes under the same name, not an orphan
    material file that it would take for another model's); a copy never replaces one of
    the source's own, nor a material file already in the output's folder other than those
    the output it replaces named (``previous``; another model's: an OBJ written as
    ``armchair.obj`` beside the ``armchair.mtl`` of the target it was deformed onto gets
    ``armchair_2.mtl``)."""
    out_folder = os.path.dirname(os.path.abspath(os.fspath(out_path)))
    names = _mtllib_names(line, src_folder)
    sources = {os.path.abspath(_beside(name, src_folder)) for name in names}
    stem = os.path.splitext(os.path.basename(os.fspath(out_path)))[0]
    out = []
    for name in names:
        mtl = os.path.abspath(_beside(name, src_folder))
        if not os.path.isfile(mtl):
            out.append(_relative(name, src_folder, out_folder))
            continue
        copy = _free_mtl_name(out_folder, stem, mtl, sources | set(written), previous)
        if copy != mtl:  # else the source's own, beside the output already: valid as it is
            copies.append((mtl, copy))
        written.append(copy)
        out.append(os.path.basename(copy))
    return " ".join(["mtllib", *out])


def _mtllib_names(line, src_folder):
    rest = line.split("#", 1)[0].split(None, 1)[1].strip() if len(line.split()) > 1 else ""
    if " " in rest and os.path.isfile(os.path.join(src_folder, rest)):
        return [rest]
    return rest.split()


def _beside(name, folder):
    return name if os.path.isabs(name) else os.path.join(folder, name)


def _free_mtl_name(out_folder, stem, mtl, taken, previous=frozenset()):
    """``<stem>.mtl``, ``<stem>_2.mtl``...: the first that is ``mtl`` itself, or is not one
    of the source's material files or already named by the output (``taken``) and is no
    file yet unless the output being replaced named it (``previous``)."""
    k = 1
    while True:
        copy = os.path.join(out_folder, f"{stem}{'' if k == 1 else f'_{k}'}.mtl")
        if copy == mtl or (copy not in taken
                           and (copy in previous or not os.path.lexists(copy))):
            return copy
        k += 1


_MTL_MAPS = ("map_", "bump", "disp", "decal", "refl", "norm")


def _copy_mtl(mtl, copy):
    """Copy a material file with every texture path made relative to the copy's folder."""
    folder, out_folder = os.path.dirname(os.path.abspath(mtl)), os.path.dirname(copy)
    lines = []
    for line in _text(mtl).splitlines():
        parts = line.split()
        if parts and parts[0].lower().startswith(_MTL_MAPS) and len(parts) > 1:
            line = _map_line(line, parts, folder, out_folder)
        lines.append(line)
    with atomic_output(copy) as tmp, open(tmp, "w", encoding="utf-8",
                                                   errors="surrogateescape") as handle:
        handle.write("\n".join(lines) + "\n")


def _map_line(line, parts, folder, out_folder):
    """A texture statement with its file (the longest run of last tokens naming a file
    that exists; options such as ``-s 1 1 1`` come before it) made relative."""
    for start in range(1, len(parts)):
        name = " ".join(parts[start:])
        path = name if os.path.isabs(name) else os.path.join(folder, name)
        if os.path.isfile(path):
            relative = os.path.relpath(path, out_folder).replace(os.sep, "/")
            if relative.startswith("../") or os.path.isabs(relative):
                relative = _texture_beside(path, out_folder)
            return " ".join([*parts[:start], relative])
    return line


def _texture_beside(path, out_folder):
    """The name of ``path``'s texture in ``out_folder``: a copy under its own name, reused
    when a file of that name there has the same bytes, else ``<stem>-<8 hex digits of its
    SHA-1><ext>`` (collections of models all naming their texture ``texture0.jpg`` get one
    copy of each). Readers such as trimesh refuse texture paths that leave the model's
    folder, so a texture from elsewhere is put beside it."""
    stem, ext = os.path.splitext(os.path.basename(path))
    name = os.path.basename(path)
    dest = os.path.join(out_folder, name)
    if os.path.exists(dest) and not filecmp.cmp(dest, path, shallow=False):
        digest = hashlib.sha1(read_bytes(path, MeshFileError)).hexdigest()[:8]
        name = f"{stem}-{digest}{ext}"
        dest = os.path.join(out_folder, name)
    if not os.path.exists(dest):
        with atomic_output(dest) as tmp:  # a copy, not a link: editing it must not
            shutil.copyfile(path, tmp)     # change the source's texture
    return name


def _relative(name, src_folder, out_folder):
    """An ``mtllib`` path relative to the output's folder (kept if absolute)."""
    if os.path.isabs(name):
        return name
    return os.path.relpath(os.path.join(src_folder, name), out_folder).replace(os.sep, "/")


def _obj_corners(lines, source):
    """Per face: its corners' ``(vertex, normal)`` 0-based indices (normal -1 if none);
    and the source's normals (k, 3). Positive normal indices may point forward (``vn``
    records after the faces), negative ones count back from the face's line."""
    normals = []
    for number, line in enumerate(lines, 1):
        parts = line.split("#", 1)[0].split()
        if parts[:1] == ["vn"]:
            try:
                normals.append([float(x) for x in parts[1:4]])
            except ValueError:
                raise MeshFileError(f"line {number}: a normal needs 3 numbers", source) from None
    corners, seen_v, seen_n = [], 0, 0
    for number, line in enumerate(lines, 1):
        parts = line.split("#", 1)[0].split()
        key = parts[0] if parts else ""
        seen_v += key == "v"
        seen_n += key == "vn"
        if key == "f":
            corners.append([_corner(token, seen_v, seen_n, len(normals), number, source)
                            for token in parts[1:]])
    return corners, np.asarray(normals, dtype=np.float64).reshape(-1, 3)


def _corner(token, seen_v, seen_n, total_n, number, source):
    fields = token.split("/")
    v = int(fields[0])
    v = v - 1 if v > 0 else v + seen_v
    n = -1
    if len(fields) >= 3 and fields[2]:
        n = int(fields[2])
        n = n - 1 if n > 0 else n + seen_n
        if not 0 <= n < total_n:
            raise MeshFileError(f"line {number}: normal index {fields[2]} is out of range",
                                source)
    return v, n


def _obj_carried_normals(V0, V1, corners, normals):
    """New face tokens' normal indices (one per corner, -1 for none) and the carried
    normals, one per ``(vertex, normal)`` pair in order of first use."""
    from cagekit.geometry.normal_transport import transported_normals  # igl, scipy: lazily

    pair_of, tri, tri_normals, tri_groups, per_face = {}, [], [], [], []
    for face in corners:
        ids = []
        for v, n in face:
            ids.append(-1 if n < 0 else pair_of.setdefault((v, n), len(pair_of)))
        per_face.append(ids)
        for k in range(1, len(face) - 1):  # the fan the reader makes
            c = [face[0], face[k], face[k + 1]]
            tri.append([v for v, _ in c])
            tri_normals.append([normals[n] if n >= 0 else (0.0, 0.0, 0.0) for _, n in c])
            tri_groups.append([ids[0], ids[k], ids[k + 1]])
    if not pair_of:
        return per_face, np.empty((0, 3))
    carried = transported_normals(V0, V1, np.asarray(tri).reshape(-1, 3),
                                  np.asarray(tri_normals).reshape(-1, 3, 3),
                                  np.asarray(tri_groups).reshape(-1, 3))
    return per_face, carried


def _obj_face(parts, normal_ids):
    tokens = ["f"]
    for token, n in zip(parts[1:], normal_ids):
        fields = token.split("/")
        if n >= 0:
            fields = [fields[0], fields[1] if len(fields) > 1 else "", str(n + 1)]
        tokens.append("/".join(fields))
    return " ".join(tokens)


# ------------------------------------------------------------------------------------- PLY


_PLY_NORMALS = {"nx", "ny", "nz"}
_PLY_COLOURS = {"red", "green", "blue", "alpha", "r", "g", "b", "a", "diffuse_red",
                "diffuse_green", "diffuse_blue"}
_PLY_UVS = {"s", "t", "u", "v", "texture_u", "texture_v", "texture_s", "texture_t"}


def _ply_contents(source):
    _, elements, _ = ply_header(read_bytes(source, MeshFileError), source)
    found = []
    for name, _, props in elements:
        names = {p[0] for p in props}
        if name == "vertex":
            extra = names - {"x", "y", "z"}
            found += [word for word, kind in (("normals", _PLY_NORMALS),
                                              ("vertex colours", _PLY_COLOURS),
                                              ("UVs", _PLY_UVS)) if extra & kind]
            other = extra - _PLY_NORMALS - _PLY_COLOURS - _PLY_UVS
        else:
            other = names - {"vertex_indices", "vertex_index"} if name == "face" else names
        if other and "other properties" not in found:
            found.append("other properties")
    return found


def _write_ply(path, V, V0, F0, source):
    data = read_bytes(source, MeshFileError)
    fmt, elements, pos = ply_header(data, source)
    if any(c is not None for n, _, props in elements if n == "vertex" for _, _, c in props):
        raise MeshFileError("has a list property in its vertex element; cannot keep it", source)
    columns, start, end = _ply_vertex(data, fmt, elements, pos)
    normals = None
    if all(k in columns for k in ("nx", "ny", "nz")):
        N = np.column_stack([np.asarray(columns[k], dtype=np.float64) for k in ("nx", "ny", "nz")])
        normals = _carried_vertex_normals(V0, V, F0, N)
    if fmt == "ascii":
        body = _ply_ascii_with(data[pos:].decode("ascii"), elements, V, normals)
        payload = data[:pos] + body.encode("ascii")
    else:
        payload = _ply_binary_with(data, start, end, fmt, elements, V, normals)
    with atomic_output(path) as tmp, open(tmp, "wb") as handle:
        handle.write(payload)


def _ply_vertex(data, fmt, elements, pos):
    """The vertex element's columns ({name: array}) and its byte range (binary only)."""
    tokens = data[pos:].decode("ascii").split() if fmt == "ascii" else None
    at = 0 if fmt == "ascii" else pos
    endian = "<" if fmt == "binary_little_endian" else ">"
    for name, count, props in elements:
        start = at
        if fmt == "ascii":
            columns, at = ply_ascii_element(tokens, at, count, props)
        else:
            columns, at = ply_binary_element(data, at, count, props, endian)
        if name == "vertex":
            return columns, start, at
    raise AssertionError("no vertex element")  # load_mesh has read it already


def _carried_vertex_normals(V0, V1, F, N):
    """Per-vertex normals ``N`` carried through ``V0 -> V1`` (a vertex no face uses keeps
    its normal)."""
    from cagekit.geometry.normal_transport import transported_normals  # igl, scipy: lazily

    carried = transported_normals(V0, V1, F, N[F], F, n_groups=len(V0))
    unused = ~np.isin(np.arange(len(V0)), F)
    carried[unused] = N[unused]
    return carried


def _ply_ascii_with(body, elements, V, normals):
    """The ASCII body with the vertex lines' coordinates and normals replaced (one record
    a line, as PLY writers put them)."""
    lines = body.split("\n")
    first = 0
    for name, count, props in elements:
        if name != "vertex":
            first += count
            continue
        names = [p[0] for p in props]
        for i in range(count):
            tokens = lines[first + i].split()
            for j, key in enumerate("xyz"):
                tokens[names.index(key)] = f"{V[i, j]:.17g}"
            if normals is not None:
                for j, key in enumerate(("nx", "ny", "nz")):
                    tokens[names.index(key)] = f"{normals[i, j]:.9g}"
            lines[first + i] = " ".join(tokens)
        break
    return "\n".join(lines)


def _ply_binary_with(data, start, end, fmt, elements, V, normals):
    """The binary data with the vertex records (bytes ``start:end``) rewritten."""
    endian = "<" if fmt == "binary_little_endian" else ">"
    props = next(props for name, _, props in elements if name == "vertex")
    dtype = np.dtype([(name, endian + kind) for name, kind, _ in props])
    table = np.frombuffer(data, dtype=dtype, count=len(V), offset=start).copy()
    for j, key in enumerate("xyz"):
        table[key] = V[:, j]
    if normals is not None:
        for j, key in enumerate(("nx", "ny", "nz")):
            table[key] = normals[:, j]
    return data[:start] + table.tobytes() + data[end:]


# -------------------------------------------------------------------------------- GLB/GLTF


def _write_glb(path, V, V0, F0, source):
    import trimesh

    _warn_unwritable_gltf(source, path)
    scene = trimesh.load(os.fspath(source), process=False, maintain_order=True, force="scene")
    offset, instanced = 0, _instanced(scene)
    for node in list(scene.graph.nodes_geometry):
        transform, name = scene.graph[node]
        mesh = scene.geometry[name]
        if not isinstance(mesh, trimesh.Trimesh) or not len(mesh.faces):
            continue
        n = len(mesh.vertices)
        world = V[offset:offset + n]
        offset += n
        copy = mesh.copy()
        rest_normals = np.asarray(mesh.vertex_normals, dtype=np.float64)
        local = trimesh.transformations.transform_points(world, np.linalg.inv(transform))
        rest_local = np.asarray(mesh.vertices, dtype=np.float64)
        copy.vertices = local
        faces = np.asarray(mesh.faces, dtype=np.int64)
        copy.vertex_normals = _carried_vertex_normals(rest_local, local, faces, rest_normals)
        if name in instanced:  # each instance gets its own moved copy, under its own parent
            name = f"{name}__{node}"
            scene.graph.transforms.node_data[node]["geometry"] = name
        scene.geometry[name] = copy
    for name in instanced:  # every instance has its copy now
        scene.geometry.pop(name, None)
    scene.graph._cache.clear()  # nodes_geometry and friends are cached on the graph
    _children_as_read(scene)
    data = trimesh.exchange.gltf.export_glb(scene, include_normals=True)
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as handle:
            handle.write(data)
        if not _same_up_to_float32(load_mesh(tmp)[0], V):  # the safety net of the above
            raise MeshFileError("cannot be written as GLB keeping the vertex order of "
                                f"{os.fspath(source)}; write OBJ or PLY", path)


def _warn_unwritable_gltf(source, path):
    """One warning when the glTF source has what trimesh cannot write: skins, animations,
    morph targets (a rig's result keeps its posed surface only)."""
    data = read_bytes(source, MeshFileError)
    if data[:4] == b"glTF":  # binary: the JSON chunk follows the 12-byte header
        length = int.from_bytes(data[12:16], "little")
        data = data[20:20 + length]
    try:
        header = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return  # trimesh read it; nothing more to say
    lost = [word for key, word in (("skins", "skins"), ("animations", "animations"))
            if header.get(key)]
    if any(p.get("targets") for m in header.get("meshes", []) for p in m.get("primitives", [])):
        lost.append("morph targets")
    if lost:
        warnings.warn(MeshFileWarning(
            f"{os.fspath(path)}: the {', '.join(lost)} of {os.fspath(source)} are not kept "
            "(the GLB result is the deformed surface with its materials)"), stacklevel=4)


def _children_as_read(scene):
    """Reverse every node's list of children in the scene graph, so the written file lists
    them as the source did. trimesh reads a glTF scene depth first with a stack (the last
    child first) and records children in the order it visits them: each list comes back
    reversed, and written as it is, the output would be read in another node order than
    the source (its meshes, and so its vertices, permuted)."""
    children = scene.graph.transforms.children
    for parent in list(children):
        children[parent] = list(reversed(children[parent]))


def _instanced(scene):
    """Geometry names drawn by more than one node (each instance gets its own copy)."""
    names = [scene.graph[node][1] for node in scene.graph.nodes_geometry]
    return {name for name in names if names.count(name) > 1}


def _same_up_to_float32(A, B):
    """Whether two vertex arrays agree to float32 rounding (GLB stores float32)."""
    scale = max(float(np.abs(B).max(initial=0.0)), 1e-30)
    return A.shape == B.shape and float(np.abs(A - B).max(initial=0.0)) <= 1e-6 * scale


_WRITERS = {".obj": _write_obj, ".ply": _write_ply, ".glb": _write_glb, ".gltf": _write_glb}
