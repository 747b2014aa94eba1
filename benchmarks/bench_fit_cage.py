"""Automatic cages on real meshes: cagekit's ``fit_cage`` beside gpytoolbox's ``lazy_cage``.

Meshes: Debian's ``libcgal-demo`` (``apt-get install libcgal-demo``; the meshes are in
``/usr/share/doc/libcgal-dev/data.tar.gz``, unpacked by this script into ``--cache``). The
set below (``MESHES``) mixes closed and open meshes, several components, animals,
humanoids and mechanical parts.

For each mesh and each face budget (200 and 1,000) the script prints, for cagekit (method
``wrap``) and for ``gpytoolbox.copyleft.lazy_cage`` (``pip install -e .[bench]``; GPL, run
with its defaults, ``force_output=True``) on the same mesh in the same run: success, every
guarantee of :func:`cagekit.cage.fitting.cage_report` (checked the same way for both), the volume
ratio, the largest cage-to-shape distance over the diagonal, and seconds. Then the medians
and the share of meshes with every guarantee met.

Usage::

    python benchmarks/bench_fit_cage.py [--faces 200 1000] [--meshes elephant cow ...]
                                        [--skip-peer] [--json out.json]

Numbers go to docs/benchmarks.md by hand with the command that made them.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import tarfile
import time
import warnings

import numpy as np

TARBALL = "/usr/share/doc/libcgal-dev/data.tar.gz"

# name -> what it is (closed/open, components, kind)
MESHES = {
    "elephant": "animal",
    "camel": "animal",
    "cow": "animal",
    "bull": "animal",
    "pig": "animal",
    "elk": "animal",
    "lion": "animal",
    "dino": "animal",
    "triceratops": "animal",
    "diplodocus": "animal",
    "armadillo": "humanoid",
    "man": "humanoid",
    "mannequin-devil": "humanoid",
    "homer": "humanoid",
    "hand": "body part",
    "femur": "body part",
    "bones": "body parts, several components",
    "head": "body part, open",
    "nefertiti": "sculpture, open",
    "elephant-with-holes": "animal, open",
    "mushroom": "organic, open",
    "fandisk": "mechanical",
    "blade": "mechanical",
    "turbine": "mechanical",
    "rotor_small": "mechanical",
    "pinion": "mechanical",
    "anchor": "mechanical",
    "joint": "mechanical",
    "dragknob": "mechanical",
    "mech-holes-shark": "mechanical, open",
    "knot2": "knot",
    "blobby_3cc": "blob, three components",
    "boeing": "mechanical",
    "helmet": "mechanical, open",
}

CHECKS = ("closed_manifold", "outward", "components", "no_self_intersection",
          "encloses_vertices", "encloses_samples", "no_cut", "face_count")


def mesh_folder(cache: str) -> str:
    """The unpacked ``data/meshes`` folder of libcgal-demo (unpacked once into ``cache``)."""
    folder = os.path.join(cache, "data", "meshes")
    if not os.path.isdir(folder):
        if not os.path.exists(TARBALL):
            raise SystemExit(f"{TARBALL} not found: apt-get install libcgal-demo")
        os.makedirs(cache, exist_ok=True)
        with tarfile.open(TARBALL) as tar:
            members = [m for m in tar.getmembers() if m.name.startswith("data/meshes/")]
            tar.extractall(cache, members=members, filter="data")
    return folder


def find_mesh(folder: str, name: str) -> str:
    for ext in (".off", ".ply", ".obj", ".stl"):
        path = os.path.join(folder, name + ext)
        if os.path.exists(path):
            return path
    raise SystemExit(f"{name}: not in {folder}")


def run_cagekit(v, f, faces):
    from cagekit.cage.fitting import CageFitError, fit_cage

    t = time.perf_counter()
    try:
        cv, cf, _ = fit_cage(v, f, faces=faces)
    except CageFitError as exc:
        return None, time.perf_counter() - t, str(exc)
    return (cv, cf), time.perf_counter() - t, ""


def run_lazy_cage(v, f, faces):
    from gpytoolbox.copyleft import lazy_cage

    t = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cv, cf = lazy_cage(v, f.astype(np.int32), num_faces=faces)
    except Exception as exc:  # a peer's failure is a result, not a crash of the benchmark
        return None, time.perf_counter() - t, f"{type(exc).__name__}: {exc}"
    if cv is None:
        return None, time.perf_counter() - t, "no cage"
    return (np.asarray(cv, float), np.asarray(cf, np.int64)), time.perf_counter() - t, ""


def evaluate(v, f, result, seconds, error, faces):
    from cagekit.cage.fitting import cage_report
    from cagekit.errors import InputError

    row = {"seconds": seconds, "error": error}
    try:
        report = None if result is None else cage_report(v, f, *result, faces=faces)
    except InputError as exc:  # for example an empty cage
        report, row["error"] = None, str(exc)
    if report is None:
        row.update(ok=False, checks={}, volume_ratio=None, max_distance=None, faces=None)
        return row
    row.update(ok=report.ok, checks=report.checks, volume_ratio=report.volume_ratio,
               max_distance=report.max_distance, faces=report.faces,
               volume_reference=report.volume_reference)
    return row


def fmt(x, spec):
    return "-" if x is None else format(x, spec)


def print_row(name, n_faces, who, row):
    failed = [c for c in CHECKS if row["checks"] and not row["checks"].get(c, True)]
    status = ("ok" if row["ok"] else
              ("error" if not row["checks"] else "FAILS " + ",".join(failed)))
    print(f"{name:<20} {n_faces:>7} {who:<9} {fmt(row['faces'], 'd'):>5} "
          f"{fmt(row['volume_ratio'], '.3f'):>7} {fmt(row['max_distance'], '.4f'):>7} "
          f"{row['seconds']:>7.2f}  {status}", flush=True)


def summary(rows, who, budget):
    sel = [r for r in rows if r["who"] == who and r["budget"] == budget]
    if not sel:
        return
    ok = [r for r in sel if r["ok"]]
    ratios = [r["volume_ratio"] for r in ok if r["volume_ratio"] is not None]
    dists = [r["max_distance"] for r in ok]
    secs = [r["seconds"] for r in sel]
    print(f"{who:<9} {budget:>5} faces: all guarantees {len(ok)}/{len(sel)} "
          f"({100 * len(ok) / len(sel):.0f}%), median volume ratio (guaranteed cages) "
          f"{fmt(statistics.median(ratios) if ratios else None, '.3f')}, median max distance "
          f"{fmt(statistics.median(dists) if dists else None, '.4f')}, median seconds "
          f"{statistics.median(secs):.2f}")
    closed = [r["volume_ratio"] for r in ok if r.get("volume_reference") == "shape"]
    if closed:
        print(f"{'':<9} {'':>5}        closed meshes only (ratio to the shape's volume): "
              f"{len(closed)}, median volume ratio {statistics.median(closed):.3f}")


def paired_summary(rows, budget):
    """Median volume ratios over the meshes where both methods met every guarantee."""
    def by_mesh(who):
        return {r["mesh"]: r for r in rows if r["who"] == who and r["budget"] == budget}

    ours, peer = by_mesh("cagekit"), by_mesh("lazy_cage")
    both = [m for m in ours if ours[m]["ok"] and m in peer and peer[m]["ok"]]
    if both:
        print(f"{budget:>5} faces, meshes where both meet every guarantee ({len(both)}): "
              f"median volume ratio cagekit "
              f"{statistics.median(ours[m]['volume_ratio'] for m in both):.3f}, lazy_cage "
              f"{statistics.median(peer[m]['volume_ratio'] for m in both):.3f}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--faces", type=int, nargs="+", default=[200, 1000])
    parser.add_argument("--meshes", nargs="+", default=list(MESHES))
    parser.add_argument("--cache", default="/tmp/cagekit-cgal")
    parser.add_argument("--skip-peer", action="store_true", help="cagekit only")
    parser.add_argument("--json", help="write every row to this file")
    args = parser.parse_args(argv)

    from cagekit.io import load_mesh

    folder = mesh_folder(args.cache)
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"python {platform.python_version()}")
    print(f"{'mesh':<20} {'faces':>7} {'method':<9} {'cage':>5} {'volume':>7} "
          f"{'maxdist':>7} {'seconds':>7}  guarantees")
    rows = []
    for name in args.meshes:
        v, f = load_mesh(find_mesh(folder, name))
        for budget in args.faces:
            runners = [("cagekit", run_cagekit)]
            if not args.skip_peer:
                runners.append(("lazy_cage", run_lazy_cage))
            for who, runner in runners:
                row = evaluate(v, f, *runner(v, f, budget), faces=budget)
                row.update(mesh=name, who=who, budget=budget, input_faces=len(f))
                print_row(name, len(f), who, row)
                rows.append(row)
    print()
    for budget in args.faces:
        for who in ("cagekit", "lazy_cage"):
            summary(rows, who, budget)
        paired_summary(rows, budget)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
