"""Tests of cagekit.deform: the per-pair cage energy, its solver and the baselines."""

import numpy as np
import pytest
import trimesh
from builders import bumpy_blob

import cagekit
from cagekit.deformation import DEFAULT_WEIGHTS, CageEnergy
from cagekit.deformation.terms import mirror
from cagekit.errors import InputError
from cagekit.metrics import dcotlap, evaluate, point_chamfer

SCALE = cagekit.DeformOptions(method="scale")


@pytest.fixture(scope="module")
def blob():
    return bumpy_blob()


@pytest.fixture(scope="module")
def blob_cage(blob):
    return cagekit.fit_cage(*blob, faces=120)[:2]


def symmetry_error(V, axis="x"):
    V = V - 0.5 * (V.min(axis=0) + V.max(axis=0))
    return point_chamfer(V, mirror(V, axis))


# ------------------------------------------------------------------------- the energy


def assert_gradient_by_differences(energy, C, grad, rng, h=1e-6):
    """Twelve random entries of ``grad`` against central differences of the energy."""
    for _ in range(12):
        i, a = rng.integers(len(C)), rng.integers(3)
        Cp, Cm = C.copy(), C.copy()
        Cp[i, a] += h
        Cm[i, a] -= h
        numeric = (energy.evaluate(Cp)[0] - energy.evaluate(Cm)[0]) / (2 * h)
        assert numeric == pytest.approx(grad[i, a], abs=1e-6 * np.abs(grad).max())


def test_energy_gradient_matches_finite_differences(blob, blob_cage):
    """The full weighted energy's gradient, every term on, by central differences."""
    V, F = blob
    cage_v, cage_f = blob_cage
    b = cagekit.bind(V, cage_v, cage_f)
    rng = np.random.default_rng(0)
    from cagekit.deformation.terms import shape_reference
    from cagekit.geometry import vertex_neighborhoods

    nb = vertex_neighborhoods(V, F)
    ref = shape_reference(V, np.arange(len(V)), nb.index, nb.mask)
    target = V * [1.2, 0.9, 1.0] + 0.01 * rng.standard_normal(V.shape)
    weights = dict(DEFAULT_WEIGHTS, landmarks=0.7, symmetry=0.5)
    from cagekit.deformation.terms import part_affinity_matrix, part_bases

    halves = part_bases(V, (V[:, 0] > 0).astype(int))  # two "parts"
    from cagekit.deformation.terms import detail_matrix
    from cagekit.geometry import cotangent_laplacian

    energy = CageEnergy(b.weights, target, b.weights, ref, cage_f, cage_v, weights,
                        symmetry="x", W_landmarks=b.weights[:5], landmarks=target[:5],
                        parts_matrix=part_affinity_matrix(b.weights, halves),
                        detail_matrix=detail_matrix(b.weights, cotangent_laplacian(V, F)))
    C = cage_v + 0.02 * rng.standard_normal(cage_v.shape)
    value, grad, values = energy.evaluate(C)
    assert set(values) == {"chamfer", "landmarks", "p2f", "normal", "symmetry", "cage",
                           "parts", "detail"}
    assert value == pytest.approx(sum(weights[k] * v for k, v in values.items()))
    assert_gradient_by_differences(energy, C, grad, rng)


def test_green_energy_gradient_matches_finite_differences(blob, blob_cage):
    """Under Green coordinates every term acts on [C; s n'(C)]; the gradient through the
    faces' normals and stretch factors, by central differences."""
    from cagekit.coords.green import FaceTerms
    from cagekit.deformation.terms import (
        detail_matrix,
        part_affinity_matrix,
        part_bases,
        shape_reference,
    )
    from cagekit.geometry import cotangent_laplacian, vertex_neighborhoods

    V, F = blob
    cage_v, cage_f = blob_cage
    b = cagekit.bind(V, cage_v, cage_f, method="green")
    W = np.hstack([b.phi, b.psi])
    terms = FaceTerms(b.cage_v, b.cage_f)
    rng = np.random.default_rng(1)
    nb = vertex_neighborhoods(V, F)
    ref = shape_reference(V, np.arange(len(V)), nb.index, nb.mask)
    target = V * [1.2, 0.9, 1.0] + 0.01 * rng.standard_normal(V.shape)
    weights = dict(DEFAULT_WEIGHTS, landmarks=0.7, symmetry=0.5)
    halves = part_bases(V, (V[:, 0] > 0).astype(int))
    energy = CageEnergy(W, target, W, ref, b.cage_f, b.cage_v, weights, symmetry="x",
                        W_landmarks=W[:5], landmarks=target[:5],
                        parts_matrix=part_affinity_matrix(W, halves),
                        detail_matrix=detail_matrix(W, cotangent_laplacian(V, F)),
                        face_terms=terms)
    # at rest the deformation is the identity: the detail and shape terms vanish
    assert energy.evaluate(b.cage_v)[2]["detail"] == pytest.approx(0.0, abs=1e-20)
    np.testing.assert_allclose(W @ energy.lift(b.cage_v), V, atol=1e-10)
    C = b.cage_v * [1.1, 0.95, 1.0] + 0.02 * rng.standard_normal(cage_v.shape)
    value, grad, values = energy.evaluate(C)
    assert value == pytest.approx(sum(weights[k] * v for k, v in values.items()))
    assert_gradient_by_differences(energy, C, grad, rng)


