"""A mesh bound to a cage that folds between its touching parts: MVC mended along the surface.

Where a character's limb hangs against its body, its cage must fold between them: two walls
a hair apart. Mean value coordinates see through such a fold (the two walls' contributions
nearly cancel), so a point of the limb gets large positive weights on its own wall and large
negative ones on the body's; when the limb moves away the point follows it several times
over and the deformed mesh grows spikes. ``sum_j max(0, -w_j)``, the negative mass of a
point's coordinates, tells such points (:func:`negative_mass`): it stays well below 1 where
the cage's parts are apart.

:func:`bind_surface` keeps mean value coordinates wherever the negative mass is small and,
on the points where it exceeds :data:`FREE_MASS`, replaces them by a smooth blend along the
mesh's own edges (the limb's surface is connected to the limb, not to the body it touches):
a graph-harmonic fit pulled towards each point's own coordinates with a confidence that
falls with its negative mass. Rows still sum to one, so the blend is affine-invariant. The
points' distance to the blend (their detail, ``offsets``) is carried in the frame of their
one-ring, turned with it (and scaled with the whole cage: a ring's own stretch is unreliable
where the blend squeezes a part to a sliver): the rest cage gives back every point exactly,
and a similarity of the cage moves every point by that similarity. :func:`check_coupling` warns
when the mending was needed and refuses a binding where it is most of the mesh.

What the coordinates cannot see (a coat's side inside the arm's tube follows the arm) shows
only once the cage moves: :meth:`SurfaceBinding.deform` then takes the cage's result as a
proposal for :func:`cagekit.transfer.robust_arap.robust_arap`, which keeps the mesh locally
rigid and lets a patch that disagrees with the surface around it follow its neighbours
(mended points start with little trust).

With ``coords="green"`` the points left alone follow the cage by Green coordinates (details
keep their proportions where the cage stretches); the mended points keep the MVC blend
above, which is what lets them ignore a fold (Green coordinates see through one as MVC do).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cagekit.cage import unique_edges
from cagekit.coords import GreenBinding, bind
from cagekit.errors import CageFitError, CagekitWarning, InputError
from cagekit.geometry import as_vertices, uniform_laplacian, vertex_rotations
from cagekit.transfer.robust_arap import robust_arap
from cagekit.typed import Floats, Vertices

__all__ = ["SurfaceBinding", "bind_surface", "negative_mass", "coupled_share",
           "check_coupling", "FREE_MASS", "CONFIDENCE_SCALE", "DATA_WEIGHT", "WARN_COUPLED",
           "MAX_COUPLED", "REFINE_SIGMA", "MENDED_TRUST"]

#: points whose negative mass is at most this keep their mean value coordinates exactly
FREE_MASS = 0.25
#: negative mass at which the confidence in a point's own coordinates falls to 1/e
CONFIDENCE_SCALE = 0.3
#: weight of the pull towards a confident point's own coordinates against the mesh
#: Laplacian (uniform, so a vertex of degree 6 weighs 6 there)
DATA_WEIGHT = 100.0
#: share of points with a negative mass above 1 above which :func:`check_coupling` warns
WARN_COUPLED = 0.001
#: share of points bound through folds (:func:`coupled_share`, the report's ``coupled``)
#: above which it refuses; the share mended along the mesh (``mended``: negative mass above
#: :data:`FREE_MASS`) is larger and has no limit
MAX_COUPLED = 0.2
#: disagreement with the cage's result, as a share of the moved cage's size (the RMS
#: distance of its vertices to their centroid), at which :meth:`SurfaceBinding.deform`
#: halves a point's trust in it (a humanoid's cage: about 2% of its height)
REFINE_SIGMA = 0.05
#: prior trust of a mended point's cage result (the others start at 1)
MENDED_TRUST = 0.05


def negative_mass(weights: ArrayLike) -> Floats:
    """``sum_j max(0, -w_j)`` per row.

    Parameters
    ----------
    weights : (n, k) array_like of float

    Returns
    -------
    (n,) float64

    Examples
    --------
    >>> negative_mass(np.array([[0.5, 0.5], [2.5, -1.5]])).tolist()
    [0.0, 1.5]
    """
    return np.maximum(-np.asarray(weights, dtype=np.float64), 0.0).sum(axis=1)


def coupled_share(weights: ArrayLike) -> float:
    """The share of rows whose negative mass exceeds 1 (points bound through a fold).

    Examples
    --------
    >>> round(coupled_share(np.array([[0.5, 0.5], [2.5, -1.5], [1.2, -0.2]])), 4)
    0.3333
    """
    return float(np.mean(negative_mass(weights) > 1.0))


@dataclass
class SurfaceBinding:
    """Mesh vertices bound to a cage, mended where the cage folds between touching parts.

    Attributes
    ----------
    weights : (n, k) float64
        Mean value coordinates, replaced on the mended points; rows sum to one.
    offsets : (n, 3) float64
        ``vertices - weights @ cage_v``, zero on the points left alone.
    mended : (n,) bool
        The points whose negative mass exceeded :data:`FREE_MASS`.
    coupled : float
        :func:`coupled_share` of the mean value coordinates.
    edges : (e, 2) int64
        The mesh's edges, each once (``unique_edges(faces)`` without degenerate ones): the
        offsets' frames and the refinement's.
    rest_base : (n, 3) float64
        ``weights @ cage_v`` of the rest cage.
    rest_cage : (k, 3) float64
        The cage bound to.
    rest_vertices : (n, 3) float64
        The mesh bound.
    faces : (m, 3) int64
        Its triangles.
    green : cagekit.coords.GreenBinding or None
        With ``coords="green"``: the points not mended, in Green coordinates (the rows of
        ``~mended``, in order); None: every point follows ``weights``.
    """

    weights: np.ndarray
    offsets: np.ndarray
    mended: np.ndarray
    coupled: float
    edges: np.ndarray
    rest_base: np.ndarray
    rest_cage: np.ndarray
    rest_vertices: np.ndarray
    faces: np.ndarray
    green: GreenBinding | None = None

    def deform(self, cage_v: ArrayLike, *, refine: bool = True) -> Vertices:
        """The mesh for the cage moved.

        Parameters
        ----------
        cage_v : (k, 3) array_like of float
        refine : bool, default True
            Pass the cage's result through :func:`cagekit.transfer.robust_arap.robust_arap`
            (``sigma`` :data:`REFINE_SIGMA` of the moved cage's size, mended points trusted
            :data:`MENDED_TRUST`); False gives the cage's result itself.

        Returns
        -------
        (n, 3) float64
        """

        C = np.asarray(cage_v, dtype=np.float64)
        out = self.weights @ C
        if self.green is not None:
            out[~self.mended] = self.green.deform(C)
        scale = _cage_scale(self.rest_cage, C)
        if self.mended.any():
            idx = np.flatnonzero(self.mended)
            R = vertex_rotations(self.rest_base, out, self.edges)[idx]
            out[idx] += scale * np.einsum("vij,vj->vi", R, self.offsets[idx])
        if not refine or not len(self.faces):
            return out
        return robust_arap(self.rest_vertices, self.faces, out,
                           sigma=REFINE_SIGMA * _rms_radius(C), scale=scale,
                           confidence=np.where(self.mended, MENDED_TRUST, 1.0),
                           edges=self.edges).vertices


def bind_surface(vertices: ArrayLike, faces: ArrayLike, cage_v: ArrayLike, cage_f: ArrayLike, *,
                 weights: ArrayLike | None = None, coords: str = "mvc") -> SurfaceBinding:
    """Bind a mesh to a cage, mending its coordinates where the cage folds.

    Parameters
    ----------
    vertices : (n, 3) array_like of float
        Inside the cage (:func:`cagekit.bind` warns of points outside).
    faces : (m, 3) array_like of int
        The mesh's faces (its edges carry the mending; a point cloud, ``m = 0``, keeps its
        mean value coordinates).
    cage_v : (k, 3) array_like of float
    cage_f : (f, 3) array_like of int
    weights : (n, k) array_like of float, optional
        The mean value coordinates of ``vertices``, when already computed.
    coords : {"mvc", "green"}, default "mvc"
        How the points that need no mending follow the cage: their mean value
        coordinates, or Green coordinates (``SurfaceBinding.green``). The mending, and
        the mended points, use mean value coordinates either way.

    Returns
    -------
    SurfaceBinding

    Examples
    --------
    >>> from cagekit.cage.shapes import box_cage
    >>> v, f = box_cage()
    >>> points = np.array([[0.1, 0.2, 0.3], [0.0, -0.5, 0.2], [0.4, 0.1, -0.6]])
    >>> b = bind_surface(points, np.array([[0, 1, 2]]), v, f)
    >>> bool(b.mended.any()), bool(np.allclose(b.deform(2 * v), 2 * points))
    (False, True)
    """

    V = as_vertices(vertices, "vertices")
    C = as_vertices(cage_v, "cage_v")
    F = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    W = (bind(V, C, cage_f).weights if weights is None
         else np.array(weights, dtype=np.float64))
    mass = negative_mass(W)
    coupled = float(np.mean(mass > 1.0))
    edges = unique_edges(F)
    edges = edges[edges[:, 0] != edges[:, 1]]
    mended = (mass > FREE_MASS) & (len(edges) > 0)
    if mended.any():
        W = _mend(W, mass, mended, edges)
    base = W @ C
    offsets = np.where(mended[:, None], V - base, 0.0)
    green = None
    if coords == "green":
        green = bind(V[~mended], C, cage_f, method="green", check=False)
    elif coords != "mvc":
        raise InputError(f"unknown coordinates {coords!r}; available: mvc, green")
    return SurfaceBinding(weights=W, offsets=offsets, mended=mended, coupled=coupled,
                          edges=edges, rest_base=base, rest_cage=C, rest_vertices=V,
                          faces=F, green=green)


def _mend(W, mass, mended, edges) -> np.ndarray:
    """Replace the rows of ``mended`` by the minimiser of the uniform graph Dirichlet
    energy plus ``DATA_WEIGHT * c_v |w_v - W_v|^2`` (``c_v`` the confidence), the other
    rows fixed: ``(L_BB + DATA_WEIGHT C_B) W_B = -L_BG W_G + DATA_WEIGHT C_B W_B``."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    L = uniform_laplacian(len(W), edges)
    B = np.flatnonzero(mended)
    G = np.flatnonzero(~mended)
    confidence = np.maximum(np.exp(-(mass[B] / CONFIDENCE_SCALE) ** 2), 1e-6)
    K = (L[B][:, B] + sp.diags(DATA_WEIGHT * confidence)).tocsc()
    rhs = DATA_WEIGHT * confidence[:, None] * W[B] - L[B][:, G] @ W[G]
    out = W.copy()
    out[B] = splu(K).solve(np.asarray(rhs))
    return out


