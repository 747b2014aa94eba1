"""Procedural shape families: chairs, tables and vases with fine detail, made from a seed.

Each shape draws its proportions from the documented ``*_RANGES`` with
``numpy.random.default_rng(seed)``, one draw per parameter in a fixed order; a keyword
replaces its drawn value without changing the others, and the same seed and keywords give
bit-identical arrays. Shapes are in metres, y up, standing on ``y = 0``, centred on the y
axis and mirror-symmetric about ``x = 0`` (chairs face +z). A shape is a union of possibly
overlapping parts (subdivided boxes, surfaces of revolution, tori), each a closed,
2-manifold, outward, vertex-disjoint component with near-equilateral or near-right
triangles (aspect ratio below about 4) and no degenerate one; the triangle size gives about
``4500 * resolution**2`` vertices. Detail: slats, spindles, rails and stretchers on chairs;
aprons, shaped legs and shelves on tables; hollow vases with rims, ridges, flutes, handles.

Examples
--------
>>> V, F = chair(seed=3)
>>> V.dtype, F.dtype, float(V[:, 1].min())
(dtype('float64'), dtype('int64'), 0.0)
>>> [len(list(family(name, 2))) for name in FAMILIES]
[2, 2, 2]
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np

from cagekit.typed import Faces, Vertices

__all__ = ["CHAIR_RANGES", "FAMILIES", "TABLE_RANGES", "VASE_RANGES", "chair", "family",
           "table", "vase"]

#: vertices of a shape at ``resolution=1`` (the triangle size is tuned to get near it)
TARGET_VERTICES = 4500

_Mesh = tuple[np.ndarray, np.ndarray]


# ------------------------------------------------------------------------- parameters


def _draw(rng: np.random.Generator, ranges: dict, given: dict) -> dict:
    """Draw every parameter (in ``ranges`` order, one draw each), then apply ``given``.

    A tuple ``(lo, hi)`` of floats is uniform on [lo, hi), of ints uniform over ``lo..hi``
    inclusive; a list is a uniform choice among its items (repeats weigh more).
    """
    unknown = sorted(set(given) - set(ranges))
    if unknown:
        raise TypeError(f"unknown parameter(s) {', '.join(unknown)}; "
                        f"known: {', '.join(ranges)}")
    drawn = {}
    for name, spec in ranges.items():
        if isinstance(spec, list):
            drawn[name] = spec[int(rng.integers(len(spec)))]
        elif all(isinstance(x, int) for x in spec):
            drawn[name] = int(rng.integers(spec[0], spec[1] + 1))
        else:
            drawn[name] = float(rng.uniform(spec[0], spec[1]))
    for name, value in given.items():
        spec = ranges[name]
        if isinstance(spec, list) and isinstance(spec[0], (str, bool)):
            if value not in spec:
                choices = ", ".join(map(repr, dict.fromkeys(spec)))
                raise ValueError(f"{name} must be one of {choices}, not {value!r}")
            value = type(spec[0])(value)
        elif all(isinstance(x, int) for x in spec):
            if int(value) != value or value < 0:
                raise ValueError(f"{name} must be an integer >= 0, not {value!r}")
            value = int(value)
        else:
            value = float(value)
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"{name} must be a positive number, not {value!r}")
        drawn[name] = value
    return drawn


def _resolution(resolution) -> float:
    value = float(resolution)
    if not np.isfinite(value) or value <= 0:
        raise ValueError(f"resolution must be a positive number, not {resolution!r}")
    return value


# ------------------------------------------------------------------------- primitives


def _even(x) -> int:
    return int(2 * np.ceil(np.asarray(x) / 2.0))


def _zip_rings(a, phase_a, b, phase_b, faces: list) -> None:
    """Triangles joining two closed rings of vertex ids (angles increasing), in order.

    Ring vertex ``j`` sits at angle ``phase + 2 pi j / len(ring)``; the strip advances on
    the ring whose next vertex comes first. A ring of one vertex is a pole.
    """
    na, nb = len(a), len(b)
    if na == 1:
        faces.extend((a[0], b[(j + 1) % nb], b[j]) for j in range(nb))
        return
    if nb == 1:
        faces.extend((a[i], a[(i + 1) % na], b[0]) for i in range(na))
        return
    i = j = 0
    step_a, step_b = 2 * np.pi / na, 2 * np.pi / nb
    while i < na or j < nb:
        next_a = phase_a + step_a * (i + 1)
        next_b = phase_b + step_b * (j + 1)
        if j == nb or (i < na and next_a <= next_b):
            faces.append((a[i % na], a[(i + 1) % na], b[j % nb]))
            i += 1
        else:
            faces.append((a[i % na], b[(j + 1) % nb], b[j % nb]))
            j += 1


def _outward(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """``F``, reversed if the closed mesh it describes has negative volume."""
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    return F if volume > 0 else np.ascontiguousarray(F[:, ::-1])


def _resample(points: np.ndarray, edge: float, bend: float = 0.3, finest: float = 0.25,
              grade: float = 0.35) -> np.ndarray:
    """Resample a dense, smooth polyline: spacing ``edge``, finer where it bends.

    The spacing is ``min(edge, bend / curvature)`` (about ``bend`` radians of turn per
    sample) but not below ``finest * edge``, and it changes gradually (by at most
    ``grade`` times the distance), so neighbouring samples are about equally far apart.
    Both ends are kept exactly.
    """
    d = np.diff(points, axis=0)
    length = np.hypot(d[:, 0], d[:, 1])
    s = np.concatenate([[0.0], np.cumsum(length)])
    heading = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    turn = np.abs(np.diff(heading))  # at interior points
    kappa = np.zeros(len(length))
    if len(turn):
        per_point = turn / (0.5 * (length[:-1] + length[1:]))
        kappa[:-1] = np.maximum(kappa[:-1], per_point)
        kappa[1:] = np.maximum(kappa[1:], per_point)
    h = edge / np.clip(kappa * edge / bend, 1.0, 1.0 / finest)
    mid = 0.5 * (s[:-1] + s[1:])
    for order in (range(1, len(h)), range(len(h) - 2, -1, -1)):  # grade the spacing
        for i in order:
            j = i - 1 if order.step == 1 else i + 1
            h[i] = min(h[i], h[j] + grade * abs(mid[i] - mid[j]))
    cum = np.concatenate([[0.0], np.cumsum(length / h)])
    n = max(1, int(np.ceil(cum[-1] - 1e-9)))
    targets = np.interp(np.linspace(0.0, cum[-1], n + 1), cum, s)
    out = np.stack([np.interp(targets, s, points[:, 0]),
                    np.interp(targets, s, points[:, 1])], axis=1)
    out[0], out[-1] = points[0], points[-1]
    return out


def _lathe(segments, edge: float, *, sections: int | None = None, min_sections=6,
           aspect: float = 1.5, modulate: Callable | None = None) -> _Mesh:
    """A closed surface of revolution about the y axis.

    Parameters
    ----------
    segments : list of (k, 2) arrays
        Dense, smooth pieces of the profile, as ``(radius, y)`` points; consecutive pieces
        share their end points (corners are kept). The profile starts and ends on the
        axis (radius 0) and has radius > 0 everywhere else.
    edge : float
        Longest profile spacing.
    sections : int, optional
        Vertices of every ring (even); by default each ring gets about its
        circumference / (``aspect`` x its profile spacing), at least ``min_sections``
        (an int, or ``min_sections(ring_index, radius, y) -> int``).
    modulate : callable, optional
        ``modulate(ring_index_in_profile, radius, y, theta) -> radius`` (flutes).
    """
    pieces = [_resample(segments[0], edge)]
    for seg in segments[1:]:
        pieces.append(_resample(seg, edge)[1:])
    profile = np.concatenate(pieces)
    r, y = profile[:, 0], profile[:, 1]
    k = len(profile)
    gaps = np.hypot(np.diff(r), np.diff(y))
    spacing = np.empty(k)
    spacing[0], spacing[-1] = gaps[0], gaps[-1]
    spacing[1:-1] = 0.5 * (gaps[:-1] + gaps[1:])
    if sections is not None:
        counts = np.full(k, int(sections))
    else:
        floor = [min_sections(i, r[i], y[i]) if callable(min_sections) else min_sections
                 for i in range(k)]
        counts = np.array([max(floor[i], _even(2 * np.pi * r[i] / (aspect * spacing[i])))
                           for i in range(k)])
        # no sudden jumps: neighbouring rings differ by a factor 1.5 at most
        for _ in range(2):
            for i in range(1, k):
                counts[i] = max(counts[i], _even(counts[i - 1] / 1.5))
            for i in range(k - 2, -1, -1):
                counts[i] = max(counts[i], _even(counts[i + 1] / 1.5))
    counts[0] = 1 if r[0] == 0 else counts[0]
    counts[-1] = 1 if r[-1] == 0 else counts[-1]
    vertices, rings, phases = [], [], []
    start = 0
    for i in range(k):
        n = int(counts[i])
        # staggered rings, symmetric end to end (a rod along x stays mirror-symmetric)
        phase = (np.pi / n) * (min(i, k - 1 - i) % 2) if n > 1 else 0.0
        theta = phase + 2 * np.pi * np.arange(n) / n
        radius = np.full(n, r[i]) if n > 1 else np.zeros(1)
        if modulate is not None and n > 1:
            radius = modulate(i, radius, y[i], theta)
        ring = np.stack([radius * np.cos(theta), np.full(n, y[i]), radius * np.sin(theta)],
                        axis=1)
        vertices.append(ring)
        rings.append(np.arange(start, start + n))
        phases.append(phase)
        start += n
    faces: list = []
    for i in range(k - 1):
        _zip_rings(rings[i], phases[i], rings[i + 1], phases[i + 1], faces)
    V = np.concatenate(vertices)
    F = np.asarray(faces, dtype=np.int64)
    return V, _outward(V, F)


def _bump(y, centre, width):
    """A smooth bump of height 1 at ``centre``, zero beyond ``centre +- width``."""
    u = np.clip((y - centre) / width, -1.0, 1.0)
    return np.cos(0.5 * np.pi * u) ** 2


def _line(p0, p1, n: int = 2) -> np.ndarray:
    return np.linspace(np.asarray(p0, dtype=np.float64), np.asarray(p1, dtype=np.float64), n)


def _arc(center, radius, a0, a1, n: int = 64) -> np.ndarray:
    t = np.linspace(a0, a1, n)
    return np.stack([center[0] + radius * np.cos(t), center[1] + radius * np.sin(t)], axis=1)


def _frame(direction) -> np.ndarray:
    """A rotation (det +1) taking +y to ``direction`` (exact for the coordinate axes)."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    axes = {(0, 1, 0): np.eye(3),
            (0, -1, 0): np.diag([1.0, -1.0, -1.0]),
            (1, 0, 0): np.array([[0.0, 1, 0], [-1, 0, 0], [0, 0, 1]]),
            (-1, 0, 0): np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]),
            (0, 0, 1): np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),
            (0, 0, -1): np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])}
    key = tuple(int(x) for x in np.round(d))
    if key in axes and np.allclose(d, key):
        return axes[key]
    helper = np.array([1.0, 0, 0]) if abs(d[0]) < 0.9 else np.array([0.0, 0, 1])
    u = np.cross(d, helper)
    u /= np.linalg.norm(u)
    w = np.cross(u, d)
    return np.stack([u, d, w], axis=1)  # columns: images of x, y, z


