"""Stock amplification: many variations of a collection, each source deformed onto a target.

The paper's first application. Pairs are drawn (seeded), listed, or all taken; each item
deforms its source to its target's proportions (:func:`cagekit.deform`) and is scored
(:func:`cagekit.evaluate`), and a plausibility filter marks the implausible ones
``rejected``, with the reason in the manifest: a Chamfer distance to the target above
:data:`MAX_CD`, a part of a multi-part source bent beyond :data:`MAX_NONAFFINITY`, or parts
that were apart in the source passing through each other (``parts cross: 2 and 3``;
:mod:`cagekit.batch.crossing`, an exact triangle-triangle test; the manifest's
``crossing_parts`` counts the pairs). Outputs are named ``<source>__<target>.obj`` (``.ply``
or ``.glb`` for such sources, which keep their asset that way) by each
shape's shortest distinctive name (:func:`cagekit.batch.collection.short_names`); the
contact sheet (:mod:`cagekit.batch.sheet`) shows the items as a grid with their status.
Items run on a process pool (no more processes than items or cores; they
end with the batch, Ctrl-C and SIGKILL included; their warnings are issued again in the
main process) or on any ``concurrent.futures`` executor (a cluster's); each is a pure
function of (source, target, method, seed), so the results do not depend on where or in
which order they ran. A source's cage is fitted once, into a file of its own, and reused
by its later pairs, and by a later run while neither the source nor the cage file
changed. The output folder may not lie in the collection. The manifest (CSV and JSON) is
rewritten atomically after every finished item, so a killed batch loses only the items in
flight, and a rerun redoes only items that are missing or whose inputs changed (content
hashes). docs/architecture.md has the data path.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import csv
import io
import json
import multiprocessing
import os
import pickle
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TypeAlias, cast

import numpy as np
from numpy.typing import ArrayLike

from cagekit.batch.collection import (
    SYNTHETIC_PREFIX,
    Shape,
    file_hash,
    find_shapes,
    load_shape_of,
    short_names,
)
from cagekit.batch.crossing import part_crossings
from cagekit.batch.sheet import SHEET_COLUMNS, Tile, cut_middle, draw_contact_sheet
from cagekit.cage.fitting import fit_cage
from cagekit.deformation import DeformOptions, DeformResult, deform
from cagekit.errors import CagekitWarning, InputError, MeshFileWarning
from cagekit.geometry.frame import Frame
from cagekit.interrupts import sigint_deferred
from cagekit.io import (
    kept_extension,
    load_mesh,
    move_deformed,
    remove_deformed,
    save_deformed,
    save_mesh,
)
from cagekit.io.files import (
    atomic_output,
    missing_folders,
    one_line,
    output_folder,
    read_text,
    remove_empty_folders,
)
from cagekit.metrics import evaluate
from cagekit.typed import Faces, Vertices

__all__ = ["COLUMNS", "COORDS", "MAX_CD", "MAX_CROSSINGS", "MAX_NONAFFINITY", "METHODS",
           "SHEET_COLUMNS", "Item", "amplify", "contact_sheet", "deform_item", "pair_title",
           "plan_pairs", "prepare_worker", "process_pool", "usable_cores", "worker_count"]

METHODS = ("cage", "scale", "model")
#: the coordinates of method cage (:data:`cagekit.deformation.COORDS`)
COORDS = ("mvc", "green")
#: a variation of a source of two or more parts whose worst part is farther than this
#: from an affine map of itself (:func:`cagekit.metrics.part_nonaffinity`, fraction of the
#: part's size) is rejected; a one-part source (an animal, a vase) is meant to bend
MAX_NONAFFINITY = 0.02
#: a variation whose Chamfer distance to its target (target's unit frame, as
#: :func:`cagekit.evaluate`) exceeds this is rejected: it did not take the target's shape
MAX_CD = 0.05
#: a variation in which more than this many pairs of parts, apart in the source, pass
#: through each other (:func:`cagekit.batch.crossing.part_crossings`) is rejected
MAX_CROSSINGS = 0
#: the manifest's columns, in order. ``method`` is the batch's; ``deformed_by`` what made
#: the item (:attr:`cagekit.DeformResult.method`): with ``model``, ``learned``, or ``scale``
#: where the network's result was further from the target than the box scaling and
#: the scaling was handed on instead, ``learned+refine``, or ``cage`` after a fall back
COLUMNS = ("source", "target", "output", "method", "deformed_by", "coords", "seed", "status",
           "reason", "cd", "dcotlap", "parts", "part_nonaffinity_median",
           "part_nonaffinity_worst", "planarity_p95_deg", "crossing_parts", "crossing_pairs",
           "seconds", "cage_seconds", "error", "source_hash", "target_hash")
#: the figures of :func:`cagekit.evaluate` an item records
_METRICS = ("cd", "dcotlap", "parts", "part_nonaffinity_median", "part_nonaffinity_worst",
            "planarity_p95_deg")
#: every figure an item records: the metrics and the crossing parts (their number, and the
#: pairs as ``"2 and 3, 4 and 7"``)
_FIGURES = _METRICS + ("crossing_parts", "crossing_pairs")
#: the cage ``deform`` fits for a source (as :func:`cagekit.deform` does by default)
CAGE_FACES = 200
#: the error of an item whose worker died (killed, out of memory, a crash): not the item's
#: own failure, so a rerun does it again
_WORKER_FAILED = "the worker failed"
#: characters of a contact sheet's pair title (about what a tile's 10-point bold line
#: holds; the sheet cuts a wider one further, :func:`cagekit.batch.sheet.draw_contact_sheet`)
_SHEET_TITLE_CHARS = 34

#: a trained model's deformation, ``deformer(V_src, F_src, V_tgt, F_tgt, seed)``
#: (:class:`cagekit_learn.inference.ModelDeformer`)
_Deformer: TypeAlias = Callable[[Vertices, Faces, Vertices, Faces, int], DeformResult]


@dataclass(frozen=True)
class Item:
    """One variation to make: ``source`` deformed onto ``target``."""

    source: Shape
    target: Shape
    output: str  # file name under variations/ (or rejected/)


# --------------------------------------------------------------------------- planning


def _allowed(shapes, category_by):
    if category_by not in (None, "folder"):
        raise InputError(f"category_by must be None or 'folder', got {category_by!r}")
    groups = {}
    for i, shape in enumerate(shapes):
        groups.setdefault(shape.category if category_by else "", []).append(i)
    return [g for g in groups.values() if len(g) >= 2]


def _read_pairs(path, by_name):
    rows = list(csv.reader(io.StringIO(read_text(path))))
    rows = [r for r in rows if r and any(cell.strip() for cell in r)]
    if rows and [c.strip().lower() for c in rows[0][:2]] == ["source", "target"]:
        rows = rows[1:]
    pairs, unknown = [], []
    for number, row in enumerate(rows, 1):
        if len(row) < 2:
            raise InputError(f"row {number}: expected 'source,target'", path)
        names = [row[0].strip(), row[1].strip()]
        unknown += [n for n in names if n not in by_name]
        pairs.append(tuple(names))
    if unknown:
        shown = ", ".join(sorted(set(unknown))[:5])
        known = ", ".join(sorted({shape.name for shape in by_name.values()})[:3])
        raise InputError(f"{len(set(unknown))} name(s) not in the collection: {shown}"
                         + (" ..." if len(set(unknown)) > 5 else "")
                         + f" (a name is a shape's path below the collection without its "
                         f"extension, {known} ..., or the short name its outputs take)",
                         path)
    if not pairs:
        raise InputError("no pairs listed", path)
    resolved = [(by_name[a], by_name[b]) for a, b in pairs]
    # a pair listed twice (under two spellings, say) is one item
    return list({(a.name, b.name): (a, b) for a, b in resolved}.values())


def plan_pairs(shapes: Sequence[Shape], *, variations: int | None = None,
               pairs: str | None = None, category_by: str | None = None,
               seed: int = 0) -> list[tuple[Shape, Shape]]:
    """The (source, target) pairs of a batch, in manifest order.

    Parameters
    ----------
    shapes : list of Shape
        From :func:`cagekit.batch.collection.find_shapes`.
    variations : int, optional
        Draw this many distinct ordered pairs, uniformly, with ``seed``; a shape is never
        paired with itself.
    pairs : str, optional
        ``"all"`` (every ordered pair) or a CSV file of ``source,target`` names (a header
        line ``source,target`` is optional): :attr:`Shape.name`, or the short name of
        :func:`~cagekit.batch.collection.short_names` that the outputs take.
    category_by : {None, "folder"}
        ``"folder"``: pairs only within a category (:attr:`Shape.category`).
    seed : int, default 0

    Returns
    -------
    list of (Shape, Shape)

    Raises
    ------
    InputError
        Neither or both of ``variations`` and ``pairs``; more variations than pairs
        exist; names in the pairs file not in the collection (named).

    Examples
    --------
    >>> from cagekit.batch.collection import find_shapes
    >>> shapes = find_shapes("synthetic:vases:3")
    >>> len(plan_pairs(shapes, pairs="all")), len(plan_pairs(shapes, variations=4))
    (6, 4)
    """
    if (variations is None) == (pairs is None):
        raise InputError("give either a number of variations or pairs ('all' or a CSV file)")
    by_name = {s.name: s for s in shapes}
    for name, short in short_names(by_name).items():  # the outputs' names are taken too
        by_name.setdefault(short, by_name[name])
        by_name.setdefault(short.replace("/", "-"), by_name[name])  # as in file names
    groups = _allowed(shapes, category_by)
    if pairs is not None and pairs != "all":
        chosen = _read_pairs(pairs, by_name)
        if category_by:
            mixed = [f"{a.name},{b.name}" for a, b in chosen if a.category != b.category]
            if mixed:
                raise InputError(f"{len(mixed)} pair(s) cross categories: {mixed[0]}", pairs)
        return chosen
    sizes = np.array([len(g) * (len(g) - 1) for g in groups], dtype=np.int64)
    total = int(sizes.sum())
    if pairs == "all":
        picks = np.arange(total)
    else:
        count = int(cast(int, variations))  # not None: checked with pairs above
        if count < 1 or count > total:
            raise InputError(f"variations must be between 1 and {total} (the distinct "
                             f"ordered pairs of this collection), got {variations}")
        picks = np.random.default_rng(seed).choice(total, size=count, replace=False)
    starts = np.concatenate([[0], np.cumsum(sizes)])
    out = []
    for k in picks:
        g = int(np.searchsorted(starts, k, side="right")) - 1
        members, local = groups[g], int(k - starts[g])
        i, j = divmod(local, len(members) - 1)
        j += j >= i
        out.append((shapes[members[i]], shapes[members[j]]))
    return out


def _unique_file(base: str, seen: set, ext: str = ".obj") -> str:
    """``<base><ext>``, or ``<base>-2<ext>``, ``-3``... the first not in ``seen`` (added)."""
    name, k = f"{base}{ext}", 2
    while name in seen:
        name, k = f"{base}-{k}{ext}", k + 1
    seen.add(name)
    return name


def _variation_extension(location: str) -> str:
    """The format a variation of ``location`` is written in: the source's own where it
    carries more than geometry (``.ply``; ``.glb`` for GLB and GLTF, see
    :func:`cagekit.io.save_deformed`), else OBJ."""
    return ".obj" if location.startswith("synthetic:") else kept_extension(location)


def _items(pairs, shapes) -> list[Item]:
    """Items with unique output names: ``<source>__<target>.obj`` (``.ply`` or ``.glb``
    for such a source: :func:`_variation_extension`), each the shape's short
    name over the whole collection (:func:`~cagekit.batch.collection.short_names`, ``/``
    as ``-``), so that a pair keeps its file whatever the plan; ``-2`` on collisions."""
    short = {name: value.replace("/", "-")
             for name, value in short_names(s.name for s in shapes).items()}
    seen: set = set()
    return [Item(source, target,
                 _unique_file(f"{short[source.name]}__{short[target.name]}", seen,
                              _variation_extension(source.location)))
            for source, target in pairs]


def _cage_files(shapes) -> dict[str, str]:
    """Unique cage file names of a collection's shapes, by :attr:`Shape.name`.

    ``<stem>.obj``, ``-2`` on collisions as :func:`_items` names variations (``a/chair``
    and ``a-chair`` are both ``a-chair``), given in name order over the whole collection,
    so that a shape keeps its file whatever the plan.

    Parameters
    ----------
    shapes : list of Shape

    Returns
    -------
    dict of str to str
        File name under ``cages/`` of each shape's name.
    """
    seen: set = set()
    return {shape.name: _unique_file(shape.stem, seen)
            for shape in sorted(shapes, key=lambda s: s.name)}


# ------------------------------------------------------------------------------ one item


def deform_item(source: str, target: str, method: str = "cage", seed: int = 0,
                cage: tuple[ArrayLike, ArrayLike] | None = None,
                deformer: _Deformer | None = None, coords: str = "mvc") -> dict[str, Any]:
    """Make one variation: a pure function of its arguments, run by a worker.

    BLAS runs single-threaded inside (``threadpoolctl``): OpenBLAS's results depend on its
    thread count in the last bits, which the optimisation amplifies, so without the limit
    a Dask worker (one thread) and a pool worker (all cores) gave different variations.
    Results are identical across worker counts and engines on machines of one CPU type;
    different CPUs (other BLAS kernels) may differ in the last bits and beyond.

    Parameters
    ----------
    source, target : str
        :attr:`Shape.location` of each.
    method : {"cage", "scale", "model"}
    seed : int
    cage : (cage_v (k, 3) float64, cage_f (c, 3) int64), optional
        The source's cage in its own frame, when known (``cage``); else it is fitted here
        exactly as :func:`cagekit.deform` fits one, and returned for reuse.
    deformer : callable, optional
        For ``model``: ``deformer(V_src, F_src, V_tgt, F_tgt, seed) -> DeformResult``
        (``cagekit_learn.inference.ModelDeformer``).
    coords : {"mvc", "green"}, default "mvc"
        The coordinates of ``cage`` (:func:`cagekit.deform`'s ``coords``).

    Returns
    -------
    dict
        ``status`` ("ok" or "failed"), ``error`` (one line or ""), and for "ok" the
        ``vertices`` (n, 3) float64 and ``faces`` of the variation, the figures of
        :func:`cagekit.evaluate` (``cd``, ``dcotlap``, part non-affinity, planarity),
        ``deformed_by`` (the result's method), the ``cage`` used (or None), ``seconds``
        (the whole item) and ``cage_seconds`` (the fit, 0 when the cage was given);
        ``warnings``, those the item issued, as ``(message, category, filename, lineno)``
        for :func:`amplify` to issue again where the batch runs (a worker's own stderr
        is not the command's; an item run in a thread other than the main one leaves its
        warnings where they are issued).
    """
    start = time.perf_counter()
    out: dict[str, Any] = {"status": "failed", "error": "", "cage": None,
                           "cage_seconds": 0.0}
    with _recorded_warnings() as caught:
        try:
            figures, result, Fs = _limited(source, target, method, seed, cage, deformer,
                                           out, coords)
        except Exception as exc:  # noqa: BLE001 - one item fails, never the batch
            figures = None
            out["error"] = one_line(exc)
    out["warnings"] = _taken(_STARTUP_WARNINGS) + [_portable(w) for w in caught]
    if figures is None:
        out["seconds"] = time.perf_counter() - start
        return out
    out.update({name: getattr(figures, name) for name in _METRICS})
    out.update(status="ok", vertices=result.vertices, faces=Fs,
               seconds=time.perf_counter() - start)
    return out


def _limited(*args):
    """:func:`_deform_and_score` on one BLAS thread (and the worker's numba threads)."""
    from threadpoolctl import threadpool_limits

    if _WORKER_NUMBA_THREADS is not None:
        import numba

        numba.set_num_threads(_WORKER_NUMBA_THREADS)
    with threadpool_limits(limits=1, user_api="blas"):
        return _deform_and_score(*args)


@contextlib.contextmanager
def _recorded_warnings():
    """Record the warnings issued in the block (yields the list), on the main thread only:
    ``warnings.catch_warnings`` is process-wide, so items in threads (a Dask worker of
    several threads) leave their warnings to the worker, as before."""
    if threading.current_thread() is not threading.main_thread():
        yield []
        return
    with warnings.catch_warnings(record=True) as caught:
        yield caught


def _taken(kept: list) -> list:
    """The items of ``kept``, which is emptied."""
    taken = list(kept)
    del kept[: len(taken)]
    return taken


def _portable(warning) -> tuple:
    """A recorded warning as ``(message, category, filename, lineno)``, fit to return from
    a worker (a category that cannot be pickled travels as UserWarning)."""
    category = warning.category
    try:
        pickle.dumps(category)
    except Exception:  # noqa: BLE001 - a local class, say
        category = UserWarning
    return str(warning.message), category, warning.filename, warning.lineno


def _deform_and_score(source, target, method, seed, cage, deformer, out, coords):
    """The item's work (see :func:`deform_item`); the fitted cage and its time in ``out``."""

    Vs, Fs = _loaded("source", source)
    Vt, Ft = _loaded("target", target)
    if method == "model":
        result = deformer(Vs, Fs, Vt, Ft, seed)
    elif method == "scale":
        result = deform(Vs, Fs, Vt, Ft, options=DeformOptions(method="scale"))
    elif method == "cage":
        if cage is None:
            t0 = time.perf_counter()
            cage = _fit(Vs, Fs, seed)
            out["cage_seconds"] = time.perf_counter() - t0
        result = deform(Vs, Fs, Vt, Ft, *cage,
                        options=DeformOptions(seed=seed, check=False, coords=coords))
        out["cage"] = cage
    else:
        raise InputError(f"unknown method {method!r}; available: {', '.join(METHODS)}")
    figures = evaluate(Vs, Fs, Vt, Ft, result.vertices, seed=seed,
                       frames=(result.source_frame, result.target_frame))
    crossings = part_crossings(Vs, Fs, result.vertices)
    out.update(crossing_parts=crossings.count, crossing_pairs=crossings.named(),
               deformed_by=result.method)
    return figures, result, Fs


def _loaded(role, location):
    try:
        return load_shape_of(location)
    except InputError as exc:
        raise InputError(f"{role} {exc}") from None


def _fit(Vs, Fs, seed):
    """The cage :func:`cagekit.deform` would fit, in the source's own frame."""

    frame = Frame.of(Vs, name="the source")
    cage_n, cage_f, _ = fit_cage(frame.to_unit(Vs), Fs, faces=CAGE_FACES, seed=seed,
                                 samples=5000, report=False)
    return frame.to_world(cage_n), cage_f


# ---------------------------------------------------------------------------- manifest


class _Manifest:
    """The batch's rows, rewritten atomically (CSV and JSON) after every change."""

    def __init__(self, folder):
        self.folder = folder
        self.rows: dict[tuple[str, str], dict] = {}
        self.cages: dict[str, dict] = {}
        path = os.path.join(folder, "manifest.json")
        if os.path.exists(path):
            try:
                data = json.loads(read_text(path))
                self.rows = {(r["source"], r["target"]): r for r in data["items"]}
                self.cages = dict(data.get("cages", {}))
            except (ValueError, KeyError, TypeError):
                raise InputError("the manifest of an earlier run cannot be read; move it "
                                 "away to start afresh", path) from None

    def save(self, order):
        rows = [self.rows[key] for key in order if key in self.rows]
        with atomic_output(os.path.join(self.folder, "manifest.json")) as tmp:
            with open(tmp, "w", encoding="utf-8") as fh:
                json.dump({"items": rows, "cages": self.cages}, fh, indent=1)
        with atomic_output(os.path.join(self.folder, "manifest.csv")) as tmp:
            with open(tmp, "w", encoding="utf-8", newline="") as fh:
                writer = csv.DictWriter(fh, fieldnames=COLUMNS, extrasaction="ignore")
                writer.writeheader()
                writer.writerows(rows)


def _verdict(row, max_nonaffinity, max_cd, max_crossings) -> tuple[str, str]:
    """The plausibility filter: ``(status, reason)`` of a row's figures.

    ``"rejected"`` with every reason, ``"; "`` between them (parts that cross, a bent part,
    a Chamfer distance too large), or ``("ok", "")``; a failed row stays failed.
    """
    if row["status"] == "failed":
        return "failed", ""
    reasons = []
    if row["crossing_parts"] > max_crossings:
        reasons.append(f"parts cross: {row['crossing_pairs']}")
    if row["parts"] >= 2 and row["part_nonaffinity_worst"] > max_nonaffinity:
        reasons.append(f"part bent {100 * row['part_nonaffinity_worst']:.1f}% > "
                       f"{100 * max_nonaffinity:.1f}%")
    if row["cd"] > max_cd:
        reasons.append(f"CD x1e2 {100 * row['cd']:.2f} > {100 * max_cd:.2f}")
    return ("rejected" if reasons else "ok"), "; ".join(reasons)


def _done(row, item, method, seed, coords, folder, drop_rejected) -> bool:
    """An earlier run's row that this run can keep as it is."""
    same = (row.get("method") == method and row.get("seed") == seed
            and row.get("coords", "mvc") == coords
            and row.get("source_hash") == item.source.fingerprint
            and row.get("target_hash") == item.target.fingerprint
            and row.get("output") == item.output)
    if not same:
        return False
    if row["status"] == "failed":  # the item's own failure; a dead worker's is redone
        return not str(row.get("error", "")).startswith(_WORKER_FAILED)
    if "crossing_parts" not in row:  # an earlier version's row: no crossing test
        return False
    return os.path.exists(os.path.join(folder, "variations", item.output)) or (
        os.path.exists(os.path.join(folder, "rejected", item.output)) or drop_rejected)


class _Cages:
    """The sources' cages under ``cages/``, each reused only for the source it was fitted to.

    Every shape of the collection has its own file (:func:`_cage_files`). The manifest's
    ``cages`` map records, by source name, the ``file``, the source's content ``hash``
    when the cage was fitted, and the cage file's own ``cage_hash``. An earlier run's
    entry is kept only when all three still hold (the file is this shape's, the source
    is unchanged, the file is the one written); any other cage is fitted again.
    """

    def __init__(self, folder, shapes, manifest):
        self.folder, self.manifest = folder, manifest
        self.files = _cage_files(shapes)
        self._loaded = {}  # source name -> its cage, read once a run
        hashes = {shape.name: shape.fingerprint for shape in shapes}
        manifest.cages = {name: entry for name, entry in manifest.cages.items()
                          if self._valid(entry, self.files.get(name), hashes.get(name))}

    def _path(self, file: str) -> str:
        return os.path.join(self.folder, "cages", file)

    def _valid(self, entry, file, source_hash) -> bool:
        """An earlier run's entry that still names this source's own, unchanged cage."""
        if not isinstance(entry, dict) or file is None or entry.get("file") != file \
                or entry.get("hash") != source_hash:
            return False
        try:
            return entry.get("cage_hash") == file_hash(self._path(file))
        except OSError:  # missing or unreadable: fitted again
            return False

    def has(self, name: str) -> bool:
        """Whether the source ``name`` has a cage to reuse."""
        return name in self.manifest.cages

    def load(self, shape):
        """The cage of ``shape``, ``(cage_v (k, 3) float64, cage_f (c, 3) int64)``, or
        None when it has none to reuse."""

        entry = self.manifest.cages.get(shape.name)  # kept only for this very source
        if entry is None:
            return None
        if shape.name not in self._loaded:
            self._loaded[shape.name] = load_mesh(self._path(entry["file"]))
        return self._loaded[shape.name]

    def save(self, shape, cage) -> None:
        """Write the cage fitted to ``shape`` (atomically) and record it; the manifest is
        saved by the caller."""

        file = self.files[shape.name]
        save_mesh(self._path(file), *cage)
        self.manifest.cages[shape.name] = {"file": file, "hash": shape.fingerprint,
                                           "cage_hash": file_hash(self._path(file))}


# ---------------------------------------------------------------------------- the batch


def amplify(collection: str, out_dir: str, *, variations: int | None = None,
            pairs: str | None = None, method: str = "cage", deformer: _Deformer | None = None,
            category_by: str | None = None, seed: int = 0, workers: int | None = None,
            executor: cf.Executor | None = None, max_nonaffinity: float = MAX_NONAFFINITY,
            max_cd: float = MAX_CD, max_crossings: int = MAX_CROSSINGS,
            drop_rejected: bool = False,
            contact_sheet_path: str | None = None,
            progress: Callable[[int, int], object] | None = None,
            coords: str = "mvc") -> list[dict[str, Any]]:
    """Make variations of a collection; resume an earlier run in the same folder.

    Parameters
    ----------
    collection : str
        A folder of meshes (recursive) or ``synthetic:<family>:<count>``
        (:func:`cagekit.batch.collection.find_shapes`).
    out_dir : str
        Output folder, outside the collection: ``variations/<source>__<target>.obj``,
        ``rejected/`` (the rejected ones, unless ``drop_rejected``), ``cages/<source>.obj``
        (each source's cage, fitted once; ``-2``... when two names flatten to one file
        name), ``manifest.csv`` and ``manifest.json`` (one row per item, columns
        :data:`COLUMNS`; the JSON also lists the cages, each with its file, its source's
        hash and its own).
    variations, pairs, category_by, seed
        As :func:`plan_pairs` takes them; ``seed`` also seeds each item.
    method : {"cage", "scale", "model"}
        ``model`` needs ``deformer`` (see :func:`deform_item`).
    workers : int, optional
        Local processes (default: every core), never more than the items to do or the
        cores (a :class:`~cagekit.errors.CagekitWarning` says so when a number asked for is
        cut); 1 runs the items in this process. Ignored when ``executor`` is given.
    executor : concurrent.futures.Executor, optional
        Where the items run instead (a cluster's executor, for example
        ``dask.distributed.Client.get_executor()``); it must reach the collection's files
        at the same paths.
    max_nonaffinity, max_cd : float
        The plausibility filter (:data:`MAX_NONAFFINITY`, :data:`MAX_CD`).
    max_crossings : int, default :data:`MAX_CROSSINGS`
        The filter's third test: more pairs of parts than this that were apart in the
        source and pass through each other in the variation
        (:func:`cagekit.batch.crossing.part_crossings`) reject it. The manifest's
        ``reason`` says why a variation was rejected (``parts cross: 2 and 3``).
    drop_rejected : bool, default False
        Do not keep the rejected variations' meshes.
    contact_sheet_path : str, optional
        A PNG of the variations (:func:`contact_sheet`).
    progress : callable, optional
        ``progress(done, total)`` after each item.
    coords : {"mvc", "green"}, default "mvc"
        The coordinates of method ``cage`` (a changed choice redoes the items).

    Returns
    -------
    list of dict
        The manifest's rows, in plan order.

    Raises
    ------
    InputError
        Bad options, an unreadable collection, an unknown name in the pairs file, an
        output folder that is the collection or lies in it (or holds it in one of its
        sub-folders above), worker processes that cannot be started.
    KeyboardInterrupt
        Re-raised after the manifest is saved (items in flight are dropped).

    Examples
    --------
    >>> rows = amplify("synthetic:vases:3", "out/vases", variations=2, workers=1)
    ... # doctest: +SKIP
    >>> [r["status"] for r in rows]  # doctest: +SKIP
    ['ok', 'ok']
    """
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; available: {', '.join(METHODS)}")
    if method == "model" and deformer is None:
        raise InputError("method model needs a trained model (deformer)")
    if coords not in COORDS:
        raise InputError(f"unknown coordinates {coords!r}; available: {', '.join(COORDS)}")
    if coords != "mvc" and method != "cage":
        raise InputError(f"coords {coords} applies to method cage only")
    _check_out_dir(collection, out_dir)
    shapes = find_shapes(collection, exclude=[out_dir])
    items = _items(plan_pairs(shapes, variations=variations, pairs=pairs,
                              category_by=category_by, seed=seed), shapes)
    made = missing_folders(out_dir)
    try:
        for sub in ("variations", "cages") + (() if drop_rejected else ("rejected",)):
            with output_folder(os.path.join(out_dir, sub)):  # one line if it cannot be made
                pass
        manifest = _Manifest(out_dir)
        order = [(it.source.name, it.target.name) for it in items]
        kept, todo = {}, []
        for key, item in zip(order, items):
            row = manifest.rows.get(key)
            if row is not None and _done(row, item, method, seed, coords, out_dir,
                                         drop_rejected):
                kept[key] = row
            else:
                todo.append(item)
        manifest.rows = kept  # rows of other pairs, or of changed inputs, are dropped
        for row in kept.values():  # a changed filter applies to kept rows too
            _refile(row, _verdict(row, max_nonaffinity, max_cd, max_crossings), out_dir,
                    drop_rejected)
        cages = _Cages(out_dir, shapes, manifest)
        manifest.save(order)
        runner = _Runner(items, todo, manifest, cages, order, out_dir, method, seed,
                         deformer, (max_nonaffinity, max_cd, max_crossings), drop_rejected,
                         progress, coords)
        runner.run(executor, workers)
    except BaseException:
        _unmake_if_nothing_done(out_dir, made)
        raise
    rows = [manifest.rows[key] for key in order]
    if contact_sheet_path:
        contact_sheet(rows, items, out_dir, contact_sheet_path)
    return rows


def _unmake_if_nothing_done(out_dir: str, made: list[str]) -> None:
    """After a failed or interrupted run: remove the output folder this run made (``made``,
    deepest first, from :func:`cagekit.io.files.missing_folders`) when nothing in it can
    be resumed: no mesh in its sub-folders and no item in its manifest. A folder that was
    there before, or that holds finished work, is left as it is; folders are removed only
    when empty, and a failure here never hides the run's own error."""
    try:
        out_dir = os.path.realpath(out_dir)
        subfolders = [os.path.join(out_dir, sub) for sub in _SUBFOLDERS]
        if not made or any(files for f in subfolders for _, _, files in os.walk(f)):
            return
        manifest = os.path.join(out_dir, "manifest.json")
        if os.path.exists(manifest) and json.loads(read_text(manifest)).get("items"):
            return  # failed items, or rejected ones dropped: finished without a mesh
        for name in ("manifest.json", "manifest.csv"):
            with contextlib.suppress(OSError):
                os.remove(os.path.join(out_dir, name))
        remove_empty_folders(subfolders + made)  # a stray file keeps its folder
    except Exception:  # noqa: BLE001 - the run's own error is the one to report
        return


def _load_variation(path: str) -> tuple[np.ndarray, np.ndarray]:
    """A variation this batch wrote, ``(V (n, 3) float64, F (m, 3) int64)``, read with every
    :class:`~cagekit.errors.MeshFileWarning` silenced: it is a copy of its source's file, so
    what that file lacks (faces of two vertices, say) was said when the source was read."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MeshFileWarning)
        return load_mesh(path)


#: the sub-folders a batch writes meshes into
_SUBFOLDERS = ("variations", "rejected", "cages")


def _inside(path: str, folder: str) -> bool:
    """Whether resolved ``path`` is resolved ``folder`` or lies below it."""
    return path == folder or path.startswith(folder.rstrip(os.sep) + os.sep)


def _check_out_dir(collection: str, out_dir: str) -> None:
    """Refuse an output folder that is the collection or lies in it (the next run would
    read its variations and cages as shapes), or that holds the collection in a folder a
    batch writes into (an input would be overwritten).

    Raises
    ------
    InputError
        Naming ``out_dir``.
    """
    if collection.startswith(SYNTHETIC_PREFIX) or not os.path.isdir(collection):
        return  # not a folder: find_shapes says so
    root, out = os.path.realpath(collection), os.path.realpath(out_dir)
    if _inside(out, root):
        where = "is the collection" if out == root else f"lies in the collection {collection}"
        raise InputError(f"the output folder {where}; choose one outside it (its meshes "
                         "would be read as shapes)", out_dir)
    for sub in _SUBFOLDERS:
        if _inside(root, os.path.join(out, sub)):
            raise InputError(f"the collection {collection} lies in the output's {sub}/ "
                             "folder, which a batch writes into; choose another output "
                             "folder", out_dir)


def _refile(row, verdict, folder, drop_rejected):
    """Put a kept variation where its (possibly new) ``(status, reason)`` says:
    variations/, rejected/, or nowhere (rejected with ``drop_rejected``)."""
    if row["status"] == "failed":
        return
    status = verdict[0]
    row["status"], row["reason"] = verdict
    here = [os.path.join(folder, sub, row["output"]) for sub in ("variations", "rejected")]
    found = next((path for path in here if os.path.exists(path)), None)
    if status == "rejected" and drop_rejected:
        if found is not None:
            remove_deformed(found)  # with its own .mtl
        return
    wanted = here[0] if status == "ok" else here[1]
    if found is not None and found != wanted:
        move_deformed(found, wanted)  # with its own .mtl, textures reachable


def prepare_worker() -> None:
    """Ready a worker process; call it in the process's main thread before any item.

    Imports pymeshlab there: imported and first used in another thread (a Dask worker's
    task thread), it leaves glibc's heap to report "malloc_consolidate(): unaligned
    fastbin chunk detected" and abort when the process exits (reproduced without Dask or
    numba; imported in the main thread first, it never happens). Runs numba's kernels on
    one thread, as the workers share the cores (numba's thread count does not change
    results). Warnings issued meanwhile (numba's about its threading layer, say) are kept
    and returned with the next item (:func:`deform_item`), so that they reach the batch.
    """
    global _WORKER_NUMBA_THREADS
    with _recorded_warnings() as caught:
        import numba
        import pymeshlab  # noqa: F401 - imported for its side effect, see above

        _WORKER_NUMBA_THREADS = 1
        numba.set_num_threads(1)
    _STARTUP_WARNINGS.extend(_portable(w) for w in caught)


#: numba threads of an item in a prepared worker (:func:`prepare_worker`); None: numba's
#: default. numba's thread count is per thread, and a Dask worker runs items in a task
#: thread, so :func:`deform_item` sets it again there (2 Dask workers of 2 threads each
#: on 2 cores ran items 35% slower than the pool's).
_WORKER_NUMBA_THREADS = None
#: warnings :func:`prepare_worker` caught, not yet returned with an item
_STARTUP_WARNINGS: list = []


def process_pool(workers: int) -> cf.ProcessPoolExecutor:
    """The local pool :func:`amplify` runs on: ``workers`` processes, each prepared by
    :func:`prepare_worker`, leaving Ctrl-C to the main process and ending when it ends.

    Spawned, not forked: a fork of a process whose numba kernels started OpenMP threads
    is killed by the OpenMP runtime. Start workers by submitting with SIGINT held
    (:func:`_sigint_held`), and stop the pool with :func:`_stop_pool` when the batch
    does not finish.

    Raises
    ------
    OSError
        The pool's pipes or locks cannot be made (too many open files, say).
    """
    return cf.ProcessPoolExecutor(max_workers=workers,
                                  mp_context=multiprocessing.get_context("spawn"),
                                  initializer=_pool_worker, initargs=(os.getpid(),))


def _pool_worker(parent: int) -> None:
    """A pool worker: Ctrl-C left to the main process (which stops the batch), ended with
    process ``parent`` (:func:`_end_with`), then :func:`prepare_worker`."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _end_with(parent)
    prepare_worker()


def _end_with(parent: int) -> None:
    """End this process as soon as process ``parent`` (its parent) ends, even by SIGKILL.

    On Linux the kernel sends SIGKILL at once (``prctl(PR_SET_PDEATHSIG)``); everywhere, a
    daemon thread checks every half second that the parent is still the one it was (an
    orphan is adopted by another process) and ends the process when not.
    """
    _parent_death_signal(signal.SIGKILL)
    if os.getppid() != parent:  # gone already, before the signal was asked for
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent,), name="cagekit-parent-watch",
                     daemon=True).start()


def _parent_death_signal(signum: int) -> None:
    """Ask the kernel (Linux) to send ``signum`` to this process when its parent ends; a
    no-op elsewhere or when ``prctl`` cannot be called."""
    if not sys.platform.startswith("linux"):
        return
    import ctypes

    PR_SET_PDEATHSIG = 1
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, int(signum), 0, 0, 0)
    except (OSError, AttributeError):  # no libc prctl: the watching thread remains
        pass


