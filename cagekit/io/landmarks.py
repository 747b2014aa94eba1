"""Named landmarks: reading and writing them, and pairing two sets by label.

Landmarks load to a ``dict`` label -> (3,) float64 in file order. Labels are stripped of
surrounding whitespace; duplicate labels, non-numeric or non-finite values, wrong column
counts and empty files are errors (:class:`~cagekit.errors.LandmarkFileError`, one line
naming the file). In Thea ``.picked`` files the face, barycentric and vertex columns must
be numeric but are otherwise unused. :func:`save_landmarks` writes JSON or CSV only: a
``.picked`` row needs a face index and barycentric coordinates that a label -> position
mapping does not have. Real files often misspell or miss a few labels, so
:func:`match_landmarks` pairs the shared labels and reports the others (``require_all``
for the strict case).
"""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from cagekit.errors import InputError, LandmarkFileError
from cagekit.io.files import atomic_output, extension, one_line, read_text
from cagekit.typed import Vertices

__all__ = ["SUPPORTED_LANDMARK_EXTENSIONS", "LandmarkMatch", "SurfacePoint", "load_landmarks",
           "match_landmarks", "save_landmarks", "save_picked"]

SUPPORTED_LANDMARK_EXTENSIONS = (".picked", ".json", ".csv")
"""Extensions :func:`load_landmarks` reads (:func:`save_landmarks` writes JSON and CSV)."""


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
        extension(path)
    )
    if parser is None:
        raise LandmarkFileError(
            f"unknown landmark extension {extension(path) or '(none)'!r}; "
            f"supported: {', '.join(SUPPORTED_LANDMARK_EXTENSIONS)}",
            path,
        )
    text = read_text(path, LandmarkFileError)
    try:
        entries = parser(text, path)
    except InputError:
        raise
    except Exception as exc:  # any parser failure is a property of the file
        kind = extension(path)[1:].upper()
        raise LandmarkFileError(f"cannot be read as {kind}: {one_line(exc)}", path) from exc
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
    ext = extension(path)
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
class SurfacePoint:
    """A labelled point on a mesh's surface, as a Thea ``.picked`` row names it.

    Attributes
    ----------
    label : str
    face : int
        Index of the face the point lies on.
    barycentric : (3,) tuple of float
        Its weights on the face's three vertices (summing to 1).
    position : (3,) tuple of float
        ``barycentric @ vertices[faces[face]]``.
    """

    label: str
    face: int
    barycentric: tuple
    position: tuple


def save_picked(path: str | os.PathLike, points: Iterable[SurfacePoint]) -> None:
    """Write surface points atomically as a Thea ``.picked`` file (9 columns).

    Parameters
    ----------
    path : str or os.PathLike
        Destination ending in ``.picked``.
    points : sequence of SurfacePoint
        Labels without whitespace (a ``.picked`` row splits on it), finite values.

    Raises
    ------
    InputError
        Another extension, no points, a label with whitespace, non-finite values.

    Examples
    --------
    >>> p = SurfacePoint("nose", 12, (0.5, 0.25, 0.25), (0.0, 1.6, 0.1))
    >>> save_picked("marks.picked", [p])  # doctest: +SKIP
    >>> load_landmarks("marks.picked")["nose"]  # doctest: +SKIP
    array([0. , 1.6, 0.1])
    """
    if extension(path) != ".picked":
        raise InputError("save_picked writes .picked files only", path)
    points = list(points)
    if not points:
        raise InputError("no landmarks to write", path)
    lines = [str(len(points))]
    for p in points:
        values = np.asarray([*p.barycentric, *p.position], dtype=np.float64)
        if (not p.label or any(c.isspace() for c in p.label) or values.shape != (6,)
                or not np.isfinite(values).all()):
            raise InputError(f"landmark {p.label!r}: a label without spaces, 3 barycentric "
                             "and 3 finite coordinates are needed", path)
        numbers = " ".join(repr(float(v)) for v in values[:3])
        xyz = " ".join(repr(float(v)) for v in values[3:])
        lines.append(f"Picked {int(p.face)} {numbers} {p.label} {xyz}")
    with atomic_output(path) as tmp, open(tmp, "w", encoding="utf-8", newline="") as fh:
        fh.write("\n".join(lines) + "\n")


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

    labels: list[str]
    source: Vertices
    target: Vertices
    source_only: list[str]
    target_only: list[str]

    def unmatched(self, source_name: str | os.PathLike | None = None,
                  target_name: str | os.PathLike | None = None, shown: int = 8) -> str | None:
        """One line listing the labels found in one set only, or None when there are none.

        Examples
        --------
        >>> m = LandmarkMatch(["a"], None, None, ["nose"], ["noze"])
        >>> print(m.unmatched("s.json", "t.json"))  # doctest: +NORMALIZE_WHITESPACE
        2 landmark label(s) in one file only, not used: nose (only in s.json);
        noze (only in t.json)
        """
        parts = []
        for labels, name in ((self.source_only, source_name or "the source"),
                             (self.target_only, target_name or "the target")):
            if labels:
                more = f" and {len(labels) - shown} more" if len(labels) > shown else ""
                parts.append(f"{', '.join(labels[:shown])}{more} (only in {name})")
        if not parts:
            return None
        count = len(self.source_only) + len(self.target_only)
        return f"{count} landmark label(s) in one file only, not used: {'; '.join(parts)}"


def match_landmarks(source: Mapping[str, object], target: Mapping[str, object], *,
                    minimum: int = 4, require_all: bool = False,
                    source_name: str | os.PathLike | None = None,
                    target_name: str | os.PathLike | None = None) -> LandmarkMatch:
    """Pair two sets of named landmarks by label.

    Parameters
    ----------
    source, target : mapping of str to (3,) array_like of float
        Label -> position, as :func:`load_landmarks` returns them.
    minimum : int, default 4
        Fewest shared labels accepted.
    require_all : bool, default False
        Refuse sets whose labels differ at all (the strict case); by default the labels
        found in one set only are left out and reported in the result.
    source_name, target_name : str or os.PathLike, optional
        The files the sets came from, named in the error.

    Returns
    -------
    LandmarkMatch
        Shared labels in ``source``'s order, and the labels only one set has.

    Raises
    ------
    InputError
        Fewer than ``minimum`` shared labels (the message names both files and the count),
        or, with ``require_all``, a label in one set only.

    Examples
    --------
    >>> m = match_landmarks({"a": [0, 0, 0], "b": [1, 0, 0], "c": [0, 1, 0]},
    ...                     {"b": [2, 0, 0], "a": [0, 0, 1], "d": [0, 0, 0]}, minimum=2)
    >>> m.labels, m.source_only, m.target_only, m.target[0].tolist()
    (['a', 'b'], ['c'], ['d'], [0.0, 0.0, 1.0])
    """
    labels = [label for label in source if label in target]
    names = (f"{source_name or 'the source landmarks'} and "
             f"{target_name or 'the target landmarks'}")
    if len(labels) < minimum:
        raise InputError(f"{names} share {len(labels)} landmark label(s); at least "
                         f"{minimum} are needed")

    def rows(marks):
        return np.array([np.asarray(marks[label], dtype=np.float64) for label in labels])

    match = LandmarkMatch(labels=labels, source=rows(source), target=rows(target),
                          source_only=[label for label in source if label not in target],
                          target_only=[label for label in target if label not in source])
    if require_all and (match.source_only or match.target_only):
        raise InputError(f"{names} must name the same landmarks: "
                         f"{match.unmatched(source_name, target_name)}")
    return match
