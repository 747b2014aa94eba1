"""Differentiable mean value coordinates in torch (batched, chunked, gradient-safe).

The torch twin of :mod:`cagekit.coords.mvc`, whose docstring has the formulation: the same
numbers from plain tensor operations (relative to the cage's bounding-box centre), so that
the weights can be differentiated with respect to the points *and* the cage vertices, as in
the training loop of "Neural Cages". The switch-over zone, its order (vertex, edge, face),
the skipped in-plane faces, the far-point blend into the affine extension and the
closest-point fallback (a constant, zero gradient) are the core's; :data:`DEFAULT_SNAP` is
``1e-13`` in float64 and ``1e-6`` in float32, where the formula breaks down close to an edge
(``snap`` must lie in ``[eps**2, 0.1]`` of the dtype). In float32, single weights of points
near the plane of a face they lie outside of are ill-conditioned, so each row's error is
estimated and rows above ``1e-6`` (or unresolvable) are recomputed in float64. Gradients are
finite everywhere the forward pass is defined, on vertices, edges and faces too: every masked
branch replaces the *inputs* of a dangerous operation by safe values before it ("double
where"), and snap rows are differentiable limit interpolants. Points run ``chunk_size`` at a
time, as component tensors with the points innermost and one 0/1 matrix product back to the
vertices; with a gradient, large chunks run under :func:`torch.utils.checkpoint.checkpoint`
(``use_reentrant=False``), so backward keeps about the points' size, not ``B x n x k``.

On the CPU the same numbers come, by default, from compiled kernels
(:mod:`cagekit.coords.mvc_grad`, forward and hand-derived vector-Jacobian product, float64
inside for both dtypes) through one :class:`torch.autograd.Function`; the rows those kernels
flag (within the switch-over distance of a face's plane, unresolvable sums, degenerate terms)
are computed by the torch graph above and put in place, and the far blend is applied after.
:func:`compiled_kernels` switches them off (the torch graph alone, as on CUDA).
See docs/architecture.md.
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Literal, overload

import numpy as np
import torch
from numpy.typing import ArrayLike
from torch.utils.checkpoint import checkpoint

from cagekit.cage import cage_topology, check_cage
from cagekit.coords.mvc import FAR_BLEND, closest_point_weights
from cagekit.coords.mvc_grad import mvc_vjp, mvc_weights_flagged
from cagekit.errors import InputError
from cagekit_learn.green import GreenBinding, green_coordinates
from cagekit_learn.threads import torch_threads_kept

__all__ = ["mean_value_coordinates", "CageBinding", "bind", "deform", "DEFAULT_SNAP",
           "METHODS", "compiled_kernels", "kernels_enabled"]

METHODS = ("mvc", "green")

#: Default switch-over distance, relative to the cage's bounding-box diagonal, per dtype.
DEFAULT_SNAP = {torch.float64: 1e-13, torch.float32: 1e-6}

# Relative size below which the weight sum counts as unresolvable (core: 1e-15 in float64);
# float32 rows below theirs are recomputed in float64 first.
_RESOLVE_TOL = {torch.float64: 1e-15, torch.float32: 1e-6}
# Tolerance of the "inside the face" test of the face switch-over (core: 1e-12 in float64).
_FACE_TOL = {torch.float64: 1e-12, torch.float32: 1e-5}
# float32 rows whose estimated weight error exceeds this are recomputed in float64.
_RECHECK = 1e-6
# Below this ratio s / c the edge term uses its Taylor form.
_TAYLOR_RATIO = 1e-3
#: (batch x points x faces) of a chunk above which the backward recomputes it
_RECOMPUTE_ABOVE = 1 << 17


@dataclass(frozen=True)
class _Consts:
    """Index and incidence tensors of one cage topology on one device and dtype."""

    faces: torch.Tensor        # (m, 3) int64
    edges: torch.Tensor        # (e, 2) int64
    e0: torch.Tensor           # (e,) lower vertex of each edge
    e1: torch.Tensor           # (e,) higher vertex
    face_opp: torch.Tensor     # (3 m,) edges opposite vertex a, b, c of each face: bc, ca, ab
    face_sgn: torch.Tensor     # (3, m, 1) their signs
    face_vert: torch.Tensor    # (3 m,) vertex a, b, c of each face
    fa: torch.Tensor           # (m,) vertex a of each face
    scatter_t: torch.Tensor    # (k, 3 m) 0/1: column r * m + f has a one at faces[f, r]
    faces_np: np.ndarray       # (m, 3) int64, for the numba fallback
    resolve_tol: float
    face_tol: float
    thr_s2: float              # s**2 below which the direct edge branch is sanitised
    thr_det: float             # |det| below which a face is skipped
    eps: float                 # machine epsilon of the dtype
    hi: _Consts | None         # float64 twin, for rows that float32 cannot resolve


def _consts(faces_np: np.ndarray, k: int, snap: float, dtype, device) -> _Consts:
    """The cage's constants for the layer, kept for the last :data:`_CACHED_CONSTS` cages
    (a training step binds through the same cage faces every time)."""
    faces_np = np.array(faces_np, dtype=np.int64)  # its own copy: the caller's may change
    faces_np.flags.writeable = False
    if len(faces_np) > _CACHED_FACES:
        return _make_consts(faces_np, k, snap, dtype, device)
    key = (faces_np.shape, faces_np.tobytes(), k, snap, dtype, str(device))
    with _CONSTS_LOCK:
        known = _CONSTS.get(key)
    if known is None:
        known = _make_consts(faces_np, k, snap, dtype, device)
        with _CONSTS_LOCK:
            while len(_CONSTS) >= _CACHED_CONSTS:
                _CONSTS.pop(next(iter(_CONSTS)))  # the oldest
            _CONSTS[key] = known
    return known


_CACHED_CONSTS = 16
_CACHED_FACES = 5_000  # larger cages are not kept: their scatter matrix is (k, 3 m) dense
_CONSTS: dict[tuple, _Consts] = {}
_CONSTS_LOCK = threading.Lock()


def _make_consts(faces_np: np.ndarray, k: int, snap: float, dtype, device) -> _Consts:
    topo = cage_topology(faces_np)
    m = len(faces_np)
    fe = topo.face_edges            # columns: ab, bc, ca
    fs = topo.face_edge_signs
    opp = np.concatenate([fe[:, 1], fe[:, 2], fe[:, 0]])
    sgn = np.stack([fs[:, 1], fs[:, 2], fs[:, 0]])
    vert = np.concatenate([faces_np[:, 0], faces_np[:, 1], faces_np[:, 2]])
    scatter = np.zeros((k, 3 * m))
    scatter[vert, np.arange(3 * m)] = 1.0

    def idx(a):  # a copy: the topology's arrays are read-only
        return torch.tensor(np.ascontiguousarray(a), dtype=torch.int64, device=device)

    tiny = torch.finfo(dtype).tiny
    hi = _consts(faces_np, k, snap, torch.float64, device) if dtype != torch.float64 else None
    return _Consts(
        faces=idx(faces_np), edges=idx(topo.edges), e0=idx(topo.edges[:, 0]),
        e1=idx(topo.edges[:, 1]), face_opp=idx(opp),
        face_sgn=torch.as_tensor(sgn[:, :, None], dtype=dtype, device=device), face_vert=idx(vert),
        fa=idx(faces_np[:, 0]),
        scatter_t=torch.as_tensor(scatter, dtype=dtype, device=device),
        faces_np=np.ascontiguousarray(faces_np, dtype=np.int64),
        resolve_tol=_RESOLVE_TOL[dtype], face_tol=_FACE_TOL[dtype],
        thr_s2=(1e-3 * snap) ** 2, thr_det=tiny ** 0.4, eps=torch.finfo(dtype).eps, hi=hi,
    )


def _dot(a, b):
    """Dot product of two vectors given as component lists (broadcasting)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    """Cross product of two vectors given as component lists."""
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _half_angle_over_sin(s2, c, thr_s2):
    """``atan2(s, c) / (2 s)`` with ``s = sqrt(s2)``, 0 where ``s2 <= thr_s2`` and ``c <= 0``.

    Gradient-safe: the Taylor branch (``c > 0``, ``s < 1e-3 c``) is smooth at ``s = 0`` and
    the direct branch only ever sees ``s2 > thr_s2`` (inputs replaced before the operations).
    """
    taylor = (c > 0) & (s2 < (_TAYLOR_RATIO ** 2) * c * c)
    direct = ~taylor & (s2 > thr_s2)
    if bool(direct.all()):  # the usual case: no point on or near the line of an edge
        rs = torch.rsqrt(s2)
        return torch.atan2(s2 * rs, c) * (0.5 * rs)
    ict = 1.0 / torch.where(taylor, c, 1.0)
    t = s2 * (ict * ict)
    g_taylor = (0.5 * ict) * (1.0 - t * (1.0 / 3.0 - t * 0.2))
    s2d = torch.where(direct, s2, 1.0)
    rs = torch.rsqrt(s2d)
    g_direct = torch.atan2(s2d * rs, torch.where(direct, c, 1.0)) * (0.5 * rs)
    return torch.where(taylor, g_taylor, torch.where(direct, g_direct, 0.0))