def _rms_radius(points) -> float:
    """The root-mean-square distance of ``points`` to their centroid."""
    return float(np.sqrt(((points - points.mean(axis=0)) ** 2).sum(axis=1).mean()))


def _cage_scale(rest_cage, cage_v) -> float:
    """The cage's overall change of size (of its :func:`_rms_radius`)."""
    before = _rms_radius(rest_cage)
    return _rms_radius(cage_v) / before if before > 0 else 1.0


def check_coupling(binding: SurfaceBinding) -> float:
    """Warn when a binding had to be mended, refuse one that is mostly mended.

    Parameters
    ----------
    binding : SurfaceBinding

    Returns
    -------
    float
        ``binding.coupled``.

    Raises
    ------
    CageFitError
        ``binding.coupled`` above :data:`MAX_COUPLED`.
    """
    share = binding.coupled
    if share > MAX_COUPLED:
        raise CageFitError(
            f"the character's cage folds so thinly between touching parts that mean value "
            f"coordinates bind {100 * share:.1f}% of its vertices through the folds (at "
            f"most {100 * MAX_COUPLED:.0f}%): give the character a rest pose with its "
            "limbs apart from its body")
    if share > WARN_COUPLED:
        warnings.warn(CagekitWarning(
            f"{100 * share:.1f}% of the character's vertices are bound through folds of "
            f"its cage, where limbs touch the body (refused above {100 * MAX_COUPLED:.0f}%): "
            "they and their neighbours are mended along the mesh; expect stretched cloth "
            "or skin where they touched"), stacklevel=2)
    return share
