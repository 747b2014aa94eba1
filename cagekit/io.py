"""Reading and writing meshes, point clouds and landmarks.

Meshes come back as ``V`` (n, 3) float64 and ``F`` (m, 3) int64; a point cloud is a mesh with
no faces. Every problem with a file raises :class:`~cagekit.errors.MeshFileError` or
:class:`~cagekit.errors.LandmarkFileError` (both :class:`~cagekit.errors.InputError`) with one
line that names the file and the problem; problems with arrays or destinations given to a
``save_*`` function raise :class:`~cagekit.errors.InputError`.

Decisions
---------
- **Vertex order is identity.** A cage's vertex order is what binds it to its coordinates, so
  the readers return every vertex of the file, in file order: unreferenced and duplicate
  vertices are kept and nothing is merged or reindexed (STL, which stores no shared vertices,
  is the one exception: identical positions are merged in order of first appearance).
- **OBJ, OFF and PLY are parsed here, not by trimesh.** trimesh 5.2 breaks vertex identity
  on common files: an OBJ with several ``usemtl`` blocks comes back with every vertex
  repeated once per material, relative (negative) OBJ indices resolve against the end of the
  file instead of the current vertex, index 0 and two-vertex faces pass silently, a truncated
  ASCII PLY loads as a shorter mesh without a word, binary PLY mixing triangles and quads is
  refused, and its PLY writer stores float32. These three formats are simple, so they are
  read and written here; STL and GLB/GLTF go through ``trimesh.load(..., process=False,
  maintain_order=True)``.
- **Polygons are fan-triangulated** in file order (face ``a b c d`` gives ``a b c``,
  ``a c d``), which is exact for convex polygons. Faces with fewer than 3 vertices (lines or
  points written as faces, as real files have) are dropped with one
  :class:`~cagekit.errors.MeshFileWarning` per file that counts them; vertices are kept.
  Degenerate triangles (a repeated index, zero area) are kept as they are.
- **OBJ** reads ``v`` and ``f`` statements only (texture coordinates, normals, groups,
  materials, lines and points are ignored); extra ``v`` columns (w or colours) are ignored;
  indices are 1-based, negative indices count back from the latest vertex, index 0 is an
  error; ``#`` starts a comment that runs to the end of its line (on every line, after a
  ``v`` or ``f`` statement too); lines ending in a backslash (trailing spaces and a comment
  aside) continue on the next line.
- **GLB/GLTF scenes are flattened**: every mesh instance is transformed by its node's world
  transform and the instances are concatenated in trimesh's scene-graph order. A scene with
  point clouds and no meshes loads as a point cloud.
- **Text point clouds** (``.xyz``, ``.pts``, ``.txt``): one point a line, whitespace- or
  comma-separated, the first three columns are x y z, extra columns are ignored; blank lines
  and lines starting with ``#`` or ``//`` are skipped; the first line may be a single point
  count (the PTS convention), which must then match the number of points.
- **Writing** is exact where the format allows: OBJ, OFF, XYZ, TXT and PTS use ``%.17g`` so
  text round-trips bit for bit, PLY is binary little-endian with float64 coordinates and
  int32 indices, NPY is float64. STL and GLB store float32 by definition. Every file is
  written atomically (see :func:`atomic_output`).
- **Landmarks** load to a ``dict`` label -> (3,) float64 in file order. Labels are stripped
  of surrounding whitespace; duplicate labels, non-numeric or non-finite values, wrong
  column counts and empty files are errors. In ``.picked`` files the face, barycentric and
  vertex columns must be numeric but are otherwise unused; the first column is not checked.
  ``save_landmarks`` writes JSON or CSV only: a ``.picked`` row needs a face index and
  barycentric coordinates that a label -> position mapping does not have.
- **Quiet failures.** Any exception a parser raises becomes a one-line ``MeshFileError`` /
  ``LandmarkFileError``; a NullHandler on the ``trimesh`` logger stops trimesh from printing
  tracebacks on stderr through Python's last-resort handler.
"""

from __future__ import annotations

import contextlib
import csv
import json
import logging
import os
import re
import secrets
import stat
import struct
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import numpy as np
import trimesh