def _place(mesh: _Mesh, origin, direction=(0, 1, 0)) -> _Mesh:
    V, F = mesh
    R = _frame(direction)
    return V @ R.T + np.asarray(origin, dtype=np.float64), F


def _rod(p0, p1, radius: float, edge: float, sections: int = 8) -> _Mesh:
    """A closed round rod (cylinder with flat ends) from ``p0`` to ``p1``."""
    p0, p1 = np.asarray(p0, dtype=np.float64), np.asarray(p1, dtype=np.float64)
    length = float(np.linalg.norm(p1 - p0))
    step = min(edge, 3.0 * 2 * np.pi * radius / sections)
    profile = [_line((0, 0), (radius, 0)), _line((radius, 0), (radius, length)),
               _line((radius, length), (0, length))]
    return _place(_lathe(profile, step, sections=sections), p0, p1 - p0)


def _box(lo, hi, edge: float, taper: float = 1.0) -> _Mesh:
    """An axis-aligned box split into a grid of near-square cells on every side.

    The spacing along an axis is at most ``edge`` and at most 2.5 x the box's smallest
    other extent, so thin, long boxes get no slivers. ``taper`` < 1 shrinks the bottom
    (x and z about the centre, linearly in y) to that fraction: a tapered leg.
    """
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    size = hi - lo
    counts = []
    for axis in range(3):
        others = min(size[(axis + 1) % 3], size[(axis + 2) % 3])
        counts.append(max(1, int(np.ceil(size[axis] / min(edge, 2.5 * others) - 1e-9))))
    grids = [np.linspace(lo[a], hi[a], counts[a] + 1) for a in range(3)]
    shape = tuple(c + 1 for c in counts)
    boundary = np.zeros(shape, dtype=bool)
    for axis in range(3):
        index: list[slice | int] = [slice(None)] * 3
        for side in (0, -1):
            index[axis] = side
            boundary[tuple(index)] = True
    ids = np.full(shape, -1, dtype=np.int64)
    ids[boundary] = np.arange(int(boundary.sum()))
    i, j, k = np.nonzero(boundary)
    V = np.stack([grids[0][i], grids[1][j], grids[2][k]], axis=1)
    faces = []
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        for side, outward in ((0, False), (counts[axis], True)):
            index = [slice(None)] * 3
            index[axis] = side
            sheet = ids[tuple(index)]
            if u > v:  # the sheet's axes come in increasing order: put them as (u, v)
                sheet = sheet.T
            a, b = sheet[:-1, :-1].ravel(), sheet[1:, :-1].ravel()
            c, d = sheet[1:, 1:].ravel(), sheet[:-1, 1:].ravel()
            quads = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
            faces.append(quads if outward else quads[:, ::-1])
    F = np.concatenate(faces).astype(np.int64)
    if taper != 1.0:
        centre = 0.5 * (lo + hi)
        t = (V[:, 1] - lo[1]) / size[1]
        factor = (taper + (1.0 - taper) * t)[:, None]
        V[:, [0, 2]] = centre[[0, 2]] + (V[:, [0, 2]] - centre[[0, 2]]) * factor
    return V, _outward(V, F)


