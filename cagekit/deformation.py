"""Per-pair cage deformation: move a source's cage so the source takes a target's shape.

Minimises the paper's per-pair energy (section 3.3 of "Neural Cages") over the cage
vertices, with no training: the source is bound once (:func:`cagekit.bind`), a deformed
point is ``W @ C``, and each term's gradient is the exact ``W.T @ dE/dX``
(:mod:`cagekit.losses`). The energy is an alignment term (Chamfer, or landmarks, which
replace it by default), the shape terms ``L_p2f`` and ``L_normal`` (0.1 each, the paper's
``alpha_shape``), an optional symmetry term and the change of the cage's cotangent
Laplacian (0.3, or 1 with ``reference="source"``; ours: the paper gives no weight), and on
a source of two or more parts (connected components) a part-affinity term (300, ours): each
part's distance from an affine map of itself, so that legs stay straight and seats flat
while the parts move, stretch and shear to the target; and on a mesh the detail term (1,
ours): the change of the source's own cotangent Laplacian coordinates from the box-aligned
source (the dCotLap metric as a quadratic form of the cage), which keeps the fine relief
and the sharp creases of real meshes. The
source's bounding box is first mapped onto the target's; nlopt's L-BFGS then minimises the
full energy with its analytic gradient (not an alternating linearised scheme: the PCA-normal
terms are not quadratic in the cage), 60 evaluations by default, restarted once from the
best point if it stops at a Chamfer switch. ``reference="aligned"`` (default) compares the
shape and cage terms with the box-aligned source, so the box stretch is free and straight
parts stay straight; ``reference="source"`` (the paper's) charges every stretch. Cage
symmetry asks for a symmetric motion, not a symmetric cage
(:func:`cagekit.losses.cage_symmetry_loss`). Samples are drawn once from ``seed``; point
clouds use 16-nearest-neighbour neighbourhoods. A scan seen from one side takes
``target_kind="partial"`` (with full Chamfer the source is squashed towards the seen part).
See docs/architecture.md.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from cagekit import losses
from cagekit.alignment import box_scale, partial_box_scale
from cagekit.cage import check_cage
from cagekit.coords import bind
from cagekit.coords.binding import warn_outside
from cagekit.errors import InputError
from cagekit.frame import Frame
from cagekit.geometry import (
    as_shape,
    as_vertices,
    cotangent_laplacian,
    vertex_neighborhoods,
)
from cagekit.optimize import minimise
from cagekit.sampling import subset, surface_samples

__all__ = ["CageEnergy", "CageProblem", "CageSolution", "DeformResult", "DEFAULT_WEIGHTS",
           "METHODS", "deform", "solve"]

METHODS = ("cage", "scale", "nricp")
#: the coordinates the energy takes (Green's through their faces' terms, exactly)
COORDS = ("mvc", "green")
TARGET_KINDS = ("full", "partial")
#: weight of the part-affinity term (:func:`cagekit.losses.part_affinity_loss`) on sources
#: of two or more parts (connected components of 30 vertices or more); chosen on real
#: furniture pairs (docs/benchmarks.md, "Per-pair deformation")
PARTS_WEIGHT = 300.0
#: weight of the detail term (:func:`cagekit.losses.detail_loss`, the change of the
#: source's own cotangent Laplacian coordinates); chosen on real furniture pairs
DETAIL_WEIGHT = 1.0
REFERENCES = ("source", "aligned")
DEFAULT_WEIGHTS = {
    "chamfer": 1.0,
    "landmarks": 1.0,
    "p2f": losses.ALPHA_SHAPE,
    "normal": losses.ALPHA_SHAPE,
    "symmetry": 1.0,
    "cage": 0.3,
    "parts": PARTS_WEIGHT,
    "detail": DETAIL_WEIGHT,
}
#: samples of each surface (Chamfer) and vertices of the shape terms. On 39 real furniture
#: pairs 250 shape vertices gave the figures of 500 in 0.8 of the time; 1,000 samples
#: did too on those pairs, but doubled the error on a scaled copy of the source (1.4% of
#: its size against 0.7%: Chamfer's sampling noise), so 2,000 are kept
#: (docs/benchmarks.md, "Per-pair deformation")
SAMPLES = 2000
SHAPE_POINTS = 250
#: the cage weight's default with ``reference="source"``
SOURCE_REFERENCE_CAGE_WEIGHT = 1.0
#: landmarks may lie this far outside their shape's box (unit frame: the box fills
#: [-1, 1] on its longest axis, so 0.35 is 10% of the largest diagonal, 2 sqrt 3)
LANDMARK_MARGIN = 0.35


@dataclass
class DeformResult:
    """What :func:`deform` returns.

    Attributes
    ----------
    vertices : (n, 3) float64
        The deformed source, in the target's frame and units, in the source's vertex order.
    faces : (m, 3) int64
        The source's faces (empty for a point-cloud source).
    method : str
        ``"cage"``, ``"scale"`` or ``"nricp"`` (``"learned"`` or ``"learned+refine"`` from
        :func:`cagekit_learn.inference.deform_with_model`).
    cage_v, cage_f : (k, 3) float64 and (c, 3) int64, or None
        The source cage in the source's frame (``cage`` only).
    deformed_cage_v : (k, 3) float64 or None
        The deformed cage in the target's frame (``cage`` only).
    losses : dict of str to float
        Each term's unweighted value at the end, in the paper's frame (``cage`` only;
        terms with zero weight are left out).
    weights : dict of str to float
        The weights used.
    energy : float or None
        The weighted sum at the end.
    initial_energy : float or None
        The weighted sum after the coarse stage (bounding boxes aligned), where the
        optimiser starts.
    iterations : int
        Energy evaluations of the optimiser (0 for ``scale``).
    seconds : float
        Wall time of the whole call, cage fitting included.
    source_frame, target_frame : cagekit.frame.Frame
        The unit frames of the source and the target (the paper's frame, in which the
        losses are measured; :func:`cagekit.metrics.evaluate` takes them).
    """

    vertices: np.ndarray
    faces: np.ndarray
    method: str
    cage_v: np.ndarray | None = None
    cage_f: np.ndarray | None = None
    deformed_cage_v: np.ndarray | None = None
    losses: dict = field(default_factory=dict)
    weights: dict = field(default_factory=dict)
    energy: float | None = None
    initial_energy: float | None = None
    iterations: int = 0
    seconds: float = 0.0
    source_frame: Frame | None = None
    target_frame: Frame | None = None

    def set_solution(self, problem: CageProblem, solution: CageSolution) -> None:
        """Take a :func:`solve` result, mapped from the unit frames to the shapes' own."""
        ft = self.target_frame
        self.vertices = ft.to_world(solution.vertices)
        self.cage_v = self.source_frame.to_world(problem.cage_v)
        self.cage_f = problem.cage_f
        self.deformed_cage_v = ft.to_world(solution.deformed_cage)
        self.losses, self.weights = solution.losses, problem.weights
        self.initial_energy, self.energy = solution.initial_energy, solution.energy
        self.iterations = solution.evaluations