def _unnormalised(P, V, snap_d, h, cst: _Consts, nrm=None):
    """Unnormalised MVC ``w`` (k, N), in-plane faces skipped; values always finite.

    ``P`` (B, c, 3) and ``V`` (B, k, 3) are centred, ``N = B * c``; ``h`` (m, N) (detached)
    are the signed distances to the face planes and ``snap_d`` (N,) the switch-over
    distances. Vectors are kept as three component tensors of shape ``(rows, N)`` (rows:
    vertices, edges or faces), so that gathers copy contiguous rows and all element-wise
    work runs over the points, innermost.

    With the unit face normals ``nrm`` (B, m, 3) it also returns, per point, the rounding
    error amplification of its worst ill-conditioned face: ``max_r (1 / d_r) / |det|`` over
    the faces whose plane's foot point lies outside the triangle (else None). Times ``eps``
    and divided by the weight sum it estimates the error of the normalised weights.
    """
    B, c, k = P.shape[0], P.shape[1], V.shape[1]
    m = cst.fa.shape[0]
    N = B * c
    A = [(V[:, :, i].T.unsqueeze(-1) - P[:, :, i].unsqueeze(0)).reshape(k, N) for i in range(3)]
    d2 = A[0] * A[0] + A[1] * A[1] + A[2] * A[2]                            # (k, N)
    near = d2 <= (0.5 * snap_d) ** 2        # those rows snap to the vertex
    if bool(near.any()):
        inv_d = torch.rsqrt(torch.where(near, 1.0, d2))
        U = [torch.where(near, float(i == 0), a * inv_d) for i, a in enumerate(A)]
    else:
        inv_d = torch.rsqrt(d2)
        U = [a * inv_d for a in A]
    ua = [u.index_select(0, cst.e0) for u in U]                             # (e, N)
    ub = [u.index_select(0, cst.e1) for u in U]
    X = _cross(ua, ub)
    g = _half_angle_over_sin(_dot(X, X), _dot(ua, ub), cst.thr_s2)         # (e, N)
    # The edges opposite a, b and c of each face are its three edges, so the face's mean
    # vector sum_r sgn_r G_r (G = g X) uses the same gathered cross products.
    sgn = cst.face_sgn                                                      # (3, m, 1)
    Xo = [x.index_select(0, cst.face_opp).view(3, m, N) for x in X]        # (3, m, N)
    go = g.index_select(0, cst.face_opp).view(3, m, N) * sgn
    mean = [(go * x).sum(0) for x in Xo]                                    # (m, N)
    det = sgn[0] * _dot([u.index_select(0, cst.fa) for u in U], [x[0] for x in Xo])
    ok = (h.abs() > snap_d) & (det.abs() > cst.thr_det)
    if bool(ok.all()):
        inv = 1.0 / det
    else:
        inv = torch.where(ok, 1.0 / torch.where(ok, det, 1.0), 0.0)
    num = _dot(mean, Xo)                                                    # (3, m, N)
    ivd = inv_d.index_select(0, cst.face_vert).view(3, m, N)
    lam = num * (inv * sgn) * ivd
    W = cst.scatter_t @ lam.view(3 * m, N)                                  # (k, N)
    if nrm is None:
        return W, None
    with torch.no_grad():
        # signs of the foot point's barycentric coordinates: sgn_r (X_r . n) (d's > 0)
        n = [nrm[:, :, i].detach().T.unsqueeze(-1) for i in range(3)]      # (m, B, 1)
        side = sgn.unsqueeze(-1) * _dot([x.detach().view(3, m, B, c) for x in Xo], n) > 0
        off = side.any(0) & ~side.all(0)
        amp = torch.where(off.view(m, N), ivd.detach().amax(0) * inv.detach().abs(), 0.0)
    return W, amp.amax(0)


