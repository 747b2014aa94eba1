"""0 A.D.'s PMD model files (the meshes of Debian's ``0ad-data``).

PMD is the binary mesh format of the game 0 A.D. (Wildfire Games), documented by its
developers: little-endian; the magic ``PSMD``, a version (1-4) and the size of the rest of
the file; then the vertices (position, normal, ``numTexCoords`` UV pairs, four bone indices
and weights), triangles of ``u16`` vertex indices, the bones' rest states (translation,
quaternion ``x, y, z, w``) and, from version 2, named prop points. Version 4 adds
``numTexCoords`` (1 before). Versions 3 and 4 store positions in world space; version 2
stored skinned positions relative to their bone's rest state, which :func:`read_pmd` refuses
(no such file ships with the game today: ``0ad-data`` 0.0.26 holds 4,010 files, all version
4). Positions are float32 in the file and come back as float64, exactly.

:func:`cagekit.io.load_mesh` reads ``.pmd`` files through :func:`read_pmd` (vertices and
triangles); cagekit writes no PMD.
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass

import numpy as np

from cagekit.errors import MeshFileError
from cagekit.io.files import read_bytes

__all__ = ["PmdModel", "PmdPropPoint", "read_pmd"]

_MAGIC = b"PSMD"
_NO_BONE = 0xFF


@dataclass(frozen=True)
class PmdPropPoint:
    """A named point where the game attaches another model.

    Attributes
    ----------
    name : str
    translation : (3,) float64 ndarray
    rotation : (4,) float64 ndarray
        A quaternion ``x, y, z, w``.
    bone : int
        Its bone, 255 for none.
    """

    name: str
    translation: np.ndarray
    rotation: np.ndarray
    bone: int


@dataclass(frozen=True)
class PmdModel:
    """What a PMD file holds.

    Attributes
    ----------
    version : int
        1 to 4.
    vertices : (n, 3) float64 ndarray
        Positions, in file order (world space, the rest pose).
    faces : (m, 3) int64 ndarray
        Triangles indexing ``vertices``.
    normals : (n, 3) float64 ndarray
    uv : (n, k, 2) float64 ndarray
        ``k`` texture coordinate pairs per vertex (1 before version 4).
    bones : (n, 4) int64 ndarray
        Bone indices per vertex, 255 where unused.
    weights : (n, 4) float64 ndarray
        Their weights (0 where unused).
    rest_translation : (b, 3) float64 ndarray
        Each bone's rest state: translation ...
    rest_rotation : (b, 4) float64 ndarray
        ... and rotation, a quaternion ``x, y, z, w``.
    prop_points : tuple of PmdPropPoint
    """

    version: int
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    uv: np.ndarray
    bones: np.ndarray
    weights: np.ndarray
    rest_translation: np.ndarray
    rest_rotation: np.ndarray
    prop_points: tuple[PmdPropPoint, ...]


def read_pmd(path: str | os.PathLike) -> PmdModel:
    """Read a PMD file (0 A.D.'s mesh format, versions 1, 3 and 4; 2 without bones).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    PmdModel

    Raises
    ------
    MeshFileError
        Naming the file: missing, empty, not PMD (magic, version), truncated or longer
        than its header says, a face index out of range, a non-finite value (position,
        normal, texture coordinate, bone weight, rest state, prop point), a bone index
        beyond the file's bones, a negative bone weight, or a skinned version-2 file.

    Examples
    --------
    >>> import struct, tempfile, os
    >>> body = struct.pack("<II", 3, 1) + b"".join(            # 3 vertices, 1 UV set
    ...     struct.pack("<8f4B4f", *p, 0, 0, 1, 0, 0, 255, 255, 255, 255, 0, 0, 0, 0)
    ...     for p in [(0, 0, 0), (1, 0, 0), (0, 1, 0)])
    >>> body += struct.pack("<I3H", 1, 0, 1, 2) + struct.pack("<II", 0, 0)
    >>> path = os.path.join(tempfile.mkdtemp(), "tri.pmd")
    >>> with open(path, "wb") as fh:
    ...     _ = fh.write(b"PSMD" + struct.pack("<II", 4, len(body)) + body)
    >>> model = read_pmd(path)
    >>> model.vertices.shape, model.faces.tolist(), model.uv.shape
    ((3, 3), [[0, 1, 2]], (3, 1, 2))
    """
    data = read_bytes(path, MeshFileError)
    try:
        return _parse(data, path)
    except struct.error:
        raise MeshFileError("is truncated: it ends inside a PMD record", path) from None


def _parse(data: bytes, path) -> PmdModel:
    if data[:4] != _MAGIC:
        raise MeshFileError(f"is not a PMD file: it starts {data[:4]!r}, not {_MAGIC!r}", path)
    version, size = struct.unpack_from("<II", data, 4)
    if version not in (1, 2, 3, 4):
        raise MeshFileError(f"has PMD version {version}; versions 1 to 4 are known", path)
    if size != len(data) - 12:
        raise MeshFileError(f"says {size} bytes follow its header, but {len(data) - 12} "
                            "do (truncated or padded)", path)
    reader = _Reader(data, 12)
    n = reader.u32()
    k = reader.u32() if version >= 4 else 1
    if (44 + 8 * k) * n > len(data):  # each vertex takes 44 + 8 k bytes
        raise MeshFileError(f"says it has {n} vertices of {k} UV set(s) each, more than "
                            f"its {len(data)} bytes hold", path)
    record = np.dtype([("position", "<f4", 3), ("normal", "<f4", 3), ("uv", "<f4", (k, 2)),
                       ("bones", "u1", 4), ("weights", "<f4", 4)])
    vertices = reader.array(record, n)
    faces = reader.array(np.dtype("<u2"), 3 * reader.u32()).reshape(-1, 3).astype(np.int64)
    bone_count = reader.u32()
    rest = reader.array(np.dtype("<f4"), 7 * bone_count).reshape(-1, 7).astype(np.float64)
    props = tuple(reader.prop_point() for _ in range(reader.u32())) if version >= 2 else ()
    if reader.pos != len(data):
        raise MeshFileError(f"has {len(data) - reader.pos} bytes after its last PMD record",
                            path)
    V = vertices["position"].astype(np.float64)
    _check_geometry(V, faces, path)
    bones = vertices["bones"].astype(np.int64)
    weights = vertices["weights"].astype(np.float64)
    _check_skin(bones, weights, bone_count, path)
    if version == 2 and bone_count and (bones != _NO_BONE).any():
        raise MeshFileError("is a skinned PMD of version 2 (positions relative to their "
                            "bones); versions 3 and 4 are read", path)
    normals, uv = vertices["normal"].astype(np.float64), vertices["uv"].astype(np.float64)
    props_array = np.array([np.r_[p.translation, p.rotation] for p in props]).reshape(-1, 7)
    for what, values in (("normal of vertex", normals),
                         ("texture coordinates of vertex", uv.reshape(n, 2 * k)),
                         ("rest state of bone", rest), ("prop point", props_array)):
        _check_finite(what, values, path)
    return PmdModel(version=version, vertices=V, faces=faces, normals=normals, uv=uv,
                    bones=bones, weights=weights, rest_translation=rest[:, :3],
                    rest_rotation=rest[:, 3:], prop_points=props)


def _check_geometry(V: np.ndarray, F: np.ndarray, path) -> None:
    _check_finite("vertex", V, path)
    if len(F) and F.max() >= len(V):
        i = int(np.argmax((F >= len(V)).any(axis=1)))
        raise MeshFileError(f"face {i} (0-based) refers to vertices {F[i].tolist()}; "
                            f"there are {len(V)} vertices", path)


def _check_finite(what: str, values: np.ndarray, path) -> None:
    """A one-line error naming the first row of ``values`` holding NaN or inf."""
    bad = ~np.isfinite(values).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise MeshFileError(f"{what} {i} (0-based) is not finite: {values[i].tolist()}", path)


def _check_skin(bones: np.ndarray, weights: np.ndarray, bone_count: int, path) -> None:
    """Bone indices within the file's bones (or 255: none; the bone count itself is the
    format's bind-shape bone) and finite, non-negative weights."""
    _check_finite("bone weight of vertex", weights, path)
    bad = ((bones > bone_count) & (bones != _NO_BONE)).any(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise MeshFileError(f"vertex {i} (0-based) names bones {bones[i].tolist()}; the "
                            f"file has {bone_count}", path)
    bad = (weights < 0).any(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise MeshFileError(f"vertex {i} (0-based) has a negative bone weight: "
                            f"{weights[i].tolist()}", path)


class _Reader:
    """Little-endian records read in order from ``data`` (struct.error past its end)."""

    def __init__(self, data: bytes, pos: int):
        self.data, self.pos = data, pos

    def u32(self) -> int:
        (value,) = struct.unpack_from("<I", self.data, self.pos)
        self.pos += 4
        return int(value)

    def array(self, dtype: np.dtype, count: int) -> np.ndarray:
        end = self.pos + dtype.itemsize * count
        if end > len(self.data):
            raise struct.error("past the end")
        out = np.frombuffer(self.data, dtype=dtype, count=count, offset=self.pos)
        self.pos = end
        return out

    def prop_point(self) -> PmdPropPoint:
        length = self.u32()
        name = self.data[self.pos:self.pos + length]
        if len(name) < length:
            raise struct.error("past the end")
        self.pos += length
        values = self.array(np.dtype("<f4"), 7).astype(np.float64)
        bone = self.array(np.dtype("u1"), 1)
        return PmdPropPoint(name=name.decode("ascii", "replace"), translation=values[:3],
                            rotation=values[3:], bone=int(bone[0]))
