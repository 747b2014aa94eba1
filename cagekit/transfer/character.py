"""A transfer run: the character's cage and binding once, then each template pose carried over.

The template (rest pose, cage ``C_s``, example poses as meshes) and a novel character (rest
pose, landmarks whose labels match the template's): the character's cage ``C_c`` is fitted
once by :func:`cagekit.transfer.character_cage.fit_character_cage` (landmark reproduction,
enclosure, no self-intersection: a valid cage or an error) and the character bound to it by
:func:`cagekit.transfer.surface_binding.bind_surface` (mean value coordinates, mended along
the mesh where the cage folds between a limb and the body it touches; the cage's result made
as rigid as possible where it tears the mesh, :mod:`cagekit.transfer.robust_arap`); each
pose's template cage ``C_st`` comes from a per-pair fit (classical) or a trained
fixed-source network (``--model``, :mod:`cagekit_learn.transfer`); the character's cage
moves by a :mod:`cagekit.transfer.rules` rule,
``"pose"`` (default: the template's rotations with the character's own stretch, so a
T-pose example gives a T-pose whatever the character's rest pose) or ``"offsets"`` (the
paper's ``C_c + A (C_st - C_s)``, ``A`` the linear part of the template-to-character
alignment, ``--align box`` or ``similarity``). A pose with the template's vertex count is
taken to share its vertex order and is fitted exactly by linear least squares with every
vertex as a correspondence and a small cage-Laplacian term (:data:`SMOOTHNESS`); other
poses use :func:`cagekit.deform` with Chamfer. Labels in one file only are reported, never
dropped silently; fewer than 4 shared labels is an error. The command is ``cagekit
transfer`` (:mod:`cagekit.cli.transfer`). See docs/architecture.md.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from cagekit.cage import check_cage
from cagekit.coords import bind
from cagekit.datasets.humanoid import RIGID_PARTS, landmark_part
from cagekit.deformation import DeformOptions, deform
from cagekit.errors import InputError
from cagekit.geometry import as_vertices, cotangent_laplacian
from cagekit.geometry.alignment import box_alignment, similarity_alignment
from cagekit.io.landmarks import LandmarkMatch, match_landmarks
from cagekit.transfer.character_cage import CharacterCageFit, fit_character_cage
from cagekit.transfer.loose_pieces import LoosePieces, find_loose_pieces
from cagekit.transfer.rules import has_rotation, transfer_cage
from cagekit.transfer.surface_binding import SurfaceBinding, bind_surface, check_coupling
from cagekit.typed import Vertices

__all__ = ["CharacterCage", "fit_character", "check_landmarks_on_mesh", "corresponds",
           "template_cage_classical", "classical_fitter", "ClassicalFitter", "transfer",
           "cage_oracle", "render_grid", "landmark_parts", "PART_LANDMARKS", "ROOTS", "SMOOTHNESS"]

#: weight of the cage-Laplacian term of the classical template fit (the cage's own units)
SMOOTHNESS = 1e-2
#: L-BFGS evaluations of the Chamfer template fit (poses need more than the default 60)
TEMPLATE_EVALUATIONS = 200
#: fewest landmarks of one rigid part that give it a rotation (:func:`landmark_parts`)
PART_LANDMARKS = 3
#: where the character goes when the example moves the template's root (:func:`transfer`)
ROOTS = ("follow", "ground")
#: largest median distance of a mesh's landmarks from its vertices, in its bounding-box
#: diagonals: landmarks farther off were given in another frame or unit than the mesh
LANDMARK_OFFSET = 0.1


@dataclass
class CharacterCage:
    """A novel character bound to its fitted cage.

    Attributes
    ----------
    vertices : (n, 3) float64
        The character in rest pose.
    faces : (m, 3) int64
    template_cage_v : (k, 3) float64
        ``C_s``, in the template's frame.
    cage_v : (k, 3) float64
        ``C_c``, in the character's frame.
    cage_f : (f, 3) int64
    fit : cagekit.transfer.character_cage.CharacterCageFit
        Its landmark errors, consistency, checks and alignment.
    match : cagekit.io.landmarks.LandmarkMatch
    binding : cagekit.transfer.surface_binding.SurfaceBinding
        The character bound to ``C_c``: mean value coordinates (or Green coordinates),
        mended along the mesh where the cage folds between touching parts.
    parts : tuple of ((n_i, 3), (n_i, 3)) float64 pairs
        The matched landmarks grouped by the rigid part they lie on, on the template and
        on the character (:func:`landmark_parts`); the pose rule keeps the character's own
        shape where its part is oriented like the template's
        (:func:`cagekit.transfer.rules.shape_rotations`). Empty: every face takes the
        example's rotation alone.
    loose : cagekit.transfer.loose_pieces.LoosePieces or None
        The character's separate pieces that the cage binds poorly and that follow what
        they touch at rest (with the refinement, :func:`transfer`).
    """

    vertices: np.ndarray
    faces: np.ndarray
    template_cage_v: np.ndarray
    cage_v: np.ndarray
    cage_f: np.ndarray
    fit: CharacterCageFit
    match: LandmarkMatch
    binding: SurfaceBinding
    parts: tuple[tuple[np.ndarray, np.ndarray], ...] = ()
    loose: LoosePieces | None = None


def landmark_parts(labels: Sequence[str], template_points: ArrayLike,
                   character_points: ArrayLike) -> tuple[tuple[Vertices, Vertices], ...]:
    """Matched landmarks grouped by the humanoid's rigid part they lie on.

    Parameters
    ----------
    labels : sequence of str
        Landmark names (:data:`cagekit.datasets.humanoid.LANDMARK_NAMES`; others are
        left out).
    template_points, character_points : (n, 3) array_like of float
        Their positions on the template and on the character.

    Returns
    -------
    tuple of ((n_i, 3), (n_i, 3)) float64 pairs
        Per part (:data:`cagekit.datasets.humanoid.RIGID_PARTS` order) with
        :data:`PART_LANDMARKS` or more landmarks, not nearly on a line on either mesh
        (:func:`cagekit.transfer.rules.has_rotation`): its template points and character
        points. Other parts are left out (their faces follow the nearest parts kept).

    Examples
    --------
    >>> pts = np.eye(4)[:, :3]
    >>> parts = landmark_parts(["head_top", "chin", "l_eye", "l_toe"], pts, 2 * pts)
    >>> [(len(P), len(Q)) for P, Q in parts]
    [(3, 3)]
    """
    P = as_vertices(template_points, "template_points")
    Q = as_vertices(character_points, "character_points")
    if not len(labels) == len(P) == len(Q):
        raise InputError(f"{len(labels)} labels for {len(P)} template points and {len(Q)} "
                         "character points")
    of_part = _parts_of(labels)
    groups = []
    for part in RIGID_PARTS:
        on = of_part == part
        if on.sum() >= PART_LANDMARKS and has_rotation(P[on]) and has_rotation(Q[on]):
            groups.append((P[on], Q[on]))
    return tuple(groups)


def _parts_of(labels) -> np.ndarray:
    """(L,) str: each landmark label's rigid part of the humanoid, ``""`` for none."""
    return np.array([landmark_part(str(label)) or "" for label in labels], dtype="<U16")


