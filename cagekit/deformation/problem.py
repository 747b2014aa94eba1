"""One pair's energy over the source's cage (``CageProblem``) and its minimisation (``solve``).

Minimises the paper's per-pair energy (section 3.3 of "Neural Cages") over the cage
vertices, with no training: the source is bound once (:func:`cagekit.bind`), a deformed
point is ``W @ C``, and each term's gradient is the exact ``W.T @ dE/dX``
(:mod:`cagekit.deformation.terms`). The energy is an alignment term (Chamfer, or landmarks, which
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
(:func:`cagekit.deformation.terms.cage_symmetry_loss`). Samples are drawn once from ``seed``; point
clouds use 16-nearest-neighbour neighbourhoods. A scan seen from one side takes
``target_kind="partial"`` (with full Chamfer the source is squashed towards the seen part).
See docs/architecture.md.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import cast

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from cagekit.coords import GreenBinding, bind
from cagekit.coords.green import FaceTerms
from cagekit.deformation import terms as losses
from cagekit.deformation.options import DeformOptions
from cagekit.deformation.solver import minimise
from cagekit.errors import InputError
from cagekit.geometry import cotangent_laplacian, surface_laplacian, vertex_neighborhoods
from cagekit.geometry.alignment import box_scale, partial_box_scale
from cagekit.geometry.parts import vertex_parts
from cagekit.geometry.sampling import sample_surface, subset
from cagekit.metrics import MIN_PART_VERTICES
from cagekit.typed import Faces, Floats, Vertices

__all__ = ["CageEnergy", "CageProblem", "CageSolution", "DEFAULT_WEIGHTS", "box_factors",
           "solve", "term_weights"]

#: weight of the part-affinity term (:func:`cagekit.deformation.terms.part_affinity_loss`)
#: on sources of two or more parts (connected components of 30 vertices or more); chosen on real
#: furniture pairs (docs/benchmarks.md, "Per-pair deformation")
PARTS_WEIGHT = 300.0
#: weight of the detail term (:func:`cagekit.deformation.terms.detail_loss`, the change of the
#: source's own cotangent Laplacian coordinates); chosen on real furniture pairs
DETAIL_WEIGHT = 1.0
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
#: the cage weight's default with ``reference="source"``
SOURCE_REFERENCE_CAGE_WEIGHT = 1.0
#: landmarks may lie this far outside their shape's box (unit frame: the box fills
#: [-1, 1] on its longest axis, so 0.35 is 10% of the largest diagonal, 2 sqrt 3)
LANDMARK_MARGIN = 0.35


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
    shape_ref : cagekit.deformation.terms.ShapeReference
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
        (:func:`cagekit.deformation.terms.part_affinity_matrix`).
    detail_matrix : (k, k) float64, optional
        The detail term as a quadratic form of the cage's motion from ``cage_ref``
        (:func:`cagekit.deformation.terms.detail_matrix`).
    partial : bool
        The target is a scan seen from one side: the alignment term is
        :func:`cagekit.deformation.terms.partial_chamfer_loss`, not Chamfer.
    face_terms : cagekit.coords.green.FaceTerms, optional
        Green coordinates: the ``W`` matrices then have ``k + m`` columns and act on
        ``Z = [C; face_terms(C)]`` (points, parts and detail); the cage and the cage's
        symmetry terms act on ``C``; the gradient goes back through the faces' normals
        and stretch factors exactly (:meth:`~cagekit.coords.green.FaceTerms.vjp`).
    """

    def __init__(self, W_samples: Floats | None, target: Vertices | None, W_shape: Floats,
                 shape_ref: losses.ShapeReference, cage_f: Faces, cage_ref: Vertices,
                 weights: dict[str, float], symmetry: str | None = None,
                 W_landmarks: Floats | None = None, landmarks: Vertices | None = None,
                 parts_matrix: Floats | None = None, partial: bool = False,
                 detail_matrix: Floats | None = None,
                 face_terms: FaceTerms | None = None) -> None:
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

    def lift(self, C: Vertices) -> Vertices:
        """What the ``W`` matrices act on: ``C``, or ``[C; face_terms(C)]`` (Green)."""
        return _lifted(C, self.face_terms)

    def evaluate(self, C: Vertices) -> tuple[float, Vertices, dict[str, float]]:
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

        # given whenever their terms are on (a target or a symmetry axis; landmarks)
        W_samples, W_landmarks = cast(Floats, self.W_samples), cast(Floats, self.W_landmarks)
        Y = None
        if w["chamfer"] and self.target is not None:
            Y = W_samples @ Z
            value, g = (losses.partial_chamfer_loss(Y, self.target, self.tree) if self.partial
                        else losses.chamfer_loss(Y, self.target, self.tree))
            add("chamfer", value, W_samples.T @ g)
        if w["landmarks"] and self.landmarks is not None:
            value, g = losses.landmark_loss(W_landmarks @ Z, self.landmarks)
            add("landmarks", value, W_landmarks.T @ g)
        if w["p2f"] or w["normal"]:
            shape, g = losses.shape_losses(self.W_shape @ Z, self.shape_ref, w["p2f"],
                                           w["normal"])
            values.update(shape)
            energy += sum(w[name] * value for name, value in shape.items())
            grad += self.W_shape.T @ g
        if w["symmetry"] and self.symmetry is not None:
            Y = W_samples @ Z if Y is None else Y
            v_shape, g_shape = losses.symmetry_loss(Y, self.symmetry)
            v_cage, g_cage = losses.cage_symmetry_loss(C, *self.partners, self.symmetry)
            g = W_samples.T @ g_shape
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

    def __call__(self, C: Vertices) -> tuple[float, Vertices]:
        """Weighted energy and its gradient, shape (k, 3)."""
        energy, grad, _ = self.evaluate(C)
        return energy, grad


