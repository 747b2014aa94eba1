"""Evaluation metrics of a deformation: Chamfer distance, cotangent-Laplacian distortion and
the structure of man-made shapes (parts kept affine, planes kept planar, symmetry kept).

The definitions are those of docs/architecture.md ("Metrics", as the paper's evaluation
code computes them): ``CD = mean_a min_b |a - b|^2 + mean_b min_a |a - b|^2`` on 5000
area-uniform samples per surface (tables print ``CD x 10^2``), and ``dCotLap``, the mean
over all ``n x 3`` entries of ``(L (V_out - V_src))^2`` with ``L`` the cotangent Laplacian,
no mass matrix, of the normalised source (tables print ``dCotLap x 10^3``). In
:func:`evaluate` the target is normalised on its own, the deformed source is mapped by the
target's normalisation and the source normalised on its own is the distortion reference.
The two surfaces are sampled with independent streams spawned from one ``seed``, so CD
measures the distance between surfaces, not vertex correspondence: identical shapes give a
small positive CD and ``chamfer(a, b)`` equals ``chamfer(b, a)`` only in distribution. A
point cloud is not resampled (a seeded subset when it has more than ``n`` points). dCotLap
is invariant to translating ``V_out``, not to rotating or scaling it. Duplicate faces,
zero-area faces and slivers are removed before ``L`` is built
(:func:`cagekit.geometry.surface_laplacian`; a vertex only on such faces gets an empty row,
still counted in ``n``); a source without other faces raises ``InputError``.

The structure figures (docs/architecture.md, "Metrics") see what CD and dCotLap do not: a chair leg
bent, a seat warped, a symmetric chair made lopsided. :func:`part_nonaffinity` fits an
affine map to each connected component of the source, :func:`planarity` measures how far
adjacent faces of its planar regions turn against each other and :func:`symmetry_error`
how far the result is from the source's mirror symmetry. Any affine map of the shape
scores 0 on the first two; the figures are invariant to similarities of the result.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from cagekit.errors import InputError
from cagekit.geometry import (
    as_count,
    as_faces,
    as_shape,
    as_vertices,
    face_areas,
    remove_duplicate_faces,
    surface_laplacian,
)
from cagekit.geometry.frame import Frame
from cagekit.geometry.parts import vertex_parts
from cagekit.geometry.sampling import sample_surface

__all__ = ["Evaluation", "chamfer", "chamfers_to", "point_chamfer", "conformal_distortion",
           "dcotlap", "evaluate", "nearest_residuals", "part_nonaffinity", "planarity",
           "symmetry_error", "MIN_PART_VERTICES", "PLANAR_DEGREES", "SYMMETRY_TOLERANCE"]

#: a source component with fewer vertices is too small to be a part (a screw, a label)
MIN_PART_VERTICES = 30
#: adjacent source faces whose normals differ by at most this are one planar region
PLANAR_DEGREES = 1.0
#: a source is mirror-symmetric when every mirrored vertex is this close to a vertex
#: (share of its bounding-box diagonal)
SYMMETRY_TOLERANCE = 1e-3


def nearest_residuals(P: np.ndarray, Q: np.ndarray,
                      tree_Q: cKDTree | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Each point of ``P`` minus its nearest point of ``Q``: the one nearest-neighbour step
    of every Chamfer in cagekit (:func:`point_chamfer`, and the energy's
    :func:`cagekit.deformation.terms.chamfer_loss` with its gradient).

    Parameters
    ----------
    P : (n, 3) float64
    Q : (m, 3) float64
    tree_Q : scipy.spatial.cKDTree, optional
        A tree built on ``Q``, reused across calls.

    Returns
    -------
    residuals : (n, 3) float64
        ``P - Q[index]``.
    index : (n,) int64
        The nearest point of ``Q`` to each point of ``P`` (``scipy.spatial.cKDTree``).

    Examples
    --------
    >>> residuals, index = nearest_residuals(np.array([[0.0, 0, 1]]), np.zeros((2, 3)))
    >>> residuals.tolist(), index.tolist()
    ([[0.0, 0.0, 1.0]], [0])
    """
    _, index = (cKDTree(Q) if tree_Q is None else tree_Q).query(P)
    return P - Q[index], index


