"""Builders and assertions shared by the test files (shapes, rotations, the command line)."""

import os
import subprocess
import sys

import numpy as np
import trimesh
from scipy.spatial import cKDTree

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXAMPLE = os.path.join(ROOT, "data", "example")
SHAPE = os.path.join(EXAMPLE, "shape.obj")
CAGE = os.path.join(EXAMPLE, "cage.obj")
DEFORMED = os.path.join(EXAMPLE, "cage_deformed.obj")


def cagekit(*args, cwd=None, stderr=subprocess.PIPE):
    """Run ``python -m cagekit.cli ARGS``; return the CompletedProcess (text mode)."""
    env = dict(os.environ)
    env.pop("CAGEKIT_DEBUG", None)
    env["PYTHONPATH"] = ROOT + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.run(
        [sys.executable, "-m", "cagekit.cli", *map(str, args)],
        stdout=subprocess.PIPE, stderr=stderr, text=True, cwd=cwd, env=env, timeout=300,
        check=False,
    )


def load_obj(path):
    from cagekit.io import load_mesh

    return load_mesh(path)


def assert_bad_input(result, *names):
    """Exit 2, exactly one line on stderr naming the file(s), no traceback, no stdout."""
    assert result.returncode == 2, (result.returncode, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.stderr
    for name in names:
        assert str(name) in lines[0], (name, lines[0])
    assert result.stdout == ""



def nn_margin(P, Q):
    """Smallest gap between the nearest and second-nearest distance, both directions."""
    margins = []
    for A, B in ((P, Q), (Q, P)):
        if len(B) < 2:
            continue
        d, _ = cKDTree(B).query(A, k=2)
        margins.append((d[:, 1] - d[:, 0]).min())
    return min(margins, default=np.inf)


def icosphere(subdivisions=2):
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    return np.asarray(m.vertices, dtype=float), np.asarray(m.faces, dtype=np.int64)



def random_rotation(seed):
    """A proper (3, 3) rotation drawn from ``seed``."""
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q
