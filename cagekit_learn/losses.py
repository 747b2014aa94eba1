"""The per-pair energy's terms (section 3.3 of "Neural Cages") in torch, batched.

Every function takes a batch of ``B`` pairs (tensors with a leading batch dimension) and
returns a ``(B,)`` tensor of per-pair values, for the caller to weight and average;
gradients come from autograd, in float32 or float64, on any device. Each term is the same
function as its NumPy form in :mod:`cagekit.deformation.terms`, value and gradient
(``tests/learn/test_learn_losses.py`` compares them), and states its formula. Chamfer uses squared
distances, both directions summed, not halved; nearest neighbours are found without gradient
(exact :func:`torch.cdist` in chunks) and held fixed. The PCA normal's backward is the
first-order eigenvector perturbation, not :func:`torch.linalg.eigh`'s (NaN or inf wherever
two eigenvalues coincide, as on a planar patch); eigenvalue pairs closer than ``1e-12``
(float32: ``8 eps``, above its rounding noise) times the covariance's trace contribute no
gradient, so gradients stay finite. A normal's sign never matters. Training combines the
terms with the paper's weights: ``L = L_align + ALPHA_MVC * L_MVC + ALPHA_SHAPE * L_shape``
(and ours, :func:`part_affinity_loss`, ``cagekit deform``'s part-affinity term, on the parts
of :func:`part_reference`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import torch
from numpy.typing import ArrayLike
from torch.autograd.function import once_differentiable

from cagekit.deformation.terms import (  # the paper's weights and the plane test, defined once
    ALPHA_MVC,
    ALPHA_SHAPE,
    PLANE_GAP,
    axis_index,
    part_bases,
)
from cagekit.errors import InputError
from cagekit_learn.coords import kernels_enabled

__all__ = [
    "ALPHA_MVC",
    "ALPHA_SHAPE",
    "MIN_PART_POINTS",
    "PartReference",
    "ShapeReference",
    "cage_symmetry_loss",
    "chamfer_loss",
    "knn_neighborhoods",
    "landmark_loss",
    "mirror",
    "mvc_loss",
    "normal_loss",
    "p2f_loss",
    "part_affinity_loss",
    "part_reference",
    "part_rows",
    "shape_losses",
    "shape_reference",
    "symmetry_loss",
]


MAX_ELEMENTS = 1 << 24
"""Default bound on the entries of one chunk of a distance matrix (64 MiB in float32)."""

_EXACT = "donot_use_mm_for_euclid_dist"  # cdist without the |a|^2 - 2ab + |b|^2 shortcut


def _check_points(P, what: str, batch: int | None = None) -> None:
    if not isinstance(P, torch.Tensor):
        raise InputError(f"{what} must be a torch tensor, got {type(P).__name__}")
    if P.ndim != 3 or P.shape[-1] != 3:
        raise InputError(f"{what} must have shape (B, n, 3), got {tuple(P.shape)}")
    if P.shape[1] == 0:
        raise InputError(f"{what} has no points")
    if batch is not None and P.shape[0] != batch:
        raise InputError(f"{what} has batch size {P.shape[0]}, expected {batch}")


def _gather(X: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """``X[b, index[b, ...]]`` for every batch element: (B, n, c), (B, ...) -> (B, ..., c)."""
    B, c = X.shape[0], X.shape[-1]
    flat = index.reshape(B, -1, 1).expand(-1, -1, c)
    return X.gather(1, flat).reshape(*index.shape, c)


def _rows(B: int, cols: int, max_elements: int) -> int:
    """Rows per chunk so that a (B, rows, cols) block has at most ``max_elements`` entries."""
    return max(1, int(max_elements) // max(1, B * cols))


# ---------------------------------------------------------------------------- alignment


@torch.no_grad()
def _nearest(P: torch.Tensor, Q: torch.Tensor, max_elements: int):
    """Nearest ``Q`` point of each ``P`` point (B, s) and nearest ``P`` point of each ``Q``
    point (B, t), from one pass over chunks of ``P``'s rows."""
    P, Q = P.detach(), Q.detach()
    if kernels_enabled(P.device):
        return _nearest_kdtree(P, Q)
    B, s, t = P.shape[0], P.shape[1], Q.shape[1]
    to_q = torch.empty((B, s), dtype=torch.long, device=P.device)
    to_p = torch.zeros((B, t), dtype=torch.long, device=P.device)
    best = torch.full((B, t), float("inf"), dtype=P.dtype, device=P.device)
    rows = _rows(B, t, max_elements)
    for start in range(0, s, rows):
        d = torch.cdist(P[:, start : start + rows], Q, compute_mode=_EXACT)  # (B, c, t)
        to_q[:, start : start + rows] = d.argmin(dim=2)
        col_min, col_arg = d.min(dim=1)
        better = col_min < best  # strict: the first of tied rows wins, as in one argmin
        best = torch.where(better, col_min, best)
        to_p = torch.where(better, col_arg + start, to_p)
    return to_q, to_p


