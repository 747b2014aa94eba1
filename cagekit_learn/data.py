"""Training data of the learned mode: normalised point samples of shape collections.

A :class:`ShapeCollection` holds ``P`` surface samples of each of ``N`` shapes, each
normalised on its own into the unit frame (:meth:`cagekit.Frame.of`). It comes from a
folder of meshes (:meth:`ShapeCollection.from_folder`, cached incrementally by a
:class:`SampleCache` keyed on each file's path, size and ``mtime_ns``), from the procedural
families (:meth:`ShapeCollection.synthetic`), from shapes in correspondence
(:meth:`ShapeCollection.corresponding`) or from arrays. Each epoch draws (source, target)
pairs (:func:`epoch_pairs`, or :func:`fixed_source_pairs` with a fixed source,
:class:`FixedSource`), splits them between ranks (:func:`shard`) and turns them into
tensors with the paper's anisotropic-scaling augmentation (:func:`make_batch`; a fixed
source is never augmented). Every random draw is seeded through
``numpy.random.SeedSequence`` with a tag per use, and a shape's samples depend only on
``(seed, name)``, so adding a file changes no other shape's samples. torch is imported by
:func:`make_batch` alone. See docs/architecture.md.

Examples
--------
>>> shapes = ShapeCollection.synthetic("vases", n=4, points=256, resolution=0.5)
>>> shapes.points.shape, shapes.names[1]
((4, 256, 3), 'vases/0001')
"""

from __future__ import annotations

import json
import os
import pathlib
import secrets
import warnings
import zlib
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from cagekit.datasets import synthetic as _synthetic
from cagekit.errors import CagekitWarning, InputError
from cagekit.geometry import as_count, as_faces, as_vertices
from cagekit.geometry.frame import Frame
from cagekit.geometry.parts import vertex_parts
from cagekit.geometry.sampling import sample_surface
from cagekit.io import SUPPORTED_MESH_EXTENSIONS, load_shape
from cagekit.io.files import atomic_output
from cagekit.metrics import MIN_PART_VERTICES
from cagekit.progress import progress_bar
from cagekit.typed import Ints

if TYPE_CHECKING:
    import torch

__all__ = [
    "CACHE_DIRNAME",
    "CACHE_FORMAT",
    "FIXED_SOURCE",
    "MESH_EXTENSIONS",
    "SampleCache",
    "FixedSource",
    "ShapeCollection",
    "augment",
    "corresponding_rows",
    "epoch_pairs",
    "find_meshes",
    "fixed_source_pairs",
    "make_batch",
    "sample_parts",
    "shard",
]

MESH_EXTENSIONS = SUPPORTED_MESH_EXTENSIONS
"""Extensions :func:`find_meshes` collects, case-insensitive (as :func:`cagekit.io.load_mesh`)."""

CACHE_DIRNAME = ".cagekit-cache"
"""Name of the default cache folder, inside the collection's root."""

CACHE_FORMAT = 3
"""Version of the cache layout; a cache of another version is rebuilt (2: the samples'
part labels, :attr:`ShapeCollection.parts`, are cached with them; 3: parts join pieces
split at seams, :func:`cagekit.geometry.parts.vertex_parts`)."""

_SAMPLES_FILE = "samples.npz"
_MANIFEST_FILE = "manifest.json"

# A leading tag per use of randomness: no two uses share a stream (NumPy treats trailing zero
# words of a seed as absent, so [1, 2] and [1, 2, 0] would give the same stream)
_TAG_SAMPLES = 0x5A3D1E01
_TAG_PAIRS = 0x5A3D1E02
_TAG_AUGMENT = 0x5A3D1E03
_TAG_CORRESPONDING = 0x5A3D1E05
_TAG_FIXED_PAIRS = 0x5A3D1E06
_TAG_AUGMENT_TARGET = 0x5A3D1E07

FIXED_SOURCE = -1
"""Source index of a pair whose source is the fixed source (:func:`fixed_source_pairs`)."""


# ------------------------------------------------------------------------------ helpers


def _shape_seed(seed: int, name: str) -> int:
    """Sampling seed of one shape: a function of ``(seed, name)`` only."""
    state = np.random.SeedSequence([_TAG_SAMPLES, seed, zlib.crc32(name.encode("utf-8"))])
    return int(state.generate_state(1, dtype=np.uint64)[0])


