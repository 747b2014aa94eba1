"""``deform``: a source deformed onto a target by its cage (or by a baseline method).

The energy, its terms and the solver are :mod:`cagekit.deformation.problem`,
:mod:`cagekit.deformation.terms` and :mod:`cagekit.deformation.solver`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from cagekit.cage import check_cage
from cagekit.cage.fitting import fit_cage
from cagekit.coords.binding import warn_outside
from cagekit.deformation.options import DeformOptions
from cagekit.deformation.problem import (
    LANDMARK_MARGIN,
    CageProblem,
    CageSolution,
    box_factors,
    solve,
    term_weights,
)
from cagekit.errors import InputError
from cagekit.geometry import as_shape, as_vertices
from cagekit.geometry.frame import Frame, pair_frames

__all__ = ["DeformResult", "deform"]

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
        :func:`cagekit_learn.inference.deform_with_model`, or ``"cage"`` or ``"scale"``
        where it handed on a fall back).
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
        fs, ft = self.source_frame, self.target_frame
        if fs is None or ft is None:
            raise ValueError("set_solution needs the result's source and target frames")
        self.vertices = ft.to_world(solution.vertices)
        self.cage_v = fs.to_world(problem.cage_v)
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


def deform(V_src: ArrayLike, F_src: ArrayLike | None, V_tgt: ArrayLike,
           F_tgt: ArrayLike | None = None, cage_v: ArrayLike | None = None,
           cage_f: ArrayLike | None = None, options: DeformOptions | None = None, *,
           landmarks: tuple[ArrayLike, ArrayLike] | None = None,
           initial_cage: ArrayLike | None = None,
           progress: Callable[[int, int], object] | None = None) -> DeformResult:
    """Deform a source so it takes the shape of a target, keeping its detail.

    Parameters
    ----------
    V_src : (n, 3) array_like of float
        The shape to deform.
    F_src : (m, 3) array_like of int, or None
        Its faces; None or empty for a point cloud, whose points are deformed.
    V_tgt : (t, 3) array_like of float
        The shape to match.
    F_tgt : (p, 3) array_like of int, or None
        Its faces; None or empty for a point cloud (noisy or coarse; partial ones squash
        the source, see the module docstring).
    cage_v, cage_f : (k, 3) array_like of float and (c, 3) array_like of int, optional
        The source's cage in the source's frame: closed, 2-manifold, free of
        self-intersection (refused otherwise, see ``DeformOptions.check``); a cage that
        leaves part of the source outside is used with an
        :class:`~cagekit.errors.OutsideCageWarning` (those points are extrapolated). When
        None, :func:`cagekit.fit_cage` builds one with ``options.faces`` faces, checked
        against 5,000 surface samples instead of fit-cage's 20,000 (faster; the
        coordinates are defined outside the cage too, so a sample a hair outside does no
        harm).
    options : DeformOptions, optional
        The method, the energy's terms and the solver's budget (default:
        ``DeformOptions()``).
    landmarks : (source points (l, 3), target points (l, 3)), optional
        Corresponding points, each in its own shape's frame; the alignment term becomes
        their mean squared distance.
    initial_cage : (k, 3) array_like of float, optional
        Where the optimisation starts: a deformed position of the cage's vertices in the
        target's frame and units (for example a learned prediction; ``cagekit deform
        --model --refine`` refines one in the unit frames with :class:`CageProblem` and
        :func:`solve`). Default: the box-aligned cage. Needs the cage; the references of
        the shape and cage terms are unchanged.
    progress : callable, optional
        Called as ``progress(evaluations, max_evaluations)`` after each energy
        evaluation of ``cage`` (the command line moves a progress bar with it).

    Returns
    -------
    DeformResult

    Raises
    ------
    InputError
        Bad shapes, a cage given without its faces (or faces without vertices), bad
        landmarks, weights for terms that are off, landmark counts that differ, a
        point-cloud source with ``nricp``.

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> V, F = box_cage(4, half_extent=(1.0, 0.5, 0.5))
    >>> result = deform(V, F, V * [2.0, 1.0, 1.0], F, options=DeformOptions(method="scale"))
    >>> np.allclose(result.vertices, V * [2.0, 1.0, 1.0])
    True
    """
    start = time.perf_counter()
    options = DeformOptions() if options is None else options
    if not isinstance(options, DeformOptions):
        raise InputError(f"options must be DeformOptions, got {type(options).__name__}")
    method = options.method
    if (cage_v is None) != (cage_f is None):
        raise InputError("a cage needs both its vertices and its faces (cage_v, cage_f)")
    if initial_cage is not None and method != "cage":
        raise InputError("initial_cage applies to method cage only")
    if initial_cage is not None and cage_v is None:
        raise InputError("initial_cage needs the cage it deforms (cage_v, cage_f)")
    # refuse bad weights before any work
    term_weights(options.weights, landmarks, options.symmetry, options.reference)
    Vs, Fs = as_shape((as_vertices(V_src, "the source"), F_src), name="source")
    Vt, Ft = as_shape((as_vertices(V_tgt, "the target"), F_tgt), name="target")
    fs, ft = pair_frames(Vs, Vt)
    Vs_n, Vt_n = fs.to_unit(Vs), ft.to_unit(Vt)
    result = DeformResult(vertices=Vs, faces=Fs, method=method, source_frame=fs,
                          target_frame=ft)
    if method == "scale":
        result.vertices = ft.to_world(Vs_n * box_factors(Vs_n, Vt_n, options.target_kind))
    elif method == "nricp":
        start_n = Vs_n * box_factors(Vs_n, Vt_n, options.target_kind)
        result.vertices = ft.to_world(_nricp(start_n, Fs, Vt_n, Ft))
    else:
        cage = _unit_cage(Vs_n, Fs, cage_v, cage_f, fs, options)
        C_start = None
        if initial_cage is not None:
            C_start = ft.to_unit(as_vertices(initial_cage, "initial cage vertices"))
            if C_start.shape != cage[0].shape:  # before any sampling or binding
                raise InputError(f"initial cage has {len(C_start)} vertices, the cage "
                                 f"{len(cage[0])}")
        lm = _landmarks_in_frames(landmarks, fs, ft)
        problem = CageProblem.create(Vs_n, Fs, Vt_n, Ft, cage[0], cage[1], options,
                                     landmarks=None if lm[0] is None else lm)
        solution = solve(problem, C_start, max_evaluations=options.max_evaluations,
                         tolerance=options.tolerance, progress=progress)
        result.set_solution(problem, solution)
    if not np.isfinite(result.vertices).all():
        raise FloatingPointError(f"method {method} produced NaN or inf positions")
    result.seconds = time.perf_counter() - start
    return result


def _unit_cage(Vs_n, Fs, cage_v, cage_f, source_frame, options):
    """The source's cage in its unit frame: the given one checked, or a fitted one."""
    if cage_v is None:
        fitted = fit_cage(Vs_n, Fs, faces=options.faces, seed=options.seed, samples=5000,
                          report=False)
        return fitted.vertices, fitted.faces
    cage_n = source_frame.to_unit(as_vertices(cage_v, "cage vertices"))
    cage_f = check_cage(cage_n, cage_f, intersections=options.check)
    warn_outside(Vs_n, cage_n, cage_f, shape="the source", cage="the given cage")
    return cage_n, cage_f