def test_deform_with_green_coordinates_recovers_a_similar_copy(blob, blob_cage):
    # the target: the source rotated, scaled and moved; both coordinates get it back
    V, F = blob
    angle = 0.4
    R = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0],
                  [0, 0, 1]])
    target = (2.5 * V @ R.T + [1.0, -2.0, 0.5], F)
    errors = {}
    for coords in ("mvc", "green"):
        result = cagekit.deform(V, F, *target, *blob_cage,
                                options=cagekit.DeformOptions(coords=coords, seed=0))
        assert result.iterations > 1 and np.isfinite(result.vertices).all()
        errors[coords] = point_chamfer(result.vertices, target[0]) / 2.5**2
    scale = point_chamfer(cagekit.deform(V, F, *target, options=SCALE).vertices,
                             target[0]) / 2.5**2
    assert errors["green"] < 0.5 * scale


def test_optimiser_lowers_the_energy_and_the_chamfer_distance(blob, blob_cage):
    target = (bumpy_blob((1.0, 0.6, 0.45))[0] * [1.0, 1.0, 1.0], blob[1])
    # a non-affine target: the top half swells
    Vt = target[0].copy()
    Vt[Vt[:, 1] > 0] *= [1.25, 1.0, 1.25]
    result = cagekit.deform(*blob, Vt, blob[1], *blob_cage)
    assert result.energy < 0.8 * result.initial_energy
    assert result.iterations > 5
    scale = cagekit.deform(*blob, Vt, blob[1], options=SCALE)
    cd_cage = evaluate(*blob, Vt, blob[1], result.vertices).cd
    cd_scale = evaluate(*blob, Vt, blob[1], scale.vertices).cd
    assert cd_cage < 0.7 * cd_scale


@pytest.mark.parametrize("stretch, reference", [
    ((2.0, 2.0, 2.0), "source"),    # a uniformly scaled copy: dCotLap of the exact answer 0
    ((2.0, 2.0, 2.0), "aligned"),
    ((1.4, 0.8, 1.0), "aligned"),   # a stretched copy: the stretch is free with "aligned"
])
def test_scaled_copy_is_recovered_with_near_zero_distortion(blob, blob_cage, stretch,
                                                            reference):
    V, F = blob
    target = V * stretch + [5.0, -3.0, 1.0]  # another frame and units
    result = cagekit.deform(*blob, target, F, *blob_cage,
                            options=cagekit.DeformOptions(reference=reference))
    size = np.ptp(target, axis=0).max()
    assert np.abs(result.vertices - target).max() < 0.01 * size
    Vs_n = cagekit.Frame.of(V).to_unit(V)
    frame = cagekit.Frame.of(target)
    Vt_n = frame.to_unit(target)
    d = dcotlap(Vs_n, F, frame.to_unit(result.vertices))
    exact = dcotlap(Vs_n, F, Vt_n)  # 0 for the uniform copy, the stretch's own cost
    # 5e-6 is 0.005 in the paper's tables (x 1e3): sample noise of the Chamfer term
    assert d - exact < 5e-6