def _nearest_sq(P: np.ndarray, Q: np.ndarray, tree_Q: cKDTree | None = None) -> np.ndarray:
    """Squared distance from each point of P to its nearest point of Q, shape (len(P),)."""
    diff, _ = nearest_residuals(P, Q, tree_Q)
    return np.einsum("ij,ij->i", diff, diff)


def point_chamfer(P: ArrayLike, Q: ArrayLike) -> float:
    """Chamfer distance between two point sets (squared, both directions summed).

    ``mean_{a in P} min_{b in Q} |a - b|^2 + mean_{b in Q} min_{a in P} |a - b|^2``,
    nearest neighbours by ``scipy.spatial.cKDTree``.

    Parameters
    ----------
    P : array_like, shape (n, 3), float
    Q : array_like, shape (m, 3), float

    Returns
    -------
    cd : float
        Non-negative; 0 for equal sets; symmetric in ``P`` and ``Q``.

    Examples
    --------
    >>> point_chamfer([[0, 0, 0]], [[0, 0, 2]])
    8.0
    """
    P = as_vertices(P, "P")
    Q = as_vertices(Q, "Q")
    return float(_nearest_sq(P, Q).mean() + _nearest_sq(Q, P).mean())


def chamfer(
    Va: ArrayLike,
    Fa: ArrayLike | None,
    Vb: ArrayLike,
    Fb: ArrayLike | None,
    n_samples: int = 5000,
    seed: int = 0,
) -> float:
    """Chamfer distance between two surfaces (or clouds), sampled independently.

    Shape a is sampled with the first and shape b with the second of two random streams
    derived from ``seed`` (``numpy.random.SeedSequence(seed).spawn(2)``), so the result
    is deterministic for a given seed but two shapes of the same topology do not get
    samples at the same places of the same faces.

    Parameters
    ----------
    Va, Vb : array_like, shape (na, 3) and (nb, 3), float
        Vertex positions of the two shapes.
    Fa, Fb : array_like, shape (ma, 3) and (mb, 3), int, or None
        Their triangles; ``None`` or empty for point clouds.
    n_samples : int, optional
        Samples per shape (see :func:`~cagekit.geometry.sampling.sample_surface`).
    seed : int, optional
        Non-negative; the two sampling streams are derived from it.

    Returns
    -------
    cd : float
        :func:`point_chamfer` of the two sample sets. Identical shapes give a small
        positive value, of the order of the squared sample spacing.

    Raises
    ------
    InputError
        A negative or non-integer ``seed``, or bad input.

    Examples
    --------
    >>> V, F = [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]
    >>> cd = chamfer(V, F, V, F, n_samples=1000)
    >>> 0.0 < cd < 1e-3, cd == chamfer(V, F, V, F, n_samples=1000)
    (True, True)
    """
    seed_a, seed_b = _chamfer_seeds(seed)
    A = sample_surface(Va, Fa, n_samples, seed_a)
    B = sample_surface(Vb, Fb, n_samples, seed_b)
    return point_chamfer(A, B)


def _chamfer_seeds(seed):
    """The two sample streams' seeds of :func:`chamfer` (``seed`` checked)."""
    return tuple(int(s.generate_state(1)[0])
                 for s in np.random.SeedSequence(as_count(seed, "seed")).spawn(2))