def _face_bary(x, pa, pb, pc, n):
    """Twice the signed areas (along ``n``) of the sub-triangles opposite a, b and c."""
    a, b, c = pa - x, pb - x, pc - x
    return torch.stack([(torch.linalg.cross(b, c) * n).sum(-1),
                        (torch.linalg.cross(c, a) * n).sum(-1),
                        (torch.linalg.cross(a, b) * n).sum(-1)], -1)


def _snap_rows(x, V, nrm, h, sd, cst: _Consts):
    """Switch-over weights of candidate rows, in the core's order: vertex, edge, face.

    Parameters: ``x`` (r, 3), ``V`` (r, k, 3), ``nrm`` (r, m, 3), ``h`` (r, m) detached,
    ``sd`` (r,). Returns ``snapped`` (r,) bool and ``rows`` (r, k) (meaningful where
    snapped), differentiable in ``x``, ``V`` and ``nrm``.
    """
    r, k = V.shape[0], V.shape[1]
    rr = torch.arange(r, device=x.device)
    e0, e1, faces = cst.e0, cst.e1, cst.faces
    with torch.no_grad():
        xd, Vd, nd = x.detach(), V.detach(), nrm.detach()
        s = sd.unsqueeze(-1)
        vhit = ((Vd - xd.unsqueeze(1)).square().sum(-1)).sqrt() <= s
        a = Vd[:, e0]
        ab = Vd[:, e1] - a
        t = (((xd.unsqueeze(1) - a) * ab).sum(-1) / (ab * ab).sum(-1)).clamp(0.0, 1.0)
        q = a + t.unsqueeze(-1) * ab - xd.unsqueeze(1)
        ehit = q.square().sum(-1).sqrt() <= s
        bary = _face_bary(xd.unsqueeze(1), Vd[:, faces[:, 0]], Vd[:, faces[:, 1]],
                          Vd[:, faces[:, 2]], nd)
        tot = bary.sum(-1)
        fhit = (h.abs() <= s) & (tot > 0) & (bary.amin(-1) >= -cst.face_tol * tot)
        is_v = vhit.any(-1)
        is_e = ~is_v & ehit.any(-1)
        is_f = ~is_v & ~is_e & fhit.any(-1)
        jv = vhit.to(torch.int8).argmax(-1)      # first hit, as the core's loops
        je = ehit.to(torch.int8).argmax(-1)
        jf = fhit.to(torch.int8).argmax(-1)
    dt = x.dtype
    w_v = torch.nn.functional.one_hot(jv, k).to(dt)
    # edge: linear interpolation at the closest point of the chosen edge
    ia, ib = e0[je], e1[je]
    pa, pb = V[rr, ia], V[rr, ib]
    ab = pb - pa
    ab2 = (ab * ab).sum(-1)
    ab2 = torch.where(ab2 > 0, ab2, 1.0)
    t = (((x - pa) * ab).sum(-1) / ab2).clamp(0.0, 1.0).unsqueeze(-1)
    w_e = ((1.0 - t) * torch.nn.functional.one_hot(ia, k).to(dt)
           + t * torch.nn.functional.one_hot(ib, k).to(dt))
    # face: barycentric coordinates in the chosen face
    fv = faces[jf]                                                           # (r, 3)
    bary = _face_bary(x, V[rr, fv[:, 0]], V[rr, fv[:, 1]], V[rr, fv[:, 2]], nrm[rr, jf])
    bary = bary.clamp(min=0.0)
    tot = bary.sum(-1, keepdim=True)
    tot = torch.where(is_f.unsqueeze(-1) & (tot > 0), tot, 1.0)
    w_f = torch.zeros(r, k, dtype=dt, device=x.device).scatter_add(1, fv, bary / tot)
    rows = torch.where(is_v.unsqueeze(-1), w_v,
                       torch.where(is_e.unsqueeze(-1), w_e, w_f))
    return is_v | is_e | is_f, rows


