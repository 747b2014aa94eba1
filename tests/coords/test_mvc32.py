"""Mean value coordinates in float32 (``dtype=np.float32``) against the float64 kernel.

Bounds tested: every weight within 1e-5 of the float64 weights, inside, near faces, edges
and vertices (both sides), outside and far outside; rows sum to one to float32 rounding;
rows float32 cannot resolve (on the cage, in a face's plane, beyond the far blend) are the
float64 rows rounded; the float32 edge factor to four units in float32's last place.
"""

import numpy as np
import pytest
from builders import CAGES, diag, unit_normals
from hypothesis import given
from hypothesis import strategies as st

from cagekit import InputError
from cagekit.cage import cage_topology
from cagekit.cage.shapes import box_cage
from cagekit.coords import mean_value_coordinates
from cagekit.coords.mvc32 import FLOAT32_SNAP, _half_angle_over_sin32, mvc_float32

BOUND = 1e-5


def _both(p, v, f):
    w64 = mean_value_coordinates(p, v, f)
    w32 = mean_value_coordinates(p, v, f, dtype=np.float32)
    assert w32.dtype == np.float32 and w32.shape == w64.shape
    return w64, w32


def _near(v, f, rng, n, exponent):
    """Points ``10**exponent`` diagonals from random faces, edges and vertices, both sides."""
    D = diag(v)
    normals = unit_normals(v, f)
    fi = rng.integers(len(f), size=n)
    kind = rng.integers(3, size=n)
    bary = np.where(kind[:, None] == 0, rng.dirichlet([1, 1, 1], n),
                    np.where(kind[:, None] == 1, [0.5, 0.5, 0.0], [1.0, 0.0, 0.0]))
    base = np.einsum("ni,nic->nc", bary, v[f[fi]])
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    direction = np.where(kind[:, None] == 0, normals[fi], direction)
    sign = rng.choice([-1.0, 1.0], size=(n, 1))
    return base + sign * 10.0 ** exponent * D * direction


@pytest.mark.parametrize("name", sorted(CAGES))
def test_float32_matches_float64_inside_and_out(name):
    v, f = CAGES[name]
    rng = np.random.default_rng(11)
    lo, hi = v.min(axis=0), v.max(axis=0)
    centre, span = (lo + hi) / 2, hi - lo
    p = np.vstack([rng.uniform(centre - 0.6 * span, centre + 0.6 * span, (3000, 3)),
                   rng.uniform(centre - 3 * span, centre + 3 * span, (300, 3))])
    w64, w32 = _both(p, v, f)
    assert np.abs(w32.astype(np.float64) - w64).max() <= BOUND
    assert np.abs(w32.astype(np.float64).sum(axis=1) - 1).max() <= 1e-6


@pytest.mark.parametrize("half_extent", [(10.0, 1.0, 0.02), (3.0, 1.0, 0.01)])
def test_float32_on_flat_and_long_cages(half_extent):
    """Points near the vertices and edges of flat, long boxes, where rounding the points to
    float32 before taking differences would cost 2e-5 (a review's case)."""
    v, f = box_cage(3, half_extent=half_extent)
    rng = np.random.default_rng(7)
    p = np.vstack([_near(v, f, rng, 4000, e) for e in (-4, -3, -2)]
                  + [[[-9.996893252313807, 0.021454371649810566, 0.013162028442229436]]])
    p = p[np.all(np.abs(p) <= half_extent, axis=1)]  # inside
    w64, w32 = _both(p, v, f)
    assert np.abs(w32.astype(np.float64) - w64).max() <= BOUND


def test_float32_lanes_are_used_inside_a_loose_cage():
    """Inside a box most rows come from the float32 lanes (not float64's rows rounded)."""
    v, f = box_cage()
    p = np.random.default_rng(8).uniform(-0.9, 0.9, (2000, 3))
    w64, w32 = _both(p, v, f)
    from_float32 = np.any(w32 != w64.astype(np.float32), axis=1)
    assert from_float32.mean() > 0.5
    assert np.abs(w32.astype(np.float64) - w64).max() <= 1e-6


@given(seed=st.integers(0, 2**32 - 1), exponent=st.floats(-8, -1),
       cage=st.sampled_from(sorted(CAGES)))
def test_float32_near_the_cage_property(seed, exponent, cage):
    v, f = CAGES[cage]
    p = _near(v, f, np.random.default_rng(seed), 64, exponent)
    w64, w32 = _both(p, v, f)
    assert np.all(np.isfinite(w32))
    assert np.abs(w32.astype(np.float64) - w64).max() <= BOUND


@given(seed=st.integers(0, 2**32 - 1), scale=st.floats(1e-3, 1e3),
       shift=st.floats(-1e4, 1e4))