def test_source_reference_charges_for_stretch(blob, blob_cage):
    """The paper's reference follows a stretch most of the way, not all of it."""
    V, F = blob
    target = V * [1.4, 0.8, 1.0]
    result = cagekit.deform(*blob, target, F, *blob_cage,
                            options=cagekit.DeformOptions(reference="source"))
    assert result.weights["cage"] == 1.0  # its own default
    aligned = cagekit.deform(*blob, target, F, *blob_cage)
    assert aligned.weights["cage"] == 0.3
    error = np.abs(result.vertices - target).max()
    assert error < 0.05 * np.ptp(target, axis=0).max()
    assert error < 0.25 * np.abs(V - target).max()


def test_symmetric_inputs_stay_symmetric_with_the_symmetry_term(blob):
    V, F = blob
    Vt = V.copy()
    Vt[Vt[:, 1] > 0] *= [1.3, 1.0, 1.0]  # symmetric about x = 0 still
    assert symmetry_error(Vt) < 1e-4
    without = cagekit.deform(*blob, Vt, F)
    with_symmetry = cagekit.deform(*blob, Vt, F, options=cagekit.DeformOptions(symmetry="x"))
    assert "symmetry" in with_symmetry.losses and "symmetry" not in without.losses
    assert symmetry_error(with_symmetry.vertices) < 1e-3 * np.ptp(Vt, axis=0).max() ** 2
    assert symmetry_error(with_symmetry.vertices) <= symmetry_error(without.vertices)


def test_deterministic_with_a_seed(blob, blob_cage):
    Vt = blob[0] * [1.2, 1.0, 0.9]
    a = cagekit.deform(*blob, Vt, None, *blob_cage, options=cagekit.DeformOptions(seed=3))
    b = cagekit.deform(*blob, Vt, None, *blob_cage, options=cagekit.DeformOptions(seed=3))
    np.testing.assert_array_equal(a.vertices, b.vertices)


def test_result_fields_and_frames(blob, blob_cage):
    V, F = blob
    target = (V * 10.0 + 100.0, F)
    result = cagekit.deform(*blob, *target, *blob_cage,
                            options=cagekit.DeformOptions(max_evaluations=10))
    assert isinstance(result, cagekit.DeformResult)
    assert result.vertices.shape == V.shape and result.vertices.dtype == np.float64
    np.testing.assert_array_equal(result.faces, F)
    np.testing.assert_allclose(result.cage_v, blob_cage[0])  # the source's frame
    assert result.deformed_cage_v.shape == blob_cage[0].shape
    # the deformed cage carries the deformed shape: binding reproduces the output
    b = cagekit.bind(V, *blob_cage)
    np.testing.assert_allclose(b.deform(result.deformed_cage_v), result.vertices,
                               atol=1e-9 * 10)
    assert 90.0 < result.vertices.mean(axis=0).min()  # in the target's units
    assert result.seconds > 0 and result.method == "cage"
    assert set(result.losses) == {"chamfer", "p2f", "normal", "cage", "detail"}


def test_a_numerically_collinear_face_keeps_the_detail_term(blob, blob_cage):
    # a sliver on an edge, as real meshes have: its cotangents are not finite in libigl;
    # the detail term (and dCotLap) drop it instead of the whole term (or the result)
    V, F = blob
    a, b = F[0, 0], F[0, 1]
    V2 = np.vstack([V, 0.3 * V[a] + 0.7 * V[b]])
    F2 = np.vstack([F, [[a, len(V), b]]])
    target = (V * [1.3, 0.9, 1.1], F)
    result = cagekit.deform(V2, F2, *target, *blob_cage,
                            options=cagekit.DeformOptions(max_evaluations=5))
    assert "detail" in result.losses and np.isfinite(result.losses["detail"])
    figures = cagekit.evaluate(V2, F2, *target, result.vertices, n_samples=500)
    assert np.isfinite(figures.dcotlap) and figures.dcotlap > 0


def test_initial_cage_sets_where_the_optimiser_starts(blob, blob_cage):
    V, F = blob
    target = (V * [1.3, 0.9, 1.1] * 5.0 + 2.0, F)
    first = cagekit.deform(*blob, *target, *blob_cage,
                           options=cagekit.DeformOptions(max_evaluations=15))
    # starting from an earlier result (in the target's frame) continues from its energy
    again = cagekit.deform(*blob, *target, *blob_cage,
                           options=cagekit.DeformOptions(max_evaluations=15),
                           initial_cage=first.deformed_cage_v)
    assert again.initial_energy == pytest.approx(first.energy, rel=1e-9)
    assert again.energy <= first.energy
    # a start far from the answer begins higher than the box-aligned default
    far = cagekit.deform(*blob, *target, *blob_cage,
                         options=cagekit.DeformOptions(max_evaluations=1),
                         initial_cage=first.deformed_cage_v * 1.5)
    assert far.initial_energy > first.initial_energy
    with pytest.raises(InputError, match="method cage only"):
        cagekit.deform(*blob, *target, options=SCALE, initial_cage=first.deformed_cage_v)
    with pytest.raises(InputError, match="needs the cage"):
        cagekit.deform(*blob, *target, initial_cage=first.deformed_cage_v)
    with pytest.raises(InputError, match="vertices"):
        cagekit.deform(*blob, *target, *blob_cage, initial_cage=first.deformed_cage_v[:-1])