def _watch_parent(parent: int, interval: float = 0.5) -> None:
    """Wait until this process's parent is no longer ``parent``; then end the process."""
    while os.getppid() == parent:
        time.sleep(interval)
    os._exit(1)


@contextlib.contextmanager
def _sigint_held():
    """Hold SIGINT back in this thread while the block runs.

    A worker process started in the block inherits the mask: a Ctrl-C, which a terminal
    sends to every process of the group, then never reaches a worker still importing
    (before its initializer ignores SIGINT it would print a traceback). This process
    still gets it (another of its threads takes it, and the main thread's handler runs).
    """
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


#: how often (seconds) a batch on a pool or an executor looks for a Ctrl-C that came
#: (:func:`cagekit.interrupts.sigint_deferred`: one raised inside ``concurrent.futures``
#: could leave a future's lock held and the interpreter's exit waiting for ever)
_INTERRUPT_POLL = 0.1


def _stop_pool(pool: cf.ProcessPoolExecutor) -> None:
    """Stop a :func:`process_pool` now: queued items cancelled, its processes ended (the
    items they run are dropped), without waiting for them to finish.

    A worker ended while it writes a large result (more than a pipe holds) leaves the
    pool's manager thread waiting for the rest of that message in ``recv``, and Python
    joins that thread at exit, so the process would never end. The parent still holds the
    write end of the result pipe, so no end-of-file ever comes; closing it once the
    workers are gone gives ``recv`` its end-of-file and the thread ends. It is waited for
    here, so that it is not still closing its pipes when Python's exit hook writes to one
    (Python 3.11 then prints an ignored ``Bad file descriptor`` at exit).
    """
    terminate = getattr(pool, "terminate_workers", None)  # Python 3.14
    if terminate is not None:
        terminate()
        return
    processes = list((getattr(pool, "_processes", None) or {}).values())
    results = getattr(pool, "_result_queue", None)  # shutdown() forgets both
    manager = getattr(pool, "_executor_manager_thread", None)
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.terminate()
    for process in processes:
        process.join(5)
        if process.is_alive():
            process.kill()
            process.join(5)
    writer = getattr(results, "_writer", None)
    if writer is not None:
        writer.close()
    if manager is not None:
        manager.join(10)


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system has one).

    Returns
    -------
    int
        At least 1.

    Examples
    --------
    >>> usable_cores() >= 1
    True
    """
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


def worker_count(workers: int | None, pending: int | None = None,
                 default: int | None = None) -> int:
    """The local worker processes to start: a pool's or a local Dask cluster's.

    Parameters
    ----------
    workers : int or None
        Asked for; None takes ``default``.
    pending : int, optional
        Items to do: no more workers than that.
    default : int, optional
        Workers when none are asked for (None: every core).

    Returns
    -------
    int
        ``workers`` cut to the cores (and ``pending``), at least 1; a
        :class:`~cagekit.errors.CagekitWarning` when a number asked for is cut.

    Raises
    ------
    InputError
        ``workers`` below 1.

    Examples
    --------
    >>> worker_count(None, pending=1)
    1
    """
    cpus = usable_cores()
    limit = cpus if pending is None else min(cpus, pending)
    if workers is None:
        return max(1, min(limit, cpus if default is None else default))
    asked = int(workers)
    if asked < 1:
        raise InputError(f"workers must be at least 1, got {workers}")
    count = max(1, min(asked, limit))
    if count < asked:
        todo = "" if pending is None else f"{pending} item(s) to do, "
        warnings.warn(f"{asked} workers asked for, {count} started ({todo}{cpus} core(s))",
                      CagekitWarning, stacklevel=3)
    return count


def _cannot_start(workers: int, exc: OSError) -> InputError:
    """The one-line error of worker processes that cannot be started."""
    return InputError(f"cannot start {workers} worker processes ({one_line(exc)}); ask for "
                      "fewer workers, or 1 to run the items in this process")


def _starting(pool: cf.ProcessPoolExecutor, workers: int):
    """``pool.submit`` with SIGINT held (:func:`_sigint_held`: the submit may start a
    worker); a worker that cannot be started is an InputError (:func:`_cannot_start`)."""

    def submit(fn, *args):
        try:
            with _sigint_held():
                return pool.submit(fn, *args)
        except OSError as exc:
            raise _cannot_start(workers, exc) from None

    return submit


class _Runner:
    """Submits items, a bounded number at a time, and records each as it finishes."""

    def __init__(self, items, todo, manifest, cages, order, folder, method, seed, deformer,
                 limits, drop_rejected, progress, coords):
        self.todo, self.manifest, self.order, self.folder = todo, manifest, order, folder
        self.method, self.seed, self.deformer = method, seed, deformer
        self.coords = coords
        self.limits = limits  # (max_nonaffinity, max_cd, max_crossings)
        self.drop_rejected, self.progress = drop_rejected, progress
        self.total, self.finished = len(items), len(items) - len(todo)
        self.cages = cages
        self.relayed: set = set()

    def _cage_of(self, shape):
        return self.cages.load(shape) if self.method == "cage" else None

    def _next(self, pending, fitting):
        """The first pending item whose source's cage is known or not being fitted."""
        for k, item in enumerate(pending):
            name = item.source.name
            if self.method != "cage" or self.cages.has(name) or name not in fitting:
                return pending.pop(k)
        return None

    def run(self, executor, workers):
        """Run the items to do: on ``executor``, else on a pool of ``workers`` processes
        (:func:`worker_count`), or in this process for one."""
        if self.progress is not None:
            self.progress(self.finished, self.total)
        if not self.todo:
            return
        if executor is not None:
            self._loop(executor.submit, 2 * (workers or 2))
            return
        workers = worker_count(workers, len(self.todo))
        if workers == 1:
            for item in self.todo:
                self._record(item, deform_item(*self._args(item)))
            return
        try:
            pool = process_pool(workers)
        except OSError as exc:
            raise _cannot_start(workers, exc) from None
        try:
            self._loop(_starting(pool, workers), 2 * workers)
            pool.shutdown(wait=True)
        except BaseException:  # Ctrl-C, an error: no worker outlives the batch
            _stop_pool(pool)
            raise

    def _loop(self, submit, window):
        """Submit items, ``window`` at most in flight, and record each as it finishes. A
        Ctrl-C is held back inside (:func:`cagekit.interrupts.sigint_deferred`) and raised
        before each round of submissions, at least every :data:`_INTERRUPT_POLL` seconds."""
        with sigint_deferred() as interrupted:
            self._rounds(submit, window, interrupted)

    def _rounds(self, submit, window, interrupted):
        """The rounds of :meth:`_loop`; the futures still running when it ends are
        cancelled."""
        pending, fitting, running = list(self.todo), set(), {}
        try:
            while pending or running:
                interrupted()
                while pending and len(running) < window:
                    item = self._next(pending, fitting)
                    if item is None:
                        break
                    if self.method == "cage" and not self.cages.has(item.source.name):
                        fitting.add(item.source.name)
                    running[submit(deform_item, *self._args(item))] = item
                done, _ = cf.wait(running, timeout=_INTERRUPT_POLL,
                                  return_when=cf.FIRST_COMPLETED)
                # before recording: a SIGTERM sent to the whole group (`timeout`) kills the
                # workers too, and their items would be recorded as failed
                interrupted()
                for future in done:
                    item = running.pop(future)
                    try:
                        result = future.result()
                    except Exception as exc:  # noqa: BLE001 - a worker died (memory, crash)
                        result = {"status": "failed", "error": f"{_WORKER_FAILED}: "
                                  f"{one_line(exc)}", "cage": None, "seconds": 0.0,
                                  "cage_seconds": 0.0}
                    fitting.discard(item.source.name)
                    self._record(item, result)
        finally:
            for future in running:
                future.cancel()

    def _relay(self, caught, pair=None):
        """Issue again, here, the warnings an item issued in its worker: each message once
        a batch (each worker issues a library's one-time warnings once). A deformation's
        own warnings (cagekit's, but for a file's) are about one pair: ``pair`` names it."""
        for message, category, filename, lineno in caught:
            if (pair is not None and issubclass(category, CagekitWarning)
                    and not issubclass(category, MeshFileWarning)):
                message = f"{pair}: {message}"
            if (category, message) not in self.relayed:
                self.relayed.add((category, message))
                warnings.warn_explicit(message, category, filename, lineno)

    def _args(self, item):
        return (item.source.location, item.target.location, self.method, self.seed,
                self._cage_of(item.source), self.deformer, self.coords)

    def _record(self, item, result):

        row = {"source": item.source.name, "target": item.target.name,
               "output": item.output, "method": self.method, "coords": self.coords,
               "seed": self.seed,
               "status": result["status"], "reason": "", "error": result["error"],
               "seconds": round(result.get("seconds", 0.0), 4),
               "cage_seconds": round(result.get("cage_seconds", 0.0), 4),
               "source_hash": item.source.fingerprint, "target_hash": item.target.fingerprint}
        for name in _FIGURES:
            row[name] = result.get(name)
        row["deformed_by"] = result.get("deformed_by", "")
        self._relay(result.get("warnings", ()), f"{item.source.name} -> {item.target.name}")
        if result["status"] == "ok":
            row["status"], row["reason"] = _verdict(row, *self.limits)
            if row["status"] == "ok" or not self.drop_rejected:
                folder = "variations" if row["status"] == "ok" else "rejected"
                path = os.path.join(self.folder, folder, item.output)
                try:
                    with warnings.catch_warnings(record=True) as caught:
                        warnings.simplefilter("always")
                        _save_variation(path, result["vertices"], result["faces"],
                                        item.source.location)
                    # what a source's file loses in the output's format, once a source:
                    # without the output's name, the messages of one source are equal
                    self._relay([(str(w.message).removeprefix(f"{path}: "), w.category,
                                  w.filename, w.lineno) for w in caught])
                except InputError as exc:  # this item failed, not the batch
                    row["status"], row["reason"], row["error"] = "failed", "", one_line(exc)
            if result.get("cage") is not None and not self.cages.has(item.source.name):
                self.cages.save(item.source, result["cage"])
        self.manifest.rows[(item.source.name, item.target.name)] = row
        self.manifest.save(self.order)
        self.finished += 1
        if self.progress is not None:
            self.progress(self.finished, self.total)


