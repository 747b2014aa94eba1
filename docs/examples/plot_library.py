"""
The library
===========

The README's "Library" example as it is: bind a shape to its cage with mean value
coordinates and deform it by moving the cage, then deform a chair to another chair's
proportions (per-pair cage deformation) and score the result (Chamfer distance and
dCotLap). It runs from the repository root, where ``data/example`` is, and writes into
``out/``.
"""

# sphinx_gallery_start_ignore
# ruff: noqa: E402 (the README's example follows, as it is, after this hidden part)
# The README's paths are relative to the repository root. sphinx-gallery runs each code
# block in the example's own folder (docs/examples) and restores the folder after it.
import os as _os
from pathlib import Path as _Path

_os.chdir(_Path.cwd().parents[1])
# sphinx_gallery_end_ignore
import os

import cagekit
from cagekit.io import load_mesh, save_mesh

V, F = load_mesh("data/example/shape.obj")
cage_v, cage_f = load_mesh("data/example/cage.obj")
new_cage_v, _ = load_mesh("data/example/cage_deformed.obj")

b = cagekit.bind(V, cage_v, cage_f)        # b.weights: (n, k) float64, rows sum to 1
os.makedirs("out", exist_ok=True)
save_mesh("out/deformed.obj", b.deform(new_cage_v), F)

# per-pair deformation: the source takes the target's proportions
Vs, Fs = load_mesh("data/example/chair_source.obj")
Vt, Ft = load_mesh("data/example/chair_target.obj")
result = cagekit.deform(Vs, Fs, Vt, Ft, options=cagekit.DeformOptions(symmetry="x"))
print(result.losses, result.iterations, result.seconds)
figures = cagekit.evaluate(Vs, Fs, Vt, Ft, result.vertices)
print(figures.cd_x1e2, figures.dcotlap_x1e3, figures.part_nonaffinity_worst)
save_mesh("out/chair.obj", result.vertices, result.faces)