def _lifted(C, face_terms):
    """``C``, or with Green coordinates ``[C; face_terms(C)]`` (k + m, 3)."""
    return C if face_terms is None else np.vstack([C, face_terms(C)])


# -------------------------------------------------------------------------- the methods


def term_weights(user: Mapping[str, float] | None,
                 landmarks: tuple[ArrayLike, ArrayLike] | None, symmetry: str | None,
                 reference: str) -> dict[str, float]:
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


def _shape_rows(Vs_n, Fs, shape_points, rng):
    """Rows (own vertex, neighbourhood) of the shape terms, compacted to the points used."""
    nb = vertex_neighborhoods(Vs_n, Fs, k=16)
    rows = subset(len(Vs_n), shape_points, rng)
    columns = nb.mask[rows].any(axis=0)  # a prefix: drop the padding no chosen row needs
    index, mask = nb.index[rows][:, columns], nb.mask[rows][:, columns]
    used, inverse = np.unique(np.concatenate([rows, index.ravel()]), return_inverse=True)
    own = inverse[: len(rows)]
    return used, own, inverse[len(rows):].reshape(index.shape), mask


def box_factors(Vs_n: ArrayLike, Vt_n: ArrayLike, target_kind: str) -> Floats:
    """The coarse stage's per-axis factors: :func:`~cagekit.geometry.alignment.box_scale`, or
    :func:`~cagekit.geometry.alignment.partial_box_scale` onto a partial target."""
    return (partial_box_scale if target_kind == "partial" else box_scale)(Vs_n, Vt_n)


def _part_term(Vs_n, Fs, W_vertices):
    """The part-affinity quadratic form of the source's parts
    (:func:`cagekit.geometry.parts.vertex_parts`, seams joined) of at least
    ``MIN_PART_VERTICES`` vertices, or None when it has fewer than two."""

    if not len(Fs):
        return None
    parts = losses.part_bases(Vs_n, vertex_parts(Vs_n, Fs), MIN_PART_VERTICES)
    if len(parts.bases) < 2:
        return None
    return losses.part_affinity_matrix(W_vertices, parts)