def test_point_cloud_target_and_source(blob, blob_cage):
    V, F = blob
    rng = np.random.default_rng(1)
    Vt = V.copy()
    Vt[Vt[:, 1] > 0] *= [1.25, 1.0, 1.25]
    cloud = trimesh.Trimesh(Vt, F).sample(3000, seed=rng) + 0.003 * rng.standard_normal((3000, 3))
    result = cagekit.deform(*blob, cloud, None, *blob_cage)
    scale = cagekit.deform(*blob, cloud, None, options=SCALE)
    cd = [point_chamfer(r.vertices, cloud) for r in (result, scale)]
    assert cd[0] < 0.7 * cd[1]
    points = trimesh.Trimesh(V, F).sample(1500, seed=2)
    moved = cagekit.deform(points, None, cloud, None)
    assert moved.vertices.shape == (1500, 3) and len(moved.faces) == 0
    assert "normal" in moved.losses  # shape terms on k-NN neighbourhoods
    assert "detail" not in moved.losses  # no faces, no cotangent Laplacian


def test_partial_point_cloud_target(blob, blob_cage):
    """A single-view-like scan: only the points facing +z, noisy, of a swollen target."""
    V, F = blob
    Vt = V.copy()
    Vt[Vt[:, 1] > 0] *= [1.25, 1.0, 1.25]
    rng = np.random.default_rng(4)
    cloud = trimesh.Trimesh(Vt, F).sample(4000, seed=rng)
    cloud = cloud[cloud[:, 2] > -0.1]
    cloud = cloud + 0.002 * rng.standard_normal(cloud.shape)
    result = cagekit.deform(*blob, cloud, None, *blob_cage)
    scale = cagekit.deform(*blob, cloud, None, options=SCALE)
    assert np.isfinite(result.vertices).all()
    # how far the scanned points are from the result (the direction a partial scan defines)
    from scipy.spatial import cKDTree

    def scan_to_shape(X):
        return float(np.mean(cKDTree(X).query(cloud)[0] ** 2))

    assert scan_to_shape(result.vertices) < 0.7 * scan_to_shape(scale.vertices)


def test_landmarks_replace_chamfer(blob, blob_cage):
    V, F = blob
    target = V * [1.3, 1.0, 1.0]
    idx = np.array([0, 5, 40, 100, 300, 500])
    moved_target = target[idx] + [0.0, 0.05, 0.0]
    result = cagekit.deform(*blob, target, F, *blob_cage, landmarks=(V[idx], moved_target))
    assert "landmarks" in result.losses and "chamfer" not in result.losses
    before = np.abs(V[idx] * [1.3, 1, 1] - moved_target).max()
    after = np.abs(result.vertices[idx] - moved_target).max()
    assert after < 0.5 * before


def test_scale_baseline_maps_bounding_boxes(blob):
    V, F = blob
    target = V * [3.0, 0.5, 2.0] + 7.0
    result = cagekit.deform(*blob, target, F, options=SCALE)
    np.testing.assert_allclose(result.vertices.min(axis=0), target.min(axis=0), atol=1e-12)
    np.testing.assert_allclose(result.vertices.max(axis=0), target.max(axis=0), atol=1e-12)
    assert result.cage_v is None and result.iterations == 0


def test_nricp_baseline_runs(blob):
    V, F = blob
    target = V * [1.2, 1.0, 1.0]
    result = cagekit.deform(*blob, target, F, options=cagekit.DeformOptions(method="nricp"))
    assert result.vertices.shape == V.shape and np.isfinite(result.vertices).all()
    with pytest.raises(InputError, match="nricp needs a source mesh"):
        cagekit.deform(V, None, target, F, options=cagekit.DeformOptions(method="nricp"))