def _torus(centre, major: float, minor: float, edge: float, normal=(0, 0, 1)) -> _Mesh:
    """A torus around ``centre`` whose ring lies in the plane with the given normal."""
    m = max(8, _even(2 * np.pi * minor / edge))
    n = 4 * max(3, int(np.ceil(major / (1.6 * minor / m) / 4)))  # 4 | n: x-mirror symmetric
    rings, phases, vertices = [], [], []
    for i in range(n):
        u = 2 * np.pi * i / n
        phase = (np.pi / m) * (i % 2)
        v = phase + 2 * np.pi * np.arange(m) / m
        rho = major + minor * np.cos(v)
        # the ring lies in the x-y plane (axis z); rotated below
        vertices.append(np.stack([rho * np.cos(u), rho * np.sin(u), minor * np.sin(v)], 1))
        rings.append(np.arange(i * m, (i + 1) * m))
        phases.append(phase)
    faces: list = []
    for i in range(n):
        _zip_rings(rings[i], phases[i], rings[(i + 1) % n], phases[(i + 1) % n], faces)
    V = np.concatenate(vertices)
    F = np.asarray(faces, dtype=np.int64)
    # rotate so that z (the ring's axis) goes to `normal`: reuse _frame (y -> normal)
    to_y = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])  # z -> y, det +1
    R = _frame(normal) @ to_y
    V = V @ R.T + np.asarray(centre, dtype=np.float64)
    return V, _outward(V, F)