# ------------------------------------------------------------------------------ energy


class CageEnergy:
    """The per-pair energy as a function of the cage vertices, with its gradient.

    Parameters
    ----------
    W_samples : (s, k) float64 or None
        Coordinates of the source samples (Chamfer and symmetry terms).
    target : (t, 3) float64 or None
        Target samples (Chamfer).
    W_shape : (p, k) float64
        Coordinates of the points the shape terms use.
    shape_ref : cagekit.losses.ShapeReference
        Rest planes of those points (indices into ``W_shape``'s rows).
    cage_f : (c, 3) int64
    cage_ref : (k, 3) float64
        Reference cage of the regulariser (its cotangent Laplacian is built once).
    weights : dict
        Term weights; a zero weight skips the term.
    symmetry : {"x", "y", "z"} or None
    W_landmarks, landmarks : (l, k) and (l, 3) float64, optional
    parts_matrix : (k, k) float64, optional
        The part-affinity term as a quadratic form of the cage
        (:func:`cagekit.losses.part_affinity_matrix`).
    detail_matrix : (k, k) float64, optional
        The detail term as a quadratic form of the cage's motion from ``cage_ref``
        (:func:`cagekit.losses.detail_matrix`).
    partial : bool
        The target is a scan seen from one side: the alignment term is
        :func:`cagekit.losses.partial_chamfer_loss`, not Chamfer.
    face_terms : cagekit.coords.green.FaceTerms, optional
        Green coordinates: the ``W`` matrices then have ``k + m`` columns and act on
        ``Z = [C; face_terms(C)]`` (points, parts and detail); the cage and the cage's
        symmetry terms act on ``C``; the gradient goes back through the faces' normals
        and stretch factors exactly (:meth:`~cagekit.coords.green.FaceTerms.vjp`).
    """

    def __init__(self, W_samples, target, W_shape, shape_ref, cage_f, cage_ref, weights,
                 symmetry=None, W_landmarks=None, landmarks=None, parts_matrix=None,
                 partial=False, detail_matrix=None, face_terms=None):
        self.W_samples, self.target = W_samples, target
        self.tree = cKDTree(target) if target is not None else None
        self.W_shape, self.shape_ref = W_shape, shape_ref
        self.cage_ref = cage_ref
        self.L = cotangent_laplacian(cage_ref, cage_f)
        self.weights = weights
        self.symmetry = symmetry
        if symmetry is not None:
            self.partners = losses.mirror_partners(cage_ref, symmetry)
        self.W_landmarks, self.landmarks = W_landmarks, landmarks
        self.parts_matrix = parts_matrix
        self.detail_matrix = detail_matrix
        self.partial = partial
        self.face_terms = face_terms
        self.Z_ref = self.lift(cage_ref)

    def lift(self, C):
        """What the ``W`` matrices act on: ``C``, or ``[C; face_terms(C)]`` (Green)."""
        return _lifted(C, self.face_terms)

    def evaluate(self, C):
        """Weighted energy, its gradient (k, 3) and each active term's unweighted value."""
        w = self.weights
        Z = self.lift(C)
        values, energy, grad = {}, 0.0, np.zeros_like(Z)

        def add(name, value, g):
            nonlocal energy, grad
            values[name] = value
            energy += w[name] * value
            grad += w[name] * g

        def add_cage(name, value, g):  # a term of C alone: its rows of Z's gradient
            add(name, value, np.vstack([g, np.zeros((len(Z) - len(C), 3))]))

        Y = None
        if w["chamfer"] and self.target is not None:
            Y = self.W_samples @ Z
            value, g = (losses.partial_chamfer_loss(Y, self.target, self.tree) if self.partial
                        else losses.chamfer_loss(Y, self.target, self.tree))
            add("chamfer", value, self.W_samples.T @ g)
        if w["landmarks"] and self.landmarks is not None:
            value, g = losses.landmark_loss(self.W_landmarks @ Z, self.landmarks)
            add("landmarks", value, self.W_landmarks.T @ g)
        if w["p2f"] or w["normal"]:
            shape, g = losses.shape_losses(self.W_shape @ Z, self.shape_ref, w["p2f"],
                                           w["normal"])
            values.update(shape)
            energy += sum(w[name] * value for name, value in shape.items())
            grad += self.W_shape.T @ g
        if w["symmetry"] and self.symmetry is not None:
            Y = self.W_samples @ Z if Y is None else Y
            v_shape, g_shape = losses.symmetry_loss(Y, self.symmetry)
            v_cage, g_cage = losses.cage_symmetry_loss(C, *self.partners, self.symmetry)
            g = self.W_samples.T @ g_shape
            g[:len(C)] += g_cage
            add("symmetry", v_shape + v_cage, g)
        if w["cage"]:
            add_cage("cage", *losses.laplacian_loss(C, self.L, self.cage_ref))
        if w["parts"] and self.parts_matrix is not None:
            QZ = self.parts_matrix @ Z
            add("parts", float(np.einsum("ij,ij->", Z, QZ)), 2.0 * QZ)
        if w["detail"] and self.detail_matrix is not None:
            add("detail", *losses.detail_loss(Z, self.detail_matrix, self.Z_ref))
        if self.face_terms is not None:
            grad = grad[:len(C)] + self.face_terms.vjp(C, grad[len(C):])
        return energy, grad, values

    def __call__(self, C):
        """Weighted energy and its gradient, shape (k, 3)."""
        energy, grad, _ = self.evaluate(C)
        return energy, grad