def _nearest_kdtree(P: torch.Tensor, Q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`_nearest` of CPU tensors by scipy's k-d trees (as the core's Chamfer term): the
    same neighbours but where two are equally near."""
    from scipy.spatial import cKDTree

    p, q = P.numpy(), Q.numpy()
    to_q = np.stack([cKDTree(q[b]).query(p[b])[1] for b in range(len(p))])
    to_p = np.stack([cKDTree(p[b]).query(q[b])[1] for b in range(len(p))])
    return torch.from_numpy(to_q.astype(np.int64)), torch.from_numpy(to_p.astype(np.int64))


def _knn_kdtree(X: torch.Tensor, k: int) -> torch.Tensor:
    """:func:`knn_neighborhoods` of CPU tensors by the core's k-d tree search
    (:func:`cagekit.geometry.vertex_neighborhoods`), each point moved to the front of its
    own neighbourhood (coincident points may come before it)."""
    from cagekit.geometry import vertex_neighborhoods

    x = X.numpy()
    out = np.stack([vertex_neighborhoods(x[b], None, k=k).index for b in range(len(x))])
    own = np.arange(x.shape[1])
    for b, i in zip(*np.nonzero(out[:, :, 0] != own)):
        row = out[b, i]
        out[b, i] = np.concatenate(([i], row[row != i]))
    return torch.from_numpy(out)


def chamfer_loss(P: torch.Tensor, Q: torch.Tensor, *,
                 max_elements: int = MAX_ELEMENTS) -> torch.Tensor:
    """Chamfer distance between the point sets of each pair.

    Parameters
    ----------
    P : (B, s, 3) float tensor
        Moving points (deformed source samples).
    Q : (B, t, 3) float tensor
        Target points (may require grad too: the gradient reaches both sets).
    max_elements : int, optional
        Most entries of a ``(B, rows, t)`` distance block held at once; the nearest
        neighbours are found over chunks of ``P``'s rows.

    Returns
    -------
    (B,) tensor, dtype of ``P``
        ``mean_i min_j |P_i - Q_j|^2 + mean_j min_i |P_i - Q_j|^2``; differentiable with
        the nearest neighbours held fixed (as :func:`cagekit.deformation.terms.chamfer_loss`).
        CPU tensors find them with scipy's k-d trees, as the core does (4x faster than
        ``cdist`` at 1,024 points); CUDA tensors, and any under
        :func:`~cagekit_learn.coords.compiled_kernels` ``(False)``, with ``cdist``.

    Examples
    --------
    >>> chamfer_loss(torch.zeros(1, 1, 3), torch.tensor([[[0.0, 0, 2]]])).tolist()
    [8.0]
    """
    _check_points(P, "the moving point set")
    _check_points(Q, "the target point set", P.shape[0])
    to_q, to_p = _nearest(P, Q, max_elements)
    e_pq = P - _gather(Q, to_q)  # (B, s, 3): each P point minus its nearest Q point
    e_qp = Q - _gather(P, to_p)  # (B, t, 3)
    return e_pq.square().sum(dim=(1, 2)) / P.shape[1] + e_qp.square().sum(dim=(1, 2)) / Q.shape[1]


def landmark_loss(P: torch.Tensor, T: torch.Tensor) -> torch.Tensor:
    """Mean squared distance between corresponding points.

    Parameters
    ----------
    P : (B, l, 3) float tensor
        Moving points (deformed source landmarks).
    T : (B, l, 3) or (l, 3) float tensor
        Their targets, row for row.

    Returns
    -------
    (B,) tensor
        ``mean_l |P_l - T_l|^2``.

    Examples
    --------
    >>> landmark_loss(torch.zeros(1, 2, 3), torch.tensor([[1.0, 0, 0], [0, 0, 0]])).tolist()
    [0.5]
    """
    _check_points(P, "the moving landmarks")
    return (P - T).square().sum(dim=(1, 2)) / P.shape[1]


def mirror(P: torch.Tensor, axis: str) -> torch.Tensor:
    """Reflect points across the plane through the origin normal to ``axis``.

    Parameters
    ----------
    P : (..., 3) float tensor
    axis : {"x", "y", "z"}

    Returns
    -------
    (..., 3) tensor
        A new tensor (differentiable); ``P`` is not modified.

    Examples
    --------
    >>> mirror(torch.tensor([[1.0, 2.0, 3.0]]), "x").tolist()
    [[-1.0, 2.0, 3.0]]
    """
    sign = torch.ones(3, dtype=P.dtype, device=P.device)
    sign[axis_index(axis)] = -1.0
    return P * sign


def symmetry_loss(P: torch.Tensor, axis: str, *,
                  max_elements: int = MAX_ELEMENTS) -> torch.Tensor:
    """Chamfer distance between each point set and its mirror image.

    Both sets move with ``P`` (the gradient has the direct part and the part through the
    mirror image). 0 exactly for a set symmetric about the plane through the origin
    normal to ``axis``.

    Parameters
    ----------
    P : (B, s, 3) float tensor
    axis : {"x", "y", "z"}
    max_elements : int, optional
        As in :func:`chamfer_loss`.

    Returns
    -------
    (B,) tensor

    Examples
    --------
    >>> symmetry_loss(torch.tensor([[[-1.0, 0, 0], [1.0, 0, 0]]]), "x").tolist()
    [0.0]
    """
    return chamfer_loss(P, mirror(P, axis), max_elements=max_elements)


def cage_symmetry_loss(C: torch.Tensor, partner: torch.Tensor | ArrayLike,
                       offset: torch.Tensor | ArrayLike, axis: str) -> torch.Tensor:
    """Change of each cage vertex's offset from its rest mirror partner.

    Parameters
    ----------
    C : (B, k, 3) float tensor
        Cage vertices.
    partner : (k,) integer tensor or array
        From :func:`cagekit.deformation.terms.mirror_partners` on the rest cage.
    offset : (B, k, 3) or (k, 3) float tensor or array
        Likewise (0 for a symmetric rest cage).
    axis : {"x", "y", "z"}

    Returns
    -------
    (B,) tensor
        ``mean_i |C_i - mirror(C_partner(i)) - offset_i|^2``: 0 for a symmetric motion.

    Examples
    --------
    >>> import numpy as np
    >>> from cagekit.deformation.terms import mirror_partners
    >>> C = np.array([[-1.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0]])
    >>> partner, offset = mirror_partners(C, "x")
    >>> C2 = torch.tensor(C * [1, 2, 1])[None]
    >>> cage_symmetry_loss(C2, partner, offset, "x").tolist()
    [0.0]
    """
    _check_points(C, "the cage")
    partner = torch.as_tensor(partner, dtype=torch.long, device=C.device)
    offset = torch.as_tensor(offset, dtype=C.dtype, device=C.device)
    e = C - mirror(C[:, partner], axis) - offset
    return e.square().sum(dim=(1, 2)) / C.shape[1]


def mvc_loss(W: torch.Tensor) -> torch.Tensor:
    """Mean squared negative mean value coordinate of each pair, the paper's ``L_MVC``.

    Parameters
    ----------
    W : (B, n, k) float tensor
        Binding weights of ``n`` points to ``k`` cage vertices.

    Returns
    -------
    (B,) tensor
        ``mean over the n x k entries of min(W, 0)^2``; 0 without negative weights.

    Examples
    --------
    >>> mvc_loss(torch.tensor([[[1.5, -0.5], [0.0, 0.25]]])).tolist()
    [0.0625]
    """
    if W.ndim < 2 or W[0].numel() == 0:
        raise InputError(f"MVC weights must have shape (B, n, k), got {tuple(W.shape)}")
    return W.clamp(max=0.0).square().flatten(1).mean(dim=1)


# ------------------------------------------------------------------------ shape terms


@torch.no_grad()
def knn_neighborhoods(X: torch.Tensor, k: int = 16, *,
                      max_elements: int = MAX_ELEMENTS) -> torch.Tensor:
    """The ``min(k, n)`` nearest points of every point, the point itself first.

    Parameters
    ----------
    X : (B, n, 3) float tensor
    k : int, optional
        Neighbourhood size, ``k >= 1``.
    max_elements : int, optional
        Most entries of a ``(B, rows, n)`` distance block held at once.

    Returns
    -------
    (B, n, min(k, n)) int64 tensor
        Indices into ``X``'s points, by increasing distance; column 0 is the point itself
        (also among coincident points). Use it as ``index`` of :func:`shape_reference`.
        Found as :func:`chamfer_loss` finds its neighbours (k-d trees on the CPU).

    Examples
    --------
    >>> X = torch.tensor([[[0.0, 0, 0], [1, 0, 0], [3, 0, 0]]])
    >>> knn_neighborhoods(X, k=2).tolist()
    [[[0, 1], [1, 0], [2, 1]]]
    """
    _check_points(X, "the points")
    if int(k) < 1:
        raise InputError(f"k must be at least 1, got {k}")
    X = X.detach()
    B, n = X.shape[:2]
    k = min(int(k), n)
    if kernels_enabled(X.device):
        return _knn_kdtree(X, k)
    out = torch.empty((B, n, k), dtype=torch.long, device=X.device)
    rows = _rows(B, n, max_elements)
    for start in range(0, n, rows):
        stop = min(start + rows, n)
        d = torch.cdist(X[:, start:stop], X, compute_mode=_EXACT)  # (B, c, n)
        own = torch.arange(start, stop, device=X.device)
        d[:, own - start, own] = -1.0  # the point itself first
        out[:, start:stop] = d.topk(k, dim=2, largest=False, sorted=True).indices
    return out


class ShapeReference(NamedTuple):
    """Neighbourhoods and rest planes of a batch for :func:`shape_losses` (all detached).

    Attributes
    ----------
    own : (B, r) int64 tensor
        The point each neighbourhood (row) belongs to.
    index : (B, r, m) int64 tensor
        Members of each neighbourhood (indices into the points), padded.
    mask : (B, r, m) bool tensor
        True for real members.
    normals : (B, r, 3) float tensor
        Rest PCA normals ``n^0`` (unit, arbitrary sign).
    distances : (B, r) float tensor
        Rest signed distances ``d^0`` of each own point to its plane.
    planar : (B, r) bool tensor or None
        Rows whose rest neighbourhood has a plane (``cagekit.deformation.terms.PLANE_GAP``); the
        losses average over these only. None: every row.
    """

    own: torch.Tensor
    index: torch.Tensor  # type: ignore[assignment]  # a field named as tuple.index, on purpose
    mask: torch.Tensor
    normals: torch.Tensor
    distances: torch.Tensor
    planar: torch.Tensor | None = None


def _planes(X: torch.Tensor, index: torch.Tensor, mask: torch.Tensor):
    """Covariance (B, r, 3, 3) and centroid (B, r, 3) of every neighbourhood."""
    w = mask.to(X.dtype)
    m = w.sum(dim=-1)
    P = _gather(X, index)  # (B, r, m, 3)
    centroid = torch.einsum("brj,brjk->brk", w, P) / m[..., None]
    D = (P - centroid[..., None, :]) * w[..., None]
    cov = torch.einsum("brji,brjk->brik", D, D) / m[..., None, None]
    return cov, centroid


def _gap_floor(dtype: torch.dtype) -> float:
    """Relative eigenvalue gap below which a pair gives no gradient: NumPy's ``1e-12`` in
    float64; in float32 (eigenvalues rounded at ~1e-7 of the trace) ``8 eps`` ~ 1e-6."""
    return max(1e-12, 8.0 * torch.finfo(dtype).eps)


class _SmallestEigenvector(torch.autograd.Function):
    """Unit eigenvector of the smallest eigenvalue of symmetric 3 x 3 matrices.

    Backward: first-order perturbation ``dn = sum_{k>0} v_k (v_k . dM n) / (l_0 - l_k)``,
    so ``dL/dM = sym(-sum_k a_k v_k n^T)`` with ``a_k = (g . v_k) / (l_k - l_0)``; a pair
    whose gap is at most :func:`_gap_floor` times the trace (and at most the dtype's
    smallest normal number) contributes nothing. In float64 this is exactly
    ``cagekit.deformation.terms._normal_backward``.
    """

    @staticmethod
    def forward(ctx, M):
        lam, vec = torch.linalg.eigh(M)
        ctx.save_for_backward(lam, vec)
        return vec[..., 0].clone()

    @staticmethod
    @once_differentiable
    def backward(ctx, g):
        lam, vec = ctx.saved_tensors
        n = vec[..., 0]
        info = torch.finfo(lam.dtype)
        floor = (_gap_floor(lam.dtype) * lam.sum(dim=-1).clamp_min(info.tiny)).clamp_min(info.tiny)
        G = torch.zeros(vec.shape, dtype=vec.dtype, device=vec.device)
        for k in (1, 2):
            v = vec[..., k]
            gap = lam[..., k] - lam[..., 0]
            ok = gap > floor
            a = torch.where(ok, (g * v).sum(dim=-1) / torch.where(ok, gap, 1.0), 0.0)
            outer = a[..., None, None] * v[..., :, None] * n[..., None, :]
            G = G - 0.5 * (outer + outer.transpose(-1, -2))
        return G


def _as_rows(value, shape, dtype, device, what) -> torch.Tensor:
    t = torch.as_tensor(value, dtype=dtype, device=device)
    if t.ndim == len(shape) - 1 and tuple(t.shape) == tuple(shape[1:]):
        t = t.expand(*shape)
    if tuple(t.shape) != tuple(shape):
        raise InputError(f"{what} must have shape {tuple(shape)} or {tuple(shape[1:])}, "
                         f"got {tuple(t.shape)}")
    return t


@torch.no_grad()
def shape_reference(X: torch.Tensor, index: torch.Tensor | ArrayLike,
                    mask: torch.Tensor | ArrayLike | None = None,
                    own: torch.Tensor | ArrayLike | None = None) -> ShapeReference:
    """Rest normals and point-to-plane distances of the given neighbourhoods.

    Parameters
    ----------
    X : (B, n, 3) float tensor
        Rest positions (detached here).
    index : (B, r, m) or (r, m) integer tensor or array
        Neighbourhood members, for example from :func:`knn_neighborhoods` or
        :func:`cagekit.geometry.vertex_neighborhoods`; ``(r, m)`` is shared by the batch.
    mask : (B, r, m) or (r, m) bool, optional
        True for real members (default: all); at least one per row.
    own : (B, r) or (r,) integer, optional
        The point each row belongs to (default: row ``i`` belongs to point ``i``).

    Returns
    -------
    ShapeReference
        On ``X``'s device, in ``X``'s dtype. The batch keeps every row; rows without a
        plane (points on a line) are marked in ``planar`` and left out of the losses,
        as :func:`cagekit.deformation.terms.shape_reference` drops them.

    Examples
    --------
    >>> X = torch.tensor([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]])
    >>> ref = shape_reference(X, [[0, 1, 2, 3]])
    >>> ref.normals[0, 0].abs().tolist(), ref.distances.tolist()
    ([0.0, 0.0, 1.0], [[0.0]])
    """
    _check_points(X, "the rest points")
    X = X.detach()
    B, n = X.shape[:2]
    index = torch.as_tensor(index, dtype=torch.long, device=X.device)
    if index.ndim not in (2, 3):
        raise InputError(f"index must have shape (B, r, m) or (r, m), got {tuple(index.shape)}")
    r, m = index.shape[-2:]
    index = _as_rows(index, (B, r, m), torch.long, X.device, "index")
    mask = (torch.ones((B, r, m), dtype=torch.bool, device=X.device) if mask is None
            else _as_rows(mask, (B, r, m), torch.bool, X.device, "mask"))
    own = (torch.arange(r, device=X.device).expand(B, r) if own is None
           else _as_rows(own, (B, r), torch.long, X.device, "own"))
    if index.numel() and (index.min() < 0 or index.max() >= n):
        raise InputError(f"neighbourhood indices must lie in [0, {n})")
    if own.numel() and (own.min() < 0 or own.max() >= n):
        raise InputError(f"own indices must lie in [0, {n})")
    if not mask.any(dim=-1).all():
        raise InputError("every neighbourhood needs at least one real member")
    cov, centroid = _planes(X, index, mask)
    lam, vec = torch.linalg.eigh(cov)
    normals = vec[..., 0]
    distances = ((_gather(X, own) - centroid) * normals).sum(dim=-1)
    planar = lam[..., 1] - lam[..., 0] > PLANE_GAP * lam[..., 2]
    return ShapeReference(own.contiguous(), index.contiguous(), mask.contiguous(), normals,
                          distances, planar)


def shape_losses(X: torch.Tensor, ref: ShapeReference) -> dict[str, torch.Tensor]:
    """:func:`p2f_loss` and :func:`normal_loss` together, from one eigen-decomposition.

    Parameters
    ----------
    X : (B, n, 3) float tensor
        Deformed positions (same indexing as the reference).
    ref : ShapeReference
        From :func:`shape_reference` on the rest positions.

    Returns
    -------
    dict
        ``{"p2f": (B,) tensor, "normal": (B,) tensor}``.

    Examples
    --------
    >>> X = torch.tensor([[[0.0, 0, 1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]]])
    >>> ref = shape_reference(X, [[0, 1, 2, 3, 4]])
    >>> {k: [round(x, 6) for x in v.tolist()] for k, v in shape_losses(X, ref).items()}
    {'p2f': [0.0], 'normal': [0.0]}
    """
    _check_points(X, "the deformed points", ref.index.shape[0])
    cov, centroid = _planes(X, ref.index, ref.mask)
    n_raw = _SmallestEigenvector.apply(cov)
    n0 = ref.normals.to(X.dtype)
    cos = (n_raw * n0).sum(dim=-1)
    flip = 1.0 - 2.0 * (cos.detach() < 0).to(X.dtype)  # orients n along n0; a constant
    # |cos| may exceed 1 by rounding: clamp so the value is never negative
    normal = (1.0 - cos * flip).clamp_min(0.0)
    offset = _gather(X, ref.own) - centroid
    residual = (offset * n_raw).sum(dim=-1) * flip - ref.distances.to(X.dtype)
    return {"p2f": _planar_mean(residual.square(), ref), "normal": _planar_mean(normal, ref)}


def _planar_mean(values: torch.Tensor, ref: ShapeReference) -> torch.Tensor:
    """Mean over each batch item's planar rows, (B, r) -> (B,); 0 where it has none."""
    if ref.planar is None:
        return values.mean(dim=-1)
    w = ref.planar.to(values.dtype)
    # where() so a degenerate row's non-finite value cannot reach the sum or the gradient
    kept = torch.where(ref.planar, values, torch.zeros_like(values))
    return (kept * w).sum(dim=-1) / w.sum(dim=-1).clamp_min(1.0)