def _sample_shape(V, F, points: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Normalise ``V`` and draw ``points`` samples: (points, 3) float32 and their part
    labels (points,) int32 (:func:`sample_parts`; all -1 for a point cloud).

    Raises InputError for shapes that cannot be normalised or sampled (zero extent, zero
    area).
    """
    Vn, F = Frame.of(V).to_unit(V), as_faces(F, len(V))
    if not len(F):  # a point cloud: no faces, no parts
        P = sample_surface(Vn, F, points, seed=seed, fill=True)
        return np.ascontiguousarray(P, dtype=np.float32), np.full(len(P), -1, np.int32)
    P, faces = sample_surface(Vn, F, points, seed=seed, fill=True, return_faces=True)
    return np.ascontiguousarray(P, dtype=np.float32), sample_parts(V, F, faces)


def sample_parts(V: ArrayLike, F: ArrayLike, faces: ArrayLike,
                 min_vertices: int = MIN_PART_VERTICES) -> np.ndarray:
    """The part of each surface sample: the part of the face it lies on.

    Parts are as ``cagekit deform``'s part-affinity term takes them
    (:func:`cagekit.geometry.parts.vertex_parts`: connected components, faces that share
    an edge by position joined across seams) of at least ``min_vertices`` vertices.

    Parameters
    ----------
    V : (v, 3) array_like of float
        The mesh's vertices.
    F : (m, 3) array_like of int
        Its triangles.
    faces : (n,) array_like of int
        Index into ``F`` of each sample's face (``sample_surface(..., return_faces=True)``).
    min_vertices : int, default :data:`cagekit.metrics.MIN_PART_VERTICES`
        Smaller components are no part.

    Returns
    -------
    (n,) int32 ndarray
        The component label of each sample's face, or -1 on a component of fewer than
        ``min_vertices`` vertices.

    Examples
    --------
    >>> V = np.arange(21.0).reshape(7, 3)
    >>> F = [[0, 1, 2], [3, 4, 5], [4, 5, 6]]  # a triangle, then two triangles
    >>> sample_parts(V, F, [0, 1, 2, 0], min_vertices=4).tolist()
    [-1, 1, 1, -1]
    """
    V = as_vertices(V, "V")
    F = as_faces(F, len(V))
    corners = F[np.asarray(faces, dtype=np.int64), 0]  # a face's vertices share its part
    return _vertex_parts(V, F, int(min_vertices))[corners]


def _vertex_parts(V, F, min_vertices: int = MIN_PART_VERTICES) -> np.ndarray:
    """The part of each vertex, (v,) int32: its part (:func:`vertex_parts`) when that has
    at least ``min_vertices`` vertices, else -1 (also on no face, and for a point cloud)."""
    F = as_faces(F, len(V))
    if not len(F):
        return np.full(len(V), -1, dtype=np.int32)
    labels = vertex_parts(V, F)
    sizes = np.bincount(labels[labels >= 0])
    big = (labels >= 0) & (sizes[np.maximum(labels, 0)] >= min_vertices)
    return np.where(big, labels, -1).astype(np.int32)


def _as_parts(parts, shape) -> np.ndarray:
    """Part labels as an (N, P) int32 array (-1 everywhere when None); InputError when
    they are not integers of that shape."""
    if parts is None:
        return np.full(shape, -1, dtype=np.int32)
    parts = np.asarray(parts)
    if parts.shape != tuple(shape) or not np.issubdtype(parts.dtype, np.integer):
        raise InputError(f"part labels must be an integer array of shape {tuple(shape)}, "
                         f"got {parts.dtype} {parts.shape}")
    return np.ascontiguousarray(parts, dtype=np.int32)


def _is_hidden(name: str) -> bool:
    return name.startswith(".")


# --------------------------------------------------------------------------- discovery


def find_meshes(root: str | os.PathLike) -> list[pathlib.Path]:
    """Mesh files under a folder, recursively, in a stable order.

    Parameters
    ----------
    root : str or os.PathLike
        A folder. Any layout works, ShapeNet's ``<synset>/<id>/model.obj`` and
        ``<synset>/<id>/models/model_normalized.obj`` included.

    Returns
    -------
    paths : list of pathlib.Path
        ``root / relative`` for every regular file (or link to one) whose extension is in
        :data:`MESH_EXTENSIONS` (case-insensitive), sorted by the relative path in POSIX
        form. Hidden files and folders below ``root`` (names starting with ``.``, such as
        the cache folder ``.cagekit-cache`` and temporary files of atomic writes) are
        skipped. Links to folders are followed, each real folder once.

    Raises
    ------
    InputError
        ``root`` does not exist or is not a folder.

    Examples
    --------
    >>> find_meshes("ShapeNetCore.v1/03001627")[:1]  # doctest: +SKIP
    [PosixPath('ShapeNetCore.v1/03001627/1006be65e7bc937e9141f9b58470d646/model.obj')]
    """
    base = pathlib.Path(root)
    if not base.is_dir():
        what = "does not exist" if not base.exists() else "is not a folder"
        raise InputError(f"{what}; a folder of meshes is required", base)
    found: list[tuple[str, pathlib.Path]] = []
    seen: set[str] = set()
    for folder, dirs, files in os.walk(base, followlinks=True):
        real = os.path.realpath(folder)
        if real in seen:  # a link loop or a folder reached twice
            dirs[:] = []
            continue
        seen.add(real)
        dirs[:] = [d for d in dirs if not _is_hidden(d)]
        for name in files:
            if _is_hidden(name) or os.path.splitext(name)[1].lower() not in MESH_EXTENSIONS:
                continue
            path = pathlib.Path(folder, name)
            if path.is_file():
                found.append((path.relative_to(base).as_posix(), path))
    found.sort(key=lambda item: item[0])
    return [path for _, path in found]


# -------------------------------------------------------------------------- collection


class ShapeCollection:
    """Normalised point samples of a collection of shapes.

    Build one with :meth:`from_folder`, :meth:`synthetic` or :meth:`from_arrays`.

    Attributes
    ----------
    names : list of str
        One per shape: its path relative to the folder in POSIX form, or a synthetic name
        such as ``"chairs/0007"``.
    points : (N, P, 3) float32 ndarray
        ``P`` samples of each shape, uniform by area on the surface of the shape normalised
        on its own (bounding-box centre at the origin, largest half-extent 1), so every
        point lies in ``[-1, 1]^3``.
    parts : (N, P) int32 ndarray
        The part of each sample (:func:`sample_parts`: the part of the face it was drawn
        from, :func:`cagekit.geometry.parts.vertex_parts`; in correspondence, of its
        vertex), for the part-affinity training term; -1 on no part: a part of fewer than
        :data:`cagekit.metrics.MIN_PART_VERTICES` vertices, a point cloud, samples given
        without labels.
    rows : (P,) int64 ndarray or None
        For a collection in correspondence (:meth:`corresponding`): the vertex rows every
        shape's samples were taken from; None otherwise.
    vertex_count : int or None
        For a collection in correspondence: the vertex count all its meshes share.

    Examples
    --------
    >>> c = ShapeCollection.from_arrays(["a", "b"], np.zeros((2, 8, 3)))
    >>> len(c), c.points.dtype
    (2, dtype('float32'))
    """

    def __init__(self, names: Iterable[str], points: ArrayLike, parts: ArrayLike | None = None):
        names = [str(n) for n in names]
        points = np.asarray(points)
        if points.ndim != 3 or points.shape[2] != 3:
            raise InputError(f"points must have shape (N, P, 3), got {points.shape}")
        if not np.issubdtype(points.dtype, np.number) or np.iscomplexobj(points):
            raise InputError(f"points must be real numbers, got dtype {points.dtype}")
        points = np.ascontiguousarray(points, dtype=np.float32)
        if len(names) != len(points):
            raise InputError(f"{len(names)} names for {len(points)} shapes")
        if len(set(names)) != len(names):
            raise InputError("names must be unique")
        if not np.isfinite(points).all():
            raise InputError("points must be finite (no NaN or infinity)")
        self.names: list[str] = names
        self.points: np.ndarray = points
        self.parts: np.ndarray = _as_parts(parts, points.shape[:2])
        self.rows: np.ndarray | None = None
        self.vertex_count: int | None = None

    def __len__(self) -> int:
        return len(self.names)

    def __repr__(self) -> str:
        n, p = self.points.shape[:2]
        return f"ShapeCollection({n} shapes x {p} points)"

    # ------------------------------------------------------------------ constructors

    @classmethod
    def from_arrays(cls, names: Iterable[str], points: ArrayLike,
                    parts: ArrayLike | None = None) -> ShapeCollection:
        """A collection from given names and point samples (copied, as float32).

        Parameters
        ----------
        names : sequence of str
            ``N`` unique names.
        points : (N, P, 3) array_like of float
            Finite samples, assumed already normalised.
        parts : (N, P) array_like of int, optional
            Each sample's part label (:attr:`parts`); default -1 everywhere (no parts).

        Returns
        -------
        ShapeCollection

        Raises
        ------
        InputError
            Wrong shape, non-finite values, a name count that differs from ``N``,
            duplicate names, or part labels of another shape than ``(N, P)``.

        Examples
        --------
        >>> ShapeCollection.from_arrays(["a", "b", "c"], np.zeros((3, 16, 3))).points.shape
        (3, 16, 3)
        """
        return cls(list(names), np.array(points, dtype=np.float32, copy=True),
                   None if parts is None else np.array(parts, copy=True))

    @classmethod
    def corresponding(cls, root: str | os.PathLike, points: int = 1024,
                      seed: int = 0) -> ShapeCollection:
        """Samples in correspondence, for the L2 alignment loss (``--align l2``).

        Every mesh under ``root`` must have the same vertex count (a collection with
        consistent vertex order: poses of one character, morphs of one template). Each
        is normalised on its own and the *same* seeded vertex indices are taken from
        all, so point ``i`` of one shape corresponds to point ``i`` of every other
        (vertices are drawn with replacement when there are fewer than ``points``).
        Nothing is cached: reading vertices is cheap next to sampling surfaces.

        Parameters
        ----------
        root : str or os.PathLike
        points : int, default 1024
        seed : int, default 0

        Returns
        -------
        ShapeCollection

        Raises
        ------
        InputError
            No meshes, fewer than two, or vertex counts that differ (naming the file).
        """
        root = pathlib.Path(root)
        paths = find_meshes(root)
        if len(paths) < 2:
            raise InputError(f"{root}: needs at least two meshes in correspondence, found "
                             f"{len(paths)}")
        meshes = [load_shape(path) for path in paths]
        shapes = [V for V, _ in meshes]
        n = len(shapes[0])
        for path, V in zip(paths, shapes):
            if len(V) != n:
                raise InputError(f"{path}: {len(V)} vertices, but {paths[0].name} has {n}: "
                                 "shapes in correspondence share one vertex order")
        rows = corresponding_rows(n, points, seed)
        names = [path.relative_to(root).as_posix() for path in paths]
        collection = cls(names, np.stack([Frame.of(V).to_unit(V)[rows] for V in shapes]
                                         ).astype(np.float32),
                         np.stack([_vertex_parts(V, F)[rows] for V, F in meshes]))
        collection.rows, collection.vertex_count = rows, n
        return collection

    @classmethod
    def synthetic(cls, family: str = "chairs", n: int = 32, seed: int = 0, points: int = 1024,
                  resolution: float = 1.0) -> ShapeCollection:
        """Built-in data: shapes of a procedural family, normalised and sampled.

        Parameters
        ----------
        family : {"chairs", "tables", "vases"}
            A family of :mod:`cagekit.datasets.synthetic`.
        n : int, default 32
            Number of shapes; shape ``i`` is the family's shape of seed ``seed + i``.
        seed : int, default 0
            Seed of the first shape and of the sampling (>= 0).
        points : int, default 1024
            Samples per shape (>= 1).
        resolution : float, default 1.0
            Mesh resolution passed to the family (about ``4500 * resolution**2`` vertices).

        Returns
        -------
        ShapeCollection
            Names ``f"{family}/{i:04d}"``; samples drawn as in :meth:`from_folder`.

        Raises
        ------
        InputError
            Unknown family or bad counts.

        Examples
        --------
        >>> c = ShapeCollection.synthetic("vases", n=2, points=64, resolution=0.5)
        >>> c.names, c.points.shape
        (['vases/0000', 'vases/0001'], (2, 64, 3))
        """
        if family not in _synthetic.FAMILIES:
            raise InputError(f"unknown family {family!r}; available: "
                             f"{', '.join(_synthetic.FAMILIES)}")
        n = as_count(n, "n")
        seed = as_count(seed, "seed")
        points = as_count(points, "points", 1)
        names, samples, parts = [], [], []
        for i, (V, F) in enumerate(_synthetic.family(family, n, seed=seed,
                                                     resolution=resolution)):
            name = f"{family}/{i:04d}"
            names.append(name)
            P, labels = _sample_shape(V, F, points, _shape_seed(seed, name))
            samples.append(P)
            parts.append(labels)
        stack = np.stack(samples) if samples else np.empty((0, points, 3), np.float32)
        return cls(names, stack, np.stack(parts) if parts else None)

    @classmethod
    def from_folder(cls, root: str | os.PathLike, points: int = 1024, seed: int = 0,
                    cache_dir: str | os.PathLike | Literal[False] | None = None,
                    progress: bool = False) -> ShapeCollection:
        """Every mesh under a folder, normalised and sampled, with an incremental cache.

        Parameters
        ----------
        root : str or os.PathLike
            A folder of meshes in any layout (see :func:`find_meshes`), ShapeNet's
            included.
        points : int, default 1024
            Samples per shape (>= 1).
        seed : int, default 0
            Sampling seed (>= 0). A shape's samples depend only on ``(seed, name)``.
        cache_dir : str or os.PathLike or False, optional
            Where ``samples.npz`` and ``manifest.json`` are kept. Default
            ``<root>/.cagekit-cache``; when that cannot be written the collection is
            built without a cache and a warning says so. A folder given here is created
            if needed and must be writable. ``False`` turns the cache off.
        progress : bool, default False
            Show a tqdm progress bar over the files being sampled.

        Returns
        -------
        ShapeCollection
            Shapes in :func:`find_meshes` order, named by their relative POSIX paths; files
            that could not be used are left out.

        Raises
        ------
        InputError
            ``root`` is not a folder, holds no mesh file, or fewer than 2 shapes could be
            used; ``cache_dir`` was given and cannot be written.

        Warns
        -----
        cagekit.errors.CagekitWarning
            For each file skipped (naming the file and the problem; files a cache
            remembers as broken are warned about again without being read), and when the
            default cache cannot be written.

        Notes
        -----
        The manifest holds the format version, ``points``, ``seed``, and for each used
        file its ``name``, ``size`` (bytes) and ``mtime_ns``; skipped files are listed
        under ``"skipped"`` with their ``problem``. On the next call a file with the same
        name, size and ``mtime_ns`` is taken from the cache without being read; changed or
        new files are (re)sampled and removed ones dropped. Another ``points`` or
        ``seed`` resamples everything.

        Examples
        --------
        >>> c = ShapeCollection.from_folder("ShapeNetCore.v2/03001627")  # doctest: +SKIP
        >>> c.names[0]  # doctest: +SKIP
        '1006be65e7bc937e9141f9b58470d646/models/model_normalized.obj'
        """
        points = as_count(points, "points", 1)
        seed = as_count(seed, "seed")
        base = pathlib.Path(root)
        paths = find_meshes(base)
        if not paths:
            raise InputError("holds no mesh file (looked for "
                             f"{', '.join(MESH_EXTENSIONS)}, hidden folders skipped)", base)
        cache = SampleCache.for_folder(base, cache_dir)
        old = cache.read(points, seed) if cache is not None else None
        entries, skipped, todo = _scan(base, paths, old)
        failed = _sample_new(entries, skipped, todo, points, seed, progress)
        entries = [e for i, e in enumerate(entries) if i not in failed]
        skipped.sort(key=lambda s: s["name"])
        names = [e[0] for e in entries]
        stack = (np.stack([e[3] for e in entries]) if entries
                 else np.empty((0, points, 3), np.float32))
        parts = (np.stack([e[4] for e in entries]) if entries
                 else np.empty((0, points), np.int32))
        if cache is not None:
            manifest = {
                "format": CACHE_FORMAT,
                "points": points,
                "seed": seed,
                "files": [{"name": e[0], "size": e[1], "mtime_ns": e[2]} for e in entries],
                "skipped": skipped,
            }
            if old is None or old["manifest"] != manifest:
                cache.write(manifest, names, stack, parts)
        if len(entries) < 2:
            raise InputError(f"only {len(entries)} usable shape(s) of {len(paths)} mesh "
                             "file(s); at least 2 are needed to make pairs", base)
        return cls(names, stack, parts)


# ------------------------------------------------------------------------ correspondence


def corresponding_rows(n_vertices: int, points: int, seed: int = 0) -> np.ndarray:
    """The seeded vertex rows sampled from shapes in correspondence.

    Parameters
    ----------
    n_vertices : int
        The vertex count the shapes share (>= 1).
    points : int
        Number of rows (>= 1).
    seed : int, default 0

    Returns
    -------
    rows : (points,) int64 ndarray
        Sorted distinct rows when ``n_vertices >= points``, else drawn with replacement.
        Deterministic in ``(n_vertices, points, seed)``: :meth:`ShapeCollection.corresponding`
        and :meth:`FixedSource.from_file` take the same rows.

    Examples
    --------
    >>> corresponding_rows(10, 4, seed=1).shape
    (4,)
    """
    n = as_count(n_vertices, "n_vertices", 1)
    points = as_count(points, "points", 1)
    rng = np.random.default_rng([_TAG_CORRESPONDING, as_count(seed, "seed")])
    rows = (np.sort(rng.choice(n, size=points, replace=False)) if n >= points
            else rng.integers(0, n, size=points))
    return rows.astype(np.int64)


class FixedSource:
    """The one source shape of every training pair (a template character in rest pose).

    Build it with :meth:`from_file`.

    Attributes
    ----------
    path : str
        The template's file.
    points : (P, 3) float32 ndarray
        Its samples in its normalised frame (bounding-box centre at the origin, largest
        half-extent 1): the vertex rows :attr:`rows` with ``corresponding=True``, else
        ``P`` samples uniform by area on its surface (as any shape of
        :meth:`ShapeCollection.from_folder`).
    rows : (P,) int64 ndarray or None
        The vertex rows of :attr:`points` (``corresponding=True``), else None.
    vertex_count : int
        Vertex count of the template.
    center : (3,) float64 ndarray
    scale : float
        Its normalisation: ``normalised = (V - center) / scale``.
    """

    def __init__(self, path: str | os.PathLike, points: ArrayLike, rows: ArrayLike | None,
                 vertex_count: int, center: ArrayLike, scale: float):
        self.path = str(path)
        self.points = np.ascontiguousarray(points, dtype=np.float32)
        self.rows = None if rows is None else np.asarray(rows, dtype=np.int64)
        self.vertex_count = int(vertex_count)
        self.center = np.asarray(center, dtype=np.float64)
        self.scale = float(scale)

    def __repr__(self) -> str:
        return f"FixedSource({self.path!r}, {len(self.points)} points)"

    @classmethod
    def from_file(cls, path: str | os.PathLike, points: int = 1024, seed: int = 0,
                  corresponding: bool = False, vertex_count: int | None = None) -> FixedSource:
        """Read and sample a template mesh.

        Parameters
        ----------
        path : str or os.PathLike
            A mesh file (or a point cloud when not ``corresponding``).
        points : int, default 1024
            Samples (>= 1).
        seed : int, default 0
            Seed of the samples, as the collection's.
        corresponding : bool, default False
            Take the vertex rows :func:`corresponding_rows` of the template (for the L2
            alignment with a collection in correspondence: point ``i`` of the template is
            then point ``i`` of every shape), instead of surface samples.
        vertex_count : int, optional
            With ``corresponding``: the collection's vertex count, which the template must
            share.

        Returns
        -------
        FixedSource

        Raises
        ------
        InputError
            An unreadable or degenerate file, or (``corresponding``) a vertex count that
            differs from ``vertex_count``; the message names the file.
        """
        points = as_count(points, "points", 1)
        seed = as_count(seed, "seed")
        path = pathlib.Path(path)
        V, F = load_shape(path)
        try:
            frame = Frame.of(V)
            Vn, center, scale = frame.to_unit(V), frame.centre, frame.scale
        except InputError as exc:
            raise InputError(exc.problem, path) from None
        if corresponding:
            if vertex_count is not None and len(V) != int(vertex_count):
                raise InputError(f"{len(V)} vertices, but the training shapes have "
                                 f"{int(vertex_count)}: with the L2 alignment the fixed "
                                 "source shares their vertex order", path)
            rows = corresponding_rows(len(V), points, seed)
            samples = Vn[rows]
        else:
            rows = None
            try:
                samples = _sample_shape(V, F, points, _shape_seed(seed, path.name))[0]
            except InputError as exc:
                raise InputError(exc.problem, path) from None
        return cls(path, samples, rows, len(V), center, scale)


def _scan(base, paths, old):
    """What :meth:`ShapeCollection.from_folder` takes from the cache and what it samples.

    Returns ``(entries, skipped, todo)``: ``[name, size, mtime_ns, samples or None, parts
    or None]`` per usable file, the skipped files' records, and ``(entry index, path)`` to sample.
    """
    old_files = old["files"] if old else {}
    old_skipped = old["skipped"] if old else {}
    entries, skipped, todo = [], [], []
    for path in paths:
        name = path.relative_to(base).as_posix()
        try:
            st = path.stat()
        except OSError as exc:
            problem = f"cannot read: {exc.strerror or exc}"
            warnings.warn(CagekitWarning(f"skipping {path}: {problem}"), stacklevel=3)
            skipped.append({"name": name, "size": -1, "mtime_ns": -1, "problem": problem})
            continue
        key = (st.st_size, st.st_mtime_ns)
        if name in old_files and old_files[name][0] == key:
            entries.append([name, *key, *old_files[name][1:]])
        elif name in old_skipped and old_skipped[name][0] == key:
            problem = old_skipped[name][1]
            warnings.warn(CagekitWarning(f"skipping {path}: {problem} (remembered by the "
                                         "cache)"), stacklevel=3)
            skipped.append({"name": name, "size": key[0], "mtime_ns": key[1],
                            "problem": problem})
        else:
            todo.append((len(entries), path))
            entries.append([name, *key, None, None])
    return entries, skipped, todo


def _sample_new(entries, skipped, todo, points, seed, progress) -> set:
    """Read and sample the files of ``todo`` into ``entries``; the indices that failed."""
    failed = set()
    with progress_bar("sampling shapes", "shape", total=len(todo),
                      enabled=bool(progress and todo), leave=True) as bar:
        for index, path in todo:
            name = entries[index][0]
            try:
                V, F = load_shape(path)
                entries[index][3:5] = _sample_shape(V, F, points, _shape_seed(seed, name))
            except InputError as exc:
                warnings.warn(CagekitWarning(f"skipping {path}: {exc.problem}"), stacklevel=3)
                skipped.append({"name": name, "size": entries[index][1],
                                "mtime_ns": entries[index][2], "problem": exc.problem})
                failed.add(index)
            bar.update(1)
    return failed


# ------------------------------------------------------------------------------- cache


class SampleCache:
    """The samples of a folder's shapes, kept between runs (``samples.npz`` and
    ``manifest.json``, written atomically; see :meth:`ShapeCollection.from_folder`).

    Parameters
    ----------
    folder : pathlib.Path
    explicit : bool
        The user chose the folder: a failure to write it is an error, not a warning.
    """

    def __init__(self, folder: pathlib.Path, explicit: bool):
        self.folder, self.explicit = folder, explicit

    @classmethod
    def for_folder(cls, root: pathlib.Path,
                   cache_dir: str | os.PathLike | Literal[False] | None) -> SampleCache | None:
        """The cache of ``root`` (``cache_dir`` as ``from_folder`` takes it), or None."""
        if cache_dir is False:
            return None
        if cache_dir is None:
            return cls(root / CACHE_DIRNAME, explicit=False)
        folder = pathlib.Path(cache_dir)
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"cannot create the cache folder: {exc.strerror or exc}",
                             folder) from None
        if not os.access(folder, os.W_OK | os.X_OK):
            raise InputError("cache folder is not writable", folder)
        return cls(folder, explicit=True)

    def read(self, points: int, seed: int) -> dict[str, Any] | None:
        """The cache's entries when it is valid for ``(points, seed)``, else None."""
        cache = self.folder
        manifest_path, samples_path = cache / _MANIFEST_FILE, cache / _SAMPLES_FILE
        if not manifest_path.is_file():
            return None
        try:
            with open(manifest_path, encoding="utf-8") as f:
                manifest = json.load(f)
            if (manifest.get("format") != CACHE_FORMAT or manifest.get("points") != points
                    or manifest.get("seed") != seed):
                return None
            with np.load(samples_path, allow_pickle=False) as npz:
                token = str(npz["token"])
                names = [str(n) for n in npz["names"]]
                stack = np.asarray(npz["points"], dtype=np.float32)
                parts = np.asarray(npz["parts"], dtype=np.int32)
            files = manifest["files"]
            if (token != manifest["token"] or names != [f["name"] for f in files]
                    or stack.shape != (len(files), points, 3)
                    or parts.shape != (len(files), points)):
                return None
            token = manifest.pop("token")
            return {
                "manifest": manifest,
                "files": {f["name"]: ((int(f["size"]), int(f["mtime_ns"])), stack[i], parts[i])
                          for i, f in enumerate(files)},
                "skipped": {s["name"]: ((int(s["size"]), int(s["mtime_ns"])), str(s["problem"]))
                            for s in manifest.get("skipped", [])},
            }
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            warnings.warn(CagekitWarning(f"ignoring the unreadable cache in {cache} "
                                         f"({type(exc).__name__}: {exc}); it will be rebuilt"),
                          stacklevel=3)
            return None

    def write(self, manifest: dict, names: Sequence[str], stack: ArrayLike,
              parts: ArrayLike) -> None:
        """Write samples (``stack`` (N, P, 3), ``parts`` (N, P)) then manifest atomically;
        warn (default cache) or raise (explicit)."""
        cache, explicit = self.folder, self.explicit
        token = secrets.token_hex(8)
        try:
            cache.mkdir(parents=True, exist_ok=True)
            with atomic_output(cache / _SAMPLES_FILE) as tmp, open(tmp, "wb") as f:
                np.savez(f, token=np.array(token), names=np.array(names, dtype=str),
                         points=stack, parts=parts)
            with atomic_output(cache / _MANIFEST_FILE) as tmp, open(tmp, "w",
                                                                    encoding="utf-8") as f:
                json.dump({**manifest, "token": token}, f, indent=1)
                f.write("\n")
        except (OSError, InputError) as exc:
            problem = getattr(exc, "problem", None) or getattr(exc, "strerror", None) or str(exc)
            if explicit:
                raise InputError(f"cannot write the cache: {problem}", cache) from None
            warnings.warn(CagekitWarning(f"not caching samples: cannot write {cache} "
                                         f"({problem})"), stacklevel=3)


