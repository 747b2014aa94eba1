"""The textbook mean value coordinates, densely vectorised with NumPy (a reference and peer).

This is the pseudo-code of Ju, Schaefer & Warren 2005 (their figure 4: ``theta_i``, ``h``,
``c_i``, ``s_i``), the formula of VTK's ``vtkMeanValueCoordinatesInterpolator``, written as
plain array expressions over (points x faces). It is what a user would write first, so the
benchmarks use it as a peer, and the tests use it (in ``np.longdouble`` too) as an
independently derived reference away from the cage. Close to the cage it loses digits to
cancellation (``pi - h`` and ``1 - c_i**2``); use :func:`cagekit.coords.mvc.
mean_value_coordinates` for real work.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

__all__ = ["mean_value_coordinates_textbook"]


def mean_value_coordinates_textbook(points: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike,
                                    eps: float = 1e-8, dtype: DTypeLike = np.float64,
                                    chunk: int = 2048) -> np.ndarray:
    """Textbook MVC, vectorised over points and faces.

    Parameters
    ----------
    points : (n, 3) array_like of float
    cage_v : (k, 3) array_like of float
    cage_f : (m, 3) array_like of int
        Closed cage with outward normals.
    eps : float, default 1e-8
        The pseudo-code's tolerance for "on a vertex", "on a face" and "in a face's plane".
    dtype : numpy floating type, default float64
        Working precision (``np.longdouble`` gives a few more digits on x86).
    chunk : int, default 2048
        Points processed at once; memory is ``O(chunk * m)``.

    Returns
    -------
    weights : (n, k) ndarray of ``dtype``

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> w = mean_value_coordinates_textbook([[0.1, 0.2, -0.3]], v, f)
    >>> bool(np.allclose(w @ v, [[0.1, 0.2, -0.3]]))
    True
    """
    pts = np.asarray(points, dtype=dtype).reshape(-1, 3)
    cv = np.asarray(cage_v, dtype=dtype)
    f = np.asarray(cage_f, dtype=np.int64)
    out = np.zeros((len(pts), len(cv)), dtype=dtype)
    for start in range(0, len(pts), chunk):
        out[start:start + chunk] = _chunk(pts[start:start + chunk], cv, f, eps)
    return out


def _chunk(x, cv, f, eps):
    n, k = len(x), len(cv)
    pi = np.asarray(np.pi, dtype=cv.dtype)
    if cv.dtype == np.longdouble:
        pi = np.arccos(np.asarray(-1.0, dtype=np.longdouble))
    rel = cv[None, :, :] - x[:, None, :]                     # (n, k, 3)
    d = np.sqrt(np.einsum("nkc,nkc->nk", rel, rel))          # (n, k)
    on_vertex = d < eps
    u = rel / np.where(d > 0, d, 1)[:, :, None]
    uf = u[:, f, :]                                          # (n, m, 3, 3)
    df = d[:, f]                                             # (n, m, 3)
    nxt, prv = [1, 2, 0], [2, 0, 1]
    length = np.linalg.norm(uf[:, :, nxt] - uf[:, :, prv], axis=3)
    theta = 2 * np.arcsin(np.clip(length / 2, 0, 1))          # (n, m, 3)
    h = theta.sum(axis=2) / 2                                 # (n, m)
    sin_t = np.sin(theta)
    on_face = pi - h < eps
    with np.errstate(divide="ignore", invalid="ignore"):
        c = 2 * np.sin(h)[..., None] * np.sin(h[..., None] - theta) / (
            sin_t[:, :, nxt] * sin_t[:, :, prv]) - 1
        det = np.einsum("nmc,nmc->nm", uf[:, :, 0], np.cross(uf[:, :, 1], uf[:, :, 2]))
        s = np.sign(det)[..., None] * np.sqrt(np.clip(1 - c * c, 0, None))
        skip = np.any(np.abs(s) <= eps, axis=2) | ~np.all(np.isfinite(s), axis=2)
        num = theta - c[:, :, nxt] * theta[:, :, prv] - c[:, :, prv] * theta[:, :, nxt]
        wf = num / (df * sin_t[:, :, nxt] * s[:, :, prv])
    wf[skip | on_face] = 0
    w = np.zeros((n, k), dtype=cv.dtype)
    for i in range(3):
        np.add.at(w, (np.arange(n)[:, None], f[None, :, i]), wf[:, :, i])
    # points on a face: barycentric limit sin(theta_i) d_{i-1} d_{i+1}
    rows, faces = np.nonzero(on_face)
    for r, fi in zip(rows, faces):
        w[r] = 0
        bary = sin_t[r, fi] * df[r, fi, prv] * df[r, fi, nxt]
        w[r, f[fi]] = bary
    rows, cols = np.nonzero(on_vertex)
    w[rows] = 0
    w[rows, cols] = 1
    return w / w.sum(axis=1, keepdims=True)
