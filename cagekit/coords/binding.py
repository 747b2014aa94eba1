"""Binding points to a cage: compute coordinates once, deform many times."""

from __future__ import annotations

import warnings
from typing import Literal, overload

import numba
import numpy as np
from numpy.typing import ArrayLike

from cagekit.cage import cage_encloses, check_cage, distance_in_diagonals, winding_numbers
from cagekit.cage.placement import placement_hint
from cagekit.coords.green import FaceTerms, green_coordinates_and_plan
from cagekit.coords.mvc import FAR_BLEND, mean_value_coordinates, mvc_and_winding
from cagekit.errors import InputError, OutsideCageError, OutsideCageWarning
from cagekit.typed import Faces, Floats, Vertices

__all__ = ["CageBinding", "GreenBinding", "bind", "warn_outside", "METHODS"]

METHODS = ("mvc", "green")


@numba.njit(parallel=True, cache=True)
def _weights_times_vertices(weights, vertices):
    """``weights @ vertices`` for (n, k) x (k, 3): a row-parallel loop, about twice as fast
    as BLAS for this tall-skinny shape, and the same sum order for every row."""
    n, k = weights.shape
    out = np.empty((n, 3))
    for i in numba.prange(n):
        x = 0.0
        y = 0.0
        z = 0.0
        for j in range(k):
            w = weights[i, j]
            x += w * vertices[j, 0]
            y += w * vertices[j, 1]
            z += w * vertices[j, 2]
        out[i, 0] = x
        out[i, 1] = y
        out[i, 2] = z
    return out


class CageBinding:
    """Points written as generalised barycentric coordinates of a cage's vertices.

    Attributes
    ----------
    weights : (n, k) float64
        Row ``i`` holds the coordinates of point ``i``; rows sum to one.
    cage_v : (k, 3) float64
        The cage the points were bound to.
    cage_f : (m, 3) int64
        Its faces, oriented outward.
    method : str
        ``"mvc"``: what :func:`bind` returns for it (Green coordinates give a
        :class:`GreenBinding`).
    winding : (n,) float64 or None
        The cage's winding number at each point when :func:`bind` was asked for it
        (``winding=True``), else None.
    """

    def __init__(self, weights: Floats, cage_v: Vertices, cage_f: Faces, method: str,
                 winding: Floats | None = None) -> None:
        self.weights = weights
        self.cage_v = cage_v
        self.cage_f = cage_f
        self.method = method
        self.winding = winding

    @property
    def n_points(self) -> int:
        """Number of bound points."""
        return self.weights.shape[0]

    def deform(self, new_cage_v: ArrayLike) -> Vertices:
        """Positions of the bound points for moved cage vertices.

        Raises :class:`cagekit.InputError` for a cage of the wrong shape, with NaN or inf,
        or so large that the positions overflow float64.

        Parameters
        ----------
        new_cage_v : (k, 3) array_like of float
            The cage's vertices after moving them, in the same order.

        Returns
        -------
        (n, 3) float64
            ``weights @ new_cage_v``.

        Examples
        --------
        >>> from cagekit.cage.shapes import box_cage
        >>> v, f = box_cage()
        >>> b = bind([[0.5, 0.0, 0.0]], v, f)
        >>> (b.deform(2 * v).round(12) + 0.0).tolist()  # + 0.0: no negative zero
        [[1.0, 0.0, 0.0]]
        """
        new = _checked_cage(new_cage_v, self.cage_v.shape)
        return _finite_positions(_weights_times_vertices(self.weights, new))

    def encloses(self, points: ArrayLike) -> bool:
        """Whether the given points (usually the bound ones) all lie inside the cage."""
        return cage_encloses(points, self.cage_v, self.cage_f)


