"""Deforming a full-resolution mesh with a trained model (``cagekit deform --model``).

One forward pass predicts the source cage and its deformation from 1,024 samples of each
shape; the full-resolution source is then bound to the predicted cage with the core's
exact MVC (:func:`cagekit.bind`, float64) and moved with the predicted deformed cage.
``refine=True`` then runs the per-pair optimisation of :func:`cagekit.deform` on the
predicted cage, starting from its predicted deformation.
"""

from __future__ import annotations

import time

import numpy as np
import torch

from cagekit.coords import bind
from cagekit.deformation import DeformResult, _as_pair
from cagekit.deformation import deform as optimise
from cagekit.geometry import normalize
from cagekit.metrics import surface_samples
from cagekit_learn.networks import NeuralCages

__all__ = ["predict", "deform_with_model"]


def predict(model: NeuralCages, source_points, target_points) -> tuple[np.ndarray, np.ndarray]:
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


def deform_with_model(model: NeuralCages, source, target, *, points: int | None = None,
                      seed: int = 0, refine: bool = False, **refine_options) -> DeformResult:
    """Deform ``source`` to take ``target``'s shape with a trained model.

    Parameters
    ----------
    model : NeuralCages
        From :func:`cagekit_learn.train.load_model`.
    source, target : (V, F) pairs, trimesh objects or (n, 3) arrays
        As :func:`cagekit.deform` takes them.
    points : int, optional
        Samples of each shape fed to the network; default: the number it was trained with
        (1,024 unless configured otherwise), which the caller passes.
    seed : int, default 0
        Seed of the samples.
    refine : bool, default False
        Then optimise the cage per pair (:func:`cagekit.deform` with the predicted cage,
        started from the predicted deformation).
    **refine_options
        Passed to :func:`cagekit.deform` when refining (``symmetry``, ``weights``, ...).

    Returns
    -------
    DeformResult
        ``method`` is ``"learned"`` or ``"learned+refine"``; vertices in the target's
        frame and units; the cages in the source's and target's frames.
    """
    start = time.perf_counter()
    points = 1024 if points is None else int(points)
    Vs, Fs = _as_pair(source, "source")
    Vt, Ft = _as_pair(target, "target")
    Vs_n, cs, ss = normalize(Vs)
    Vt_n, ct, st = normalize(Vt)
    S = surface_samples(Vs_n, Fs, points, seed=seed)
    T = surface_samples(Vt_n, Ft, points, seed=seed + 1)
    cage_n, deformed_n = predict(model, S, T)
    cage_f = model.cage_f.cpu().numpy()
    cage_v, deformed_v = cage_n * ss + cs, deformed_n * st + ct
    if refine:
        result = optimise((Vs, Fs), (Vt, Ft), (cage_v, cage_f), seed=seed,
                          initial_cage=deformed_v, **refine_options)
        result.method = "learned+refine"
        result.seconds = time.perf_counter() - start
        return result
    binding = bind(Vs_n, cage_n, cage_f)
    X = binding.deform(deformed_n) * st + ct
    if not np.isfinite(X).all():
        raise FloatingPointError("the model produced NaN or inf positions")
    return DeformResult(vertices=X, faces=Fs, method="learned", cage_v=cage_v,
                        cage_f=binding.cage_f, deformed_cage_v=deformed_v,
                        seconds=time.perf_counter() - start)
