"""How far points lie inside a predicted cage, as a training loss (issue 32).

A predicted source cage is only usable when it encloses the source (mean value coordinates
extrapolate outside, and :func:`cagekit_learn.cage_repair.check_predicted_cage` refuses a
cage that still leaves points out after growing it by 1.3x). The paper's ``L_MVC``
(negative weights, :func:`cagekit_learn.losses.mvc_loss`) is too weak to keep a learned cage
around real furniture: trained with it alone, N_c flattened its template into a disc at
seat height and left 30-93% of every unseen source outside.

:func:`enclosure_loss` asks every point to lie at least ``margin`` inside the cage:
``mean_i max(0, margin - s_i)^2`` with ``s_i`` the signed distance of point ``i`` to the
cage's surface, positive inside. The side comes from the generalised winding number
(inside where it is at least 1/2, :func:`winding_numbers`), which is constant in the cage's
vertices away from the surface and carries no gradient; the gradient comes from the
distance to the nearest triangle (:func:`triangle_distances`), chosen without gradient and
held fixed, as :func:`cagekit_learn.losses.chamfer_loss` holds its nearest neighbours. On
the CPU the side comes from the core's compiled winding number
(:func:`cagekit.coords.winding.batched_winding_numbers`, float64, 24x faster than libigl's
``winding_number`` a cage at a time) and the nearest face from libigl
(``point_mesh_squared_distance``, float64), together 5x faster than the torch graph of
all point-face pairs that CUDA tensors and :func:`~cagekit_learn.coords.compiled_kernels`
``(False)`` use; the loss and its gradient are the same but where two faces are equally
near. It has no NumPy twin in :mod:`cagekit.deformation.terms` (per-pair optimisation starts from
a fitted cage that encloses the source by construction); its parts are checked against
libigl's winding number and point-mesh distance (``tests/learn/test_enclosure.py``).
"""

from __future__ import annotations

import math

import numpy as np
import torch
from numpy.typing import ArrayLike

from cagekit.coords.winding import batched_winding_numbers
from cagekit.errors import InputError
from cagekit_learn.coords import kernels_enabled

__all__ = ["ENCLOSURE_MARGIN", "winding_numbers", "triangle_distances", "enclosure_loss"]

ENCLOSURE_MARGIN = 0.05
"""How far inside the cage every source point is asked to be, in the normalised frame
(the source's largest half-extent is 1): 2.5% of its largest extent."""

_TINY = 1e-30  # below any squared area or length of a real triangle; guards divisions


def _triangles(V: torch.Tensor, F: torch.Tensor | ArrayLike) -> torch.Tensor:
    """(B, m, 3, 3) corners of the faces ``F`` (m, 3) of the batched cages ``V`` (B, k, 3)."""
    if V.ndim != 3 or V.shape[-1] != 3:
        raise InputError(f"cages must have shape (B, k, 3), got {tuple(V.shape)}")
    F = torch.as_tensor(F, dtype=torch.long, device=V.device)
    if F.ndim != 2 or F.shape[1] != 3 or F.numel() == 0:
        raise InputError(f"cage faces must have shape (m, 3), m >= 1, got {tuple(F.shape)}")
    return V[:, F]


def _check_points(P: torch.Tensor, batch: int) -> None:
    if P.ndim != 3 or P.shape[-1] != 3 or P.shape[0] != batch:
        raise InputError(f"points must have shape ({batch}, n, 3), got {tuple(P.shape)}")


def winding_numbers(P: torch.Tensor, V: torch.Tensor,
                    F: torch.Tensor | ArrayLike) -> torch.Tensor:
    """Generalised winding number of each point with respect to its cage.

    The sum of the solid angles its triangles subtend (Van Oosterom and Strackee's
    formula) over ``4 pi``: 1 inside a closed outward-oriented cage, 0 outside, 1/2 on it.

    Parameters
    ----------
    P : (B, n, 3) float tensor
        Points.
    V : (B, k, 3) float tensor
        Cage vertices.
    F : (m, 3) int array or tensor
        Cage faces, shared by the batch.

    Returns
    -------
    (B, n) tensor

    Examples
    --------
    >>> from cagekit.cage import box_cage
    >>> v, f = box_cage()
    >>> P = torch.tensor([[[0.0, 0, 0], [3, 0, 0]]], dtype=torch.float64)
    >>> w = winding_numbers(P, torch.as_tensor(v)[None], f)
    >>> [round(x, 9) for x in w[0].tolist()]
    [1.0, 0.0]
    """
    T = _triangles(V, F)
    _check_points(P, T.shape[0])
    a, b, c = (T[:, None, :, i] - P[:, :, None] for i in range(3))  # (B, n, m, 3) each
    la, lb, lc = a.norm(dim=-1), b.norm(dim=-1), c.norm(dim=-1)
    det = (a * torch.linalg.cross(b, c, dim=-1)).sum(-1)
    den = (la * lb * lc + (a * b).sum(-1) * lc + (b * c).sum(-1) * la
           + (c * a).sum(-1) * lb)
    return torch.atan2(det, den).sum(-1) / (2 * math.pi)


