"""A cage that cannot pass through itself while it moves: IPC barrier and safe steps.

Incremental Potential Contact (Li et al., SIGGRAPH 2020) keeps a moving triangle mesh free
of self-intersection with two parts: a log barrier on the distance between every pair of
non-adjacent elements closer than ``dhat`` (zero beyond, infinite at contact), and a
continuous collision check that shortens a step to the part of its straight path along
which nothing crosses. The IPC Toolkit (``ipctk``) computes both; :class:`SelfContact`
adapts it to a cage (vertices ``(k, 3)`` in, gradients ``(k, 3)``, a positive
semi-definite Hessian ``(3k, 3k)``), and :func:`minimise_with_contact` runs Newton on a
quadratic energy plus the barrier, so that a cage that starts free of self-intersection
stays free of it whatever the energy asks.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from cagekit.cage import self_intersecting_faces
from cagekit.typed import Floats, Vertices

if TYPE_CHECKING:
    import scipy.sparse

__all__ = ["SelfContact", "minimise_with_contact", "DHAT", "STIFFNESS"]

#: distance below which two elements of a cage repel, in cage diagonals
DHAT = 3e-3
#: barrier stiffness for energies of order one in a unit-diagonal frame (the barrier of
#: ipctk is in squared distances, about ``dhat**4`` at its widest: this makes its push at
#: half ``dhat`` comparable to a unit-weight quadratic pull over ``dhat``)
STIFFNESS = 1e6


class SelfContact:
    """The barrier and the collision-free step of one cage (fixed faces, moving vertices).

    Parameters
    ----------
    rest_v : (k, 3) array_like of float
        A configuration of the cage (for its connectivity only; ipctk's rest positions).
    faces : (m, 3) array_like of int
        Closed triangle cage.
    dhat : float, default :data:`DHAT`
        Activation distance of the barrier, in the units of the vertices.

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> contact = SelfContact(v, f, dhat=0.1)
    >>> contact.energy(v)
    0.0
    >>> squeezed = v * [1.0, 1.0, 0.01]       # top and bottom 0.02 apart: they repel
    >>> bool(contact.energy(squeezed) > 0)
    True
    >>> contact.max_step(v, v * [1.0, 1.0, -1.0]) < 0.5  # flipping passes through itself
    True
    """

    def __init__(self, rest_v: ArrayLike, faces: ArrayLike, dhat: float = DHAT) -> None:
        import ipctk

        # ipctk's threads sum the barrier's terms in varying orders: one thread makes a
        # result repeatable (a cage of a few hundred faces does not need more)
        ipctk.set_num_threads(1)
        self._ipc = ipctk
        self.faces = np.asarray(faces, dtype=np.int64)
        F = np.ascontiguousarray(faces, dtype=np.int32)
        self.mesh = ipctk.CollisionMesh(np.asfortranarray(rest_v, dtype=np.float64),
                                        np.asfortranarray(ipctk.edges(F)),
                                        np.asfortranarray(F))
        self.ccd = ipctk.AdditiveCCD()
        self.dhat = dhat

    @property
    def dhat(self) -> float:
        """Activation distance of the barrier (settable)."""
        return self._dhat

    @dhat.setter
    def dhat(self, value: float) -> None:
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"dhat must be a positive number, got {value!r}")
        self._dhat = float(value)
        self.potential = self._ipc.BarrierPotential(self._dhat, 1.0)

    def _collisions(self, V, reach=None):
        """The pairs of elements closer than ``reach`` (default ``dhat``)."""
        collisions = self._ipc.NormalCollisions()
        collisions.build(self.mesh, V, self.dhat if reach is None else reach)
        return collisions

    def clearance(self, cage_v: ArrayLike) -> float:
        """The smallest distance between two non-adjacent elements (0 where they touch).

        Examples
        --------
        >>> from cagekit.cage.shapes import box_cage
        >>> v, f = box_cage()
        >>> round(SelfContact(v, f, dhat=0.1).clearance(v * [1.0, 1.0, 0.25]), 3)
        0.485
        """
        V = np.asfortranarray(cage_v, dtype=np.float64)
        collisions = self._collisions(V, reach=float(np.linalg.norm(np.ptp(V, axis=0))))
        if len(collisions) == 0:
            return np.inf
        return float(np.sqrt(collisions.compute_minimum_distance(self.mesh, V)))

    def energy(self, cage_v: ArrayLike) -> float:
        """The barrier (0 when no two elements are within ``dhat``; inf at contact)."""
        V = np.asfortranarray(cage_v, dtype=np.float64)
        return float(self.potential(self._collisions(V), self.mesh, V))

    def gradient_and_hessian(self, cage_v: ArrayLike) -> tuple[Floats, scipy.sparse.spmatrix]:
        """``((k, 3) gradient, (3k, 3k) sparse Hessian projected to be PSD)``, rows in
        vertex order (x, y, z of vertex 0, then vertex 1, ...)."""
        V = np.asfortranarray(cage_v, dtype=np.float64)
        collisions = self._collisions(V)
        g = self.potential.gradient(collisions, self.mesh, V).reshape(-1, 3)
        H = self.potential.hessian(collisions, self.mesh, V,
                                   self._ipc.PSDProjectionMethod.CLAMP)
        return g, H

    def max_step(self, cage_v: ArrayLike, cage_v1: ArrayLike) -> float:
        """The largest ``t`` in [0, 1] such that the straight path from ``cage_v`` towards
        ``cage_v1`` is free of intersection up to ``t`` (conservative)."""
        return float(self._ipc.compute_collision_free_stepsize(
            self.mesh, np.asfortranarray(cage_v, dtype=np.float64),
            np.asfortranarray(cage_v1, dtype=np.float64), narrow_phase_ccd=self.ccd))

    def crosses(self, cage_v: ArrayLike) -> bool:
        """Whether two faces intersect (exact predicates,
        :func:`cagekit.cage.self_intersecting_faces`): the check behind every step."""

        return bool(self_intersecting_faces(cage_v, self.faces).any())


def minimise_with_contact(H: ArrayLike, b: ArrayLike, c0: float, start: ArrayLike,
                          contact: SelfContact, *, stiffness: float = STIFFNESS,
                          iterations: int = 2) -> Vertices:
    """Newton steps on ``tr(C^T H C) - 2 tr(C^T b) + c0 + stiffness * barrier(C)``.

    Every step is shortened to the collision-free part of its path (continuous collision
    detection) and then halved until the energy does not rise and the exact test finds no
    crossing at its end, so a start free of self-intersection gives a result free of it.

    Parameters
    ----------
    H : (k, k) array_like of float
        Symmetric positive semi-definite (the same matrix for x, y and z).
    b : (k, 3) array_like of float
    c0 : float
        The constant term (only for the energy's value in the line search).
    start : (k, 3) array_like of float
        Free of self-intersection.
    contact : SelfContact
    stiffness : float, default :data:`STIFFNESS`
    iterations : int, default 2

    Returns
    -------
    (k, 3) float64

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> contact = SelfContact(v, f, dhat=0.1)
    >>> # pull every vertex to the plane z = 0: the barrier keeps top and bottom apart
    >>> flat = v * [1.0, 1.0, 0.0]
    >>> C = minimise_with_contact(np.eye(8), flat, float((flat ** 2).sum()), v, contact,
    ...                           stiffness=1e3, iterations=30)
    >>> bool(0 < np.ptp(C[:, 2]) < 0.1)
    True
    """
    import scipy.sparse as sp
    from scipy.sparse.linalg import spsolve

    H = np.asarray(H, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    C = np.array(start, dtype=np.float64)
    quadratic = sp.kron(sp.csr_matrix(2.0 * H), sp.identity(3, format="csr"))

    def energy(X) -> float:
        return float(np.sum(X * (H @ X)) - 2.0 * np.sum(X * b) + c0
                     + stiffness * contact.energy(X))

    for _ in range(iterations):
        gb, Hb = contact.gradient_and_hessian(C)
        g = 2.0 * (H @ C - b) + stiffness * gb
        step = -spsolve((quadratic + stiffness * Hb).tocsc(), g.ravel()).reshape(C.shape)
        if not np.isfinite(step).all():
            break
        t = min(1.0, contact.max_step(C, C + step))
        before = energy(C)
        if not np.isfinite(before):
            break  # in contact already: no step can be told safe by the energy
        while t > 1e-10 and not (energy(C + t * step) <= before
                                 and not contact.crosses(C + t * step)):
            t *= 0.5
        if t <= 1e-10:
            break
        C = C + t * step
    return C
