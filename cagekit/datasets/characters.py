"""Novel characters that differ from the humanoid template the way real ones do.

The bodies of :mod:`cagekit.datasets.humanoid` share the template's T rest pose, its mesh
and its landmark vertices, so a transfer benchmark on them cannot see what goes wrong on a
real character. Each :class:`Character` here has, from the same rig (so with ground truth):

- a rest pose of its own (:data:`CHARACTERS`): arms 15-76 degrees above or below the
  template's T (``arms_down``: a stocky body whose hands hang a few centimetres from its
  hips), legs apart, a slight torso turn, or the T itself;
- a mesh of its own: the rig at another resolution with its vertices shuffled (another
  vertex count and order), or for ``robot_boxes`` one open box per part (25 boxes, no
  lids, each moved rigidly by its part's main joint);
- landmarks on its own surface, a face and barycentric coordinates as Thea writes them
  (near the rig's landmark vertex, not on it), with labels missing and misspelt
  (:data:`MISSING`, :data:`MISSPELT`).

``truth(pose)`` poses the character with the given joint rotations *from the canonical
T-pose* (those of :meth:`cagekit.datasets.humanoid.Rig.pose`, the T-pose being the
identity), not from the character's rest pose: pose transfer
of a template example ``(rest -> pose)`` must give ``truth(pose)``, and of the example
``(pose -> rest)`` must give ``truth({})``, whatever the character's rest pose.

Examples
--------
>>> c = character("a_pose")
>>> c.vertices.shape[0] != len(humanoid.rig("template").vertices)
True
>>> bool(np.allclose(c.truth(c.rest_pose), c.vertices))
True
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cagekit.datasets import humanoid
from cagekit.io.landmarks import SurfacePoint
from cagekit.typed import Vertices

__all__ = ["CHARACTERS", "UNLIKE_CHARACTERS", "FINGERS", "MISSING", "MISSPELT", "Character",
           "character", "rest_pose", "surface_landmarks"]

#: the rig's finger names (joints ``{side}_{finger}{1,2,3}``)
FINGERS = ("thumb", "index", "middle", "ring", "pinky")
#: labels left out of every character's landmark file
MISSING = ("r_ear", "l_ring_tip")
#: labels misspelt in every character's landmark file (true -> written)
MISSPELT = {"nose_tip": "nose-tip", "l_heel": "L_heel"}


def rest_pose(arms: float = 0.0, legs: float = 0.0, turn: float = 0.0,
              elbows: float = 0.0) -> dict[str, np.ndarray]:
    """A symmetric rest pose, in degrees from the template's T.

    Parameters
    ----------
    arms : float
        Shoulders raised (> 0) or lowered (< 0) about the forward axis.
    legs : float
        Hips spread apart.
    turn : float
        The chest turned about the vertical (the only asymmetric angle).
    elbows : float
        Forearms bent forward.

    Returns
    -------
    dict[str, (3, 3) float64]
        Local rotations for :meth:`cagekit.datasets.humanoid.Rig.pose`.

    Examples
    --------
    >>> P = rest_pose(arms=-45)
    >>> r = humanoid.rig(resolution=0.5)
    >>> tip = r.pose(P)[r.landmarks["l_hand_tip"]]
    >>> bool(tip[1] < r.vertices[r.landmarks["l_hand_tip"], 1] - 0.3)
    True
    """
    y, z = np.eye(3)[1], np.eye(3)[2]
    mirror = np.outer([-1.0, 1, 1], [-1.0, 1, 1])
    left = {"l_shoulder": humanoid.rotation_matrix(z * np.radians(arms)),
            "l_elbow": humanoid.rotation_matrix(-y * np.radians(elbows)),
            "l_hip": humanoid.rotation_matrix(z * np.radians(legs))}
    pose = dict(left)
    for name, R in left.items():
        pose["r_" + name[2:]] = R * mirror
    pose["chest"] = humanoid.rotation_matrix(y * np.radians(turn))
    return pose


#: name -> (body, resolution, rest pose angles, mesh kind)
CHARACTERS: dict[str, tuple] = {
    "t_pose": (humanoid.random_body(3), 0.7, {}, "remeshed"),
    "a_pose": ("skinny", 0.8, {"arms": -45, "legs": 6}, "remeshed"),
    "arms_up": ("stocky", 1.25, {"arms": 25}, "remeshed"),
    "relaxed": (humanoid.random_body(11), 0.9, {"arms": -60, "legs": 12, "turn": 10,
                                                "elbows": 15}, "remeshed"),
    "robot_boxes": ("robot", 1.0, {"arms": -37, "legs": 4}, "boxes"),
    "arms_down": ("stocky", 0.9, {"arms": -76}, "remeshed"),
    # proportions far from the template's (humanoid.UNLIKE_BODIES) and rest poses of their
    # own: what went wrong on a real bulky robot with arms 37 degrees down (issue 30)
    "brute_arms_down": ("brute", 0.9, {"arms": -37, "legs": 4}, "remeshed"),
    "child_a_pose": ("child", 0.9, {"arms": -45, "legs": 5}, "remeshed"),
    "tall_thin_wide": ("tall_thin", 0.8, {"arms": 20, "legs": 8}, "remeshed"),
    "long_torso_relaxed": ("long_torso", 0.9, {"arms": -55, "legs": 6, "turn": 8,
                                                "elbows": 15}, "remeshed"),
    # a tree-like "Ent" (issue 30): arms 1.7x as long held 35 degrees above the T, legs
    # apart; about 10,000 vertices, as the user's
    "long_limbed_wide": ("long_limbed", 1.05, {"arms": 35, "legs": 10}, "remeshed"),
    # the bulky robot of issue 30 as an artist would build it: one open box per part
    "brute_boxes": ("brute", 1.0, {"arms": -37, "legs": 4}, "boxes"),
}

#: the characters of :data:`CHARACTERS` whose proportions are far from the template's
UNLIKE_CHARACTERS: tuple[str, ...] = ("brute_arms_down", "child_a_pose", "tall_thin_wide",
                                      "long_torso_relaxed", "long_limbed_wide",
                                      "brute_boxes")


@dataclass
class Character:
    """A novel character in its own rest pose, with the rig that poses it.

    Attributes
    ----------
    name : str
    vertices : (n, 3) float64
        The rest pose.
    faces : (m, 3) int64
    rest_pose : dict[str, (3, 3) float64]
        The rest pose's joint rotations from the canonical T-pose (the local rotations
        :meth:`cagekit.datasets.humanoid.Rig.pose` takes), not relative to anything of
        the character's.
    landmarks : list of cagekit.io.landmarks.SurfacePoint
        On the rest-pose surface, with :data:`MISSING` left out and :data:`MISSPELT`
        misspelt.
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    rest_pose: dict
    landmarks: list
    _pose: Callable[[Mapping[str, ArrayLike]], np.ndarray] | None = None

    def truth(self, pose: Mapping[str, ArrayLike]) -> Vertices:
        """(n, 3) float64: the character in ``pose`` (joint rotations from the T-pose)."""
        if self._pose is None:
            raise RuntimeError(f"character {self.name!r} has no pose function; build it with "
                               "character()")
        return self._pose(pose)