class GreenBinding:
    """Points written in Green coordinates of a cage (:mod:`cagekit.coords.green`).

    Attributes
    ----------
    phi : (n, k) float64
        Vertex coordinates; rows sum to one.
    psi : (n, m) float64
        Face coordinates (in the cage's units).
    cage_v : (k, 3) float64
        The cage the points were bound to.
    cage_f : (m, 3) int64
        Its faces, oriented outward.
    method : str
        ``"green"``.
    winding : (n,) float64 or None
        As :attr:`CageBinding.winding`.
    """

    def __init__(self, phi: Floats, psi: Floats, cage_v: Vertices, cage_f: Faces,
                 winding: Floats | None = None) -> None:

        self.phi, self.psi = phi, psi
        self.cage_v, self.cage_f = cage_v, cage_f
        self.method = "green"
        self.winding = winding
        self._face_terms = FaceTerms(cage_v, cage_f)

    @property
    def n_points(self) -> int:
        """Number of bound points."""
        return self.phi.shape[0]

    def deform(self, new_cage_v: ArrayLike) -> Vertices:
        """Positions of the bound points for moved cage vertices.

        ``phi @ new_cage_v + psi @ (s * n')``, with ``n'`` the moved faces' unit normals
        and ``s`` their stretch factors (:class:`cagekit.coords.green.FaceTerms`).
        Raises :class:`cagekit.InputError` as :meth:`CageBinding.deform` does, and for a
        moved cage with a face of zero area (its normal is undefined).

        Parameters
        ----------
        new_cage_v : (k, 3) array_like of float

        Returns
        -------
        (n, 3) float64

        Examples
        --------
        >>> from cagekit.cage.shapes import box_cage
        >>> v, f = box_cage()
        >>> b = bind([[0.5, 0.0, 0.0]], v, f, method="green")
        >>> (b.deform(2 * v + 1).round(12) + 0.0).tolist()  # similarities are exact
        [[2.0, 1.0, 1.0]]
        """
        new = _checked_cage(new_cage_v, self.cage_v.shape)
        with np.errstate(divide="ignore", invalid="ignore"):
            scaled = self._face_terms(new)  # a face of zero area has no normal: NaN
        if not np.all(np.isfinite(scaled)):
            raise InputError("the deformed cage has a face of zero area: Green coordinates "
                             "need its normal")
        return _finite_positions(_weights_times_vertices(self.phi, new)
                                 + _weights_times_vertices(self.psi,
                                                           np.ascontiguousarray(scaled)))

    encloses = CageBinding.encloses


def _finite_positions(out: np.ndarray) -> np.ndarray:
    """Deformed positions, refused when they overflowed float64."""
    if not np.all(np.isfinite(out)):
        raise InputError("the deformed positions overflow float64 (cage or points too "
                         "large)")
    return out


def _checked_cage(new_cage_v, shape) -> np.ndarray:
    """A moved cage as a contiguous float64 array of the bound cage's shape, all finite."""
    new = np.asarray(new_cage_v, dtype=np.float64)
    if new.shape != shape:
        raise InputError(f"deformed cage has shape {new.shape}, the bound cage has "
                         f"{shape}: vertex counts must match")
    if not np.all(np.isfinite(new)):
        raise InputError("deformed cage has NaN or inf coordinates")
    return np.ascontiguousarray(new)


@overload
def bind(points: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike,
         method: Literal["mvc"] = "mvc", *, check: bool = True,
         winding: bool = False) -> CageBinding: ...
@overload
def bind(points: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike,
         method: Literal["green"], *, check: bool = True,
         winding: bool = False) -> GreenBinding: ...
@overload
def bind(points: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike, method: str = "mvc", *,
         check: bool = True, winding: bool = False) -> CageBinding | GreenBinding: ...


def bind(points: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike, method: str = "mvc", *,
         check: bool = True, winding: bool = False) -> CageBinding | GreenBinding:
    """Compute the coordinates of points with respect to a cage.

    Parameters
    ----------
    points : (n, 3) array_like of float
        Points to bind (mesh vertices or a point cloud). They may lie outside the cage:
        MVC is defined everywhere off the cage (weights may then be negative); see
        :func:`cagekit.cage_encloses` to check.
    cage_v : (k, 3) array_like of float
        Cage vertices.
    cage_f : (m, 3) array_like of int
        Cage faces: closed and 2-manifold. A consistently inward cage is flipped; an open,
        non-manifold or inconsistently oriented one raises :class:`cagekit.CageError`, and
        so does (with ``check``) one that intersects itself.
    method : {"mvc", "green"}, default "mvc"
        Mean value coordinates (Ju, Schaefer & Warren 2005): a :class:`CageBinding`,
        affine-invariant. Green coordinates (Lipman, Levin & Cohen-Or 2008): a
        :class:`GreenBinding`, exact for similarities and quasi-conformal otherwise
        (details keep their proportions under stretch); points outside the cage take the
        extension across their closest face (:mod:`cagekit.coords.green`).
    check : bool, default True
        Run the exact self-intersection test on the cage (about a millisecond per 100
        faces). False skips it, for speed, when the cage is known to be free of it (a
        cage from :func:`cagekit.fit_cage`) or folds on purpose; the checks MVC itself
        needs (closed, 2-manifold, oriented) always run.
    winding : bool, default False
        Also keep the cage's winding number at each point (``binding.winding``, for
        :func:`warn_outside`). MVC computes it in the same pass
        (:func:`cagekit.coords.mvc.mvc_and_winding`: 3-5% more time, where libigl's
        separate pass costs half the binding's or more); Green coordinates have it anyway
        (:attr:`cagekit.coords.green.EvaluationPlan.winding`).

    Returns
    -------
    CageBinding or GreenBinding
        ``"mvc"``: a :class:`CageBinding` (``weights``, ``(n, k)``); ``"green"``: a
        :class:`GreenBinding` (``phi``, ``(n, k)``, and ``psi``, ``(n, m)``); both have
        ``deform``, ``encloses``, ``n_points`` and ``method``. Type checkers see which
        from a literal ``method``.

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> b = bind(np.zeros((1, 3)), v, f)
    >>> b.weights.shape, round(float(b.weights.sum()), 12)
    ((1, 8), 1.0)
    """

    if method not in METHODS:
        raise InputError(f"unknown coordinates {method!r}; available: {', '.join(METHODS)}")
    v = np.ascontiguousarray(cage_v, dtype=np.float64)
    faces = check_cage(v, cage_f, intersections=check)
    if method == "green":
        phi, psi, plan = green_coordinates_and_plan(points, v, faces)
        return GreenBinding(phi, psi, v, faces, plan.winding if winding else None)
    if winding:
        weights, wn = mvc_and_winding(points, v, faces, check=False)
        return CageBinding(weights, v, faces, method, wn)
    weights = np.asarray(mean_value_coordinates(points, v, faces, check=False), np.float64)
    return CageBinding(weights, v, faces, method)


