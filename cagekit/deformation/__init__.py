"""Per-pair cage deformation: move a source's cage so the source takes a target's shape.

- :mod:`~cagekit.deformation.terms`: the energy's terms, each with its exact gradient;
- :mod:`~cagekit.deformation.problem`: one pair's energy over the cage
  (:class:`CageProblem`) and :func:`solve`;
- :mod:`~cagekit.deformation.solver`: L-BFGS (nlopt) keeping the best point, Ctrl-C safe;
- :mod:`~cagekit.deformation.options`: :class:`DeformOptions`, checked in one place;
- :mod:`~cagekit.deformation.api`: :func:`deform` and :class:`DeformResult`.
"""

from cagekit.deformation.api import DeformResult, deform
from cagekit.deformation.options import (
    COORDS,
    METHODS,
    SAMPLES,
    SHAPE_POINTS,
    TARGET_KINDS,
    DeformOptions,
)
from cagekit.deformation.problem import (
    DEFAULT_WEIGHTS,
    CageEnergy,
    CageProblem,
    CageSolution,
    solve,
)

__all__ = ["COORDS", "CageEnergy", "CageProblem", "CageSolution", "DEFAULT_WEIGHTS",
           "DeformOptions", "DeformResult", "METHODS", "SAMPLES", "SHAPE_POINTS",
           "TARGET_KINDS", "deform", "solve"]
