"""Reading and writing meshes and point clouds.

Meshes come back as ``V`` (n, 3) float64 and ``F`` (m, 3) int64; a point cloud is a mesh with
no faces. A bad file raises a one-line :class:`~cagekit.errors.MeshFileError` (an
:class:`~cagekit.errors.InputError`, as are bad arrays or destinations given to ``save_*``)
naming the file; a NullHandler on the ``trimesh`` logger keeps its tracebacks off stderr.
Vertex order is identity: readers return every vertex in file order, unreferenced and
duplicate ones included (STL, which shares no vertices, merges identical positions in order
of first appearance). OBJ, OFF and PLY are therefore parsed here, as trimesh does not keep
vertex identity on common files; STL and GLB/GLTF use ``trimesh.load(..., process=False,
maintain_order=True)``, scenes flattened by world transform in scene-graph order (only point
clouds: a point cloud). Polygons are fan-triangulated in file order; faces of fewer than 3
vertices, and OBJ line elements (``l`` records), are dropped with one
:class:`~cagekit.errors.MeshFileWarning` per file that counts them; degenerate triangles are
kept. OBJ reads ``v`` (first three columns) and ``f`` (and counts ``l``) only: 1-based,
negative indices count back from the latest vertex, index 0 is an error, ``#`` comments on
any line, backslash continuations. Text clouds (``.xyz``, ``.pts``, ``.txt``): one point a line,
whitespace or commas, first three columns; blank, ``#`` and ``//`` lines skipped; a leading
point count (PTS) must match. Writing is atomic (:func:`cagekit.io.files.atomic_output`) and
exact where the format allows: ``%.17g`` text, binary little-endian PLY (float64, int32
indices), float64 NPY; STL and GLB store float32.
"""

from __future__ import annotations

import logging
import os
import struct
import warnings

import numpy as np
from numpy.typing import ArrayLike

from cagekit.errors import InputError, MeshFileError, MeshFileWarning
from cagekit.io.files import atomic_output, check_file, extension, one_line, read_bytes, read_text
from cagekit.io.pmd import read_pmd

__all__ = [
    "SUPPORTED_MESH_EXTENSIONS",
    "SUPPORTED_POINT_EXTENSIONS",
    "WRITTEN_MESH_EXTENSIONS",
    "load_mesh",
    "load_points",
    "load_shape",
    "save_mesh",
    "save_points",
]

SUPPORTED_MESH_EXTENSIONS = (".obj", ".ply", ".off", ".stl", ".glb", ".gltf", ".pmd")
"""Extensions :func:`load_mesh` reads (``.pmd``: 0 A.D.'s models, :mod:`cagekit.io.pmd`)."""
WRITTEN_MESH_EXTENSIONS = (".obj", ".ply", ".off", ".stl", ".glb")
"""Extensions :func:`save_mesh` writes (not GLTF or PMD)."""
SUPPORTED_POINT_EXTENSIONS = (".ply", ".xyz", ".pts", ".txt", ".npy")
"""Point-cloud extensions :func:`load_shape` reads and :func:`save_points` writes."""

_NO_FACES = np.empty((0, 3), dtype=np.int64)

# trimesh logs parse failures (with tracebacks) as warnings; with no handler configured,
# Python prints them to stderr, which would break the command line's one-line errors.
# A NullHandler keeps them quiet unless the application configures logging itself.
logging.getLogger("trimesh").addHandler(logging.NullHandler())


# ----------------------------------------------------------------------------- loading


