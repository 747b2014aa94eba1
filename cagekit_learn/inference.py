"""Deforming a full-resolution mesh with a trained model (``cagekit deform --model``).

One forward pass predicts the source cage and its deformation from 1,024 samples of each
shape; the predicted cage is checked (:func:`cagekit_learn.cage_repair.check_predicted_cage`:
grown when it leaves part of the source out, refused when it intersects itself or cannot
be grown to enclose it, and then the pair is deformed by :func:`cagekit.deform` with a
fitted cage, with one warning); the full-resolution source is then bound to the cage with
the core's exact MVC (:func:`cagekit.bind`, float64) and moved with the deformed cage.
``refine=True`` then runs the per-pair optimisation of :func:`cagekit.deform` on the
predicted cage, starting from its predicted deformation. Without it, the result is polished
by :data:`POLISH_EVALUATIONS` evaluations of the same energy on :data:`POLISH_SAMPLES`
samples (``polish``; 0 hands on the network's result as it is, the default for a model
trained with a fixed source); then a result further from
the target than the predicted cage scaled as the source's box scales onto the target's is
replaced by that scaling, with one warning (:func:`warn_if_worse_than_scaling`;
``scaling_fallback=False``, ``cagekit deform --keep-prediction``, keeps the network's
(polished) result and still warns).

A model trained with a fixed source (``cagekit train --fixed-source``) carries the
template's normalised samples (``model.fixed_source``); :func:`predict_fixed_source` and
:func:`deform_with_model` feed those as the source, exactly as in training. Frames: the
source cage is in the template's normalised frame (``* fixed_source_scale +
fixed_source_center`` of ``model.config`` maps it to the template's own frame), the
deformed cage in the target's normalised frame (``* target scale + target centre``, from
:meth:`cagekit.Frame.of` of the target).
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Callable

import numpy as np
import torch
from numpy.typing import ArrayLike

from cagekit.cage import check_cage
from cagekit.coords import bind
from cagekit.deformation import CageProblem, DeformOptions, DeformResult, deform, solve
from cagekit.errors import CageError, CagekitWarning, InputError
from cagekit.geometry import as_count, as_shape
from cagekit.geometry.alignment import box_scale
from cagekit.geometry.frame import pair_frames
from cagekit.geometry.sampling import sample_surface
from cagekit.metrics import chamfers_to
from cagekit.typed import Vertices
from cagekit_learn.cage_repair import check_predicted_cage
from cagekit_learn.networks import NeuralCages
from cagekit_learn.train import load_model

__all__ = ["ModelDeformer", "predict", "predict_fixed_source", "predict_cages",
           "deform_with_model", "warn_if_worse_than_scaling", "REFINE_CAGE_WEIGHT"]

#: weight of the cage term (the cage Laplacian's change,
#: :data:`cagekit.deformation.DEFAULT_WEIGHTS` ``"cage"``, 0.3 for a fitted cage) when
#: ``refine=True`` and the caller sets none: the predicted cage already carries the
#: network's prior on the deformation, and at 0.3 the refinement stopped 2-7% above
#: ``cage``'s Chamfer distance with parts much straighter than needed. Chosen on pairs of
#: the shipped models' *training* seats and tables (0.3, 0.1, 0.03, 0.01, 0: 0.01 is the
#: largest whose median CD is no worse than ``cage``'s there); docs/benchmarks.md, "The
#: refinement's cage weight".
REFINE_CAGE_WEIGHT = 0.01
#: samples of each shape in the polish's Chamfer term (``polish`` of
#: :func:`deform_with_model`; the refinement takes ``options.samples``, 2,000 by default)
POLISH_SAMPLES = 1000
#: evaluations of the refinement's energy that polish the network's result by default
#: (``polish`` of :func:`deform_with_model`, ``cagekit deform --polish``): chosen on 24
#: pairs of the ``chairs`` model's *training* seats (0, 10, 15, 20, 30: per-pair Chamfer
#: distance 1, 0.90, 0.870, 0.866, 0.85 of the network's alone, worst part 0.144, 0.189,
#: 0.155, 0.156, 0.143%; 15 is 20's result at 0.01 s less a pair on a 2-core AMD EPYC);
#: docs/benchmarks.md, "The network's result polished"
POLISH_EVALUATIONS = 15
#: the most evaluations a polish may ask for (a longer one is the refinement: ``refine``;
#: ``--polish`` of ``cagekit deform`` and ``cagekit amplify`` has the same bound)
MAX_POLISH = 10_000


def predict(model: NeuralCages, source_points: ArrayLike,
            target_points: ArrayLike) -> tuple[Vertices, Vertices]:
    """Predicted source cage and deformed cage for one pair of normalised clouds.

    Parameters
    ----------
    model : NeuralCages
    source_points, target_points : (P, 3) array_like of float
        Samples of the normalised source and target.

    Returns
    -------
    source_cage, deformed_cage : (k, 3) float64
        In the normalised source and target frames; faces are ``model.cage_f``.
    """
    device = model.template.device
    with torch.no_grad():
        s = torch.as_tensor(np.asarray(source_points), dtype=torch.float32, device=device)
        t = torch.as_tensor(np.asarray(target_points), dtype=torch.float32, device=device)
        out = model(s[None], t[None])
    return (out["source_cage"][0].double().cpu().numpy(),
            out["deformed_cage"][0].double().cpu().numpy())


def predict_fixed_source(model: NeuralCages,
                         target_points: ArrayLike) -> tuple[Vertices, Vertices]:
    """Source cage and deformed cage for a model trained with a fixed source.

    Parameters
    ----------
    model : NeuralCages
        Trained with ``--fixed-source`` (``model.fixed_source`` holds the template's
        normalised samples, which are the source here).
    target_points : (P, 3) array_like of float
        Samples of the target normalised on its own (:meth:`cagekit.Frame.of`). Under
        the L2 alignment the model saw the vertex rows ``model.config.fixed_source_rows``
        of its targets; taking the same rows of a target in correspondence matches
        training best.

    Returns
    -------
    source_cage, deformed_cage : (k, 3) float64
        The source cage in the template's normalised frame (equal to the fixed cage when
        there is one; ``* model.config.fixed_source_scale + fixed_source_center`` maps it
        to the template's own frame) and the deformed cage in the target's normalised
        frame (``* target scale + target centre`` maps it back); faces ``model.cage_f``.

    Raises
    ------
    InputError
        The model has no fixed source, or the target points are not (P, 3).
    """
    fixed = getattr(model, "fixed_source", None)
    if fixed is None:
        raise InputError("the model was not trained with a fixed source (cagekit train "
                         "--fixed-source); use predict(model, source_points, target_points)")
    target = np.asarray(target_points, dtype=np.float64)
    if target.ndim != 2 or target.shape[1] != 3 or len(target) < 1:
        raise InputError(f"target points must have shape (P, 3), got {target.shape}")
    return predict(model, fixed.cpu().numpy(), target)


def _predicted(model, Vs, Fs, Vt, Ft, points, seed):
    """Normalise both shapes, sample them as in training and run the model.

    Returns ``(fs, ft, Vs_n, Vt_n, cage_n, deformed_n)``: both unit frames, both shapes
    in them, and the two cages in the source's and the target's unit frames.
    """
    points = 1024 if points is None else int(points)
    fs, ft = pair_frames(Vs, Vt)
    Vs_n, Vt_n = fs.to_unit(Vs), ft.to_unit(Vt)
    fixed = getattr(model, "fixed_source", None)
    config = getattr(model, "config", None)
    rows = getattr(config, "fixed_source_rows", None)
    if fixed is not None and rows is not None and len(Vt) == getattr(
            config, "fixed_source_vertex_count", None):
        T = Vt_n[np.asarray(rows, dtype=np.int64)]
    else:
        T = sample_surface(Vt_n, Ft, points, seed=seed + 1)
    if fixed is not None:
        cage_n, deformed_n = predict_fixed_source(model, T)
    else:
        S = sample_surface(Vs_n, Fs, points, seed=seed)
        cage_n, deformed_n = predict(model, S, T)
    return fs, ft, Vs_n, Vt_n, cage_n, deformed_n


def _shapes(V_src, F_src, V_tgt, F_tgt):
    """Both shapes checked, as :func:`cagekit.deform` checks them."""
    return as_shape((V_src, F_src), name="source") + as_shape((V_tgt, F_tgt), name="target")


def predict_cages(model: NeuralCages, V_src: ArrayLike, F_src: ArrayLike | None,
                  V_tgt: ArrayLike, F_tgt: ArrayLike | None = None, *,
                  points: int | None = None, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The predicted source cage and its deformation, in the shapes' own frames.

    The first half of :func:`deform_with_model` (samples fed exactly as it feeds them,
    fixed source included), for callers that move the cage themselves.

    Parameters
    ----------
    model : NeuralCages
    V_src, F_src, V_tgt, F_tgt : array_like
        The source and the target, as :func:`cagekit.deform` takes them.
    points : int, optional
        Samples of each shape; default 1,024.
    seed : int, default 0

    Returns
    -------
    cage_v, deformed_cage_v : (k, 3) float64
        In the source's and the target's frames and units; faces ``model.cage_f``.
    """
    Vs, Fs, Vt, Ft = _shapes(V_src, F_src, V_tgt, F_tgt)
    fs, ft, _, _, cage_n, deformed_n = _predicted(model, Vs, Fs, Vt, Ft, points, seed)
    return fs.to_world(cage_n), ft.to_world(deformed_n)