def _join(parts) -> _Mesh:
    vertices, faces, offset = [], [], 0
    for V, F in parts:
        vertices.append(V)
        faces.append(F + offset)
        offset += len(V)
    V = np.ascontiguousarray(np.concatenate(vertices), dtype=np.float64)
    F = np.ascontiguousarray(np.concatenate(faces), dtype=np.int64)
    return V, F


def _sized(build: Callable[[float], list], edge: float, resolution: float) -> _Mesh:
    """Build with triangle size ``edge``, re-tuned (deterministically) to the vertex target."""
    target = TARGET_VERTICES * resolution ** 2
    edge = edge / resolution
    for _ in range(4):
        parts = build(edge)
        n = sum(len(V) for V, _ in parts)
        if 0.8 * target <= n <= 1.25 * target:
            break
        edge *= float(np.clip(np.sqrt(n / target), 0.5, 2.0))
    return _join(parts)


# ----------------------------------------------------------------------------- chairs

CHAIR_RANGES = {
    "seat_width": (0.40, 0.60),
    "seat_depth": (0.38, 0.55),
    "seat_height": (0.40, 0.50),
    "seat_thickness": (0.03, 0.06),
    "back_height": (0.30, 0.55),
    "leg_thickness": (0.025, 0.05),
    "leg_style": ["square", "round"],
    "back_style": ["slats", "spindles", "ladder"],
    "back_count": (2, 7),
    "stretchers": [True, True, False],
}
"""Chair parameters and the ranges they are drawn from (metres; ints inclusive)."""