def fit_character(template_v: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike,
                  template_landmarks: Mapping[str, ArrayLike], character_v: ArrayLike,
                  character_f: ArrayLike, character_landmarks: Mapping[str, ArrayLike], *,
                  align: str = "box", coords: str = "mvc", template_name: str | None = None,
                  character_name: str | None = None) -> CharacterCage:
    """Fit the template's cage to a character by its landmarks and bind the character.

    Parameters
    ----------
    template_v : (n_s, 3) array_like of float
        The template in rest pose (for the box alignment).
    cage_v, cage_f : (k, 3) float, (f, 3) int
        The template's cage ``C_s``.
    template_landmarks, character_landmarks : mapping of str to (3,) float
        Named landmarks of the two rest poses; matched by label (at least 4 shared).
    character_v, character_f : (n, 3) float, (m, 3) int
        The novel character in rest pose (any number of parts, open or closed).
    align : {"box", "similarity"}, default "box"
        How the rest poses are aligned before the fit: bounding-box centres and heights
        (:func:`cagekit.geometry.alignment.box_alignment`), or the landmarks' similarity.
    coords : {"mvc", "green"}, default "mvc"
        How the character follows its cage (:func:`cagekit.transfer.surface_binding.bind_surface`):
        mean value coordinates, or Green coordinates where no mending is needed. The
        template's own cage fit is the same either way.
    template_name, character_name : str, optional
        The landmark files, named in errors.

    Returns
    -------
    CharacterCage

    Raises
    ------
    InputError
        Too few shared labels, a bad cage, shapes that cannot be aligned.
    CageFitError
        No valid character cage, or one folded between touching parts over most of the
        character (:func:`cagekit.transfer.surface_binding.check_coupling`; the message says what
        failed).
    """

    match = match_landmarks(template_landmarks, character_landmarks,
                            source_name=template_name, target_name=character_name)
    cage_v = as_vertices(cage_v, "cage_v")  # checked by the fit
    character_v = as_vertices(character_v, "character_v")
    check_landmarks_on_mesh(as_vertices(template_v, "template_v"), match.source,
                            template_name or "the template")
    check_landmarks_on_mesh(character_v, match.target, character_name or "the character")
    names = f"{template_name or 'the template'} and {character_name or 'the character'}"
    if align == "box":
        try:
            alignment = box_alignment(template_v, character_v)
        except InputError as exc:
            raise InputError("cannot align the template's and the character's meshes by "
                             f"their bounding boxes: {exc.problem}") from None
    elif align == "similarity":
        try:
            alignment = similarity_alignment(match.source, match.target)
        except InputError as exc:
            raise InputError(f"cannot align the landmarks of {names}: {exc}") from None
    else:
        raise InputError(f"align must be 'box' or 'similarity', got {align!r}")
    fit = fit_character_cage(cage_v, cage_f, match.source, match.target, character_v,
                             alignment=alignment, labels=match.labels)
    # the fit checked this cage (closed, no crossing, every vertex inside)
    weights = bind(character_v, fit.cage_v, fit.cage_f, check=False).weights
    binding = bind_surface(character_v, character_f, fit.cage_v, fit.cage_f, weights=weights,
                           coords=coords)
    fit.checks["coupled"] = check_coupling(binding)
    fit.checks["mended"] = float(binding.mended.mean())
    faces = np.asarray(character_f, np.int64)
    nearest = cKDTree(match.target).query(character_v)[1]
    vertex_parts = _parts_of(match.labels)
    loose = find_loose_pieces(character_v, faces, binding.mended, vertex_parts[nearest])
    return CharacterCage(vertices=character_v, faces=faces, template_cage_v=cage_v,
                         cage_v=fit.cage_v, cage_f=fit.cage_f, fit=fit, match=match,
                         binding=binding,
                         parts=landmark_parts(match.labels, match.source, match.target),
                         loose=loose)