def _lifted(C, face_terms):
    """``C``, or with Green coordinates ``[C; face_terms(C)]`` (k + m, 3)."""
    return C if face_terms is None else np.vstack([C, face_terms(C)])


# -------------------------------------------------------------------------- the methods


def _weights(user, landmarks, symmetry, reference):
    weights = dict(DEFAULT_WEIGHTS)
    if reference == "source":
        weights["cage"] = SOURCE_REFERENCE_CAGE_WEIGHT
    if landmarks is not None:
        weights["chamfer"] = 0.0
    if symmetry is None:
        weights["symmetry"] = 0.0
    if landmarks is None:
        weights["landmarks"] = 0.0
    for name, value in (user or {}).items():
        if name not in DEFAULT_WEIGHTS:
            raise InputError(f"unknown energy term {name!r}; terms: "
                             f"{', '.join(DEFAULT_WEIGHTS)}")
        if name == "landmarks" and landmarks is None:
            raise InputError("a landmarks weight was given but no landmarks")
        if name == "symmetry" and symmetry is None:
            raise InputError("a symmetry weight was given but no symmetry axis")
        value = float(value)
        if not (np.isfinite(value) and value >= 0.0):
            raise InputError(f"weight of {name} must be finite and >= 0, got {value}")
        weights[name] = value
    return weights


