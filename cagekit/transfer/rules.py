"""Carry a template cage's motion onto a character's cage of the same topology.

The template's cage ``C_s`` moves to ``C_st`` (an example pose); the character's cage
``C_c`` (same faces, fitted to the character's rest pose) must move "the same way". Two
rules:

- ``"offsets"``, the paper's ``C_c + A (C_st - C_s)``: right when the two rest poses
  agree, but an arm that starts higher is pushed past the target.
- ``"pose"`` (deformation transfer on the cage, after Sumner & Popovic 2004; no
  correspondence problem since the cages share their faces): per face, the deformation
  gradient of ``C_s -> C_st`` is split ``R_t S_t`` and that of ``C_s -> C_c`` is split
  ``R_c S_c`` (polar decomposition); the new cage's face takes ``R_t S_t S_c``, the
  template's rotation and stretch after the character's own stretch, so the character's
  rest rotation is replaced (a T-pose example gives a T-pose, whatever the character's
  rest pose). The cage is the sparse least-squares fit of every face's edges to those
  gradients; its translation, which edges cannot fix, follows the offsets rule at the
  **root** of each component (:func:`root_weights`): the point inside ``C_s`` that the
  example moves least, preferring the cage's centre (a body turned about its pelvis stays
  pinned at the pelvis; a body the example carries along is carried by its centre, scaled
  like the offsets rule).

  With ``parts`` (the same points on the template's and the character's rigid parts,
  for example their landmarks grouped by limb: :func:`shape_rotations`) the pose rule
  also keeps the character's own shape where its part is oriented like the template's.
  A face of the character's cage is turned from the template's by its part's pose and by
  its shape (a wider shoulder slopes otherwise, a bigger head bulges otherwise): dropping
  the whole rotation ``R_c`` drops the shape too, keeping it keeps a rest pose that
  differs. So each part's rest rotation (the best rotation of its points on the template
  onto the character's) is taken out of ``R_c`` and the rest kept: in full for a part
  not turned, in proportion for one turned less than :data:`PART_ANGLE` from the
  template's rest, not at all from there on; a face's turn of a few degrees
  (:data:`SHAPE_NOISE`) is the fit's noise and dropped.

Both work in the template's frame: ``alignment`` maps it to the character's.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np
import scipy.sparse
import scipy.sparse.linalg
from numpy.typing import ArrayLike

from cagekit.cage import face_components, winding_numbers
from cagekit.coords.mvc import mean_value_coordinates
from cagekit.errors import InputError
from cagekit.geometry import as_vertices, polar
from cagekit.geometry.alignment import Similarity, similarity_alignment
from cagekit.geometry.frame import Frame
from cagekit.typed import Floats, Vertices

__all__ = ["RULES", "PART_ANGLE", "PART_REACH", "PART_SPREAD", "SHAPE_NOISE", "face_gradients",
           "has_rotation", "root_weights", "shape_rotations", "transfer_offsets",
           "transfer_pose", "transfer_cage"]

#: the rules :func:`transfer_cage` knows
RULES = ("pose", "offsets")
#: share of the points sampled inside the template's cage whose score gap sets the root's
#: softness (:func:`root_weights`)
ROOT_SHARE = 0.02
#: points per axis of the grid sampled over the template cage's bounding box for the root
ROOT_GRID = 24
#: the root's preference for the cage's centre: distance from it counts this much against
#: the motion (a turn about a pivot of more than 6 degrees moves points near the centre
#: more than this; a translation moves every point alike, and the centre is taken)
ROOT_CENTRE = 0.1
#: a part of the character turned this many degrees or more from the template's rest
#: orientation is posed otherwise: its faces take the example's rotations alone; one turned
#: less keeps its own rotations (its shape) in proportion (:func:`shape_rotations`; chosen
#: on a variant that carried the parts' points through the cages, docs/benchmarks.md)
PART_ANGLE = 10.0
#: how far a part reaches over the cage's faces beyond the part nearest to them, in
#: template-cage diagonals (a Gaussian of the distance; chosen as PART_ANGLE was)
PART_REACH = 0.01
#: a part's points must spread across their line by this share of their length at least
#: to have a rotation (:func:`has_rotation`)
PART_SPREAD = 0.05
#: a face's shape rotation (degrees) up to the first value is the fit's noise and dropped,
#: from the second on it is shape and kept, in between in proportion
#: (:func:`shape_rotations`)
SHAPE_NOISE = (2.0, 5.0)


def _frames(V, F) -> np.ndarray:
    """(m, 3, 3) per face: the columns are two edges and the scaled normal (Sumner)."""
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    e1, e2 = b - a, c - a
    n = np.cross(e1, e2)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    if np.any(length <= 0):
        raise InputError("a cage face has zero area: its deformation gradient is undefined")
    return np.stack([e1, e2, n / np.sqrt(length)], axis=2)


def face_gradients(rest_v: ArrayLike, deformed_v: ArrayLike, faces: ArrayLike) -> Floats:
    """Per-face deformation gradients of a triangle mesh (Sumner & Popovic 2004).

    Parameters
    ----------
    rest_v, deformed_v : (k, 3) array_like of float
        The same mesh before and after a deformation.
    faces : (m, 3) array_like of int

    Returns
    -------
    (m, 3, 3) float64
        ``T_f`` with ``T_f e = e'`` for both edges of face ``f`` from its first vertex and
        ``T_f n = n'`` for its normal scaled by ``1/sqrt(|n|)``.

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> bool(np.allclose(face_gradients(v, 2 * v + 1, f), 2 * np.eye(3)))
    True
    """
    F = np.asarray(faces, dtype=np.int64)
    rest = _frames(as_vertices(rest_v, "rest_v"), F)
    moved = _frames(as_vertices(deformed_v, "deformed_v"), F)
    return moved @ np.linalg.inv(rest)


def transfer_offsets(template_cage_v: ArrayLike, deformed_template_cage_v: ArrayLike,
                     character_cage_v: ArrayLike, alignment: Similarity) -> Vertices:
    """The paper's rule ``C_c + A (C_st - C_s)``, A the alignment's linear part.

    Parameters
    ----------
    template_cage_v, deformed_template_cage_v : (k, 3) array_like of float
        ``C_s`` and ``C_st``, in the template's frame.
    character_cage_v : (k, 3) array_like of float
        ``C_c``, in the character's frame.
    alignment : Similarity
        Template frame -> character frame.

    Returns
    -------
    (k, 3) float64

    Examples
    --------
    >>> A = Similarity(2.0, np.eye(3), np.zeros(3))
    >>> transfer_offsets(np.zeros((1, 3)), np.ones((1, 3)), np.full((1, 3), 5.0), A).tolist()
    [[7.0, 7.0, 7.0]]
    """
    offsets = (as_vertices(deformed_template_cage_v, "deformed_template_cage_v")
               - as_vertices(template_cage_v, "template_cage_v"))
    return as_vertices(character_cage_v, "character_cage_v") + alignment.apply_vectors(offsets)


def _edge_operator(F: np.ndarray, k: int) -> scipy.sparse.csr_matrix:
    """(3m, k): row ``3f + i`` is vertex ``(i+1) % 3`` minus vertex ``i`` of face ``f``."""
    m = len(F)
    rows = np.repeat(np.arange(3 * m), 2)
    heads, tails = F[:, [1, 2, 0]].ravel(), F.ravel()
    cols = np.stack([heads, tails], axis=1).ravel()
    vals = np.tile([1.0, -1.0], 3 * m)
    return scipy.sparse.csr_matrix((vals, (rows, cols)), shape=(3 * m, k))


def transfer_pose(template_cage_v: ArrayLike, deformed_template_cage_v: ArrayLike,
                  character_cage_v: ArrayLike, cage_f: ArrayLike, alignment: Similarity,
                  parts: Sequence[tuple[ArrayLike, ArrayLike]] | None = None) -> Vertices:
    """The pose-aware rule: the template's rotations, the character's stretch (see module).

    Parameters
    ----------
    template_cage_v, deformed_template_cage_v : (k, 3) array_like of float
        ``C_s`` and ``C_st``, in the template's frame.
    character_cage_v : (k, 3) array_like of float
        ``C_c``, in the character's frame; same faces as ``C_s``.
    cage_f : (m, 3) array_like of int
    alignment : Similarity
        Template frame -> character frame.
    parts : sequence of ((n_i, 3), (n_i, 3)) array_like of float, optional
        Per rigid part, points on the template's rest shape (template frame) and the same
        points on the character's (character frame), for example landmarks grouped by
        limb (:func:`shape_rotations`): the character keeps its own shape where its part
        is oriented like the template's. Without them every face takes the example's
        rotation alone.

    Returns
    -------
    (k, 3) float64
        The character's deformed cage, in the character's frame.

    Examples
    --------
    A character whose cage is the template's turned by 90 degrees, under an example that
    leaves the template still, is turned back (pose transfer; the offsets rule would
    leave it turned):

    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> turn = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    >>> out = transfer_pose(v, v, v @ turn.T, f, Similarity.identity())
    >>> bool(np.allclose(out - out.mean(0), v - v.mean(0)))
    True
    """
    Cs = as_vertices(template_cage_v, "template_cage_v")
    Ct = as_vertices(deformed_template_cage_v, "deformed_template_cage_v")
    F = np.asarray(cage_f, dtype=np.int64)
    Cc = alignment.invert(as_vertices(character_cage_v, "character_cage_v"))
    if not Cs.shape == Ct.shape == Cc.shape:
        raise InputError(f"the three cages must have the same vertex count, got {len(Cs)}, "
                         f"{len(Ct)} and {len(Cc)}")
    unused = np.setdiff1d(np.arange(len(Cs)), F)
    if len(unused):
        raise InputError(f"cage vertex {int(unused[0])} is used by no face: its position "
                         "cannot be transferred")
    # in a frame of unit size (the gradients are scale-free; zero-area tests are not)
    frame = Frame.of(Cs, unit="diagonal")
    if parts is None:
        shape = np.eye(3)
    else:
        pairs = [_part_points(part, i) for i, part in enumerate(parts)]
        shape = shape_rotations(Cs, Cc, F, [(P, alignment.invert(Q)) for P, Q in pairs])
    Cs, Ct, Cc = frame.to_unit(Cs), frame.to_unit(Ct), frame.to_unit(Cc)
    Rt, St = polar(face_gradients(Cs, Ct, F))
    _, Sc = polar(face_gradients(Cs, Cc, F))
    G = Rt @ St @ shape @ Sc
    # every face edge of C_s mapped by its face's gradient: the target edges
    D = _edge_operator(F, len(Cs))
    rest_edges = (D @ Cs).reshape(-1, 3, 3)
    target = np.einsum("fij,fej->fei", G, rest_edges).reshape(-1, 3)
    offsets = transfer_offsets(Cs, Ct, Cc, Similarity.identity())
    components = _vertex_components(len(Cs), F)
    roots = [root_weights(Cs, Ct, F, component) for component in components]
    weights = np.zeros(len(Cs))
    for component, root in zip(components, roots):
        weights[component] = np.abs(root)
    # min |D X - target|^2 + eps sum_i w_i |x_i - offsets_i|^2: the tiny term makes the
    # system definite; the translation is then set exactly below
    eps = 1e-8 * 6.0 * len(F) / weights.sum()
    K = (D.T @ D + eps * scipy.sparse.diags(weights)).tocsc()
    rhs = D.T @ target + eps * weights[:, None] * offsets
    X = scipy.sparse.linalg.splu(K).solve(rhs)
    # each component's root where the offsets rule puts it (its coordinates sum to one)
    for component, root in zip(components, roots):
        X[component] += root @ offsets[component] - root @ X[component]
    if not np.isfinite(X).all():
        raise FloatingPointError("the pose-aware transfer produced NaN or inf positions")
    return alignment.apply(frame.to_world(X))


def shape_rotations(template_cage_v: ArrayLike, character_cage_v: ArrayLike, cage_f: ArrayLike,
                    parts: Sequence[tuple[ArrayLike, ArrayLike]]) -> Floats:
    """Per face, the character's own rest rotation with its part's pose taken out.

    The face's rotation from the template's rest cage to the character's (``R_c`` of the
    polar decomposition) is its part's rotation ``R_p`` (the best rotation of the part's
    points on the template onto the same points on the character, Kabsch/Umeyama:
    :func:`cagekit.geometry.alignment.similarity_alignment`) times the
    face's shape rotation ``R_p^T R_c``. A part turned less than :data:`PART_ANGLE` from
    the template's rest orientation keeps that shape rotation in proportion
    (``1 - angle / PART_ANGLE``); one turned more is posed otherwise and keeps none. Faces
    blend the parts' rotations and shares with Gaussian weights of their distance to each
    part's points beyond the nearest part's (:data:`PART_REACH` template-cage diagonals).
    Then a face's kept rotation of under :data:`SHAPE_NOISE` ``[0]`` degrees is taken for
    the cage fit's noise and dropped, one over ``[1]`` kept, one in between kept in
    proportion: on the humanoid benchmark, ``t_pose`` (a T rest pose, proportions near the
    template's, remeshed) shows turns up to 5 degrees (median 2), and keeping them made it
    worse (0.99% -> 1.06% of the height).

    Parameters
    ----------
    template_cage_v : (k, 3) array_like of float
        ``C_s`` at rest.
    character_cage_v : (k, 3) array_like of float
        ``C_c``, brought into the template's frame (the alignment undone).
    cage_f : (m, 3) array_like of int
    parts : sequence of ((n_i, 3), (n_i, 3)) array_like of float
        Per rigid part (a limb segment, the chest, the head): points on the template's
        rest shape and the same points on the character's, in the template's frame; on
        each, at least 3 not on a line (:func:`has_rotation`).

    Returns
    -------
    (m, 3, 3) float64
        Proper rotations; the identity everywhere when ``parts`` is empty.

    Raises
    ------
    InputError
        A part with fewer than 3 points, on a line, with NaN, or with point counts that
        differ; cages that differ in vertex count; a template cage without extent.

    Examples
    --------
    A character whose cage is the template's own: nothing is turned, every face keeps
    the identity.

    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> parts = [(v[:4] * 0.5, v[:4] * 0.5), (v[4:] * 0.5, v[4:] * 0.5)]
    >>> bool(np.allclose(shape_rotations(v, v, f, parts), np.eye(3)))
    True
    """
    Cs = as_vertices(template_cage_v, "template_cage_v")
    Cc = as_vertices(character_cage_v, "character_cage_v")
    F = np.asarray(cage_f, dtype=np.int64)
    if Cs.shape != Cc.shape:
        raise InputError(f"the two cages must have the same vertex count, got {len(Cs)} "
                         f"and {len(Cc)}")
    Frame.of(Cs, unit="diagonal")  # refuses a cage without extent
    pairs = [_part_points(part, i) for i, part in enumerate(parts)]
    if not pairs:
        return np.broadcast_to(np.eye(3), (len(F), 3, 3)).copy()
    rotations = np.stack([similarity_alignment(P, Q).rotation for P, Q in pairs])
    keep = np.clip(1.0 - _angles(rotations) / PART_ANGLE, 0.0, 1.0)
    # each cage vertex's distance to each part, in diagonals; a face's weights are its
    # vertices' mean
    diagonal = float(np.linalg.norm(np.ptp(Cs, axis=0)))
    gaps = np.stack([np.linalg.norm(Cs[:, None] - P[None], axis=2).min(axis=1)
                     for P, _ in pairs], axis=1) / diagonal
    W = np.exp(-(((gaps - gaps.min(axis=1, keepdims=True)) / PART_REACH) ** 2))
    W = (W / W.sum(axis=1, keepdims=True))[F].mean(axis=1)
    Rp, _ = polar(np.einsum("fp,pij->fij", W, rotations))
    Rc, _ = polar(face_gradients(Cs, Cc, F))
    share = (W @ keep)[:, None, None]
    R, _ = polar((1.0 - share) * np.eye(3) + share * (np.swapaxes(Rp, 1, 2) @ Rc))
    # the fit's noise: small turns of single faces are dropped, larger ones kept, in
    # between in proportion (after the part's share: a part turned 8 degrees keeps 1/5 of
    # a face's 20 degrees, 4, and the band then keeps 2/3 of that)
    low, high = SHAPE_NOISE
    signal = np.clip((_angles(R) - low) / (high - low), 0.0, 1.0)[:, None, None]
    R, _ = polar((1.0 - signal) * np.eye(3) + signal * R)
    return R


def _angles(R) -> np.ndarray:
    """The angles of rotations ``(..., 3, 3)`` in degrees (from both their sine and
    cosine: an arc cosine alone turns rounding near the identity into 1e-6 degrees)."""
    R = np.asarray(R, dtype=np.float64)
    cosine = (np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0
    axial = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                      R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    return np.degrees(np.arctan2(np.linalg.norm(axial, axis=-1) / 2.0, cosine))


def has_rotation(points: ArrayLike) -> bool:
    """Whether points determine a rotation: 3 or more, not (nearly) on a line.

    Parameters
    ----------
    points : (n, 3) array_like of float

    Returns
    -------
    bool
        True when the points' second principal spread is at least :data:`PART_SPREAD`
        times their first (a turn about their line is then more than noise).

    Examples
    --------
    >>> has_rotation([[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    True
    >>> has_rotation([[0, 0, 0], [1, 0, 0], [2, 0.01, 0]])
    False
    """
    P = as_vertices(points, "points")
    if len(P) < 3:
        return False
    spread = np.linalg.svd(P - P.mean(axis=0), compute_uv=False)
    return bool(spread[1] > 0 and spread[1] >= PART_SPREAD * spread[0])


def _part_points(part, i) -> tuple[np.ndarray, np.ndarray]:
    """Part ``i`` as a checked pair (template points, character points), both (n_i, 3)."""
    if len(part) != 2:
        raise InputError(f"parts[{i}] must be a pair (template points, character points)")
    P = as_vertices(part[0], f"parts[{i}][0]")
    Q = as_vertices(part[1], f"parts[{i}][1]")
    if P.shape != Q.shape:
        raise InputError(f"parts[{i}] has {len(P)} template points and {len(Q)} "
                         "character points")
    for points, whose in ((P, "template"), (Q, "character")):
        if not has_rotation(points):
            raise InputError(f"parts[{i}]: its {len(points)} {whose} points lie on a line "
                             "(or are fewer than 3): they have no rotation")
    return P, Q


def _vertex_components(k, F) -> list[np.ndarray]:
    """The vertex indices of each connected component of the faces."""
    labels = face_components(k, F)
    return [np.unique(F[labels == label]) for label in np.unique(labels)]


def root_weights(template_cage_v: ArrayLike, deformed_template_cage_v: ArrayLike,
                 cage_f: ArrayLike, part: ArrayLike | None = None) -> Floats:
    """The root of a cage's motion, as mean value coordinates in the rest cage.

    The centres of a :data:`ROOT_GRID` grid over the rest cage's bounding box, kept where
    they lie inside it, are scored by how far the motion moves them plus
    :data:`ROOT_CENTRE` times how far they lie from their centroid (the centre of the
    cage's interior); the root is the weighted mean of the best ones. Turned about a pivot
    inside it (a body about its pelvis), the cage's root is near the pivot; carried along,
    it is its centre.

    Parameters
    ----------
    template_cage_v, deformed_template_cage_v : (k, 3) array_like of float
        The cage at rest and moved (same faces).
    cage_f : (m, 3) array_like of int
    part : (p,) array_like of int, optional
        The vertices of one connected component (faces using only them are its cage);
        default all.

    Returns
    -------
    (p,) float64
        Coordinates summing to one: ``weights @ cage_v[part]`` is the root. It moves
        continuously with the motion: each point weighs ``exp(-gap / tau)``, ``gap`` its
        score above the best and ``tau`` the gap of the best :data:`ROOT_SHARE`. A part
        thinner than the grid's cells, with no cell centre inside, is scored at its
        vertices.

    Raises
    ------
    InputError
        Cages of different vertex counts, NaN or inf, a ``part`` that makes no face, a
        rest cage flat along an axis.

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> w = root_weights(v, v + [1.0, 0.0, 0.0], f)  # carried along: its centre
    >>> bool(np.linalg.norm(w @ v) < 0.05 * np.linalg.norm(np.ptp(v, axis=0)))
    True
    >>> turn = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    >>> pivot = np.array([0.5, 0.5, 0.0])  # turned about a point off the centre
    >>> w = root_weights(v, (v - pivot) @ turn.T + pivot, f)
    >>> bool(np.linalg.norm(w @ v - pivot) < np.linalg.norm(pivot))
    True
    """
    Cs, Ct, faces = _root_cage(template_cage_v, deformed_template_cage_v, cage_f, part)
    W, centrality = _interior(np.ascontiguousarray(Cs).tobytes(),
                              np.ascontiguousarray(faces, dtype=np.int64).tobytes())
    diagonal = float(np.linalg.norm(np.ptp(Cs, axis=0)))
    score = np.linalg.norm(W @ (Ct - Cs), axis=1) / diagonal + ROOT_CENTRE * centrality
    # soft, so that the root moves continuously with the motion (a hard cut would jump
    # between two equally still places, say two feet): each point weighs exp(-gap / tau),
    # gap its score above the best, tau the gap of the best share
    gap = score - score.min()
    tau = max(float(np.quantile(gap, ROOT_SHARE)), 1e-9)
    closeness = np.exp(-gap / tau)
    weights = closeness @ W
    return weights / weights.sum()


@functools.lru_cache(maxsize=8)
def _interior(cage_bytes: bytes, face_bytes: bytes) -> tuple[np.ndarray, np.ndarray]:
    """The root's sample points inside a rest cage, once per cage (every pose of a
    transfer shares it): their mean value coordinates ``(s, k)`` and their distances from
    their centroid in cage diagonals ``(s,)``, both read-only."""
    Cs = np.frombuffer(cage_bytes, dtype=np.float64).reshape(-1, 3)
    faces = np.frombuffer(face_bytes, dtype=np.int64).reshape(-1, 3)
    lo, hi = Cs.min(axis=0), Cs.max(axis=0)
    centres = (np.arange(ROOT_GRID) + 0.5) / ROOT_GRID  # cell centres: none on a box's face
    axes = [lo[i] + centres * (hi[i] - lo[i]) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    # either orientation of the faces: inside is where the winding number is +-1
    inside = grid[np.abs(winding_numbers(grid, Cs, faces)) >= 0.5]
    if len(inside) == 0:  # a sliver thinner than the grid cells: its vertices stand in
        inside = Cs
    W = mean_value_coordinates(inside, Cs, faces, check=False)
    centrality = (np.linalg.norm(inside - inside.mean(axis=0), axis=1)
                  / float(np.linalg.norm(hi - lo)))
    W.flags.writeable = centrality.flags.writeable = False
    return W, centrality


def _root_cage(template_cage_v, deformed_template_cage_v, cage_f, part):
    """The rest and moved vertices of ``part`` and its faces (renumbered), checked."""
    Cs = as_vertices(template_cage_v, "template_cage_v")
    Ct = as_vertices(deformed_template_cage_v, "deformed_template_cage_v")
    if Cs.shape != Ct.shape:
        raise InputError(f"the rest and moved cages must have the same vertex count, got "
                         f"{len(Cs)} and {len(Ct)}")
    if not (np.isfinite(Cs).all() and np.isfinite(Ct).all()):
        raise InputError("the rest or moved cage holds NaN or inf")
    F = np.asarray(cage_f, dtype=np.int64)
    part = np.arange(len(Cs)) if part is None else np.asarray(part, dtype=np.int64)
    index = np.full(len(Cs), -1)
    index[part] = np.arange(len(part))
    faces = index[F[np.isin(F, part).all(axis=1)]]
    if not len(faces):
        raise InputError("the cage's vertices given (part) make no face: no root")
    Cs, Ct = Cs[part], Ct[part]
    if not np.ptp(Cs, axis=0).all():
        raise InputError("the rest cage has no extent along some axis: no root")
    return Cs, Ct, faces


def transfer_cage(rule: str, template_cage_v: ArrayLike, deformed_template_cage_v: ArrayLike,
                  character_cage_v: ArrayLike, cage_f: ArrayLike, alignment: Similarity,
                  parts: Sequence[tuple[ArrayLike, ArrayLike]] | None = None) -> Vertices:
    """The character's deformed cage by ``rule`` (``"pose"`` or ``"offsets"``).

    Parameters
    ----------
    rule : {"pose", "offsets"}
    template_cage_v, deformed_template_cage_v, character_cage_v, cage_f, alignment, parts
        As for :func:`transfer_pose` (``parts`` only matter to the pose rule).

    Returns
    -------
    (k, 3) float64
    """
    if rule == "pose":
        return transfer_pose(template_cage_v, deformed_template_cage_v, character_cage_v,
                             cage_f, alignment, parts)
    if rule == "offsets":
        return transfer_offsets(template_cage_v, deformed_template_cage_v, character_cage_v,
                                alignment)
    raise InputError(f"rule must be one of {', '.join(RULES)}, got {rule!r}")