def load_mesh(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Load a triangle mesh, keeping the file's vertices exactly, in order.

    Parameters
    ----------
    path : str or os.PathLike
        An OBJ, PLY, OFF, STL, GLB, GLTF or PMD (0 A.D.'s models) file with at least one
        face. Polygons are fan-triangulated; GLB/GLTF scenes are flattened with their
        transforms applied; a PMD model is read in its rest pose.

    Returns
    -------
    V : (n, 3) float64 ndarray, C-contiguous
        Every vertex of the file in file order, unreferenced and duplicate ones included.
    F : (m, 3) int64 ndarray
        Triangles indexing ``V``, in file order.

    Raises
    ------
    MeshFileError
        The file is missing, empty, unparsable, of an unknown kind, has no faces, has
        non-finite coordinates or out-of-range indices.

    Examples
    --------
    >>> V, F = load_mesh("data/example/cage.obj")  # doctest: +SKIP
    >>> V.shape[1], F.shape[1], V.dtype, F.dtype  # doctest: +SKIP
    (3, 3, dtype('float64'), dtype('int64'))
    """
    ext = extension(path)
    if ext not in SUPPORTED_MESH_EXTENSIONS:
        kind = "is a point-cloud format" if ext in SUPPORTED_POINT_EXTENSIONS else "is not known"
        raise MeshFileError(
            f"extension {ext or '(none)'!r} {kind}; a triangle mesh is required "
            f"({', '.join(SUPPORTED_MESH_EXTENSIONS)})",
            path,
        )
    V, F = _load(path, ext)
    if len(F) == 0:
        raise MeshFileError("has no faces; a triangle mesh is required", path)
    return V, F


def load_shape(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Load a mesh or a point cloud.

    Parameters
    ----------
    path : str or os.PathLike
        Any mesh file :func:`load_mesh` reads, or a point cloud: PLY without faces,
        XYZ/PTS/TXT text, or NPY holding an (n, 3) or (n, >=3) numeric array (the first
        three columns are used). At least one point is required.

    Returns
    -------
    V : (n, 3) float64 ndarray, C-contiguous
        The vertices or points, in file order.
    F : (m, 3) int64 ndarray
        The triangles of a mesh; ``np.empty((0, 3), int64)`` for a point cloud.

    Raises
    ------
    MeshFileError
        As :func:`load_mesh`, except that having no faces is allowed.

    Examples
    --------
    >>> V, F = load_shape("scan.xyz")  # doctest: +SKIP
    >>> F.shape  # doctest: +SKIP
    (0, 3)
    """
    ext = extension(path)
    if ext not in _READERS:
        known = ", ".join(sorted(_READERS))
        raise MeshFileError(f"unknown extension {ext or '(none)'!r}; supported: {known}", path)
    return _load(path, ext)


def load_points(path: str | os.PathLike) -> np.ndarray:
    """Load the vertices (or points) of any file :func:`load_shape` reads.

    Parameters
    ----------
    path : str or os.PathLike
        A mesh or point-cloud file.

    Returns
    -------
    V : (n, 3) float64 ndarray, C-contiguous
        The vertices or points, in file order; faces are dropped.

    Examples
    --------
    >>> P = load_points("shape.ply")  # doctest: +SKIP
    >>> P.shape[1]  # doctest: +SKIP
    3
    """
    return load_shape(path)[0]


def _load(path, ext):
    reader, kind = _READERS[ext]
    try:
        V, F = reader(path)
    except InputError:
        raise
    except Exception as exc:  # any parser failure is a property of the file
        raise MeshFileError(f"cannot be read as {kind}: {one_line(exc)}", path) from exc
    return _checked(V, F, path)


def _checked(V, F, path):
    V = np.ascontiguousarray(V, dtype=np.float64).reshape(-1, 3)
    F = np.ascontiguousarray(F, dtype=np.int64).reshape(-1, 3)
    if len(V) == 0:
        raise MeshFileError("contains no vertices or points", path)
    bad = ~np.isfinite(V).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise MeshFileError(f"vertex {i} (0-based) is not finite: {V[i].tolist()}", path)
    if len(F) and (F.min() < 0 or F.max() >= len(V)):
        i = int(np.argmax(((F < 0) | (F >= len(V))).any(axis=1)))
        raise MeshFileError(
            f"face {i} (0-based) refers to vertices {F[i].tolist()}; "
            f"there are {len(V)} vertices",
            path,
        )
    return V, F


def _triangulate(flat, sizes, n_vertices, path, lines=None, base=0,
                 line_elements=None) -> np.ndarray:
    """Fan-triangulate polygons given as concatenated indices ``flat`` and ``sizes``.

    Errors name ``lines[i]`` (else the face number) and show indices counted from ``base``.
    Polygons of fewer than 3 vertices are dropped; they and ``line_elements`` (``(count,
    first line)`` of the file's dropped line elements, or None) are counted in one warning.
    """
    flat = np.asarray(flat, dtype=np.int64).reshape(-1)
    sizes = np.asarray(sizes, dtype=np.int64)
    if lines is None:  # name faces by their number in the file, also after dropping some
        lines = np.arange(len(sizes))
        where = lambda i: f"face {lines[i]}"  # noqa: E731
    else:
        where = lambda i: f"line {lines[i]}"  # noqa: E731
    short = sizes < 3
    dropped = []
    if short.any():  # lines or points written as faces: dropped, with one warning
        first = int(np.argmax(short))
        dropped.append(f"{int(short.sum()):,} face(s) with fewer than 3 vertices "
                       f"(the first at {where(first)})")
        flat = flat[np.repeat(~short, sizes)]
        lines = [line for line, bad in zip(lines, short) if not bad]
        sizes = sizes[~short]
    if line_elements is not None:
        count, first_line = line_elements
        dropped.append(f"{count:,} line element(s) (the first at line {first_line})")
    if dropped:
        _warn_dropped(path, dropped, kept=len(sizes))
    if len(flat) and (flat.min() < 0 or flat.max() >= n_vertices):
        polygon = np.repeat(np.arange(len(sizes)), sizes)
        j = int(np.argmax((flat < 0) | (flat >= n_vertices)))
        raise MeshFileError(
            f"{where(polygon[j])}: vertex index {flat[j] + base} is out of range "
            f"(the file has {n_vertices} vertices)",
            path,
        )
    if not len(sizes) or (sizes == 3).all():
        return flat.reshape(-1, 3)
    triangles = sizes - 2
    polygon = np.repeat(np.arange(len(sizes)), triangles)
    start = (np.cumsum(sizes) - sizes)[polygon]
    corner = np.arange(triangles.sum()) - np.repeat(np.cumsum(triangles) - triangles, triangles)
    return np.column_stack([flat[start], flat[start + corner + 1], flat[start + corner + 2]])


def _warn_dropped(path, dropped, kept):
    """One :class:`MeshFileWarning` for a file: what was ``dropped`` (phrases with counts),
    and how many faces were ``kept``."""
    warnings.warn(MeshFileWarning(
        f"{os.fspath(path)}: dropped {' and '.join(dropped)}; kept {kept:,} face(s)"),
        stacklevel=6)  # _warn_dropped, _triangulate, the reader, _load, load_*, its caller


def _numbers(rows, lines, path, what="coordinate") -> np.ndarray:
    """Convert rows of 3 strings to float64, naming the line of the first bad one."""
    try:
        return np.array(rows, dtype=np.float64).reshape(-1, 3)
    except ValueError:
        for row, line in zip(rows, lines):
            for token in row:
                try:
                    float(token)
                except ValueError:
                    raise MeshFileError(
                        f"line {line}: {what} {token!r} is not a number", path
                    ) from None
        raise


def _int_table(rows):
    """Rows of integer strings as an (m, k) int64 array; None if ragged or not plain ints."""
    try:
        table = np.array(rows, dtype=np.int64)
    except (ValueError, OverflowError):
        return None
    return table if table.ndim == 2 else None


def _read_obj(path):
    rows, v_lines, faces, f_lines, f_seen, l_lines = _obj_records(path)
    V = _numbers(rows, v_lines, path)
    line_elements = (len(l_lines), l_lines[0]) if l_lines else None
    table = _int_table(faces)
    if table is not None and table.shape[1] == 3 and (table > 0).all():  # fast path
        return V, _triangulate(table - 1, np.full(len(table), 3), len(V), path, f_lines, 1,
                               line_elements)
    flat = _obj_face_indices(faces, f_lines, f_seen, path)
    sizes = [len(face) for face in faces]
    return V, _triangulate(flat, sizes, len(V), path, f_lines, 1, line_elements)


def _obj_records(path):
    """The ``v``, ``f`` and ``l`` records of an OBJ file, with their line numbers.

    Returns ``(rows, v_lines, faces, f_lines, f_seen, l_lines)``: the vertices' first three
    tokens, the faces' tokens, the vertex count before each face (relative indices count
    back from there) and the line numbers of the line elements (which are only counted).
    """
    text = read_text(path, MeshFileError)
    rows, v_lines, faces, f_lines, f_seen, l_lines = [], [], [], [], [], []
    pending = ""
    for number, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].rstrip()  # a comment runs to the end of the line
        if line.endswith("\\"):
            pending += line[:-1] + " "
            continue
        parts = (pending + line).split()
        pending = ""
        if not parts:
            continue
        if parts[0] == "v":
            if len(parts) < 4:
                raise MeshFileError(f"line {number}: a vertex needs 3 coordinates", path)
            rows.append(parts[1:4])
            v_lines.append(number)
        elif parts[0] == "f":
            faces.append(parts[1:])
            f_lines.append(number)
            f_seen.append(len(rows))
        elif parts[0] == "l":
            l_lines.append(number)
    return rows, v_lines, faces, f_lines, f_seen, l_lines


def _obj_face_indices(faces, f_lines, f_seen, path):
    """The 0-based vertex indices of OBJ faces, concatenated (``v/vt/vn`` and relative
    indices resolved); a bad index raises naming its line."""
    flat = []
    for number, face, seen in zip(f_lines, faces, f_seen):
        for token in face:
            try:
                index = int(token.split("/", 1)[0])
            except ValueError:
                raise MeshFileError(
                    f"line {number}: {token!r} is not a vertex index", path
                ) from None
            if index == 0:
                raise MeshFileError(f"line {number}: vertex index 0 (OBJ counts from 1)", path)
            if index < 0 and index + seen < 0:
                raise MeshFileError(
                    f"line {number}: relative index {index} reaches before the first vertex",
                    path,
                )
            flat.append(index - 1 if index > 0 else index + seen)
    return flat


def _read_off(path):
    text = read_text(path, MeshFileError)
    lines = [(n, line.split("#", 1)[0].split()) for n, line in enumerate(text.splitlines(), 1)]
    lines = [(n, tokens) for n, tokens in lines if tokens]
    if not lines:
        raise MeshFileError("is empty", path)
    head, lines = lines[0][1], lines[1:]
    if head[0].upper().endswith("OFF"):  # the keyword is optional; counts may share its line
        if head[0].upper() not in ("OFF", "COFF", "NOFF", "CNOFF", "NCOFF", "STOFF", "STCOFF"):
            raise MeshFileError(f"unsupported OFF variant {head[0]!r}", path)
        if len(head) == 1:
            head, lines = (lines[0][1], lines[1:]) if lines else ([], [])
        else:
            head = head[1:]
    try:
        n_vertices, n_faces = int(head[0]), int(head[1])
    except (ValueError, IndexError):
        raise MeshFileError(
            f"expected 'vertex_count face_count edge_count' after the OFF keyword, got {head}",
            path,
        ) from None
    if n_vertices < 0 or n_faces < 0 or len(lines) < n_vertices + n_faces:
        raise MeshFileError(
            f"declares {n_vertices} vertices and {n_faces} faces but has only "
            f"{len(lines)} data lines",
            path,
        )
    vertex_lines = lines[:n_vertices]
    for number, tokens in vertex_lines:
        if len(tokens) < 3:
            raise MeshFileError(f"line {number}: a vertex needs 3 coordinates", path)
    V = _numbers([t[:3] for _, t in vertex_lines], [n for n, _ in vertex_lines], path)
    face_lines = lines[n_vertices : n_vertices + n_faces]
    f_lines = [n for n, _ in face_lines]
    table = _int_table([t[:4] for _, t in face_lines])
    if table is not None and table.shape[1] == 4 and (table[:, 0] == 3).all():  # fast path
        return V, _triangulate(table[:, 1:], table[:, 0], len(V), path, f_lines)
    flat, sizes = [], []
    for number, tokens in face_lines:
        try:
            size = int(tokens[0])
            indices = [int(t) for t in tokens[1 : 1 + size]]
        except ValueError:
            raise MeshFileError(f"line {number}: face indices must be integers", path) from None
        if size < 0 or len(indices) != size:
            raise MeshFileError(f"line {number}: face declares {size} vertices", path)
        flat += indices
        sizes.append(size)
    return V, _triangulate(flat, sizes, len(V), path, f_lines)


# PLY scalar type names -> struct/numpy type characters.
_PLY_TYPES = {
    "char": "b", "int8": "b", "uchar": "B", "uint8": "B", "short": "h", "int16": "h",
    "ushort": "H", "uint16": "H", "int": "i", "int32": "i", "uint": "I", "uint32": "I",
    "float": "f", "float32": "f", "double": "d", "float64": "d",
}  # fmt: skip


def ply_header(data, path):
    """Parse a PLY header into (format, [(element, count, [(name, type, list_count_type)])])."""
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise MeshFileError("is not a PLY file (no 'ply' ... 'end_header' header)", path)
    body = data.find(b"\n", end) + 1 or len(data)
    fmt, elements = None, []
    for line in data[:end].decode("ascii", errors="replace").splitlines()[1:]:
        t = line.split()
        try:
            if not t or t[0] in ("comment", "obj_info"):
                continue
            if t[0] == "format":
                fmt = t[1]
            elif t[0] == "element":
                elements.append((t[1], int(t[2]), []))
                if elements[-1][1] < 0:
                    raise ValueError
            elif t[0] == "property" and t[1] == "list":
                elements[-1][2].append((t[4], _PLY_TYPES[t[3]], _PLY_TYPES[t[2]]))
            elif t[0] == "property":
                elements[-1][2].append((t[2], _PLY_TYPES[t[1]], None))
            else:
                raise ValueError
        except (ValueError, IndexError, KeyError):
            raise MeshFileError(f"invalid PLY header line {line.strip()!r}", path) from None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise MeshFileError(f"unknown PLY format {fmt!r}", path)
    return fmt, elements, body


def _as_columns(columns):
    """Lists read row by row -> arrays; a list property becomes (flat int64, sizes)."""
    return {
        k: (np.array(v[0], dtype=np.int64), np.array(v[1])) if isinstance(v, tuple) else v
        for k, v in columns.items()
    }


def ply_ascii_element(tokens, pos, count, props):
    """Read one element of an ASCII PLY: {name: column or (flat, sizes)}, new position."""
    if all(counter is None for _, _, counter in props):
        block = tokens[pos : pos + count * len(props)]
        if len(block) < count * len(props):
            raise EOFError
        table = np.array(block, dtype=np.float64).reshape(count, len(props))
        return {name: table[:, j] for j, (name, _, _) in enumerate(props)}, pos + len(block)
    columns = {name: ([], []) if counter else [] for name, _, counter in props}
    for _ in range(count):
        for name, _, counter in props:
            if counter is None:
                columns[name].append(tokens[pos])
                pos += 1
                continue
            size = int(tokens[pos])
            items = tokens[pos + 1 : pos + 1 + size]
            if size < 0 or len(items) < size:
                raise EOFError
            columns[name][0].extend(items)
            columns[name][1].append(size)
            pos += 1 + size
        if pos > len(tokens):
            raise EOFError
    return _as_columns(columns), pos


def ply_binary_element(data, pos, count, props, endian):
    """Read one element of a binary PLY: {name: column or (flat, sizes)}, new position."""
    # Fast path: assume every list is as long as in the first row, then check it.
    fields, offset = [], pos
    for name, kind, counter in props:
        if counter is None:
            fields.append((name, endian + kind))
            offset += struct.calcsize(kind)
            continue
        (size,) = struct.unpack_from(endian + counter, data, offset) if count else (0,)
        fields += [("#" + name, endian + counter), (name, endian + kind, (size,))]
        offset += struct.calcsize(counter) + size * struct.calcsize(kind)
    dtype = np.dtype(fields)
    end = pos + count * dtype.itemsize
    lists = [name for name, _, counter in props if counter]
    if end > len(data) and not lists:
        raise EOFError
    if end <= len(data):
        table = np.frombuffer(data, dtype=dtype, count=count, offset=pos)
        if all((table["#" + n] == table.dtype[n].shape[0]).all() for n in lists):
            columns = {name: table[name] for name, _, _ in props}
            for name in lists:
                columns[name] = (columns[name].reshape(-1).astype(np.int64), table["#" + name])
            return columns, end
    # Slow path: lists of varying length (e.g. triangles mixed with quads).
    columns = {name: ([], []) if counter else [] for name, _, counter in props}
    for _ in range(count):
        for name, kind, counter in props:
            if counter is None:
                columns[name] += struct.unpack_from(endian + kind, data, pos)
                pos += struct.calcsize(kind)
                continue
            (size,) = struct.unpack_from(endian + counter, data, pos)
            pos += struct.calcsize(counter)
            columns[name][0].extend(struct.unpack_from(f"{endian}{size}{kind}", data, pos))
            columns[name][1].append(size)
            pos += size * struct.calcsize(kind)
    return _as_columns(columns), pos


def _read_ply(path):
    data = read_bytes(path, MeshFileError)
    fmt, elements, pos = ply_header(data, path)
    if fmt == "ascii":
        body = data[pos:].decode("ascii", errors="replace").split()
        pos = 0
    values = {}
    for name, count, props in elements:
        if "vertex" in values and "face" in values:
            break
        try:
            if fmt == "ascii":
                values[name], pos = ply_ascii_element(body, pos, count, props)
            else:
                endian = "<" if fmt == "binary_little_endian" else ">"
                values[name], pos = ply_binary_element(data, pos, count, props, endian)
        except (EOFError, IndexError, struct.error):
            raise MeshFileError(
                f"is truncated: the data ends inside element '{name}' ({count} declared)", path
            ) from None
    vertex = values.get("vertex", {})
    if not all(k in vertex and not isinstance(vertex[k], tuple) for k in "xyz"):
        raise MeshFileError("has no 'vertex' element with x, y, z properties", path)
    V = np.column_stack([np.asarray(vertex[k], dtype=np.float64) for k in "xyz"])
    if "face" not in values:
        return V, _NO_FACES
    face = values["face"]
    key = next((k for k in ("vertex_indices", "vertex_index") if k in face), None)
    lists = [k for k, v in face.items() if isinstance(v, tuple)]
    if key is None and len(lists) != 1:
        raise MeshFileError("'face' element has no 'vertex_indices' list property", path)
    flat, sizes = face[key or lists[0]]
    return V, _triangulate(flat, sizes, len(V), path)


def _check_stl(path):
    """Refuse a file named ``.stl`` that is neither an ASCII STL (``solid ...``) nor a
    binary one (80-byte header, triangle count, 50 bytes a triangle), saying what it looks
    like: trimesh reads such a file as an empty mesh, and the error said "no vertices"."""
    with open(path, "rb") as fh:
        head = fh.read(84)
    size = os.path.getsize(path)
    if head.lstrip().lower().startswith(b"solid") or (
            len(head) == 84 and size == 84 + 50 * int.from_bytes(head[80:84], "little")):
        return
    text = head.decode("ascii", "replace").lstrip()
    looks = (" (it looks like an OBJ file: rename it .obj)"
             if text.startswith(("v ", "#", "o ", "g ", "mtllib")) else "")
    raise MeshFileError("is not an STL file: neither ASCII ('solid ...') nor binary (a "
                        f"header, a triangle count and 50 bytes a triangle){looks}", path)


def _read_with_trimesh(path):
    import trimesh  # 0.5 s to import: only for the formats that need it

    check_file(path, MeshFileError)
    if extension(path) == ".stl":
        _check_stl(path)
    loaded = trimesh.load(
        os.fspath(path), file_type=extension(path)[1:], process=False, maintain_order=True
    )
    parts = loaded.dump() if isinstance(loaded, trimesh.Scene) else [loaded]
    meshes = [g for g in parts if isinstance(g, trimesh.Trimesh) and len(g.faces)]
    clouds = [g for g in parts if isinstance(g, (trimesh.Trimesh, trimesh.PointCloud))]
    if not meshes:
        V = np.concatenate([np.asarray(g.vertices) for g in clouds] or [np.empty((0, 3))])
        return V, _NO_FACES
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes])
    V = np.concatenate([np.asarray(m.vertices, dtype=np.float64) for m in meshes])
    F = np.concatenate([np.asarray(m.faces, dtype=np.int64) + o for m, o in zip(meshes, offsets)])
    if extension(path) == ".stl":  # a triangle soup: merge identical corners, first seen first
        _, first, inverse = np.unique(V + 0.0, axis=0, return_index=True, return_inverse=True)
        order = np.argsort(first)
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        V, F = V[first[order]], rank[inverse.reshape(-1)][F]
    return V, F