def _shuffled(rig, seed):
    """The rig's mesh with its vertices in a random order: (order, inverse, faces)."""
    order = np.random.default_rng(seed).permutation(len(rig.vertices))
    inverse = np.empty_like(order)
    inverse[order] = np.arange(len(order))
    return order, inverse[rig.faces]


def _box(points, subdivisions: int = 5):
    """An open box (no lid at +third axis) around points, by their principal axes: (V, F)."""
    centre = points.mean(axis=0)
    _, _, axes = np.linalg.svd(points - centre, full_matrices=False)
    if np.linalg.det(axes) < 0:  # a right-handed frame, so the faces stay outward
        axes[2] *= -1
    local = (points - centre) @ axes.T
    lo, hi = local.min(axis=0), local.max(axis=0)
    n = subdivisions
    grid = np.linspace(0.0, 1.0, n + 1)
    sheets_v: list[np.ndarray] = []
    sheets_f: list[np.ndarray] = []
    # five sides of the unit cube, each an (n+1) x (n+1) grid, outward
    sides = [(0, 0.0, (1, 2)), (0, 1.0, (2, 1)), (1, 0.0, (2, 0)), (1, 1.0, (0, 2)),
             (2, 0.0, (1, 0))]
    for axis, value, (u, v) in sides:
        a, b = np.meshgrid(grid, grid, indexing="ij")
        P = np.zeros((a.size, 3))
        P[:, axis], P[:, u], P[:, v] = value, a.ravel(), b.ravel()
        base = sum(len(x) for x in sheets_v)
        idx = base + np.arange(a.size).reshape(n + 1, n + 1)
        quads = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], -1)
        quads = quads.reshape(-1, 4)
        sheets_f.append(np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]))
        sheets_v.append(P)
    V = np.concatenate(sheets_v) * (hi - lo) + lo
    F = np.concatenate(sheets_f)
    # outward: flip when the first face points at the centre
    normal = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    outward = ((V[F].mean(axis=1) - (lo + hi) / 2) * normal).sum(axis=1)
    F = np.where((outward < 0)[:, None], F[:, ::-1], F)
    return V @ axes + centre, F