from cagekit.errors import InputError, LandmarkFileError, MeshFileError, MeshFileWarning

__all__ = [
    "SUPPORTED_LANDMARK_EXTENSIONS",
    "SUPPORTED_MESH_EXTENSIONS",
    "SUPPORTED_POINT_EXTENSIONS",
    "atomic_output",
    "load_landmarks",
    "load_mesh",
    "load_points",
    "load_shape",
    "LandmarkMatch",
    "output_folder",
    "match_landmarks",
    "save_landmarks",
    "save_mesh",
    "save_points",
]

SUPPORTED_MESH_EXTENSIONS = (".obj", ".ply", ".off", ".stl", ".glb", ".gltf")
"""Extensions :func:`load_mesh` reads (:func:`save_mesh` writes all but ``.gltf``)."""
SUPPORTED_POINT_EXTENSIONS = (".ply", ".xyz", ".pts", ".txt", ".npy")
"""Point-cloud extensions :func:`load_shape` reads and :func:`save_points` writes."""
SUPPORTED_LANDMARK_EXTENSIONS = (".picked", ".json", ".csv")
"""Extensions :func:`load_landmarks` reads (:func:`save_landmarks` writes JSON and CSV)."""

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
        An OBJ, PLY, OFF, STL, GLB or GLTF file with at least one face. Polygons are
        fan-triangulated; GLB/GLTF scenes are flattened with their transforms applied.

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
    ext = _extension(path)
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
    ext = _extension(path)
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
        raise MeshFileError(f"cannot be read as {kind}: {_one_line(exc)}", path) from exc
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


def _extension(path) -> str:
    return os.path.splitext(os.fspath(path))[1].lower()


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def _check_file(path, error=MeshFileError) -> None:
    if os.path.isdir(path):
        raise error("is a directory, not a file", path)
    try:
        size = os.stat(path).st_size
    except FileNotFoundError:
        raise error("no such file", path) from None
    except OSError as exc:
        raise error(f"cannot be read: {exc.strerror or exc}", path) from None
    if size == 0:
        raise error("is empty", path)


def _read_bytes(path, error=MeshFileError) -> bytes:
    _check_file(path, error)
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise error(f"cannot be read: {exc.strerror or exc}", path) from None
    if not data.strip():
        raise error("is empty", path)
    return data


def _read_text(path, error=MeshFileError) -> str:
    return _read_bytes(path, error).decode("utf-8-sig", errors="replace")


def _triangulate(flat, sizes, n_vertices, path, lines=None, base=0) -> np.ndarray:
    """Fan-triangulate polygons given as concatenated indices ``flat`` and ``sizes``.

    Errors name ``lines[i]`` (else the face number) and show indices counted from ``base``.
    """
    flat = np.asarray(flat, dtype=np.int64).reshape(-1)
    sizes = np.asarray(sizes, dtype=np.int64)
    if lines is None:  # name faces by their number in the file, also after dropping some
        lines = np.arange(len(sizes))
        where = lambda i: f"face {lines[i]}"  # noqa: E731
    else:
        where = lambda i: f"line {lines[i]}"  # noqa: E731
    short = sizes < 3
    if short.any():  # lines or points written as faces: dropped, with one warning
        first = int(np.argmax(short))
        warnings.warn(MeshFileWarning(
            f"{os.fspath(path)}: dropped {int(short.sum()):,} face(s) with fewer than 3 "
            f"vertices (the first at {where(first)}); kept {int((~short).sum()):,}"),
            stacklevel=5)
        flat = flat[np.repeat(~short, sizes)]
        lines = [line for line, bad in zip(lines, short) if not bad]
        sizes = sizes[~short]
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
    text = _read_text(path)
    rows, v_lines, faces, f_lines, f_seen = [], [], [], [], []
    pending = ""
    for number, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].rstrip()  # a comment runs to the end of the line
        if line.endswith("\\"):
            pending += line[:-1] + " "
            continue
        parts = (pending + line).split()
        pending = ""
        if not parts or parts[0] not in ("v", "f"):
            continue
        if parts[0] == "v":
            if len(parts) < 4:
                raise MeshFileError(f"line {number}: a vertex needs 3 coordinates", path)
            rows.append(parts[1:4])
            v_lines.append(number)
        else:
            faces.append(parts[1:])
            f_lines.append(number)
            f_seen.append(len(rows))  # relative indices count back from here
    V = _numbers(rows, v_lines, path)
    table = _int_table(faces)
    if table is not None and table.shape[1] == 3 and (table > 0).all():  # fast path
        return V, _triangulate(table - 1, np.full(len(table), 3), len(V), path, f_lines, 1)
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
    sizes = [len(face) for face in faces]
    return V, _triangulate(flat, sizes, len(V), path, f_lines, base=1)


