"""``deform``: a source deformed onto a target by its cage (or by a baseline method).

The energy, its terms and the solver are :mod:`cagekit.deformation.problem`,
:mod:`cagekit.deformation.terms` and :mod:`cagekit.deformation.solver`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from cagekit.cage import check_cage
from cagekit.cage.fitting import fit_cage
from cagekit.coords.binding import warn_outside
from cagekit.deformation.problem import (
    LANDMARK_MARGIN,
    SAMPLES,
    SHAPE_POINTS,
    CageProblem,
    CageSolution,
    box_factors,
    check_choices,
    check_counts,
    solve,
    term_weights,
)
from cagekit.errors import InputError
from cagekit.geometry import as_shape, as_vertices
from cagekit.geometry.frame import Frame

__all__ = ["COORDS", "DeformResult", "METHODS", "TARGET_KINDS", "deform"]

METHODS = ("cage", "scale", "nricp")
#: the coordinates the energy takes (Green's through their faces' terms, exactly)
COORDS = ("mvc", "green")
TARGET_KINDS = ("full", "partial")


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
    source_frame, target_frame : cagekit.geometry.frame.Frame
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
        with :func:`cagekit.deformation.terms.partial_chamfer_loss` (every scanned point onto the
        source, the source onto the scan at a tenth of the weight), so the source's
        unseen side is not squashed onto the seen one; every method's box alignment
        keeps each axis's stretch at least the median of the three
        (:func:`cagekit.geometry.alignment.partial_box_scale`: the scan is shallow along the view).

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
    >>> from cagekit.cage.shapes import box_cage
    >>> V, F = box_cage(4, half_extent=(1.0, 0.5, 0.5))
    >>> result = deform((V, F), (V * [2.0, 1.0, 1.0], F), method="scale")
    >>> np.allclose(result.vertices, V * [2.0, 1.0, 1.0])
    True
    """
    start = time.perf_counter()
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; available: {', '.join(METHODS)}")
    check_choices(symmetry, reference)
    if initial_cage is not None and method != "cage":
        raise InputError("initial_cage applies to method cage only")
    if initial_cage is not None and cage is None:
        raise InputError("initial_cage needs the cage it deforms (cage=...)")
    if coords not in COORDS:
        raise InputError(f"deform takes coords {', '.join(COORDS)}, got {coords!r}")
    term_weights(weights, landmarks, symmetry, reference)  # refuse bad weights before any work
    check_counts({"samples": samples, "shape_points": shape_points,
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
        result.vertices = ft.to_world(Vs_n * box_factors(Vs_n, Vt_n, target_kind))
    elif method == "nricp":
        result.vertices = ft.to_world(_nricp(Vs_n * box_factors(Vs_n, Vt_n, target_kind),
                                             Fs, Vt_n, Ft))
    else:
        lm = _landmarks_in_frames(landmarks, fs, ft)
        if cage is None:

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