def normal_loss(X: torch.Tensor, ref: ShapeReference) -> torch.Tensor:
    """Change of PCA normals, ``mean_i max(1 - |n_i(X) . n_i^0|, 0)``.

    Parameters
    ----------
    X : (B, n, 3) float tensor
        Deformed positions.
    ref : ShapeReference
        From :func:`shape_reference` on the rest positions.

    Returns
    -------
    (B,) tensor
        In ``[0, 1]``; 0 when every normal is unchanged up to sign.

    Examples
    --------
    >>> X = torch.tensor([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]])
    >>> ref = shape_reference(X, [[0, 1, 2, 3]])
    >>> normal_loss(2.0 * X, ref).tolist()
    [0.0]
    """
    return shape_losses(X, ref)["normal"]


def p2f_loss(X: torch.Tensor, ref: ShapeReference) -> torch.Tensor:
    """Change of point-to-plane distances, ``mean_i (d_i(X) - d_i^0)^2``.

    ``d_i = n_i . (x_i - c_i)``: the signed distance of point ``own_i`` to the PCA plane of
    its neighbourhood (centroid ``c_i``, normal ``n_i`` flipped to agree with ``n_i^0``).

    Parameters
    ----------
    X : (B, n, 3) float tensor
        Deformed positions.
    ref : ShapeReference
        From :func:`shape_reference` on the rest positions.

    Returns
    -------
    (B,) tensor

    Examples
    --------
    >>> X = torch.tensor([[[0.0, 0, 1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]]],
    ...                  dtype=torch.float64)
    >>> ref = shape_reference(X, [[0, 1, 2, 3, 4]])
    >>> [round(v, 12) for v in p2f_loss(X * torch.tensor([1, 1, 1.5]), ref).tolist()]
    [0.16]
    """
    return shape_losses(X, ref)["p2f"]