def chair(seed: int = 0, *, resolution: float = 1.0, height: float | None = None,
          **params: float | str | bool) -> tuple[Vertices, Faces]:
    """A chair: seat, four legs, back posts, a top rail, back slats/spindles/rails.

    Parameters
    ----------
    seed : int, default 0
        Draws every parameter not given (:data:`CHAIR_RANGES`).
    resolution : float, default 1.0
        Scales the vertex count by about ``resolution**2`` (4,500 vertices at 1).
    height : float, optional
        Total height (top of the back); sets ``back_height = height - seat_height``.
    **params
        Fix any drawn parameter (metres):

        - ``seat_width`` (x) 0.40-0.60, ``seat_depth`` (z) 0.38-0.55,
          ``seat_height`` (top of the seat) 0.40-0.50, ``seat_thickness`` 0.03-0.06;
        - ``back_height`` (above the seat) 0.30-0.55;
        - ``leg_thickness`` (side or diameter) 0.025-0.05, ``leg_style`` "square" or
          "round";
        - ``back_style`` "slats" (vertical boards), "spindles" (round rods) or "ladder"
          (horizontal rails), ``back_count`` 2-7 of them (ladder: at most 5 rails);
        - ``stretchers`` (bool, True with probability 2/3): side and front rails
          between the legs.

    Returns
    -------
    V : (n, 3) float64
        y up, standing on y = 0, seat centred on the y axis, facing +z.
    F : (m, 3) int64
        Closed, outward, 2-manifold parts (legs, seat, rails, slats...), overlapping.

    Examples
    --------
    >>> V, F = chair(seed=0, seat_height=0.45, height=0.9)
    >>> float(V[:, 1].max())
    0.9
    >>> V2, F2 = chair(seed=0)
    >>> V2.shape == chair(seed=0)[0].shape
    True
    """
    p = _draw(np.random.default_rng(seed), CHAIR_RANGES, params)
    if height is not None:
        height = float(height)
        if not height > p["seat_height"] + 0.05:
            raise ValueError(f"height {height} must exceed seat_height "
                             f"({p['seat_height']:.3f}) by 0.05 at least")
        p["back_height"] = height - p["seat_height"]
    w, d, sh, st = p["seat_width"], p["seat_depth"], p["seat_height"], p["seat_thickness"]
    lt = min(p["leg_thickness"], 0.2 * min(w, d))
    top = sh + p["back_height"]
    xl, zl = w / 2 - lt / 2 - 0.01, d / 2 - lt / 2 - 0.01  # leg centres
    rail = float(np.clip(0.22 * p["back_height"], 0.05, 0.1))
    bt = 0.55 * lt  # thickness (z) of the back's boards
    count = int(p["back_count"])

    def build(edge):
        parts = [_box([-w / 2, sh - st, -d / 2], [w / 2, sh, d / 2], edge)]
        for sx in (-1, 1):
            for sz, y1 in ((1, sh - st / 2), (-1, top)):  # front legs; back legs + posts
                x, z = sx * xl, sz * zl
                if p["leg_style"] == "round":
                    parts.append(_rod([x, 0, z], [x, y1, z], lt / 2, edge, sections=10))
                else:
                    parts.append(_box([x - lt / 2, 0, z - lt / 2], [x + lt / 2, y1, z + lt / 2],
                                      edge))
        # the back: a top rail between the posts, and boards below it
        parts.append(_box([-xl, top - rail, -zl - bt / 2], [xl, top, -zl + bt / 2], edge))
        low, high = sh, top - rail
        if p["back_style"] == "ladder":
            n = min(count, 5)
            rung = min(0.045, 0.5 * (high - low - 0.04) / n)
            for yc in np.linspace(low + 0.06, high - 0.02, n + 1)[:-1] + rung / 2:
                parts.append(_box([-xl, yc - rung / 2, -zl - bt / 3],
                                  [xl, yc + rung / 2, -zl + bt / 3], edge))
        else:
            gap = 2 * xl / (count + 1)
            xs = -xl + gap * np.arange(1, count + 1)
            xs = 0.5 * (xs - xs[::-1])  # exactly mirror-symmetric
            for x in xs:
                if p["back_style"] == "spindles":
                    radius = min(0.011, 0.3 * gap, 0.4 * bt)
                    parts.append(_rod([x, low - 0.01, -zl], [x, high + 0.01, -zl], radius,
                                      edge, sections=8))
                else:
                    half = min(0.035, 0.3 * gap)
                    parts.append(_box([x - half, low - 0.01, -zl - bt / 3],
                                      [x + half, high + 0.01, -zl + bt / 3], edge))
        if p["stretchers"]:
            ys = 0.3 * (sh - st)
            radius = 0.3 * lt
            for sx in (-1, 1):
                parts.append(_rod([sx * xl, ys, -zl], [sx * xl, ys, zl], radius, edge))
            parts.append(_rod([-xl, ys + 0.06, zl], [xl, ys + 0.06, zl], radius, edge))
            parts.append(_rod([-xl, ys + 0.06, -zl], [xl, ys + 0.06, -zl], radius, edge))
        return parts

    return _sized(build, 0.03, _resolution(resolution))


