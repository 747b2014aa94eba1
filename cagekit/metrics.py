"""Evaluation metrics of a deformation: Chamfer distance and cotangent-Laplacian distortion.

The definitions are those of docs/architecture.md ("Metrics", as the paper's evaluation
code computes them): ``CD = mean_a min_b |a - b|^2 + mean_b min_a |a - b|^2`` on 5000
area-uniform samples per surface (tables print ``CD x 10^2``), and ``dCotLap``, the mean
over all ``n x 3`` entries of ``(L (V_out - V_src))^2`` with ``L`` the cotangent Laplacian,
no mass matrix, of the normalised source (tables print ``dCotLap x 10^3``). In
:func:`evaluate` the target is normalised on its own, the deformed source is mapped by the
target's normalisation and the source normalised on its own is the distortion reference.
The two surfaces are sampled with independent streams spawned from one ``seed``, so CD
measures the distance between surfaces, not vertex correspondence: identical shapes give a
small positive CD and ``chamfer(a, b)`` equals ``chamfer(b, a)`` only in distribution. A
point cloud is not resampled (a seeded subset when it has more than ``n`` points). dCotLap
is invariant to translating ``V_out``, not to rotating or scaling it. Duplicate and
zero-area faces are removed before ``L`` is built (a vertex only on such faces gets an empty
row, still counted in ``n``); a source without faces of positive area raises ``InputError``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from cagekit.errors import InputError
from cagekit.frame import Frame
from cagekit.geometry import (
    as_faces,
    as_shape,
    as_vertices,
    cotangent_laplacian,
    face_areas,
    remove_duplicate_faces,
)
from cagekit.sampling import surface_samples

__all__ = ["chamfer", "chamfer_distance", "dcotlap", "evaluate"]


def _nearest_sq(P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Squared distance from each point of P to its nearest point of Q, shape (len(P),)."""
    _, idx = cKDTree(Q).query(P)
    diff = P - Q[idx]
    return np.einsum("ij,ij->i", diff, diff)


def chamfer_distance(P: ArrayLike, Q: ArrayLike) -> float:
    """Chamfer distance between two point sets (squared, both directions summed).

    ``mean_{a in P} min_{b in Q} |a - b|^2 + mean_{b in Q} min_{a in P} |a - b|^2``,
    nearest neighbours by ``scipy.spatial.cKDTree``.

    Parameters
    ----------
    P : array_like, shape (n, 3), float
    Q : array_like, shape (m, 3), float

    Returns
    -------
    cd : float
        Non-negative; 0 for equal sets; symmetric in ``P`` and ``Q``.

    Examples
    --------
    >>> chamfer_distance([[0, 0, 0]], [[0, 0, 2]])
    8.0
    """
    P = as_vertices(P, "P")
    Q = as_vertices(Q, "Q")
    return float(_nearest_sq(P, Q).mean() + _nearest_sq(Q, P).mean())