def _read_off(path):
    text = _read_text(path)
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


def _ply_header(data, path):
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


def _ply_ascii_element(tokens, pos, count, props):
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


def _ply_binary_element(data, pos, count, props, endian):
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
    data = _read_bytes(path)
    fmt, elements, pos = _ply_header(data, path)
    if fmt == "ascii":
        body = data[pos:].decode("ascii", errors="replace").split()
        pos = 0
    values = {}
    for name, count, props in elements:
        if "vertex" in values and "face" in values:
            break
        try:
            if fmt == "ascii":
                values[name], pos = _ply_ascii_element(body, pos, count, props)
            else:
                endian = "<" if fmt == "binary_little_endian" else ">"
                values[name], pos = _ply_binary_element(data, pos, count, props, endian)
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


def _read_with_trimesh(path):
    _check_file(path)
    loaded = trimesh.load(
        os.fspath(path), file_type=_extension(path)[1:], process=False, maintain_order=True
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
    if _extension(path) == ".stl":  # a triangle soup: merge identical corners, first seen first
        _, first, inverse = np.unique(V + 0.0, axis=0, return_index=True, return_inverse=True)
        order = np.argsort(first)
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        V, F = V[first[order]], rank[inverse.reshape(-1)][F]
    return V, F


def _read_xyz(path):
    text = _read_text(path)
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
    _check_file(path)
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
    ".xyz": (_read_xyz, "XYZ"),
    ".pts": (_read_xyz, "PTS"),
    ".txt": (_read_xyz, "TXT"),
    ".npy": (_read_npy, "NPY"),
}


# ----------------------------------------------------------------------------- saving