def _read_pmd(path):
    model = read_pmd(path)
    return model.vertices, model.faces


def _read_xyz(path):
    text = read_text(path, MeshFileError)
    rows, lines = [], []
    for number, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if line and not line.startswith(("#", "//")):
            rows.append(line.replace(",", " ").split()[:3])
            lines.append(number)
    if rows and len(rows[0]) == 1:  # a PTS point count
        try:
            count = int(rows[0][0])
        except ValueError:
            raise MeshFileError(f"line {lines[0]}: expected 3 coordinates or a point count",
                                path) from None
        rows, lines = rows[1:], lines[1:]
        if count != len(rows):
            raise MeshFileError(f"the count line says {count} points but {len(rows)} follow",
                                path)
    for row, number in zip(rows, lines):
        if len(row) < 3:
            raise MeshFileError(f"line {number}: expected 3 coordinates, found {len(row)}", path)
    return _numbers(rows, lines, path), _NO_FACES


def _read_npy(path):
    check_file(path, MeshFileError)
    array = np.load(os.fspath(path), allow_pickle=False)
    if not isinstance(array, np.ndarray):
        raise MeshFileError("holds several arrays; one (n, 3) array is required", path)
    if array.dtype.kind not in "iuf" or array.ndim != 2 or array.shape[1] < 3:
        raise MeshFileError(
            f"holds a {array.dtype} array of shape {array.shape}; "
            "an (n, 3) or (n, >=3) numeric array is required",
            path,
        )
    return array[:, :3], _NO_FACES


