"""fit_cage: every guarantee on procedural shapes, bad input, and MVC of the fitted cage."""

import numpy as np
import pytest
import trimesh

from cagekit import InputError
from cagekit.cage.fitting import CageFitError, cage_report, fit_cage, template_cage
from cagekit.coords import mean_value_coordinates


def _mesh(m):
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


def thin_parts():
    """A plate (2 x 2 x 0.04) with a thin rod (radius 0.03) standing on it."""
    plate = trimesh.creation.box(extents=(2.0, 2.0, 0.04))
    rod = trimesh.creation.cylinder(radius=0.03, height=1.0, sections=12)
    rod.apply_translation((0.0, 0.0, 0.5))
    return _mesh(trimesh.util.concatenate([plate, rod]))  # overlapping: self-intersecting


def torus():
    return _mesh(trimesh.creation.torus(major_radius=1.0, minor_radius=0.3))


def two_spheres():
    a = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    b = trimesh.creation.icosphere(subdivisions=2, radius=0.3)
    b.apply_translation((2.0, 0.5, 0.0))
    return _mesh(trimesh.util.concatenate([a, b]))


def open_hemisphere():
    v, f = _mesh(trimesh.creation.icosphere(subdivisions=3))
    f = f[v[f].mean(axis=1)[:, 2] > 0]
    used = np.unique(f)
    remap = np.full(len(v), -1)
    remap[used] = np.arange(len(used))
    return v[used], remap[f]


def star_blob(seed=0):
    v, f = _mesh(trimesh.creation.icosphere(subdivisions=3))
    d = v / np.linalg.norm(v, axis=1, keepdims=True)
    lobes = np.random.default_rng(seed).normal(size=(5, 3))
    r = 1.0 + 0.2 * np.sin(2.5 * d @ lobes.T).mean(axis=1)
    return d * r[:, None], f


def cloud(seed=0):
    p = np.random.default_rng(seed).normal(size=(3000, 3)) * [1.0, 0.5, 0.2]
    return p, None


def messy():
    """Duplicate faces, a degenerate face and unreferenced vertices."""
    v, f = _mesh(trimesh.creation.box(extents=(1.0, 2.0, 0.5)))
    v = np.vstack([v, [[0.8, 0.0, 0.0]]])  # unreferenced, outside the box: still enclosed
    f = np.vstack([f, f[:3], [[0, 0, 1]]])
    return v, f


SHAPES = {
    "thin-parts": thin_parts,
    "torus": torus,
    "two-components": two_spheres,
    "open": open_hemisphere,
    "star": star_blob,
    "cloud": cloud,
    "messy": messy,
}


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_wrap_meets_every_guarantee(name):
    v, f = SHAPES[name]()
    cv, cf, _ = fit_cage(v, f, faces=150)
    report = cage_report(v, f, cv, cf, faces=150)
    assert report.ok, report.checks
    assert len(cf) <= 150
    assert report.max_distance < 0.25


def test_units_and_orientation_do_not_matter():
    v, f = star_blob(1)
    q, _ = np.linalg.qr(np.random.default_rng(2).normal(size=(3, 3)))
    w = 1000.0 * v @ q.T + [5e4, -3e3, 7.0]
    cv, cf, _ = fit_cage(w, f, faces=120)
    report = cage_report(w, f, cv, cf, faces=120)
    assert report.ok, report.checks
    # the same cage up to the similarity, in the user's frame
    assert report.max_distance < 0.2


def test_template_method():
    v, f = star_blob(2)
    cv, cf, _ = fit_cage(v, f, method="template")
    tv, tf = template_cage()
    assert cv.shape == tv.shape and np.array_equal(cf, tf)
    assert cage_report(v, f, cv, cf, faces=80).ok


def test_template_cage_is_the_42_vertex_icosphere():
    v, f = template_cage()
    assert v.shape == (42, 3) and f.shape == (80, 3)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0)


@pytest.mark.parametrize("seed", [0, 1])
def test_mvc_of_star_shape_in_fitted_cage_is_nearly_positive(seed):
    v, f = star_blob(seed)
    cv, cf, _ = fit_cage(v, f, faces=200)
    w = mean_value_coordinates(v, cv, cf)
    assert w.min() >= -0.05


def test_deterministic():
    v, f = torus()
    a = fit_cage(v, f, faces=100, seed=3)
    b = fit_cage(v, f, faces=100, seed=3)
    assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
    assert a.report == b.report


@pytest.mark.parametrize("shape, message", [
    (np.zeros((0, 3)), "no points"),
    (np.array([[0.0, 0.0, 0.0]]), "at least two"),
    (np.array([[0.0, 0.0, np.nan], [1.0, 0.0, 0.0]]), "NaN"),
    (np.ones((5, 3)), "coincide"),
    (np.zeros((4, 2)), r"\(n, 3\)"),
])
def test_bad_input(shape, message):
    with pytest.raises(InputError, match=message):
        fit_cage(shape, None)


def test_bad_options():
    v, f = torus()
    with pytest.raises(InputError, match="unknown cage method"):
        fit_cage(v, f, method="hull")
    with pytest.raises(InputError, match="at least 4 faces"):
        fit_cage(v, f, faces=2)