def _check_choices(symmetry, reference):
    if reference not in REFERENCES:
        raise InputError(f"reference must be one of {', '.join(REFERENCES)}, got "
                         f"{reference!r}")
    if symmetry is not None and symmetry not in losses.AXES:
        raise InputError(f"symmetry must be x, y, z or None, got {symmetry!r}")


def _check_counts(counts):
    for name, value in counts.items():
        if int(value) < 1:
            raise InputError(f"{name} must be at least 1, got {value}")


def _landmarks_in_frames(landmarks, source_frame, target_frame):
    """Landmark pairs mapped to the unit frames, refused when far outside their shape."""
    if landmarks is None:
        return None, None
    try:
        src, tgt = landmarks
    except (TypeError, ValueError):
        raise InputError("landmarks must be a (source points, target points) pair") from None
    src = as_vertices(src, "source landmarks")
    tgt = as_vertices(tgt, "target landmarks")
    if len(src) != len(tgt):
        raise InputError(f"{len(src)} source landmarks but {len(tgt)} target landmarks")
    src_n, tgt_n = source_frame.to_unit(src), target_frame.to_unit(tgt)
    for name, points in (("source", src_n), ("target", tgt_n)):
        if np.abs(points).max() > 1.0 + LANDMARK_MARGIN:
            raise InputError(f"the {name} landmarks lie far outside the {name} shape's "
                             "bounding box (more than 10% of its diagonal): wrong file or "
                             "units?")
    return src_n, tgt_n


def _shape_rows(Vs_n, Fs, shape_points, rng):
    """Rows (own vertex, neighbourhood) of the shape terms, compacted to the points used."""
    nb = vertex_neighborhoods(Vs_n, Fs, k=16)
    rows = subset(len(Vs_n), shape_points, rng)
    columns = nb.mask[rows].any(axis=0)  # a prefix: drop the padding no chosen row needs
    index, mask = nb.index[rows][:, columns], nb.mask[rows][:, columns]
    used, inverse = np.unique(np.concatenate([rows, index.ravel()]), return_inverse=True)
    own = inverse[: len(rows)]
    return used, own, inverse[len(rows):].reshape(index.shape), mask


def _box_factors(Vs_n, Vt_n, target_kind) -> np.ndarray:
    """The coarse stage's per-axis factors: :func:`~cagekit.alignment.box_scale`, or
    :func:`~cagekit.alignment.partial_box_scale` onto a partial target."""
    return (partial_box_scale if target_kind == "partial" else box_scale)(Vs_n, Vt_n)


def _part_term(Vs_n, Fs, W_vertices):
    """The part-affinity quadratic form of the source's parts (face components of at least
    ``MIN_PART_VERTICES`` vertices), or None when it has fewer than two."""
    from cagekit.cage import vertex_components
    from cagekit.metrics import MIN_PART_VERTICES

    if not len(Fs):
        return None
    parts = losses.part_bases(Vs_n, vertex_components(len(Vs_n), Fs), MIN_PART_VERTICES)
    if len(parts.bases) < 2:
        return None
    return losses.part_affinity_matrix(W_vertices, parts)


def _detail_term(Vs_n, Fs, W_vertices):
    """The detail term's quadratic form, or None for a point cloud or a mesh whose
    cotangent Laplacian is undefined (no faces of positive area, non-finite weights)."""
    from cagekit.geometry import surface_laplacian

    if not len(Fs):
        return None
    try:
        L = surface_laplacian(Vs_n, Fs)
    except InputError:
        return None
    return losses.detail_matrix(W_vertices, L)