def chamfers_to(versions: list[ArrayLike], Fa: ArrayLike | None, Vb: ArrayLike,
                Fb: ArrayLike | None, n_samples: int = 5000, seed: int = 0) -> list[float]:
    """:func:`chamfer` of each of several positions of one mesh to one target, the target
    sampled (and its tree built) once.

    Parameters
    ----------
    versions : list of (n, 3) array_like of float
        Vertex positions of the mesh, each with faces ``Fa``.
    Fa, Vb, Fb, n_samples, seed
        As :func:`chamfer`.

    Returns
    -------
    list of float
        ``chamfer(V, Fa, Vb, Fb, n_samples, seed)`` for each ``V`` of ``versions``, equal
        to it bit for bit.

    Examples
    --------
    >>> V, F = [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]
    >>> moved = [[0, 0, 1], [1, 0, 1], [0, 1, 1]]
    >>> cds = chamfers_to([V, moved], F, V, F, n_samples=100)
    >>> cds == [chamfer(V, F, V, F, 100), chamfer(moved, F, V, F, 100)]
    True
    """
    seed_a, seed_b = _chamfer_seeds(seed)
    B = as_vertices(sample_surface(Vb, Fb, n_samples, seed_b), "Q")
    tree_B = cKDTree(B)
    out = []
    for V in versions:
        A = as_vertices(sample_surface(V, Fa, n_samples, seed_a), "P")
        out.append(float(_nearest_sq(A, B, tree_B).mean() + _nearest_sq(B, A).mean()))
    return out


def dcotlap(V_src: ArrayLike, F_src: ArrayLike, V_out: ArrayLike) -> float:
    """Cotangent-Laplacian distortion of a deformation ``V_src -> V_out``.

    ``mean over all n x 3 entries of (L (V_out - V_src))^2``, ``L`` the cotangent
    Laplacian of ``(V_src, F_src)`` after duplicate faces
    (:func:`cagekit.geometry.remove_duplicate_faces`), faces of zero area and slivers are
    removed (:func:`cagekit.geometry.surface_laplacian`: their cotangents are undefined or
    rounding noise). Both vertex sets must already be in the
    frame the caller wants (:func:`evaluate` uses the normalised frames).

    Parameters
    ----------
    V_src : array_like, shape (n, 3), float
        Source vertices (the rest shape ``L`` is built from).
    F_src : array_like, shape (m, 3), int
        Source triangles, at least one of positive area.
    V_out : array_like, shape (n, 3), float
        Deformed vertices, same order as ``V_src``.

    Returns
    -------
    d : float
        Non-negative; 0 for ``V_out = V_src + t`` (any translation ``t``).

    Raises
    ------
    InputError
        Different vertex counts, no faces of positive area, or bad input.

    Examples
    --------
    >>> V, F = [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]
    >>> dcotlap(V, F, np.asarray(V) + 5.0)
    0.0
    """
    V_src = as_vertices(V_src, "V_src")
    V_out = as_vertices(V_out, "V_out")
    if V_out.shape != V_src.shape:
        raise InputError(
            f"V_out has {len(V_out)} vertices but the source has {len(V_src)}; "
            "the deformed shape must keep the source's vertices"
        )
    F = as_faces(F_src, len(V_src), "F_src")
    if len(F) == 0:
        raise InputError("dCotLap needs the source's faces; the source has none")
    L = surface_laplacian(V_src, F)
    return float(np.mean(np.square(L @ (V_out - V_src))))


@dataclass(frozen=True)
class Evaluation:
    """The figures of one deformation (:func:`evaluate`).

    Attributes
    ----------
    cd, dcotlap : float
        Chamfer distance and cotangent-Laplacian distortion (module docstring).
    cd_x1e2, dcotlap_x1e3 : float
        The same as the paper's tables print them.
    part_nonaffinity_median, part_nonaffinity_worst : float
        :func:`part_nonaffinity`'s vertex-weighted median and worst part.
    parts : int
        Parts measured.
    planarity_mean_deg, planarity_p95_deg : float
        :func:`planarity`'s mean and 95th percentile, degrees.
    symmetry_axis : {"x", "y", "z"} or None
        The source's mirror axis (:func:`symmetry_error`), None when it has none.
    symmetry_error : float or None
    n_samples, seed : int
        The Chamfer distance's samples per surface and seed.
    """

    cd: float
    dcotlap: float
    cd_x1e2: float
    dcotlap_x1e3: float
    part_nonaffinity_median: float
    part_nonaffinity_worst: float
    parts: int
    planarity_mean_deg: float
    planarity_p95_deg: float
    symmetry_axis: str | None
    symmetry_error: float | None
    n_samples: int
    seed: int

    def as_dict(self) -> dict:
        """The figures as a plain dict (for JSON), in field order."""
        return asdict(self)


