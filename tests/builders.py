"""Builders and assertions shared by the test files (shapes, rotations, files, the command line).

Every helper or constant used by more than one test file lives here, and test files import
it from here (``from builders import ...``), never from another test file.
"""

import os
import pathlib
import subprocess
import sys

import numpy as np
import trimesh
from hypothesis import strategies as st
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from cagekit.errors import MeshFileError

# ------------------------------------------------------------------------------ paths

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REPOSITORY = pathlib.Path(__file__).resolve().parents[1]  # ROOT as a resolved Path
EXAMPLE = os.path.join(ROOT, "data", "example")
SHAPE = os.path.join(EXAMPLE, "shape.obj")
CAGE = os.path.join(EXAMPLE, "cage.obj")
DEFORMED = os.path.join(EXAMPLE, "cage_deformed.obj")

# ---------------------------------------------------------------------- the command line


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


def invoke(*args):
    """Run the ``cagekit`` command in this process (click's CliRunner); return the Result."""
    from click.testing import CliRunner

    from cagekit.cli import main

    return CliRunner().invoke(main, [str(a) for a in args])


def assert_bad_input(result, *names):
    """Exit 2, exactly one line on stderr naming the file(s), no traceback, no stdout."""
    assert result.returncode == 2, (result.returncode, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.stderr
    for name in names:
        assert str(name) in lines[0], (name, lines[0])
    assert result.stdout == ""


# ------------------------------------------------------------------------------ files


def load_obj(path):
    from cagekit.io import load_mesh

    return load_mesh(path)


def write(path, content):
    """Write ``content`` (str: text, bytes: binary) to ``path``; return ``path``."""
    mode = "wb" if isinstance(content, bytes) else "w"
    with open(path, mode) as fh:
        fh.write(content)
    return path


def bits(a):
    """The exact bit pattern of a float64 array (distinguishes -0.0 and 0.0)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def expect_error(path, cls=MeshFileError, loader=None, match=None):
    """``loader(path)`` (default ``cagekit.io.load_shape``) raises ``cls``: one line naming
    the file (and holding ``match``); return the message."""
    import pytest

    if loader is None:
        from cagekit.io import load_shape as loader
    with pytest.raises(cls) as info:
        loader(path)
    message = str(info.value)
    assert os.path.basename(os.fspath(path)) in message
    assert "\n" not in message
    if match is not None:
        assert match in message, message
    return message


# ----------------------------------------------------------------------------- shapes

SQUARE_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)
SQUARE_F = np.array([[0, 1, 2], [1, 3, 2]])


def grid(nx=7, ny=6, jitter=0.0, seed=0):
    """Flat triangulated grid in z = 0: vertices (nx*ny, 3), faces, interior mask."""
    x, y = np.meshgrid(
        np.arange(nx, dtype=float), np.arange(ny, dtype=float), indexing="ij"
    )
    interior = ((x > 0) & (x < nx - 1) & (y > 0) & (y < ny - 1)).ravel()
    V = np.stack([x.ravel(), y.ravel(), np.zeros(nx * ny)], axis=1)
    V[interior, :2] += jitter * np.random.default_rng(seed).uniform(
        -1, 1, (interior.sum(), 2)
    )
    idx = np.arange(nx * ny).reshape(nx, ny)
    a, b, c, d = (
        idx[:-1, :-1].ravel(),
        idx[1:, :-1].ravel(),
        idx[:-1, 1:].ravel(),
        idx[1:, 1:].ravel(),
    )
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([b, d, c], 1)])
    return V, F, interior


def icosphere(subdivisions=2):
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    return np.asarray(m.vertices, dtype=float), np.asarray(m.faces, dtype=np.int64)


def bumpy_blob(stretch=(1.0, 0.6, 0.45), subdivisions=3):
    """An ellipsoid with bumps, mirror-symmetric about x = 0 (and z = 0), about 640 vertices."""
    m = trimesh.creation.icosphere(subdivisions)
    V = np.asarray(m.vertices, dtype=float)
    bumps = 1.0 + 0.06 * np.cos(9 * V[:, 1]) * np.cos(7 * np.abs(V[:, 0]))
    return V * bumps[:, None] * stretch, np.asarray(m.faces, dtype=np.int64)


def deformed(X0, seed=5, amount=0.05):
    """``X0`` stretched and jittered (seeded): a deformed copy for loss tests."""
    rng = np.random.default_rng(seed)
    return X0 * [1.1, 0.95, 1.0] + amount * rng.standard_normal(X0.shape)


def diag(v):
    """The bounding-box diagonal of the points ``v``."""
    return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))


def unit_normals(v, f):
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def outside_plane_distance(p, v, f):
    """Per point: the smallest distance to the plane of a face whose triangle it projects
    outside of (inf if none) -- where single MVC weights are ill-conditioned."""
    n = unit_normals(v, f)
    h = p @ n.T - np.einsum("ij,ij->i", v[f[:, 0]], n)                    # (n, m)
    a, b, c = (v[f[:, i]][None] - p[:, None] for i in range(3))            # (n, m, 3)
    bary = np.stack([np.einsum("pmi,mi->pm", np.cross(b, c), n),
                     np.einsum("pmi,mi->pm", np.cross(c, a), n),
                     np.einsum("pmi,mi->pm", np.cross(a, b), n)], -1)
    outside = bary.min(-1) < 0
    return np.where(outside, np.abs(h), np.inf).min(axis=1)


def nn_margin(P, Q):
    """Smallest gap between the nearest and second-nearest distance, both directions."""
    margins = []
    for A, B in ((P, Q), (Q, P)):
        if len(B) < 2:
            continue
        d, _ = cKDTree(B).query(A, k=2)
        margins.append((d[:, 1] - d[:, 0]).min())
    return min(margins, default=np.inf)


# -------------------------------------------------------------------------- rotations


def random_rotation(seed):
    """A proper (3, 3) rotation drawn from ``seed``."""
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def tilt(V, seed=1):
    """Apply an arbitrary rotation and translation."""
    R = Rotation.random(random_state=seed).as_matrix()
    return V @ R.T + np.array([3.0, -2.0, 0.7]), R


# ------------------------------------------------------------------------- hypothesis

SEEDS = st.integers(min_value=0, max_value=2**32 - 1)

# ------------------------------------------------------------------- learning (torch)

TINY_MODEL = {"bottleneck": 16, "decoder_widths": [32, 32]}


def states_equal(a, b):
    """Two state dicts hold the same keys and bit-equal tensors."""
    import torch

    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


# --------------------------------------------------------------------- data sets (apps)


def small_humanoid_data(out):
    """A small humanoid data set in ``out``: template (resolution 0.5), its artist cage,
    one body in its rest pose ("stocky"), one novel character in its own ("a_pose"), two
    poses with ground truth, the reverse examples, two training poses; returns the
    summary."""
    from apps import humanoid_data

    return humanoid_data.write(out, poses=2, train_poses=2, landmarks=40, resolution=0.5,
                               bodies=("stocky",), novel=("a_pose",))


# ------------------------------------------------------------- cages for the coordinates


def star_cage(seed, subdivisions=2, spread=0.4):
    """A non-convex, star-shaped cage: an icosphere with random radii."""
    from cagekit.cage.shapes import icosphere_cage

    v, f = icosphere_cage(subdivisions)
    r = np.random.default_rng(seed).uniform(1 - spread, 1 + spread, len(v))
    return v * r[:, None], f


def sliver_cage():
    """A box whose top square is a fan around a point 1e-9 from one of its sides.

    Two of the fan's triangles are near-degenerate: one is a sliver of height 1e-9, one has
    an angle of almost 180 degrees.
    """
    from cagekit.cage.shapes import box_cage

    v, f = box_cage(1)
    top = np.all(v[f][:, :, 2] == 1.0, axis=1)
    # boundary loop of the top square, in the faces' orientation
    nxt = {}
    directed = {(a, b) for face in f[top] for a, b in zip(face, np.roll(face, -1))}
    for a, b in directed:
        if (b, a) not in directed:
            nxt[a] = b
    loop = [next(iter(nxt))]
    while len(loop) < 4:
        loop.append(nxt[loop[-1]])
    x = len(v)
    vv = np.vstack([v, [[0.3, 1.0 - 1e-9, 1.0]]])
    fan = [(loop[i], loop[(i + 1) % 4], x) for i in range(4)]
    return vv, np.vstack([f[~top], np.array(fan)])


def _cages():
    from cagekit.cage.shapes import box_cage, icosphere_cage

    return {
        "box1": box_cage(1),
        "box3": box_cage(3),
        "ico1": icosphere_cage(1),
        "star": star_cage(0),
        "flat-box": box_cage(2, half_extent=(3.0, 1.0, 0.05)),
        "sliver": sliver_cage(),
    }


#: the coordinates' test cages by name (convex, non-convex, flat, with sliver faces)
CAGES = _cages()