@contextlib.contextmanager
def output_folder(path: str | os.PathLike) -> Iterator[str]:
    """Make a folder for a command's outputs; if the block fails, remove what it made.

    The folder and its missing parents are created; when the block raises (an error, an
    interrupt), each folder this call created is removed again if it is still empty, so a
    failed run leaves no empty folder behind. A folder that existed before is left alone.

    Parameters
    ----------
    path : str or os.PathLike

    Yields
    ------
    str
        The folder's absolute path.

    Raises
    ------
    InputError
        The path (or a parent) is a regular file, or the folder cannot be created
        (read-only file system, no permission).

    Examples
    --------
    >>> with output_folder("out/shapes") as folder:  # doctest: +SKIP
    ...     save_mesh(os.path.join(folder, "a.obj"), V, F)
    """
    target = os.path.abspath(os.fspath(path))
    missing = []
    probe = target
    while not os.path.lexists(probe):
        missing.append(probe)
        probe = os.path.dirname(probe)
    if not os.path.isdir(probe):
        raise InputError(f"cannot make the folder: {probe} is not a folder", path)
    try:
        os.makedirs(target, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot make the folder: {exc.strerror or exc}", path) from None
    try:
        yield target
    except BaseException:
        for folder in missing:  # deepest first
            with contextlib.suppress(OSError):
                os.rmdir(folder)
        raise


#: folders whose stale temporaries this process has removed (once per folder and process)
_SWEPT: set[str] = set()

#: temporary names: ``.<name>.tmp-<8 hex><ext>`` (being written, locked) and
#: ``.<name>.new-<8 hex><ext>`` (just created, about to be locked and renamed)
_TEMPORARY = re.compile(r"^\..*\.(tmp|new)-[0-9a-f]{8}(\.[^.]*)?$")


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike) -> Iterator[str]:
    """Write a file atomically: yield a temporary path, then rename it to ``path``.

    The temporary file ``.<name>.tmp-<8 hex digits><ext>`` is created (empty) in the
    destination's folder with the same extension, so writers that pick a format from the
    extension work. When the block succeeds the file is fsynced and renamed over ``path``
    with ``os.replace`` (keeping the mode of a file it replaces); when the block raises, it
    is removed and ``path`` is left untouched.

    A process killed while writing (SIGKILL, a power cut) cannot remove its temporary file.
    So the temporary file is locked (``flock``) for as long as it exists under that name (it
    is created as ``.<name>.new-...``, locked, then renamed, which keeps the lock), and the
    first write into a folder in a process removes the folder's unlocked temporary files:
    what dead writers left behind (``.new-`` ones only when older than a minute). A live
    writer's file is locked and stays. On file systems whose ``flock`` is emulated or absent
    (some NFS set-ups) nothing is ever taken for stale.

    Parameters
    ----------
    path : str or os.PathLike
        The final destination. Its folder must exist.

    Yields
    ------
    str
        The temporary path to write to.

    Raises
    ------
    InputError
        ``path`` is a directory, its folder does not exist or cannot be written.

    Examples
    --------
    >>> with atomic_output("out/preview.png") as tmp:  # doctest: +SKIP
    ...     figure.savefig(tmp)
    """
    target = os.path.abspath(os.fspath(path))
    folder, name = os.path.split(target)
    if os.path.isdir(target):
        raise InputError("is a directory; cannot write a file there", path)
    if not os.path.isdir(folder):
        raise InputError(f"cannot write: folder {folder} does not exist", path)
    if folder not in _SWEPT:
        _remove_stale_temporaries(folder)
        _SWEPT.add(folder)
    root, ext = os.path.splitext(name)
    while True:
        token = secrets.token_hex(4)
        fresh = os.path.join(folder, f".{root}.new-{token}{ext}")
        tmp = os.path.join(folder, f".{root}.tmp-{token}{ext}")
        try:
            lock = os.open(fresh, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        except OSError as exc:
            raise InputError(f"cannot write: {exc.strerror or exc}", path) from None
        if os.path.lexists(tmp):  # a name clash: try another token
            os.close(lock)
            os.remove(fresh)
            continue
        break
    try:
        _lock(lock, blocking=True)
        os.rename(fresh, tmp)  # the same inode, still locked: never unlocked under .tmp-
        try:
            yield tmp
            _fsync_written(tmp, lock)
            with contextlib.suppress(OSError):
                os.chmod(tmp, stat.S_IMODE(os.stat(target).st_mode))
            os.replace(tmp, target)
        except BaseException:
            with contextlib.suppress(OSError):
                os.remove(tmp)
            raise
    finally:
        with contextlib.suppress(OSError):
            os.remove(fresh)  # only there if the rename failed
        os.close(lock)
    with contextlib.suppress(OSError):  # make the rename itself durable (POSIX)
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _fsync_written(tmp: str, lock: int) -> None:
    """fsync what was written to ``tmp``: through the lock's descriptor when it is still
    the same file (opening and closing another descriptor would drop an emulated lock)."""
    if os.fstat(lock).st_ino == os.stat(tmp).st_ino:
        os.fsync(lock)
        return
    fd = os.open(tmp, os.O_RDONLY)  # the writer replaced the file
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _lock(fd: int, blocking: bool) -> bool:
    """An exclusive ``flock`` on ``fd``; False if another process holds one (non-blocking).

    Where ``fcntl`` is missing (not POSIX) or the file system has no locks, nothing is
    locked and False is returned, so that no temporary file is ever taken for stale there.
    """
    try:
        import fcntl
    except ImportError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | (0 if blocking else fcntl.LOCK_NB))
    except OSError:  # held by another process, or no locks on this file system
        return False
    return True