_READERS = {
    ".obj": (_read_obj, "OBJ"),
    ".off": (_read_off, "OFF"),
    ".ply": (_read_ply, "PLY"),
    ".stl": (_read_with_trimesh, "STL"),
    ".glb": (_read_with_trimesh, "GLB"),
    ".gltf": (_read_with_trimesh, "GLTF"),
    ".pmd": (_read_pmd, "PMD"),
    ".xyz": (_read_xyz, "XYZ"),
    ".pts": (_read_xyz, "PTS"),
    ".txt": (_read_xyz, "TXT"),
    ".npy": (_read_npy, "NPY"),
}


# ----------------------------------------------------------------------------- saving


def save_mesh(path: str | os.PathLike, V: ArrayLike, F: ArrayLike) -> None:
    """Write a triangle mesh atomically, the format chosen by the extension.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ending in ``.obj``, ``.ply``, ``.off``, ``.stl`` or ``.glb``.
    V : (n, 3) array_like of float
        Vertices, finite; written in this order. OBJ/OFF (``%.17g``) and PLY (binary
        float64) reload bit for bit; STL and GLB store float32.
    F : (m, 3) array_like of int, m >= 1
        Triangles indexing ``V`` (0-based).

    Raises
    ------
    InputError
        Unsupported extension, bad shapes or dtypes, non-finite vertices, indices out of
        range, or a destination that cannot be written.

    Examples
    --------
    >>> save_mesh("tri.obj", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])  # doctest: +SKIP
    >>> load_mesh("tri.obj")[1]  # doctest: +SKIP
    array([[0, 1, 2]])
    """
    writer = _MESH_WRITERS.get(extension(path))
    if writer is None:
        raise InputError(
            f"cannot write meshes as {extension(path) or '(no extension)'!r}; "
            f"use one of {', '.join(_MESH_WRITERS)}",
            path,
        )
    V = valid_vertices(V, path)
    F = valid_faces(F, len(V), path)
    with atomic_output(path) as tmp:
        writer(tmp, V, F)