@pytest.mark.parametrize("kwargs, message", [
    ({"method": "warp"}, "unknown method"),
    ({"symmetry": "w"}, "symmetry"),
    ({"weights": {"smooth": 1.0}}, "unknown energy term"),
    ({"weights": {"cage": -1.0}}, ">= 0"),
    ({"landmarks": (np.zeros((2, 3)), np.zeros((3, 3)))}, "landmarks"),
    ({"reference": "target"}, "reference"),
    ({"weights": {"landmarks": 1.0}}, "no landmarks"),
    ({"weights": {"symmetry": 1.0}}, "no symmetry axis"),
    ({"samples": 0}, "samples"),
    ({"landmarks": (np.zeros((1, 3)) + 50.0, np.zeros((1, 3)))}, "far outside"),
])
def test_bad_arguments(blob, blob_cage, kwargs, message):
    with pytest.raises(InputError, match=message):
        landmarks = kwargs.pop("landmarks", None)
        cagekit.deform(*blob, *blob, *blob_cage, options=cagekit.DeformOptions(**kwargs),
                       landmarks=landmarks)


def test_a_cage_needs_its_vertices_and_faces(blob, blob_cage):
    with pytest.raises(InputError, match="both its vertices and its faces"):
        cagekit.deform(*blob, *blob, np.zeros((8, 3)))
    with pytest.raises(InputError, match="both its vertices and its faces"):
        cagekit.deform(*blob, *blob, cage_f=blob_cage[1])
    with pytest.raises(InputError, match="options must be DeformOptions"):
        cagekit.deform(*blob, *blob, options={"method": "scale"})


def test_a_two_point_cloud_target(blob):
    result = cagekit.deform(*blob, [[0.0, 0, 0], [1.0, 2.0, 1.0]], None, options=SCALE)
    assert np.allclose(result.vertices.min(axis=0), 0) and len(result.faces) == len(blob[1])


def test_nan_target_is_refused(blob):
    bad = blob[0].copy()
    bad[3, 1] = np.nan
    with pytest.raises(InputError):
        cagekit.deform(*blob, bad, blob[1])


def test_the_parts_of_a_multi_part_source_stay_affine():
    # procedural chairs of 17 parts: with the part-affinity term (default) every part
    # stays within 0.5% of an affine map of itself while the shape still moves well
    # towards the target (CD below box scaling's); without it (parts=0) a part bends
    from cagekit.datasets import synthetic

    source, target = synthetic.chair(seed=2), synthetic.chair(seed=3)
    kept = cagekit.deform(*source, *target, options=cagekit.DeformOptions(symmetry="x"))
    bent = cagekit.deform(*source, *target,
                          options=cagekit.DeformOptions(symmetry="x", weights={"parts": 0.0}))
    scaled = cagekit.deform(*source, *target, options=SCALE)
    figures = {name: evaluate(*source, *target, r.vertices)
               for name, r in (("kept", kept), ("bent", bent), ("scaled", scaled))}
    assert figures["kept"].parts == 17
    assert figures["kept"].part_nonaffinity_worst < 0.005
    assert figures["bent"].part_nonaffinity_worst > 0.01
    assert figures["kept"].cd < 0.5 * figures["scaled"].cd
    assert "parts" in kept.losses and "parts" not in bent.losses  # the term ran or not


def test_a_source_split_at_its_seams_keeps_its_parts_affine():
    # a file that repeats vertices along every edge (UV seams) has the same 17 parts: the
    # part term runs on them, and no part bends
    from cagekit.datasets import synthetic

    (V, F), target = synthetic.chair(seed=2), synthetic.chair(seed=3)
    Vs, Fs = V[F.ravel()], np.arange(3 * len(F)).reshape(-1, 3)
    kept = cagekit.deform(Vs, Fs, *target, options=cagekit.DeformOptions(symmetry="x"))
    figures = evaluate(Vs, Fs, *target, kept.vertices)
    assert "parts" in kept.losses
    assert figures.parts == 17
    assert figures.part_nonaffinity_worst < 0.005


def test_nricp_refuses_vertices_on_no_face_in_one_line():
    # trimesh's nricp_amberg fails deep inside scipy on such a mesh (a shape mismatch, or
    # a singular system); cagekit names the problem instead
    V, F = bumpy_blob()
    loose = np.vstack([V, [[0.0, 0.0, 0.0]]])
    with pytest.raises(InputError, match="1 are on none"):
        cagekit.deform(loose, F, V * [1.2, 1.0, 1.0], F,
                       options=cagekit.DeformOptions(method="nricp"))