def _closest_rows(x, V, faces_np):
    """Barycentric weights of the closest cage point (the core's fallback), as constants."""

    xs = x.detach().to("cpu", torch.float64).numpy()
    vs = V.detach().to("cpu", torch.float64).numpy()
    out = np.zeros((len(xs), vs.shape[1]))
    for i in range(len(xs)):  # rare: only unresolvable rows, very far outside
        closest_point_weights(xs[i], np.ascontiguousarray(vs[i]), faces_np, out[i])
    return torch.as_tensor(out, dtype=x.dtype, device=x.device)


def _normalise(W, tol):
    """Divide (k, N) weights by their sums where resolvable; returns (rows, resolvable)."""
    with torch.no_grad():
        Wd = W.detach()
        mag = Wd.abs().sum(0)
        resolvable = (Wd.sum(0).abs() > tol * mag) & torch.isfinite(mag)
    return W * (1.0 / torch.where(resolvable, W.sum(0), 1.0)), resolvable


def _chunk(P, V, nrm, off, snap_d, cst: _Consts):
    """Normalised MVC of one chunk of points: (B, c, 3) -> (B, c, k)."""
    B, c, k = P.shape[0], P.shape[1], V.shape[1]
    m = cst.fa.shape[0]
    with torch.no_grad():
        h = nrm.detach() @ P.detach().transpose(1, 2) - off.unsqueeze(-1)  # (B, m, c)
        sd = snap_d.repeat_interleave(c)                                    # (N,)
        cand = (h.abs() <= snap_d.view(-1, 1, 1)).any(1)                    # (B, c)
        any_cand = bool(cand.any())
    W, amp = _unnormalised(P, V, sd, h.transpose(0, 1).reshape(m, B * c), cst,
                           nrm if cst.hi is not None else None)             # (k, N)
    out, resolvable = _normalise(W, cst.resolve_tol)
    out = out.view(k, B, c).permute(1, 2, 0).contiguous()                   # (B, c, k)
    resolvable = resolvable.view(B, c)
    snapped = torch.zeros_like(cand)
    if any_cand:
        bi, ci = torch.nonzero(cand, as_tuple=True)
        hit, rows = _snap_rows(P[bi, ci], V[bi], nrm[bi], h[bi, :, ci], snap_d[bi], cst)
        bi, ci, rows = bi[hit], ci[hit], rows[hit]
        snapped[bi, ci] = True
    if cst.hi is not None:
        # float32: rows whose estimated error exceeds _RECHECK (points outside the cage,
        # near the plane of a face) or whose sum is unresolvable are redone in float64
        with torch.no_grad():
            err = cst.eps * amp / W.detach().sum(0).abs()
            redo = ~snapped & (~resolvable | ~(err <= _RECHECK).view(B, c))
        if bool(redo.any()):
            rb, rc = torch.nonzero(redo, as_tuple=True)
            W64, _ = _unnormalised(P[rb, rc].double().unsqueeze(1), V[rb].double(),
                                   snap_d[rb].double(), h[rb, :, rc].double().T, cst.hi)
            rows64, ok64 = _normalise(W64, cst.hi.resolve_tol)
            out = out.index_put((rb, rc), rows64.T.to(out.dtype))
            resolvable = resolvable.index_put((rb, rc), ok64)
    fallback = ~snapped & ~resolvable
    if bool(fallback.any()):
        fb, fc = torch.nonzero(fallback, as_tuple=True)
        out = out.index_put((fb, fc), _closest_rows(P[fb, fc], V[fb], cst.faces_np))
    if any_cand and bool(snapped.any()):
        out = out.index_put((bi, ci), rows)
    return out


_KERNELS = [True]


@contextlib.contextmanager
def compiled_kernels(enabled: bool) -> Iterator[None]:
    """Use (or not) the compiled CPU kernels for MVC inside the block; then restore.

    Parameters
    ----------
    enabled : bool
        False computes CPU tensors with the torch graph alone (what CUDA tensors always
        use): the reference the kernels are tested against, and the baseline of
        ``benchmarks/bench_layer.py``.

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> x = torch.tensor([[0.1, 0.2, -0.3]], dtype=torch.float64)
    >>> with compiled_kernels(False):
    ...     w = mean_value_coordinates(x, torch.tensor(v), f)
    >>> bool(torch.allclose(w, mean_value_coordinates(x, torch.tensor(v), f), atol=1e-14))
    True
    """
    before = _KERNELS[0]
    _KERNELS[0] = bool(enabled)
    try:
        yield
    finally:
        _KERNELS[0] = before


def kernels_enabled(device: torch.device) -> bool:
    """Whether tensors on ``device`` use compiled code: on the CPU, unless
    :func:`compiled_kernels` ``(False)`` is in force (this module's MVC kernels, libigl in
    :func:`cagekit_learn.enclosure.enclosure_loss`, k-d trees in
    :func:`cagekit_learn.losses.chamfer_loss`).

    Examples
    --------
    >>> cpu = torch.device("cpu")
    >>> kernels_enabled(cpu), kernels_enabled(torch.device("cuda"))
    (True, False)
    >>> with compiled_kernels(False):
    ...     kernels_enabled(cpu)
    False
    """
    return device.type == "cpu" and _KERNELS[0]