def _detail_term(Vs_n, Fs, W_vertices):
    """The detail term's quadratic form, or None for a point cloud or a mesh whose
    cotangent Laplacian is undefined (every face of zero area or a sliver)."""

    if not len(Fs):
        return None
    try:
        L = surface_laplacian(Vs_n, Fs)
    except InputError:
        return None
    return losses.detail_matrix(W_vertices, L)


def _samples_of(role, V, F, n, seed):
    """``sample_surface``, its errors naming the role (the command line blames the file)."""
    try:
        return sample_surface(V, F, n, seed=seed)
    except InputError as exc:
        raise InputError(f"the {role}: {exc.problem}") from None


@dataclass
class CageProblem:
    """One source-target pair, bound to the source's cage, in the unit frames.

    Build it with :meth:`create`; :func:`solve` minimises its energy. Everything is in
    the paper's frame: the source, its cage and the source landmarks normalised by the
    source's :class:`~cagekit.geometry.frame.Frame`, the target and its landmarks by the target's.

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

    def vertices_of(self, C: Vertices) -> Vertices:
        """The deformed source for a deformed cage ``C`` (k, 3), target's unit frame."""
        return self.W_vertices @ self.energy.lift(C)

    @classmethod
    def create(cls, Vs_n: np.ndarray, Fs: np.ndarray, Vt_n: np.ndarray, Ft: np.ndarray,
               cage_v: np.ndarray, cage_f: np.ndarray, options: DeformOptions, *,
               landmarks: tuple[np.ndarray, np.ndarray] | None = None) -> CageProblem:
        """Sample, bind and set up the energy of one pair (all arrays in unit frames).

        Parameters
        ----------
        Vs_n, Fs, Vt_n, Ft : (n, 3) float64, (m, 3) int64, (t, 3) float64, (p, 3) int64
            The source and the target, each normalised on its own (``F`` empty for a
            point cloud).
        cage_v, cage_f : (k, 3) float64 and (c, 3) int64
            The source cage in the source's unit frame, checked already.
        options : DeformOptions
            The terms and their sampling (``symmetry``, ``weights``, ``samples``,
            ``shape_points``, ``reference``, ``coords``, ``seed``, ``target_kind``; the
            solver's fields are :func:`solve`'s).
        landmarks : (source points (l, 3), target points (l, 3)), optional
            In the unit frames.
        """
        symmetry, reference, coords = options.symmetry, options.reference, options.coords
        weights = term_weights(options.weights, landmarks, symmetry, reference)
        src_lm, tgt_lm = (None, None) if landmarks is None else landmarks
        samples, target_kind = options.samples, options.target_kind
        rng = np.random.default_rng(options.seed)
        S = _samples_of("source", Vs_n, Fs, samples, int(rng.integers(2**31)))
        T = _samples_of("target", Vt_n, Ft, samples, int(rng.integers(2**31)))
        used, own, index, mask = _shape_rows(Vs_n, Fs, options.shape_points, rng)
        parts = [Vs_n, S] + ([src_lm] if src_lm is not None else [])
        binding = bind(np.concatenate(parts), cage_v, cage_f, method=coords, check=False)
        face_terms = None
        if isinstance(binding, GreenBinding):
            W = np.hstack([binding.phi, binding.psi])
            face_terms = FaceTerms(binding.cage_v, binding.cage_f)
        else:
            W = binding.weights
        n, s = len(Vs_n), len(S)
        W_samples = W[n:n + s]
        W_landmarks = W[n + s:] if src_lm is not None else None
        W_shape = np.ascontiguousarray(W[:n][used])
        box_cage = binding.cage_v * box_factors(Vs_n, Vt_n, target_kind)
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


def solve(problem: CageProblem, start: Vertices | None = None, *, max_evaluations: int = 60,
          tolerance: float = 1e-7,
          progress: Callable[[int, int], object] | None = None) -> CageSolution:
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