def _scan_from_below(V, F, rays=60):
    """The first hits of a grid of vertical rays cast upwards: what a scanner below sees."""
    mesh = trimesh.Trimesh(V, F, process=False)
    lo, hi = V.min(axis=0), V.max(axis=0)
    x, z = np.meshgrid(np.linspace(lo[0], hi[0], rays), np.linspace(lo[2], hi[2], rays))
    origins = np.column_stack([x.ravel(), np.full(x.size, lo[1] - 0.1), z.ravel()])
    directions = np.tile([0.0, 1.0, 0.0], (len(origins), 1))
    return mesh.ray.intersects_location(origins, directions, multiple_hits=False)[0]


def test_a_partial_target_is_reached_without_squashing_the_unseen_side():
    # a chair seen from below (seat underside, legs; no backrest): treated as a full
    # target the source is squashed onto it; with target_kind="partial" the result is
    # much closer to the full target it was scanned from
    from cagekit.datasets import synthetic
    from cagekit.geometry.frame import Frame
    from cagekit.metrics import chamfer

    source, target = synthetic.chair(seed=4), synthetic.chair(seed=5)
    scan = _scan_from_below(*target)
    frame = Frame.of(target[0])

    def cd(result):
        return chamfer(frame.to_unit(result.vertices), source[1], frame.to_unit(target[0]),
                       target[1], n_samples=3000, seed=0)

    as_full = cd(cagekit.deform(*source, scan, None, options=cagekit.DeformOptions(symmetry="x")))
    partial = cd(cagekit.deform(*source, scan, None,
                                options=cagekit.DeformOptions(symmetry="x", target_kind="partial")))
    assert partial < 0.5 * as_full
    with pytest.raises(InputError, match="target_kind"):
        cagekit.deform(*source, scan, None, options=cagekit.DeformOptions(target_kind="half"))


def test_the_detail_term_lowers_dcotlap(blob, blob_cage):
    # the source's own cotangent Laplacian charged (default weight 1, or 10) against none:
    # dCotLap falls while the target is still reached (CD well below box scaling's)
    V, F = blob
    Vt = V.copy()
    Vt[Vt[:, 1] > 0] *= [1.25, 1.0, 1.25]  # the top half swells
    figures = {}
    for weight in (0.0, 1.0, 10.0):
        r = cagekit.deform(*blob, Vt, F, *blob_cage,
                           options=cagekit.DeformOptions(weights={"detail": weight}))
        figures[weight] = evaluate(*blob, Vt, F, r.vertices)
        assert ("detail" in r.losses) == (weight > 0)
    scale = cagekit.deform(*blob, Vt, F, options=SCALE)
    cd_scale = evaluate(*blob, Vt, F, scale.vertices).cd
    assert figures[10.0].dcotlap < figures[1.0].dcotlap < figures[0.0].dcotlap
    assert figures[10.0].cd < 0.7 * cd_scale


def test_shape_rows_keep_only_the_columns_their_rows_need():
    # a fan's centre of degree 12 sets the width of the one-ring arrays (13); rows that
    # do not include it are trimmed to their own widest neighbourhood, members unchanged
    from cagekit.deformation.problem import _shape_rows
    from cagekit.geometry import vertex_neighborhoods

    V, F = bumpy_blob()
    angles = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    fan = np.vstack([[3.0, 0, 0], np.c_[3 + np.cos(angles), np.sin(angles), 0 * angles]])
    ring = len(V) + 1 + np.arange(12)
    fan_f = np.c_[np.full(12, len(V)), ring, np.roll(ring, -1)]
    V, F = np.vstack([V, fan]), np.vstack([F, fan_f])
    nb = vertex_neighborhoods(V, F)
    assert nb.mask.shape[1] == 13
    used, own, index, mask = _shape_rows(V, F, 40, np.random.default_rng(0))
    rows = used[own]
    assert len(V) - 13 not in rows  # the centre is not a chosen row
    assert index.shape == mask.shape and mask.any(axis=0).all()
    assert mask.shape[1] == mask.sum(axis=1).max() <= 7
    for r, row in enumerate(rows):
        members = used[index[r][mask[r]]]
        np.testing.assert_array_equal(members, nb.index[row][nb.mask[row]])
