"""Differentiable Green coordinates in torch: the twin of :mod:`cagekit.coords.green`.

The core's formulation (its docstring has it) from plain tensor operations, so that the
coordinates can be differentiated with respect to the points and the cage vertices, and
a Green deformation with respect to the deformed cage (its normals and stretch factors).
The three angles of each face's spherical excess are summed one by one here (the core
folds them into one ``atan2`` for speed); the planes through the point and each edge are
shared by the edge's two faces as in the core, so the two agree to rounding near edges
too. Points within :data:`cagekit.coords.green.SNAP` cage diagonals of the cage are
evaluated where the core evaluates them (``INSET`` inside), with the gradient of the
point itself (the shift is a constant); points outside take the core's extension across
their exit face (chosen by the core, a constant), differentiable through that face.
Points run ``chunk_size`` at a time: memory ``O(chunk x faces)``.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from numpy.typing import ArrayLike

from cagekit.cage import cage_topology
from cagekit.coords import green as core
from cagekit.errors import InputError

__all__ = ["GreenBinding", "green_coordinates", "green_deform", "stretch_factors"]


def _safe_norm(v: torch.Tensor) -> torch.Tensor:
    """``|v|`` along the last axis, with a finite gradient at 0 (where it is 0)."""
    sq = (v * v).sum(dim=-1)
    tiny = torch.finfo(v.dtype).tiny
    return torch.where(sq > tiny, sq.clamp_min(tiny).sqrt(), torch.zeros_like(sq))


def _angle(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """The angle between unit vectors along the last axis, accurate at every angle."""
    return torch.atan2(_safe_norm(torch.linalg.cross(a, b, dim=-1)), (a * b).sum(dim=-1))


def _face_terms(V: torch.Tensor, faces: torch.Tensor):
    """Unit normals (m, 3), twice the areas (m,), the edges' outward in-plane normals
    (m, 3, 3) and the hat functions' gradients (m, 3, 3) of a cage (differentiable)."""
    corners = V[faces]  # (m, 3, 3)
    cross = torch.linalg.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0],
                               dim=-1)
    twice = cross.norm(dim=-1)
    n = cross / twice[:, None]
    ahead = torch.roll(corners, -1, dims=1)
    tangent = ahead - corners
    tangent = tangent / tangent.norm(dim=-1, keepdim=True)
    edge_m = torch.linalg.cross(tangent, n[:, None, :].expand_as(tangent), dim=-1)
    opposite = torch.roll(corners, -2, dims=1) - torch.roll(corners, -1, dims=1)
    grads = torch.linalg.cross(n[:, None, :].expand_as(opposite), opposite,
                               dim=-1) / twice[:, None, None]
    return n, twice, edge_m, grads