def save_points(path: str | os.PathLike, V: ArrayLike) -> None:
    """Write a point cloud atomically, the format chosen by the extension.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ending in ``.ply`` (binary float64), ``.xyz``, ``.txt``, ``.pts`` (text,
        ``%.17g``; PTS starts with the point count) or ``.npy`` (float64).
    V : (n, 3) array_like of float
        Points, finite, n >= 1; written in this order.

    Raises
    ------
    InputError
        Unsupported extension, bad shape, non-finite values, or an unwritable destination.

    Examples
    --------
    >>> save_points("cloud.xyz", np.random.default_rng(0).random((100, 3)))  # doctest: +SKIP
    """
    writer = _POINT_WRITERS.get(extension(path))
    if writer is None:
        raise InputError(
            f"cannot write point clouds as {extension(path) or '(no extension)'!r}; "
            f"use one of {', '.join(_POINT_WRITERS)}",
            path,
        )
    V = valid_vertices(V, path)
    with atomic_output(path) as tmp:
        writer(tmp, V)


def valid_vertices(V, path) -> np.ndarray:
    try:
        V = np.asarray(V, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("vertices must be a numeric (n, 3) array", path) from None
    if V.ndim != 2 or V.shape[1] != 3 or len(V) == 0:
        raise InputError(f"vertices must have shape (n, 3) with n >= 1, got {V.shape}", path)
    bad = ~np.isfinite(V).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"vertex {i} is not finite: {V[i].tolist()}", path)
    return np.ascontiguousarray(V)