def _samples_of(role, V, F, n, seed):
    """``surface_samples``, its errors naming the role (the command line blames the file)."""
    try:
        return surface_samples(V, F, n, seed=seed)
    except InputError as exc:
        raise InputError(f"the {role}: {exc.problem}") from None


@dataclass
class CageProblem:
    """One source-target pair, bound to the source's cage, in the unit frames.

    Build it with :meth:`create`; :func:`solve` minimises its energy. Everything is in
    the paper's frame: the source, its cage and the source landmarks normalised by the
    source's :class:`~cagekit.frame.Frame`, the target and its landmarks by the target's.

    Attributes
    ----------
    W_vertices : (n, k) or (n, k + m) float64
        Coordinates of the source's vertices (the result is :meth:`vertices_of` ``(C)``:
        ``W_vertices @ C``, or with Green coordinates ``W_vertices @ [C; s n'(C)]``).
    cage_v, cage_f : (k, 3) float64 and (c, 3) int64
        The source cage (faces as :func:`cagekit.bind` oriented them).
    box_cage : (k, 3) float64
        The cage after the coarse stage (the bounding boxes mapped onto each other).
    energy : CageEnergy
    weights : dict of str to float
    """

    W_vertices: np.ndarray
    cage_v: np.ndarray
    cage_f: np.ndarray
    box_cage: np.ndarray
    energy: CageEnergy
    weights: dict

    def vertices_of(self, C) -> np.ndarray:
        """The deformed source for a deformed cage ``C`` (k, 3), target's unit frame."""
        return self.W_vertices @ self.energy.lift(C)

    @classmethod
    def create(cls, source, target, cage, *, symmetry=None, landmarks=None, weights=None,
               samples=SAMPLES, shape_points=SHAPE_POINTS, reference="aligned", coords="mvc",
               seed=0, target_kind="full") -> CageProblem:
        """Sample, bind and set up the energy of one pair (all arrays in unit frames).

        Parameters
        ----------
        source, target : (V, F) pairs of (n, 3) float64 and (m, 3) int64
            Normalised on their own (``F`` empty for a point cloud).
        cage : (cage_v, cage_f) pair
            The source cage in the source's unit frame, checked already.
        symmetry, weights, samples, shape_points, reference, coords, seed, target_kind
            As :func:`deform` takes them.
        landmarks : (source points (l, 3), target points (l, 3)), optional
            In the unit frames.
        """
        _check_choices(symmetry, reference)
        weights = _weights(weights, landmarks, symmetry, reference)
        _check_counts({"samples": samples, "shape_points": shape_points})
        (Vs_n, Fs), (Vt_n, Ft) = source, target
        src_lm, tgt_lm = (None, None) if landmarks is None else landmarks
        rng = np.random.default_rng(seed)
        S = _samples_of("source", Vs_n, Fs, samples, int(rng.integers(2**31)))
        T = _samples_of("target", Vt_n, Ft, samples, int(rng.integers(2**31)))
        used, own, index, mask = _shape_rows(Vs_n, Fs, shape_points, rng)
        parts = [Vs_n, S] + ([src_lm] if src_lm is not None else [])
        binding = bind(np.concatenate(parts), *cage, method=coords, check=False)
        face_terms = None
        if coords == "green":
            from cagekit.coords.green import FaceTerms

            W = np.hstack([binding.phi, binding.psi])
            face_terms = FaceTerms(binding.cage_v, binding.cage_f)
        else:
            W = binding.weights
        n, s = len(Vs_n), len(S)
        W_samples = W[n:n + s]
        W_landmarks = W[n + s:] if src_lm is not None else None
        W_shape = np.ascontiguousarray(W[:n][used])
        box_cage = binding.cage_v * _box_factors(Vs_n, Vt_n, target_kind)
        reference_cage = box_cage if reference == "aligned" else binding.cage_v
        shape_ref = losses.shape_reference(W_shape @ _lifted(reference_cage, face_terms),
                                           own, index, mask)
        parts_matrix = _part_term(Vs_n, Fs, W[:n]) if weights["parts"] else None
        detail = _detail_term(Vs_n, Fs, W[:n]) if weights["detail"] else None
        energy = CageEnergy(W_samples, T, W_shape, shape_ref, binding.cage_f,
                            reference_cage, weights, symmetry, W_landmarks, tgt_lm,
                            parts_matrix, target_kind == "partial", detail, face_terms)
        return cls(W[:n], binding.cage_v, binding.cage_f, box_cage, energy, weights)


