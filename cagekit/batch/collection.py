"""A collection of shapes: a folder of meshes, or a procedural family, by name.

``cagekit amplify`` and :func:`cagekit.batch.amplify.amplify` take a collection, name its shapes
uniquely (for output files and pair lists), group them by category and fingerprint their
content (so that a resumed batch redoes only what changed). Loading happens where the
work runs (a worker process or a cluster node), from a :class:`Shape`'s ``location``.
"""

from __future__ import annotations

import hashlib
import os
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from cagekit.datasets.synthetic import FAMILIES
from cagekit.errors import InputError
from cagekit.io import SUPPORTED_MESH_EXTENSIONS, load_mesh
from cagekit.io.files import distinct_tails

__all__ = ["SYNTHETIC_PREFIX", "Shape", "file_hash", "find_shapes", "load_shape_of",
           "short_names"]

#: a collection spec ``synthetic:<family>:<count>`` names procedural shapes
#: (:data:`cagekit.datasets.synthetic.FAMILIES`, seeds 0 to count - 1)
SYNTHETIC_PREFIX = "synthetic:"


@dataclass(frozen=True)
class Shape:
    """One shape of a collection.

    Attributes
    ----------
    name : str
        Unique within the collection: the file's path below the collection folder,
        without extension, ``/`` kept (``chairs/a1b2/model``), or ``chairs_007``.
    location : str
        A mesh file's absolute path, or ``synthetic:<family>:<seed>``.
    category : str
        The sub-folder the file lies in (``""`` at the top), or the family.
    fingerprint : str
        SHA-256 of the file's bytes, or of ``location`` for a procedural shape.
    """

    name: str
    location: str
    category: str
    fingerprint: str

    @property
    def stem(self) -> str:
        """``name`` with ``/`` replaced by ``-``: fit for a file name."""
        return self.name.replace("/", "-")


def file_hash(path: str | os.PathLike) -> str:
    """SHA-256 of a file's bytes, in hex (a :attr:`Shape.fingerprint`).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    str
        64 hex digits.

    Raises
    ------
    OSError
        The file cannot be read.
    """
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _synthetic(spec: str) -> list[Shape]:

    parts = spec.split(":")
    if len(parts) != 3 or parts[1] not in FAMILIES or not parts[2].isdigit() \
            or int(parts[2]) < 2:
        raise InputError(f"a procedural collection is synthetic:<family>:<count> with family "
                         f"one of {', '.join(FAMILIES)} and count >= 2, got {spec!r}")
    family, count = parts[1], int(parts[2])
    width = len(str(count - 1))
    return [Shape(f"{family}_{i:0{width}d}", f"{SYNTHETIC_PREFIX}{family}:{i}", family,
                  hashlib.sha256(f"{SYNTHETIC_PREFIX}{family}:{i}".encode()).hexdigest())
            for i in range(count)]


def find_shapes(collection: str, exclude: Iterable[str | os.PathLike] = ()) -> list[Shape]:
    """The shapes of a collection, sorted by name.

    Parameters
    ----------
    collection : str
        A folder, searched recursively for mesh files
        (:data:`cagekit.io.SUPPORTED_MESH_EXTENSIONS`; hidden files and folders skipped;
        ShapeNet's ``<synset>/<id>/model.obj`` works), or ``synthetic:<family>:<count>``.
    exclude : iterable of str or os.PathLike, optional
        Folders not searched (a batch's output folder, say), wherever they lie.

    Returns
    -------
    list of Shape
        At least two.

    Raises
    ------
    InputError
        Not a folder, fewer than two meshes, or a bad ``synthetic:`` spec.

    Examples
    --------
    >>> [s.name for s in find_shapes("synthetic:vases:3")]
    ['vases_0', 'vases_1', 'vases_2']
    """
    if collection.startswith(SYNTHETIC_PREFIX):
        return _synthetic(collection)
    root = os.path.abspath(collection)
    if not os.path.isdir(root):
        raise InputError("not a folder (a collection is a folder of meshes or "
                         "synthetic:<family>:<count>)", collection)
    skipped = {os.path.realpath(path) for path in exclude}
    shapes = []
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and not (
            skipped and os.path.realpath(os.path.join(folder, d)) in skipped))
        for file in sorted(files):
            stem, ext = os.path.splitext(file)
            if file.startswith(".") or ext.lower() not in SUPPORTED_MESH_EXTENSIONS:
                continue
            path = os.path.join(folder, file)
            rel = os.path.relpath(path, root)
            category = os.path.dirname(rel).split(os.sep)[0] if os.sep in rel else ""
            name = os.path.splitext(rel)[0].replace(os.sep, "/")
            try:
                fingerprint = file_hash(path)
            except OSError as exc:
                fingerprint = f"unreadable: {exc.strerror or exc}"
            shapes.append(Shape(name, path, category, fingerprint))
    names = [s.name for s in shapes]
    if len(set(names)) != len(names):  # a.obj beside a.ply: keep the extension
        shapes = [Shape(os.path.relpath(s.location, root).replace(os.sep, "/"), s.location,
                        s.category, s.fingerprint) for s in shapes]
    shapes.sort(key=lambda s: s.name)
    if len(shapes) < 2:
        raise InputError(f"found {len(shapes)} mesh file(s); a collection needs at least two "
                         f"({', '.join(SUPPORTED_MESH_EXTENSIONS)})", collection)
    return shapes