def check_landmarks_on_mesh(vertices: ArrayLike, landmarks: ArrayLike, name: str) -> None:
    """Refuse landmarks that lie far from their mesh (another frame or unit than it).

    Parameters
    ----------
    vertices : (n, 3) float64
        The mesh (or point cloud) the landmarks were picked on.
    landmarks : (l, 3) array_like of float
        Their positions.
    name : str
        The mesh's name (its file), put in front of the message.

    Raises
    ------
    InputError
        The median distance from a landmark to the nearest vertex exceeds
        :data:`LANDMARK_OFFSET` bounding-box diagonals of the mesh.

    Examples
    --------
    >>> V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> check_landmarks_on_mesh(V, V[:3] + 0.01, "tet.obj")
    >>> check_landmarks_on_mesh(V, V[:3] + 5.0, "tet.obj")
    Traceback (most recent call last):
    ...
    cagekit.errors.InputError: tet.obj: its landmarks lie far from its mesh (median 5 ...
    """
    from scipy.spatial import cKDTree

    diagonal = float(np.linalg.norm(np.ptp(vertices, axis=0)))
    distance = cKDTree(vertices).query(np.asarray(landmarks, dtype=np.float64))[0]
    offset = float(np.median(distance)) / diagonal if diagonal > 0 else 0.0
    if offset > LANDMARK_OFFSET:
        raise InputError(f"its landmarks lie far from its mesh (median {offset:.3g} of its "
                         f"bounding-box diagonal, at most {LANDMARK_OFFSET} expected): given "
                         "in another frame or unit than the mesh?", name)