class _KernelMVC(torch.autograd.Function):
    """MVC of CPU tensors by :mod:`cagekit.coords.mvc_grad`: returns the weights (zero on
    flagged rows) and the flags; the backward pass is the kernels' vector-Jacobian product
    (zero on flagged rows, which the caller replaces)."""

    @staticmethod
    def forward(ctx, P, V, faces, snap, det_tol, skip):
        with torch_threads_kept():
            w, flagged = mvc_weights_flagged(P.detach().numpy(), V.detach().numpy(), faces,
                                             snap=snap, skip=skip.numpy(), det_tol=det_tol)
        flagged_t = torch.from_numpy(flagged)
        ctx.save_for_backward(P, V, flagged_t)
        ctx.args = (faces, snap, det_tol)
        ctx.mark_non_differentiable(flagged_t)
        return torch.from_numpy(w).to(P.dtype), flagged_t

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx, grad_w, _grad_flagged):
        P, V, flagged = ctx.saved_tensors
        faces, snap, det_tol = ctx.args
        with torch_threads_kept():
            gp, gv = mvc_vjp(P.numpy(), V.numpy(), faces, grad_w.double().numpy(), snap=snap,
                             skip=flagged.numpy(), det_tol=det_tol)
        return (torch.from_numpy(gp).to(P.dtype), torch.from_numpy(gv).to(V.dtype), None, None,
                None, None)


def _kernel_weights(Pc, Vc, nrm, off, snap_d, snap, cst: _Consts, chunk_size):
    """Normalised MVC (B, n, k) of CPU tensors by the compiled kernels, flagged rows by the
    torch graph (:func:`_chunk`, ``chunk_size`` rows at a time)."""
    B, n = Pc.shape[0], Pc.shape[1]
    with torch.no_grad():
        # rows the torch graph gives switch-over treatment: within snap_d of a face's plane
        skip = torch.zeros(B, n, dtype=torch.bool)
        for start in range(0, n, chunk_size):
            p = Pc[:, start:start + chunk_size].detach()
            h = nrm.detach() @ p.transpose(1, 2) - off.unsqueeze(-1)              # (B, m, c)
            skip[:, start:start + chunk_size] = (h.abs() <= snap_d.view(-1, 1, 1)).any(1)
    out, flagged = _KernelMVC.apply(Pc, Vc, cst.faces_np, snap, cst.thr_det, skip)
    if not bool(flagged.any()):
        return out
    bi, ni = torch.nonzero(flagged, as_tuple=True)
    for start in range(0, len(bi), chunk_size):
        b, i = bi[start:start + chunk_size], ni[start:start + chunk_size]
        rows = _chunk(Pc[b, i].unsqueeze(1), Vc[b], nrm[b], off[b], snap_d[b], cst)
        out = out.index_put((b, i), rows.squeeze(1))
    return out


def _as_float_tensor(a, name):
    if not isinstance(a, torch.Tensor):
        a = torch.as_tensor(np.asarray(a, dtype=np.float64))
    if a.dtype not in (torch.float32, torch.float64):
        raise InputError(f"{name} must be a float32 or float64 tensor, got {a.dtype}")
    if a.ndim not in (2, 3) or a.shape[-1] != 3:
        raise InputError(f"{name} must have shape (n, 3) or (B, n, 3), got {tuple(a.shape)}")
    return a


def mean_value_coordinates(points: torch.Tensor | ArrayLike, cage_v: torch.Tensor | ArrayLike,
                           cage_f: torch.Tensor | ArrayLike, *, snap: float | None = None,
                           chunk_size: int = 2048) -> torch.Tensor:
    """Differentiable mean value coordinates of points with respect to closed triangle cages.

    Parameters
    ----------
    points : (B, n, 3) or (n, 3) torch.Tensor, float32 or float64
        Query points, anywhere off or on the cage. Arrays are converted to float64 tensors.
    cage_v : (B, k, 3) or (k, 3) torch.Tensor, same dtype as ``points``
        Cage vertices; a ``(k, 3)`` cage is shared by the whole batch, a batch of points of
        size 1 (or an ``(n, 3)`` array) is shared by a batch of cages.
    cage_f : (m, 3) array_like or torch.Tensor of int
        Faces shared by the batch: closed, 2-manifold, consistently oriented. They are
        validated once with :func:`cagekit.cage.check_cage` on the first cage (an inward
        cage is flipped), which raises :class:`cagekit.errors.CageError` otherwise. Cages
        that intersect themselves are accepted here (a network's predictions may, during
        training); the core's :func:`cagekit.bind` refuses them.
    snap : float, optional
        Switch-over distance relative to the cage's bounding-box diagonal (see the module
        docstring); defaults to :data:`DEFAULT_SNAP` of the dtype (1e-13 in float64, 1e-6 in
        float32). Must lie in ``[eps**2, 0.1]`` of the dtype.
    chunk_size : int, default 2048
        Points processed at a time (per batch element); peak memory is proportional to it.

    Returns
    -------
    weights : (B, n, k) torch.Tensor, or (n, k) when ``points`` and ``cage_v`` are both
        unbatched; the dtype of ``points``. Rows sum to one and ``weights @ cage_v``
        reproduces the points; differentiable with respect to ``points`` and ``cage_v``.

    Raises
    ------
    InputError
        Wrong shapes or dtypes, NaN or inf inputs, a bad ``snap`` or ``chunk_size``.
    CageError
        An open, non-manifold or inconsistently oriented cage (a subclass of InputError).

    Examples
    --------
    >>> import torch
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> cage = torch.tensor(v, requires_grad=True)
    >>> x = torch.tensor([[0.1, 0.2, -0.3]], dtype=torch.float64)
    >>> w = mean_value_coordinates(x, cage, f)
    >>> w.shape, round(float(w.detach().sum()), 12)
    (torch.Size([1, 8]), 1.0)
    >>> torch.allclose(w @ cage, x)
    True
    >>> (w @ cage).sum().backward()  # gradients reach the cage
    >>> bool(torch.isfinite(cage.grad).all())
    True
    """
    return _weights_and_faces(points, cage_v, cage_f, snap, chunk_size)[0]