def chamfer(
    Va: ArrayLike,
    Fa: ArrayLike | None,
    Vb: ArrayLike,
    Fb: ArrayLike | None,
    n_samples: int = 5000,
    seed: int = 0,
) -> float:
    """Chamfer distance between two surfaces (or clouds), sampled independently.

    Shape a is sampled with the first and shape b with the second of two random streams
    derived from ``seed`` (``numpy.random.SeedSequence(seed).spawn(2)``), so the result
    is deterministic for a given seed but two shapes of the same topology do not get
    samples at the same places of the same faces.

    Parameters
    ----------
    Va, Vb : array_like, shape (na, 3) and (nb, 3), float
        Vertex positions of the two shapes.
    Fa, Fb : array_like, shape (ma, 3) and (mb, 3), int, or None
        Their triangles; ``None`` or empty for point clouds.
    n_samples : int, optional
        Samples per shape (see :func:`surface_samples`).
    seed : int, optional
        Non-negative; the two sampling streams are derived from it.

    Returns
    -------
    cd : float
        :func:`chamfer_distance` of the two sample sets. Identical shapes give a small
        positive value, of the order of the squared sample spacing.

    Raises
    ------
    InputError
        A negative or non-integer ``seed``, or bad input.

    Examples
    --------
    >>> V, F = [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]
    >>> cd = chamfer(V, F, V, F, n_samples=1000)
    >>> 0.0 < cd < 1e-3, cd == chamfer(V, F, V, F, n_samples=1000)
    (True, True)
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed must be an integer >= 0, got {seed!r}")
    seed_a, seed_b = (
        int(s.generate_state(1)[0]) for s in np.random.SeedSequence(int(seed)).spawn(2)
    )
    A = surface_samples(Va, Fa, n_samples, seed_a)
    B = surface_samples(Vb, Fb, n_samples, seed_b)
    return chamfer_distance(A, B)


def dcotlap(V_src: ArrayLike, F_src: ArrayLike, V_out: ArrayLike) -> float:
    """Cotangent-Laplacian distortion of a deformation ``V_src -> V_out``.

    ``mean over all n x 3 entries of (L (V_out - V_src))^2``, ``L`` the cotangent
    Laplacian of ``(V_src, F_src)`` after duplicate faces
    (:func:`cagekit.geometry.remove_duplicate_faces`) and faces of zero area are removed
    (a zero-area face has undefined cotangents). Both vertex sets must already be in the
    frame the caller wants (:func:`evaluate` uses the normalised frames).

    Parameters
    ----------
    V_src : array_like, shape (n, 3), float
        Source vertices (the rest shape ``L`` is built from).
    F_src : array_like, shape (m, 3), int
        Source triangles, at least one of positive area.
    V_out : array_like, shape (n, 3), float
        Deformed vertices, same order as ``V_src``.

    Returns
    -------
    d : float
        Non-negative; 0 for ``V_out = V_src + t`` (any translation ``t``).

    Raises
    ------
    InputError
        Different vertex counts, no faces of positive area, or bad input.

    Examples
    --------
    >>> V, F = [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]
    >>> dcotlap(V, F, np.asarray(V) + 5.0)
    0.0
    """
    V_src = as_vertices(V_src, "V_src")
    V_out = as_vertices(V_out, "V_out")
    if V_out.shape != V_src.shape:
        raise InputError(
            f"V_out has {len(V_out)} vertices but the source has {len(V_src)}; "
            "the deformed shape must keep the source's vertices"
        )
    F = remove_duplicate_faces(as_faces(F_src, len(V_src), "F_src"))
    if len(F) == 0:
        raise InputError("dCotLap needs the source's faces; the source has none")
    F = F[face_areas(V_src, F) > 0.0]  # zero-area faces have undefined cotangents
    if len(F) == 0:
        raise InputError("dCotLap needs faces of positive area; all the source's faces "
                         "have zero area")
    L = cotangent_laplacian(V_src, F)
    return float(np.mean(np.square(L @ (V_out - V_src))))


def evaluate(source, target, deformed, n_samples: int = 5000, seed: int = 0,
             frames=None) -> dict:
    """CD and dCotLap of a deformed source against a target, in the paper's frames.

    The target is normalised on its own; the deformed source is mapped by the target's
    ``(center, scale)``; the source normalised on its own is the distortion reference.
    ``cd`` compares the deformed source (target frame) with the normalised target;
    ``dcotlap`` uses ``L`` of the normalised source and ``V_out`` = the deformed source
    in the target's frame.

    Parameters
    ----------
    source : (V, F) pair
        Source mesh before deformation, ``V`` (n, 3) float, ``F`` (m, 3) int, ``m >= 1``.
    target : (V, F) pair
        Target mesh, or point cloud with ``F`` None or empty.
    deformed : (V, F) pair
        Deformed source, ``V`` (n, 3) in the same vertex order as the source. ``F`` is
        used for sampling; when None or empty the source's faces are used.
    n_samples : int, optional
        Samples per surface for CD (5000 in the paper).
    seed : int, optional
        Sampling seed, non-negative; the two surfaces get independent streams derived
        from it (see :func:`chamfer`).
    frames : (source Frame, target Frame), optional
        The shapes' unit frames (:meth:`cagekit.frame.Frame.of`) when the caller has them
        already (``DeformResult.source_frame``, ``target_frame``); computed otherwise.

    Returns
    -------
    dict
        ``{"cd": float, "dcotlap": float, "cd_x1e2": float, "dcotlap_x1e3": float,
        "n_samples": int, "seed": int}``.

    Raises
    ------
    InputError
        Deformed and source vertex counts differ, the source has no faces (of positive
        area), a shape has zero extent, a negative seed, or bad input.

    Examples
    --------
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    >>> F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> moved = (2 * V + 1, F)  # scaled and translated copy, also used as the target
    >>> m = evaluate((V, F), moved, moved)
    >>> 0.0 < m["cd"] < 1e-2, m["dcotlap"] < 1e-20  # CD: the sampling resolution only
    (True, True)
    """
    Vs, Fs = as_shape(source, name="source")
    Vt, Ft = as_shape(target, name="target")
    Vd, Fd = as_shape(deformed, name="deformed")
    if len(Vd) != len(Vs):
        raise InputError(
            f"the deformed shape has {len(Vd)} vertices but the source has {len(Vs)}"
        )
    if len(Fs) == 0:
        raise InputError("the source must be a mesh with faces (dCotLap needs them)")
    if len(Fd) == 0:
        Fd = Fs
    fs, ft = (Frame.of(Vs), Frame.of(Vt)) if frames is None else frames
    Vs_n, Vt_n, Vd_t = fs.to_unit(Vs), ft.to_unit(Vt), ft.to_unit(Vd)
    cd = chamfer(Vd_t, Fd, Vt_n, Ft, n_samples=n_samples, seed=seed)
    dist = dcotlap(Vs_n, Fs, Vd_t)
    return {
        "cd": cd,
        "dcotlap": dist,
        "cd_x1e2": cd * 1e2,
        "dcotlap_x1e3": dist * 1e3,
        "n_samples": int(n_samples),
        "seed": int(seed),
    }