def _raw_chunk(X, V, faces, edges, face_edges, face_signs, terms):
    """Raw Green coordinates of the points ``X`` (c, 3): phi (c, k), psi (c, m)."""
    n, twice, edge_m, grads = terms
    k = V.shape[0]
    d = V[None, :, :] - X[:, None, :]  # (c, k, 3)
    R = _safe_norm(d)
    dp, dq = d[:, edges[:, 0]], d[:, edges[:, 1]]  # (c, e, 3)
    cross = torch.linalg.cross(dp, dq, dim=-1)
    cross_sq = (cross * cross).sum(dim=-1)
    cross_norm = _safe_norm(cross)
    unit = cross / torch.where(cross_norm > 0, cross_norm, torch.ones_like(cross_norm))[..., None]
    dot = (dp * dq).sum(dim=-1)
    rr = R[:, edges[:, 0]] * R[:, edges[:, 1]]
    apart = dot < 0
    # R_p R_q + d_p . d_q without cancellation where the vectors point apart ("double
    # where": the branch not taken gets a harmless denominator)
    half = torch.where(apart, cross_sq / torch.where(apart, rr - dot, torch.ones_like(rr)),
                       rr + dot)
    length = (V[edges[:, 1]] - V[edges[:, 0]]).norm(dim=-1)
    total = R[:, edges[:, 0]] + R[:, edges[:, 1]] + length
    I = torch.log(total * total / (2.0 * half))  # (c, e)
    N = unit[:, face_edges] * face_signs[None, :, :, None]  # (c, m, 3 edges, 3)
    excess = (2.0 * math.pi - _angle(N[:, :, 2], N[:, :, 0]) - _angle(N[:, :, 0], N[:, :, 1])
              - _angle(N[:, :, 1], N[:, :, 2]))
    d0 = d[:, faces[:, 0]]  # (c, m, 3)
    h = (d0 * n[None]).sum(dim=-1)
    omega = torch.where(h < 0, -excess, excess)
    # the foot's barycentrics from the edges' unnormalised normals: (d1 x d2) . n etc.
    C = cross[:, face_edges] * face_signs[None, :, :, None]  # (c, m, 3, 3)
    gam = torch.stack([(C[:, :, 1] * n).sum(-1), (C[:, :, 2] * n).sum(-1),
                       (C[:, :, 0] * n).sum(-1)], dim=-1) / twice[None, :, None]
    Ie = I[:, face_edges]  # (c, m, 3)
    vec = (edge_m[None] * Ie[..., None]).sum(dim=2)  # (c, m, 3)
    dcorner = d[:, faces]  # (c, m, 3 corners, 3): corner c starts edge c
    single = ((dcorner * edge_m[None]).sum(dim=-1) * Ie).sum(dim=-1)
    psi = (single - h * omega) / (4.0 * math.pi)
    terms_phi = (gam * omega[..., None]
                 - h[..., None] * (grads[None] * vec[:, :, None, :]).sum(dim=-1)) / (4 * math.pi)
    phi = torch.zeros(X.shape[0], k, dtype=X.dtype, device=X.device)
    phi = phi.index_add(1, faces.reshape(-1), terms_phi.reshape(X.shape[0], -1))
    return phi, psi


def green_coordinates(points: torch.Tensor, cage_v: torch.Tensor,
                      cage_f: torch.Tensor | ArrayLike,
                      chunk_size: int = 1024) -> tuple[torch.Tensor, torch.Tensor]:
    """Green coordinates of points, differentiable in the points and the cage vertices.

    Parameters
    ----------
    points : (n, 3) float tensor
    cage_v : (k, 3) float tensor
        Of the same dtype and device.
    cage_f : (m, 3) integer array or tensor
        Closed, 2-manifold, outward (:func:`cagekit.check_cage`), no face of zero area.
    chunk_size : int, default 1024
        Points evaluated at a time.

    Returns
    -------
    phi : (n, k) tensor
    psi : (n, m) tensor
        As :func:`cagekit.coords.green.green_coordinates` returns them.

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> x = torch.tensor([[0.1, 0.2, -0.3]], dtype=torch.float64)
    >>> phi, psi = green_coordinates(x, torch.tensor(v), f)
    >>> round(float(phi.sum()), 12)
    1.0
    """

    X, V = _as_tensor(points, "points"), _as_tensor(cage_v, "cage vertices")
    if V.dtype != X.dtype or V.device != X.device:
        raise InputError("points and cage vertices must share dtype and device")
    faces_np = np.ascontiguousarray(np.asarray(cage_f), dtype=np.int64)
    topo = cage_topology(faces_np)
    faces = torch.as_tensor(faces_np, device=X.device)
    edges = torch.tensor(topo.edges, device=X.device)  # copies: the topology is read-only
    face_edges = torch.tensor(topo.face_edges, device=X.device)
    signs = torch.tensor(topo.face_edge_signs, dtype=X.dtype, device=X.device)
    terms = _face_terms(V, faces)
    if not bool((terms[1] > 0).all()):
        raise InputError("Green coordinates need cage faces of positive area")
    # where the core evaluates each point, and which are outside: constants from the core
    points_np = X.detach().cpu().double().numpy()
    plan = core.evaluation_plan(points_np, V.detach().cpu().double().numpy(), faces_np)
    shift = torch.as_tensor(plan.evaluated - points_np, dtype=X.dtype, device=X.device)
    Xe = X + shift
    phis, psis = [], []
    for start in range(0, X.shape[0], max(1, int(chunk_size))):
        stop = start + max(1, int(chunk_size))
        phi, psi = _raw_chunk(Xe[start:stop], V, faces, edges, face_edges, signs, terms)
        phis.append(phi)
        psis.append(psi)
    k, m = V.shape[0], faces.shape[0]
    phi = torch.cat(phis) if phis else X.new_zeros((0, k))
    psi = torch.cat(psis) if psis else X.new_zeros((0, m))
    if len(plan.outside_rows):
        phi, psi = _extend(X, V, faces, terms[0], plan, phi, psi)
    if not (torch.isfinite(phi).all() and torch.isfinite(psi).all()):
        raise FloatingPointError("Green coordinates are not finite")
    return phi, psi