# ------------------------------------------------------------------------------- pairs


def epoch_pairs(n_shapes: int, epoch: int, seed: int = 0) -> np.ndarray:
    """The (source, target) pairs of one epoch.

    Parameters
    ----------
    n_shapes : int
        Number of shapes, >= 2.
    epoch : int
        Epoch number (>= 0).
    seed : int, default 0
        Seed (>= 0).

    Returns
    -------
    pairs : (n_shapes, 2) int64 ndarray
        Column 0 is a seeded permutation of ``range(n_shapes)`` (every shape is a source
        once); column 1 a target drawn uniformly among the other shapes. Deterministic in
        ``(n_shapes, epoch, seed)``; different epochs give different pairs.

    Examples
    --------
    >>> p = epoch_pairs(5, epoch=0)
    >>> sorted(p[:, 0].tolist()), bool((p[:, 0] != p[:, 1]).all())
    ([0, 1, 2, 3, 4], True)
    """
    n = as_count(n_shapes, "n_shapes", 2)
    rng = np.random.default_rng([_TAG_PAIRS, as_count(seed, "seed"), as_count(epoch, "epoch")])
    sources = rng.permutation(n).astype(np.int64)
    targets = (sources + rng.integers(1, n, size=n)) % n
    return np.stack([sources, targets], axis=1).astype(np.int64)