def _boxes(rig):
    """One open box per rig part, and each box vertex's joint (its part's heaviest)."""
    V, F, joint, start = [], [], [], 0
    for rows in rig.parts.values():
        points = rig.vertices[rows]
        bv, bf = _box(points)
        main = int(np.argmax(rig.weights[rows].sum(axis=0)))
        V.append(bv)
        F.append(bf + start)
        joint.append(np.full(len(bv), main))
        start += len(bv)
    return np.concatenate(V), np.concatenate(F), np.concatenate(joint)


def _rigid_pose(rig, joint):
    """Pose function of points rigidly attached to joints (canonical T-pose points)."""
    def pose(points, rotations):
        A, t = rig.joint_transforms(rotations)
        return np.einsum("nij,nj->ni", A[joint], points) + t[joint]
    return pose


def surface_landmarks(vertices: ArrayLike, faces: ArrayLike, anchors: ArrayLike,
                      labels: Iterable[str], seed: int = 0) -> list[SurfacePoint]:
    """Points on a surface near given anchor points, as (face, barycentric) rows.

    Parameters
    ----------
    vertices : (n, 3) float64
    faces : (m, 3) int64
    anchors : (L, 3) float64
        Where each landmark should be; it lands on the nearest face, moved off that
        face's nearest vertex by random barycentric weights (15-35% on the two others).
    labels : sequence of str
    seed : int

    Returns
    -------
    list of cagekit.io.landmarks.SurfacePoint
    """
    import igl

    V, F = np.asarray(vertices), np.asarray(faces)
    points = np.asarray(anchors, np.float64)
    rng = np.random.default_rng(seed)
    _, face, _ = igl.point_mesh_squared_distance(points, V, F)
    out = []
    for label, anchor, f in zip(labels, points, np.asarray(face, np.int64)):
        tri = V[F[f]]
        near = int(np.argmin(np.linalg.norm(tri - anchor, axis=1)))
        b = np.zeros(3)
        others = [i for i in range(3) if i != near]
        b[others] = rng.uniform(0.15, 0.35, 2)
        b[near] = 1.0 - b[others].sum()
        out.append(SurfacePoint(label, int(f), tuple(map(float, b)), tuple(map(float, b @ tri))))
    return out


def _labelled(marks: list[SurfacePoint]) -> list[SurfacePoint]:
    """Drop :data:`MISSING`, misspell :data:`MISSPELT`."""
    out = []
    for m in marks:
        if m.label in MISSING:
            continue
        out.append(SurfacePoint(MISSPELT.get(m.label, m.label), m.face, m.barycentric,
                            m.position))
    return out


def character(name: str, labels: Iterable[str] | None = None, seed: int = 0) -> Character:
    """Build one of :data:`CHARACTERS`.

    Parameters
    ----------
    name : str
    labels : sequence of str, optional
        Landmark labels to place (default all of
        :data:`cagekit.datasets.humanoid.LANDMARK_NAMES`).
    seed : int
        Seeds the vertex order and the landmark jitter.

    Returns
    -------
    Character
    """
    if name not in CHARACTERS:
        raise ValueError(f"unknown character {name!r}; available: {', '.join(CHARACTERS)}")
    body, resolution, angles, kind = CHARACTERS[name]
    rig = humanoid.rig(body, resolution=resolution)
    rest = rest_pose(**angles)
    labels = list(humanoid.LANDMARK_NAMES if labels is None else labels)
    if kind == "boxes":
        points, faces, joint = _boxes(rig)
        rigid = _rigid_pose(rig, joint)

        def pose(rotations):
            return rigid(points, rotations)
    else:
        order, faces = _shuffled(rig, seed)

        def pose(rotations):
            return rig.pose(rotations)[order]
    V = pose(rest)
    anchors = rig.pose(rest)[[rig.landmarks[label] for label in labels]]
    marks = _labelled(surface_landmarks(V, faces, anchors, labels, seed))
    return Character(name, V, np.asarray(faces, np.int64), rest, marks, pose)
