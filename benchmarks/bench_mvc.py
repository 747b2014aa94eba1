"""Speed of mean value coordinates: cagekit beside VTK and a dense NumPy vectorisation.

Cases (issue 2):
  (a) 15,000 points bound to a 216-face cage;
  (b) 100,000 points bound to a 1,000-face cage;
  (c) 1,000,000 points bound to a 200-face cage: bind time, peak memory, deform time.

cagekit runs twice, in float64 (the default) and with ``dtype=np.float32``.
Peers, measured in the same run on the same points and cages:
  * VTK's ``vtkMeanValueCoordinatesInterpolator.ComputeInterpolationWeights``, called once per
    point (``pip install -e .[bench]``), the way a Python user would call it;
  * the textbook formula densely vectorised with NumPy
    (:func:`cagekit.coords.mean_value_coordinates_textbook`), what a user would write first.
The peers are timed on a prefix of the points (``--peer-points``, default 5,000) when the
case is larger; the rate is per point-triangle pair, so it does not depend on the count.

Usage::

    python benchmarks/bench_mvc.py [--threads N] [--peer-points 5000] [--skip-million]

Prints one table; numbers go to docs/benchmarks.md by hand with the command that made them.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time

import numpy as np


def star_cage(faces: int, seed: int = 0):
    """A deterministic non-convex star-shaped cage with exactly ``faces`` faces."""
    import pymeshlab
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=5)
    direction = sphere.vertices
    rng = np.random.default_rng(seed)
    lobes = rng.normal(size=(6, 3))
    radius = 1.0 + 0.25 * np.sin(3.0 * direction @ lobes.T).mean(axis=1)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(direction * radius[:, None], sphere.faces))
    ms.meshing_decimation_quadric_edge_collapse(targetfacenum=faces, preservetopology=True)
    mesh = ms.current_mesh()
    v = np.asarray(mesh.vertex_matrix(), dtype=np.float64)
    f = np.asarray(mesh.face_matrix(), dtype=np.int64)
    assert len(f) == faces, (len(f), faces)
    return v, f


def interior_points(v, f, n: int, seed: int = 1):
    """``n`` points uniformly inside the cage (rejection by winding number)."""
    import igl

    rng = np.random.default_rng(seed)
    lo, hi = v.min(axis=0), v.max(axis=0)
    out = []
    count = 0
    while count < n:
        p = rng.uniform(lo, hi, (2 * n, 3))
        p = p[igl.winding_number(v, f, p) > 0.5]
        out.append(p)
        count += len(p)
    return np.vstack(out)[:n]


def time_cagekit(p, v, f, repeats: int = 3, dtype=np.float64):
    from cagekit.coords import mean_value_coordinates

    mean_value_coordinates(p[:64], v, f, dtype=dtype)  # load the compiled kernel
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        w = mean_value_coordinates(p, v, f, dtype=dtype)
        best = min(best, time.perf_counter() - t)
    return w, best


def time_vtk(p, v, f):
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk

    points = vtk.vtkPoints()
    points.SetData(numpy_to_vtk(np.ascontiguousarray(v), deep=True))
    tris = vtk.vtkIdList()
    for i in f.ravel():
        tris.InsertNextId(int(i))
    interp = vtk.vtkMeanValueCoordinatesInterpolator
    out = np.empty((len(p), len(v)))
    weights = [0.0] * len(v)
    t = time.perf_counter()
    for i, x in enumerate(p.tolist()):
        interp.ComputeInterpolationWeights(x, points, tris, weights)
        out[i] = weights
    return out, time.perf_counter() - t


def time_textbook(p, v, f):
    from cagekit.coords import mean_value_coordinates_textbook

    t = time.perf_counter()
    w = mean_value_coordinates_textbook(p, v, f)
    return w, time.perf_counter() - t


def run_case(label, n, faces, peer_points):
    import igl

    v, f = star_cage(faces)
    p = interior_points(v, f, n)
    D = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    w, t_ck = time_cagekit(p, v, f)
    w32, t_32 = time_cagekit(p, v, f, dtype=np.float32)
    q = p[:min(n, peer_points)]
    rows = [("cagekit (numba)", n, t_ck, n * faces / t_ck),
            ("cagekit, dtype=float32", n, t_32, n * faces / t_32)]
    far = np.sqrt(igl.point_mesh_squared_distance(q, v, f)[0]) >= 1e-4 * D
    lin = np.linalg.norm(w @ v - p, axis=1).max() / D
    result = {"case": label, "faces": faces, "points": n, "cagekit_pairs_per_s": n * faces / t_ck,
              "cagekit_seconds": t_ck, "linear_precision_over_D": lin,
              "float32_pairs_per_s": n * faces / t_32, "float32_seconds": t_32,
              "max_diff_float32": float(np.abs(w32.astype(np.float64) - w).max())}
    try:
        w_vtk, t_vtk = time_vtk(q, v, f)
        rows.append(("VTK, once per point", len(q), t_vtk, len(q) * faces / t_vtk))
        diff = np.abs(w_vtk - w[: len(q)])
        result.update(vtk_pairs_per_s=len(q) * faces / t_vtk,
                      max_diff_vs_vtk=float(diff.max()),
                      max_diff_vs_vtk_1e4D=float(diff[far].max()),
                      speedup_vs_vtk=(n * faces / t_ck) / (len(q) * faces / t_vtk))
    except ImportError:
        rows.append(("VTK (not installed: pip install -e .[bench])", 0, np.nan, np.nan))
    w_np, t_np = time_textbook(q, v, f)
    rows.append(("NumPy dense textbook", len(q), t_np, len(q) * faces / t_np))
    result.update(numpy_pairs_per_s=len(q) * faces / t_np,
                  max_diff_vs_numpy=float(np.abs(w_np - w[: len(q)]).max()))
    return rows, result


MILLION = r"""
import json, sys, time
import numpy as np


