"""Seeded samples of shapes: the one place points are drawn from a surface or a cloud.

Faces are chosen with probability proportional to their area and a point uniformly inside
each, driven by a ``numpy.random.Generator`` made from the seed (the global random state is
never used). The draws are trimesh's (``trimesh.sample.sample_surface``: the same numbers
from the generator, in the same order, the same arithmetic), so the points are the ones
trimesh gives, bit for bit (a test checks it); they are written out here because importing
trimesh takes 0.3-0.5 s, most of the start-up of a command that samples a surface
(``cagekit deform``; issue 34). A point cloud stands for itself: its points, or a seeded
subset of them.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cagekit.errors import InputError
from cagekit.geometry import as_count, as_faces, as_vertices, face_areas

__all__ = ["sample_surface", "subset"]


def sample_surface(
    V: ArrayLike, F: ArrayLike | None, n: int = 5000, seed: int = 0, *,
    return_faces: bool = False, fill: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Points standing for a shape: area-uniform samples of a mesh, or a cloud's points.

    On a mesh a face is chosen with probability proportional to its area, then a point
    uniformly inside it, driven by ``numpy.random.default_rng(seed)`` (the global random
    state is not used); the points are those of ``trimesh.sample.sample_surface`` with
    that generator, bit for bit. A point
    cloud (no faces) is not resampled: its points, or a seeded subset of them.

    Parameters
    ----------
    V : array_like, shape (v, 3), float
        Vertex positions.
    F : array_like, shape (m, 3), int, or None
        Triangles with positive total area; ``None`` or empty for a point cloud.
    n : int, default 5000
        Number of samples: ``n >= 0`` on a mesh, ``n >= 1`` for a cloud.
    seed : int, optional
        Seed; the same inputs and seed give the same points.
    return_faces : bool, optional
        Also return the face each point lies on (meshes only).
    fill : bool, default False
        A cloud of fewer than ``n`` points gives exactly ``n`` all the same: its points
        drawn with replacement (training batches need equal sizes).

    Returns
    -------
    points : numpy.ndarray, shape (n, 3) or (v, 3), float64
        A mesh: ``n`` points uniform by area. A point cloud with ``v <= n`` points: the
        points themselves (``fill``: ``n`` of them, with replacement, when ``v < n``). A
        larger cloud: a seeded subset of ``n`` distinct points, in their original order
        (:func:`subset`).
    faces : numpy.ndarray, shape (n,), int64
        Only when ``return_faces`` is True: index into ``F`` of each point's face.

    Raises
    ------
    InputError
        Faces of zero total area, face areas that overflow (coordinates too large),
        ``return_faces`` for a cloud, a negative ``n``, or bad input.

    Examples
    --------
    >>> P, fi = sample_surface([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], 4,
    ...                        return_faces=True)
    >>> P.shape, fi.tolist()
    ((4, 3), [0, 0, 0, 0])
    >>> sample_surface([[0, 0, 0], [1, 0, 0], [0, 1, 0]], None, n=10).shape
    (3, 3)
    """
    V = as_vertices(V)
    F = as_faces(F, len(V))
    if len(F) == 0:
        if return_faces:
            raise InputError("a point cloud has no faces to return (return_faces)")
        return _cloud_samples(V, n, seed, fill)
    n = as_count(n, "n", 0)
    if not face_areas(V, F).sum() > 0.0:
        raise InputError("cannot sample a surface of zero total area")
    points, face_index = _area_uniform(V, F, n, np.random.default_rng(seed))
    points = np.ascontiguousarray(points, dtype=np.float64)
    if return_faces:
        return points, np.asarray(face_index, dtype=np.int64)
    return points


def _area_uniform(V: np.ndarray, F: np.ndarray, n: int,
                  rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``n`` area-uniform points of a mesh and their faces, as trimesh draws them.

    A face by inverting the cumulative areas at ``rng.random(n)`` times the total, then
    two lengths along its edges from the first vertex, reflected into the triangle when
    they sum past 1 (Weisstein's triangle point picking). Areas are half the norms of
    ``(b - a) x (c - b)``, as trimesh computes them, so that the same draws pick the same
    faces.
    """
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    area = np.sqrt((np.cross(b - a, c - b) ** 2).sum(axis=1)) / 2.0
    cumulative = np.cumsum(area)
    face = np.searchsorted(cumulative, rng.random(n) * cumulative[-1])
    lengths = rng.random((n, 2, 1))
    lengths[lengths.sum(axis=1).reshape(-1) > 1.0] -= 1.0
    lengths = np.abs(lengths)
    edges = np.stack([b - a, c - a], axis=1)[face]
    return (edges * lengths).sum(axis=1) + a[face], face


def _cloud_samples(V: np.ndarray, n: int, seed: int, fill: bool) -> np.ndarray:
    """A cloud's stand-in points: itself, a seeded subset, or (``fill``) ``n`` drawn."""
    n = as_count(n, "n", 1)
    rng = np.random.default_rng(seed)
    if len(V) < n and fill:
        return V[rng.integers(0, len(V), size=n)]
    if len(V) <= n:
        return V.copy()
    return V[subset(len(V), n, rng)]


def subset(n: int, limit: int, rng: np.random.Generator) -> np.ndarray:
    """Sorted indices of a seeded subset of ``range(n)`` of size ``min(n, limit)``.

    Parameters
    ----------
    n, limit : int
    rng : numpy.random.Generator

    Returns
    -------
    (min(n, limit),) int64, increasing; ``arange(n)`` when ``n <= limit``.

    Examples
    --------
    >>> subset(5, 10, np.random.default_rng(0)).tolist()
    [0, 1, 2, 3, 4]
    """
    if n <= limit:
        return np.arange(n)
    return np.sort(rng.choice(n, size=limit, replace=False))
