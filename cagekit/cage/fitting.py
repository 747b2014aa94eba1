"""Automatic cages: ``fit_cage`` wraps any mesh or point cloud in a verified cage.

``wrap`` (default): CGAL's alpha wrap (through pymeshlab), with a small outward offset and a
first alpha of about ``0.9 / sqrt(faces)`` of the diagonal (:func:`default_alphas`: a
coarser cage needs a coarser wrap), gives a closed, 2-manifold, outward surface around any
input, open, non-manifold or a point cloud; libigl's QSlim with ``block_intersections``
decimates it to the face count; a repair pushes vertices out along their normals until
every sample is ``margin`` inside (halving the face count step by step when a thin or open
input's decimation is beyond repair), and faces an input edge pokes through are pushed out
by ``2 margin``. If any check fails the next offset, then the next alpha, is tried, and
:class:`CageFitError` is raised when none passes. QSlim's placement limits tightness: after
the repair each face rests on the input. ``template``: the paper's 42-vertex icosphere
(:func:`template_cage`) centred on the bounding box and shrunk radially by a linear
program: with ``s_i = 1 / r_i``, a point ``c + rho u`` (``u = a u_a + b u_b + g u_g`` in its
spherical triangle) is inside when ``rho (a s_a + b s_b + g s_g) <= 1``; maximising
``sum s_i`` under this constraint for every sample, with a margin, gives the tightest
radial cage that encloses them, embedded because it is a radial graph. Both methods work in
the frame where the input's bounding-box diagonal is 1 and return only cages that pass every
check of :func:`cage_report`. See docs/architecture.md.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from cagekit.cage import check_cage, face_components, self_intersecting_faces, signed_volume
from cagekit.cage.shapes import icosphere_cage
from cagekit.errors import CageError, CageFitError, InputError
from cagekit.geometry import as_shape, face_areas
from cagekit.geometry.frame import Frame
from cagekit.geometry.sampling import sample_surface
from cagekit.typed import Faces, Vertices

__all__ = ["fit_cage", "FittedCage", "cage_report", "CageReport", "template_cage",
           "wrap_input", "check_face_budget", "METHODS", "MIN_FACES",
           "MAX_FACES"]

METHODS = ("wrap", "template")

#: fewest faces a cage can have (a tetrahedron)
MIN_FACES = 4
#: largest face budget :func:`fit_cage` takes (``cagekit fit-cage --faces`` shares it): the
#: wrap is already finer than this for any budget above about 2,000 faces (its alpha stops
#: at 0.02 of the diagonal), and binding cost grows with the cage's faces
MAX_FACES = 100_000

#: faces of :func:`template_cage` (the paper's icosphere)
TEMPLATE_FACES = 80


def check_face_budget(faces: int | np.integer) -> int:
    """A cage face budget as an int, or a one-line :class:`InputError`.

    Parameters
    ----------
    faces : int
        A Python or NumPy integer (not a bool, not a float) from :data:`MIN_FACES` to
        :data:`MAX_FACES`.

    Returns
    -------
    int

    Raises
    ------
    InputError
        Not an integer, or out of range.

    Examples
    --------
    >>> check_face_budget(np.int64(200))
    200
    """
    if (isinstance(faces, bool) or not isinstance(faces, (int, np.integer))
            or not MIN_FACES <= faces <= MAX_FACES):
        raise InputError(f"faces must be an integer from {MIN_FACES} to {MAX_FACES:,} (a cage "
                         f"has at least {MIN_FACES} faces), got {faces!r}")
    return int(faces)


def template_cage() -> tuple[Vertices, Faces]:
    """The paper's template cage: a 42-vertex, 80-face icosphere of radius 1.

    Returns
    -------
    vertices : (42, 3) float64
    faces : (80, 3) int64

    Examples
    --------
    >>> v, f = template_cage()
    >>> v.shape, f.shape
    ((42, 3), (80, 3))
    """

    return icosphere_cage(subdivisions=1, radius=1.0)


# ----------------------------------------------------------------------------- input


def _as_shape(shape_v, shape_f):
    """The shape (:func:`cagekit.geometry.as_shape`) and its fitting frame; refuses fewer
    than two distinct points and extents that are zero, overflow or cannot be resolved."""
    v, f = as_shape(shape_v, shape_f)
    if len(v) < 2:
        raise InputError("a cage needs a shape with at least two distinct points")
    return v, f, _frame(v)


def _frame(v):
    """The fitting frame: bounding-box centre, the diagonal as unit."""

    try:
        return Frame.of(v, unit="diagonal")
    except InputError as exc:
        if "coincide" in exc.problem:
            raise InputError("all points of the shape coincide: nothing to cage") from None
        raise


def _samples(v, f, n, seed):
    """Vertices plus ``n`` area-uniform samples (mesh) or the points themselves (cloud)."""
    if len(f) == 0:
        return v

    if not face_areas(v, f).sum() > 0:
        return v
    return np.vstack([v, sample_surface(v, f, n, seed=seed)])


# ----------------------------------------------------------------------------- wrap


#: size of the stand-in triangles given to the wrap for points and segments (unit diagonal)
_STAND_IN = 1e-4


def wrap_input(v: Vertices, f: ArrayLike) -> tuple[Vertices, Faces]:
    """The triangle soup the alpha wrap is given for a shape: proper triangles only.

    pymeshlab's alpha wrap (CGAL 5) crashes the process (a segmentation fault) on input it
    cannot take: no faces at all, only zero-area faces, or a zero-area face before the
    others. So the wrap is never given a face of zero area. The rule:

    - a face is *proper* when its three indices differ and twice its area exceeds
      ``1e-12`` times the square of its longest edge; proper faces are kept as they are;
    - any other face (repeated index, collinear or coincident corners) whose longest edge is
      longer than ``1e-4`` (this frame's unit is the bounding-box diagonal) is a segment: it
      becomes a thin triangle along that edge, of height ``1e-4``;
    - every vertex used by no proper face (points of a cloud, unreferenced vertices, the
      corners of a degenerate face) becomes a tiny triangle of legs ``1e-4`` at it.

    The wrap encloses these stand-ins with its offset (at least ``4e-3``), so every point and
    every segment of the input stays inside. The exact cut test of a cage uses the proper
    faces and the segments' stand-ins (:func:`_cut_soup`), points being checked by winding
    numbers.

    Parameters
    ----------
    v : (n, 3) float64
        Vertices, in the frame whose bounding-box diagonal is 1.
    f : (m, 3) int64
        Faces (may be empty).

    Returns
    -------
    wv : (p, 3) float64
    wf : (q, 3) int64
        Vertices and faces of proper triangles only, q >= 1.

    Examples
    --------
    >>> v = np.array([[0.0, 0, 0], [0.5, 0, 0], [1.0, 0, 0]])
    >>> wv, wf = wrap_input(v, np.array([[0, 1, 2]]))  # one collinear face
    >>> len(wf), bool(np.all(_twice_areas(wv, wf) > 0))  # its segment and 3 corner points
    (4, True)
    """
    return _with_stand_ins(v, *_cut_soup(v, f, return_used=True))


def _with_stand_ins(v, sv, sf, used):
    """:func:`wrap_input` from :func:`_cut_soup`'s ``(sv, sf, used)``: the soup plus a tiny
    triangle at each vertex no proper face uses."""
    loose = v[~used]
    if not len(loose):
        return sv, sf
    e = _STAND_IN
    tiny_v = np.concatenate([loose + [e, 0, 0], loose + [0, e, 0], loose + [0, 0, e]])
    return np.vstack([sv, tiny_v]), np.vstack([sf, _fresh_triangles(len(sv), len(loose))])


def _cut_soup(v, f, return_used=False):
    """The proper faces of a shape and a thin triangle along each degenerate face.

    See :func:`wrap_input` for the rule. Returns ``(sv, sf)``, and with ``return_used``
    also which vertices a proper face uses, ``(n,)`` bool.
    """
    f = np.asarray(f, dtype=np.int64).reshape(-1, 3)
    corners = v[f]
    edges = np.stack([corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 1],
                      corners[:, 0] - corners[:, 2]], axis=1)
    lengths = np.linalg.norm(edges, axis=2).reshape(-1, 3)
    longest = lengths.max(axis=1, initial=0.0)
    distinct = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    proper = distinct & (_twice_areas(v, f) > 1e-12 * longest**2)
    segments = ~proper & (longest > _STAND_IN)
    sv, sf = v, f[proper]
    if segments.any():
        k = lengths[segments].argmax(axis=1)
        c = corners[segments]
        rows = np.arange(len(c))
        a, b = c[rows, k], c[rows, (k + 1) % 3]
        sv = np.vstack([v, a, b, a + _STAND_IN * _perpendicular(b - a)])
        sf = np.vstack([sf, _fresh_triangles(len(v), len(a))])
    if not return_used:
        return sv, sf
    used = np.zeros(len(v), dtype=bool)
    used[f[proper].ravel()] = True
    return sv, sf, used


def _twice_areas(v, f):
    if not len(f):
        return np.zeros(0)
    return np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)


def _perpendicular(d):
    """A unit vector perpendicular to each row of ``d`` (rows of positive length)."""
    axis = np.eye(3)[np.argmin(np.abs(d), axis=1)]
    n = np.cross(d, axis)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _fresh_triangles(start, count):
    """Faces ``(s + i, s + count + i, s + 2 count + i)`` over three stacked blocks."""
    idx = start + np.arange(count)
    return np.stack([idx, idx + count, idx + 2 * count], axis=1)


def _alpha_wrap(v, f, alpha, offset, given=None):
    """Alpha wrap of a mesh or cloud (unit-diagonal frame); returns (V, F) or None.

    The wrap is given :func:`wrap_input`'s proper triangles only (see there for why);
    ``given``: that input, when already built.
    """
    import pymeshlab

    wv, wf = wrap_input(v, f) if given is None else given
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(wv, wf))
    ms.generate_alpha_wrap(alpha=pymeshlab.PercentageValue(alpha * 100),
                           offset=pymeshlab.PercentageValue(offset * 100))
    m = ms.current_mesh()
    if m.face_number() == 0:
        return None
    return (np.asarray(m.vertex_matrix(), dtype=np.float64),
            np.asarray(m.face_matrix(), dtype=np.int64))


def _decimate(v, f, faces):
    import igl

    if len(f) <= faces:
        return v, f
    out = igl.qslim(np.asfortranarray(v), np.asfortranarray(f.astype(np.int32)), int(faces),
                    True)
    return np.ascontiguousarray(out[0]), np.ascontiguousarray(out[1], dtype=np.int64)


def _signed_distance(points, cv, cf):
    """Signed distance to a closed, oriented cage (negative inside), closest faces and points.

    libigl's pseudonormal sign is exact for a closed, 2-manifold, self-intersection-free
    cage and faster than the winding-number sign; the final checks use the exact winding
    number regardless.
    """
    import igl

    sign = igl.SignedDistanceType.SIGNED_DISTANCE_TYPE_PSEUDONORMAL
    return igl.signed_distance(np.ascontiguousarray(points), cv, cf, sign)[:3]


def _repair(cv, cf, samples, margin, rounds):
    """Push cage vertices outward until every sample is at least ``margin`` inside.

    A sample short of ``margin`` by ``need`` at barycentric coordinates ``b`` on its
    closest cage face asks vertex ``k`` of that face for ``need b_k / |b|^2`` along the
    vertex normal, divided by the normal's share along the face normal (the smallest push
    that covers it, to first order); each vertex takes the largest request. Returns the
    repaired vertices, or None when ``rounds`` rounds did not suffice or the repair
    diverges.

    Only samples that may have come within ``margin`` are measured again each round: a
    round moves the cage surface by at most its largest push ``p``, so a sample's signed
    distance grows by at most ``p`` (it cannot cross the moving surface while farther
    from it than that); a sample whose last distance plus the pushes since stays below
    ``-margin`` is still inside by ``margin``.
    """
    import igl

    known = np.full(len(samples), np.inf)  # last measured signed distance + pushes since
    first = None
    for round_ in range(rounds):
        near = np.flatnonzero(known > -margin)
        dist, face, closest = _signed_distance(samples[near], cv, cf)
        known[near] = dist
        bad = np.flatnonzero(dist > -margin)
        if len(bad) == 0:
            return cv
        worst = float(dist[bad].max() + margin)
        first = worst if first is None else first
        if round_ >= 8 and worst > 2 * first:  # diverging: pushes expose more than they cover
            return None
        tri = cf[face[bad]]
        bary = igl.barycentric_coordinates(np.ascontiguousarray(closest[bad]),
                                           np.ascontiguousarray(cv[tri[:, 0]]),
                                           np.ascontiguousarray(cv[tri[:, 1]]),
                                           np.ascontiguousarray(cv[tri[:, 2]]))
        bary = np.clip(bary, 0.0, 1.0)
        normals = igl.per_vertex_normals(cv, cf)
        face_n = igl.per_face_normals(cv, cf, np.zeros(3))[face[bad]]
        # a push t along the vertex normal n moves the face's plane by t (n . N)
        along = np.clip(np.einsum("rkc,rc->rk", normals[tri], face_n), 0.6, 1.0)
        need = (dist[bad] + 1.5 * margin) / np.maximum((bary**2).sum(axis=1), 1e-12)
        push = np.zeros(len(cv))
        for k in range(3):
            np.maximum.at(push, tri[:, k], need * bary[:, k] / along[:, k])
        cv = cv + push[:, None] * normals
        known += push.max()
    return None


def _decimate_enclosing(cv, cf, faces, samples, margin, rounds):
    """Decimate to ``faces`` and repair; if one step cannot be repaired, halve step by step.

    One large decimation can fold the two sheets of a wrapped thin or open input onto each
    other, beyond repair; small steps keep each repair small. Returns None on failure.
    """
    once = _decimate(cv, cf, faces)
    repaired = _repair(once[0], once[1], samples, margin, rounds)
    if repaired is not None:
        return repaired, once[1]
    while len(cf) > faces:
        before = len(cf)
        cv, cf = _decimate(cv, cf, max(faces, before // 2))
        cv = _repair(cv, cf, samples, margin, rounds)
        if cv is None:
            return None
        if len(cf) >= before:  # blocked collapses: no progress possible
            break
    return cv, cf


def _push_cut_faces(cv, cf, v, f, margin, rounds=4, soup=None):
    """Push the vertices of cage faces that cross an input face outward by ``margin``.

    Samples can all lie inside while an input edge between them pokes through a cage face;
    the exact test finds those faces. Returns the vertices, or None if cuts remain.
    ``soup``: :func:`_cut_soup`'s ``(sv, sf)``, when already built.
    """
    import igl

    soup = _cut_soup(v, f) if soup is None else soup
    for _ in range(rounds):
        cut = _cut_faces(cv, cf, v, f, soup=soup)
        if not cut.any():
            return cv
        push = np.zeros(len(cv))
        push[np.unique(cf[cut])] = 2 * margin
        cv = cv + push[:, None] * igl.per_vertex_normals(cv, cf)
    return None


def default_alphas(faces: int) -> tuple[float, ...]:
    """Alpha values tried by the wrap for a face budget: about ``0.9 / sqrt(faces)`` first.

    A coarser wrap is enough for a coarser cage and is several times faster to build; the
    larger values are fall-backs for inputs the first wrap cannot serve: very thin parts,
    and (0.5) parts so far apart that smaller wraps leave them in separate components
    (a shower head above its tray; such a cage is loose, ``components`` > 1 gives a tighter
    one).
    """
    first = float(np.clip(0.9 / np.sqrt(max(faces, 1)), 0.02, 0.1))
    return (first, 2 * first, 0.2, 0.5)


def _fit_wrap(v, f, faces, samples, margin, offsets, alphas, rounds, components):
    failures = []
    sv, sf, used = _cut_soup(v, f, return_used=True)  # once for every wrap and cut test
    given = _with_stand_ins(v, sv, sf, used)
    for alpha in alphas:
        for offset in offsets:
            where = f"alpha {alpha:g}, offset {offset:g}"
            wrapped = _alpha_wrap(v, f, alpha, offset, given)
            if wrapped is None:
                failures.append(f"{where}: empty wrap")
                continue
            decimated = _decimate_enclosing(*wrapped, faces, samples, margin, rounds)
            if decimated is None:
                failures.append(f"{where}: the decimated wrap could not be repaired")
                continue
            cv, cf = decimated
            if len(f):
                cv = _push_cut_faces(cv, cf, v, f, margin, soup=(sv, sf))
                if cv is None:
                    failures.append(f"{where}: no_cut")
                    continue
            report = _checks(cv, cf, v, f, samples, faces, components,
                             cut_checked=bool(len(f)))
            if all(report.values()):
                return cv, cf, report
            failures.append(f"{where}: " + ", ".join(k for k, ok in report.items() if not ok))
    raise CageFitError("could not build a cage meeting every guarantee (" + "; ".join(failures)
                       + ")")


# ----------------------------------------------------------------------------- template


def _fit_template(v, samples, margin):
    """The template icosphere shrunk radially (unit-diagonal frame); see the module doc."""
    from scipy.optimize import linprog

    tv, tf = template_cage()
    u = tv / np.linalg.norm(tv, axis=1, keepdims=True)
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    rel = samples - centre
    rho = np.linalg.norm(rel, axis=1)
    keep = rho > 1e-12
    rel, rho = rel[keep], rho[keep]
    dirs = rel / rho[:, None]
    # which spherical triangle each direction falls in, and its coefficients there
    coef = np.full((len(dirs), 3), -np.inf)
    tri = np.zeros(len(dirs), dtype=np.int64)
    for fi, (a, b, c) in enumerate(tf):
        m = np.linalg.inv(np.stack([u[a], u[b], u[c]], axis=1))
        abc = dirs @ m.T
        inside = abc.min(axis=1) >= -1e-12
        better = inside & (abc.min(axis=1) > coef.min(axis=1))
        coef[better] = abc[better]
        tri[better] = fi
    coef = np.maximum(coef, 0.0)
    n_v = len(tv)
    rows = np.repeat(np.arange(len(dirs)), 3)
    cols = tf[tri].ravel()
    from scipy.sparse import coo_matrix

    grown = rho + margin
    A = coo_matrix(((coef * grown[:, None]).ravel(), (rows, cols)),
                   shape=(len(dirs), n_v)).tocsr()
    b = np.ones(len(dirs))
    bounds = [(1.0, 1.0 / 0.02)] * n_v  # radii between 0.02 and 1 (the box fits in 0.5)
    # minimise sum_i r_i = sum_i 1 / s_i (convex) over the polytope by Frank-Wolfe steps,
    # each a linear program; start from the tightest sphere
    sphere = float((grown * coef.sum(axis=1)).max())  # smallest feasible sphere radius
    s = np.full(n_v, 1.0 / min(max(sphere, 0.02), 1.0))
    for _ in range(12):
        res = linprog(-1.0 / s**2, A_ub=A, b_ub=b, bounds=bounds, method="highs")
        if res.status != 0:
            raise CageFitError(f"template cage: the linear program failed ({res.message})")
        step = res.x - s
        ts = np.linspace(0.0, 1.0, 21)
        costs = [np.sum(1.0 / (s + t * step)) for t in ts]
        best = ts[int(np.argmin(costs))]
        if best == 0.0:
            break
        s = s + best * step
    return centre + u * (1.0 / s)[:, None], tf


# ----------------------------------------------------------------------------- checks


def _n_components(f):

    return len(np.unique(face_components(int(f.max()) + 1, f))) if len(f) else 0


def _cut_faces(cv, cf, v, f, alone=None, soup=None):
    """Cage faces that intersect an input face (exact triangle-triangle test), (c,) bool.

    The input's faces are taken as :func:`_cut_soup` gives them (``soup``, when already
    built): proper faces, and a thin triangle along each degenerate one. Only cage-input
    pairs are tested, never the input's own faces against each other (a multi-part input
    has many overlapping parts): :func:`_candidate_pairs` keeps the pairs that may meet,
    then libigl's ``tri_tri_overlap_test_3d`` (coplanar overlaps included) decides.
    ``alone``: the cage's own self-intersecting faces, when already known; they are left
    out, as before.
    """
    import igl

    sv, sf = _cut_soup(v, f) if soup is None else soup
    out = np.zeros(len(cf), dtype=bool)
    if not len(sf):
        return out
    if alone is None:
        alone = self_intersecting_faces(cv, cf)
    C = np.ascontiguousarray(cv[cf])
    T = np.ascontiguousarray(sv[sf])
    cj, ti = _candidate_pairs(C, T, alone)
    for j, i in zip(cj, ti):
        if not out[j] and igl.tri_tri_overlap_test_3d(C[j, 0:1], C[j, 1:2], C[j, 2:3],
                                                      T[i, 0:1], T[i, 1:2], T[i, 2:3]):
            out[j] = True
    return out


def _candidate_pairs(C, T, skip):
    """Pairs (cage face ``j``, input face ``i``) that may intersect: their bounding boxes
    overlap and neither triangle has its three corners strictly on one side of the other's
    plane (beyond a slack of ``1e-9`` of the coordinates' size, so that nearly touching
    pairs go to the exact test). Cage faces flagged in ``skip`` are left out."""
    from cagekit.cage._cut_kernel import candidate_pairs

    return candidate_pairs(C, T, skip)


def _checks(cv, cf, v, f, samples, faces, components, cut_checked=False):
    """The guarantees of a fitted cage, each True or False (unit-diagonal frame).

    ``cut_checked``: the caller has just run the same exact cut test (:func:`_cut_faces`)
    on these very vertices and found no cut, so it is not run again.
    """
    import igl


    out = {}
    try:
        oriented = np.array_equal(check_cage(cv, cf, intersections=False), cf)
        out["closed_manifold"] = True
    except CageError:
        oriented = False
        out["closed_manifold"] = False
    out["outward"] = bool(oriented and signed_volume(cv, cf) > 0)
    out["components"] = _n_components(cf) <= components
    alone = self_intersecting_faces(cv, cf)
    out["no_self_intersection"] = not alone.any()
    # the samples begin with the vertices (see _samples): one winding-number pass
    wn = igl.winding_number(cv, cf, np.ascontiguousarray(samples))
    out["encloses_vertices"] = bool(np.all(wn[: len(v)] >= 0.5))
    out["encloses_samples"] = bool(np.all(wn >= 0.5))
    if cut_checked:
        out["no_cut"] = True
    elif len(f):
        out["no_cut"] = not _cut_faces(cv, cf, v, f, alone).any()
    else:
        out["no_cut"] = out["encloses_samples"]
    out["face_count"] = len(cf) <= faces
    return out


def _shape_volume(v, f):
    """Volume of a closed shape, else of its convex hull; and which one it is."""
    import trimesh
    from scipy.spatial import ConvexHull

    if len(f):
        mesh = trimesh.Trimesh(v, f, process=False)
        if mesh.is_watertight and mesh.is_winding_consistent and abs(mesh.volume) > 0:
            return abs(float(mesh.volume)), "shape"
    try:
        return float(ConvexHull(v).volume), "convex hull"
    except Exception:  # flat or degenerate input: no volume to compare with
        return 0.0, "none"


@dataclass(frozen=True)
class CageReport:
    """Every guarantee of a fitted cage and its tightness (:func:`cage_report`).

    Attributes
    ----------
    ok : bool
        Every check passed.
    checks : dict of str to bool
        ``closed_manifold``, ``outward``, ``components``, ``no_self_intersection``,
        ``encloses_vertices``, ``encloses_samples``, ``no_cut``, ``face_count``.
    faces, vertices : int
        The cage's counts.
    volume_ratio : float or None
        Cage volume over the shape's, or over its convex hull's for open shapes and clouds
        (``volume_reference`` says which); None when that volume is 0.
    volume_reference : {"shape", "convex hull", "none"}
    max_distance : float
        Largest distance from the cage's surface to the shape, over the shape's
        bounding-box diagonal.
    """

    ok: bool
    checks: dict[str, bool]
    faces: int
    vertices: int
    volume_ratio: float | None
    volume_reference: str
    max_distance: float

    def as_dict(self) -> dict:
        """The report as a plain dict (for JSON), in field order."""
        return asdict(self)


class FittedCage(NamedTuple):
    """What :func:`fit_cage` returns; it unpacks as ``cage_v, cage_f, report``.

    Attributes
    ----------
    vertices : (k, 3) float64
        In the shape's frame and units.
    faces : (c, 3) int64
        Closed, 2-manifold, outward, not self-intersecting.
    report : CageReport or None
        The checks the fit has just passed and the cage's tightness; None when
        ``fit_cage(..., report=False)``.
    """

    vertices: np.ndarray
    faces: np.ndarray
    report: CageReport | None


def cage_report(shape_v: ArrayLike, shape_f: ArrayLike | None, cage_v: ArrayLike,
                cage_f: ArrayLike, faces: int | None = None, components: int = 1,
                samples: int = 20000, seed: int = 0) -> CageReport:
    """Every guarantee of a fitted cage and its tightness.

    Parameters
    ----------
    shape_v : (n, 3) array_like of float
    shape_f : (m, 3) array_like of int or None
        Faces of the shape; None or empty for a point cloud.
    cage_v : (k, 3) array_like of float
    cage_f : (c, 3) array_like of int
    faces : int, optional
        The requested face count, as :func:`check_face_budget` takes it (default: the
        cage's own).
    components : int, default 1
        Allowed number of cage components.
    samples : int, default 20000
        Area-uniform samples of the shape checked for enclosure, besides its vertices.
    seed : int, default 0

    Raises
    ------
    InputError
        A bad shape (as :func:`fit_cage`), a bad ``faces``, or a cage with fewer than 4
        vertices or faces, NaN coordinates or face indices out of range.

    Returns
    -------
    CageReport
    """
    if faces is not None:
        faces = check_face_budget(faces)
    v, f, frame = _as_shape(shape_v, shape_f)
    cv = np.asarray(cage_v, dtype=np.float64)
    cf = np.asarray(cage_f, dtype=np.int64)
    if cv.ndim != 2 or cv.shape[1] != 3 or len(cv) < 4 or cf.ndim != 2 or len(cf) < 4:
        raise InputError(f"a cage needs at least 4 vertices and 4 faces, got {len(cv)} "
                         f"vertices and {len(cf)} faces")
    if not np.all(np.isfinite(cv)) or cf.min() < 0 or cf.max() >= len(cv):
        raise InputError("the cage has NaN coordinates or face indices out of range")
    vn, cvn = frame.to_unit(v), frame.to_unit(cv)
    pts = _samples(vn, f, samples, seed)
    checks = _checks(cvn, cf, vn, f, pts, len(cf) if faces is None else faces, components)
    return _report(checks, vn, f, cvn, cf, seed)


def _report(checks, vn, f, cvn, cf, seed):
    """:func:`cage_report`'s result from the checks and the cage (unit-diagonal frame)."""
    import igl
    from scipy.spatial import cKDTree


    shape_vol, reference = _shape_volume(vn, f)
    cage_vol = signed_volume(cvn, cf)
    cage_pts = _samples(cvn, cf, 20000, seed)
    if len(f):
        dist = np.sqrt(igl.point_mesh_squared_distance(cage_pts, vn, f)[0])
    else:
        dist = cKDTree(vn).query(cage_pts)[0]
    return CageReport(
        ok=all(checks.values()), checks=dict(checks), faces=int(len(cf)),
        vertices=int(len(cvn)),
        volume_ratio=float(cage_vol / shape_vol) if shape_vol > 0 else None,
        volume_reference=reference, max_distance=float(dist.max()))


# ----------------------------------------------------------------------------- main


def fit_cage(shape_v: ArrayLike, shape_f: ArrayLike | None = None, faces: int = 200,
             method: str = "wrap", *, components: int = 1, margin: float = 0.001,
             samples: int = 20000, seed: int = 0,
             offsets: tuple[float, ...] = (0.004, 0.008, 0.016, 0.03, 0.06),
             alphas: tuple[float, ...] | None = None, max_repairs: int = 30,
             report: bool = True) -> FittedCage:
    """Build a cage around a mesh or point cloud, verified before it is returned.

    Parameters
    ----------
    shape_v : (n, 3) array_like of float, or a mesh
        The shape's vertices (any units and orientation); or a ``trimesh.Trimesh``,
        ``trimesh.PointCloud`` or ``(vertices, faces)`` pair, with ``shape_f`` left out.
    shape_f : (m, 3) array_like of int, optional
        Its faces; None or empty for a point cloud. Open, multi-component, non-manifold,
        self-intersecting input and duplicate or degenerate faces are all accepted.
    faces : int, default 200
        Largest number of cage faces: an integer from :data:`MIN_FACES` (4) to
        :data:`MAX_FACES` (100,000). The template always has 80: fewer is refused.
    method : {"wrap", "template"}, default "wrap"
    components : int, default 1
        Largest number of cage components (``wrap``).
    margin : float, default 0.001
        How far inside the cage every sample must be, relative to the bounding-box diagonal.
    samples : int, default 20000
        Area-uniform samples of the surface that must be enclosed, besides the vertices.
    seed : int, default 0
    offsets, alphas : sequences of float
        Wrap offsets and alpha values (relative to the diagonal) tried in turn, every
        offset for the first alpha, then for the next (``wrap``); alphas default to
        :func:`default_alphas` of ``faces``.
    max_repairs : int, default 30
        Rounds of the outward repair after decimation (``wrap``).
    report : bool, default True
        Measure the cage's tightness for :class:`CageReport` from the checks the fit has
        just passed (``face_count`` is judged against ``faces``); False leaves
        ``report`` None and saves that measurement (:func:`cagekit.deform` does).

    Returns
    -------
    FittedCage
        ``(vertices, faces, report)``: the cage in the shape's frame and units, with
        ``len(faces) <= faces``.

    Raises
    ------
    InputError
        Empty shape, NaN, a single point, an unknown method, ``faces`` not an integer
        from 4 to 100,000 (:func:`check_face_budget`), or ``faces < 80`` with the
        template.
    CageFitError
        No cage meeting every guarantee was found.

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage(3, half_extent=(1.0, 0.5, 0.25))
    >>> cage = fit_cage(v, f, faces=100)
    >>> len(cage.faces) <= 100, cage.report.ok
    (True, True)
    """
    if method not in METHODS:
        raise InputError(f"unknown cage method {method!r}; available: {', '.join(METHODS)}")
    faces = check_face_budget(faces)
    if method == "template" and faces < TEMPLATE_FACES:
        raise InputError(f"the template cage has {TEMPLATE_FACES} faces, more than the "
                         f"{faces} asked for; ask for {TEMPLATE_FACES} or more, or use "
                         "method wrap")
    v, f, frame = _as_shape(shape_v, shape_f)
    vn = frame.to_unit(v)
    pts = _samples(vn, f, samples, seed)
    if method == "template":
        # a wider margin when input edges cross the cage between samples
        for grow in (1, 4, 16):
            cvn, cf = _fit_template(vn, pts, margin * grow)
            checks = _checks(cvn, cf, vn, f, pts, faces, 1)
            if all(checks.values()):
                break
        else:
            failing = ", ".join(k for k, ok in checks.items() if not ok)
            raise CageFitError(f"the template cage fails: {failing}")
    else:
        if alphas is None:
            alphas = default_alphas(faces)
        cvn, cf, checks = _fit_wrap(vn, f, faces, pts, margin, offsets, alphas,
                                    max_repairs, components)
    return FittedCage(frame.to_world(cvn), cf,
                      _report(checks, vn, f, cvn, cf, seed) if report else None)
