"""``DeformOptions``: how :func:`cagekit.deform` works, checked in one place.

The method, the energy's terms and their sampling, and the solver's budget of one
deformation; :func:`cagekit.deform`, :meth:`cagekit.deformation.CageProblem.create` and the
learned mode's refinement take them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from cagekit.deformation.terms import AXES
from cagekit.errors import InputError

__all__ = ["COORDS", "DeformOptions", "METHODS", "REFERENCES", "SAMPLES", "SHAPE_POINTS",
           "TARGET_KINDS"]

METHODS = ("cage", "scale", "nricp")
#: the coordinates the energy takes (Green's through their faces' terms, exactly)
COORDS = ("mvc", "green")
TARGET_KINDS = ("full", "partial")
REFERENCES = ("source", "aligned")
#: samples of each surface (Chamfer) and vertices of the shape terms. On 39 real furniture
#: pairs 250 shape vertices gave the figures of 500 in 0.8 of the time; 1,000 samples
#: did too on those pairs, but doubled the error on a scaled copy of the source (1.4% of
#: its size against 0.7%: Chamfer's sampling noise), so 2,000 are kept
#: (docs/benchmarks.md, "Per-pair deformation")
SAMPLES = 2000
SHAPE_POINTS = 250


@dataclass(frozen=True)
class DeformOptions:
    """How :func:`cagekit.deform` works: the method, the energy's terms and the solver's budget.

    Every field is checked when the options are made (:class:`~cagekit.errors.InputError`
    for a bad one), so a wrong option fails before any work.

    Attributes
    ----------
    method : {"cage", "scale", "nricp"}, default "cage"
        ``cage``: the energy of :mod:`cagekit.deformation.problem`, minimised over the
        cage. ``scale``: the source's bounding box mapped onto the target's (the paper's
        simplest baseline). ``nricp``: ``trimesh.registration.nricp_amberg`` with its
        defaults, started from the box-aligned source in the paper's frame (the same start
        as ``cage``).
    symmetry : {"x", "y", "z"} or None
        Axis normal to the source's plane of symmetry; adds the symmetry term.
    weights : mapping of str to float, optional
        Overrides of :data:`~cagekit.deformation.problem.DEFAULT_WEIGHTS` (``chamfer``,
        ``landmarks``, ``p2f``, ``normal``, ``symmetry``, ``cage``, ``parts``,
        ``detail``); ``result.weights`` holds those used.
    faces : int, default 200
        Face budget of the fitted cage when no cage is given.
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
        their straight lines), or the source and its cage as given (the paper's choice:
        any stretch costs, so dCotLap, which charges for stretch, is lower, but parts
        bend where the target's proportions differ; the cage weight then defaults to 1,
        not 0.3). docs/benchmarks.md ("Per-pair deformation") has both on 20 pairs.
    coords : {"mvc", "green"}, default "mvc"
        The coordinates that bind the source to its cage (:func:`cagekit.bind`); with
        ``"green"`` the energy's gradient goes through the faces' normals and stretch
        factors exactly.
    seed : int, default 0
    check : bool, default True
        Refuse a given cage that intersects itself (as :func:`cagekit.bind`); False skips
        that test (a network's predicted cage, which may fold).
    target_kind : {"full", "partial"}, default "full"
        ``"partial"``: the target is a scan seen from one side; method ``cage`` aligns
        with :func:`cagekit.deformation.terms.partial_chamfer_loss` (every scanned point
        onto the source, the source onto the scan at a tenth of the weight), so the
        source's unseen side is not squashed onto the seen one; every method's box
        alignment keeps each axis's stretch at least the median of the three
        (:func:`cagekit.geometry.alignment.partial_box_scale`: the scan is shallow along
        the view).

    Examples
    --------
    >>> DeformOptions(method="scale", symmetry="x").symmetry
    'x'
    >>> DeformOptions(coords="harmonic")
    Traceback (most recent call last):
    ...
    cagekit.errors.InputError: deform takes coords mvc, green, got 'harmonic'
    """

    method: str = "cage"
    symmetry: str | None = None
    weights: Mapping[str, float] | None = None
    faces: int = 200
    samples: int = SAMPLES
    shape_points: int = SHAPE_POINTS
    max_evaluations: int = 60
    tolerance: float = 1e-7
    reference: str = "aligned"
    coords: str = "mvc"
    seed: int = 0
    check: bool = True
    target_kind: str = "full"

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise InputError(f"unknown method {self.method!r}; available: "
                             f"{', '.join(METHODS)}")
        if self.reference not in REFERENCES:
            raise InputError(f"reference must be one of {', '.join(REFERENCES)}, got "
                             f"{self.reference!r}")
        if self.symmetry is not None and self.symmetry not in AXES:
            raise InputError(f"symmetry must be x, y, z or None, got {self.symmetry!r}")
        if self.coords not in COORDS:
            raise InputError(f"deform takes coords {', '.join(COORDS)}, got {self.coords!r}")
        if self.target_kind not in TARGET_KINDS:
            raise InputError(f"target_kind must be full or partial, got {self.target_kind!r}")
        for name in ("samples", "shape_points", "max_evaluations"):
            if int(getattr(self, name)) < 1:
                raise InputError(f"{name} must be at least 1, got {getattr(self, name)}")