def evaluate(V_src: ArrayLike, F_src: ArrayLike, V_tgt: ArrayLike, F_tgt: ArrayLike | None,
             V_out: ArrayLike, n_samples: int = 5000, seed: int = 0,
             frames: tuple[Frame, Frame] | None = None) -> Evaluation:
    """CD, dCotLap and the structure figures of a deformed source against a target.

    The target is normalised on its own; the deformed source is mapped by the target's
    ``(center, scale)``; the source normalised on its own is the distortion reference.
    ``cd`` compares the deformed source (target frame, the source's faces) with the
    normalised target; ``dcotlap`` uses ``L`` of the normalised source and ``V_out`` = the
    deformed source in the target's frame.

    Parameters
    ----------
    V_src : (n, 3) array_like of float
        The source before deformation.
    F_src : (m, 3) array_like of int
        Its faces, ``m >= 1`` of positive area.
    V_tgt : (t, 3) array_like of float
        The target.
    F_tgt : (p, 3) array_like of int, or None
        Its faces; None or empty for a point cloud.
    V_out : (n, 3) array_like of float
        The deformed source, in the source's vertex order (its faces are ``F_src``).
    n_samples : int, optional
        Samples per surface for CD (5000 in the paper).
    seed : int, optional
        Sampling seed, non-negative; the two surfaces get independent streams derived
        from it (see :func:`chamfer`).
    frames : (source Frame, target Frame), optional
        The shapes' unit frames (:meth:`cagekit.geometry.frame.Frame.of`) when the caller has them
        already (``DeformResult.source_frame``, ``target_frame``); computed otherwise.

    Returns
    -------
    Evaluation
        The structure figures are those of :func:`part_nonaffinity`, :func:`planarity` and
        :func:`symmetry_error` on the source and the deformed source (invariant to the
        frames).

    Raises
    ------
    InputError
        Deformed and source vertex counts differ, the source has no faces (of positive
        area), a shape has zero extent, a negative seed, or bad input.

    Examples
    --------
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    >>> F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> moved = 2 * V + 1  # scaled and translated copy, also used as the target
    >>> m = evaluate(V, F, moved, F, moved)
    >>> 0.0 < m.cd < 1e-2, m.dcotlap < 1e-20  # CD: the sampling resolution only
    (True, True)
    """
    Vs = as_vertices(V_src, "the source")
    Fs = as_faces(F_src, len(Vs), "the source's faces")
    Vt, Ft = as_shape((as_vertices(V_tgt, "the target"), F_tgt), name="target")
    Vd = as_vertices(V_out, "the deformed shape")
    if len(Vd) != len(Vs):
        raise InputError(
            f"the deformed shape has {len(Vd)} vertices but the source has {len(Vs)}"
        )
    if len(Fs) == 0:
        raise InputError("the source must be a mesh with faces (dCotLap needs them)")
    fs, ft = (Frame.of(Vs), Frame.of(Vt)) if frames is None else frames
    Vs_n, Vt_n, Vd_t = fs.to_unit(Vs), ft.to_unit(Vt), ft.to_unit(Vd)
    cd = chamfer(Vd_t, Fs, Vt_n, Ft, n_samples=n_samples, seed=seed)
    dist = dcotlap(Vs_n, Fs, Vd_t)
    parts = part_nonaffinity(Vs, Fs, Vd)
    flat = planarity(Vs, Fs, Vd)
    mirror = symmetry_error(Vs, Vd)
    return Evaluation(
        cd=cd, dcotlap=dist, cd_x1e2=cd * 1e2, dcotlap_x1e3=dist * 1e3,
        part_nonaffinity_median=parts["median"], part_nonaffinity_worst=parts["worst"],
        parts=parts["parts"], planarity_mean_deg=flat["mean_deg"],
        planarity_p95_deg=flat["p95_deg"],
        symmetry_axis=None if mirror is None else mirror["axis"],
        symmetry_error=None if mirror is None else mirror["error"],
        n_samples=int(n_samples), seed=int(seed))