def _weights_and_faces(points, cage_v, cage_f, snap, chunk_size):
    """:func:`mean_value_coordinates` and the checked (outward) faces as NumPy int64."""
    points = _as_float_tensor(points, "points")
    cage_v = _as_float_tensor(cage_v, "cage_v")
    if cage_v.dtype != points.dtype:
        raise InputError(f"cage_v has dtype {cage_v.dtype}, points have {points.dtype}: "
                         "they must match")
    if cage_v.device != points.device:
        raise InputError("points and cage_v must be on the same device")
    dtype, device = points.dtype, points.device
    if snap is None:
        snap = DEFAULT_SNAP[dtype]
    eps = torch.finfo(dtype).eps
    if not (isinstance(snap, (int, float)) and math.isfinite(snap) and eps ** 2 <= snap <= 0.1):
        raise InputError(f"snap must be a float in [{eps ** 2:.3g}, 0.1] for {dtype}, "
                         f"got {snap!r}")
    if not isinstance(chunk_size, (int, np.integer)) or chunk_size < 1:
        raise InputError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    unbatched = points.ndim == 2 and cage_v.ndim == 2
    P = points if points.ndim == 3 else points.unsqueeze(0)
    V = cage_v if cage_v.ndim == 3 else cage_v.unsqueeze(0)
    if P.shape[0] != V.shape[0] and 1 not in (P.shape[0], V.shape[0]):
        raise InputError(f"batch sizes differ: points {tuple(points.shape)}, "
                         f"cage_v {tuple(cage_v.shape)}")
    if V.shape[0] == 0:
        raise InputError("cage_v has an empty batch")
    if not bool(torch.isfinite(P.detach()).all()):
        raise InputError("points contain NaN or inf")
    if not bool(torch.isfinite(V.detach()).all()):
        raise InputError("cage_v contains NaN or inf")
    f_np = cage_f.detach().cpu().numpy() if isinstance(cage_f, torch.Tensor) else cage_f
    faces_np = check_cage(V[0].detach().to("cpu", torch.float64).numpy(), np.asarray(f_np),
                          intersections=False)
    B = max(P.shape[0], V.shape[0])
    k = V.shape[1]
    P = P.expand(B, -1, -1)
    V = V.expand(B, -1, -1)
    n = P.shape[1]
    cst = _consts(faces_np, k, snap, dtype, device)

    with torch.no_grad():
        lo, hi = V.amin(1), V.amax(1)
        centre = (0.5 * (lo + hi)).unsqueeze(1)                            # (B, 1, 3)
        snap_d = snap * torch.linalg.vector_norm(hi - lo, dim=-1)          # (B,)
    # centring is exact for the gradient: MVC is translation invariant
    Pc = P - centre
    Vc = V - centre
    f = cst.faces
    nrm = torch.linalg.cross(Vc[:, f[:, 1]] - Vc[:, f[:, 0]], Vc[:, f[:, 2]] - Vc[:, f[:, 0]])
    nn2 = (nrm * nrm).sum(-1, keepdim=True)
    nrm = nrm * torch.rsqrt(torch.where(nn2 > 0, nn2, 1.0))                # (B, m, 3)
    with torch.no_grad():
        off = (Vc[:, f[:, 0]] * nrm).sum(-1)                                # (B, m)

    if n == 0:
        out = Pc.new_zeros((B, 0, k))
    elif kernels_enabled(device):
        out = _blend_far_rows(Pc, Vc, faces_np,
                              _kernel_weights(Pc, Vc, nrm, off, snap_d, snap, cst, chunk_size))
    else:
        out = _blend_far_rows(Pc, Vc, faces_np, _graph_weights(Pc, Vc, nrm, off, snap_d, cst,
                                                               chunk_size))
    return (out[0] if unbatched else out), faces_np


def _graph_weights(Pc, Vc, nrm, off, snap_d, cst: _Consts, chunk_size):
    """Normalised MVC (B, n, k) by the torch graph, ``chunk_size`` points at a time."""
    B, n = Pc.shape[0], Pc.shape[1]
    grad = torch.is_grad_enabled() and (Pc.requires_grad or Vc.requires_grad)
    # recomputation only pays where the saved tensors would be large (not for a few
    # landmarks in a small cage, where it would double the cost of every evaluation)
    recompute = B * min(n, chunk_size) * len(cst.faces_np) > _RECOMPUTE_ABOVE
    outs = []
    for start in range(0, n, chunk_size):
        p = Pc[:, start:start + chunk_size]
        if grad and recompute:
            outs.append(checkpoint(_chunk, p, Vc, nrm, off, snap_d, cst, use_reentrant=False))
        else:
            outs.append(_chunk(p, Vc, nrm, off, snap_d, cst))
    return outs[0] if len(outs) == 1 else torch.cat(outs, 1)