def corresponds(template_v: ArrayLike, template_f: ArrayLike | None, pose_v: ArrayLike,
                pose_f: ArrayLike | None) -> bool:
    """True if the pose shares the template's vertex order: same vertex count and, when
    both have faces, the same faces (poses of one rigged character).

    Parameters
    ----------
    template_v, pose_v : (n, 3) array_like of float
    template_f, pose_f : (m, 3) array_like of int, or None
        Either may be None or empty (then only the vertex counts are compared).

    Returns
    -------
    bool

    Examples
    --------
    >>> V, F = np.zeros((4, 3)), np.array([[0, 1, 2], [0, 2, 3]])
    >>> corresponds(V, F, V + 1, F), corresponds(V, F, V[:3], None)
    (True, False)
    """
    if len(np.asarray(template_v)) != len(np.asarray(pose_v)):
        return False
    if template_f is None or pose_f is None:
        return True
    Fs, Fp = np.asarray(template_f), np.asarray(pose_f)
    return not (len(Fs) and len(Fp)) or np.array_equal(Fs, Fp)


def template_cage_classical(template_v: ArrayLike, template_f: ArrayLike | None,
                            cage_v: ArrayLike, cage_f: ArrayLike, pose_v: ArrayLike,
                            pose_f: ArrayLike | None, *, seed: int = 0,
                            smoothness: float = SMOOTHNESS,
                            fitter: ClassicalFitter | None = None,
                            max_evaluations: int = TEMPLATE_EVALUATIONS) -> np.ndarray:
    """The template's deformed cage ``C_(s->t)`` by a per-pair cage fit (no training).

    Parameters
    ----------
    template_v, template_f : (n, 3) array_like of float and (m, 3) array_like of int
        The template in rest pose.
    cage_v, cage_f : (k, 3) array_like of float and (c, 3) array_like of int
        ``C_s`` in the template's frame.
    pose_v, pose_f : (p, 3) array_like of float and (q, 3) array_like of int, or None
        The template in the target pose. When it :func:`corresponds` to the template
        (same vertex count and faces), the cage is the linear least-squares fit
        ``min_C |W C - V_pose|^2 + smoothness |L (C - C_s)|^2`` (``W`` the template's
        mean value coordinates, ``L`` the cage's cotangent Laplacian): the L2 alignment
        with every vertex as a correspondence, solved exactly. Otherwise the pose is
        matched by :func:`cagekit.deform` (Chamfer distance, ``max_evaluations``).
    seed : int, default 0
    smoothness : float, default :data:`SMOOTHNESS`
    fitter : callable, optional
        :func:`classical_fitter` of this template and cage, when already built (for
        many poses).
    max_evaluations : int, default 200

    Returns
    -------
    (k, 3) float64
        ``C_(s->t)`` in the pose's frame (the template's, for poses of one character).
    """
    Vs, Vp = np.asarray(template_v, np.float64), np.asarray(pose_v, np.float64)
    cage_v = as_vertices(cage_v, "cage_v")
    if not corresponds(Vs, template_f, Vp, pose_f):
        result = deform(Vs, template_f, Vp, pose_f, cage_v, cage_f,
                        DeformOptions(method="cage", max_evaluations=max_evaluations,
                                      seed=seed))
        if result.deformed_cage_v is None:  # method cage always sets it
            raise AssertionError("deform returned no deformed cage")
        return result.deformed_cage_v
    if fitter is None:
        fitter = classical_fitter(Vs, cage_v, cage_f, smoothness=smoothness)
    return fitter(Vp)


