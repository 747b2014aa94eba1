"""Loose pieces of a character's mesh follow the pieces they touch.

A character's mesh is often several pieces with no edge between them: shoes, hands,
cuffs, hems. A piece the cage binds poorly (at least :data:`LOOSE_MENDED` of its vertices
mended by :func:`cagekit.transfer.surface_binding.bind_surface`: they lie where the cage folds
between touching parts) has no well-bound vertex of its own to be mended from, and the
cage can carry it off with the wrong part: a hand resting on the hip stays at the hip, a
shoe parts from its trouser hem. Such a piece follows what it touched at rest instead: it
is moved by the median (per coordinate) of the moves that would restore its rest offsets
to the vertices it touched (each of its vertices' nearest settled vertex within
:data:`CONTACT` of the mesh's largest extent; :data:`CONTACT_PAIRS` such pairs at least).
A translation, not a rigid motion fitted to the contacts: the touched vertices are often a
thin ring (a cuff, a hem), which determines a translation well and a rotation not at all;
the piece keeps the cage's turn of it.

Unless the cage bent it out of shape. Where the cage folds between two parts (a hand
resting on the hip: the fold between forearm and hip) it moves a piece's vertices apart,
and no translation undoes that (the fingers come out folded over). A piece is bent when
its moved vertices deviate from their own best rigid fit to its rest shape (root mean
square) by more than :data:`BENT` of its size (root mean square distance from its centre)
and by more than :data:`BENT_RATIO` times as much as the well-bound vertices around its
contacts deviate from theirs (its *patch*: the vertices that are neither mended nor of a
loose piece, within :data:`PATCH_REACH` of the mesh's largest extent of a touched vertex,
of the parts it may follow; :data:`PATCH_SIZE` of them at least). A bent piece is replaced
by a rigid copy of its rest shape, turned by the best rotation of its patch and placed by
the same median rule. Where the surface around the contacts is as bent as the piece (a
hem at the ankle, which the cage's joint bends with the leg) the piece keeps the cage's
shape.

A piece still off what it touched after that (its contacts on the piece it touched most
farther than :data:`DETACHED` of the mesh's largest extent from their rest offsets, in the
median: a hand that the cage pushed out through the skin it lay under) is fitted rigidly to
those contacts instead (its rest shape, the best rotation and shift, Kabsch), when they
spread in two directions by :data:`CONTACT_SPREAD` of its size (a wrist, not a thin cuff,
which would turn a hand into its sleeve) and the fit leaves :data:`FIT_GAIN` of the gap or
less.

A *watched* piece is one the cage binds half well (:data:`WATCHED_MENDED` to
:data:`LOOSE_MENDED` of it mended, at most :data:`WATCHED_SIZE` of the mesh): the cage
moves it, unless it takes it off every piece it touched (by more than :data:`DETACHED`, in
the median per touched piece): then it follows them like a loose piece (a shoe stretched
forward off its trouser hem). Larger pieces are never watched: a trouser leg translated
back to the pieces it touched went with the wrong one.

Watched pieces are visited first, the larger first; then loose pieces outward from the
well-bound ones, so a shoe follows its hem after the hem has followed the leg. Given each
vertex's rigid part (the humanoid's, from the nearest landmark), a piece follows only what
it touched on its own part or the parts next to it along the skeleton
(:data:`cagekit.datasets.humanoid.RIGID_PARENTS`): a hand resting on the hip follows the
wrist, not the hip.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from cagekit.cage import vertex_components
from cagekit.datasets.humanoid import RIGID_PARENTS
from cagekit.errors import InputError
from cagekit.geometry import as_faces, as_vertices
from cagekit.geometry.rotations import polar
from cagekit.typed import Vertices

__all__ = ["LoosePieces", "find_loose_pieces", "CONTACT", "CONTACT_PAIRS", "LOOSE_MENDED",
           "LOOSE_SIZE", "BENT", "BENT_RATIO", "PATCH_REACH", "PATCH_SIZE", "DETACHED",
           "WATCHED_MENDED", "WATCHED_SIZE", "CONTACT_SPREAD", "FIT_GAIN"]

#: pieces touch where their vertices lie this close, in shares of the mesh's largest extent
CONTACT = 0.01
#: a piece is loose when at least this share of its vertices is mended
LOOSE_MENDED = 0.5
#: pieces with more than this share of the mesh's vertices are never loose
LOOSE_SIZE = 0.1
#: fewest touching vertex pairs a loose piece needs to follow what it touches
CONTACT_PAIRS = 3
#: a piece is bent when its deviation from its best rigid fit exceeds this share of its size
#: (root mean square distances, both)...
BENT = 0.1
#: ...and this many times its patch's deviation (on the three real characters 1.5 and 1.75
#: did alike; 1.2 turned the girl's shin pieces, 2 left male02's hand bent in two poses)
BENT_RATIO = 1.5
#: a piece's patch: well-bound vertices this close to its touched ones, in shares of the
#: mesh's largest extent (0.04 found too few on male02's coarse mesh; 0.07 took in bent ones)
PATCH_REACH = 0.05
#: fewest patch vertices to turn a bent piece by
PATCH_SIZE = 10
#: pieces with at least this share of their vertices mended (and under LOOSE_MENDED) are
#: watched (0.25-0.45 did alike on the three real characters; 0.5: none, the suit's shoe
#: stays off its hem)...
WATCHED_MENDED = 0.25
#: ...unless they have more than this share of the mesh's vertices (0.03-0.05 did alike;
#: 0.1 took in trouser legs, which went with the wrong piece)
WATCHED_SIZE = 0.03
#: a piece is off what it touched when its touching pairs lie farther than this from their
#: rest offsets (median, in shares of the mesh's largest extent; 0.02-0.03 did alike, 0.015
#: fitted the suit's cuffs into their sleeves)
DETACHED = 0.02
#: a piece left off is fitted rigidly to its contacts when they spread this far in two
#: directions (root mean square, in shares of the piece's size; 0.2-0.35 did alike)...
CONTACT_SPREAD = 0.3
#: ...and the fit leaves this share of the gap or less (0.35-0.5 did alike; 0.7 moved a
#: piece of the girl's that straddles both feet off its shin)
FIT_GAIN = 0.5


@dataclass(frozen=True)
class LoosePieces:
    """The loose pieces of a mesh and what each touched at rest (:func:`find_loose_pieces`).

    Attributes
    ----------
    n_vertices : int
        The mesh's vertex count.
    pieces : tuple of (p_i,) int64
        The vertices of each loose piece, in the order they are moved.
    touching : tuple of (t_i,) int64
        Per piece, its vertices that touched another piece at rest...
    touched : tuple of (t_i,) int64
        ...and the vertices they touched (pieces settled before it).
    patches : tuple of (q_i,) int64
        Per piece, the well-bound vertices around its contacts whose best rotation turns
        it when the cage bent it (see the module); empty: never turned.
    watched : tuple of bool
        Per piece, True for a watched piece (moved only when the cage took it off every
        piece it touched), False for a loose one; empty: all loose.
    sides : tuple of (t_i,) int64
        Per piece, which piece each touched vertex lies on (a label of the mesh's pieces);
        empty: one piece.
    """

    n_vertices: int
    pieces: tuple
    touching: tuple
    touched: tuple
    patches: tuple = ()
    watched: tuple = ()
    sides: tuple = ()

    def reattach(self, rest_v: ArrayLike, deformed_v: ArrayLike) -> Vertices:
        """The deformed mesh with each loose piece moved back to what it touched.

        Parameters
        ----------
        rest_v, deformed_v : (n, 3) array_like of float
            The mesh at rest and deformed (same vertices).

        Returns
        -------
        (n, 3) float64
            ``deformed_v`` with each piece translated by the median (per coordinate),
            over its touching pairs ``(i, j)``, of
            ``deformed[j] + (rest[i] - rest[j]) - deformed[i]`` (the rest offsets, under
            1% of the mesh, are not turned). A piece the cage bent (see the module) is
            replaced by its rest shape turned by its patch's best rotation ``R`` and
            moved by the median of ``deformed[j] - R @ rest[j]``.

        Examples
        --------
        A well-bound box (98 vertices) moves up by 2; a loose triangle lying 0.001 off
        its side is left behind by the cage, and follows:

        >>> import trimesh
        >>> box = trimesh.creation.box().subdivide().subdivide()
        >>> V = np.vstack([box.vertices, [[0.501, 0, 0], [0.501, 0.25, 0], [0.501, 0, 0.25]]])
        >>> F = np.vstack([box.faces, [[98, 99, 100]]])
        >>> mended = np.arange(101) >= 98
        >>> moved = V + np.where(mended[:, None], 0.0, [0.0, 2.0, 0.0])
        >>> out = find_loose_pieces(V, F, mended).reattach(V, moved)
        >>> bool(np.allclose(out[-3:] - V[-3:], [0.0, 2.0, 0.0]))
        True

        A hand of 9 vertices sticks out of a finer box (1538 vertices); the box turns by
        0.5 radians about z, the cage turns the hand's 3 touching vertices with it and
        leaves its fingers behind (bent): the hand is its rest shape turned with the box.

        >>> box = trimesh.creation.box().subdivide().subdivide().subdivide().subdivide()
        >>> hand = [[x, y, 0.0] for x in (0.501, 0.75, 1.0) for y in (-0.125, 0.0, 0.125)]
        >>> V = np.vstack([box.vertices, hand])
        >>> F = np.vstack([box.faces, [[k, k + 1, k + 2] for k in range(1538, 1545)]])
        >>> loose = find_loose_pieces(V, F, np.arange(1547) >= 1538)
        >>> c, s = np.cos(0.5), np.sin(0.5)
        >>> turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        >>> moved = V @ turn.T
        >>> moved[-6:] = V[-6:]
        >>> out = loose.reattach(V, moved)
        >>> bool(np.allclose(out[-9:], V[-9:] @ turn.T))
        True
        """
        rest = as_vertices(rest_v, "rest_v")
        out = as_vertices(deformed_v, "deformed_v").copy()
        if not len(rest) == len(out) == self.n_vertices:
            raise InputError(f"the loose pieces are of a mesh of {self.n_vertices} vertices; "
                             f"rest_v has {len(rest)} and deformed_v {len(out)}")
        n = len(self.pieces)
        patches = self.patches or (np.zeros(0, np.int64),) * n
        watched = self.watched or (False,) * n
        sides = self.sides or tuple(np.zeros(len(i), np.int64) for i in self.touching)
        off = DETACHED * float(np.ptp(rest, axis=0).max())
        for piece, i, j, patch, watch, side in zip(self.pieces, self.touching, self.touched,
                                                   patches, watched, sides):
            if watch and not _off(rest, out, i, j, side, off):
                continue  # the cage kept it on something it touched
            turn = _turn(rest, out, piece, patch)
            if turn is None:
                moved = out[piece] + np.median(out[j] + (rest[i] - rest[j]) - out[i], axis=0)
            else:
                moved = rest[piece] @ turn.T + np.median(out[j] - rest[j] @ turn.T, axis=0)
            out[piece] = _fitted(rest, out, piece, i, j, side, moved, off)
        return out


def find_loose_pieces(vertices: ArrayLike, faces: ArrayLike, mended: ArrayLike,
                      parts: ArrayLike | None = None) -> LoosePieces:
    """The loose pieces of a mesh, and what each touched at rest (see the module).

    Parameters
    ----------
    vertices : (n, 3) array_like of float
        The mesh at rest.
    faces : (m, 3) array_like of int
    mended : (n,) array_like of bool
        The vertices the cage binds poorly (:attr:`SurfaceBinding.mended`).
    parts : (n,) array_like of str, optional
        Each vertex's rigid part (:data:`cagekit.datasets.humanoid.RIGID_PARTS`; ``""``
        for none). A loose piece takes its vertices' most common part; of the vertices
        it touches (each of its vertices' nearest settled vertex), it follows those of its
        part, its parent, its children or of no part.

    Returns
    -------
    LoosePieces
        The watched pieces (the larger first), then the loose ones (outward from the
        well-bound pieces). Pieces that touch fewer than :data:`CONTACT_PAIRS` settled
        vertices they may follow are left out (the cage moves them).

    Raises
    ------
    InputError
        Bad vertices or faces, ``mended`` or ``parts`` not one per vertex, a part the
        humanoid does not have.

    Examples
    --------
    A box of 98 vertices, well bound, and a triangle of 3 mended vertices lying 0.001 off
    three of its vertices:

    >>> import trimesh
    >>> box = trimesh.creation.box().subdivide().subdivide()
    >>> V = np.vstack([box.vertices, [[0.501, 0, 0], [0.501, 0.25, 0], [0.501, 0, 0.25]]])
    >>> F = np.vstack([box.faces, [[98, 99, 100]]])
    >>> loose = find_loose_pieces(V, F, np.arange(101) >= 98)
    >>> [p.tolist() for p in loose.pieces], [len(j) for j in loose.touched]
    ([[98, 99, 100]], [3])
    """
    V = as_vertices(vertices, "vertices")
    F = as_faces(faces, len(V), "faces")
    mended = np.asarray(mended, dtype=bool)
    if mended.shape != (len(V),):
        raise InputError(f"mended must have one flag per vertex ({len(V)}), got shape "
                         f"{mended.shape}")
    labels = np.full(len(V), "") if parts is None else np.asarray(parts, dtype=str)
    if labels.shape != (len(V),):
        raise InputError(f"parts must name one part per vertex ({len(V)}), got shape "
                         f"{labels.shape}")
    unknown = sorted({str(label) for label in np.unique(labels)} - set(RIGID_PARENTS) - {""})
    if unknown:
        raise InputError(f"parts names {unknown[0]!r}, which is no rigid part of the humanoid "
                         "(cagekit.datasets.humanoid.RIGID_PARTS, or '' for none)")
    label = vertex_components(len(V), F)
    used = label >= 0
    pieces = [np.flatnonzero(label == c) for c in np.unique(label[used])]
    small = [p for p in pieces if len(p) <= LOOSE_SIZE * used.sum()]
    loose = [p for p in small if mended[p].mean() >= LOOSE_MENDED]
    watched = sorted((p for p in small if WATCHED_MENDED <= mended[p].mean() < LOOSE_MENDED
                      and len(p) <= WATCHED_SIZE * used.sum()),
                     key=len, reverse=True)
    settled = used.copy()
    for p in loose:
        settled[p] = False
    well = np.flatnonzero(settled & ~mended)  # what a bent piece's patch is made of
    extent = float(np.ptp(V, axis=0).max())
    reach = CONTACT * extent
    order, touching, touched, kinds = [], [], [], []
    for p in watched:  # against every other settled piece, the larger watched ones first
        anchors = np.flatnonzero(settled & (label != label[p[0]]))
        i, j = _touching(V, p, anchors, cKDTree(V[anchors]) if len(anchors) else None, labels,
                         reach)
        if len(i) >= CONTACT_PAIRS:
            order.append(p)
            touching.append(i)
            touched.append(j)
            kinds.append(True)
    while loose:
        anchors = np.flatnonzero(settled)  # one tree a round: the settled set is fixed in it
        tree = cKDTree(V[anchors]) if len(anchors) else None
        followed = []
        for p in loose:
            i, j = _touching(V, p, anchors, tree, labels, reach)
            if len(i) >= CONTACT_PAIRS:
                order.append(p)
                touching.append(i)
                touched.append(j)
                kinds.append(False)
                followed.append(p)
        if not followed:
            break
        for p in followed:
            settled[p] = True
        loose = [p for p in loose if not settled[p[0]]]
    well_tree = cKDTree(V[well]) if len(well) else None
    patches = tuple(_patch(V, p, j, well, well_tree, labels, PATCH_REACH * extent)
                    for p, j in zip(order, touched))
    return LoosePieces(len(V), tuple(order), tuple(touching), tuple(touched), patches,
                       tuple(kinds), tuple(label[j] for j in touched))


def _touching(V, piece, anchors, tree, labels, reach) -> tuple[np.ndarray, np.ndarray]:
    """The piece's vertices whose nearest settled vertex (``anchors``, in ``tree``) lies
    within ``reach`` and is of a related part or of none, and those vertices. (The nearest
    of all, then its part: taking the nearest of the related parts instead reached past
    the other shoe of two touching ones to the wrong trouser leg, and flung the suit's
    shoe by 35% of its height.)"""
    if tree is None:
        return piece[:0], anchors
    dist, k = tree.query(V[piece], distance_upper_bound=reach)
    near = np.isfinite(dist)
    i, j = piece[near], anchors[k[near]]
    allowed = _related(_common(labels[piece]))
    if allowed is not None:
        keep = np.isin(labels[j], [*allowed, ""])
        i, j = i[keep], j[keep]
    return i, j


def _patch(V, piece, touched, well, tree, labels, reach) -> np.ndarray:
    """The well-bound vertices (``well``, in ``tree``) within ``reach`` of a touched vertex
    and of the parts the piece may follow (or of none)."""
    if tree is None or not len(touched):
        return well[:0]
    near = tree.query_ball_point(V[np.unique(touched)], reach)
    patch = well[np.unique(np.concatenate([np.asarray(k, np.int64) for k in near]))]
    allowed = _related(_common(labels[piece]))
    if allowed is not None:
        patch = patch[np.isin(labels[patch], [*allowed, ""])]
    return patch


def _rigid_fit(rest, moved) -> tuple[np.ndarray, float]:
    """The best rotation ``R`` (no scale, Kabsch) taking ``rest`` (centred) onto ``moved``
    (centred), and the root mean square distance left."""
    a, b = rest - rest.mean(axis=0), moved - moved.mean(axis=0)
    R = polar((b.T @ a)[None])[0][0]
    return R, float(np.sqrt(np.mean(np.sum((a @ R.T - b) ** 2, axis=1))))


def _fitted(rest, out, piece, i, j, side, moved, off) -> np.ndarray:
    """``moved`` (the piece's vertices), or its rest shape fitted rigidly to its contacts
    on the piece it touched most when ``moved`` is off them by more than ``off`` (median),
    the contacts spread enough to turn it by (:data:`CONTACT_SPREAD`) and the fit leaves
    :data:`FIT_GAIN` of the gap or less (see the module)."""
    on = side == np.bincount(side).argmax()
    i, j = i[on], j[on]
    target = out[j] + (rest[i] - rest[j])
    at = np.searchsorted(piece, i)
    gap = _gap(moved[at], target)
    if gap <= off or not _spread(rest[piece], rest[i]):
        return moved
    a, b = rest[i] - rest[i].mean(axis=0), target - target.mean(axis=0)
    R = polar((b.T @ a)[None])[0][0]
    fitted = (rest[piece] - rest[i].mean(axis=0)) @ R.T + target.mean(axis=0)
    return fitted if _gap(fitted[at], target) <= FIT_GAIN * gap else moved


def _spread(piece_v, contact_v) -> bool:
    """Whether the contacts spread in two directions by :data:`CONTACT_SPREAD` of the
    piece's size (root mean square distances from their centres)."""
    size = np.sqrt(np.mean(np.sum((piece_v - piece_v.mean(axis=0)) ** 2, axis=1)))
    s = np.linalg.svd(contact_v - contact_v.mean(axis=0), compute_uv=False)
    return len(s) >= 2 and s[1] / np.sqrt(len(contact_v)) >= CONTACT_SPREAD * size


def _gap(points, targets) -> float:
    """The median distance between the points and their targets."""
    return float(np.median(np.linalg.norm(points - targets, axis=1)))


def _off(rest, out, i, j, side, off) -> bool:
    """Whether the touching pairs ``(i, j)`` opened from their rest offsets by more than
    ``off`` (median) on every piece touched (``side``: each ``j``'s piece)."""
    gaps = np.linalg.norm(out[i] - out[j] - (rest[i] - rest[j]), axis=1)
    return all(np.median(gaps[side == s]) > off for s in np.unique(side))


def _turn(rest, out, piece, patch) -> np.ndarray | None:
    """The rotation to turn a bent piece's rest shape by (its patch's best), or None for a
    piece not bent or with too small a patch (see the module)."""
    if len(patch) < PATCH_SIZE:
        return None
    size = float(np.sqrt(np.mean(np.sum((rest[piece] - rest[piece].mean(axis=0)) ** 2,
                                        axis=1))))
    bent = _rigid_fit(rest[piece], out[piece])[1]
    turn, spread = _rigid_fit(rest[patch], out[patch])
    return turn if bent > BENT * size and bent > BENT_RATIO * spread else None


def _common(labels) -> str:
    """The most common label (the first in sorted order on a tie)."""
    values, counts = np.unique(labels, return_counts=True)
    return str(values[np.argmax(counts)])


def _related(part: str) -> set[str] | None:
    """The part, its parent and its children; None (any) for a vertex of no part."""
    if part not in RIGID_PARENTS:
        return None
    parent = RIGID_PARENTS[part]  # None for the root
    return {part, *([] if parent is None else [parent]),
            *(c for c, p in RIGID_PARENTS.items() if p == part)}