def _save_variation(path: str, V: np.ndarray, F: np.ndarray, source: str) -> None:
    """Write a variation; from a source file, as a copy of it that keeps its UVs,
    materials, groups and normals (:func:`cagekit.io.save_deformed`)."""
    if source.startswith("synthetic:"):
        save_mesh(path, V, F)
    else:
        save_deformed(path, V, F, source)


# ------------------------------------------------------------------------ contact sheet


def contact_sheet(rows: Sequence[dict[str, Any]], items: Sequence[Item], folder: str, path: str,
                  limit: int = 24, columns: int = SHEET_COLUMNS) -> str:
    """A PNG grid of the first ``limit`` finished items (:mod:`cagekit.batch.sheet`).

    Each tile shows the variation, its source and its target, the pair by short names
    (:func:`pair_title`), the figures the filter decided on (CD x1e2, the worst part's
    non-affinity, the crossing parts) and the status in its colour with the reason.
    Failed items are left out.

    Parameters
    ----------
    rows : list of dict
        Manifest rows (as :func:`amplify` returns them), in the order of ``items``.
    items : list of Item
    folder : str
        The batch's output folder.
    path : str
        The PNG to write (atomically).
    limit : int, default 24
    columns : int, default :data:`~cagekit.batch.sheet.SHEET_COLUMNS`
        Tiles to a line, at most.

    Returns
    -------
    str
        ``path``.

    Raises
    ------
    InputError
        No finished variation to show.
    """
    short = short_names([i.source.name for i in items] + [i.target.name for i in items])
    tiles = []
    for row, item in zip(rows, items):
        sub = {"ok": "variations", "rejected": "rejected"}.get(row["status"])
        file = os.path.join(folder, sub or "", row["output"])
        if sub is None or not os.path.exists(file):
            continue
        tiles.append(Tile(load_shape_of(item.source.location),
                          load_shape_of(item.target.location), _load_variation(file),
                          pair_title(short[row["source"]], short[row["target"]],
                                     width=_SHEET_TITLE_CHARS),
                          _decisive_figures(row), row["status"], row.get("reason", ""),
                          _handed_on(row)))
        if len(tiles) == limit:
            break
    if not tiles:
        raise InputError("no finished variation to show on a contact sheet")
    return draw_contact_sheet(tiles, path, columns)