def deform_with_model(model: NeuralCages, V_src: ArrayLike, F_src: ArrayLike | None,
                      V_tgt: ArrayLike, F_tgt: ArrayLike | None = None, *,
                      points: int | None = None, seed: int = 0, refine: bool = False,
                      options: DeformOptions | None = None,
                      progress: Callable[[int, int], object] | None = None,
                      fallback: bool = True, scaling_fallback: bool = True,
                      polish: int | None = None) -> DeformResult:
    """Deform a source to take a target's shape with a trained model.

    Parameters
    ----------
    model : NeuralCages
        From :func:`cagekit_learn.train.load_model`.
    V_src, F_src, V_tgt, F_tgt : array_like
        The source and the target, as :func:`cagekit.deform` takes them.
    points : int, optional
        Samples of each shape fed to the network; default: the number it was trained with
        (1,024 unless configured otherwise), which the caller passes.
    seed : int, default 0
        Seed of the samples.
    refine : bool, default False
        Then optimise the cage per pair, started from the predicted deformation (the
        energy of :func:`cagekit.deform`, as a :class:`cagekit.deformation.CageProblem`
        solved by :func:`cagekit.deformation.solve` in the unit frames).
    options : cagekit.DeformOptions, optional
        When refining or polishing, the energy's terms and (refining) the solver's
        budget (``symmetry``, ``weights``, ``samples``, ``shape_points``, ``reference``,
        ``max_evaluations``, ``tolerance``, ``target_kind``); both run in the unit frames the
        prediction is in (:class:`cagekit.deformation.CageProblem`), with the
        coordinates the model was trained with (``coords``, ``method``, ``faces`` and
        ``check`` do not apply). Unless ``weights`` sets ``"cage"`` (or ``reference`` is
        ``"source"``), the cage term weighs :data:`REFINE_CAGE_WEIGHT`.
    progress : callable, optional
        When refining (or falling back), as :func:`cagekit.deform` calls it.
    fallback : bool, default True
        What to do with a predicted cage that cannot be used
        (:func:`cagekit_learn.cage_repair.check_predicted_cage`: it intersects itself,
        or leaves source points outside even when grown): True deforms by per-pair
        optimisation with a fitted cage instead (:func:`cagekit.deform`, ``options``
        with method ``"cage"``) and says so in one warning; False raises.
    scaling_fallback : bool, default True
        Without ``refine``: what to do with a result further from the target than the
        box scaling (:func:`warn_if_worse_than_scaling`, one warning either way). The
        scaling is the predicted source cage scaled per axis as the source's bounding
        box maps onto the target's, the source moved by it: with MVC exactly the source
        scaled (``cagekit deform --method scale``), with Green coordinates, which keep
        angles, near it. True hands that on instead (method ``"scale"``, the scaled
        cage as the deformed cage); False keeps the network's result (polished, with
        ``polish``: the polished result is what is compared, on fresh samples).
    polish : int, optional
        Without ``refine``: evaluations of the refinement's energy (``options``' terms,
        :data:`POLISH_SAMPLES` samples) that polish the network's result, started from its
        predicted deformation (``options``' terms; its ``samples`` and
        ``max_evaluations`` do not apply); 0 hands on the network's result as it is.
        Default :data:`POLISH_EVALUATIONS` (about 0.05 s more than the network alone on
        real seats of 1,000-12,000 vertices, on 2 cores), or 0 for a model trained with a
        fixed source, whose targets correspond vertex for vertex (the energy's Chamfer
        term would not keep that), and with ``refine``. A positive ``polish`` with
        ``refine`` is refused.

    Returns
    -------
    DeformResult
        ``method`` is ``"learned"`` (polished or not) or ``"learned+refine"``
        (``"cage"`` or ``"scale"`` after a fall back); vertices in the target's frame and
        units; the cages in the source's and target's frames: the cage used, which is the
        predicted one grown about the source's centre when it left points outside.

    Raises
    ------
    CageError
        With ``fallback=False``, the predicted cage cannot be used (the message says why).

    Notes
    -----
    A model trained with a fixed source gets its stored template samples as the source
    (not samples of ``source``), so ``source`` should be that template (or a mesh with
    the same normalised frame, a finer version of it say): the predicted cage is placed
    around ``source`` normalised on its own. The target's samples are then its vertex
    rows ``model.config.fixed_source_rows`` when the model was trained with them (L2
    alignment) and the target has the template's vertex count, as in training; surface
    samples otherwise.
    """
    start = time.perf_counter()
    options = DeformOptions() if options is None else options
    if polish is None:
        polish = 0 if getattr(model, "fixed_source", None) is not None else POLISH_EVALUATIONS
        if refine:
            polish = 0
    polish = _checked_polish(polish)
    if refine and polish:
        raise InputError("polish applies without refine (the refinement runs to "
                         "options.max_evaluations)")
    if not isinstance(options, DeformOptions):
        raise InputError(f"options must be DeformOptions, got {type(options).__name__}")
    Vs, Fs, Vt, Ft = _shapes(V_src, F_src, V_tgt, F_tgt)
    fs, ft, Vs_n, Vt_n, cage_n, deformed_n = _predicted(model, Vs, Fs, Vt, Ft, points, seed)
    cage_f = check_cage(cage_n, model.cage_f.cpu().numpy(), intersections=False)
    checked = check_predicted_cage(Vs_n, cage_n, deformed_n, cage_f)
    if not checked.valid:
        message = f"the model's cage for the source cannot be used: {checked.problem}"
        if not fallback:
            raise CageError(message)
        warnings.warn(CagekitWarning(f"{message}; deformed by per-pair optimisation with a "
                                     "fitted cage (method 'cage') instead"), stacklevel=2)
        return deform(Vs, Fs, Vt, Ft, options=dataclasses.replace(options, method="cage"),
                      progress=progress)
    cage_n, deformed_n = checked.cage_v, checked.deformed_v
    result = DeformResult(vertices=Vs, faces=Fs, method="learned", cage_f=cage_f,
                          source_frame=fs, target_frame=ft)
    if refine:  # the per-pair optimisation from the prediction, in the unit frames
        problem = CageProblem.create(
            Vs_n, Fs, Vt_n, Ft, cage_n, cage_f,
            dataclasses.replace(options, coords=_coords_of(model), seed=seed,
                                weights=_refine_weights(options)))
        result.set_solution(problem, solve(
            problem, deformed_n, max_evaluations=options.max_evaluations,
            tolerance=options.tolerance, progress=progress))
        result.method = "learned+refine"
    else:
        move: Callable[[Vertices], Vertices]
        if polish:  # a few steps of the refinement's energy from the prediction
            problem = CageProblem.create(
                Vs_n, Fs, Vt_n, Ft, cage_n, cage_f,
                dataclasses.replace(options, coords=_coords_of(model), seed=seed,
                                    samples=POLISH_SAMPLES,
                                    weights=_refine_weights(options)))
            polished = solve(problem, deformed_n, max_evaluations=polish,
                             tolerance=options.tolerance)
            result.set_solution(problem, polished)  # the energy, terms and evaluations
            move, used_f = problem.vertices_of, problem.cage_f
            moved_n, deformed_n = polished.vertices, polished.deformed_cage
        else:
            binding = bind(Vs_n, cage_n, cage_f, method=_coords_of(model), check=False)
            move, used_f = binding.deform, binding.cage_f
            moved_n = move(deformed_n)
        scaled_cage = cage_n * box_scale(Vs_n, Vt_n)
        scaled_n = move(scaled_cage)
        # fresh samples: the polish's own would favour the result it was fitted to
        if warn_if_worse_than_scaling(Vs_n, Fs, Vt_n, Ft, moved_n, seed=seed,
                                      instead=scaling_fallback,
                                      scaled_n=scaled_n) and scaling_fallback:
            moved_n, deformed_n = scaled_n, scaled_cage
            result.method = "scale"
        result.vertices = ft.to_world(moved_n)
        result.cage_v, result.cage_f = fs.to_world(cage_n), used_f
        result.deformed_cage_v = ft.to_world(deformed_n)
    if not np.isfinite(result.vertices).all():
        raise FloatingPointError("the model produced NaN or inf positions")
    result.seconds = time.perf_counter() - start
    return result