def fixed_source_pairs(n_targets: int, epoch: int, seed: int = 0) -> np.ndarray:
    """The (source, target) pairs of one epoch with a fixed source.

    Parameters
    ----------
    n_targets : int
        Number of shapes in the collection (the targets), >= 1.
    epoch : int
        Epoch number (>= 0).
    seed : int, default 0
        Seed (>= 0).

    Returns
    -------
    pairs : (n_targets, 2) int64 ndarray
        Column 0 is :data:`FIXED_SOURCE` (-1, the fixed source, which is not a shape of
        the collection); column 1 a seeded permutation of ``range(n_targets)``, so every
        target is visited once per epoch. Deterministic in ``(n_targets, epoch, seed)``;
        different epochs give different orders. Split it between ranks with
        :func:`shard`, as :func:`epoch_pairs`.

    Examples
    --------
    >>> p = fixed_source_pairs(4, epoch=0)
    >>> p[:, 0].tolist(), sorted(p[:, 1].tolist())
    ([-1, -1, -1, -1], [0, 1, 2, 3])
    """
    n = as_count(n_targets, "n_targets", 1)
    rng = np.random.default_rng([_TAG_FIXED_PAIRS, as_count(seed, "seed"),
                                 as_count(epoch, "epoch")])
    targets = rng.permutation(n).astype(np.int64)
    return np.stack([np.full(n, FIXED_SOURCE, dtype=np.int64), targets], axis=1)