def warn_outside(points: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike, *,
                 shape: str = "the shape", cage: str = "the cage",
                 refuse_above: float = 1.0, winding: ArrayLike | None = None) -> float:
    """Warn when points lie outside their cage, with the share outside and its likely cause.

    Every command that binds a shape calls it, so they all warn alike. Points outside a
    cage are extrapolated by its coordinates (MVC is defined there); those beyond
    :data:`cagekit.coords.mvc.FAR_BLEND` ``[0]`` cage diagonals follow the cage's affine
    fit (see :mod:`cagekit.coords.mvc`) and are counted in the message. When more than half
    of the points are outside and the bounding boxes suggest why (a cage in other units,
    another origin), the message says so (:func:`cagekit.cage.placement.placement_hint`).

    Parameters
    ----------
    points : (n, 3) array_like of float
    cage_v : (k, 3) array_like of float
    cage_f : (m, 3) array_like of int
        Outward faces (:func:`cagekit.check_cage`).
    shape, cage : str
        How the message names them (file names on the command line).
    refuse_above : float, default 1.0
        Share of points outside above which :class:`~cagekit.errors.OutsideCageError` is
        raised instead of the warning (the command line refuses more than half, see
        ``--allow-outside``); 1 never refuses.
    winding : (n,) array_like of float, optional
        The cage's winding numbers at the points when known already (``bind(...,
        winding=True).winding``); computed by libigl otherwise.

    Returns
    -------
    float
        The share of points outside (winding number below 0.5), 0 when none is: then
        nothing is issued. Otherwise an :class:`~cagekit.errors.OutsideCageWarning`.

    Examples
    --------
    >>> import warnings
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     share = warn_outside([[0.0, 0, 0], [5.0, 0, 0]], v, f)
    >>> share, str(caught[0].message)
    (0.5, '50% of the shape (1 of 2 points) lies outside the cage: extrapolated')
    >>> warn_outside(9 * v, v, f, refuse_above=0.5)  # a cage a little larger than the shape
    Traceback (most recent call last):
    ...
    cagekit.errors.OutsideCageError: 100% of the shape (8 of 8 points) lies outside the cage: \
the shape is 9x the size of the cage: different units (the shape in mm, the cage in cm?)
    """

    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if winding is None:
        winding = winding_numbers(points, cage_v, cage_f)
    elif np.shape(winding) != (len(points),):
        raise InputError(f"winding numbers of shape {np.shape(winding)} for {len(points)} "
                         "points")
    outside = np.asarray(winding) < 0.5 - 1e-9
    count = int(outside.sum())
    if not count:
        return 0.0
    share = count / len(points)
    hint = placement_hint(points, cage_v, shape=shape, cage=cage) if share > 0.5 else None
    text = (f"{100 * share:.3g}% of {shape} ({count:,} of {len(points):,} points) lies "
            f"outside {cage}")
    if share > refuse_above:
        raise OutsideCageError(text + (f": {hint}" if hint else ""))
    text += ": extrapolated"
    far = int((distance_in_diagonals(points[outside], cage_v) > FAR_BLEND[0]).sum())
    if far:
        text += (f"; {far:,} of them more than {FAR_BLEND[0]:g} cage diagonals away follow "
                 "the cage's affine fit")
    if hint:
        text += f"; {hint}"
    warnings.warn(OutsideCageWarning(text), stacklevel=2)
    return share