def part_nonaffinity(V_src: ArrayLike, F_src: ArrayLike, V_out: ArrayLike,
                     min_vertices: int = MIN_PART_VERTICES) -> dict:
    """How far each part of a deformed shape is from an affine map of itself.

    For each part of the source (:func:`cagekit.geometry.parts.vertex_parts`: connected
    components, pieces split at UV or normal seams joined) with at least ``min_vertices``
    vertices (the whole shape when none has), the RMS residual of the least-squares affine fit
    ``V_out ~ [V_src 1] A`` over the part's vertices, divided by the deformed part's
    bounding-box diagonal. Any affine map of the whole shape, or of each part on its own,
    scores 0; a bend scores about the bend's sag over the part's size.

    Parameters
    ----------
    V_src : (n, 3) array_like of float
        The source's vertices.
    F_src : (m, 3) array_like of int
        Its faces (they define the parts).
    V_out : (n, 3) array_like of float
        The deformed vertices, in the source's order (any frame: the figure is invariant
        to similarities of ``V_out``).
    min_vertices : int, default :data:`MIN_PART_VERTICES`

    Returns
    -------
    dict
        ``{"median": float, "worst": float, "parts": int}``: the vertex-weighted median
        over parts, the worst part, the number of parts measured.

    Raises
    ------
    InputError
        Shapes that disagree, no faces.

    Examples
    --------
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    >>> F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> A = np.array([[2.0, 0.3, 0], [0, 1, 0], [0.5, 0, 0.2]])
    >>> part_nonaffinity(V, F, V @ A + 1)["worst"] < 1e-12
    True
    """

    Vs, Vo, F = _paired(V_src, F_src, V_out)
    labels = vertex_parts(Vs, F)
    counts = np.bincount(labels[labels >= 0])
    parts = [np.flatnonzero(labels == c) for c in np.flatnonzero(counts >= min_vertices)]
    if not parts:
        parts = [np.flatnonzero(labels >= 0)]
    values = np.array([_affine_residual(Vs[idx], Vo[idx]) for idx in parts])
    sizes = np.array([len(idx) for idx in parts], dtype=np.float64)
    order = np.argsort(values)
    cumulative = np.cumsum(sizes[order])
    median = values[order][np.searchsorted(cumulative, 0.5 * cumulative[-1])]
    return {"median": float(median), "worst": float(values.max()), "parts": len(parts)}


def planarity(V_src: ArrayLike, F_src: ArrayLike, V_out: ArrayLike,
              tolerance_degrees: float = PLANAR_DEGREES) -> dict:
    """How far faces of the source's planar regions turn against each other.

    Over every pair of faces that share an edge and whose normals in the source differ by
    at most ``tolerance_degrees``: the change of the angle between their normals, in
    degrees. An affine map keeps exactly coplanar faces coplanar (0); a pair within the
    tolerance but not coplanar may change by a fraction of it under a stretch.

    Parameters
    ----------
    V_src : (n, 3) array_like of float
    F_src : (m, 3) array_like of int
    V_out : (n, 3) array_like of float
        The deformed vertices, in the source's order.
    tolerance_degrees : float, default :data:`PLANAR_DEGREES`

    Returns
    -------
    dict
        ``{"mean_deg": float, "p95_deg": float, "pairs": int}`` (zeros and 0 pairs when
        the source has no planar region).

    Examples
    --------
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]])
    >>> F = np.array([[0, 1, 2], [0, 2, 3]])
    >>> bent = V.copy(); bent[3, 2] = 1.0     # one triangle folded about the diagonal
    >>> round(planarity(V, F, bent)["mean_deg"], 3)   # arccos(1 / sqrt(3))
    54.736
    """
    Vs, Vo, F = _paired(V_src, F_src, V_out)
    F = remove_duplicate_faces(F)
    F = F[face_areas(Vs, F) > 0]
    a, b = _adjacent_faces(F)
    before = _normal_angles(Vs, F, a, b)
    planar = before <= tolerance_degrees
    if not planar.any():
        return {"mean_deg": 0.0, "p95_deg": 0.0, "pairs": 0}
    turn = np.abs(_normal_angles(Vo, F, a[planar], b[planar]) - before[planar])
    return {"mean_deg": float(turn.mean()), "p95_deg": float(np.quantile(turn, 0.95)),
            "pairs": int(planar.sum())}


