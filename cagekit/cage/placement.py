"""Why a shape lies outside its cage: sizes in other units, or centres far apart.

A cage made in centimetres and applied to a mesh in millimetres leaves the mesh 10x the
cage's size and almost all of it outside; a cage exported from a scene with another origin
leaves the two apart. :func:`placement_hint` compares the bounding boxes of the shape and
the cage and names the likely cause, for the messages of
:func:`cagekit.coords.binding.warn_outside` (every command that binds a shape to a given
cage). It only reads the boxes: the outside test itself is the winding number's.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["placement_hint", "UNIT_RATIOS", "SIZE_RATIO", "OFFSET"]

#: size ratios of unit pairs a shape and its cage may have been made in, with the smaller
#: and the larger unit (a mesh in mm is 10x its cage in cm)
UNIT_RATIOS = ((10.0, "mm", "cm"), (100.0, "cm", "m"), (1000.0, "mm", "m"),
               (2.54, "cm", "inches"), (25.4, "mm", "inches"), (39.37, "inches", "m"),
               (12.0, "inches", "feet"), (30.48, "cm", "feet"), (304.8, "mm", "feet"),
               (3.281, "feet", "m"))
#: a cage's diagonal is usually about this much larger than its shape's: a mesh in mm in a
#: cage in cm measures about 9x, a cage in mm around a mesh in cm about 11x
_CAGE_MARGIN = 1.1
#: a size ratio (corrected by the margin) within this factor of a unit ratio is named after
#: it (the closest one)
_UNIT_TOLERANCE = 1.25
#: sizes (bounding-box diagonals) further apart than this factor are reported
SIZE_RATIO = 1.5
#: bounding-box centres further apart than this, in cage diagonals, are reported (when
#: the sizes agree)
OFFSET = 0.25


def placement_hint(points: ArrayLike, cage_v: ArrayLike, *, shape: str = "the shape",
                   cage: str = "the cage") -> str | None:
    """The likely reason a shape lies outside its cage, or None when the boxes agree.

    Sizes are bounding-box diagonals. When they differ by more than :data:`SIZE_RATIO`,
    the hint says by how much, and names the units when the ratio is close to one of
    :data:`UNIT_RATIOS` (10, 100, 1000, 2.54, 25.4...); when they agree but the centres
    are more than :data:`OFFSET` cage diagonals apart, it gives the distance.

    Parameters
    ----------
    points : (n, 3) array_like of float
        The shape's points.
    cage_v : (k, 3) array_like of float
        The cage's vertices.
    shape, cage : str
        How the hint names them (file names on the command line).

    Returns
    -------
    str or None
        One clause, e.g. ``"the shape is 10x the size of the cage: different units (the
        shape in mm, the cage in cm?)"``.

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> placement_hint(9.5 * v, v)
    'the shape is 9.5x the size of the cage: different units (the shape in mm, the cage in cm?)'
    >>> placement_hint(v + [10.0, 0.0, 0.0], v)
    'the shape is offset from the cage by 2.9 cage diagonals: a different origin?'
    >>> placement_hint(0.9 * v, v) is None
    True
    """
    if np.size(points) == 0:
        return None
    (shape_centre, shape_size), (cage_centre, cage_size) = _box(points), _box(cage_v)
    if not (cage_size > 0 and math.isfinite(shape_size) and math.isfinite(cage_size)):
        return None
    ratio = shape_size / cage_size
    if ratio > SIZE_RATIO or 0 < ratio < 1 / SIZE_RATIO:
        return _size_hint(ratio, shape, cage)
    with np.errstate(over="ignore", invalid="ignore"):
        offset = float(np.linalg.norm(shape_centre - cage_centre)) / cage_size
    if math.isfinite(offset) and offset > OFFSET:
        return (f"{shape} is offset from {cage} by {offset:.2g} cage diagonals: a different "
                "origin?")
    return None


def _box(points: ArrayLike) -> tuple[np.ndarray, float]:
    """Centre ``(3,)`` and diagonal of the bounding box of ``(n, 3)`` points."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    lo, hi = p.min(axis=0), p.max(axis=0)
    with np.errstate(over="ignore", invalid="ignore"):
        return 0.5 * lo + 0.5 * hi, float(np.hypot(np.hypot(*(hi - lo)[:2]), (hi - lo)[2]))


def _size_hint(ratio: float, shape: str, cage: str) -> str:
    """The clause for sizes that differ: the factor, and the units it suggests."""
    larger, smaller, factor = (shape, cage, ratio) if ratio > 1 else (cage, shape, 1 / ratio)
    units = _closest_units(factor * _CAGE_MARGIN if ratio > 1 else factor / _CAGE_MARGIN)
    times = f"{factor:,.0f}" if 100 <= factor < 1e7 else f"{factor:.3g}"  # 1,000, not 1e+03
    text = f"{larger} is {times}x the size of {smaller}: "
    if units is None:
        return text + "a different scale or different units?"
    small_unit, large_unit = units
    return text + f"different units ({larger} in {small_unit}, {smaller} in {large_unit}?)"


def _closest_units(factor: float) -> tuple[str, str] | None:
    """(smaller, larger) unit of the unit ratio closest to ``factor``, when within the
    tolerance."""
    distance, small, large = min((abs(math.log(factor / r)), s, big)
                                 for r, s, big in UNIT_RATIOS)
    return (small, large) if distance <= math.log(_UNIT_TOLERANCE) else None