def _blend_far_rows(Pc, Vc, faces_np, out):
    """The core's far-point rule: beyond ``FAR_BLEND[0]`` cage diagonals from the cage's
    centre, MVC is blended into the affine extension (:mod:`cagekit.coords.mvc`).

    Only the far rows are gathered, blended and put back, so memory stays that of the
    output and no other row's gradient passes through the blend. The pseudo-inverse is
    taken in float64 (then cast), which keeps float32 cages accurate.
    """
    lo, hi = FAR_BLEND
    with torch.no_grad():
        D = torch.linalg.vector_norm(Vc.amax(1) - Vc.amin(1), dim=-1)          # (B,)
        q = Pc.detach() / D.view(-1, 1, 1)
        far = ~(torch.hypot(torch.hypot(q[..., 0], q[..., 1]), q[..., 2]) <= lo)  # (B, n)
    if not bool(far.any()):
        return out
    bi, ni = torch.nonzero(far, as_tuple=True)
    # the distance in diagonals as a function of the cage too (its box's centre and
    # diagonal), so that the blend factor's gradient reaches the cage
    top, bottom = Vc.amax(1), Vc.amin(1)
    D = torch.linalg.vector_norm(top - bottom, dim=-1)                      # (B,)
    C = 0.5 * (top + bottom)                                                # (B, 3), ~0
    qf = (Pc[bi, ni] - C[bi]) / D[bi].unsqueeze(-1)                         # (f, 3)
    r = torch.hypot(torch.hypot(qf[:, 0], qf[:, 1]), qf[:, 2])
    t = ((r - lo) / (hi - lo)).clamp(0.0, 1.0)
    s = (t * t * (3.0 - 2.0 * t)).unsqueeze(-1)                              # (f, 1)
    used = torch.as_tensor(np.unique(faces_np), device=Pc.device)
    Vu = (Vc[:, used].double() - C.double().unsqueeze(1)) / D.double().view(-1, 1, 1)
    H = torch.cat([Vu, torch.ones_like(Vu[..., :1])], -1)                   # (B, u, 4)
    M = torch.linalg.pinv(H).to(out.dtype)                                  # (B, 4, u)
    Ph = torch.cat([qf, torch.ones_like(qf[:, :1])], -1)                    # (f, 4)
    affine_used = (Ph.unsqueeze(1) @ M[bi]).squeeze(1)                     # (f, u)
    rows = out[bi, ni]                                                      # (f, k)
    affine = torch.zeros_like(rows).index_copy(1, used, affine_used)
    blended = torch.where(s == 1.0, affine, (1.0 - s) * rows + s * affine)
    return out.index_put((bi, ni), blended)


def deform(weights: torch.Tensor, new_cage_v: torch.Tensor | ArrayLike) -> torch.Tensor:
    """Positions of bound points for moved cage vertices: ``weights @ new_cage_v``.

    Parameters
    ----------
    weights : (B, n, k) or (n, k) torch.Tensor
        Coordinates from :func:`mean_value_coordinates`.
    new_cage_v : (B, k, 3) or (k, 3) torch.Tensor or array_like
        The moved cage vertices, same dtype (an array is converted to the weights' dtype
        and device); a ``(k, 3)`` cage is shared by the batch.

    Returns
    -------
    (B, n, 3) or (n, 3) torch.Tensor
        Broadcast like :func:`torch.matmul`; differentiable in both arguments.

    Examples
    --------
    >>> w = torch.tensor([[0.5, 0.5]], dtype=torch.float64)
    >>> deform(w, torch.tensor([[0.0, 0, 0], [2.0, 0, 0]], dtype=torch.float64)).tolist()
    [[1.0, 0.0, 0.0]]
    """
    if not isinstance(weights, torch.Tensor) or weights.ndim not in (2, 3):
        raise InputError("weights must be an (n, k) or (B, n, k) tensor")
    new = new_cage_v
    if not isinstance(new, torch.Tensor):
        new = torch.as_tensor(np.asarray(new, dtype=np.float64), dtype=weights.dtype,
                              device=weights.device)
    if new.ndim not in (2, 3) or new.shape[-1] != 3 or new.shape[-2] != weights.shape[-1]:
        raise InputError(f"deformed cage has shape {tuple(new.shape)}, expected "
                         f"({weights.shape[-1]}, 3) or (B, {weights.shape[-1]}, 3): vertex "
                         "counts must match")
    if new.ndim == 3 and weights.ndim == 3 and new.shape[0] not in (1, weights.shape[0]):
        raise InputError(f"deformed cage batch {new.shape[0]} does not match the weights' "
                         f"batch {weights.shape[0]}")
    if new.dtype != weights.dtype:
        raise InputError(f"deformed cage has dtype {new.dtype}, weights have {weights.dtype}")
    if not bool(torch.isfinite(new.detach()).all()):
        raise InputError("deformed cage has NaN or inf coordinates")
    return weights @ new