def shard(pairs: ArrayLike, rank: int, world_size: int) -> Ints:
    """One rank's share of the pairs for DistributedDataParallel.

    Parameters
    ----------
    pairs : (n, 2) array_like of int
        The epoch's pairs, the same on every rank (:func:`epoch_pairs`).
    rank : int
        This process's rank, ``0 <= rank < world_size``.
    world_size : int
        Number of processes, >= 1.

    Returns
    -------
    (n // world_size, 2) int64 ndarray
        ``pairs`` truncated to a multiple of ``world_size`` (so every rank runs the same
        number of steps), then every ``world_size``-th row from ``rank``. The shares of the
        ranks are disjoint and together make the truncated pairs.

    Raises
    ------
    InputError
        Bad rank or world size, or fewer pairs than ranks.

    Examples
    --------
    >>> shard(np.arange(10).reshape(5, 2), rank=1, world_size=2).tolist()
    [[2, 3], [6, 7]]
    """
    pairs = np.asarray(pairs)
    if pairs.ndim != 2 or pairs.shape[1] != 2 or not np.issubdtype(pairs.dtype, np.integer):
        raise InputError(f"pairs must be an (n, 2) integer array, got {pairs.dtype} "
                         f"{pairs.shape}")
    world_size = as_count(world_size, "world_size", 1)
    rank = as_count(rank, "rank")
    if rank >= world_size:
        raise InputError(f"rank must be below world_size ({world_size}), got {rank}")
    if len(pairs) < world_size:
        raise InputError(f"{len(pairs)} pairs cannot be shared by {world_size} ranks")
    used = len(pairs) // world_size * world_size
    return np.ascontiguousarray(pairs[:used][rank::world_size], dtype=np.int64)