def conformal_distortion(V_src: ArrayLike, F_src: ArrayLike, V_out: ArrayLike) -> dict:
    """How far each face's deformation is from a similarity: ``sigma_1 / sigma_2``.

    Per face of positive area, the singular values of the linear map that takes the
    source face's two edges to the deformed face's (the 3 x 2 deformation gradient in
    the face's own frame): 1 for a similarity of the face, the stretch ratio otherwise
    (2 for a face stretched twice along one of its directions), inf for a face
    collapsed to a segment.

    Parameters
    ----------
    V_src : (n, 3) array_like of float
    F_src : (m, 3) array_like of int
    V_out : (n, 3) array_like of float
        The deformed vertices, in the source's order.

    Returns
    -------
    dict
        ``{"mean": float, "p95": float, "max": float}`` over the faces (area-weighted
        mean).

    Examples
    --------
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    >>> F = np.array([[0, 1, 2]])
    >>> conformal_distortion(V, F, V * [2.0, 1.0, 1.0])["mean"]
    2.0
    """
    Vs, Vo, F = _paired(V_src, F_src, V_out)
    area = face_areas(Vs, F)
    F, area = F[area > 0], area[area > 0]
    if not len(F):
        raise InputError("conformal distortion needs faces of positive area")
    e1, e2 = Vs[F[:, 1]] - Vs[F[:, 0]], Vs[F[:, 2]] - Vs[F[:, 0]]
    t = e1 / np.linalg.norm(e1, axis=1, keepdims=True)
    b = e2 - np.einsum("ij,ij->i", e2, t)[:, None] * t
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    # the source edges in the face's frame (2 x 2, upper triangular) and the deformed ones
    E = np.zeros((len(F), 2, 2))
    E[:, 0, 0] = np.linalg.norm(e1, axis=1)
    E[:, 0, 1] = np.einsum("ij,ij->i", e2, t)
    E[:, 1, 1] = np.einsum("ij,ij->i", e2, b)
    D = np.stack([Vo[F[:, 1]] - Vo[F[:, 0]], Vo[F[:, 2]] - Vo[F[:, 0]]], axis=2)  # (m, 3, 2)
    J = D @ np.linalg.inv(E)
    sigma = np.linalg.svd(J, compute_uv=False)
    with np.errstate(divide="ignore"):
        ratio = np.where(sigma[:, 1] > 0, sigma[:, 0] / np.where(sigma[:, 1] > 0,
                                                                 sigma[:, 1], 1.0), np.inf)
    # collapsed faces (inf) stand in as the largest float for the quantile, whose linear
    # interpolation would make inf - inf = NaN of them
    big = np.finfo(np.float64).max
    p95 = float(np.quantile(np.minimum(ratio, big), 0.95))
    return {"mean": float(np.sum(area * ratio) / area.sum()),
            "p95": p95 if p95 < big else np.inf, "max": float(ratio.max())}