def test_impossible_request_is_a_clear_error():
    v, f = two_spheres()
    # two far-apart components cannot share one 4-face cage
    with pytest.raises(CageFitError, match="guarantee"):
        fit_cage(v, f, faces=4, offsets=(0.01,), alphas=(0.03,))


def test_report_detects_a_cage_that_cuts_the_shape():
    v, f = torus()
    cv, cf, _ = fit_cage(v, f, faces=150)
    centre = cv.mean(axis=0)
    shrunk = centre + 0.8 * (cv - centre)
    report = cage_report(v, f, shrunk, cf, faces=150)
    assert not report.ok
    assert not report.checks["encloses_vertices"]
    assert not report.checks["no_cut"]


def test_bundled_template_cage_file_is_template_cage():
    import os

    from cagekit.io import load_mesh

    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    v, f = load_mesh(os.path.join(root, "data", "template_cage.obj"))
    tv, tf = template_cage()
    np.testing.assert_array_equal(f, tf)
    np.testing.assert_allclose(v, tv, rtol=0, atol=1e-15)


def test_mesh_objects_and_pairs_are_accepted():
    v, f = star_blob(3)
    expected = fit_cage(v, f, faces=80)
    for shape in (trimesh.Trimesh(v, f, process=False), (v, f)):
        cv, cf, _ = fit_cage(shape, faces=80)
        assert np.array_equal(cv, expected[0]) and np.array_equal(cf, expected[1])
    cloud_v, _ = cloud()
    a = fit_cage(trimesh.PointCloud(cloud_v), faces=80)
    b = fit_cage(cloud_v, faces=80)
    assert np.array_equal(a[0], b[0])
    with pytest.raises(InputError, match="not both"):
        fit_cage(trimesh.Trimesh(v, f, process=False), f)


def test_one_cage_component_per_input_component_when_allowed():
    v, f = two_spheres()
    one = fit_cage(v, f, faces=200)
    two = fit_cage(v, f, faces=200, components=2)
    r1 = cage_report(v, f, *one[:2], faces=200)
    r2 = cage_report(v, f, *two[:2], faces=200, components=2)
    # the fit's own report, measured again (the volume to rounding: other frames)
    assert r1.checks == one.report.checks and r2.checks == two.report.checks
    assert r2.volume_ratio == pytest.approx(two.report.volume_ratio, rel=1e-9)
    assert r1.ok and r2.ok
    from cagekit.cage.fitting import _n_components

    assert _n_components(one[1]) == 1
    assert _n_components(two[1]) == 2  # the far-apart spheres get a cage each
    assert r2.volume_ratio < r1.volume_ratio
    # two components are refused where one is asked for
    assert not cage_report(v, f, *two[:2], faces=200, components=1).checks["components"]


def test_report_refuses_an_empty_cage():
    v, f = torus()
    with pytest.raises(InputError, match="at least 4"):
        cage_report(v, f, np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64))


def test_template_below_its_face_count_is_refused():
    from cagekit.cage.shapes import box_cage
    from cagekit.errors import InputError

    v, f = box_cage(2)
    with pytest.raises(InputError, match="80 faces"):
        fit_cage(v, f, faces=79, method="template")


def test_repair_leaves_every_sample_margin_inside():
    # a cage too small for its samples is pushed out over several rounds; the repair
    # measures again only samples that may have come near the cage, so every sample is
    # checked here with a full signed-distance pass
    from cagekit.cage.fitting import _repair, _signed_distance

    sphere = trimesh.creation.icosphere(subdivisions=1)
    cv, cf = np.asarray(sphere.vertices) * 0.3, np.asarray(sphere.faces, dtype=np.int64)
    rng = np.random.default_rng(0)
    directions = rng.normal(size=(4000, 3))
    samples = 0.31 * directions / np.linalg.norm(directions, axis=1, keepdims=True)
    samples *= rng.uniform(0.2, 1.0, (4000, 1)) ** 0.1  # most near the surface
    assert (_signed_distance(samples, cv, cf)[0] > -1e-3).sum() > 100
    repaired = _repair(cv, cf, samples, margin=1e-3, rounds=30)
    assert repaired is not None
    assert _signed_distance(samples, repaired, cf)[0].max() <= -1e-3


@pytest.mark.parametrize("faces", [10**9, 100_001, 200.5, 200.0, True, "200", 3, None])
def test_face_budget_is_an_int_within_the_documented_range(faces):
    from cagekit.cage.shapes import box_cage

    v, f = box_cage(2)
    message = r"faces must be an integer from 4 to 100,000 .*got " + repr(faces)
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        fit_cage(v, f, faces=faces)
    if faces is not None:  # None is cage_report's default: the cage's own count
        with pytest.raises(InputError, match="faces must be an integer"):
            cage_report(v, f, v, f, faces=faces)


def test_face_budget_takes_numpy_integers_and_the_bounds():
    from cagekit.cage.fitting import MAX_FACES, MIN_FACES, check_face_budget

    assert (MIN_FACES, MAX_FACES) == (4, 100_000)
    assert check_face_budget(np.int64(200)) == 200 and type(check_face_budget(np.int64(200))) is int
    assert check_face_budget(4) == 4 and check_face_budget(100_000) == 100_000