def warn_if_worse_than_scaling(Vs_n: ArrayLike, Fs: ArrayLike | None, Vt_n: ArrayLike,
                               Ft: ArrayLike | None, moved_n: ArrayLike,
                               seed: int = 0, instead: bool = False,
                               scaled_n: ArrayLike | None = None) -> bool:
    """Warn when a learned result is further from the target than box scaling is.

    A network that has not seen shapes like these can add a deformation the pair does not
    need (docs/benchmarks.md, "Unseen game furniture": low-poly game tables came out lower
    than their targets, 2-4x the per-pair Chamfer distance and above plain scaling). The
    target is at hand, so the result is compared with the source's bounding box scaled onto
    the target's (``cagekit deform --method scale``): Chamfer distances of 2,048 samples
    each, in the unit frames (10-20 ms for both on 2 cores).

    Parameters
    ----------
    Vs_n : (n, 3) array_like of float
        The source in its unit frame (:class:`cagekit.geometry.frame.Frame`).
    Fs : (m, 3) array_like of int or None
        Its faces (None or empty: a point cloud).
    Vt_n, Ft : array_like
        The target in its unit frame, and its faces.
    moved_n : (n, 3) array_like of float
        The learned result, in the target's unit frame.
    seed : int, default 0
        Of the samples.
    instead : bool, default False
        The caller hands on the scaling instead (:func:`deform_with_model`'s
        ``scaling_fallback``): the warning says so.
    scaled_n : (n, 3) array_like of float, optional
        The scaling to compare with, in the target's unit frame; default the source
        scaled per axis onto the target's bounding box
        (:func:`cagekit.geometry.alignment.box_scale`).

    Returns
    -------
    bool
        True when it warned (one :class:`cagekit.CagekitWarning`).

    Examples
    --------
    >>> import numpy as np
    >>> from cagekit.cage.shapes import box_cage
    >>> V, F = box_cage()
    >>> warn_if_worse_than_scaling(V, F, V * [1, 2, 1], F, V * [1, 2, 1])
    False
    """
    Vs_n, Vt_n = np.asarray(Vs_n, dtype=np.float64), np.asarray(Vt_n, dtype=np.float64)
    scaled = Vs_n * box_scale(Vs_n, Vt_n) if scaled_n is None else scaled_n
    learned, scaling = chamfers_to([moved_n, scaled], Fs, Vt_n, Ft, n_samples=2048,
                                   seed=seed)
    if not learned > scaling:
        return False
    warnings.warn(CagekitWarning(
        f"the model's result is further from the target than the source's bounding box "
        f"scaled onto the target's (Chamfer x1e2 of 2,048 samples {100 * learned:.3f} "
        f"against {100 * scaling:.3f}; the CD printed with a result takes 5,000 and "
        f"can come out lower): the pair may be unlike the shapes the model was trained "
        f"on; {'the scaling is returned instead' if instead else 'the result is kept'}, "
        "and refining (--refine) optimises from the prediction"), stacklevel=3)
    return True