def _extend(X, V, faces, normals, plan, phi, psi):
    """The core's extension across each outside point's exit face, in torch."""
    rows = torch.as_tensor(plan.outside_rows, device=X.device)
    exit_faces = torch.as_tensor(plan.exit_faces, device=X.device)
    f = faces[exit_faces]
    v0, v1, v2 = V[f[:, 0]], V[f[:, 1]], V[f[:, 2]]
    A = torch.stack([v1 - v0, v2 - v0, normals[exit_faces]], dim=2)
    coef = torch.linalg.solve(A, (X[rows] - v0)[..., None])[..., 0]
    add_phi = torch.zeros_like(phi)
    add_phi = add_phi.index_put((rows, f[:, 0]), 1.0 - coef[:, 0] - coef[:, 1], accumulate=True)
    add_phi = add_phi.index_put((rows, f[:, 1]), coef[:, 0], accumulate=True)
    add_phi = add_phi.index_put((rows, f[:, 2]), coef[:, 1], accumulate=True)
    add_psi = torch.zeros_like(psi).index_put((rows, exit_faces), coef[:, 2], accumulate=True)
    return phi + add_phi, psi + add_psi


def stretch_factors(rest_v: torch.Tensor, new_v: torch.Tensor,
                    faces: ArrayLike) -> torch.Tensor:
    """:func:`cagekit.coords.green.stretch_factors` in torch (differentiable in ``new_v``
    and ``rest_v``)."""
    f = torch.as_tensor(np.asarray(faces, dtype=np.int64), device=new_v.device)
    u1, u2 = rest_v[f[:, 1]] - rest_v[f[:, 0]], rest_v[f[:, 2]] - rest_v[f[:, 0]]
    w1, w2 = new_v[f[:, 1]] - new_v[f[:, 0]], new_v[f[:, 2]] - new_v[f[:, 0]]
    len1 = u1.norm(dim=-1)
    twice = torch.linalg.cross(u1, u2, dim=-1).norm(dim=-1)
    a = (u1 * u2).sum(dim=-1) / len1
    b = twice / len1
    across = _safe_norm(w2 - (a / len1)[:, None] * w1)
    inside = (len1 * across) ** 2 + (b * w1.norm(dim=-1)) ** 2
    return inside.sqrt() / (math.sqrt(2.0) * twice)


def green_deform(phi: torch.Tensor, psi: torch.Tensor, rest_v: torch.Tensor,
                 new_v: torch.Tensor, faces: ArrayLike) -> torch.Tensor:
    """Deformed points ``phi @ new_v + psi @ (s * n')``, differentiable in everything.

    Parameters
    ----------
    phi : (n, k) tensor
    psi : (n, m) tensor
    rest_v, new_v : (k, 3) tensor
        The cage the points were bound to and its moved vertices.
    faces : (m, 3) integer array

    Returns
    -------
    (n, 3) tensor
    """
    f = torch.as_tensor(np.asarray(faces, dtype=np.int64), device=new_v.device)
    cross = torch.linalg.cross(new_v[f[:, 1]] - new_v[f[:, 0]], new_v[f[:, 2]] - new_v[f[:, 0]],
                               dim=-1)
    normals = cross / cross.norm(dim=-1, keepdim=True)
    s = stretch_factors(rest_v, new_v, faces)
    return phi @ new_v + psi @ (normals * s[:, None])