class CageBinding:
    """Points bound to a cage by differentiable coordinates (torch).

    Attributes
    ----------
    weights : (B, n, k) or (n, k) torch.Tensor
        Coordinates of the bound points (rows sum to one); keeps its autograd graph.
    cage_v : (B, k, 3) or (k, 3) torch.Tensor
        The cage the points were bound to.
    cage_f : (m, 3) int64 torch.Tensor
        Its faces, oriented outward.
    method : str
        ``"mvc"``: what :func:`bind` returns for it (Green coordinates give a
        :class:`~cagekit_learn.green.GreenBinding`).
    """

    def __init__(self, weights: torch.Tensor, cage_v: torch.Tensor, cage_f: torch.Tensor,
                 method: str = "mvc"):
        self.weights = weights
        self.cage_v = cage_v
        self.cage_f = cage_f
        self.method = method

    @property
    def n_points(self) -> int:
        """Number of bound points (per batch element)."""
        return self.weights.shape[-2]

    def deform(self, new_cage_v: torch.Tensor | ArrayLike) -> torch.Tensor:
        """Positions of the bound points for moved cage vertices.

        Parameters
        ----------
        new_cage_v : (k, 3) or (B, k, 3) torch.Tensor or array_like
            The cage's vertices after moving them, in the same order (as
            :func:`deform` takes them).

        Returns
        -------
        (B, n, 3) torch.Tensor
            ``weights @ new_cage_v`` (``(n, 3)`` for unbatched weights and cage).

        Examples
        --------
        >>> from cagekit.cage.shapes import box_cage
        >>> v, f = box_cage()
        >>> x = torch.tensor([[[0.5, 0.0, 0.0]]], dtype=torch.float64)
        >>> b = bind(x, torch.tensor(v), f)
        >>> (b.deform(2 * torch.tensor(v)).round(decimals=12) + 0.0).tolist()
        [[[1.0, 0.0, 0.0]]]
        """
        return deform(self.weights, new_cage_v)


@overload
def bind(points: torch.Tensor | ArrayLike, cage_v: torch.Tensor | ArrayLike,
         cage_f: torch.Tensor | ArrayLike, method: Literal["mvc"] = "mvc",
         chunk_size: int = 2048) -> CageBinding: ...
@overload
def bind(points: torch.Tensor | ArrayLike, cage_v: torch.Tensor | ArrayLike,
         cage_f: torch.Tensor | ArrayLike, method: Literal["green"],
         chunk_size: int = 2048) -> GreenBinding: ...
@overload
def bind(points: torch.Tensor | ArrayLike, cage_v: torch.Tensor | ArrayLike,
         cage_f: torch.Tensor | ArrayLike, method: str = "mvc",
         chunk_size: int = 2048) -> CageBinding | GreenBinding: ...


def bind(points: torch.Tensor | ArrayLike, cage_v: torch.Tensor | ArrayLike,
         cage_f: torch.Tensor | ArrayLike, method: str = "mvc",
         chunk_size: int = 2048) -> CageBinding | GreenBinding:
    """Compute the coordinates of points with respect to a cage (or a batch of cages).

    Parameters
    ----------
    points : (B, n, 3) or (n, 3) torch.Tensor, float32 or float64
        ``(n, 3)`` only for ``"green"``. Arrays are converted to float64 tensors.
    cage_v : (B, k, 3) or (k, 3) torch.Tensor, same dtype
        ``(k, 3)`` only for ``"green"``.
    cage_f : (m, 3) array_like or torch.Tensor of int
        Closed, 2-manifold, consistently oriented faces (see
        :func:`mean_value_coordinates`); an inward cage is flipped.
    method : {"mvc", "green"}, default "mvc"
        Mean value coordinates, or Green coordinates (:mod:`cagekit_learn.green`, the
        coordinates the learned mode trains with under ``--coords green``).
    chunk_size : int, default 2048
        Points processed at a time.

    Returns
    -------
    CageBinding or GreenBinding
        ``"mvc"``: a :class:`CageBinding` (``weights``, batched like the inputs);
        ``"green"``: a :class:`~cagekit_learn.green.GreenBinding` (``phi``, ``psi``),
        equal to :func:`cagekit.bind`'s in float64. Type checkers see which from a
        literal ``method``.

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> b = bind(torch.zeros(2, 5, 3, dtype=torch.float64), torch.tensor(v), f)
    >>> tuple(b.weights.shape), b.n_points
    ((2, 5, 8), 5)
    >>> g = bind(torch.zeros(5, 3, dtype=torch.float64), torch.tensor(v), f, method="green")
    >>> type(g).__name__, tuple(g.phi.shape), tuple(g.psi.shape)
    ('GreenBinding', (5, 8), (5, 12))
    """
    if method not in METHODS:
        raise InputError(f"unknown coordinates {method!r}; available: {', '.join(METHODS)}")
    if method == "green":
        return _bind_green(points, cage_v, cage_f, chunk_size)
    weights, faces = _weights_and_faces(points, cage_v, cage_f, None, chunk_size)
    cage = cage_v if isinstance(cage_v, torch.Tensor) else torch.as_tensor(
        np.asarray(cage_v, dtype=np.float64))
    return CageBinding(weights, cage, torch.as_tensor(faces, device=weights.device), method)


def _bind_green(points, cage_v, cage_f, chunk_size) -> GreenBinding:
    """:func:`bind` with Green coordinates: one unbatched cage, faces checked (outward)."""
    P = _as_float_tensor(points, "points")
    V = _as_float_tensor(cage_v, "cage_v")
    if P.ndim != 2 or V.ndim != 2:
        raise InputError("Green coordinates bind one cage at a time: points (n, 3) and "
                         f"cage_v (k, 3), got {tuple(P.shape)} and {tuple(V.shape)}")
    if not (bool(torch.isfinite(P.detach()).all()) and bool(torch.isfinite(V.detach()).all())):
        raise InputError("points or cage_v contain NaN or inf")
    f_np = cage_f.detach().cpu().numpy() if isinstance(cage_f, torch.Tensor) else cage_f
    faces = check_cage(V.detach().to("cpu", torch.float64).numpy(), np.asarray(f_np),
                       intersections=False)
    phi, psi = green_coordinates(P, V, faces, chunk_size=chunk_size)
    return GreenBinding(phi, psi, V, torch.as_tensor(faces, device=V.device))
