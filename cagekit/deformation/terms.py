"""The per-pair energy's terms (section 3.3 of "Neural Cages"), each with its exact gradient.

Every function takes point positions (usually the deformed points ``X = W @ C``, linear in
the cage ``C``) and returns ``(value, gradient)`` with respect to the positions it was
given, so the chain rule through the binding is one product, ``dE/dC = W.T @ dE/dX``; all
arrays are float64. The terms: Chamfer and landmark alignment, point-set and cage symmetry,
point-to-plane and PCA-normal change (:func:`shape_losses`, one eigen-decomposition), each
part's distance from an affine map of itself (:func:`part_affinity_loss`, ours: the
structure of man-made shapes), the cage's Laplacian change and ``L_MVC`` (negative
weights); each function states its formula.
Chamfer follows docs/architecture.md ("Metrics"): squared distances, both directions summed,
not halved; its gradient is that of the current nearest neighbours (it is piecewise
quadratic). The PCA normal's derivative is the first-order eigenvector perturbation, and
pairs of eigenvalues closer than ``1e-12`` times the covariance's trace contribute no
gradient, so gradients stay finite where the normal is not a function of the points. A
normal's sign is arbitrary; both shape terms compare it with the rest normal up to sign.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from cagekit.errors import InputError
from cagekit.metrics import nearest_residuals
from cagekit.typed import Bools, Floats, Ints, Vertices

__all__ = [
    "ALPHA_MVC",
    "ALPHA_SHAPE",
    "ShapeReference",
    "cage_symmetry_loss",
    "chamfer_loss",
    "detail_loss",
    "detail_matrix",
    "partial_chamfer_loss",
    "landmark_loss",
    "laplacian_loss",
    "mirror",
    "mirror_partners",
    "mvc_loss",
    "normal_loss",
    "p2f_loss",
    "PartBases",
    "part_affinity_loss",
    "part_affinity_matrix",
    "part_bases",
    "shape_losses",
    "shape_reference",
    "symmetry_loss",
]

#: weight of the MVC regulariser in the training energy (the paper's ``alpha_MVC``)
ALPHA_MVC = 1.0
#: weight of the shape terms, point-to-plane and normal (the paper's ``alpha_shape``)
ALPHA_SHAPE = 0.1

AXES = {"x": 0, "y": 1, "z": 2}


def _finite(value: float, what: str) -> float:
    if not np.isfinite(value):
        raise FloatingPointError(f"{what} is not finite (NaN or inf positions?)")
    return float(value)


# ---------------------------------------------------------------------------- alignment


def _scatter(n, index, values):
    """Sum ``values[..., :]`` into row ``index[...]`` of an ``(n, 3)`` array."""
    flat = index.ravel()
    vals = values.reshape(-1, 3)
    return np.stack([np.bincount(flat, weights=vals[:, a], minlength=n) for a in range(3)],
                    axis=1)


def _check_points(P, what):
    """FloatingPointError for NaN, inf, or coordinates whose squares would overflow."""
    if not np.isfinite(P).all():
        raise FloatingPointError(f"{what} has NaN or inf coordinates")
    if len(P) and np.abs(P).max() > 1e150:
        raise FloatingPointError(f"{what} has coordinates too large to square (> 1e150)")


def _chamfer_pair(P, Q, tree_Q=None, weight_pq=1.0):
    """Chamfer value and the gradients with respect to both point sets (the ``P -> Q``
    direction weighted by ``weight_pq``)."""
    _check_points(P, "the moving point set")
    _check_points(Q, "the fixed point set")
    e_pq, to_q = nearest_residuals(P, Q, tree_Q)  # (s, 3): each P point minus its nearest Q
    e_qp, to_p = nearest_residuals(Q, P)  # (t, 3)
    s, t = len(P), len(Q)
    value = (weight_pq * np.einsum("ij,ij->", e_pq, e_pq) / s
             + np.einsum("ij,ij->", e_qp, e_qp) / t)
    grad_P = 2.0 * weight_pq * e_pq / s - _scatter(s, to_p, 2.0 * e_qp / t)
    grad_Q = 2.0 * e_qp / t - _scatter(t, to_q, 2.0 * weight_pq * e_pq / s)
    return _finite(value, "Chamfer distance"), grad_P, grad_Q


def chamfer_loss(P: Vertices, Q: Vertices, tree_Q: cKDTree | None = None) -> tuple[float, Vertices]:
    """Chamfer distance between moving points ``P`` and fixed points ``Q``, with ``dL/dP``.

    Parameters
    ----------
    P : (s, 3) float64
        Moving points (deformed source samples).
    Q : (t, 3) float64
        Fixed points (target samples).
    tree_Q : scipy.spatial.cKDTree, optional
        A tree built on ``Q``, reused across calls.

    Returns
    -------
    value : float
        ``mean_i min_j |P_i - Q_j|^2 + mean_j min_i |P_i - Q_j|^2``.
    grad : (s, 3) float64
        Gradient of ``value`` with respect to ``P`` (nearest neighbours held fixed).

    Examples
    --------
    >>> value, grad = chamfer_loss(np.array([[0.0, 0, 0]]), np.array([[0.0, 0, 2]]))
    >>> value, grad.tolist()
    (8.0, [[0.0, 0.0, -8.0]])
    """
    value, grad_P, _ = _chamfer_pair(P, Q, tree_Q)
    return value, grad_P


def partial_chamfer_loss(P: Vertices, Q: Vertices, tree_Q: cKDTree | None = None,
                         source_weight: float = 0.1) -> tuple[float, Vertices]:
    """Chamfer onto a partial target: the moving points' own direction down-weighted.

    A scan seen from one side covers only part of the target: every scanned point
    should lie on the deformed source (``Q -> P``, full weight), but the source's unseen
    side has no scanned point to go to, and the ``P -> Q`` direction at full weight
    squashes it onto the seen side.

    Parameters
    ----------
    P : (s, 3) float64
        Moving points (deformed source samples).
    Q : (t, 3) float64
        Fixed points (the scan's points).
    tree_Q : scipy.spatial.cKDTree, optional
    source_weight : float, default 0.1
        Weight of ``mean_i min_j |P_i - Q_j|^2``.

    Returns
    -------
    value : float
        ``source_weight * mean_i min_j |P_i - Q_j|^2 + mean_j min_i |P_i - Q_j|^2``.
    grad : (s, 3) float64

    Examples
    --------
    >>> value, grad = partial_chamfer_loss(np.array([[0.0, 0, 0]]), np.array([[0.0, 0, 2]]))
    >>> round(value, 6), grad.round(6).tolist()
    (4.4, [[0.0, 0.0, -4.4]])
    """
    value, grad_P, _ = _chamfer_pair(P, Q, tree_Q, source_weight)
    return value, grad_P


def landmark_loss(P: Vertices, T: Vertices) -> tuple[float, Vertices]:
    """Mean squared distance between corresponding points, with ``dL/dP``.

    Parameters
    ----------
    P : (l, 3) float64
        Moving points (deformed source landmarks).
    T : (l, 3) float64
        Their fixed targets, row for row.

    Returns
    -------
    value : float
        ``mean_l |P_l - T_l|^2``.
    grad : (l, 3) float64

    Examples
    --------
    >>> landmark_loss(np.zeros((2, 3)), np.array([[1.0, 0, 0], [0, 0, 0]]))[0]
    0.5
    """
    diff = P - T
    value = np.einsum("ij,ij->", diff, diff) / len(P)
    return _finite(value, "landmark loss"), 2.0 * diff / len(P)


def axis_index(axis: str) -> int:
    """0, 1 or 2 for a symmetry axis ``"x"``, ``"y"`` or ``"z"``; InputError otherwise."""
    if axis not in AXES:
        raise InputError(f"symmetry axis must be one of x, y, z, got {axis!r}")
    return AXES[axis]


def mirror(P: ArrayLike, axis: str) -> Vertices:
    """Reflect points across the plane through the origin normal to ``axis``.

    Parameters
    ----------
    P : (n, 3) float64
    axis : {"x", "y", "z"}

    Returns
    -------
    (n, 3) float64

    Examples
    --------
    >>> mirror(np.array([[1.0, 2.0, 3.0]]), "x").tolist()
    [[-1.0, 2.0, 3.0]]
    """
    out = np.array(P, dtype=np.float64, copy=True)
    out[:, axis_index(axis)] *= -1.0
    return out


def symmetry_loss(P: Vertices, axis: str) -> tuple[float, Vertices]:
    """Chamfer distance between a point set and its mirror image, with ``dL/dP``.

    Both sets move with ``P``: the gradient sums the direct part and the part through the
    mirror image. It is 0 exactly when the set is symmetric about the plane through the
    origin normal to ``axis`` (shapes are centred by normalisation).

    Parameters
    ----------
    P : (s, 3) float64
    axis : {"x", "y", "z"}

    Returns
    -------
    value : float
    grad : (s, 3) float64

    Examples
    --------
    >>> symmetry_loss(np.array([[-1.0, 0, 0], [1.0, 0, 0]]), "x")[0]
    0.0
    """
    value, grad_P, grad_Q = _chamfer_pair(P, mirror(P, axis))
    return value, grad_P + mirror(grad_Q, axis)


def mirror_partners(C_ref: Vertices, axis: str) -> tuple[Ints, Vertices]:
    """Each vertex's mirror partner in a rest cage, and its rest offset from the partner.

    Parameters
    ----------
    C_ref : (k, 3) float64
        Rest cage vertices, centred on the plane of symmetry.
    axis : {"x", "y", "z"}

    Returns
    -------
    partner : (k,) int64
        Index of the vertex nearest to each vertex's mirror image.
    offset : (k, 3) float64
        ``C_ref - mirror(C_ref[partner])``: 0 for an exactly symmetric cage.

    Examples
    --------
    >>> C = np.array([[-1.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0]])
    >>> partner, offset = mirror_partners(C, "x")
    >>> partner.tolist(), float(abs(offset).max())
    ([1, 0, 2], 0.0)
    """
    M = mirror(C_ref, axis)
    _, partner = cKDTree(M).query(C_ref)
    partner = np.asarray(partner, dtype=np.int64)
    return partner, C_ref - M[partner]


def cage_symmetry_loss(C: Vertices, partner: Ints, offset: Vertices,
                       axis: str) -> tuple[float, Vertices]:
    """Change of each cage vertex's offset from its rest mirror partner, with ``dL/dC``.

    ``mean_i |C_i - mirror(C_partner(i)) - offset_i|^2``. For a symmetric rest cage
    (``offset = 0``) this is half the Chamfer distance between the cage and its mirror
    image with the rest nearest neighbours; for a cage that is not symmetric (fitted
    cages rarely are) it asks for a symmetric *motion* instead of pulling the cage
    towards symmetry, which would bend a symmetric shape inside it.

    Parameters
    ----------
    C : (k, 3) float64
    partner, offset : from :func:`mirror_partners` on the rest cage
    axis : {"x", "y", "z"}

    Returns
    -------
    value : float
    grad : (k, 3) float64

    Examples
    --------
    >>> C = np.array([[-1.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0]])
    >>> partner, offset = mirror_partners(C, "x")
    >>> cage_symmetry_loss(C * [1, 2, 1], partner, offset, "x")[0]
    0.0
    """
    e = C - mirror(C[partner], axis) - offset
    k = len(C)
    value = np.einsum("ij,ij->", e, e) / k
    grad = 2.0 * e / k + _scatter(k, partner, mirror(-2.0 * e / k, axis))
    return _finite(value, "cage symmetry loss"), grad


def laplacian_loss(C: Vertices, L: scipy.sparse.spmatrix,
                   C_ref: Vertices) -> tuple[float, Vertices]:
    """Change of a cage's Laplacian coordinates, with ``dL/dC``.

    Parameters
    ----------
    C : (k, 3) float64
        Cage vertices.
    L : (k, k) sparse
        Laplacian of the reference cage (cotangent, :func:`cagekit.cotangent_laplacian`).
    C_ref : (k, 3) float64
        Reference cage vertices.

    Returns
    -------
    value : float
        ``mean over k x 3 entries of (L (C - C_ref))^2``, 0 for any translation of
        ``C_ref``.
    grad : (k, 3) float64

    Examples
    --------
    >>> L = scipy.sparse.csr_matrix([[-1.0, 1.0], [1.0, -1.0]])
    >>> laplacian_loss(np.ones((2, 3)), L, np.zeros((2, 3)))[0]
    0.0
    """
    R = L @ (C - C_ref)
    value = np.einsum("ij,ij->", R, R) / R.size
    return _finite(value, "cage Laplacian loss"), 2.0 * (L.T @ R) / R.size


def mvc_loss(W: ArrayLike) -> tuple[float, Floats]:
    """Mean squared negative mean value coordinate, ``L_MVC`` of the paper, with ``dL/dW``.

    Mean value coordinates of points outside the cage's kernel go negative, which makes
    the deformation non-local; this term pushes the cage to keep them non-negative.

    Parameters
    ----------
    W : (n, k) float64
        Binding weights (mean value coordinates of ``n`` points with respect to ``k``
        cage vertices).

    Returns
    -------
    value : float
        ``mean over all n x k entries of min(W, 0)^2``: 0 when no weight is negative.
    grad : (n, k) float64
        ``2 min(W, 0) / W.size``.

    Examples
    --------
    >>> value, grad = mvc_loss(np.array([[1.5, -0.5], [0.0, 0.25]]))
    >>> value, grad.tolist()
    (0.0625, [[0.0, -0.25], [0.0, 0.0]])
    """
    W = np.asarray(W, dtype=np.float64)
    if W.size == 0:
        raise InputError("MVC loss of an empty weight matrix")
    negative = np.minimum(W, 0.0)
    value = np.vdot(negative, negative) / W.size
    return _finite(value, "MVC loss"), 2.0 * negative / W.size


# ------------------------------------------------------------------------ shape terms


class ShapeReference(NamedTuple):
    """Neighbourhoods and rest-state planes for :func:`p2f_loss` and :func:`normal_loss`.

    Attributes
    ----------
    own : (r, ) int64
        Index (into the points passed to the losses) of each plane's own vertex.
    index : (r, m) int64
        Members of each neighbourhood (indices into the points), padded.
    mask : (r, m) bool
        True for real members.
    normals : (r, 3) float64
        Rest PCA normals ``n^0``.
    distances : (r,) float64
        Rest signed distances ``d^0`` of each own vertex to its plane.
    """

    own: np.ndarray
    index: np.ndarray  # type: ignore[assignment]  # a field named as tuple.index, on purpose
    mask: np.ndarray
    normals: np.ndarray
    distances: np.ndarray


def _planes(X, index, mask):
    """Eigen-decomposition of every neighbourhood's covariance."""
    w = mask.astype(np.float64)
    m = w.sum(axis=1)
    P = X[index]
    centroid = np.einsum("rj,rjk->rk", w, P) / m[:, None]
    D = (P - centroid[:, None, :]) * w[:, :, None]
    cov = np.matmul(D.transpose(0, 2, 1), D) / m[:, None, None]
    lam, vec = np.linalg.eigh(cov)
    return lam, vec, centroid, D, m


#: a neighbourhood whose two smallest spreads (covariance eigenvalues) differ by at most
#: this fraction of its largest has no plane (its points lie on a line, or at one point):
#: its normal is arbitrary and jumps under any motion, so :func:`shape_reference` drops it
PLANE_GAP = 1e-3


def shape_reference(X: Vertices, own: ArrayLike, index: ArrayLike,
                    mask: ArrayLike) -> ShapeReference:
    """Rest normals and point-to-plane distances of the given neighbourhoods.

    Neighbourhoods without a plane (:data:`PLANE_GAP`: points on a line, as along a
    real mesh's thin strips and wires) are dropped; the losses average over the rest.

    Parameters
    ----------
    X : (n, 3) float64
        Rest positions.
    own : (r,) int
        The vertex each neighbourhood belongs to.
    index, mask : (r, m) int and bool
        Neighbourhood members (for example rows of :func:`cagekit.geometry.
        vertex_neighborhoods`); at least one real member per row.

    Returns
    -------
    ShapeReference

    Examples
    --------
    >>> X = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    >>> ref = shape_reference(X, [0], [[0, 1, 2, 3]], [[True] * 4])
    >>> float(abs(ref.normals[0, 2])), ref.distances.tolist()
    (1.0, [0.0])
    """
    own = np.asarray(own, dtype=np.int64)
    index = np.asarray(index, dtype=np.int64)
    mask = np.asarray(mask, dtype=bool)
    lam, vec, centroid, _, _ = _planes(X, index, mask)
    keep: Bools = lam[:, 1] - lam[:, 0] > PLANE_GAP * lam[:, 2]
    own, index, mask, centroid = own[keep], index[keep], mask[keep], centroid[keep]
    normals = vec[keep, :, 0]
    distances = np.einsum("rk,rk->r", X[own] - centroid, normals)
    return ShapeReference(own, index, mask, normals, distances)


def _normal_backward(g, lam, vec, D, m, mask):
    """Gradient with respect to the neighbourhood members of ``f(n)`` given ``g = df/dn``.

    ``dn = sum_{k=1,2} v_k (v_k . dM n) / (l_0 - l_k)``, so ``df/dM = sym(-sum_k a_k v_k n^T)``
    with ``a_k = (g . v_k) / (l_k - l_0)``; and ``dM = (2/m) sum_j sym(dD_j D_j^T)`` with
    ``sum_j D_j = 0`` (the centroid's own variation drops out).
    """
    n = vec[:, :, 0]
    gap_floor = 1e-12 * np.maximum(lam.sum(axis=1), np.finfo(float).tiny)
    G = np.zeros((len(g), 3, 3))
    for k in (1, 2):
        gap = lam[:, k] - lam[:, 0]
        ok = gap > gap_floor
        a = np.where(ok, np.einsum("ri,ri->r", g, vec[:, :, k]) / np.where(ok, gap, 1.0), 0.0)
        outer = (a[:, None] * vec[:, :, k])[:, :, None] * n[:, None, :]
        G -= 0.5 * (outer + outer.transpose(0, 2, 1))
    return (2.0 / m)[:, None, None] * np.matmul(D, G.transpose(0, 2, 1)) * mask[:, :, None]


def shape_losses(X: Vertices, ref: ShapeReference, p2f_weight: float = 1.0,
                 normal_weight: float = 1.0) -> tuple[dict[str, float], Vertices]:
    """:func:`p2f_loss` and :func:`normal_loss` together, from one eigen-decomposition.

    Parameters
    ----------
    X : (n, 3) float64
        Deformed positions.
    ref : ShapeReference
    p2f_weight, normal_weight : float
        Weights of the two terms in the returned gradient; a zero weight skips the term.

    Returns
    -------
    values : dict
        ``{"p2f": float, "normal": float}`` for the terms with non-zero weight.
    grad : (n, 3) float64
        Gradient of ``p2f_weight * L_p2f + normal_weight * L_normal``.

    Examples
    --------
    >>> X = np.array([[0.0, 0, 1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]])
    >>> ref = shape_reference(X, [0], [[0, 1, 2, 3, 4]], [[True] * 5])
    >>> values, grad = shape_losses(X, ref)
    >>> sorted(values), float(abs(grad).max())
    (['normal', 'p2f'], 0.0)
    """
    if not len(ref.own):  # no neighbourhood has a plane
        names = [name for name, w in (("normal", normal_weight), ("p2f", p2f_weight)) if w]
        return dict.fromkeys(names, 0.0), np.zeros_like(X)
    lam, vec, centroid, D, m = _planes(X, ref.index, ref.mask)
    n_raw = vec[:, :, 0]
    cos = np.einsum("ri,ri->r", n_raw, ref.normals)
    flip = np.where(cos < 0, -1.0, 1.0)  # orients n along n0; a constant for derivatives
    r = len(cos)
    values = {}
    g_n = np.zeros_like(n_raw)  # d(weighted sum)/d(n_raw)
    members = np.zeros_like(D)  # direct (centroid) part of d(weighted sum)/d(members)
    grad = np.zeros_like(X)
    if normal_weight:
        # |cos| may exceed 1 by rounding: clip so the value is never negative
        values["normal"] = _finite(np.mean(np.maximum(1.0 - np.abs(cos), 0.0)),
                                   "normal loss")
        g_n -= (normal_weight * flip / r)[:, None] * ref.normals
    if p2f_weight:
        n = n_raw * flip[:, None]
        offset = X[ref.own] - centroid
        residual = np.einsum("ri,ri->r", offset, n) - ref.distances
        values["p2f"] = _finite(np.mean(residual**2), "point-to-plane loss")
        coef = p2f_weight * 2.0 * residual / r  # d(weighted value) / d(d_i)
        g_n += (coef * flip)[:, None] * offset
        members -= (coef / m)[:, None, None] * n[:, None, :] * ref.mask[:, :, None]
        grad += _scatter(len(X), ref.own[:, None], (coef[:, None] * n)[:, None, :])
    if values:
        members += _normal_backward(g_n, lam, vec, D, m, ref.mask)
        grad += _scatter(len(X), ref.index, members)
    return values, grad


def normal_loss(X: Vertices, ref: ShapeReference) -> tuple[float, Vertices]:
    """Change of PCA normals, ``mean_i (1 - |n_i(X) . n_i^0|)``, with ``dL/dX``.

    Parameters
    ----------
    X : (n, 3) float64
        Deformed positions (same indexing as the reference).
    ref : ShapeReference
        From :func:`shape_reference` on the rest positions.

    Returns
    -------
    value : float
        In ``[0, 1]``; 0 when every normal is unchanged (up to sign).
    grad : (n, 3) float64

    Examples
    --------
    >>> X = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    >>> ref = shape_reference(X, [0], [[0, 1, 2, 3]], [[True] * 4])
    >>> round(normal_loss(2.0 * X, ref)[0], 12)
    0.0
    """
    values, grad = shape_losses(X, ref, p2f_weight=0.0)
    return values["normal"], grad


def p2f_loss(X: Vertices, ref: ShapeReference) -> tuple[float, Vertices]:
    """Change of point-to-plane distances, ``mean_i (d_i(X) - d_i^0)^2``, with ``dL/dX``.

    ``d_i = n_i . (x_i - c_i)``: the signed distance of vertex ``i`` to the PCA plane of
    its neighbourhood (centroid ``c_i``, normal ``n_i`` flipped to agree with ``n_i^0``).
    It measures how much the local relief (a bump, a ridge, a corner) is flattened or
    exaggerated.

    Parameters
    ----------
    X : (n, 3) float64
        Deformed positions.
    ref : ShapeReference
        From :func:`shape_reference` on the rest positions.

    Returns
    -------
    value : float
    grad : (n, 3) float64

    Examples
    --------
    >>> X = np.array([[0.0, 0, 1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]])
    >>> ref = shape_reference(X, [0], [[0, 1, 2, 3, 4]], [[True] * 5])
    >>> round(p2f_loss(X * [1, 1, 1.5], ref)[0], 12)  # the bump grows: d 0.8 -> 1.2
    0.16
    """
    values, grad = shape_losses(X, ref, normal_weight=0.0)
    return values["p2f"], grad


class PartBases(NamedTuple):
    """Per part of a shape, an orthonormal basis of the affine functions of its rest points
    (:func:`part_bases`)."""

    # (p,) int64: the rows of the points of every part, part after part
    index: np.ndarray  # type: ignore[assignment]  # a field named as tuple.index, on purpose
    starts: np.ndarray  # (parts + 1,) int64: part i is index[starts[i]:starts[i + 1]]
    bases: tuple  # per part, (n_i, r_i) float64 with orthonormal columns, r_i <= 4


def part_bases(X_rest: ArrayLike, labels: ArrayLike, min_points: int = 30) -> PartBases:
    """The affine span of each part's rest points, for :func:`part_affinity_loss`.

    Parameters
    ----------
    X_rest : (n, 3) float64
        The points at rest.
    labels : (n,) int
        A part label per point; negative labels and parts of fewer than ``min_points``
        points are left out.
    min_points : int

    Returns
    -------
    PartBases
        For each part, the left singular vectors of ``[X_rest 1]`` over its points whose
        singular values exceed ``1e-9`` times the largest (a flat part spans 3 columns).

    Examples
    --------
    >>> X = np.random.default_rng(0).normal(size=(40, 3))
    >>> b = part_bases(X, np.zeros(40, int))
    >>> b.bases[0].shape
    (40, 4)
    """
    X_rest = np.asarray(X_rest, dtype=np.float64)
    labels = np.asarray(labels)
    index, starts, bases = [], [0], []
    for label in np.unique(labels[labels >= 0]):
        rows = np.flatnonzero(labels == label)
        if len(rows) < min_points:
            continue
        U, sigma, _ = np.linalg.svd(np.column_stack([X_rest[rows], np.ones(len(rows))]),
                                    full_matrices=False)
        bases.append(U[:, sigma > 1e-9 * sigma[0]])
        index.append(rows)
        starts.append(starts[-1] + len(rows))
    rows_all = np.concatenate(index) if index else np.zeros(0, np.int64)
    return PartBases(rows_all.astype(np.int64), np.array(starts, np.int64), tuple(bases))


def part_affinity_loss(X: ArrayLike, parts: PartBases) -> tuple[float, Vertices]:
    """How far each part is from an affine map of its rest points, with ``dL/dX``.

    Parameters
    ----------
    X : (n, 3) float64
        The points (all of them; ``parts.index`` picks each part's).
    parts : PartBases

    Returns
    -------
    value : float
        ``sum over parts of |X_p - B_p B_p^T X_p|^2``, over the number of part points:
        the mean squared residual of each part's least-squares affine fit (``B_p`` the
        part's basis). 0 for any affine map of each part.
    grad : (n, 3) float64
        ``2 (X_p - B_p B_p^T X_p) / count`` on the part points, 0 elsewhere.

    Examples
    --------
    >>> X = np.random.default_rng(0).normal(size=(40, 3))
    >>> b = part_bases(X, np.zeros(40, int))
    >>> value, _ = part_affinity_loss(X @ np.diag([2.0, 1.0, 0.5]) + 3.0, b)
    >>> value < 1e-20
    True
    """
    X = np.asarray(X, dtype=np.float64)
    grad = np.zeros_like(X)
    count = len(parts.index)
    if not count:
        return 0.0, grad
    value = 0.0
    for i, B in enumerate(parts.bases):
        rows = parts.index[parts.starts[i]:parts.starts[i + 1]]
        Xp = X[rows]
        r = Xp - B @ (B.T @ Xp)
        value += float(np.einsum("ij,ij->", r, r))
        grad[rows] = 2.0 * r / count
    return _finite(value / count, "part affinity loss"), grad


def part_affinity_matrix(W: ArrayLike, parts: PartBases) -> Floats:
    """:func:`part_affinity_loss` of points ``W @ C`` as a quadratic form of ``C``.

    Parameters
    ----------
    W : (n, k) float64
        Coordinates of the points (``parts.index`` indexes its rows).
    parts : PartBases

    Returns
    -------
    (k, k) float64
        ``Q`` with ``part_affinity_loss(W @ C, parts)[0] == sum(C * (Q @ C))``; the
        gradient with respect to ``C`` is ``2 Q C``. Building it costs one pass over
        ``W``; each evaluation then costs ``k^2``, not ``n k``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> X, W, C = rng.normal(size=(40, 3)), rng.random((40, 5)), rng.normal(size=(5, 3))
    >>> parts = part_bases(X, np.zeros(40, int))
    >>> Q = part_affinity_matrix(W, parts)
    >>> bool(np.isclose(np.sum(C * (Q @ C)), part_affinity_loss(W @ C, parts)[0]))
    True
    """
    W = np.asarray(W, dtype=np.float64)
    Q = np.zeros((W.shape[1], W.shape[1]))
    count = len(parts.index)
    for i, B in enumerate(parts.bases):
        Wp = W[parts.index[parts.starts[i]:parts.starts[i + 1]]]
        R = Wp - B @ (B.T @ Wp)
        Q += R.T @ R
    return Q / max(count, 1)


# ------------------------------------------------------------------------------ detail


def detail_matrix(W: ArrayLike, L: scipy.sparse.spmatrix) -> Floats:
    """The change of a surface's Laplacian coordinates, ``L (W C - W C_ref)``, as a
    quadratic form of the cage ``C``.

    With ``L`` the source's cotangent Laplacian
    (:func:`cagekit.geometry.surface_laplacian`), this is the dCotLap metric
    (:func:`cagekit.metrics.dcotlap`) of the points ``W @ C`` against ``W @ C_ref``: the
    change of each vertex's mean-curvature normal, the fine detail a cage should carry
    and not redraw.

    Parameters
    ----------
    W : (n, k) float64
        Coordinates of the surface's vertices.
    L : (n, n) sparse
        The surface's Laplacian.

    Returns
    -------
    (k, k) float64
        ``Q = (L W)^T (L W) / (3 n)``: :func:`detail_loss` is ``sum(D * (Q @ D))`` with
        ``D = C - C_ref``; each evaluation costs ``k^2``, not ``n k``.

    Examples
    --------
    >>> import scipy.sparse
    >>> W = np.eye(3)
    >>> L = scipy.sparse.csr_matrix([[-2.0, 1, 1], [1, -1, 0], [1, 0, -1]])
    >>> Q = detail_matrix(W, L)
    >>> D = np.ones((3, 3))  # a translation
    >>> float(np.sum(D * (Q @ D)))
    0.0
    """
    LW = np.asarray(L @ np.asarray(W, dtype=np.float64))
    return LW.T @ LW / (3.0 * len(LW))


def detail_loss(C: Vertices, Q: Floats, C_ref: Vertices) -> tuple[float, Vertices]:
    """:func:`detail_matrix`'s quadratic form at a cage ``C``, with ``dL/dC``.

    Parameters
    ----------
    C, C_ref : (k, 3) float64
        The cage and the reference cage.
    Q : (k, k) float64
        From :func:`detail_matrix`.

    Returns
    -------
    value : float
        ``mean over n x 3 entries of (L W (C - C_ref))^2``.
    grad : (k, 3) float64
        ``2 Q (C - C_ref)``.

    Examples
    --------
    >>> Q = np.eye(2)
    >>> detail_loss(np.array([[1.0, 0, 0], [0, 0, 0]]), Q, np.zeros((2, 3)))[0]
    1.0
    """
    D = C - C_ref
    QD = Q @ D
    return _finite(float(np.einsum("ij,ij->", D, QD)), "detail loss"), 2.0 * QD