def peak_rss():
    # VmHWM: this process's peak resident memory since exec (ru_maxrss would include the
    # parent's, inherited through fork)
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024


sys.path.insert(0, sys.argv[1])
from bench_mvc import star_cage, interior_points
import cagekit
v, f = star_cage(200)
p = np.random.default_rng(2).uniform(-0.45, 0.45, (1_000_000, 3))
cagekit.bind(p[:64], v, f)
t = time.perf_counter(); b = cagekit.bind(p, v, f); t_bind = time.perf_counter() - t
peak = peak_rss()
new = v * [1.2, 0.9, 1.0]
b.deform(new)
times = []
for _ in range(5):
    t = time.perf_counter(); b.deform(new); times.append(time.perf_counter() - t)
t = time.perf_counter(); b.weights @ new; t_blas = time.perf_counter() - t
print(json.dumps({"bind_s": t_bind, "peak_bytes": peak, "weights_bytes": b.weights.nbytes,
                  "deform_s": min(times), "deform_blas_s": t_blas, "k": len(v)}))
"""


def run_million():
    here = os.path.dirname(os.path.abspath(__file__))
    out = subprocess.run([sys.executable, "-c", MILLION, here], capture_output=True, text=True,
                         check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--threads", type=int, default=None, help="numba threads")
    parser.add_argument("--peer-points", type=int, default=5000)
    parser.add_argument("--skip-million", action="store_true")
    parser.add_argument("--json", action="store_true", help="also print the raw results")
    args = parser.parse_args(argv)
    import numba

    if args.threads:
        numba.set_num_threads(args.threads)
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cpus, "
          f"numba threads {numba.get_num_threads()}, python {platform.python_version()}")
    results = []
    print(f"{'case':<28}{'method':<34}{'points':>9}{'seconds':>10}{'Mpairs/s':>10}")
    for label, n, faces in (("(a) 15k pts, 216 faces", 15_000, 216),
                            ("(b) 100k pts, 1000 faces", 100_000, 1000)):
        rows, result = run_case(label, n, faces, args.peer_points)
        results.append(result)
        for method, pts, secs, rate in rows:
            print(f"{label:<28}{method:<34}{pts:>9}{secs:>10.3f}{rate / 1e6:>10.2f}")
        extra = [f"linear precision {result['linear_precision_over_D']:.1e} D",
                 f"float32 {result['float32_pairs_per_s'] / result['cagekit_pairs_per_s']:.2f}x "
                 f"float64, max|w32 - w| {result['max_diff_float32']:.1e}"]
        if "speedup_vs_vtk" in result:
            extra += [f"{result['speedup_vs_vtk']:.1f}x VTK",
                      f"max|w - w_vtk| {result['max_diff_vs_vtk']:.1e} "
                      f"({result['max_diff_vs_vtk_1e4D']:.1e} at >= 1e-4 D from the cage)"]
        extra.append(f"max|w - w_numpy| {result['max_diff_vs_numpy']:.1e}")
        print(f"{'':<28}" + "; ".join(extra))
    if not args.skip_million:
        m = run_million()
        results.append(m)
        print(f"(c) 1M pts, 200 faces: bind {m['bind_s']:.2f} s, peak RSS "
              f"{m['peak_bytes'] / 2**30:.2f} GiB (weights {m['weights_bytes'] / 2**30:.2f} GiB), "
              f"deform {m['deform_s']:.3f} s (NumPy/BLAS matmul {m['deform_blas_s']:.3f} s)")
    if args.json:
        print(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