# ----------------------------------------------------------------------------- tables

TABLE_RANGES = {
    "width": (0.80, 1.60),
    "depth": (0.50, 0.95),
    "height": (0.65, 0.80),
    "top_thickness": (0.025, 0.05),
    "overhang": (0.02, 0.08),
    "leg_thickness": (0.04, 0.08),
    "leg_style": ["square", "tapered", "turned"],
    "apron_height": (0.06, 0.12),
    "lower": ["shelf", "stretchers"],
}
"""Table parameters and the ranges they are drawn from (metres)."""


def _turned_profile(radius: float, length: float, block: float) -> list:
    """Profile of a turned leg: a foot bead, a tapering shaft with beads, a top block."""
    y = np.linspace(0.0, length, 800)
    t = y / length
    shaft = radius * (0.6 + 0.2 * t)
    start = length - block
    blend = np.clip((y - (start - 0.05 * length)) / (0.05 * length), 0.0, 1.0)
    blend = blend * blend * (3 - 2 * blend)  # smoothstep into the block
    r = shaft + (radius - shaft) * blend
    r = r + 0.2 * radius * _bump(y, 0.0, 0.03 * length)  # foot
    for centre, amp in ((0.12, 0.25), (0.45, 0.18), (0.75, 0.25)):
        r = r + amp * radius * _bump(y, centre * start, 0.7 * radius)
    wall = np.stack([r, y], axis=1)
    return [_line((0, 0), (r[0], 0)), wall, _line((r[-1], length), (0, length))]


def table(seed: int = 0, *, resolution: float = 1.0,
          **params: float | str | bool) -> tuple[Vertices, Faces]:
    """A table: top, four legs, an apron, and a lower shelf or stretchers.

    Parameters
    ----------
    seed : int, default 0
        Draws every parameter not given (:data:`TABLE_RANGES`).
    resolution : float, default 1.0
        Scales the vertex count by about ``resolution**2`` (4,500 vertices at 1).
    **params
        Fix any drawn parameter (metres):

        - ``width`` (x) 0.80-1.60, ``depth`` (z) 0.50-0.95, ``height`` (top surface)
          0.65-0.80, ``top_thickness`` 0.025-0.05, ``overhang`` of the top past the
          legs 0.02-0.08;
        - ``leg_thickness`` 0.04-0.08, ``leg_style`` "square", "tapered" (narrower at the
          foot) or "turned" (round, with beads and a collar);
        - ``apron_height`` 0.06-0.12 (the boards under the top);
        - ``lower`` "shelf" or "stretchers" (an H of round rails).

    Returns
    -------
    V : (n, 3) float64
        y up, standing on y = 0, centred on the y axis.
    F : (m, 3) int64

    Examples
    --------
    >>> V, F = table(seed=0, height=0.7)
    >>> float(V[:, 1].max())
    0.7
    """
    p = _draw(np.random.default_rng(seed), TABLE_RANGES, params)
    w, d, h, tt = p["width"], p["depth"], p["height"], p["top_thickness"]
    lt = min(p["leg_thickness"], 0.15 * min(w, d))
    ov = min(p["overhang"], 0.15 * min(w, d))
    xl, zl = w / 2 - ov - lt / 2, d / 2 - ov - lt / 2
    ah = min(p["apron_height"], 0.3 * h)
    at = 0.022  # apron board thickness
    leg_top = h - tt / 2

    def build(edge):
        parts = [_box([-w / 2, h - tt, -d / 2], [w / 2, h, d / 2], 1.6 * edge)]
        for sx in (-1, 1):
            for sz in (-1, 1):
                x, z = sx * xl, sz * zl
                if p["leg_style"] == "turned":
                    leg = _lathe(_turned_profile(lt / 2, leg_top, ah + 0.01), 0.6 * edge,
                                 min_sections=12)
                    parts.append(_place(leg, [x, 0, z]))
                else:
                    taper = 0.6 if p["leg_style"] == "tapered" else 1.0
                    parts.append(_box([x - lt / 2, 0, z - lt / 2],
                                      [x + lt / 2, leg_top, z + lt / 2], edge, taper))
        y0 = h - tt - ah
        for sz in (-1, 1):  # apron boards along x, then along z, just inside the legs
            z = sz * (zl + lt / 2 - at / 2 - 0.006)
            parts.append(_box([-xl, y0, z - at / 2], [xl, h - tt / 2, z + at / 2], edge))
        for sx in (-1, 1):
            x = sx * (xl + lt / 2 - at / 2 - 0.006)
            parts.append(_box([x - at / 2, y0, -zl], [x + at / 2, h - tt / 2, zl], edge))
        low = 0.16 * h
        if p["lower"] == "shelf":
            parts.append(_box([-xl, low, -zl], [xl, low + 0.022, zl], 1.4 * edge))
        else:
            radius = 0.22 * lt
            for sx in (-1, 1):
                parts.append(_rod([sx * xl, low, -zl], [sx * xl, low, zl], radius, edge))
            parts.append(_rod([-xl, low + 0.04, 0], [xl, low + 0.04, 0], radius, edge))
        return parts

    return _sized(build, 0.04, _resolution(resolution))