def _handed_on(row) -> str:
    """What made a model's item instead of the model, for its tile (``""``: the model)."""
    if row.get("method") != "model":
        return ""
    return {"scale": "box scaling", "cage": "a fitted cage"}.get(row.get("deformed_by"), "")


def pair_title(source: str, target: str, width: int = 40) -> str:
    """A pair's caption: ``source -> target``, names cut in their middle when the two do
    not fit in ``width`` characters: the longer one first, down to half the room each.

    Parameters
    ----------
    source, target : str
        Short names (:func:`~cagekit.batch.collection.short_names`).
    width : int, default 40

    Returns
    -------
    str

    Examples
    --------
    >>> pair_title("antiqueChair", "chair2")
    'antiqueChair → chair2'
    >>> title = pair_title("a" * 30, "b" * 30)
    >>> len(title), title.count("a"), title.count("b")
    (40, 15, 16)
    >>> title = pair_title("stool", "kush_nuba_camp_bench.dae.cached", width=34)
    >>> len(title), title[:18], title[-11:]
    (34, 'stool → kush_nuba_', '.dae.cached')
    """
    room = width - 3
    if len(source) + len(target) <= room:
        return f"{source} → {target}"
    shorter = min(len(source), len(target), room // 2)
    rooms = (shorter, room - shorter) if len(source) <= len(target) else (room - shorter,
                                                                          shorter)
    return f"{cut_middle(source, rooms[0])} → {cut_middle(target, rooms[1])}"


def _decisive_figures(row: dict[str, Any]) -> str:
    """The figures the filter decides on, one line (a source of one part has no worst part
    to decide on: its bend is in the manifest, and the sheet says "one part")."""
    parts = (f"worst part {100 * row['part_nonaffinity_worst']:.2f}%" if row["parts"] >= 2
             else "one part")
    return f"CD x1e2 {100 * row['cd']:.2f} · {parts} · crossing {row['crossing_parts']}"