def test_float32_is_similarity_invariant(seed, scale, shift):
    """A moved and scaled cage and points give the same float32 weights (to the bound)."""
    v, f = CAGES["star"]
    rng = np.random.default_rng(seed)
    p = rng.uniform(v.min(axis=0), v.max(axis=0), (200, 3))
    w32 = mean_value_coordinates(p, v, f, dtype=np.float32).astype(np.float64)
    moved = mean_value_coordinates(p * scale + shift, v * scale + shift, f,
                                   dtype=np.float32).astype(np.float64)
    assert np.abs(moved - w32).max() <= 2 * BOUND


def test_rows_float32_cannot_resolve_are_the_float64_rows():
    """On vertices, edges and faces, within float32's switch-over of a face's plane and far
    outside, the rows come from the float64 kernel, rounded to float32."""
    v, f = box_cage()
    D = diag(v)
    topo = cage_topology(f)
    on_edges = v[topo.edges].mean(axis=1)
    on_faces = v[f].mean(axis=1)
    in_plane = v[f[0]].mean(axis=0) + 0.5 * FLOAT32_SNAP * D * unit_normals(v, f)[0]
    outside_in_plane = v[f[0]].mean(axis=0) + 0.3 * D * np.cross(unit_normals(v, f)[0],
                                                                    [0.0, 0.0, 1.0])
    far = np.array([[15.0 * D, 0.0, 0.0], [0.0, -40.0 * D, 0.0]])
    p = np.vstack([v, on_edges, on_faces, in_plane, outside_in_plane, far])
    w64, w32 = _both(p, v, f)
    assert np.array_equal(w32, w64.astype(np.float32))
    assert np.array_equal(w32[:len(v)], np.eye(len(v), dtype=np.float32))


def test_the_kernel_flags_the_switch_over_zone():
    """A point within FLOAT32_SNAP of a face's plane is flagged; points well inside are not."""
    v, f = box_cage()
    topo = cage_topology(f)
    normals = unit_normals(v, f)
    off = np.einsum("ij,ij->i", v[f[:, 0]], normals)
    centre = v[f[0]].mean(axis=0)
    p = np.array([centre - 0.5 * FLOAT32_SNAP * normals[0], [0.01, 0.02, -0.03]])
    rows = mvc_float32(p, v, f, topo.edges, topo.face_edges, topo.face_edge_signs, normals,
                       off, 2)
    assert rows.flagged.tolist() == [True, False]
    ref = mean_value_coordinates(p[1:], v, f)
    assert np.abs(rows.weights[1] - ref[0]).max() <= 1e-6


def test_float32_angle_to_four_units_in_the_last_place():
    """``atan2(s, c) / (2 s)`` over the half circle and near both of its ends."""
    angle = np.concatenate([np.linspace(1e-6, np.pi - 1e-6, 20001),
                            np.geomspace(1e-30, 1e-2, 200), np.pi - np.geomspace(1e-6, 1e-2, 200)])
    s = np.sin(angle).astype(np.float32)
    c = np.cos(angle).astype(np.float32)
    got = np.array([_half_angle_over_sin32(a, b) for a, b in zip(s, c)], dtype=np.float64)
    ref = np.arctan2(s.astype(np.float64), c.astype(np.float64)) / (2 * s.astype(np.float64))
    assert np.all(np.abs(got - ref) <= 4 * np.spacing(ref.astype(np.float32)))
    assert _half_angle_over_sin32(np.float32(0), np.float32(1)) == 0


def test_bad_dtype_is_refused():
    v, f = box_cage()
    for dtype in (np.float16, np.int32, "bogus"):
        with pytest.raises(InputError, match="float64 or float32"):
            mean_value_coordinates([[0.0, 0.0, 0.0]], v, f, dtype=dtype)
    w = mean_value_coordinates([[0.1, 0.0, 0.0]], v, f, dtype="float32")
    assert w.dtype == np.float32


def test_a_larger_snap_is_kept():
    """Points within the caller's ``snap`` of a face get the float64 kernel's rows with that
    snap (its face limits), not float32's own."""
    v, f = box_cage()
    D = diag(v)
    rng = np.random.default_rng(5)
    normals = unit_normals(v, f)
    fi = rng.integers(len(f), size=200)
    base = np.einsum("ni,nic->nc", rng.dirichlet([1, 1, 1], 200), v[f[fi]])
    p = base - rng.uniform(3e-5, 5e-4, (200, 1)) * D * normals[fi]
    w64 = mean_value_coordinates(p, v, f, snap=1e-3)
    w32 = mean_value_coordinates(p, v, f, snap=1e-3, dtype=np.float32)
    assert np.array_equal(w32, w64.astype(np.float32))


def test_weights_that_overflow_float32_are_refused():
    v, f = box_cage()
    with pytest.raises(InputError, match="overflow float32"):
        mean_value_coordinates([[1e40, 0.0, 0.0]], v, f, dtype=np.float32)
    assert np.isfinite(mean_value_coordinates([[1e40, 0.0, 0.0]], v, f)).all()


def test_float32_empty_points():
    v, f = box_cage()
    w = mean_value_coordinates(np.zeros((0, 3)), v, f, dtype=np.float32)
    assert w.shape == (0, 8) and w.dtype == np.float32