# ------------------------------------------------------------------------ augmentation


def augment(points: ArrayLike, rng: np.random.Generator | int, low: float = 0.75,
            high: float = 1.25) -> np.ndarray:
    """The paper's augmentation: scale each axis at random, then re-normalise.

    Parameters
    ----------
    points : (P, 3) array_like of float
        A shape's samples (not all equal).
    rng : numpy.random.Generator or int
        Source of the three scale factors (an int seeds a new Generator).
    low, high : float, default 0.75 and 1.25
        The factors are uniform in ``[low, high]``, ``0 < low <= high``.

    Returns
    -------
    (P, 3) float32 ndarray
        The scaled points with their bounding-box centre at the origin and largest
        half-extent 1.

    Examples
    --------
    >>> P = augment(np.random.default_rng(0).random((100, 3)), np.random.default_rng(1))
    >>> P.dtype, float(np.abs(P).max())
    (dtype('float32'), 1.0)
    """
    low, high = float(low), float(high)
    if not (np.isfinite(low) and np.isfinite(high) and 0.0 < low <= high):
        raise InputError(f"need 0 < low <= high, got low={low}, high={high}")
    rng = np.random.default_rng(rng)
    scale = rng.uniform(low, high, size=3)
    scaled = np.asarray(points, dtype=np.float64) * scale
    return Frame.of(scaled).to_unit(scaled).astype(np.float32)