class GreenBinding:
    """Points bound to a cage by differentiable Green coordinates (torch).

    What :func:`cagekit_learn.bind` returns for ``method="green"``, the twin of
    :class:`cagekit.coords.GreenBinding`; the learned mode deforms with it when trained
    with Green coordinates.

    Attributes
    ----------
    phi : (n, k) torch.Tensor
        Vertex coordinates; rows sum to one. Keeps its autograd graph.
    psi : (n, m) torch.Tensor
        Face coordinates (in the cage's units).
    cage_v : (k, 3) torch.Tensor
        The cage the points were bound to.
    cage_f : (m, 3) int64 torch.Tensor
        Its faces, oriented outward.
    method : str
        ``"green"``.
    """

    def __init__(self, phi: torch.Tensor, psi: torch.Tensor, cage_v: torch.Tensor,
                 cage_f: torch.Tensor) -> None:
        self.phi, self.psi = phi, psi
        self.cage_v, self.cage_f = cage_v, cage_f
        self.method = "green"

    @property
    def n_points(self) -> int:
        """Number of bound points."""
        return self.phi.shape[0]

    def deform(self, new_cage_v: torch.Tensor | ArrayLike) -> torch.Tensor:
        """Positions of the bound points for moved cage vertices (:func:`green_deform`).

        Parameters
        ----------
        new_cage_v : (k, 3) torch.Tensor or array_like
            The moved cage vertices, in the same order; an array is converted to the
            coordinates' dtype and device.

        Returns
        -------
        (n, 3) torch.Tensor
            Differentiable in the coordinates and in ``new_cage_v``.

        Examples
        --------
        >>> from cagekit.cage.shapes import box_cage
        >>> v, f = box_cage()
        >>> x = torch.tensor([[0.5, 0.0, 0.0]], dtype=torch.float64)
        >>> phi, psi = green_coordinates(x, torch.tensor(v), f)
        >>> b = GreenBinding(phi, psi, torch.tensor(v), torch.as_tensor(f))
        >>> (b.deform(2 * v + 1).round(decimals=12) + 0.0).tolist()  # similarities: exact
        [[2.0, 1.0, 1.0]]
        """
        new = new_cage_v
        if not isinstance(new, torch.Tensor):
            new = torch.as_tensor(np.asarray(new, dtype=np.float64), dtype=self.phi.dtype,
                                  device=self.phi.device)
        if tuple(new.shape) != tuple(self.cage_v.shape):
            raise InputError(f"deformed cage has shape {tuple(new.shape)}, the bound cage "
                             f"has {tuple(self.cage_v.shape)}: vertex counts must match")
        if new.dtype != self.phi.dtype:
            raise InputError(f"deformed cage has dtype {new.dtype}, the coordinates have "
                             f"{self.phi.dtype}")
        if not bool(torch.isfinite(new.detach()).all()):
            raise InputError("deformed cage has NaN or inf coordinates")
        return green_deform(self.phi, self.psi, self.cage_v, new, self.cage_f.cpu().numpy())


def _as_tensor(a, name) -> torch.Tensor:
    if not torch.is_tensor(a):
        raise InputError(f"{name} must be a torch tensor")
    if a.ndim != 2 or a.shape[-1] != 3:
        raise InputError(f"{name} must have shape (n, 3), got {tuple(a.shape)}")
    if not a.is_floating_point():
        raise InputError(f"{name} must be a floating-point tensor")
    return a
