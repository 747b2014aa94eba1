"""An artist-style cage for a T-pose humanoid: one tube per limb, built by extrusion.

Real templates come with cages that an artist drew: a box-like tube around each limb,
branching from the torso, about 130 vertices. :func:`cagekit.fit_cage` wraps a body
tightly but webs the armpits and keeps both legs in one block, which a pose transfer
cannot bend like limbs. This cage is a column of six-vertex rings (hips to the top of the
head) with each arm extruded from the column's side at the shoulders and each leg from
one half of its bottom, every cap sized to enclose the body's vertices of its segment with
``margin`` (a share of the height) to spare. Quads are split into triangles; the result is
closed, 2-manifold, outward and checked (:func:`cagekit.cage.check_cage`).

Examples
--------
>>> from cagekit.datasets import humanoid
>>> r = humanoid.rig("template", resolution=0.5)
>>> v, f = humanoid_cage(r)
>>> len(v), len(f)
(130, 256)
"""

from __future__ import annotations

import numpy as np

from cagekit.cage import check_cage
from cagekit.datasets.humanoid import JOINTS, Rig
from cagekit.typed import Faces, Vertices

__all__ = ["humanoid_cage", "MARGIN"]

#: clearance of the cage around the body, as a share of its height
MARGIN = 0.015


class _QuadMesh:
    """Vertices and outward quads, with extrusion of one quad at a time."""

    def __init__(self) -> None:
        self.vertices: list[np.ndarray] = []
        self.quads: list[tuple[int, int, int, int]] = []

    def add(self, point) -> int:
        self.vertices.append(np.asarray(point, dtype=np.float64))
        return len(self.vertices) - 1

    def extrude(self, quad, corners) -> tuple[int, int, int, int]:
        """Replace ``quad`` by side walls and a cap at ``corners`` (4 points, same order)."""
        self.quads.remove(quad)
        p0, p1, p2, p3 = corners
        cap = (self.add(p0), self.add(p1), self.add(p2), self.add(p3))
        for i in range(4):
            a, b = quad[i], quad[(i + 1) % 4]
            self.quads.append((a, b, cap[(i + 1) % 4], cap[i]))
        self.quads.append(cap)
        return cap

    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        Q = np.asarray(self.quads, dtype=np.int64)
        return np.asarray(self.vertices), np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]])


def _extent(points, axis, lo, hi):
    """Min and max of ``points`` along the two axes other than ``axis``, for the points
    whose ``axis`` coordinate lies in [lo, hi] (None when there are none)."""
    sel = points[(points[:, axis] >= lo) & (points[:, axis] <= hi)]
    if not len(sel):
        return None
    return sel.min(axis=0), sel.max(axis=0)


def _levels(points, axis, stations, margin):
    """(lo, hi) per station: the extent of the points between its two neighbours."""
    out = []
    for i, s in enumerate(stations):
        a = stations[max(i - 1, 0)]
        b = stations[min(i + 1, len(stations) - 1)]
        lo, hi = min(a, b, s), max(a, b, s)
        found = _extent(points, axis, lo, hi)
        if found is None:
            found = _extent(points, axis, lo - 2 * margin, hi + 2 * margin)
        out.append((found[0] - margin, found[1] + margin))
    return out