@dataclass
class CageSolution:
    """What :func:`solve` returns (unit frames: the deformed cage in the target's).

    Attributes
    ----------
    vertices : (n, 3) float64
        The deformed source.
    deformed_cage : (k, 3) float64
    losses : dict of str to float
        Each active term's unweighted value at the end.
    initial_energy, energy : float
        The weighted sum at the start and at the end.
    evaluations : int
    """

    vertices: np.ndarray
    deformed_cage: np.ndarray
    losses: dict
    initial_energy: float
    energy: float
    evaluations: int


class _Remembered:
    """A :class:`CageEnergy` that remembers its evaluation at the start and at the lowest
    energy so far: :func:`solve` evaluates the start before the optimiser, whose first call
    is the same point, and the optimiser's best point after it; both are looked up, not
    computed again (the energy is deterministic, so the figures are the same)."""

    def __init__(self, energy):
        self.energy = energy
        self.kept = {}  # key -> (energy, gradient, values)
        self.start = self.best = None

    def evaluate(self, C):
        C = np.asarray(C, dtype=np.float64)
        key = (C.shape, C.tobytes())
        if key in self.kept:
            value, grad, values = self.kept[key]
            return value, grad.copy(), dict(values)
        value, grad, values = self.energy.evaluate(C)
        if self.start is None:
            self.start = key
        if self.best is None or value < self.kept[self.best][0]:
            if self.best is not None and self.best != self.start:
                del self.kept[self.best]
            self.best = key
        if key in (self.start, self.best):
            self.kept[key] = (value, grad.copy(), dict(values))
        return value, grad, values

    def __call__(self, C):
        value, grad, _ = self.evaluate(C)
        return value, grad


def solve(problem: CageProblem, start=None, *, max_evaluations: int = 60,
          tolerance: float = 1e-7, progress=None) -> CageSolution:
    """Minimise a :class:`CageProblem`'s energy over the cage by L-BFGS.

    Parameters
    ----------
    problem : CageProblem
    start : (k, 3) float64, optional
        The deformed cage to start from, in the target's unit frame; default the
        box-aligned cage (``problem.box_cage``).
    max_evaluations, tolerance, progress
        As :func:`deform` takes them.

    Returns
    -------
    CageSolution
    """
    if int(max_evaluations) < 1:
        raise InputError(f"max_evaluations must be at least 1, got {max_evaluations}")
    C0 = problem.box_cage if start is None else start
    if C0.shape != problem.cage_v.shape:
        raise InputError(f"initial cage has {len(C0)} vertices, the cage "
                         f"{len(problem.cage_v)}")
    energy = _Remembered(problem.energy)
    initial, _, _ = energy.evaluate(C0)
    minimum = minimise(energy, C0, max_evaluations, tolerance, progress)
    total, _, terms = energy.evaluate(minimum.x)
    return CageSolution(problem.vertices_of(minimum.x), minimum.x, terms, initial, total,
                        minimum.evaluations)


def _nricp(Vs_box, Fs, Vt_n, Ft):
    import trimesh
    from trimesh.registration import nricp_amberg

    if not len(Fs):
        raise InputError("method nricp needs a source mesh with faces, got a point cloud")
    loose = len(Vs_box) - len(np.unique(Fs))
    if loose:
        raise InputError(f"method nricp needs every source vertex on a face; {loose} are on "
                         "none (method cage takes them)")
    source = trimesh.Trimesh(Vs_box, Fs, process=False, validate=False)
    try:
        if len(Ft):
            target = trimesh.Trimesh(Vt_n, Ft, process=False, validate=False)
            return np.asarray(nricp_amberg(source, target), dtype=np.float64)
        return np.asarray(nricp_amberg(source, Vt_n, use_faces=False,
                                       use_vertex_normals=False), dtype=np.float64)
    except RuntimeError as exc:  # scipy's solver: vertices on no face, or disconnected
        raise InputError(f"trimesh's nricp_amberg cannot solve this pair ({exc}); vertices "
                         "on no face or parts it cannot anchor make its system singular"
                         ) from None