# ----------------------------------------------------------------------- part affinity


MIN_PART_POINTS = 8
"""Fewest samples of a part in :func:`part_reference`: four points fit any affine map
exactly, so a part needs more to be held to one; twice that keeps a few-sample sliver of a
part from counting as one."""


class PartReference(NamedTuple):
    """Each point's part and its row of the part's affine basis, for
    :func:`part_affinity_loss` (detached).

    Attributes
    ----------
    ids : (B, n) int64 tensor
        The part of each point, ``0 .. parts - 1`` within its batch item; -1 for a point in
        no part (every point of an item with fewer than two parts).
    rows : (B, n, 4) float tensor
        The point's row of its part's basis ``B_p`` (orthonormal columns spanning the
        affine functions of the part's rest points, ``r_p <= 4`` of them, padded with
        zeros); 0 for a point in no part.
    """

    ids: torch.Tensor
    rows: torch.Tensor


def part_rows(X_rest: ArrayLike, labels: ArrayLike,
              min_points: int = MIN_PART_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """One shape's :class:`PartReference`, in NumPy, from its rest points.

    Parameters
    ----------
    X_rest : (n, 3) array_like of float
        The points at rest.
    labels : (n,) array_like of int
        A part label per point; negative: no part.
    min_points : int, default :data:`MIN_PART_POINTS`
        Parts of fewer points are left out.

    Returns
    -------
    ids : (n,) int64 ndarray
        ``0 .. parts - 1`` in the order of :func:`cagekit.deformation.terms.part_bases`;
        -1 everywhere when fewer than two parts are left (the term then costs nothing, as
        ``cagekit deform``'s, which needs a source of two parts or more).
    rows : (n, 4) float64 ndarray
        Each part point's row of its part's basis (``part_bases``), padded with zeros.

    Examples
    --------
    >>> X = np.random.default_rng(0).normal(size=(20, 3))
    >>> ids, rows = part_rows(X, np.repeat([0, 1], 10))
    >>> ids.tolist() == [0] * 10 + [1] * 10, rows.shape
    (True, (20, 4))
    >>> int(part_rows(X, np.zeros(20, int))[0].max())  # one part: no term
    -1
    """
    X_rest = np.asarray(X_rest, dtype=np.float64)
    ids = np.full(len(X_rest), -1, dtype=np.int64)
    rows = np.zeros((len(X_rest), 4))
    parts = part_bases(X_rest, labels, int(min_points))
    if len(parts.bases) < 2:
        return ids, rows
    for i, B in enumerate(parts.bases):
        members = parts.index[parts.starts[i]:parts.starts[i + 1]]
        ids[members] = i
        rows[members, :B.shape[1]] = B
    return ids, rows


@torch.no_grad()
def part_reference(X_rest: torch.Tensor, labels: torch.Tensor | ArrayLike,
                   min_points: int = MIN_PART_POINTS) -> PartReference:
    """The parts of a batch of rest shapes, for :func:`part_affinity_loss`.

    Parameters
    ----------
    X_rest : (B, n, 3) float tensor
        The rest points (detached here; the bases are computed in float64 on the CPU).
    labels : (B, n) integer tensor or array
        A part label per point (:attr:`cagekit_learn.data.ShapeCollection.parts`);
        negative: no part.
    min_points : int, default :data:`MIN_PART_POINTS`
        Parts of fewer points are left out.

    Returns
    -------
    PartReference
        On ``X_rest``'s device, ``rows`` in its dtype (:func:`part_rows` per item).

    Examples
    --------
    >>> X = torch.randn(2, 20, 3, generator=torch.Generator().manual_seed(0))
    >>> ref = part_reference(X, np.repeat([[0, 1]], 10, axis=1).repeat(2, axis=0))
    >>> ref.ids.shape, ref.rows.shape
    (torch.Size([2, 20]), torch.Size([2, 20, 4]))
    """
    _check_points(X_rest, "the rest points")
    labels = np.asarray(labels.cpu() if isinstance(labels, torch.Tensor) else labels)
    if labels.shape != tuple(X_rest.shape[:2]):
        raise InputError(f"part labels must have shape {tuple(X_rest.shape[:2])}, got "
                         f"{labels.shape}")
    rest = X_rest.detach().cpu().double().numpy()
    ids, rows = zip(*(part_rows(x, label, min_points) for x, label in zip(rest, labels)))
    return PartReference(torch.as_tensor(np.stack(ids), device=X_rest.device),
                         torch.as_tensor(np.stack(rows), dtype=X_rest.dtype,
                                         device=X_rest.device))


def part_affinity_loss(X: torch.Tensor, ref: PartReference) -> torch.Tensor:
    """How far each part is from an affine map of its rest points.

    The torch form of :func:`cagekit.deformation.terms.part_affinity_loss`, the term of
    ``cagekit deform`` that keeps legs straight and seats flat while the parts move.

    Parameters
    ----------
    X : (B, n, 3) float tensor
        The deformed points.
    ref : PartReference
        From :func:`part_reference` on the rest points.

    Returns
    -------
    (B,) tensor
        ``sum over parts of |X_p - B_p B_p^T X_p|^2`` over the number of part points: the
        mean squared residual of each part's least-squares affine fit. 0 for any affine
        map of each part, and for an item without parts. ``B_p^T X_p`` is summed over each
        part's points with :meth:`torch.Tensor.index_add`; the residual is formed point by
        point (not as ``|X_p|^2 - |B_p^T X_p|^2``, which cancels in float32).

    Examples
    --------
    >>> X = torch.randn(1, 20, 3, dtype=torch.float64,
    ...                 generator=torch.Generator().manual_seed(0))
    >>> ref = part_reference(X, np.repeat([[0, 1]], 10, axis=1))
    >>> moved = torch.cat([X[:, :10] * 2.0 + 1.0, X[:, 10:] @ torch.randn(3, 3).double()], 1)
    >>> round(part_affinity_loss(moved, ref).item(), 12) + 0.0
    0.0
    >>> bent = moved.clone()
    >>> bent[0, 0] += 1.0
    >>> part_affinity_loss(bent, ref).item() > 0.01
    True
    """
    _check_points(X, "the deformed points", ref.ids.shape[0])
    B, n = ref.ids.shape
    if X.shape[1] != n:
        raise InputError(f"the deformed points number {X.shape[1]}, the parts' {n}")
    rows = ref.rows.to(X.dtype)
    member = ref.ids >= 0
    slots = int(ref.ids.max()) + 1 if member.any() else 0
    slot = torch.where(member, ref.ids + slots * torch.arange(B, device=X.device)[:, None],
                       B * slots)  # one spare slot for the points of no part (rows 0)
    outer = rows[..., :, None] * X[..., None, :]  # (B, n, 4, 3): row^T x of each point
    BtX = X.new_zeros((B * slots + 1, 4, 3)).index_add(0, slot.flatten(), outer.flatten(0, 1))
    fit = torch.einsum("bnk,bnkc->bnc", rows, BtX[slot])  # B_p B_p^T X_p, point by point
    residual = (X - fit) * member[..., None].to(X.dtype)
    return residual.square().sum(dim=(1, 2)) / member.sum(dim=1).clamp_min(1).to(X.dtype)