def _checked_polish(polish):
    """``polish`` as an int >= 0 (None stays None), or InputError."""
    if polish is None:
        return None
    polish = as_count(polish, "polish")
    if polish > MAX_POLISH:
        raise InputError(f"polish must be at most {MAX_POLISH:,} (a longer optimisation is "
                         f"the refinement), got {polish}")
    return polish


def _refine_weights(options: DeformOptions):
    """The caller's weights, with the cage term at :data:`REFINE_CAGE_WEIGHT` unless set."""
    if "cage" in (options.weights or {}) or options.reference != "aligned":
        return options.weights
    return {**(options.weights or {}), "cage": REFINE_CAGE_WEIGHT}


def _coords_of(model) -> str:
    """The coordinates a model was trained with (``mvc`` for models from before)."""
    return getattr(model.config, "coords", "mvc")


class ModelDeformer:
    """:func:`deform_with_model` as a picklable callable, for batches run by workers.

    The checkpoint is loaded once per process, on first use (a pickled copy carries only
    the path), so that a process pool or a cluster's workers each read it once.

    Parameters
    ----------
    path : str
        A checkpoint or run folder (:func:`cagekit_learn.train.load_model`).
    refine : bool, default False
        As :func:`deform_with_model`.
    scaling_fallback : bool, default True
        As :func:`deform_with_model`.
    polish : int, optional
        As :func:`deform_with_model`.

    Examples
    --------
    >>> deformer = ModelDeformer("runs/chairs", refine=True)  # doctest: +SKIP
    >>> result = deformer(V_src, F_src, V_tgt, F_tgt, seed=0)  # doctest: +SKIP
    """

    def __init__(self, path: str, refine: bool = False, scaling_fallback: bool = True,
                 polish: int | None = None):
        self.path, self.refine = path, bool(refine)
        self.scaling_fallback, self.polish = bool(scaling_fallback), _checked_polish(polish)
        if self.refine and self.polish:
            raise InputError("polish applies without refine")
        self._model: tuple[NeuralCages, int] | None = None

    def __getstate__(self):
        return {**self.__dict__, "_model": None}  # the settings, never the loaded model

    def __call__(self, V_src: ArrayLike, F_src: ArrayLike | None, V_tgt: ArrayLike,
                 F_tgt: ArrayLike | None = None, seed: int = 0) -> DeformResult:
        if self._model is None:

            model, payload = load_model(self.path)
            self._model = (model, int(payload.get("config", {}).get("points", 1024)))
        model, points = self._model
        return deform_with_model(model, V_src, F_src, V_tgt, F_tgt, points=points, seed=seed,
                                 refine=self.refine, scaling_fallback=self.scaling_fallback,
                                 polish=self.polish)