def valid_faces(F, n_vertices, path) -> np.ndarray:
    try:
        F = np.asarray(F)
    except ValueError:  # ragged nested lists
        F = np.empty(0, dtype=object)
    if F.dtype.kind not in "iu" or F.ndim != 2 or F.shape[1] != 3 or len(F) == 0:
        raise InputError(
            f"faces must be an integer (m, 3) array with m >= 1, got {F.dtype} {F.shape}; "
            "use save_points for point clouds",
            path,
        )
    if F.min() < 0 or F.max() >= n_vertices:
        i = int(np.argmax(((F < 0) | (F >= n_vertices)).any(axis=1)))
        raise InputError(
            f"face {i} refers to vertices {F[i].tolist()}; there are {n_vertices}", path
        )
    return F.astype(np.int64)


def _write_obj(tmp, V, F):
    with open(tmp, "w", encoding="ascii", newline="\n") as fh:
        np.savetxt(fh, V, fmt="v %.17g %.17g %.17g")
        np.savetxt(fh, F + 1, fmt="f %d %d %d")


def _write_off(tmp, V, F):
    with open(tmp, "w", encoding="ascii", newline="\n") as fh:
        fh.write(f"OFF\n{len(V)} {len(F)} 0\n")
        np.savetxt(fh, V, fmt="%.17g %.17g %.17g")
        np.savetxt(fh, F, fmt="3 %d %d %d")