def _remove_stale_temporaries(folder: str) -> None:
    """Remove the unlocked temporary files in ``folder`` (what dead writers left)."""
    import time

    try:
        names = [n for n in os.listdir(folder) if n.startswith(".") and _TEMPORARY.match(n)]
    except OSError:
        return
    for stale in names:
        candidate = os.path.join(folder, stale)
        try:
            info = os.lstat(candidate)
        except OSError:
            continue
        if not stat.S_ISREG(info.st_mode):  # a link, a FIFO, a folder: not ours
            continue
        if ".new-" in stale and time.time() - info.st_mtime < 60:
            continue  # being created right now, about to be locked
        try:
            fd = os.open(candidate, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOFOLLOW", 0))
        except OSError:
            continue
        try:
            opened = os.fstat(fd)
            same = (opened.st_ino, opened.st_dev) == (info.st_ino, info.st_dev)
            if same and stat.S_ISREG(opened.st_mode) and _lock(fd, blocking=False):
                with contextlib.suppress(OSError):
                    os.remove(candidate)
        finally:
            os.close(fd)


def save_mesh(path: str | os.PathLike, V, F) -> None:
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
    writer = _MESH_WRITERS.get(_extension(path))
    if writer is None:
        raise InputError(
            f"cannot write meshes as {_extension(path) or '(no extension)'!r}; "
            f"use one of {', '.join(_MESH_WRITERS)}",
            path,
        )
    V = _valid_vertices(V, path)
    F = _valid_faces(F, len(V), path)
    with atomic_output(path) as tmp:
        writer(tmp, V, F)


def save_points(path: str | os.PathLike, V) -> None:
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
    writer = _POINT_WRITERS.get(_extension(path))
    if writer is None:
        raise InputError(
            f"cannot write point clouds as {_extension(path) or '(no extension)'!r}; "
            f"use one of {', '.join(_POINT_WRITERS)}",
            path,
        )
    V = _valid_vertices(V, path)
    with atomic_output(path) as tmp:
        writer(tmp, V)


def _valid_vertices(V, path) -> np.ndarray:
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


def _valid_faces(F, n_vertices, path) -> np.ndarray:
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
    mesh = trimesh.Trimesh(vertices=V, faces=F, process=False)
    with open(tmp, "wb") as fh:
        fh.write(mesh.export(file_type=_extension(tmp)[1:]))


def _write_xyz(tmp, V):
    with open(tmp, "w", encoding="ascii", newline="\n") as fh:
        if _extension(tmp) == ".pts":
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


# ----------------------------------------------------------------------------- landmarks


def load_landmarks(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Load named 3D landmarks.

    Parameters
    ----------
    path : str or os.PathLike
        A Thea ``.picked`` file (first line: the number of landmarks; then one row
        ``Picked <face> <b0> <b1> <b2> <label> <x> <y> <z> [vertex]`` each, 9 or 10
        whitespace-separated columns), a ``.json`` object ``{label: [x, y, z]}``, or a
        ``.csv`` file of ``label,x,y,z`` rows with an optional ``label,x,y,z`` header.

    Returns
    -------
    dict of str to (3,) float64 ndarray
        Label -> position, in file order.

    Raises
    ------
    LandmarkFileError
        Missing or empty file, unknown extension, wrong column count, a count line that
        does not match, non-numeric or non-finite values, duplicate or empty labels.

    Examples
    --------
    >>> marks = load_landmarks("source.picked")  # doctest: +SKIP
    >>> marks["nose"]  # doctest: +SKIP
    array([0.01, 0.42, 0.13])
    """
    parser = {".picked": _parse_picked, ".json": _parse_json, ".csv": _parse_csv}.get(
        _extension(path)
    )
    if parser is None:
        raise LandmarkFileError(
            f"unknown landmark extension {_extension(path) or '(none)'!r}; "
            f"supported: {', '.join(SUPPORTED_LANDMARK_EXTENSIONS)}",
            path,
        )
    text = _read_text(path, LandmarkFileError)
    try:
        entries = parser(text, path)
    except InputError:
        raise
    except Exception as exc:  # any parser failure is a property of the file
        kind = _extension(path)[1:].upper()
        raise LandmarkFileError(f"cannot be read as {kind}: {_one_line(exc)}", path) from exc
    landmarks: dict[str, np.ndarray] = {}
    for where, label, coords in entries:
        if not label:
            raise LandmarkFileError(f"{where}: empty label", path)
        if label in landmarks:
            raise LandmarkFileError(f"{where}: duplicate label {label!r}", path)
        try:
            xyz = np.array([float(c) for c in coords], dtype=np.float64)
        except (TypeError, ValueError):
            raise LandmarkFileError(
                f"{where}: coordinates of {label!r} are not numbers: {list(coords)}", path
            ) from None
        except OverflowError:  # a JSON integer too large for a float
            raise LandmarkFileError(
                f"{where}: coordinates of {label!r} are not finite (too large for a float)",
                path,
            ) from None
        if not np.isfinite(xyz).all():
            raise LandmarkFileError(f"{where}: coordinates of {label!r} are not finite", path)
        landmarks[label] = xyz
    if not landmarks:
        raise LandmarkFileError("contains no landmarks", path)
    return landmarks


def _parse_picked(text, path):
    rows = [(n, line.split()) for n, line in enumerate(text.splitlines(), 1) if line.strip()]
    if not rows:
        raise LandmarkFileError("is empty", path)
    (first, head), rows = rows[0], rows[1:]
    try:
        (count,) = map(int, head)
    except ValueError:
        raise LandmarkFileError(
            f"line {first}: the first line must be the number of landmarks, got {' '.join(head)!r}",
            path,
        ) from None
    if count != len(rows):
        raise LandmarkFileError(f"the first line says {count} landmarks but {len(rows)} follow",
                                path)
    entries = []
    for number, t in rows:
        if len(t) not in (9, 10):
            raise LandmarkFileError(
                f"line {number}: expected 9 or 10 columns "
                f"(Picked face b0 b1 b2 label x y z [vertex]), found {len(t)}",
                path,
            )
        try:
            for convert, token in zip([int, float, float, float], t[1:5]):
                convert(token)
            if len(t) == 10:
                int(t[9])
        except ValueError:
            raise LandmarkFileError(
                f"line {number}: face, barycentric and vertex columns must be numbers", path
            ) from None
        entries.append((f"line {number}", t[5], t[6:9]))
    return entries


def _csv_rows(reader, path):
    try:
        yield from reader
    except csv.Error as exc:
        raise LandmarkFileError(f"line {reader.line_num}: invalid CSV: {exc}", path) from None


class _Pairs(list):
    """A JSON object as its (key, value) pairs, so duplicate keys can be reported."""


def _parse_json(text, path):
    try:
        data = json.loads(text, object_pairs_hook=_Pairs)
    except json.JSONDecodeError as exc:
        raise LandmarkFileError(f"is not valid JSON: {exc}", path) from None
    if not isinstance(data, _Pairs):
        raise LandmarkFileError('must hold a JSON object {"label": [x, y, z], ...}', path)
    entries = []
    for number, (label, value) in enumerate(data, 1):
        where = f"entry {number}"
        if (
            not isinstance(value, list)
            or len(value) != 3
            or not all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in value)
        ):
            raise LandmarkFileError(
                f"{where}: {label!r} must map to [x, y, z] numbers, got {json.dumps(value)}",
                path,
            )
        entries.append((where, label.strip(), value))
    return entries


def _parse_csv(text, path):
    reader = csv.reader(text.splitlines())
    entries, first = [], True
    for row in _csv_rows(reader, path):
        cells = [c.strip() for c in row]
        if not any(cells) or cells[0].startswith("#"):
            continue
        header, first = first and [c.lower() for c in cells] == ["label", "x", "y", "z"], False
        if header:
            continue
        if len(cells) != 4:
            raise LandmarkFileError(
                f"line {reader.line_num}: expected 4 columns (label,x,y,z), found {len(cells)}",
                path,
            )
        entries.append((f"line {reader.line_num}", cells[0], cells[1:]))
    return entries


def save_landmarks(path: str | os.PathLike, landmarks: Mapping[str, object]) -> None:
    """Write landmarks atomically as JSON or CSV.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ending in ``.json`` (``{label: [x, y, z]}``) or ``.csv`` (header
        ``label,x,y,z``). ``.picked`` is refused: its rows need a face index and barycentric
        coordinates that a label -> position mapping does not carry.
    landmarks : mapping of str to (3,) array_like of float
        Non-empty string labels (no surrounding whitespace) to finite positions; written in
        the mapping's order with ``repr``-exact floats.

    Raises
    ------
    InputError
        Unsupported extension, empty mapping, bad labels or coordinates, or an unwritable
        destination.

    Examples
    --------
    >>> save_landmarks("marks.json", {"nose": [0.0, 0.4, 0.1]})  # doctest: +SKIP
    >>> load_landmarks("marks.json")  # doctest: +SKIP
    {'nose': array([0. , 0.4, 0.1])}
    """
    ext = _extension(path)
    if ext not in (".json", ".csv"):
        why = " (a .picked row needs a face index and barycentric coordinates)"
        raise InputError(
            f"cannot write landmarks as {ext or '(no extension)'!r}"
            f"{why if ext == '.picked' else ''}; use .json or .csv",
            path,
        )
    if not isinstance(landmarks, Mapping):
        raise InputError("landmarks must be a mapping {label: [x, y, z]}", path)
    items = []
    for label, value in landmarks.items():
        if not isinstance(label, str) or not label or label != label.strip():
            raise InputError(
                f"landmark label {label!r} must be a non-empty string without surrounding "
                "spaces",
                path,
            )
        try:
            xyz = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            xyz = np.empty(0)
        if xyz.shape != (3,) or not np.isfinite(xyz).all():
            raise InputError(f"landmark {label!r} must be 3 finite numbers, got {value!r}", path)
        items.append((label, [float(c) for c in xyz]))
    if not items:
        raise InputError("no landmarks to write", path)
    with atomic_output(path) as tmp, open(tmp, "w", encoding="utf-8", newline="") as fh:
        if ext == ".json":
            json.dump(dict(items), fh, indent=2, allow_nan=False)
            fh.write("\n")
        else:
            writer = csv.writer(fh, lineterminator="\n")
            writer.writerow(["label", "x", "y", "z"])
            writer.writerows([label, *map(repr, xyz)] for label, xyz in items)


@dataclass(frozen=True)
class LandmarkMatch:
    """Two landmark sets matched by label (:func:`match_landmarks`).

    Attributes
    ----------
    labels : list of str
        The shared labels, in the first set's order.
    source, target : (L, 3) float64
        Their positions in each set; row ``i`` is ``labels[i]``.
    source_only, target_only : list of str
        Labels found in one set only (reported, never silently dropped).
    """

    labels: list
    source: np.ndarray
    target: np.ndarray
    source_only: list
    target_only: list


def match_landmarks(source: Mapping[str, object], target: Mapping[str, object], *,
                    minimum: int = 4, source_name=None, target_name=None) -> LandmarkMatch:
    """Pair two sets of named landmarks by label.

    Parameters
    ----------
    source, target : mapping of str to (3,) array_like of float
        Label -> position, as :func:`load_landmarks` returns them.
    minimum : int, default 4
        Fewest shared labels accepted.
    source_name, target_name : str or os.PathLike, optional
        The files the sets came from, named in the error.

    Returns
    -------
    LandmarkMatch
        Shared labels in ``source``'s order, and the labels only one set has.

    Raises
    ------
    InputError
        Fewer than ``minimum`` shared labels (the message names both files and the count).

    Examples
    --------
    >>> m = match_landmarks({"a": [0, 0, 0], "b": [1, 0, 0], "c": [0, 1, 0]},
    ...                     {"b": [2, 0, 0], "a": [0, 0, 1], "d": [0, 0, 0]}, minimum=2)
    >>> m.labels, m.source_only, m.target_only, m.target[0].tolist()
    (['a', 'b'], ['c'], ['d'], [0.0, 0.0, 1.0])
    """
    labels = [label for label in source if label in target]
    if len(labels) < minimum:
        names = (f"{source_name or 'the source landmarks'} and "
                 f"{target_name or 'the target landmarks'}")
        raise InputError(f"{names} share {len(labels)} landmark label(s); at least "
                         f"{minimum} are needed")

    def rows(marks):
        return np.array([np.asarray(marks[label], dtype=np.float64) for label in labels])

    return LandmarkMatch(labels=labels, source=rows(source), target=rows(target),
                         source_only=[label for label in source if label not in target],
                         target_only=[label for label in target if label not in source])