def humanoid_cage(rig: Rig, margin: float = MARGIN) -> tuple[Vertices, Faces]:
    """The cage of a rig in its rest T-pose (see the module docstring).

    Parameters
    ----------
    rig : cagekit.datasets.humanoid.Rig
    margin : float, default :data:`MARGIN`

    Returns
    -------
    V : (k, 3) float64
    F : (m, 3) int64
        Closed, 2-manifold, outward, free of self-intersection.
    """

    V = rig.vertices
    height = float(np.ptp(V[:, 1]))
    m = margin * height
    parts = rig.parts
    joint = {name: rig.joints[i] for i, name in enumerate(JOINTS)}

    def verts(*names):
        return np.concatenate([V[parts[n]] for n in names])

    core = verts("torso", "neck", "head")
    arm = verts("l_upper_arm", "l_forearm", "l_palm", "l_thumb", "l_index", "l_middle",
                "l_ring", "l_pinky")
    leg = verts("l_thigh", "l_shin", "l_foot")
    shoulder, elbow, wrist = joint["l_shoulder"], joint["l_elbow"], joint["l_wrist"]
    hip, knee, ankle = joint["l_hip"], joint["l_knee"], joint["l_ankle"]
    arm_radius = float(np.abs(arm[np.abs(arm[:, 0] - shoulder[0]) < 0.02 * height, 1]
                              - shoulder[1]).max())
    # the column: rings of 6 vertices from the hips to the top of the head
    y_bottom = float(V[parts["torso"], 1].min())
    y_top = float(core[:, 1].max())
    armpit = shoulder[1] - arm_radius - m
    top_of_shoulder = shoulder[1] + arm_radius + m
    head = V[parts["head"]]
    head_low = float(head[:, 1].min())
    levels = np.maximum.accumulate(np.asarray([
        y_bottom, 0.5 * (y_bottom + armpit), armpit, top_of_shoulder,
        head_low + 0.2 * (y_top - head_low), head_low + 0.6 * (y_top - head_low), y_top]))
    mesh = _QuadMesh()
    rings = []
    for i, y in enumerate(levels):
        lo = levels[max(i - 1, 0)]
        hi = levels[min(i + 1, len(levels) - 1)]
        found = _extent(core, 1, lo, hi)
        (x0, _, z0), (x1, _, z1) = found[0] - m, found[1] + m
        w = max(abs(x0), abs(x1))
        yy = y - m if i == 0 else (y + m if i == len(levels) - 1 else y)
        rings.append([mesh.add(p) for p in ((w, yy, z1), (0, yy, z1), (-w, yy, z1),
                                             (-w, yy, z0), (0, yy, z0), (w, yy, z0))])
    for low, up in zip(rings[:-1], rings[1:]):
        for i in range(6):
            j = (i + 1) % 6
            mesh.quads.append((low[i], up[i], up[j], low[j]))
    b, t = rings[0], rings[-1]
    left_bottom, right_bottom = (b[0], b[1], b[4], b[5]), (b[1], b[2], b[3], b[4])
    mesh.quads += [left_bottom, right_bottom, (t[5], t[4], t[1], t[0]),
                   (t[4], t[3], t[2], t[1])]
    # arms from the side quads between the armpit and shoulder rings (index 2 and 3)
    w_side = abs(mesh.vertices[rings[2][0]][0])
    tip = float(arm[:, 0].max())
    stations = [shoulder[0] + 0.4 * (elbow[0] - shoulder[0]), elbow[0],
                0.5 * (elbow[0] + wrist[0]), wrist[0], 0.5 * (wrist[0] + tip), tip]
    stations = [max(s, w_side + m) for s in stations]
    stations = list(np.maximum.accumulate(stations))
    extents = _levels(arm, 0, stations, m)
    for side in (1.0, -1.0):
        lo_ring, up_ring = rings[2], rings[3]
        if side > 0:
            quad = (lo_ring[5], up_ring[5], up_ring[0], lo_ring[0])
        else:
            quad = (lo_ring[2], up_ring[2], up_ring[3], lo_ring[3])
        for k, (s, (lo, hi)) in enumerate(zip(stations, extents)):
            x = side * (s + (m if k == len(stations) - 1 else 0.0))
            if side > 0:  # back-low, back-up, front-up, front-low
                corners = [(x, lo[1], lo[2]), (x, hi[1], lo[2]), (x, hi[1], hi[2]),
                           (x, lo[1], hi[2])]
            else:  # front-low, front-up, back-up, back-low
                corners = [(x, lo[1], hi[2]), (x, hi[1], hi[2]), (x, hi[1], lo[2]),
                           (x, lo[1], lo[2])]
            quad = mesh.extrude(quad, corners)
    # legs from the two halves of the bottom ring
    sole = float(leg[:, 1].min())
    stations = [0.5 * (hip[1] + knee[1]), knee[1], 0.5 * (knee[1] + ankle[1]), ankle[1],
                sole]
    extents = _levels(leg, 1, [y_bottom] + stations, m)[1:]
    gap = 0.25 * m
    for side in (1.0, -1.0):
        quad = left_bottom if side > 0 else right_bottom
        for k, (s, (lo, hi)) in enumerate(zip(stations, extents)):
            y = s - (m if k == len(stations) - 1 else 0.0)
            outer, inner = hi[0], max(lo[0], gap)
            if side > 0:  # outer-front, inner-front, inner-back, outer-back
                corners = [(outer, y, hi[2]), (inner, y, hi[2]), (inner, y, lo[2]),
                           (outer, y, lo[2])]
            else:  # inner-front, outer-front, outer-back, inner-back
                corners = [(-inner, y, hi[2]), (-outer, y, hi[2]), (-outer, y, lo[2]),
                           (-inner, y, lo[2])]
            quad = mesh.extrude(quad, corners)
    cage_v, cage_f = mesh.triangles()
    return cage_v, check_cage(cage_v, cage_f)