def classical_fitter(template_v: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike, *,
                     smoothness: float = SMOOTHNESS) -> ClassicalFitter:
    """The least-squares template fit of :func:`template_cage_classical`, factored once.

    ``min_C |W C - V_pose|^2 + smoothness |L (C - C_s)|^2`` has the same matrix for every
    pose of one template; its pseudo-inverse is computed here, and each pose then costs
    one matrix product.

    Parameters
    ----------
    template_v : (n_s, 3) array_like of float
        The template in rest pose.
    cage_v, cage_f : (k, 3) float, (f, 3) int
        ``C_s``.
    smoothness : float, default :data:`SMOOTHNESS`

    Returns
    -------
    ClassicalFitter
        ``fitter(pose_v)``: (n_s, 3) pose vertices in the template's vertex order ->
        (k, 3) float64 ``C_(s->t)``; ``fitter.miss(pose_v, C)``: how far the template
        moved by ``C`` lands from the pose.
    """
    cage_v = as_vertices(cage_v, "cage_v")
    cage_f = check_cage(cage_v, cage_f)
    W = bind(as_vertices(template_v, "template_v"), cage_v, cage_f, check=False).weights
    L = cotangent_laplacian(cage_v, cage_f).toarray()
    r = np.sqrt(float(smoothness))
    return ClassicalFitter(W, np.linalg.pinv(np.vstack([W, r * L])), r * (L @ cage_v))


class ClassicalFitter:
    """:func:`classical_fitter`'s result: the factored fit of a template's poses.

    Parameters
    ----------
    weights : (n_s, k) float64
        The template's mean value coordinates in ``C_s``.
    solve : (k, n_s + k) float64
        The pseudo-inverse of ``[W; sqrt(smoothness) L]``.
    anchor : (k, 3) float64
        ``sqrt(smoothness) L C_s``.
    """

    def __init__(self, weights: np.ndarray, solve: np.ndarray, anchor: np.ndarray):
        self.weights, self.solve, self.anchor = weights, solve, anchor

    def __call__(self, pose_v: ArrayLike) -> Vertices:
        """(n_s, 3) pose vertices -> (k, 3) ``C_(s->t)``."""
        C = self.solve @ np.vstack([np.asarray(pose_v, np.float64), self.anchor])
        if not np.isfinite(C).all():
            raise FloatingPointError("the cage fit produced NaN or inf positions")
        return C

    def miss(self, pose_v: ArrayLike, deformed_cage_v: ArrayLike) -> np.ndarray:
        """(n_s,) distance from each pose vertex to the template vertex moved by the cage:
        how closely the cage reproduces the template's own pose (a cage whose limbs share
        faces cannot move them apart, and the character's poses inherit the miss)."""
        moved = self.weights @ np.asarray(deformed_cage_v, np.float64)
        return np.linalg.norm(moved - np.asarray(pose_v, np.float64), axis=1)


def transfer(character: CharacterCage, deformed_template_cage_v: ArrayLike,
             rule: str = "pose", *, refine: bool = True, root: str = "follow") -> Vertices:
    """The character deformed like the template.

    Parameters
    ----------
    character : CharacterCage
        From :func:`fit_character`.
    deformed_template_cage_v : (k, 3) array_like of float
        ``C_st`` from :func:`template_cage_classical` or :func:`template_cage_learned`.
    rule : {"pose", "offsets"}, default "pose"
        How the template cage's motion is carried (:mod:`cagekit.transfer.rules`).
    refine : bool, default True
        Make the cage's result as rigid as possible where it tears the mesh
        (:meth:`cagekit.transfer.surface_binding.SurfaceBinding.deform`), and move the loose pieces
        back to what they touched at rest (:mod:`cagekit.transfer.loose_pieces`).
    root : {"follow", "ground"}, default "follow"
        Where the whole character goes when the example also moves the template's root
        (a jump, a crouch, a step): ``"follow"`` moves it as the template's root moves,
        scaled by the alignment (:func:`cagekit.transfer.rules.root_weights`; the pose
        rule pins the root, the point of the template's cage the example moves least near
        its centre); ``"ground"`` then moves every result along +y (up, the axis the
        characters stand on) until its lowest point is where its rest pose's lowest
        point was: its ground contact is kept, in a jump or a seated pose as well.

    Returns
    -------
    (n, 3) float64
        The character's vertices, in its rest pose's frame and faces.
    """
    if root not in ROOTS:
        raise InputError(f"root must be one of {', '.join(ROOTS)}, got {root!r}")
    cage = transfer_cage(rule, character.template_cage_v, deformed_template_cage_v,
                         character.cage_v, character.cage_f, character.fit.alignment,
                         parts=character.parts)
    X = character.binding.deform(cage, refine=refine)
    if not np.isfinite(X).all():
        raise FloatingPointError("the transfer produced NaN or inf positions")
    if refine and character.loose is not None:
        X = character.loose.reattach(character.vertices, X)
    if root == "ground":
        X[:, 1] += character.vertices[:, 1].min() - X[:, 1].min()
    return X


