"""Linear precision of cagekit's MVC, region by region, beside the textbook formula.

For several cages (boxes with coplanar faces, an icosphere, a non-convex star, a cage with a
sliver face) prints the largest ``|W @ cage_v - p| / D`` (D = bounding-box diagonal) over
random points in each region: inside (>= 1e-4 D from the cage), near faces / edges /
vertices (1e-12 D .. 1e-4 D away, both sides), on coplanar edges, on the cage, outside
within 2 D, and far outside (10, 100 and 1000 D away). The textbook column is the dense NumPy
version of the Ju et al. pseudo-code (VTK's formula) on the same points.

Usage::

    python benchmarks/mvc_precision.py [--points 2000]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

TESTS = Path(__file__).resolve().parents[1] / "tests"
sys.path[:0] = [str(TESTS), str(TESTS / "coords")]  # test_mvc's cages, and its builders

from test_mvc import CAGES, _near_points, diag, unit_normals  # noqa: E402

from cagekit.coords import mean_value_coordinates, mean_value_coordinates_textbook  # noqa: E402


def regions(v, f, n, rng):
    import igl

    D = diag(v)
    centre = (v.max(axis=0) + v.min(axis=0)) / 2
    out = {}
    p = rng.uniform(v.min(axis=0), v.max(axis=0), (4 * n, 3))
    dist = np.sqrt(igl.point_mesh_squared_distance(p, v, f)[0])
    out["inside"] = p[(igl.winding_number(v, f, p) > 0.5) & (dist >= 1e-4 * D)][:n]
    for region in ("face", "edge", "vertex"):
        out[f"near {region}"] = _near_points(v, f, region, rng, n)
    normals = unit_normals(v, f)
    edges = {}
    for fi, face in enumerate(f):
        for a, b in ((face[0], face[1]), (face[1], face[2]), (face[2], face[0])):
            edges.setdefault((min(a, b), max(a, b)), []).append(fi)
    cop = np.array([e for e, fs in edges.items()
                    if np.dot(normals[fs[0]], normals[fs[1]]) > 1 - 1e-12] or [(0, 0)])
    t = rng.uniform(0, 1, (len(cop), 1))
    out["on coplanar edges"] = (1 - t) * v[cop[:, 0]] + t * v[cop[:, 1]]
    bary = rng.dirichlet([1, 1, 1], n)
    out["on faces"] = np.einsum("fi,fic->fc", bary, v[f[rng.integers(len(f), size=n)]])
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    out["outside, within 2 D"] = centre + d * rng.uniform(0.5 * D, 2 * D, (n, 1))
    for r in (10, 100, 1000):
        out[f"outside at {r} D"] = centre + d * D * r
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--points", type=int, default=2000)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(0)
    worst: dict[str, list[float]] = {}
    print(f"{'cage':<10}{'region':<22}{'cagekit / D':>14}{'textbook / D':>14}")
    for name in sorted(CAGES):
        v, f = CAGES[name]
        D = diag(v)
        for region, p in regions(v, f, args.points, rng).items():
            w = mean_value_coordinates(p, v, f)
            with np.errstate(all="ignore"):
                wt = mean_value_coordinates_textbook(p, v, f)
            err = np.linalg.norm(w @ v - p, axis=1).max() / D
            with np.errstate(all="ignore"):
                errt = np.linalg.norm(wt @ v - p, axis=1).max() / D
            worst.setdefault(region, [0.0, 0.0])
            worst[region][0] = max(worst[region][0], err)
            worst[region][1] = max(worst[region][1], np.nan_to_num(errt, nan=np.inf))
            print(f"{name:<10}{region:<22}{err:>14.1e}{errt:>14.1e}")
    print("\nworst over all cages")
    for region, (err, errt) in worst.items():
        print(f"{'':<10}{region:<22}{err:>14.1e}{errt:>14.1e}")


if __name__ == "__main__":
    main()