# ------------------------------------------------------------------------------ vases

VASE_RANGES = {
    "height": (0.25, 0.55),
    "base_radius": (0.045, 0.08),
    "belly_radius": (0.08, 0.16),
    "belly_position": (0.3, 0.6),
    "neck_radius": (0.03, 0.06),
    "lip_radius": (0.045, 0.09),
    "wall": (0.008, 0.012),
    "ridges": (1, 4),
    "flutes": [0, 0, 8, 10, 12],
    "handles": [True, False],
}
"""Vase parameters and the ranges they are drawn from (metres; ``belly_position`` is a
fraction of the height; ``flutes`` is drawn from the listed values)."""


def vase(seed: int = 0, *, resolution: float = 1.0,
         **params: float | str | bool) -> tuple[Vertices, Faces]:
    """A hollow vase of revolution: foot ring, body with ridges, neck and a rolled rim.

    Parameters
    ----------
    seed : int, default 0
        Draws every parameter not given (:data:`VASE_RANGES`).
    resolution : float, default 1.0
        Scales the vertex count by about ``resolution**2`` (4,500 vertices at 1).
    **params
        Fix any drawn parameter (metres unless stated):

        - ``height`` 0.25-0.55 (top of the rim);
        - the outer profile, a smooth curve through ``base_radius`` 0.045-0.08 (at the
          foot), ``belly_radius`` 0.08-0.16 (at ``belly_position``, 0.3-0.6 of the
          height), ``neck_radius`` 0.03-0.06 (at 0.82) and ``lip_radius`` 0.045-0.09 (at
          the top);
        - ``wall`` thickness 0.008-0.012 (the opening is a hole down to a floor);
        - ``ridges`` 1-4 beads around the body;
        - ``flutes`` 0, 8, 10 or 12 vertical ribs on the body (0 with probability 2/5);
        - ``handles`` (bool): two tori on the shoulder, at x = +-.

    Returns
    -------
    V : (n, 3) float64
        y up, standing on y = 0, axis of revolution = the y axis.
    F : (m, 3) int64

    Examples
    --------
    >>> V, F = vase(seed=0, height=0.4)
    >>> round(float(V[:, 1].max()), 12)
    0.4
    """
    from scipy.interpolate import PchipInterpolator

    p = _draw(np.random.default_rng(seed), VASE_RANGES, params)
    H, wall = p["height"], min(p["wall"], 0.4 * p["neck_radius"])
    if p["flutes"] % 2:
        raise ValueError(f"flutes must be even (mirror symmetry), not {p['flutes']}")
    yb = float(np.clip(p["belly_position"], 0.2, 0.7)) * H
    yn = 0.82 * H
    smooth = PchipInterpolator([0.0, yb, yn, H],
                               [p["base_radius"], p["belly_radius"], p["neck_radius"],
                                p["lip_radius"]])
    bead = 0.6 * wall  # the rolled rim sticks out this much
    y_top = H - (wall + bead) / 2  # centre of the rim's rounding
    y = np.linspace(0.0, y_top, 1500)
    base = smooth(y)
    outer = base + 0.6 * wall * _bump(y, 0.0, 0.03 * H)  # foot ring
    ridge_amp, ridge_w = 0.45 * wall, 0.025 * H
    for yc in np.linspace(0.14 * H, yb + 0.5 * (yn - yb), p["ridges"] + 2)[1:-1]:
        outer = outer + ridge_amp * _bump(y, yc, ridge_w)
    outer = outer + bead * _bump(y, y_top, 0.05 * H)  # the rim
    # the hole: the inner wall follows the smooth outline down to a floor, which stays
    # above the handles (so that they cannot poke into it)
    handle_major, handle_minor = 0.16 * H, 0.022 * H
    handle_centre = yb + 0.45 * (yn - yb)
    floor = 0.5 * (yb + yn)
    if p["handles"]:
        floor = max(floor, handle_centre + handle_major + handle_minor + 0.01)
    floor = min(floor, y_top - 0.08 * H)
    handle_centre = min(handle_centre, floor - 0.01 - handle_major - handle_minor)
    yi = np.linspace(y_top, floor, 600)
    inner = smooth(yi) - wall
    c = np.array([0.5 * (outer[-1] + inner[0]), y_top])
    rim = 0.5 * (outer[-1] - inner[0])  # radius of the rim's rounding; its top is H
    segments = [
        _line((0.0, 0.0), (outer[0], 0.0)),
        np.stack([outer, y], axis=1),
        _arc(c, rim, 0.0, 0.5 * np.pi),  # two halves: the top point is a sample
        _arc(c, rim, 0.5 * np.pi, np.pi),
        np.stack([inner, yi], axis=1),
        _line((inner[-1], floor), (0.0, floor)),
    ]
    n_outer = None  # rings on the outer wall get the flutes

    flutes = int(p["flutes"])
    flute_lo, flute_hi = 0.12 * H, yb + 0.3 * (yn - yb)

    def modulate(i, radius, yy, theta):
        if not flutes or i >= n_outer or not flute_lo < yy < flute_hi:
            return radius
        weight = np.sin(np.pi * (yy - flute_lo) / (flute_hi - flute_lo)) ** 2
        return radius + wall * weight * (0.5 + 0.5 * np.cos(flutes * theta)) ** 2

    def build(edge):
        nonlocal n_outer
        n_outer = len(_resample(segments[0], edge)) + len(_resample(segments[1], edge)) - 1

        def min_sections(i, radius, yy):
            fluted = flutes and i < n_outer and flute_lo < yy < flute_hi
            return 8 * flutes if fluted else 12

        body = _lathe(segments, edge, min_sections=min_sections,
                      modulate=modulate if flutes else None)
        parts = [body]
        if p["handles"]:
            x = float(smooth(handle_centre)) + 0.35 * handle_major
            for sx in (-1, 1):
                parts.append(_torus([sx * x, handle_centre, 0.0], handle_major,
                                    handle_minor, 0.7 * edge, normal=(0, 0, 1)))
        return parts

    return _sized(build, 0.015 * H / 0.4, _resolution(resolution))