def symmetry_error(V_src: ArrayLike, V_out: ArrayLike,
                   tolerance: float = SYMMETRY_TOLERANCE) -> dict | None:
    """The mirror symmetry the source has, and how much of it the deformed shape keeps.

    The source is symmetric about a plane normal to axis ``x``, ``y`` or ``z`` through
    its bounding-box centre when every vertex's mirror image lies within ``tolerance`` of
    the bounding-box diagonal of a vertex (the first such axis is used). The deformed
    shape is scored with the same vertex pairs: the RMS distance between each vertex's
    mirror image, about the best plane normal to that axis, and its partner, over the
    deformed bounding-box diagonal. A scaling along the axes keeps it 0.

    Parameters
    ----------
    V_src, V_out : (n, 3) array_like of float
        The source and the deformed vertices, in the same order.
    tolerance : float, default :data:`SYMMETRY_TOLERANCE`

    Returns
    -------
    dict or None
        ``{"axis": "x" | "y" | "z", "error": float}``, or None when the source has no
        such symmetry.

    Examples
    --------
    >>> V = np.array([[-1, 0, 0], [1, 0, 0], [-1, 1, 0], [1, 1, 0.0]])
    >>> symmetry_error(V, V * [3, 1, 1])
    {'axis': 'x', 'error': 0.0}
    """
    Vs, Vo, _ = _paired(V_src, np.zeros((0, 3), int), V_out)
    centre = 0.5 * (Vs.min(axis=0) + Vs.max(axis=0))
    diagonal = float(np.linalg.norm(np.ptp(Vs, axis=0)))
    tree = cKDTree(Vs)
    for axis, name in enumerate("xyz"):
        mirrored = Vs.copy()
        mirrored[:, axis] = 2 * centre[axis] - mirrored[:, axis]
        distance, partner = tree.query(mirrored)
        if distance.max() > tolerance * diagonal:
            continue
        plane = 0.5 * (Vo[:, axis] + Vo[partner, axis]).mean()
        image = Vo.copy()
        image[:, axis] = 2 * plane - image[:, axis]
        residual = np.sqrt(np.mean(np.sum((image - Vo[partner]) ** 2, axis=1)))
        return {"axis": name,
                "error": float(residual / np.linalg.norm(np.ptp(Vo, axis=0)))}
    return None


def _paired(V_src, F_src, V_out):
    Vs = as_vertices(V_src, "V_src")
    Vo = as_vertices(V_out, "V_out")
    if Vo.shape != Vs.shape:
        raise InputError(f"V_out has shape {Vo.shape} but V_src {Vs.shape}")
    return Vs, Vo, as_faces(F_src, len(Vs), "F_src")


def _affine_residual(P, Q) -> float:
    """RMS residual of the least-squares affine map P -> Q over Q's bounding-box diagonal."""
    X = np.column_stack([P, np.ones(len(P))])
    A = np.linalg.lstsq(X, Q, rcond=None)[0]
    size = float(np.linalg.norm(np.ptp(Q, axis=0)))
    rms = float(np.sqrt(np.mean(np.sum((X @ A - Q) ** 2, axis=1))))
    return rms / size if size > 0 else 0.0


def _adjacent_faces(F) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of faces sharing an edge (each pair once; an edge with k faces gives the
    pairs of consecutive ones)."""
    m = len(F)
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    owner = np.tile(np.arange(m), 3)
    order = np.lexsort((E[:, 1], E[:, 0]))
    E, owner = E[order], owner[order]
    same = np.all(E[1:] == E[:-1], axis=1)
    return owner[:-1][same], owner[1:][same]


def _normal_angles(V, F, a, b) -> np.ndarray:
    """Angles in degrees between the normals of faces ``a`` and ``b`` (0 for a face with
    no area)."""
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
    sin = np.linalg.norm(np.cross(n[a], n[b]), axis=1)  # atan2: exact near 0 and 180
    return np.degrees(np.arctan2(sin, np.einsum("ij,ij->i", n[a], n[b])))
