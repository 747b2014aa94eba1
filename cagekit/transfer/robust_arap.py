"""A deformed mesh made as rigid as possible, trusting a proposal only where it agrees.

A cage moves every point of a bound mesh, but not every point the right way: where a real
character's coat lies inside its arm's cage tube, or its hand's coordinates reach through a
fold of the cage into the body, a patch of the surface follows the wrong part and the
deformed mesh tears into shards between the two. The patch is rarely flagged beforehand (its
coordinates can be perfectly ordinary); it shows in the deformation, as edges many times
their length.

:func:`robust_arap` takes the cage's result as a *proposal* and finds the mesh closest to it
that deforms its rest shape locally by rotations only (as-rigid-as-possible, Sorkine &
Alexa 2007, uniform edge weights: real meshes carry degenerate triangles), with each point
pulled to its proposal by a weight that falls as the two disagree (iteratively reweighted
least squares with a Cauchy weight ``1 / (1 + (r / sigma)^2)``). A patch that disagrees with
the surface around it loses its pull and follows its neighbours; a proposal that is a
similarity of the rest shape is returned unchanged.

The reweighting alone cannot reject a shard it has followed: a point pulled by full trust
lands on its proposal, agrees with it, and keeps its trust (a finger or a shoe's toe drawn
out by a cage fold stays drawn out). So the proposal's own edges are read first: a point
whose proposed edges are longer or shorter than their rest length by ``s`` (the largest
over its edges) starts with its trust divided by ``1 + (s / sigma)^2`` (:func:`strain_trust`):
the shard's ends lose their pull before the first solve and the mesh around them decides.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cagekit.cage import unique_edges
from cagekit.errors import InputError
from cagekit.geometry import as_vertices, uniform_laplacian, vertex_rotations
from cagekit.typed import Floats

__all__ = ["RobustArap", "robust_arap", "strain_trust", "STIFFNESS", "ITERATIONS"]

#: weight of a fully trusted point's pull to its proposal against the uniform Laplacian
#: (a vertex of degree 6 weighs 6 there)
STIFFNESS = 10.0
#: local-global iterations (each reweights the pulls once)
ITERATIONS = 8


@dataclass
class RobustArap:
    """The result of :func:`robust_arap`.

    Attributes
    ----------
    vertices : (n, 3) float64
        The deformed mesh.
    trust : (n,) float64
        The final weight of each point's pull, ``c / (1 + (r / sigma)^2)`` (``c`` the
        confidence times :func:`strain_trust`).
    """

    vertices: np.ndarray
    trust: np.ndarray


def robust_arap(rest_v: ArrayLike, faces: ArrayLike, proposal: ArrayLike, *, sigma: float,
                confidence: ArrayLike | None = None, scale: float = 1.0,
                stiffness: float = STIFFNESS, iterations: int = ITERATIONS,
                edges: ArrayLike | None = None) -> RobustArap:
    """The as-rigid-as-possible deformation of ``rest_v`` nearest a proposal, robustly.

    Minimises ``sum_ij |(x_i - x_j) - R_i scale (v_i - v_j)|^2 + stiffness sum_i t_i |x_i -
    p_i|^2`` over positions ``x`` and rotations ``R`` (edges of ``faces``, both directions),
    the trust ``t_i = c_i / (1 + (|x_i - p_i| / sigma)^2)`` updated after each solve, ``c_i``
    the prior ``confidence_i`` times :func:`strain_trust` (points whose proposed edges were
    torn or crushed start doubted).

    Parameters
    ----------
    rest_v : (n, 3) array_like of float
        The mesh at rest.
    faces : (m, 3) array_like of int
        Its triangles; separate components are solved together, each pulled by its own
        proposal.
    proposal : (n, 3) array_like of float
        The deformed positions to follow (for example a cage's result).
    sigma : float
        Disagreement, in the proposal's units, at which a point's pull is halved.
    confidence : (n,) array_like of float, optional
        Prior trust per point in (0, 1] (default 1): for example low where the cage's
        coordinates are known to be unreliable.
    scale : float, default 1.0
        Uniform scale of the rest shape (a cage that grew by ``scale``).
    stiffness : float
    iterations : int
    edges : (e, 2) array_like of int, optional
        ``cagekit.cage.unique_edges(faces)``, when the caller has it (a mesh deformed
        pose after pose need not find its edges again).

    Returns
    -------
    RobustArap

    Raises
    ------
    InputError
        Shapes that disagree, a non-positive ``sigma`` or ``scale``, confidences outside
        (0, 1].

    Examples
    --------
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    >>> F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> P = V.copy(); P[3] = [0, 0, 3]               # one point pulled off
    >>> out = robust_arap(V, F, P, sigma=0.1)
    >>> bool(np.abs(out.vertices[3] - V[3]).max() < 0.2), bool(out.trust[3] < 0.01)
    (True, True)
    """
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    V = as_vertices(rest_v, "rest_v")
    P = as_vertices(proposal, "proposal")
    if P.shape != V.shape:
        raise InputError(f"proposal has shape {P.shape}, rest_v {V.shape}")
    if not (sigma > 0 and scale > 0):
        raise InputError(f"sigma and scale must be positive, got {sigma}, {scale}")
    n = len(V)
    c0 = np.ones(n) if confidence is None else np.asarray(confidence, dtype=np.float64)
    if c0.shape != (n,) or not np.all((c0 > 0) & (c0 <= 1)):
        raise InputError("confidence must be n values in (0, 1]")
    E = unique_edges(faces) if edges is None else np.asarray(edges, np.int64).reshape(-1, 2)
    if not len(E):
        return RobustArap(vertices=P.copy(), trust=c0.copy())
    c0 = np.maximum(c0 * strain_trust(V, P, E, sigma=sigma, scale=scale), 1e-6)
    L = uniform_laplacian(n, E)
    i, j = np.concatenate([E[:, 0], E[:, 1]]), np.concatenate([E[:, 1], E[:, 0]])
    rest_edges = scale * (V[i] - V[j])
    X, trust = P.copy(), c0.copy()
    for _ in range(iterations):
        R = vertex_rotations(V, X, E)
        rotated = 0.5 * np.einsum("eab,eb->ea", R[i] + R[j], rest_edges)
        b = np.stack([np.bincount(i, rotated[:, k], minlength=n) for k in range(3)], axis=1)
        K = (L + sp.diags(stiffness * trust)).tocsc()
        X = splu(K).solve(b + stiffness * trust[:, None] * P)
        r = np.linalg.norm(X - P, axis=1) / sigma
        trust = c0 / (1.0 + r ** 2)
    if not np.isfinite(X).all():
        raise FloatingPointError("robust_arap produced NaN or inf positions")
    return RobustArap(vertices=X, trust=trust)


def strain_trust(rest_v: ArrayLike, proposal: ArrayLike, edges: ArrayLike, *, sigma: float,
                 scale: float = 1.0) -> Floats:
    """How far a proposal's edges at each point keep their rest length: ``1 / (1 + (s /
    sigma)^2)``, ``s`` the largest ``| |p_i - p_j| - scale |v_i - v_j| |`` over the point's
    edges (1 for a point without edges, and wherever the proposal is a similarity of the
    rest shape by ``scale``).

    Parameters
    ----------
    rest_v, proposal : (n, 3) float64
    edges : (e, 2) int64
    sigma, scale : float
        As :func:`robust_arap` takes them.

    Returns
    -------
    (n,) float64 in (0, 1]

    Raises
    ------
    InputError
        Meshes of different shapes, NaN or inf, an edge index out of range, ``sigma`` or
        ``scale`` not a positive number.

    Examples
    --------
    >>> V = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    >>> P = V.copy(); P[2, 0] = 5.0                    # the last edge drawn out by 3
    >>> strain_trust(V, P, np.array([[0, 1], [1, 2]]), sigma=1.0).round(2).tolist()
    [1.0, 0.1, 0.1]
    """
    V, P = as_vertices(rest_v, "rest_v"), as_vertices(proposal, "proposal")
    if V.shape != P.shape or not (np.isfinite(V).all() and np.isfinite(P).all()):
        raise InputError(f"strain_trust needs two finite meshes of one shape, got {V.shape} "
                         f"and {P.shape}")
    for name, value in (("sigma", sigma), ("scale", scale)):
        if not (np.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a positive number, got {value!r}")
    n = len(V)
    E = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if len(E) and (E.min() < 0 or E.max() >= n):
        raise InputError(f"an edge names a vertex outside 0..{n - 1}")
    s = np.zeros(n)
    if len(E):
        excess = np.abs(np.linalg.norm(P[E[:, 0]] - P[E[:, 1]], axis=1)
                        - scale * np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1))
        np.maximum.at(s, E[:, 0], excess)
        np.maximum.at(s, E[:, 1], excess)
    return 1.0 / (1.0 + (s / sigma) ** 2)
