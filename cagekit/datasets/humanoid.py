"""Procedural humanoids with a skeleton, linear-blend skinning and named landmarks.

A :class:`BodyShape` (proportions) posed by local joint rotations gives characters *with
ground truth* for deformation transfer ("Neural Cages", section 4.2): transfer a template's
pose to a novel body and compare with that body posed by the same rotations. Metres, y up,
facing +z, soles on ``y = 0``; the rest pose is a T-pose (palms down), mirror-symmetric
about ``x = 0``, ``l_`` on the character's left (+x). The mesh is 25 overlapping closed,
2-manifold, outward generalized cylinders (torso, neck, head with a face relief; per side
upper arm, forearm, palm, five fingers, thigh, shin, foot). Ring and sector counts depend on
``resolution`` only, so faces, part ranges and landmark indices are the same for every body and
pose. :data:`JOINTS` (parents first) and :data:`PARENTS` share the world orientation at
rest; skinning is a smoothstep between consecutive bones near each joint (at most three
weights a vertex, rigid head). :data:`LANDMARK_NAMES` are vertex indices named
``{side}_{part}_{position}_{direction}`` on the limbs (``prox``/``mid``/``dist`` at 20, 50
and 80 % along the bone from the body out; ``front`` is +z, ``outer`` is up on the arms and
away from the body on the legs), then single points such as ``head_top``, ``nose_tip``,
``l_hand_tip`` (middle finger) and ``l_heel``. See docs/architecture.md.

Examples
--------
>>> r = rig("template", resolution=0.5)
>>> V = r.pose(random_pose(seed=1))
>>> V.shape == r.vertices.shape, r.faces.dtype
(True, dtype('int64'))
>>> V2, F2 = humanoid("robot", random_pose(seed=1), resolution=0.5)
>>> bool((F2 == r.faces).all())
True
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from cagekit.typed import Faces, Floats, Vertices

__all__ = ["BODY_SHAPES", "JOINTS", "LANDMARK_NAMES", "NOVEL_BODIES", "UNLIKE_BODIES", "PARENTS",
           "PICKED_LANDMARK_NAMES", "RIGID_PARENTS", "RIGID_PARTS", "BodyShape", "Rig",
           "humanoid", "landmark_part", "random_body", "random_pose", "rig", "rotation_matrix"]

_Mesh = tuple[np.ndarray, np.ndarray]

# --------------------------------------------------------------------------- skeleton

_FINGERS = ("thumb", "index", "middle", "ring", "pinky")
_SIDE_JOINTS = ("clavicle", "shoulder", "elbow", "wrist",
                *(f"{f}{k}" for f in _FINGERS for k in (1, 2, 3)), "hip", "knee", "ankle")
_SIDE_PARENTS = {"clavicle": "chest", "shoulder": "clavicle", "elbow": "shoulder",
                 "wrist": "elbow", "hip": "pelvis", "knee": "hip", "ankle": "knee"}
for _f in _FINGERS:
    _SIDE_PARENTS.update({f"{_f}1": "wrist", f"{_f}2": f"{_f}1", f"{_f}3": f"{_f}2"})

JOINTS: tuple[str, ...] = ("pelvis", "spine", "chest", "neck", "head",
                           *(f"l_{j}" for j in _SIDE_JOINTS), *(f"r_{j}" for j in _SIDE_JOINTS))
"""Joint names, parents before children (49 joints; ``l_`` = character's left = +x)."""


def _side_parent(side: str, joint: str) -> str:
    parent = _SIDE_PARENTS[joint]
    return parent if parent in ("chest", "pelvis") else f"{side}_{parent}"


PARENTS: dict[str, str | None] = {"pelvis": None, "spine": "pelvis", "chest": "spine",
                                  "neck": "chest", "head": "neck",
                                  **{f"{s}_{j}": _side_parent(s, j) for s in "lr"
                                     for j in _SIDE_JOINTS}}
"""Joint name -> parent joint name (``None`` for the root, ``"pelvis"``)."""

_JI = {name: i for i, name in enumerate(JOINTS)}


def _parent_index(joint: str) -> int:
    parent = PARENTS[joint]
    return -1 if parent is None else _JI[parent]


_PARENT_INDEX = np.array([_parent_index(j) for j in JOINTS])


def _mirror_name(name: str) -> str:
    if name.startswith("l_"):
        return "r_" + name[2:]
    if name.startswith("r_"):
        return "l_" + name[2:]
    return name


_MIRROR_J = np.array([_JI[_mirror_name(j)] for j in JOINTS])
_MIRROR = np.array([-1.0, 1.0, 1.0])

# --------------------------------------------------------------------------- body shapes


@dataclass(frozen=True)
class BodyShape:
    """Proportions of a body (lengths in metres or as fractions of ``height``).

    Parameters
    ----------
    height : float
        Soles to the top of the head.
    leg_ratio, torso_ratio, neck_ratio, head_ratio : float
        Vertical shares (normalised to sum 1) of: ground to hip joint, hip joint to the
        base of the neck, the neck, and the head (neck top to the top of the skull).
    arm_ratio : float
        Shoulder joint to wrist, as a fraction of the height.
    forearm_share : float
        The forearm's share of the arm.
    hand_ratio, foot_ratio : float
        Wrist to the tip of the middle finger; heel to toe (fractions of the height).
    shoulder_width, hip_width : float
        Distance between the shoulder joints / the hip joints (fractions of the height).
    chest_width, waist_width : float
        Half-width of the torso at the chest / the waist (fractions of the height).
    torso_depth : float
        Depth of the torso relative to its width.
    limb_thickness : float
        Multiplies every limb radius (hands and feet grow with its square root).
    arm_radius, leg_radius : float
        Upper-arm and thigh radius at the body (fractions of the height).
    head_size : float
        Multiplies the head's width and depth.
    squareness : float
        0 gives elliptic cross-sections, 1 boxy ones (a superellipse of exponent
        ``2 + 8 * squareness``; the head becomes a block).

    Examples
    --------
    >>> BodyShape().height
    1.75
    >>> BODY_SHAPES["robot"].squareness > 0.5
    True
    """

    height: float = 1.75
    leg_ratio: float = 0.50
    torso_ratio: float = 0.33
    neck_ratio: float = 0.04
    head_ratio: float = 0.13
    arm_ratio: float = 0.33
    forearm_share: float = 0.45
    hand_ratio: float = 0.105
    foot_ratio: float = 0.15
    shoulder_width: float = 0.22
    hip_width: float = 0.10
    chest_width: float = 0.105
    waist_width: float = 0.085
    torso_depth: float = 0.62
    limb_thickness: float = 1.0
    arm_radius: float = 0.026
    leg_radius: float = 0.044
    head_size: float = 1.0
    squareness: float = 0.0

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if not np.isfinite(value) or value < 0 or (value == 0 and f.name != "squareness"):
                raise ValueError(f"BodyShape.{f.name} must be a positive number, not {value!r}")
        if self.squareness > 1:
            raise ValueError(f"BodyShape.squareness must be in [0, 1], not {self.squareness}")
        if not 0.2 <= self.forearm_share <= 0.8:
            raise ValueError(f"BodyShape.forearm_share must be in [0.2, 0.8], "
                             f"not {self.forearm_share}")


BODY_SHAPES: dict[str, BodyShape] = {
    "template": BodyShape(),
    "skinny": BodyShape(height=1.92, leg_ratio=0.53, torso_ratio=0.31, neck_ratio=0.05,
                        head_ratio=0.115, arm_ratio=0.35, hand_ratio=0.11,
                        shoulder_width=0.20, hip_width=0.09, chest_width=0.088,
                        waist_width=0.068, torso_depth=0.58, limb_thickness=0.62,
                        head_size=0.92),
    "stocky": BodyShape(height=1.52, leg_ratio=0.43, torso_ratio=0.35, neck_ratio=0.03,
                        head_ratio=0.165, arm_ratio=0.31, forearm_share=0.44,
                        hand_ratio=0.10, foot_ratio=0.16, shoulder_width=0.27,
                        hip_width=0.13, chest_width=0.135, waist_width=0.125,
                        torso_depth=0.72, limb_thickness=1.55, head_size=1.22),
    "robot": BodyShape(height=1.82, leg_ratio=0.49, torso_ratio=0.34, neck_ratio=0.045,
                       head_ratio=0.125, arm_ratio=0.32, forearm_share=0.48,
                       shoulder_width=0.26, hip_width=0.115, chest_width=0.125,
                       waist_width=0.11, torso_depth=0.66, limb_thickness=1.15,
                       head_size=1.05, squareness=0.85),
    # proportions far from the template's (issue 30): what a template cage's stretch and
    # shear of its own shoulders and armpits would ruin
    "brute": BodyShape(height=1.9, leg_ratio=0.27, torso_ratio=0.50, neck_ratio=0.03,
                       head_ratio=0.09, arm_ratio=0.33, forearm_share=0.47, hand_ratio=0.11,
                       foot_ratio=0.14, shoulder_width=0.40, hip_width=0.26,
                       chest_width=0.19, waist_width=0.15, torso_depth=0.68,
                       limb_thickness=2.5, head_size=0.75, squareness=0.6),
    "child": BodyShape(height=1.10, leg_ratio=0.33, torso_ratio=0.38, neck_ratio=0.03,
                       head_ratio=0.24, arm_ratio=0.22, hand_ratio=0.075, foot_ratio=0.11,
                       shoulder_width=0.19, hip_width=0.10, chest_width=0.10,
                       waist_width=0.095, torso_depth=0.75, limb_thickness=1.1,
                       head_size=1.7),
    "tall_thin": BodyShape(height=2.1, leg_ratio=0.60, torso_ratio=0.27, neck_ratio=0.05,
                           head_ratio=0.09, arm_ratio=0.43, hand_ratio=0.12,
                           shoulder_width=0.18, hip_width=0.08, chest_width=0.075,
                           waist_width=0.06, torso_depth=0.6, limb_thickness=0.6,
                           head_size=0.85),
    "long_torso": BodyShape(height=1.7, leg_ratio=0.38, torso_ratio=0.46, neck_ratio=0.04,
                            head_ratio=0.12, arm_ratio=0.24, forearm_share=0.46,
                            hand_ratio=0.09, shoulder_width=0.22, hip_width=0.11,
                            chest_width=0.11, waist_width=0.095),
    # a tree-like "Ent" (issue 30: refused with a third of its points outside the cage):
    # arms 1.7x as long, legs 1.3x, thin limbs on a narrow torso
    "long_limbed": BodyShape(height=2.4, leg_ratio=0.65, torso_ratio=0.22, neck_ratio=0.04,
                             head_ratio=0.09, arm_ratio=0.56, forearm_share=0.5,
                             hand_ratio=0.12, foot_ratio=0.13, shoulder_width=0.16,
                             hip_width=0.08, chest_width=0.07, waist_width=0.055,
                             torso_depth=0.6, limb_thickness=0.55, head_size=0.8),
}
"""Named body shapes: the template, three novel ones of roughly its proportions and five far
from them (:data:`UNLIKE_BODIES`)."""

NOVEL_BODIES: tuple[str, ...] = ("skinny", "stocky", "robot")
"""Bodies to transfer poses onto (see :data:`BODY_SHAPES`), of roughly the template's
proportions."""

UNLIKE_BODIES: tuple[str, ...] = ("brute", "child", "tall_thin", "long_torso", "long_limbed")
"""Bodies whose proportions are far from the template's, each posed by its own skeleton: a
brute (shoulders 1.8x as wide, chest 2x as deep, limbs 2.5x as thick, legs 0.6x as long,
a small head), a child (head 1.8x, limbs 0.65x), a tall thin one (limbs 1.3x, narrow
torso), one with a long torso and short arms, and a long-limbed one (arms 1.7x, legs 1.3x,
limbs half as thick, shoulders 0.7x as wide)."""

_BODY_RANGES = {
    "height": (1.50, 1.95), "leg_ratio": (0.44, 0.53), "torso_ratio": (0.30, 0.35),
    "neck_ratio": (0.03, 0.05), "head_ratio": (0.115, 0.155), "arm_ratio": (0.30, 0.35),
    "forearm_share": (0.42, 0.48), "hand_ratio": (0.095, 0.112), "foot_ratio": (0.14, 0.16),
    "shoulder_width": (0.20, 0.26), "hip_width": (0.09, 0.12), "chest_width": (0.09, 0.125),
    "waist_width": (0.07, 0.11), "torso_depth": (0.55, 0.72), "limb_thickness": (0.7, 1.4),
    "arm_radius": (0.024, 0.028), "leg_radius": (0.040, 0.047), "head_size": (0.9, 1.15),
    "squareness": (0.0, 0.3),
}


def random_body(seed: int) -> BodyShape:
    """Plausible random proportions, one uniform draw per field in field order.

    Parameters
    ----------
    seed : int

    Returns
    -------
    BodyShape

    Examples
    --------
    >>> random_body(3) == random_body(3), random_body(3) == random_body(4)
    (True, False)
    """
    rng = np.random.default_rng(seed)
    values = {f.name: float(rng.uniform(*_BODY_RANGES[f.name])) for f in fields(BodyShape)}
    return BodyShape(**values)


# ------------------------------------------------------------------------- primitives


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _gauss(x, width):
    return np.exp(-(np.asarray(x) / width) ** 2)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _frame(axis, hint) -> np.ndarray:
    """Right-handed frame, columns ``(e1, e2, d)``: ``d`` along ``axis``, ``e2`` near ``hint``."""
    d = _unit(axis)
    hint = np.asarray(hint, dtype=np.float64)
    e2 = _unit(hint - np.dot(hint, d) * d)
    return np.stack([np.cross(e2, d), e2, d], axis=1)


def _angles(n: int, warp: float = 0.0) -> np.ndarray:
    """Sector angles ``psi`` (0 = ``e2``, ``pi/2`` = ``-e1``), mirror pairs ``k <-> n - k``.

    ``warp`` in [0, 1) packs sectors near ``psi = 0`` (the front of the head).
    """
    k = np.arange(n)
    phi = 2.0 * np.pi * np.where(k <= n // 2, k, k - n) / n
    return phi - warp * np.sin(phi)


def _superellipse(psi: np.ndarray, p: float) -> np.ndarray:
    """Polar radius of the unit superellipse ``|x|^p + |y|^p = 1`` at angle ``psi``."""
    if p == 2.0:
        return np.ones_like(psi)
    return (np.abs(np.sin(psi)) ** p + np.abs(np.cos(psi)) ** p) ** (-1.0 / p)


def _sector(n: int, psi: float, warp: float = 0.0) -> int:
    """Index of the sector nearest to angle ``psi``."""
    diff = np.angle(np.exp(1j * (_angles(n, warp) - psi)))
    return int(np.argmin(np.abs(diff)))


@lru_cache(maxsize=64)
def _tube_faces(rings: int, n: int) -> np.ndarray:
    """Faces of pole, ``rings`` rings of ``n`` vertices, pole (outward for ``_capsule``)."""
    ring = 1 + np.arange(rings)[:, None] * n + np.arange(n)[None, :]
    nxt = np.roll(ring, -1, axis=1)
    a, b = ring[:-1].ravel(), nxt[:-1].ravel()
    c, d = nxt[1:].ravel(), ring[1:].ravel()
    top = 1 + rings * n
    faces = [np.stack([np.zeros(n, dtype=np.int64), nxt[0], ring[0]], axis=1),
             np.stack([a, b, c], axis=1), np.stack([a, c, d], axis=1),
             np.stack([ring[-1], nxt[-1], np.full(n, top)], axis=1)]
    F = np.concatenate(faces).astype(np.int64)
    F.setflags(write=False)
    return F


def _counts(base: tuple[int, int, int], resolution: float) -> tuple[int, int, int]:
    """(sectors, body rings, cap rings) at ``resolution``; sectors a multiple of 4."""
    sectors, body, cap = base
    return (max(8, 4 * int(round(sectors * resolution / 4))),
            max(4, int(round(body * resolution))), max(1, int(round(cap * resolution))))


def _ring_index(counts, fraction: float) -> int:
    n, body, cap = counts
    return cap + int(round(fraction * (body - 1)))


def _vertex(counts, ring: int, sector: int) -> int:
    return 1 + ring * counts[0] + sector


def _capsule(origin, frame, s0: float, s1: float, caps: tuple[float, float], counts,
             a_fn: Callable, b_fn: Callable, p: float, *, c2_fn: Callable | None = None,
             relief: Callable | None = None) -> np.ndarray:
    """Vertices of a generalized cylinder: pole, rings, pole (faces: :func:`_tube_faces`).

    Parameters
    ----------
    origin : (3,) array_like
    frame : (3, 3) ndarray
        Columns ``e1, e2, d``; rings lie in planes normal to ``d`` at ``origin + s d``.
    s0, s1 : float
        Axial extent of the body rings; rounded caps of lengths ``caps`` extend beyond.
    counts : (sectors, body rings, cap rings)
    a_fn, b_fn : callable
        Half-sizes along ``e1`` / ``e2`` as functions of ``t`` in [0, 1] (t = 0 at s0).
    p : float
        Superellipse exponent of the cross-sections (2 = ellipse) and of the caps.
    c2_fn : callable, optional
        Offset of the ring centres along ``e2`` (function of ``t``).
    relief : callable, optional
        ``relief(t (k, 1), psi (1, n)) -> (k, n)`` outward displacement.

    Returns
    -------
    V : (2 + rings * sectors, 3) float64
    """
    n, body, cap = counts
    psi = _angles(n)
    q = 2.0 / p
    phi = np.arange(1, cap + 1) * (0.5 * np.pi / (cap + 1))
    cos_q, sin_q = np.cos(phi) ** q, np.sin(phi) ** q
    s = np.concatenate([s0 - caps[0] * sin_q[::-1], s0 + (s1 - s0) * np.linspace(0, 1, body),
                        s1 + caps[1] * sin_q])
    scale = np.concatenate([cos_q[::-1], np.ones(body), cos_q])
    t = (s - s0) / (s1 - s0)
    tc = np.clip(t, 0.0, 1.0)
    a, b = a_fn(tc) * scale, b_fn(tc) * scale
    c2 = c2_fn(tc) if c2_fn is not None else np.zeros_like(s)
    r = _superellipse(psi, p)
    u1, u2 = -np.sin(psi), np.cos(psi)
    x1 = a[:, None] * (r * u1)[None, :]
    x2 = c2[:, None] + b[:, None] * (r * u2)[None, :]
    if relief is not None:
        D = relief(t[:, None], psi[None, :])
        x1, x2 = x1 + D * u1, x2 + D * u2
    x3 = np.broadcast_to(s[:, None], x1.shape)
    local = np.concatenate([[[0.0, c2[0], s0 - caps[0]]],
                            np.stack([x1, x2, x3], axis=-1).reshape(-1, 3),
                            [[0.0, c2[-1], s1 + caps[1]]]])
    return np.asarray(origin, dtype=np.float64) + local @ frame.T


def _chain(s: np.ndarray, joints: tuple[str, ...], bounds, halves) -> np.ndarray:
    """Skinning weights (n, J) along a chain: ``joints[k]`` between ``bounds[k-1:k+1]``.

    Across each bound the weight moves to the next joint with a smoothstep over
    ``bound +- half``. Rows are non-negative and sum to 1.
    """
    beta = [_smoothstep((s - b + h) / (2.0 * h)) for b, h in zip(bounds, halves)]
    cum = np.cumprod(np.stack([np.ones_like(s), *beta, np.zeros_like(s)], axis=1), axis=1)
    W = np.zeros((len(s), len(JOINTS)))
    for k, name in enumerate(joints):
        W[:, _JI[name]] += cum[:, k] - cum[:, k + 1]
    return W / W.sum(axis=1, keepdims=True)


# ------------------------------------------------------------------------ the layout

_PART_COUNTS = {  # sectors, body rings, cap rings (at resolution 1)
    "torso": (40, 32, 4), "neck": (20, 8, 2), "head": (48, 36, 0),
    "upper_arm": (16, 16, 3), "forearm": (16, 16, 3), "palm": (16, 10, 3),
    "finger": (8, 14, 2), "thigh": (20, 18, 3), "shin": (20, 18, 3), "foot": (16, 14, 3),
}
_SIDE_PARTS = ("upper_arm", "forearm", "palm", *_FINGERS, "thigh", "shin", "foot")
_PARTS = ("torso", "neck", "head", *(f"{s}_{p}" for s in "lr" for p in _SIDE_PARTS))

# fingers: knuckle offset along the palm (x, palm lengths) and across it (z, half-widths),
# spread angle (degrees, towards +z), length (middle-finger lengths), joint fractions
_FINGER_LAYOUT = {"index": (-0.03, 0.62, 5.0, 0.92), "middle": (0.0, 0.2, 1.0, 1.0),
                  "ring": (-0.03, -0.22, -3.0, 0.95), "pinky": (-0.10, -0.62, -8.0, 0.76)}
_PHALANGES = (0.45, 0.30)  # first two of three segments, fractions of the finger
_THUMB_DIR = _unit([0.55, -0.12, 0.83])  # left thumb, rest pose
_THUMB_SEGMENTS = (0.40, 0.32)
_THUMB_CURL = _unit([_THUMB_DIR[2], 0.0, -_THUMB_DIR[0]])  # curls the left thumb to the palm


def _layout(b: BodyShape) -> dict:
    """Joint positions (left side) and part dimensions of a body, before normalisation."""
    H = b.height
    vertical = np.array([b.leg_ratio, b.torso_ratio, b.neck_ratio, b.head_ratio])
    L_leg, L_torso, L_neck, L_head = vertical / vertical.sum() * H
    hip_y = L_leg
    neck_y = hip_y + L_torso
    head_y = neck_y + L_neck
    shoulder_y = neck_y - 0.05 * L_torso
    root = np.sqrt(b.limb_thickness)
    L_arm = b.arm_ratio * H
    L_fore = b.forearm_share * L_arm
    L_hand = b.hand_ratio * H
    shoulder = np.array([0.5 * b.shoulder_width * H, shoulder_y, 0.0])
    elbow = shoulder + [L_arm - L_fore, 0.0, 0.0]
    wrist = elbow + [L_fore, 0.0, 0.0]
    ankle_y = 0.085 * L_leg
    hip = np.array([0.5 * b.hip_width * H, hip_y, 0.0])
    ankle = np.array([hip[0] + 0.03 * L_leg, ankle_y, 0.0])
    lay = {
        "H": H, "L_torso": L_torso, "L_neck": L_neck, "L_head": L_head, "hip_y": hip_y,
        "neck_y": neck_y, "head_y": head_y, "shoulder_y": shoulder_y,
        "p": 2.0 + 8.0 * b.squareness, "r_ua": b.arm_radius * H * b.limb_thickness,
        "r_th": b.leg_radius * H * b.limb_thickness, "r_neck": 0.031 * H * root,
        "palm_len": 0.53 * L_hand, "palm_w": 0.22 * L_hand * root,
        "palm_t": 0.075 * L_hand * root, "r_f": 0.042 * L_hand * root,
        "finger_len": 0.47 * L_hand, "ankle_y": ankle_y, "foot_len": b.foot_ratio * H,
        "foot_w": 0.19 * b.foot_ratio * H * root,
    }
    joints = {"pelvis": [0.0, hip_y + 0.08 * L_torso, 0.0],
              "spine": [0.0, hip_y + 0.35 * L_torso, 0.0],
              "chest": [0.0, hip_y + 0.65 * L_torso, 0.0],
              "neck": [0.0, neck_y, 0.0], "head": [0.0, head_y, 0.0],
              "l_clavicle": [0.12 * b.shoulder_width * H, shoulder_y, 0.0],
              "l_shoulder": shoulder, "l_elbow": elbow, "l_wrist": wrist,
              "l_hip": hip, "l_knee": hip + 0.49 * (ankle - hip), "l_ankle": ankle}
    fingers = {}
    base = wrist + [0.15 * lay["palm_len"], -0.2 * lay["palm_t"], 0.5 * lay["palm_w"]]
    fingers["thumb"] = (base, _THUMB_DIR, 0.62 * L_hand, 1.2 * lay["r_f"], _THUMB_SEGMENTS)
    for name, (dx, dz, spread, length) in _FINGER_LAYOUT.items():
        base = wrist + [lay["palm_len"] * (1.0 + dx), 0.0, dz * lay["palm_w"]]
        angle = np.radians(spread)
        direction = np.array([np.cos(angle), 0.0, np.sin(angle)])
        fingers[name] = (base, direction, length * lay["finger_len"], lay["r_f"], _PHALANGES)
    for name, (base, direction, length, _, segments) in fingers.items():
        joints[f"l_{name}1"] = base
        joints[f"l_{name}2"] = base + segments[0] * length * direction
        joints[f"l_{name}3"] = base + (segments[0] + segments[1]) * length * direction
    lay["fingers"] = fingers
    J = np.zeros((len(JOINTS), 3))
    for name, position in joints.items():
        J[_JI[name]] = position
        if name.startswith("l_"):
            J[_JI[_mirror_name(name)]] = np.asarray(position) * _MIRROR
    lay["joints"] = J
    return lay


def _joint(lay, name) -> np.ndarray:
    return lay["joints"][_JI[name]]


# ----------------------------------------------------------------------------- parts
# Each part function returns (V (n_p, 3), W (n_p, J), landmarks {name: local index}).


def _torso(lay, counts):
    from scipy.interpolate import PchipInterpolator

    H, p = lay["H"], lay["p"]
    shape = lay["shape"]
    hip_y, neck_y = lay["hip_y"], lay["neck_y"]
    spine_y, chest_y = _joint(lay, "spine")[1], _joint(lay, "chest")[1]
    y0 = hip_y - 0.05 * lay["L_torso"]
    y1 = lay["shoulder_y"] + 0.3 * lay["r_ua"]
    a_hip = _joint(lay, "l_hip")[0] + 0.85 * lay["r_th"]
    a_chest = shape.chest_width * H
    a_top = max(0.9 * a_chest, _joint(lay, "l_shoulder")[0] - 0.5 * lay["r_ua"])
    knots = [0.0, (spine_y - y0) / (y1 - y0), (chest_y - y0) / (y1 - y0), 1.0]
    width = PchipInterpolator(knots, [a_hip, shape.waist_width * H, a_chest, a_top])
    d = shape.torso_depth
    depth = PchipInterpolator(knots, [d * a_hip, 1.05 * d * shape.waist_width * H,
                                      d * a_chest, 0.7 * d * a_chest])
    t_chest = knots[2] + 0.08

    def relief(t, psi):
        pecs = _gauss(t - t_chest, 0.08) * (_gauss(psi - 0.4, 0.3) + _gauss(psi + 0.4, 0.3))
        glutes = _gauss(t - 0.08, 0.1) * _gauss(np.abs(psi) - (np.pi - 0.45), 0.35)
        return 0.08 * d * a_chest * pecs + 0.12 * d * a_hip * glutes

    V = _capsule([0, 0, 0], _frame([0, 1, 0], [0, 0, 1]), y0, y1,
                 (0.6 * d * a_hip, 0.5 * 0.7 * d * a_chest), counts, width, depth, p,
                 relief=relief)
    L_t = lay["L_torso"]
    W = _chain(V[:, 1], ("pelvis", "spine", "chest", "neck"), (spine_y, chest_y, neck_y),
               (0.15 * 0.27 * L_t, 0.15 * 0.3 * L_t, 0.15 * min(0.3 * L_t, lay["L_neck"])))
    sx = _joint(lay, "l_shoulder")[0]
    clav = (_smoothstep((np.abs(V[:, 0]) - 0.35 * sx) / (0.4 * sx))
            * _smoothstep((V[:, 1] - chest_y) / (lay["shoulder_y"] - chest_y)))
    W *= (1.0 - clav)[:, None]
    for side, sign in (("l", 1.0), ("r", -1.0)):
        W[:, _JI[f"{side}_clavicle"]] += np.where(sign * V[:, 0] > 0, clav, 0.0)
    return V, W


def _neck(lay, counts):
    r = lay["r_neck"]
    y0 = lay["neck_y"] - 0.1 * lay["L_torso"]
    y1 = lay["head_y"] + 0.25 * lay["L_head"]
    V = _capsule([0, 0, 0], _frame([0, 1, 0], [0, 0, 1]), y0, y1, (0.5 * r, 0.5 * r),
                 counts, lambda t: r * (1.0 - 0.1 * t), lambda t: 0.95 * r * (1.0 - 0.1 * t),
                 lay["p"])
    h = 0.25 * lay["L_neck"]
    W = _chain(V[:, 1], ("chest", "neck", "head"), (lay["neck_y"], lay["head_y"]), (h, h))
    return V, W


# head features: (latitude, radians) of the rings carrying them
_NOSE_LAT, _EYE_LAT, _BROW_LAT, _MOUTH_LAT, _CHIN_LAT = -0.12, 0.12, 0.28, -0.38, -0.62
_EYE_PSI, _HEAD_WARP = 0.36, 0.5


def _head_lat(k: int) -> np.ndarray:
    return -0.5 * np.pi + np.pi * (np.arange(k) + 1) / (k + 1)


def _head_ring(k: int, lat: float) -> int:
    return int(np.argmin(np.abs(_head_lat(k) - lat)))


def _head_relief(lat, psi, nose_lat):
    """Outward displacement of the head surface, in head heights."""
    nose = _gauss(psi, 0.11) * (_gauss(lat - nose_lat, 0.07)
                                + 0.45 * _gauss(lat - nose_lat - 0.17, 0.12))
    brow = _gauss(lat - _BROW_LAT, 0.07) * np.exp(-((psi / 0.5) ** 4))
    eyes = _gauss(lat - _EYE_LAT, 0.08) * (_gauss(psi - _EYE_PSI, 0.13)
                                          + _gauss(psi + _EYE_PSI, 0.13))
    mouth = _gauss(lat - _MOUTH_LAT, 0.05) * _gauss(psi, 0.22)
    chin = _gauss(lat - _CHIN_LAT, 0.1) * _gauss(psi, 0.25)
    ears = _gauss(lat - 0.02, 0.14) * _gauss(np.abs(psi) - 0.5 * np.pi, 0.1)
    return 0.10 * nose + 0.035 * brow - 0.04 * eyes + 0.02 * mouth + 0.045 * chin + 0.07 * ears


def _head(lay, counts):
    n, k, _ = counts
    Lh, p, size = lay["L_head"], lay["p"], lay["shape"].head_size
    cy, c = lay["head_y"] + 0.42 * Lh, 0.58 * Lh
    a, b, z0 = 0.34 * Lh * size, 0.43 * Lh * size, 0.04 * Lh
    lat = _head_lat(k)
    psi = _angles(n, _HEAD_WARP)
    polar = _superellipse(lat, p)  # a superellipse profile, sampled by angle
    rise = polar * np.sin(lat)
    spread = polar * np.cos(lat) * (1.0 - 0.18 * _smoothstep(-lat / (0.5 * np.pi)))
    r = _superellipse(psi, p)
    X = a * spread[:, None] * (r * np.sin(psi))[None, :]
    Z = z0 + b * spread[:, None] * (r * np.cos(psi))[None, :]
    Y = np.broadcast_to((cy + c * rise)[:, None], X.shape)
    normal = np.stack([X / a**2, (Y - cy) / c**2, (Z - z0) / b**2], axis=-1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    nose_lat = lat[_head_ring(k, _NOSE_LAT)]
    D = Lh * _head_relief(lat[:, None], psi[None, :], nose_lat)
    rings = np.stack([X, Y, Z], axis=-1) + D[..., None] * normal
    V = np.concatenate([[[0.0, cy - c, z0]], rings.reshape(-1, 3), [[0.0, cy + c, z0]]])
    W = np.zeros((len(V), len(JOINTS)))
    W[:, _JI["head"]] = 1.0
    return V, W


def _arm_weights(lay, V):
    s = V[:, 0] - _joint(lay, "l_shoulder")[0]
    L_up = _joint(lay, "l_elbow")[0] - _joint(lay, "l_shoulder")[0]
    L_fore = _joint(lay, "l_wrist")[0] - _joint(lay, "l_elbow")[0]
    return _chain(s, ("l_clavicle", "l_shoulder", "l_elbow", "l_wrist"),
                  (0.0, L_up, L_up + L_fore), (0.1 * L_up, 0.1 * L_fore, 0.1 * L_fore))


def _upper_arm(lay, counts):
    r = lay["r_ua"]
    shoulder, elbow = _joint(lay, "l_shoulder"), _joint(lay, "l_elbow")
    L = elbow[0] - shoulder[0]

    def radius(t):
        return r * (1.0 - 0.22 * t + 0.06 * _gauss(t - 0.5, 0.2))

    V = _capsule(shoulder, _frame([1, 0, 0], [0, 0, 1]), -0.25 * r, L, (0.9 * r, 0.55 * r),
                 counts, radius, lambda t: 0.95 * radius(t), lay["p"])
    return V, _arm_weights(lay, V)


def _forearm(lay, counts):
    r = lay["r_ua"]
    elbow, wrist = _joint(lay, "l_elbow"), _joint(lay, "l_wrist")
    bulge = lambda t: 0.08 * _gauss(t - 0.25, 0.2)  # noqa: E731
    V = _capsule(elbow, _frame([1, 0, 0], [0, 0, 1]), 0.0, wrist[0] - elbow[0],
                 (0.6 * r, 0.35 * r), counts, lambda t: r * (0.8 - 0.3 * t + bulge(t)),
                 lambda t: r * (0.8 - 0.15 * t + bulge(t)), lay["p"])
    return V, _arm_weights(lay, V)


def _palm(lay, counts):
    length, width, thick = lay["palm_len"], lay["palm_w"], lay["palm_t"]
    V = _capsule(_joint(lay, "l_wrist"), _frame([1, 0, 0], [0, 0, 1]), 0.0,
                 length - 0.6 * thick, (0.8 * thick, thick), counts,
                 lambda t: thick * (0.85 + 0.15 * _smoothstep(t / 0.5)),
                 lambda t: width * (0.72 + 0.28 * _smoothstep(t / 0.45)), max(lay["p"], 3.0))
    return V, _arm_weights(lay, V)


def _finger(lay, counts, name):
    base, direction, length, r, segments = lay["fingers"][name]
    tip = 0.75 * r
    s1 = length - tip
    joints_s = (segments[0] * length, (segments[0] + segments[1]) * length)
    thumb = name == "thumb"

    def radius(t):
        s = t * s1
        knuckles = sum(_gauss(s - sj, 0.05 * length) for sj in joints_s)
        return r * ((1.15 - 0.4 * t) if thumb else (1.0 - 0.25 * t)) + 0.1 * r * knuckles

    V = _capsule(base, _frame(direction, [0, 1, 0]), 0.0, s1, (1.2 * r, tip), counts,
                 radius, lambda t: 0.85 * radius(t), min(lay["p"], 4.0))
    s = (V - base) @ direction
    seg = (segments[0], segments[1], 1.0 - segments[0] - segments[1])
    W = _chain(s, ("l_wrist", f"l_{name}1", f"l_{name}2", f"l_{name}3"),
               (0.0, *joints_s), tuple(0.125 * f * length for f in seg))
    return V, W


def _leg_axis(lay):
    hip, ankle = _joint(lay, "l_hip"), _joint(lay, "l_ankle")
    return hip, _unit(ankle - hip), float(np.linalg.norm(ankle - hip))


def _leg_weights(lay, V):
    hip, d, L = _leg_axis(lay)
    L_th = float(np.linalg.norm(_joint(lay, "l_knee") - hip))
    L_sh = L - L_th
    return _chain((V - hip) @ d, ("pelvis", "l_hip", "l_knee", "l_ankle"), (0.0, L_th, L),
                  (0.1 * L_th, 0.1 * L_sh, 0.1 * L_sh))


def _thigh(lay, counts):
    r = lay["r_th"]
    hip, d, _ = _leg_axis(lay)
    L = float(np.linalg.norm(_joint(lay, "l_knee") - hip))
    V = _capsule(hip, _frame(d, [0, 0, 1]), -0.35 * r, L, (0.9 * r, 0.45 * r), counts,
                 lambda t: r * (1.0 - 0.38 * t), lambda t: 0.97 * r * (1.0 - 0.38 * t),
                 lay["p"])
    return V, _leg_weights(lay, V)


def _shin(lay, counts):
    r = lay["r_th"]
    knee = _joint(lay, "l_knee")
    _, d, _ = _leg_axis(lay)
    L = float(np.linalg.norm(_joint(lay, "l_ankle") - knee))

    def radius(t):
        return r * (0.6 - 0.2 * t + 0.04 * _gauss(t - 0.3, 0.2))

    def relief(t, psi):
        kneecap = _gauss(t - 0.05, 0.07) * _gauss(psi, 0.45)
        calf = _gauss(t - 0.3, 0.15) * _gauss(np.abs(psi) - np.pi, 0.6)
        return r * (0.12 * kneecap + 0.12 * calf)

    V = _capsule(knee, _frame(d, [0, 0, 1]), 0.0, L, (0.8 * 0.6 * r, 0.9 * 0.4 * r), counts,
                 radius, radius, lay["p"], relief=relief)
    return V, _leg_weights(lay, V)


def _foot(lay, counts):
    length, width, ankle_y = lay["foot_len"], lay["foot_w"], lay["ankle_y"]
    ankle = _joint(lay, "l_ankle")
    origin = [ankle[0], 0.0, -0.2 * length]

    def height(t):
        return ankle_y * (0.62 - 0.35 * _smoothstep(t / 0.85))

    V = _capsule(origin, _frame([0, 0, 1], [0, 1, 0]), 0.12 * length, 0.86 * length,
                 (0.12 * length, 0.14 * length), counts,
                 lambda t: width * (0.62 + 0.38 * _smoothstep(t / 0.7) - 0.1 * t),
                 height, lay["p"], c2_fn=height)
    return V, _leg_weights(lay, V)


_BUILDERS: dict[str, Callable] = {
    "torso": _torso, "neck": _neck, "head": _head, "upper_arm": _upper_arm,
    "forearm": _forearm, "palm": _palm, "thigh": _thigh, "shin": _shin, "foot": _foot,
    **{f: (lambda name: lambda lay, counts: _finger(lay, counts, name))(f) for f in _FINGERS},
}


def _part_counts(part: str, resolution: float) -> tuple[int, int, int]:
    kind = part[2:] if part[:2] in ("l_", "r_") else part
    return _counts(_PART_COUNTS["finger" if kind in _FINGERS else kind], resolution)


# ------------------------------------------------------------------------- landmarks

_LIMB_POSITIONS = {"prox": 0.2, "mid": 0.5, "dist": 0.8}
_LIMB_DIRECTIONS = {"front": 0.0, "back": np.pi, "outer": -0.5 * np.pi, "inner": 0.5 * np.pi}

# (name, part, ring, angle): ring is "pole0", "pole1", a fraction of the body rings, or
# ("lat", latitude) on the head; angle psi: 0 = e2 (front), pi/2 = -e1 (left on the body).
_Ring = str | float | tuple[str, float]
_LandmarkSpec = tuple[str, str, _Ring, float]
_CENTRAL_LANDMARKS: tuple[_LandmarkSpec, ...] = (
    ("head_top", "head", "pole1", 0.0),
    ("nose_tip", "head", ("lat", _NOSE_LAT), 0.0),
    ("chin", "head", ("lat", _CHIN_LAT), 0.0),
    ("mouth", "head", ("lat", _MOUTH_LAT), 0.0),
    ("forehead", "head", ("lat", 0.5), 0.0),
    ("head_back", "head", ("lat", 0.1), np.pi),
    ("l_eye", "head", ("lat", _EYE_LAT), _EYE_PSI),
    ("l_ear", "head", ("lat", 0.02), 0.5 * np.pi),
    ("neck_front", "neck", 0.5, 0.0),
    ("neck_back", "neck", 0.5, np.pi),
    ("chest_front", "torso", 0.8, 0.0),
    ("l_chest", "torso", 0.78, 0.4),
    ("belly", "torso", 0.42, 0.0),
    ("pelvis_front", "torso", 0.1, 0.0),
    ("back_upper", "torso", 0.85, np.pi),
    ("back", "torso", 0.6, np.pi),
    ("back_lower", "torso", 0.35, np.pi),
    ("pelvis_back", "torso", 0.1, np.pi),
    ("l_waist", "torso", 0.45, 0.5 * np.pi),
    ("l_hip_side", "torso", 0.1, 0.5 * np.pi),
    ("l_buttock", "torso", 0.08, np.pi - 0.45),
)
# left-side parts; "r_" twins are their mirror images
_SIDE_LANDMARKS: tuple[_LandmarkSpec, ...] = (
    ("hand_tip", "middle", "pole1", 0.0),
    ("thumb_tip", "thumb", "pole1", 0.0),
    ("index_tip", "index", "pole1", 0.0),
    ("ring_tip", "ring", "pole1", 0.0),
    ("pinky_tip", "pinky", "pole1", 0.0),
    *((f"{f}_knuckle", f, 0.0, 0.0) for f in ("index", "middle", "ring", "pinky")),
    ("palm", "palm", 0.5, 0.5 * np.pi),
    ("hand_back", "palm", 0.5, -0.5 * np.pi),
    ("shoulder_top", "upper_arm", 0.0, -0.5 * np.pi),
    ("kneecap", "shin", 0.05, 0.0),
    ("ankle_outer", "shin", 1.0, -0.5 * np.pi),
    ("ankle_inner", "shin", 1.0, 0.5 * np.pi),
    ("toe", "foot", "pole1", 0.0),
    ("heel", "foot", "pole0", 0.0),
    ("foot_top", "foot", 0.5, 0.0),
    ("sole", "foot", 0.5, np.pi),
)


def _landmark_specs() -> list[_LandmarkSpec]:
    """Every landmark as (name, part, ring, angle), in :data:`LANDMARK_NAMES` order."""
    specs: list[_LandmarkSpec] = []
    for side in "lr":
        for part in ("upper_arm", "forearm", "thigh", "shin"):
            for pos, fraction in _LIMB_POSITIONS.items():
                for direction, angle in _LIMB_DIRECTIONS.items():
                    specs.append((f"{side}_{part}_{pos}_{direction}", f"{side}_{part}",
                                  fraction, angle))
    for name, part, ring, angle in _CENTRAL_LANDMARKS:
        specs.append((name, part, ring, angle))
        if name.startswith("l_"):
            specs.append((_mirror_name(name), part, ring, -angle))
    for side in "lr":
        for name, part, ring, angle in _SIDE_LANDMARKS:
            specs.append((f"{side}_{name}", f"{side}_{part}", ring, angle))
    return specs


LANDMARK_NAMES: tuple[str, ...] = tuple(name for name, *_ in _landmark_specs())
"""All landmark names in a fixed order (161): 96 limb points, then the rest."""

_PICKED_CENTRE = ("head_top", "nose_tip", "chin", "head_back", "neck_front", "neck_back",
                  "chest_front", "belly", "pelvis_front", "back_upper", "back_lower",
                  "pelvis_back")
_PICKED_SIDE = ("waist", "hip_side", "chest", "shoulder_top", "upper_arm_mid_outer",
                "upper_arm_mid_inner", "upper_arm_dist_front", "forearm_mid_outer",
                "forearm_mid_inner", "forearm_dist_back", "hand_tip", "thumb_tip", "hand_back",
                "palm", "thigh_prox_outer", "thigh_mid_inner", "thigh_mid_front",
                "thigh_dist_outer", "kneecap", "shin_mid_back", "shin_mid_inner", "ankle_outer",
                "heel", "toe")
PICKED_LANDMARK_NAMES: tuple[str, ...] = (
    *_PICKED_CENTRE, *(f"{side}_{name}" for side in "lr" for name in _PICKED_SIDE))
"""The 60 labels to pick on a character of one's own (those of ``data/characters/``): 12
on the centre line, then 24 on the left and the same 24 on the right (the torso's sides,
both sides of every limb: what keeps each limb's cage apart from the torso's)."""

RIGID_PARTS: tuple[str, ...] = ("head", "chest", "pelvis", *(
    f"{side}_{part}" for side in "lr"
    for part in ("upper_arm", "forearm", "hand", "thigh", "shin", "foot")))
"""The parts of the body that move rigidly, as :func:`landmark_part` names them."""

RIGID_PARENTS: dict[str, str | None] = {
    "pelvis": None, "chest": "pelvis", "head": "chest",
    **{f"{side}_{part}": parent if parent in ("chest", "pelvis") else f"{side}_{parent}"
       for side in "lr"
       for part, parent in (("upper_arm", "chest"), ("forearm", "upper_arm"),
                            ("hand", "forearm"), ("thigh", "pelvis"), ("shin", "thigh"),
                            ("foot", "shin"))}}
"""Rigid part -> the part it hangs from along the skeleton (``None`` for the pelvis)."""

# the torso's landmarks that move with the chest (the rest move with the pelvis); the
# shoulder tops sit on the arm's first ring but turn with the chest more than the arm
_CHEST_LANDMARKS = frozenset({"chest_front", "l_chest", "r_chest", "back_upper",
                              "l_shoulder_top", "r_shoulder_top"})


def landmark_part(name: str) -> str | None:
    """The rigid part of the body a landmark lies on.

    Parameters
    ----------
    name : str
        A landmark name of :data:`LANDMARK_NAMES`.

    Returns
    -------
    str or None
        One of :data:`RIGID_PARTS` (fingers and palm are the hand, the neck and upper torso
        the chest, the lower torso the pelvis); None for a name the humanoid does not have.

    Examples
    --------
    >>> landmark_part("l_index_tip"), landmark_part("neck_back"), landmark_part("belly")
    ('l_hand', 'chest', 'pelvis')
    >>> landmark_part("tail_tip") is None
    True
    """
    return _LANDMARK_PARTS.get(name)


def _rigid_part(name: str, part: str) -> str:
    if name in _CHEST_LANDMARKS or part == "neck":
        return "chest"
    if part == "torso":
        return "pelvis"
    if part[:2] in ("l_", "r_") and part[2:] in ("palm", *_FINGERS):
        return f"{part[:2]}hand"
    return part


_LANDMARK_PARTS = {name: _rigid_part(name, part) for name, part, *_ in _landmark_specs()}


def _landmark_local(spec, counts) -> int:
    """Index of a landmark within its (left or central) part."""
    name, part, ring, angle = spec
    n = counts[0]
    rings = counts[1] if part == "head" else counts[1] + 2 * counts[2]
    if ring == "pole0":
        return 0
    if ring == "pole1":
        return 1 + rings * n
    if part == "head":
        warp = _HEAD_WARP
        index = _head_ring(counts[1], ring[1])
    else:
        warp = 0.0
        index = _ring_index(counts, ring)
    sector = _sector(n, abs(angle), warp)
    if angle < 0 and part in ("head", "neck", "torso"):
        sector = (n - sector) % n  # exact mirror twin of the left landmark
    elif angle < 0:
        sector = _sector(n, angle, warp)
    return _vertex(counts, index, sector)


# ------------------------------------------------------------------------ rotations


def rotation_matrix(axis_angle: ArrayLike) -> Floats:
    """The (3, 3) rotation of an axis-angle vector (radians; Rodrigues' formula).

    Examples
    --------
    >>> bool(np.allclose(rotation_matrix([0.0, 0.0, np.pi / 2]) @ [1.0, 0, 0], [0, 1, 0]))
    True
    """
    return _rodrigues(axis_angle)


def _rodrigues(axis_angle) -> np.ndarray:
    v = np.asarray(axis_angle, dtype=np.float64)
    theta = float(np.linalg.norm(v))
    if theta == 0.0:
        return np.eye(3)
    k = v / theta
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(theta) * K + (1.0 - np.cos(theta)) * (K @ K)


def _as_rotation(name: str, value) -> np.ndarray:
    R = np.asarray(value, dtype=np.float64)
    if R.shape == (3,):
        if not np.all(np.isfinite(R)):
            raise ValueError(f"joint {name!r}: axis-angle must be finite, not {R}")
        return _rodrigues(R)
    if R.shape != (3, 3):
        raise ValueError(f"joint {name!r}: expected a (3, 3) rotation or a (3,) axis-angle, "
                         f"got shape {R.shape}")
    if (not np.all(np.isfinite(R)) or np.abs(R.T @ R - np.eye(3)).max() > 1e-6
            or np.linalg.det(R) < 0):
        raise ValueError(f"joint {name!r}: the (3, 3) matrix is not a rotation")
    return R


# ------------------------------------------------------------------------------- rig


class Rig:
    """A body in rest pose with a skeleton, skinning weights and landmarks.

    Build it with :func:`rig`; pose it with :meth:`pose`.

    Attributes
    ----------
    shape : BodyShape
    vertices : (n, 3) float64
        Rest-pose (T-pose) vertices.
    faces : (m, 3) int64
        The same for every body shape at a given resolution.
    joints : (J, 3) float64
        Rest joint positions, in :data:`JOINTS` order.
    weights : (n, J) float64
        Skinning weights: non-negative, rows sum to 1, at most 3 non-zeros per row.
    landmarks : dict[str, int]
        Landmark name -> vertex index (:data:`LANDMARK_NAMES`, same for every body).
    parts : dict[str, slice]
        Part name (``"torso"``, ``"head"``, ``"l_index"``, ...) -> its vertex range; each
        part is one closed connected component.
    """

    def __init__(self, shape: BodyShape, vertices: Vertices, faces: Faces, joints: Floats,
                 weights: Floats, landmarks: dict[str, int], parts: dict[str, slice]) -> None:
        self.shape = shape
        self.vertices = vertices
        self.faces = faces
        self.joints = joints
        self.weights = weights
        self.landmarks = landmarks
        self.parts = parts

    def __repr__(self) -> str:
        return (f"Rig({len(self.vertices)} vertices, {len(self.faces)} faces, "
                f"{len(self.joints)} joints)")

    def _locals(self, pose: Mapping | None) -> np.ndarray:
        R = np.broadcast_to(np.eye(3), (len(JOINTS), 3, 3)).copy()
        for name, value in (pose or {}).items():
            if name not in _JI:
                raise ValueError(f"unknown joint {name!r} in pose; joints are {', '.join(JOINTS)}")
            R[_JI[name]] = _as_rotation(name, value)
        return R

    def joint_transforms(self, pose: Mapping | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Every joint's global transform in ``pose`` (as for :meth:`pose`).

        Returns
        -------
        A : (J, 3, 3) float64
        t : (J, 3) float64
            A rest-pose point rigidly attached to joint ``j`` goes to ``A[j] @ x + t[j]``.
        """
        return self._transforms(pose)

    def _transforms(self, pose) -> tuple[np.ndarray, np.ndarray]:
        """Global (A (J, 3, 3), t (J, 3)) of every joint: x -> A x + t."""
        R = self._locals(pose)
        A, t = np.empty_like(R), np.empty((len(JOINTS), 3))
        for j, p in enumerate(_PARENT_INDEX):
            x = self.joints[j]
            if p < 0:
                A[j], t[j] = R[j], x - R[j] @ x
            else:
                A[j] = A[p] @ R[j]
                t[j] = A[p] @ (x - R[j] @ x) + t[p]
        return A, t

    def pose(self, pose: Mapping | None = None) -> np.ndarray:
        """Vertices posed by linear blend skinning.

        Parameters
        ----------
        pose : dict[str, array_like], optional
            Joint name -> local rotation, a (3, 3) matrix or a (3,) axis-angle vector
            (radians), relative to the parent's frame; the rest pose is the identity
            everywhere. Missing joints keep their rest orientation. The root (pelvis)
            rotates the whole body about the pelvis joint; there is no translation.

        Returns
        -------
        (n, 3) float64
            Posed vertices (the faces are :attr:`faces`).

        Raises
        ------
        ValueError
            For an unknown joint name (the message names it) or a value that is not a
            rotation.

        Examples
        --------
        >>> r = rig(resolution=0.5)
        >>> bool((r.pose({}) == r.vertices).all())
        True
        >>> V = r.pose({"l_elbow": [0.0, -1.2, 0.0]})  # bend the left elbow forward
        """
        A, t = self._transforms(pose)
        J = len(JOINTS)
        M = (self.weights @ (A - np.eye(3)).reshape(J, 9)).reshape(-1, 3, 3)
        V = self.vertices
        return V + np.einsum("nij,nj->ni", M, V) + self.weights @ t

    def posed_joints(self, pose: Mapping | None = None) -> np.ndarray:
        """Joint positions in a pose.

        Parameters
        ----------
        pose : dict[str, array_like], optional
            As for :meth:`pose`.

        Returns
        -------
        (J, 3) float64
            In :data:`JOINTS` order; bone lengths are those of the rest pose.

        Examples
        --------
        >>> r = rig(resolution=0.5)
        >>> bool((r.posed_joints({}) == r.joints).all())
        True
        """
        A, t = self._transforms(pose)
        out = self.joints.copy()
        for j, p in enumerate(_PARENT_INDEX):
            if p >= 0:
                out[j] = A[p] @ self.joints[j] + t[p]
        return out


def _body(body) -> BodyShape:
    if isinstance(body, BodyShape):
        return body
    if isinstance(body, str):
        if body not in BODY_SHAPES:
            raise ValueError(f"unknown body {body!r}; available: {', '.join(BODY_SHAPES)}")
        return BODY_SHAPES[body]
    raise TypeError(f"body must be a name or a BodyShape, not {type(body).__name__}")


def rig(body: str | BodyShape = "template", *, resolution: float = 1.0) -> Rig:
    """A body in rest pose, ready to be posed.

    Parameters
    ----------
    body : str or BodyShape, default "template"
        A name in :data:`BODY_SHAPES` or any :class:`BodyShape`.
    resolution : float, default 1.0
        Scales the ring and sector counts (9,538 vertices at 1, 2,770 at 0.5).
        Faces and landmark indices depend on it, never on the body.

    Returns
    -------
    Rig

    Examples
    --------
    >>> a, b = rig("template", resolution=0.5), rig("stocky", resolution=0.5)
    >>> bool((a.faces == b.faces).all()), a.landmarks == b.landmarks
    (True, True)
    >>> round(float(a.vertices[:, 1].max()), 9), float(a.vertices[:, 1].min())
    (1.75, 0.0)
    """
    shape = _body(body)
    res = float(resolution)
    if not np.isfinite(res) or res <= 0:
        raise ValueError(f"resolution must be a positive number, not {resolution!r}")
    lay = _layout(shape)
    lay["shape"] = shape
    built = {}
    for part in ("torso", "neck", "head", *_SIDE_PARTS):
        name = part if part in ("torso", "neck", "head") else f"l_{part}"
        built[name] = _BUILDERS[part](lay, _part_counts(name, res))
    for part in _SIDE_PARTS:
        V, W = built[f"l_{part}"]
        built[f"r_{part}"] = (V * _MIRROR, W[:, _MIRROR_J])
    vertices, faces, weights, parts, start = [], [], [], {}, 0
    for name in _PARTS:
        V, W = built[name]
        counts = _part_counts(name, res)
        rings = counts[1] if name == "head" else counts[1] + 2 * counts[2]
        F = _tube_faces(rings, counts[0])
        if name.startswith("r_"):
            F = F[:, ::-1]
        vertices.append(V)
        faces.append(F + start)
        weights.append(W)
        parts[name] = slice(start, start + len(V))
        start += len(V)
    V = np.concatenate(vertices)
    joints = lay["joints"].copy()
    bottom, top = V[:, 1].min(), V[parts["head"].stop - 1, 1]
    scale = shape.height / (top - bottom)
    shift = np.array([0.0, bottom, 0.0])
    V = (V - shift) * scale
    joints = (joints - shift) * scale
    landmarks = {}
    for spec in _landmark_specs():
        part = spec[1]
        local = _landmark_local(spec, _part_counts(part, res))
        landmarks[spec[0]] = parts[part].start + local
    return Rig(shape, V, np.concatenate(faces), joints, np.concatenate(weights), landmarks,
               parts)


# ------------------------------------------------------------------------------ poses

_X, _Y, _Z = np.eye(3)
_LIMITS: dict[str, tuple] = {  # left side and centre: (axis, low, high degrees), composed
    "pelvis": ((_X, -10, 10), (_Y, -20, 20), (_Z, -8, 8)),
    "spine": ((_X, -20, 20), (_Z, -20, 20), (_Y, -25, 25)),
    "chest": ((_X, -20, 20), (_Z, -20, 20), (_Y, -25, 25)),
    "neck": ((_X, -30, 30), (_Z, -30, 30), (_Y, -30, 30)),
    "head": ((_X, -30, 30), (_Z, -30, 30), (_Y, -30, 30)),
    "clavicle": ((_Z, -10, 15), (_Y, -10, 10)),
    "shoulder": ((_Z, -80, 40), (_Y, -70, 30), (_X, -30, 30)),  # raise, swing (-: fwd), twist
    "elbow": ((_Y, -130, 0),),  # the forearm swings forward
    "wrist": ((_Z, -40, 40), (_Y, -25, 25)),
    "hip": ((_X, -90, 20), (_Z, 0, 35), (_Y, -20, 20)),  # flex (-: forward), abduct, twist
    "knee": ((_X, 0, 120),),  # the shin bends backwards only
    "ankle": ((_X, -25, 25), (_Z, -15, 15)),
}


def random_pose(seed: int, amount: float = 1.0) -> dict[str, np.ndarray]:
    """Plausible random local rotations within joint limits, for every joint.

    Angles are uniform within the limits (degrees, for the left side; the right side is
    mirrored): pelvis +-10/+-20/+-8; spine and chest bend +-20 (forward and sideways),
    twist +-25; neck and head +-30 about each axis; clavicles -10..15 up, +-10 forward;
    shoulders raise -80..40 from the T, swing 70 forward..30 back, twist +-30; elbows
    0..130 (forearm forward); wrists +-40 flex, +-25 deviation; hips flex -20..90,
    abduct 0..35, twist +-20; knees 0..120 (backwards only); ankles +-25, +-15. Fingers
    curl 0..80 per segment (thumb 0..60) around a per-hand grip with some jitter.

    Parameters
    ----------
    seed : int
    amount : float, default 1.0
        Scales every angle; 0 gives the rest pose (identity matrices).

    Returns
    -------
    dict[str, (3, 3) float64]
        Joint name -> local rotation, for every name in :data:`JOINTS`.

    Examples
    --------
    >>> P = random_pose(0)
    >>> len(P) == len(JOINTS), P["l_knee"].shape
    (True, (3, 3))
    >>> bool(np.allclose(random_pose(0, amount=0.0)["l_knee"], np.eye(3)))
    True
    """
    rng = np.random.default_rng(seed)
    amount = float(amount)
    grip = {side: float(rng.uniform(0.0, 1.0)) for side in "lr"}
    pose = {}
    for name in JOINTS:
        side, base = (name[0], name[2:]) if name[:2] in ("l_", "r_") else ("", name)
        if base[:-1] in _FINGERS:
            curl = np.clip(grip[side] + rng.uniform(-0.25, 0.25), 0.0, 1.0)
            if base.startswith("thumb"):
                R = _rodrigues(_THUMB_CURL * np.radians(60.0 * curl * amount))
            else:
                R = _rodrigues(-_Z * np.radians(80.0 * curl * amount))
        else:
            R = np.eye(3)
            for axis, lo, hi in _LIMITS[base]:
                R = R @ _rodrigues(axis * np.radians(rng.uniform(lo, hi) * amount))
        if side == "r":
            R = R * np.outer(_MIRROR, _MIRROR)  # M R M with M = diag(-1, 1, 1)
        pose[name] = R
    return pose


def humanoid(body: str | BodyShape = "template", pose: Mapping | None = None, *,
             resolution: float = 1.0) -> _Mesh:
    """A (posed) humanoid mesh.

    Parameters
    ----------
    body : str or BodyShape, default "template"
    pose : dict[str, array_like], optional
        Local joint rotations (see :meth:`Rig.pose`); the rest T-pose by default.
    resolution : float, default 1.0

    Returns
    -------
    V : (n, 3) float64
    F : (m, 3) int64

    Examples
    --------
    >>> V, F = humanoid("skinny", random_pose(2), resolution=0.5)
    >>> V.shape[1], F.shape[1]
    (3, 3)
    """
    r = rig(body, resolution=resolution)
    return (r.vertices.copy() if pose is None else r.pose(pose)), r.faces.copy()