# ---------------------------------------------------------------------------- families

FAMILIES: dict[str, Callable[..., _Mesh]] = {"chairs": chair, "tables": table,
                                              "vases": vase}
"""Family name -> shape function."""


def family(name: str, n: int, seed: int = 0,
           **kwargs: float | str | bool | None) -> Iterator[tuple[Vertices, Faces]]:
    """``n`` shapes of a family; the i-th is ``FAMILIES[name](seed=seed + i, **kwargs)``.

    Parameters
    ----------
    name : {"chairs", "tables", "vases"}
    n : int
        Number of shapes (>= 0).
    seed : int, default 0
        Seed of the first shape.
    **kwargs
        Passed to every call (``resolution``, fixed parameters).

    Yields
    ------
    V : (n_i, 3) float64
    F : (m_i, 3) int64

    Examples
    --------
    >>> shapes = list(family("vases", 2, seed=5))
    >>> np.array_equal(shapes[1][0], vase(seed=6)[0])
    True
    """
    if name not in FAMILIES:
        raise ValueError(f"unknown family {name!r}; available: {', '.join(FAMILIES)}")
    if int(n) < 0:
        raise ValueError(f"n must be >= 0, not {n}")
    make = FAMILIES[name]
    for i in range(int(n)):
        yield make(seed=int(seed) + i, **kwargs)
