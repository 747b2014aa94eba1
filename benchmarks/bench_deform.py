"""Per-pair deformation: cagekit's cage method against the scaling baseline and nricp_amberg.

Runs the three methods of ``cagekit.deform`` (``cage``, ``scale``, ``nricp`` =
``trimesh.registration.nricp_amberg``) on the same source-target pairs in one process and
prints, per pair and in median, CD x 10^2 and dCotLap x 10^3 (DESIGN.md definitions,
``cagekit.evaluate``: 5,000 samples a surface, seed 0) and seconds. The pairs:

- procedural chairs, tables and vases of different proportions
  (``cagekit.datasets.synthetic``, seeds below);
- animals from Debian's ``libcgal-demo`` deformed onto each other (cow, bull,
  triceratops, diplodocus; the bull is mirrored in x to face +x like the others, since
  none of the methods rotates).

``cage-src`` is ``cage`` with ``reference="source"`` (the paper's reference). Then one
timing of ``cage`` on a ~10,000-vertex source (a chair at resolution 1.5) with a 200-face
cage, with the cage fitted inside the call and with the cage given.

Usage::

    python benchmarks/bench_deform.py [--cache DIR] [--picture PNG] [--json FILE]

``--cache`` is where ``/usr/share/doc/libcgal-dev/data.tar.gz`` is (or will be)
unpacked; without the archive the animal pairs are skipped.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tarfile
import time

import numpy as np

import cagekit
from cagekit.datasets import synthetic
from cagekit.io import load_mesh

CGAL_ARCHIVE = "/usr/share/doc/libcgal-dev/data.tar.gz"
SYNTHETIC_PAIRS = [
    ("chair", 0, 1), ("chair", 2, 3), ("chair", 4, 5), ("chair", 6, 7), ("chair", 8, 9),
    ("table", 0, 1), ("table", 2, 3), ("table", 4, 5), ("table", 6, 7),
    ("vase", 0, 1), ("vase", 2, 3), ("vase", 4, 5), ("vase", 6, 7),
]
ANIMAL_PAIRS = [
    ("cow", "bull"), ("bull", "cow"), ("cow", "triceratops"), ("triceratops", "cow"),
    ("triceratops", "bull"), ("cow", "diplodocus"), ("triceratops", "diplodocus"),
]
METHODS = ("scale", "nricp", "cage", "cage-src")
#: cage-src is method cage with reference="source" (the paper's reference; see
#: cagekit/deformation.py): same cage fit, every stretch charged


def cgal_meshes(cache):
    folder = os.path.join(cache, "data", "meshes")
    if not os.path.isdir(folder):
        if not os.path.exists(CGAL_ARCHIVE):
            return None
        os.makedirs(cache, exist_ok=True)
        with tarfile.open(CGAL_ARCHIVE) as tar:
            tar.extractall(cache, filter="data")
    return folder


def animal(folder, name):
    V, F = load_mesh(os.path.join(folder, f"{name}.off"))
    if name == "bull":  # faces -x; mirror it (and flip its faces to stay outward)
        V, F = V * [-1.0, 1.0, 1.0], F[:, ::-1].copy()
    return V, F


def pairs(cache):
    out = []
    for family, a, b in SYNTHETIC_PAIRS:
        make = getattr(synthetic, family)
        out.append((f"{family} {a}->{b}", make(seed=a), make(seed=b), "x"))
    folder = cgal_meshes(cache) if cache else None
    if folder is None:
        print("libcgal-demo meshes not found: animal pairs skipped", file=sys.stderr)
        return out
    for a, b in ANIMAL_PAIRS:
        out.append((f"{a}->{b}", animal(folder, a), animal(folder, b), None))
    return out


def run(source, target, method, symmetry):
    """Figures of one method on one pair; ``cage`` is also timed with its cage given."""
    t0 = time.perf_counter()
    kwargs = {}
    if method.startswith("cage"):
        kwargs = {"symmetry": symmetry,
                  "reference": "source" if method == "cage-src" else "aligned"}
        method = "cage"
    result = cagekit.deform(source, target, method=method, **kwargs)
    seconds = time.perf_counter() - t0
    figures = cagekit.evaluate(source, target, (result.vertices, source[1]))
    row = {"cd": figures["cd_x1e2"], "dcotlap": figures["dcotlap_x1e3"], "seconds": seconds}
    if method == "cage" and kwargs["reference"] == "aligned":
        t0 = time.perf_counter()
        cagekit.deform(source, target, cage=(result.cage_v, result.cage_f), **kwargs)
        row["seconds_cage_given"] = time.perf_counter() - t0
    return row, result


def median(rows, method, key):
    return float(np.median([r[method][key] for r in rows]))


def speed_check():
    """cage on a ~10,000-vertex chair with a 200-face cage: fitted in the call, and given."""
    V, F = synthetic.chair(seed=0, resolution=1.5)
    target = synthetic.chair(seed=1)
    cagekit.deform((V, F), target, max_evaluations=2)  # load numba's cache once
    t0 = time.perf_counter()
    result = cagekit.deform((V, F), target)
    fitted = time.perf_counter() - t0
    t0 = time.perf_counter()
    cagekit.deform((V, F), target, cage=(result.cage_v, result.cage_f))
    given = time.perf_counter() - t0
    return {"vertices": len(V), "cage_faces": len(result.cage_f), "seconds_fit_included":
            fitted, "seconds_cage_given": given}


def picture(path, source, target, name, symmetry):
    from cagekit.render import render_meshes

    result = cagekit.deform(source, target, symmetry=symmetry)
    scale = cagekit.deform(source, target, method="scale")
    nricp = cagekit.deform(source, target, method="nricp")
    panels = [source, target, (scale.vertices, source[1]), (nricp.vertices, source[1]),
              (result.vertices, source[1])]
    cages = [(result.cage_v, result.cage_f), None, None, None,
             (result.deformed_cage_v, result.cage_f)]
    titles = ["source", "target", "scale", "nricp_amberg", "cage (cagekit)"]
    render_meshes(panels, path, cages=cages, titles=titles, caption=name,
                  size=(360, 360))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", default="/tmp/cgal",
                        help="folder for the unpacked libcgal-demo data")
    parser.add_argument("--picture", default=None, help="PNG of one typical pair")
    parser.add_argument("--picture-pair", default="chair 2->3")
    parser.add_argument("--json", default=None, help="write every figure to this file")
    args = parser.parse_args()

    rows = []
    header = (f"{'pair':<22}{'verts':>6}"
              + "".join(f"{m + ' CD':>11}{'dCotLap':>9}{'s':>7}" for m in METHODS)
              + f"{'s, cage given':>14}")
    print("CD x1e2, dCotLap x1e3 (cagekit.evaluate, 5000 samples, seed 0), seconds")
    print(header)
    chosen = None
    for name, source, target, symmetry in pairs(args.cache):
        row = {"pair": name, "source_vertices": len(source[0])}
        for method in METHODS:
            row[method], _ = run(source, target, method, symmetry)
        rows.append(row)
        if name == args.picture_pair:
            chosen = (source, target, name, symmetry)
        print(f"{name:<22}{len(source[0]):>6}" + "".join(
            f"{row[m]['cd']:>11.3f}{row[m]['dcotlap']:>9.4f}{row[m]['seconds']:>7.2f}"
            for m in METHODS) + f"{row['cage']['seconds_cage_given']:>14.2f}", flush=True)
    print(f"{'median':<28}" + "".join(
        f"{median(rows, m, 'cd'):>11.3f}{median(rows, m, 'dcotlap'):>9.4f}"
        f"{median(rows, m, 'seconds'):>7.2f}" for m in METHODS)
        + f"{median(rows, 'cage', 'seconds_cage_given'):>14.2f}")
    cd_ratio = median(rows, "cage", "cd") / median(rows, "scale", "cd")
    dcot_ratio = median(rows, "cage", "dcotlap") / median(rows, "nricp", "dcotlap")
    speedup = median(rows, "nricp", "seconds") / median(rows, "cage", "seconds")
    per_pair_cd = np.median([r["cage"]["cd"] / r["scale"]["cd"] for r in rows])
    per_pair_dcot = np.median([r["cage"]["dcotlap"] / r["nricp"]["dcotlap"] for r in rows])
    src_cd = median(rows, "cage-src", "cd") / median(rows, "scale", "cd")
    src_dcot = median(rows, "cage-src", "dcotlap") / median(rows, "nricp", "dcotlap")
    per_pair_speed = np.median([r["nricp"]["seconds"] / r["cage"]["seconds"] for r in rows])
    speedup_given = (median(rows, "nricp", "seconds")
                     / median(rows, "cage", "seconds_cage_given"))
    speed = speed_check()
    print()
    print(f"{len(rows)} pairs. Targets on the medians:")
    print(f"  cage CD / scale CD           {cd_ratio:6.3f}  (target <= 0.7; median of "
          f"per-pair ratios {per_pair_cd:.3f})")
    print(f"  cage dCotLap / nricp dCotLap {dcot_ratio:6.3f}  (target <= 0.1; median of "
          f"per-pair ratios {per_pair_dcot:.3f})")
    print(f"  with reference='source': CD ratio {src_cd:.3f}, dCotLap ratio {src_dcot:.3f}")
    print(f"  nricp s / cage s             {speedup:6.1f}  (target >= 5; median of "
          f"per-pair ratios {per_pair_speed:.1f}); {speedup_given:.1f} with the cage given")
    print(f"  {speed['vertices']}-vertex source, {speed['cage_faces']}-face cage: "
          f"{speed['seconds_fit_included']:.2f} s with the cage fitted in the call, "
          f"{speed['seconds_cage_given']:.2f} s with the cage given (target < 2 s)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"pairs": rows, "speed": speed}, f, indent=1)
    if args.picture and chosen is not None:
        picture(args.picture, *chosen)
        print(f"wrote {args.picture}")


if __name__ == "__main__":
    main()
