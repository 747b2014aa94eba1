"""Degenerate input never takes the process down inside a native library.

pymeshlab's alpha wrap (CGAL) used to crash with a segmentation fault on meshes whose faces
all have zero area; the wrap is now only given proper triangles
(:func:`cagekit.cage.fitting.wrap_input`). The fuzz below runs in a child process, so that a
crash fails the test (with the case that caused it) instead of killing pytest.
"""

import os
import subprocess
import sys

import numpy as np
import pytest

from cagekit.cage.fitting import _cut_soup, _twice_areas, fit_cage, wrap_input

CHILD = r"""
import sys, warnings
import numpy as np
import trimesh
import cagekit
from cagekit.errors import InputError

rng = np.random.default_rng(int(sys.argv[1]))
box = trimesh.creation.box()
BV, BF = np.asarray(box.vertices), np.asarray(box.faces)


def case():
    kind = int(rng.integers(8))
    n = int(rng.integers(1, 12))
    if kind == 0:    # collinear points
        v = rng.uniform(-1, 1, (n, 1)) * rng.normal(size=3) + rng.normal(size=3)
    elif kind == 1:  # coplanar points
        v = np.c_[rng.uniform(-1, 1, (n, 2)), np.zeros(n)]
    elif kind == 2:  # a closed box with faces repeating a vertex, anywhere in the list
        extra = rng.integers(0, 8, (int(rng.integers(1, 4)), 3))
        extra[:, 1] = extra[:, 0]
        return kind, BV, np.insert(BF, rng.integers(0, 13, len(extra)), extra, axis=0)
    elif kind == 3:  # two points repeated
        v = rng.normal(size=(2, 3))[rng.integers(0, 2, n)]
    elif kind == 4:  # a collinear face first, then the box
        v = np.vstack([BV, [[0, 0, 0], [0.1, 0, 0], [0.3, 0, 0]]])
        return kind, v, np.vstack([[[8, 9, 10]], BF])
    elif kind == 5:  # slivers: collinear to 1e-13
        v = rng.uniform(-1, 1, (n, 1)) * [1.0, 0, 0] + rng.normal(size=(n, 3)) * 1e-13
    elif kind == 6:  # point clouds, possibly flat or collinear
        v = rng.normal(size=(n, 3)) * [1, rng.choice([0, 1e-9, 1]), rng.choice([0, 1])]
        return kind, v, np.zeros((0, 3), np.int64)
    else:            # a random soup
        v = rng.normal(size=(n, 3))
    return kind, v, rng.integers(0, len(v), (int(rng.integers(1, 10)), 3))


for i in range(int(sys.argv[2])):
    kind, v, f = case()
    for method in ("wrap", "template"):
        print(f"case {i} (kind {kind}, {method}, {len(v)} vertices, faces {f.tolist()})",
              flush=True)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                cv, cf, report = cagekit.fit_cage(v, f, faces=80, method=method,
                                                  samples=2000)
                assert report.ok, report
                assert np.isfinite(cagekit.bind(v, cv, cf).weights).all()
                if len(f):
                    cagekit.evaluate(v, f, v, f, v)
        except InputError as exc:
            print("  refused:", exc, flush=True)
        else:
            print("  caged", flush=True)
print("done", flush=True)
"""


@pytest.mark.parametrize("seed", [0, 1])
def test_fuzzed_degenerate_shapes_are_caged_or_refused_without_a_crash(seed):
    run = subprocess.run([sys.executable, "-c", CHILD, str(seed), "12"], capture_output=True,
                         text=True, timeout=600, env={**os.environ, "NUMBA_NUM_THREADS": "1"})
    last = run.stdout.strip().splitlines()[-2:]
    assert run.returncode == 0, f"exit {run.returncode} during: {last} {run.stderr[-2000:]}"
    assert run.stdout.strip().endswith("done")
    assert run.stdout.count("caged") >= 6  # most are caged, not refused


def test_wrap_input_holds_proper_triangles_only():
    v = np.array([[0, 0, 0], [0.5, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.2, 0.9]], float)
    f = np.array([[0, 1, 2],   # collinear: a segment
                  [0, 0, 3],   # repeats a vertex: a segment along 0-3
                  [0, 2, 3]])  # proper
    wv, wf = wrap_input(v, f)
    assert np.all(_twice_areas(wv, wf) > 1e-12)
    assert [0, 2, 3] in wf.tolist()
    # two segment stand-ins, one tiny triangle for vertices 1 and 4 (on no proper face)
    assert len(wf) == 1 + 2 + 2
    sv, sf = _cut_soup(v, f)
    assert len(sf) == 3  # the cut test sees the proper face and the two segments only


def test_mesh_of_collinear_vertices_gets_a_cage_around_its_segment():
    # every face has zero area: caged like the segment it is (it used to crash)
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], float)
    f = np.array([[0, 1, 2], [1, 2, 3], [0, 0, 1]])
    cv, cf, report = fit_cage(v, f, faces=100)
    assert report.ok
    from cagekit.cage import winding_numbers

    segment = np.linspace(v[0], v[3], 200)
    assert np.all(winding_numbers(segment, cv, cf) > 0.5)