def deform(source, target, cage=None, *, method: str = "cage", symmetry: str | None = None,
           landmarks=None, weights: dict | None = None, faces: int = 200,
           samples: int = SAMPLES, shape_points: int = SHAPE_POINTS, max_evaluations: int = 60,
           tolerance: float = 1e-7, reference: str = "aligned", coords: str = "mvc",
           seed: int = 0, progress=None, initial_cage=None, check: bool = True,
           target_kind: str = "full") -> DeformResult:
    """Deform a source so it takes the shape of a target, keeping its detail.

    Parameters
    ----------
    source : (V, F) pair, trimesh object, or (n, 3) array
        The shape to deform, ``V`` (n, 3) float, ``F`` (m, 3) int; no faces (or a bare
        array) for a point cloud, whose points are deformed.
    target : (V, F) pair, trimesh object, or (t, 3) array
        The shape to match: a mesh, or a point cloud (noisy or coarse; partial ones
        squash the source, see the module docstring).
    cage : (cage_v, cage_f) pair, optional
        The source's cage in the source's frame: closed, 2-manifold, free of
        self-intersection (refused otherwise, see ``check``); a cage that leaves part of the
        source outside is used with an :class:`~cagekit.errors.OutsideCageWarning` (those
        points are extrapolated). When None,
        :func:`cagekit.fit_cage` builds one with ``faces`` faces, checked against 5,000
        surface samples instead of fit-cage's 20,000 (faster; the coordinates are
        defined outside the cage too, so a sample a hair outside does no harm).
    method : {"cage", "scale", "nricp"}, default "cage"
        ``cage``: the energy above, minimised over the cage. ``scale``: the source's
        bounding box mapped onto the target's (the paper's simplest baseline). ``nricp``:
        ``trimesh.registration.nricp_amberg`` with its defaults, started from the
        box-aligned source in the paper's frame (the same start as ``cage``).
    symmetry : {"x", "y", "z"} or None
        Axis normal to the source's plane of symmetry; adds the symmetry term.
    landmarks : (source points (l, 3), target points (l, 3)), optional
        Corresponding points, each in its own shape's frame; the alignment term becomes
        their mean squared distance.
    weights : dict, optional
        Overrides of :data:`DEFAULT_WEIGHTS` (``chamfer``, ``landmarks``, ``p2f``,
        ``normal``, ``symmetry``, ``cage``, ``parts``, ``detail``); ``result.weights``
        holds those used.
    faces : int, default 200
        Face budget of the fitted cage when ``cage`` is None.
    samples : int, default 2000
        Samples of each surface for the Chamfer and symmetry terms.
    shape_points : int, default 250
        Vertices whose one-ring planes the shape terms use.
    max_evaluations : int, default 60
        Energy evaluations of L-BFGS.
    tolerance : float, default 1e-7
        Relative change of the energy that stops L-BFGS.
    reference : {"aligned", "source"}, default "aligned"
        What the shape terms and the cage regulariser compare with: the box-aligned
        source and cage after the coarse stage (the stretch is free: a source deformed
        onto a stretched copy of itself comes back up to sampling noise and parts keep
        their straight lines), or the source and its cage as given (the paper's choice: any stretch
        costs, so dCotLap, which charges for stretch, is lower, but parts bend where the
        target's proportions differ; the cage weight then defaults to 1, not 0.3).
        docs/benchmarks.md ("Per-pair deformation") has both on 20 pairs.
    coords : {"mvc", "green"}, default "mvc"
        The coordinates that bind the source to its cage (:func:`cagekit.bind`); with
        ``"green"`` the energy's gradient goes through the faces' normals and stretch
        factors exactly.
    seed : int, default 0
    progress : callable, optional
        Called as ``progress(evaluations, max_evaluations)`` after each energy
        evaluation of ``cage`` (the command line moves a progress bar with it).
    initial_cage : (k, 3) array_like of float, optional
        Where the optimisation starts: a deformed position of ``cage``'s vertices in the
        target's frame and units (for example a learned prediction; ``cagekit deform
        --model --refine`` refines one in the unit frames with :class:`CageProblem` and
        :func:`solve`). Default: the box-aligned cage. Needs ``cage``; the references of
        the shape and cage terms are unchanged.
    check : bool, default True
        Refuse a given ``cage`` that intersects itself (as :func:`cagekit.bind`); False
        skips that test (a network's predicted cage, which may fold).
    target_kind : {"full", "partial"}, default "full"
        ``"partial"``: the target is a scan seen from one side; method ``cage`` aligns
        with :func:`cagekit.losses.partial_chamfer_loss` (every scanned point onto the
        source, the source onto the scan at a tenth of the weight), so the source's
        unseen side is not squashed onto the seen one; every method's box alignment
        keeps each axis's stretch at least the median of the three
        (:func:`cagekit.alignment.partial_box_scale`: the scan is shallow along the view).

    Returns
    -------
    DeformResult

    Raises
    ------
    InputError
        Bad shapes, an unknown method, term or axis, landmark counts that differ, a
        point-cloud source with ``nricp``.

    Examples
    --------
    >>> from cagekit.shapes import box_cage
    >>> V, F = box_cage(4, half_extent=(1.0, 0.5, 0.5))
    >>> result = deform((V, F), (V * [2.0, 1.0, 1.0], F), method="scale")
    >>> np.allclose(result.vertices, V * [2.0, 1.0, 1.0])
    True
    """
    start = time.perf_counter()
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; available: {', '.join(METHODS)}")
    _check_choices(symmetry, reference)
    if initial_cage is not None and method != "cage":
        raise InputError("initial_cage applies to method cage only")
    if initial_cage is not None and cage is None:
        raise InputError("initial_cage needs the cage it deforms (cage=...)")
    if coords not in COORDS:
        raise InputError(f"deform takes coords {', '.join(COORDS)}, got {coords!r}")
    _weights(weights, landmarks, symmetry, reference)  # refuse bad weights before any work
    _check_counts({"samples": samples, "shape_points": shape_points,
                   "max_evaluations": max_evaluations})
    Vs, Fs = as_shape(source, name="source")
    Vt, Ft = as_shape(target, name="target")
    fs, ft = Frame.of(Vs, name="the source"), Frame.of(Vt, name="the target")
    Vs_n, Vt_n = fs.to_unit(Vs), ft.to_unit(Vt)
    result = DeformResult(vertices=Vs, faces=Fs, method=method, source_frame=fs,
                          target_frame=ft)
    if target_kind not in TARGET_KINDS:
        raise InputError(f"target_kind must be full or partial, got {target_kind!r}")
    if method == "scale":
        result.vertices = ft.to_world(Vs_n * _box_factors(Vs_n, Vt_n, target_kind))
    elif method == "nricp":
        result.vertices = ft.to_world(_nricp(Vs_n * _box_factors(Vs_n, Vt_n, target_kind),
                                             Fs, Vt_n, Ft))
    else:
        lm = _landmarks_in_frames(landmarks, fs, ft)
        if cage is None:
            from cagekit.fitting import fit_cage

            cage_n, cage_f = fit_cage(Vs_n, Fs, faces=faces, seed=seed, samples=5000)
        else:
            try:
                cage_v, cage_f = cage
            except (TypeError, ValueError):
                raise InputError("cage must be a (vertices, faces) pair") from None
            cage_n = fs.to_unit(as_vertices(cage_v, "cage vertices"))
            cage_f = check_cage(cage_n, cage_f, intersections=check)
            warn_outside(Vs_n, cage_n, cage_f, shape="the source", cage="the given cage")
        C_start = None
        if initial_cage is not None:
            C_start = ft.to_unit(as_vertices(initial_cage, "initial cage vertices"))
            if C_start.shape != cage_n.shape:  # before any sampling or binding
                raise InputError(f"initial cage has {len(C_start)} vertices, the cage "
                                 f"{len(cage_n)}")
        problem = CageProblem.create(
            (Vs_n, Fs), (Vt_n, Ft), (cage_n, cage_f), symmetry=symmetry,
            landmarks=None if lm[0] is None else lm, weights=weights, samples=samples,
            shape_points=shape_points, reference=reference, coords=coords, seed=seed,
            target_kind=target_kind)
        solution = solve(problem, C_start, max_evaluations=max_evaluations,
                         tolerance=tolerance, progress=progress)
        result.set_solution(problem, solution)
    if not np.isfinite(result.vertices).all():
        raise FloatingPointError(f"method {method} produced NaN or inf positions")
    result.seconds = time.perf_counter() - start
    return result