def cage_oracle(weights: ArrayLike, truth_v: ArrayLike) -> tuple[Vertices, Vertices]:
    """The best a cage can do: its least-squares motion onto a known result (the oracle).

    A transfer rule moves the character's cage; no rule can do better than the cage
    position whose coordinates reproduce the truth (the character posed by its own rig)
    most closely. Reported beside every rule, it separates the error the rule causes from
    the error the cage itself cannot avoid (docs/architecture.md, "Transfer metric").

    Parameters
    ----------
    weights : (n, k) array_like of float
        The character's coordinates in its cage (mean value coordinates: the deformation
        is ``weights @ cage_v``), e.g. ``CharacterCage.binding.weights``.
    truth_v : (n, 3) array_like of float
        The true posed character, same vertices and order.

    Returns
    -------
    cage_v : (k, 3) float64
        The least-squares best cage (minimum-norm where the weights leave it free).
    vertices : (n, 3) float64
        ``weights @ cage_v``: the closest the cage can bring the character to the truth.

    Examples
    --------
    >>> from cagekit.coords import bind
    >>> from cagekit.cage.shapes import box_cage
    >>> cage_v, cage_f = box_cage()
    >>> points = np.array([[0.1, 0.2, 0.3], [-0.5, 0.0, 0.4], [0.0, -0.6, 0.0]])
    >>> W = bind(points, cage_v, cage_f).weights
    >>> _, best = cage_oracle(W, points * 2.0)  # a scaling the cage makes exactly
    >>> bool(np.abs(best - points * 2.0).max() < 1e-9)
    True
    """
    W = np.asarray(weights, dtype=np.float64)
    truth = np.asarray(truth_v, dtype=np.float64)
    if W.ndim != 2 or truth.shape != (W.shape[0], 3):
        raise InputError(f"cage_oracle needs (n, k) weights and (n, 3) truth, got "
                         f"{W.shape} and {truth.shape}")
    if not (np.isfinite(W).all() and np.isfinite(truth).all()):
        raise InputError("cage_oracle: the weights or the truth hold NaN or inf")
    # float64 from float64 (numpy's stubs say only "floating")
    cage_v = cast(Vertices, np.linalg.lstsq(W, truth, rcond=None)[0])
    return cage_v, W @ cage_v


def render_grid(path: str | os.PathLike[str],
                rows: Sequence[Sequence[tuple[ArrayLike, ArrayLike]]],
                titles: Sequence[str] | None = None, labels: Sequence[str] | None = None,
                panel: tuple[int, int] = (240, 300)) -> None:
    """Rows of meshes in one PNG (atomic): for example template poses above, the
    transferred character below.

    Parameters
    ----------
    path : str or os.PathLike
    rows : sequence of sequences of (V, F)
        Each row drawn side by side in one frame (:func:`cagekit.render.render_meshes`
        with ``same_scale=True``), the rows stacked top to bottom.
    titles : sequence of str, optional
        Column titles, above the first row.
    labels : sequence of str, optional
        One caption per row, below it.
    panel : (int, int)
        Width and height of one panel in pixels.
    """
    from cagekit.render import render_grid as grid

    grid(path, rows, titles=[titles] + [None] * (len(rows) - 1) if titles else None,
         captions=labels, size=panel, same_scale=True, views=((10, -70),))

