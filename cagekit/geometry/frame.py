"""A shape's normalised frame: the one place where shapes go to unit size and back.

Every algorithm works on shapes moved into a frame (bounding-box centre at the origin,
divided by a scale) and hands results back in the user's own frame and units. The paper's
frame (docs/architecture.md, section 4) divides by the largest half-extent;
:func:`fit_cage`, whose tolerances are fractions of the bounding-box diagonal, divides by
the diagonal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cagekit.errors import InputError
from cagekit.geometry import as_vertices

__all__ = ["Frame", "MAX_SPREAD", "MIN_EXTENT", "bounding_box", "bounding_box_diagonal",
           "check_no_stray_vertex", "pair_frames"]

#: smallest extent a shape may have: below it, differences of coordinates are subnormal
#: numbers and lose digits (``2**52`` times the smallest normal float64, about 1e-292)
MIN_EXTENT = float(np.finfo(np.float64).tiny * 2.0**52)

UNITS = ("half_extent", "diagonal")

#: a vertex farther than this many times the typical vertex's distance from the shape's
#: median point is a stray (:func:`check_no_stray_vertex`): in the shape's unit frame the
#: rest would shrink below float32's resolution
MAX_SPREAD = 1e6


def _vertices(V) -> np.ndarray:

    return as_vertices(V)


@dataclass(frozen=True)
class Frame:
    """``unit = (world - centre) / scale``.

    Attributes
    ----------
    centre : (3,) float64
    scale : float
        Positive and finite.

    Examples
    --------
    >>> f = Frame.of([[0, 0, 0], [4, 2, 0]])
    >>> f.centre.tolist(), f.scale, f.to_unit([[4, 2, 0]]).tolist()
    ([2.0, 1.0, 0.0], 2.0, [[1.0, 0.5, 0.0]])
    """

    centre: np.ndarray
    scale: float

    def __post_init__(self):
        centre = np.asarray(self.centre, dtype=np.float64)
        if centre.shape != (3,) or not np.isfinite(centre).all():
            raise InputError(f"a frame's centre must be 3 finite numbers, got {centre}")
        scale = float(self.scale)
        if not (np.isfinite(scale) and scale > 0.0):
            raise InputError(f"a frame's scale must be finite and positive, got {scale}")
        object.__setattr__(self, "centre", centre)
        object.__setattr__(self, "scale", scale)

    @classmethod
    def of(cls, V: ArrayLike, unit: str = "half_extent", name: str | None = None) -> Frame:
        """The frame of a shape: its bounding-box centre and, as the unit, its largest
        half-extent (the paper's, default) or its diagonal (``unit="diagonal"``).

        Raises :class:`~cagekit.errors.InputError` for a shape whose extent is zero,
        overflows or cannot be resolved (:func:`bounding_box`); ``name`` (``"the
        source"``) starts the message, so that a caller can tell which shape it was.
        """
        if unit not in UNITS:
            raise InputError(f"unit must be one of {', '.join(UNITS)}, got {unit!r}")
        try:
            centre, extent = bounding_box(V)
        except InputError as exc:
            if name is None:
                raise
            raise InputError(f"{name}: {exc.problem}", exc.path) from None
        if unit == "diagonal":
            return cls(centre, bounding_box_diagonal(extent))
        return cls(centre, float(0.5 * np.max(extent)))

    def to_unit(self, X: ArrayLike) -> np.ndarray:
        """World points (n, 3) -> points in this frame, float64."""
        return (_vertices(X) - self.centre) / self.scale

    def to_world(self, X: ArrayLike) -> np.ndarray:
        """Points in this frame (n, 3) -> world points, float64."""
        return _vertices(X) * self.scale + self.centre


def bounding_box(V: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Centre and extent of a shape's bounding box, checked to be resolvable in float64.

    Parameters
    ----------
    V : array_like, shape (n, 3), float
        Vertex positions.

    Returns
    -------
    center : numpy.ndarray, shape (3,), float64
    extent : numpy.ndarray, shape (3,), float64
        ``max - min`` per axis; its largest entry is finite and at least
        :data:`MIN_EXTENT`.

    Raises
    ------
    InputError
        All points coincide, the extent overflows, or it is so small (below
        :data:`MIN_EXTENT`) that differences of coordinates lose digits.

    Examples
    --------
    >>> c, e = bounding_box([[0, 0, 0], [4, 2, 0]])
    >>> c.tolist(), e.tolist()
    ([2.0, 1.0, 0.0], [4.0, 2.0, 0.0])
    """
    V = _vertices(V)
    lo, hi = V.min(axis=0), V.max(axis=0)
    with np.errstate(over="ignore", invalid="ignore"):
        extent = hi - lo
    largest = float(np.max(extent))
    if largest == 0.0:
        raise InputError("all points of the shape coincide (zero extent)")
    if not np.isfinite(largest):
        raise InputError("the shape's extent overflows float64 (coordinates too large)")
    if largest < MIN_EXTENT:
        raise InputError(f"the shape's extent ({largest:.3g}) is too small to resolve in "
                         "float64 (coordinates below about 1e-292 apart)")
    # 0.5 lo + 0.5 hi: bit for bit 0.5 (lo + hi), without its overflow near 1e308
    return 0.5 * lo + 0.5 * hi, extent


def check_no_stray_vertex(V: ArrayLike, name: str | None = None) -> None:
    """Refuse a shape whose bounding box a few far-away vertices make.

    A vertex more than :data:`MAX_SPREAD` times as far from the vertices' median point as
    the median vertex is, is a stray (a typo in a file, an unset coordinate): the shape's
    unit frame would be its box, and every other vertex would collapse into a speck.

    Parameters
    ----------
    V : (n, 3) array_like of float
    name : str, optional
        Starts the message (``"the target"``), as in :meth:`Frame.of`.

    Raises
    ------
    InputError
        Such a vertex, naming its index and how far it is. Nothing is compared when the
        typical distance is zero (most vertices at one point).

    Examples
    --------
    >>> V = np.random.default_rng(0).random((50, 3))
    >>> check_no_stray_vertex(V)
    >>> V[7] = 1e38
    >>> try:
    ...     check_no_stray_vertex(V)
    ... except InputError as exc:
    ...     print(exc.problem[:37])
    vertex 7 lies 3e+38 times as far from
    """
    V = _vertices(V)
    with np.errstate(over="ignore", invalid="ignore"):
        offset = V - np.median(V, axis=0)
        # hypot squares nothing: no overflow for a far stray, no underflow for the rest
        distance = np.hypot(np.hypot(offset[:, 0], offset[:, 1]), offset[:, 2])
    typical = float(np.median(distance))
    far = int(np.argmax(distance))
    if typical > 0.0 and not distance[far] <= MAX_SPREAD * typical:
        with np.errstate(over="ignore"):
            ratio = distance[far] / typical
        start = f"{name}: " if name else ""
        raise InputError(f"{start}vertex {far} lies {ratio:.1g} times as far from the shape's "
                         f"median point as its typical vertex (more than {MAX_SPREAD:.0e}): "
                         "a stray vertex makes the shape's box, and the rest would collapse")


def pair_frames(Vs: ArrayLike, Vt: ArrayLike) -> tuple[Frame, Frame]:
    """The paper's unit frames of a source and a target, each checked for a stray vertex.

    Parameters
    ----------
    Vs, Vt : (n, 3), (k, 3) array_like of float

    Returns
    -------
    (Frame, Frame)
        The source's and the target's (:meth:`Frame.of`).

    Raises
    ------
    InputError
        As :meth:`Frame.of` and :func:`check_no_stray_vertex`, the message starting
        "the source" or "the target".

    Examples
    --------
    >>> fs, ft = pair_frames([[0, 0, 0], [2, 2, 2]], [[0, 0, 0], [1, 4, 1]])
    >>> fs.scale, ft.scale
    (1.0, 2.0)
    """
    frames = []
    for V, name in ((Vs, "the source"), (Vt, "the target")):
        frames.append(Frame.of(V, name=name))
        check_no_stray_vertex(V, name=name)
    return frames[0], frames[1]


def bounding_box_diagonal(extent: ArrayLike) -> float:
    """Length of a bounding box's diagonal from its extent, without overflow or underflow.

    Parameters
    ----------
    extent : array_like, shape (3,), float
        As :func:`bounding_box` returns it.

    Returns
    -------
    float

    Examples
    --------
    >>> round(bounding_box_diagonal([1e300, 1e300, 0.0]) / 1e300, 9)  # sqrt(2), no overflow
    1.414213562
    """
    extent = np.asarray(extent, dtype=np.float64)
    largest = float(np.max(extent))
    with np.errstate(over="ignore", under="ignore"):
        plain = float(np.linalg.norm(extent))
    if np.isfinite(plain) and plain >= largest:  # no overflow or underflow: the plain norm
        return plain
    return largest * float(np.linalg.norm(extent / largest))