def _write_ply(tmp, V, F=None):
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(V)}"]
    header += [f"property double {axis}" for axis in "xyz"]
    if F is not None:
        header += [f"element face {len(F)}", "property list uchar int vertex_indices"]
    with open(tmp, "wb") as fh:
        fh.write(("\n".join(header + ["end_header"]) + "\n").encode("ascii"))
        fh.write(V.astype("<f8").tobytes())
        if F is not None:
            faces = np.empty(len(F), dtype=[("n", "u1"), ("v", "<i4", (3,))])
            faces["n"], faces["v"] = 3, F
            fh.write(faces.tobytes())


def _write_with_trimesh(tmp, V, F):
    import trimesh

    mesh = trimesh.Trimesh(vertices=V, faces=F, process=False)
    with open(tmp, "wb") as fh:
        fh.write(mesh.export(file_type=extension(tmp)[1:]))


def _write_xyz(tmp, V):
    with open(tmp, "w", encoding="ascii", newline="\n") as fh:
        if extension(tmp) == ".pts":
            fh.write(f"{len(V)}\n")
        np.savetxt(fh, V, fmt="%.17g %.17g %.17g")


def _write_npy(tmp, V):
    with open(tmp, "wb") as fh:
        np.save(fh, V, allow_pickle=False)


_MESH_WRITERS = {
    ".obj": _write_obj,
    ".ply": _write_ply,
    ".off": _write_off,
    ".stl": _write_with_trimesh,
    ".glb": _write_with_trimesh,
}
_POINT_WRITERS = {
    ".ply": _write_ply,
    ".xyz": _write_xyz,
    ".txt": _write_xyz,
    ".pts": _write_xyz,
    ".npy": _write_npy,
}