def load_shape_of(location: str) -> tuple[np.ndarray, np.ndarray]:
    """The mesh of a :class:`Shape`'s ``location``: ``(V (n, 3) float64, F (m, 3) int64)``.

    Raises
    ------
    InputError
        The file cannot be read or is not a mesh (:func:`cagekit.io.load_mesh`).

    Examples
    --------
    >>> V, F = load_shape_of("synthetic:vases:0")
    >>> V.shape[1], F.dtype
    (3, dtype('int64'))
    """
    if location.startswith(SYNTHETIC_PREFIX):

        family, seed = location[len(SYNTHETIC_PREFIX):].split(":")
        return FAMILIES[family](seed=int(seed))
    return load_mesh(location)


def short_names(names: Iterable[str]) -> dict[str, str]:
    """The shortest distinctive name of each shape: for output files and captions.

    A name's ``/``-separated parts are taken with a part that repeats the one before it
    dropped (``antiqueChair/antiqueChair``), and the leading and trailing parts that every
    name shares (a catalog folder, ShapeNet's ``model``) dropped; what is left is cut to
    its shortest tail that no other name ends with (``tall/a`` -> ``a``, but ``x/chair``
    and ``y/chair`` stay whole). Every name keeps at least its last part.

    Parameters
    ----------
    names : iterable of str
        :attr:`Shape.name` of the shapes (distinct).

    Returns
    -------
    dict of str to str
        The short name of each name, ``/`` kept between the parts left; distinct: names
        that would still end alike (``oak`` and ``oak/oak``, ``a`` and ``x/a``) keep
        their whole names.

    Examples
    --------
    >>> short_names(["cc0/antiqueChair/antiqueChair", "cc0/chair2/chair2"])
    {'cc0/antiqueChair/antiqueChair': 'antiqueChair', 'cc0/chair2/chair2': 'chair2'}
    >>> sorted(short_names(["03001627/1a2b/model", "03001627/3c4d/model"]).values())
    ['1a2b', '3c4d']
    >>> sorted(short_names(["x/chair", "y/chair", "y/table"]).values())
    ['table', 'x/chair', 'y/chair']
    >>> short_names(["oak", "oak/oak"])
    {'oak': 'oak', 'oak/oak': 'oak/oak'}
    """
    names = list(dict.fromkeys(names))
    parts = {name: _collapsed(name.split("/")) for name in names}
    if len(names) > 1:
        lead, tail = _shared_ends(list(parts.values()))
        parts = {name: p[lead:len(p) - tail] for name, p in parts.items()}
    short = dict(zip(parts, distinct_tails(list(parts.values()))))
    counts = Counter(short.values())
    return {name: name if counts[value] > 1 else value for name, value in short.items()}


def _collapsed(parts: list[str]) -> list[str]:
    """``parts`` without a part equal to the one before it (and without empty parts)."""
    out: list[str] = []
    for part in parts:
        if part and (not out or out[-1] != part):
            out.append(part)
    return out or [""]


def _shared_ends(lists: list[list[str]]) -> tuple[int, int]:
    """How many leading and trailing parts every list shares, leaving each at least one."""
    room = min(len(p) for p in lists) - 1
    lead = 0
    while lead < room and len({p[lead] for p in lists}) == 1:
        lead += 1
    tail = 0
    while tail < room - lead and len({p[-1 - tail] for p in lists}) == 1:
        tail += 1
    return lead, tail