def _squared_distance(p: torch.Tensor, a: torch.Tensor, b: torch.Tensor,
                      c: torch.Tensor) -> torch.Tensor:
    """Squared distance of points ``p`` to triangles ``(a, b, c)``, all broadcast (..., 3)."""
    n = torch.linalg.cross(b - a, c - a, dim=-1)
    nn = n.square().sum(-1)

    def side(s, e):  # > 0 where p is on the inner side of the edge s -> e
        return (torch.linalg.cross(e - s, p - s, dim=-1) * n).sum(-1)

    inside = (side(a, b) >= 0) & (side(b, c) >= 0) & (side(c, a) >= 0) & (nn > _TINY)
    plane = ((p - a) * n).sum(-1).square() / nn.clamp(min=_TINY)

    def segment(s, e):
        d = e - s
        t = (((p - s) * d).sum(-1) / d.square().sum(-1).clamp(min=_TINY)).clamp(0.0, 1.0)
        return (p - s - t[..., None] * d).square().sum(-1)

    edges = torch.minimum(torch.minimum(segment(a, b), segment(b, c)), segment(c, a))
    return torch.where(inside, plane, edges)


def triangle_distances(P: torch.Tensor, V: torch.Tensor,
                       F: torch.Tensor | ArrayLike) -> torch.Tensor:
    """Squared distance of each point to each face of its cage.

    Parameters
    ----------
    P : (B, n, 3) float tensor
    V : (B, k, 3) float tensor
    F : (m, 3) int array or tensor

    Returns
    -------
    (B, n, m) tensor
        Exact squared point-triangle distances (a degenerate face: to its edges).

    Examples
    --------
    >>> V = torch.tensor([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]])
    >>> P = torch.tensor([[[0.2, 0.2, 2.0], [-3.0, 0, 0]]])
    >>> triangle_distances(P, V, [[0, 1, 2]])[0, :, 0].tolist()
    [4.0, 9.0]
    """
    T = _triangles(V, F)
    _check_points(P, T.shape[0])
    p = P[:, :, None]
    return _squared_distance(p, T[:, None, :, 0], T[:, None, :, 1], T[:, None, :, 2])


def _side_and_nearest_igl(P: torch.Tensor, V: torch.Tensor,
                          F: torch.Tensor | ArrayLike) -> tuple[torch.Tensor, torch.Tensor]:
    """Inside flags (winding number >= 1/2, :func:`cagekit.coords.winding.batched_winding_numbers`)
    and libigl's nearest faces, (B, n) each."""
    import igl

    faces = np.ascontiguousarray(torch.as_tensor(F).cpu().numpy(), dtype=np.int64)
    points = P.detach().double().numpy()
    cages = V.detach().double().numpy()
    inside = batched_winding_numbers(points, cages, faces) >= 0.5
    nearest = np.empty(points.shape[:2], dtype=np.int64)
    for b in range(len(points)):
        p, v = np.ascontiguousarray(points[b]), np.ascontiguousarray(cages[b])
        nearest[b] = igl.point_mesh_squared_distance(p, v, faces)[1]
    return torch.from_numpy(inside), torch.from_numpy(nearest)


def enclosure_loss(P: torch.Tensor, V: torch.Tensor, F: torch.Tensor | ArrayLike,
                   margin: float = ENCLOSURE_MARGIN) -> torch.Tensor:
    """How far each batch item's points fall short of lying ``margin`` inside its cage.

    ``mean_i max(0, margin - s_i)^2``, ``s_i`` the signed distance of point ``i`` to the
    cage surface (positive where its winding number is at least 1/2). The nearest face and
    the side are found without gradient; the gradient is the distance's to that face.

    Parameters
    ----------
    P : (B, n, 3) float tensor
        Source points (normalised frame).
    V : (B, k, 3) float tensor
        Their predicted cages.
    F : (m, 3) int array or tensor
        The cages' faces (outward-oriented).
    margin : float, default ENCLOSURE_MARGIN
        How deep inside each point is asked to be (>= 0).

    Returns
    -------
    (B,) tensor
        0 when every point lies ``margin`` or more inside.

    Examples
    --------
    >>> from cagekit.cage import box_cage
    >>> v, f = box_cage()
    >>> V = torch.as_tensor(v)[None]
    >>> inside = torch.tensor([[[0.0, 0, 0], [0.5, 0.5, 0.5]]], dtype=torch.float64)
    >>> enclosure_loss(inside, V, f).tolist()
    [0.0]
    >>> outside = torch.tensor([[[1.2, 0, 0]]], dtype=torch.float64)
    >>> [round(x, 9) for x in enclosure_loss(outside, V, f, margin=0.1).tolist()]
    [0.09]
    """
    if not (math.isfinite(margin) and margin >= 0):
        raise InputError(f"margin must be finite and >= 0, got {margin}")
    T = _triangles(V, F)
    _check_points(P, T.shape[0])
    with torch.no_grad():
        if kernels_enabled(V.device):
            inside, nearest = _side_and_nearest_igl(P, V, F)
        else:
            inside = winding_numbers(P, V, F) >= 0.5
            nearest = triangle_distances(P, V, F).argmin(dim=-1)  # (B, n)
    B = torch.arange(T.shape[0], device=V.device)[:, None]
    t = T[B, nearest]  # (B, n, 3, 3)
    d = (_squared_distance(P, t[..., 0, :], t[..., 1, :], t[..., 2, :]) + _TINY).sqrt()
    signed = torch.where(inside, d, -d)
    return (margin - signed).clamp(min=0.0).square().mean(dim=1)