def _source_parts(collection, pairs: np.ndarray, points: int, fixed: bool) -> np.ndarray:
    """The part labels of a batch's sources, (b, points) int64 (-1: no part; all of a
    fixed source's and of an array collection's)."""
    if fixed or not isinstance(collection, ShapeCollection):
        return np.full((len(pairs), points), -1, dtype=np.int64)
    return collection.parts[pairs[:, 0]].astype(np.int64)


def make_batch(collection: ShapeCollection | ArrayLike, pairs: ArrayLike, *, epoch: int,
               step: int, seed: int = 0, augmentation: bool = True,
               dtype: torch.dtype | None = None,
               source_points: ArrayLike | None = None) -> dict[str, torch.Tensor]:
    """Tensors of one training step.

    Parameters
    ----------
    collection : ShapeCollection or (N, P, 3) array_like
        The shapes.
    pairs : (b, 2) array_like of int
        Rows of (source index, target index) into ``collection``; with ``source_points``
        every source index is :data:`FIXED_SOURCE` (:func:`fixed_source_pairs`).
    epoch, step : int
        Position of the batch in training (>= 0); with ``seed`` they fix the augmentation.
    seed : int, default 0
        Seed (>= 0).
    augmentation : bool, default True
        Apply :func:`augment` to every source and, independently, every target. A fixed
        source is never augmented, only its targets.
    dtype : torch.dtype, optional
        Of the point tensors; default ``torch.float32``.
    source_points : (P, 3) array_like of float, optional
        The fixed source (normalised samples, :attr:`FixedSource.points`), the source of
        every row, as it is.

    Returns
    -------
    dict
        ``"source"``, ``"target"``: (b, P, 3) tensors of ``dtype``; ``"source_parts"``:
        (b, P) ``torch.long``, each source sample's part (:attr:`ShapeCollection.parts`; -1
        everywhere for a fixed source or an array collection); ``"source_index"``,
        ``"target_index"``: (b,) ``torch.long`` tensors. Row ``i`` is augmented with a
        Generator seeded from ``(seed, epoch, step, i, source index, target index)`` (with a
        fixed source: ``(seed, epoch, step, i, target index)``), so the same arguments give
        the same batch (a resumed run reproduces it) and ranks of a distributed run draw
        different factors.

    Examples
    --------
    >>> c = ShapeCollection.synthetic("vases", n=3, points=32, resolution=0.5)
    >>> b = make_batch(c, [[0, 1], [2, 0]], epoch=0, step=0)  # doctest: +SKIP
    >>> b["source"].shape, b["target_index"].tolist()  # doctest: +SKIP
    (torch.Size([2, 32, 3]), [1, 0])
    """
    import torch

    data = collection.points if isinstance(collection, ShapeCollection) else np.asarray(
        collection, dtype=np.float32)
    if data.ndim != 3 or data.shape[2] != 3:
        raise InputError(f"collection points must have shape (N, P, 3), got {data.shape}")
    pairs = np.asarray(pairs)
    if pairs.ndim != 2 or pairs.shape[1] != 2 or not np.issubdtype(pairs.dtype, np.integer):
        raise InputError(f"pairs must be a (b, 2) integer array, got {pairs.dtype} "
                         f"{pairs.shape}")
    fixed_points = (None if source_points is None
                    else np.asarray(source_points, dtype=np.float32))
    fixed = fixed_points is not None
    if fixed_points is not None:
        if fixed_points.shape != data.shape[1:]:
            raise InputError(f"source_points must have shape {data.shape[1:]} (as every "
                             f"shape), got {fixed_points.shape}")
        if len(pairs) and (pairs[:, 0] != FIXED_SOURCE).any():
            raise InputError(f"with source_points every source index must be "
                             f"{FIXED_SOURCE} (fixed_source_pairs)")
    elif len(pairs) and (pairs[:, 0] == FIXED_SOURCE).any():
        raise InputError(f"source index {FIXED_SOURCE} (the fixed source) needs "
                         "source_points")
    indexed = pairs[:, 1:] if fixed else pairs
    if len(pairs) and (indexed.min() < 0 or indexed.max() >= len(data)):
        raise InputError(f"pair indices must lie in [0, {len(data)}), got "
                         f"{indexed.min()}..{indexed.max()}")
    seed, epoch, step = as_count(seed, "seed"), as_count(epoch, "epoch"), as_count(step, "step")
    pairs = pairs.astype(np.int64)
    target = data[pairs[:, 1]]
    if fixed_points is not None:
        source = np.repeat(fixed_points[None], len(pairs), axis=0)
        if augmentation:
            target = target.copy()
            for i, t in enumerate(pairs[:, 1].tolist()):
                rng = np.random.default_rng([_TAG_AUGMENT_TARGET, seed, epoch, step, i, t])
                target[i] = augment(target[i], rng)
    else:
        source = data[pairs[:, 0]]
    if augmentation and not fixed:
        source = source.copy()
        target = target.copy()
        for i, (s, t) in enumerate(pairs.tolist()):
            rng = np.random.default_rng([_TAG_AUGMENT, seed, epoch, step, i, s, t])
            source[i] = augment(source[i], rng)
            target[i] = augment(target[i], rng)
    dtype = torch.float32 if dtype is None else dtype
    return {
        "source": torch.from_numpy(np.ascontiguousarray(source)).to(dtype),
        "target": torch.from_numpy(np.ascontiguousarray(target)).to(dtype),
        "source_parts": torch.from_numpy(_source_parts(collection, pairs, data.shape[1], fixed)),
        "source_index": torch.from_numpy(pairs[:, 0].copy()),
        "target_index": torch.from_numpy(pairs[:, 1].copy()),
    }
