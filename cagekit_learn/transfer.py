"""The learned template cage of deformation transfer: a fixed-source network predicts the
template's cage in each example pose (``cagekit transfer --model``), in place of the
per-pair fit of :func:`cagekit.transfer.template_cage_classical`."""

from __future__ import annotations

import os

import numpy as np
from numpy.typing import ArrayLike

from cagekit.errors import InputError
from cagekit.geometry import as_vertices
from cagekit.geometry.frame import Frame
from cagekit.typed import Vertices
from cagekit_learn.inference import predict_cages
from cagekit_learn.networks import NeuralCages

__all__ = ["check_model", "template_cage_learned"]


def check_model(model: NeuralCages, template_v: ArrayLike, cage_v: ArrayLike,
                path: str | os.PathLike | None = None) -> None:
    """Raise :class:`InputError` (naming ``path``) unless ``model`` was trained with
    ``template_v`` as its fixed source and ``cage_v`` as its fixed cage."""
    config = model.config
    if config.fixed_cage_v is None or getattr(config, "fixed_source_points", None) is None:
        raise InputError("the model was not trained with a fixed source and source cage "
                         "(cagekit train --fixed-source TEMPLATE --source-cage CAGE)", path)
    frame = Frame.of(template_v)
    cs, ss = frame.centre, frame.scale
    expected = (as_vertices(cage_v, "cage_v") - cs) / ss
    trained = np.asarray(config.fixed_cage_v, dtype=np.float64)
    if trained.shape != expected.shape or not np.allclose(trained, expected, atol=1e-6):
        raise InputError("the model was trained with another template cage (or another "
                         "template)", path)


def template_cage_learned(model: NeuralCages, template_v: ArrayLike, cage_v: ArrayLike,
                          pose: tuple[ArrayLike, ArrayLike]) -> Vertices:
    """The template's deformed cage ``C_(s->t)`` predicted by a fixed-source network.

    Parameters
    ----------
    model : cagekit_learn.networks.NeuralCages
        Trained with ``cagekit train --fixed-source TEMPLATE --source-cage CAGE``.
    template_v : (n_s, 3) array_like of float
        The template in rest pose (the model's fixed source).
    cage_v : (k, 3) array_like of float
        ``C_s``; must be the cage the model was trained with.
    pose : (V, F) pair
        The template in the target pose; sampled at the training's vertex rows when it
        has the trained template's vertex count and the model was trained with them
        (L2), otherwise on its surface.

    Returns
    -------
    (k, 3) float64
        ``C_(s->t)`` in the pose's frame.

    Raises
    ------
    InputError
        The model has no fixed source or was trained with another cage.
    """
    check_model(model, template_v, cage_v)
    fixed = model.config.fixed_source_points
    assert fixed is not None  # check_model refuses a model without one
    points = len(fixed)
    return predict_cages(model, np.asarray(template_v, np.float64), None, *pose,
                         points=points)[1]
