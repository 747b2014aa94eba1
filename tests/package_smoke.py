"""A smoke test of an installed cagekit (``make package-check``).

Run from outside the repository with the environment's own Python: it checks that
``cagekit`` comes from that environment's site-packages, prints the versions of the
libraries it found, and runs each main path once on the bundled example chairs: cage
fitting, both coordinates (partition of unity and reproduction), a short deformation and
its figures, mesh input and output, a picture, and the ``cagekit`` command; the transfer
and the batch packages import. Versions given
as ``NAME==VERSION`` must be the ones installed (the installation kept them).

Usage: python package_smoke.py EXAMPLE_FOLDER [NAME==VERSION ...]
"""

import importlib.metadata
import os
import subprocess
import sys
import tempfile

import numpy as np

import cagekit
import cagekit.batch.amplify
import cagekit.transfer
from cagekit import io
from cagekit.render import render_meshes

LIBRARIES = ("numpy", "scipy", "matplotlib", "trimesh", "libigl", "pymeshlab", "numba",
             "nlopt", "ipctk", "click", "tqdm", "rtree", "threadpoolctl")


def main(example: str, expected: list[str]) -> None:
    if "site-packages" not in cagekit.__file__:
        sys.exit(f"cagekit was imported from {cagekit.__file__}, not from the environment")
    print("cagekit", cagekit.__version__, "from", os.path.dirname(cagekit.__file__))
    if not os.path.exists(os.path.join(os.path.dirname(cagekit.__file__), "py.typed")):
        sys.exit("cagekit was installed without its py.typed")
    print(", ".join(f"{name} {importlib.metadata.version(name)}" for name in LIBRARIES))
    for pin in expected:
        name, version = pin.split("==")
        if importlib.metadata.version(name) != version:
            sys.exit(f"{name} {importlib.metadata.version(name)} is installed, not {version}: "
                     "the installation replaced it")
    source = io.load_mesh(os.path.join(example, "chair_source.obj"))
    target = io.load_mesh(os.path.join(example, "chair_target.obj"))
    cage_v, cage_f, _ = cagekit.fit_cage(*source, faces=120)
    for method in ("mvc", "green"):
        binding = cagekit.bind(source[0], cage_v, cage_f, method)
        moved = binding.deform(cage_v)
        assert np.allclose(moved, source[0], atol=1e-8), f"{method} does not reproduce"
    weights = cagekit.bind(source[0], cage_v, cage_f).weights
    assert np.allclose(weights.sum(axis=1), 1.0), "MVC weights do not sum to 1"
    result = cagekit.deform(*source, *target, cage_v, cage_f,
                            options=cagekit.DeformOptions(max_evaluations=15))
    figures = cagekit.evaluate(*source, *target, result.vertices)
    assert np.isfinite(figures.cd) and figures.cd < 0.05, figures
    with tempfile.TemporaryDirectory() as folder:
        for suffix in (".obj", ".ply", ".off"):
            path = os.path.join(folder, "deformed" + suffix)
            io.save_mesh(path, result.vertices, source[1])
            assert np.allclose(io.load_mesh(path)[0], result.vertices, atol=1e-5), suffix
        picture = render_meshes([source, target, (result.vertices, source[1])],
                                os.path.join(folder, "smoke.png"))
        assert os.path.getsize(picture) > 1000
        command = os.path.join(os.path.dirname(sys.executable), "cagekit")
        done = subprocess.run([command, "deform", os.path.join(example, "chair_source.obj"),
                               os.path.join(example, "chair_target.obj"), "-o",
                               os.path.join(folder, "cli.obj")], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
    assert callable(cagekit.transfer.fit_character) and callable(cagekit.batch.amplify.amplify)
    print(f"smoke test passed: cage {len(cage_f)} faces, deformed CD x1e2 "
          f"{100 * figures.cd:.2f}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
