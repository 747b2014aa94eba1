"""Make the bundled example: a fluted, bumpy vase, a coarse cage around it, a deformed cage.

Run from the repository root::

    python data/make_example.py            # writes data/example/{shape,cage,cage_deformed}.obj

Everything is procedural and deterministic (no randomness at all), so running the script
again reproduces the files: byte for byte on the same CPU, to the last digits elsewhere
(SIMD sin/cos and fused multiply-adds round differently; the test compares coordinates to
1e-9 of the extent). The shape is y-up, about 2 units tall.

- ``shape.obj``: a closed, watertight, outward-oriented surface of revolution (a vase or
  column) with 16 fluting ridges on its neck and a twisted band of knobs around its belly,
  so that a deformation visibly keeps (or ruins) fine detail. About 19k triangles.
- ``cage.obj``: a closed octagonal prism of six rings (50 vertices, 96 triangles, outward
  normals) that follows the profile loosely and encloses the shape with a margin.
- ``cage_deformed.obj``: the same cage (same vertex order, same faces) with its upper part
  bent sideways, its belly bulged and its top tapered.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np
from scipy.interpolate import PchipInterpolator

HEIGHT = 2.0  # y runs from -1 to 1
N_AROUND = 120  # vertices per ring of the shape
N_FLUTES = 16
N_KNOBS = 10  # knobs around the belly band
CAGE_SIDES = 8
CAGE_RINGS = 6

# (t, radius) control points of the profile, t = 0 at the foot, 1 at the lip
_PROFILE = np.array(
    [
        [0.00, 0.30],
        [0.04, 0.33],
        [0.10, 0.27],
        [0.38, 0.50],
        [0.62, 0.38],
        [0.78, 0.25],
        [0.92, 0.26],
        [1.00, 0.34],
    ]
)


def profile(t: np.ndarray) -> np.ndarray:
    """Base radius of the vase at height fraction ``t`` in [0, 1] (shape preserving spline)."""
    return PchipInterpolator(_PROFILE[:, 0], _PROFILE[:, 1])(t)


def _smoothstep(a: float, b: float, x: np.ndarray) -> np.ndarray:
    s = np.clip((x - a) / (b - a), 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def radius(t: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Radius of the detailed surface at height fraction ``t`` and angle ``theta``.

    The profile, plus fluting ridges on the neck (t in about [0.55, 0.9]) and a band of
    knobs around the belly whose rows twist around the axis.
    """
    base = profile(t)
    flute_weight = _smoothstep(0.52, 0.60, t) * (1.0 - _smoothstep(0.86, 0.92, t))
    flutes = 0.045 * flute_weight * np.abs(np.cos(0.5 * N_FLUTES * theta)) ** 0.6
    band = _smoothstep(0.20, 0.27, t) * (1.0 - _smoothstep(0.45, 0.52, t))
    twist = theta - 5.0 * t  # rows of knobs spiral around the belly
    knobs_around = (0.5 + 0.5 * np.cos(N_KNOBS * twist)) ** 3
    knobs_up = (0.5 + 0.5 * np.cos(2.0 * np.pi * (t - 0.235) / 0.1)) ** 2
    knobs = 0.06 * band * knobs_around * knobs_up
    return base * (1.0 + flutes) + knobs


def ring_heights() -> np.ndarray:
    """Height fractions of the shape's rings: denser across the band of knobs."""
    return np.concatenate(
        [
            np.linspace(0.00, 0.18, 13, endpoint=False),
            np.linspace(0.18, 0.54, 42, endpoint=False),
            np.linspace(0.54, 1.00, 26),
        ]
    )


def capped_tube_faces(n_rings: int, n_around: int) -> np.ndarray:
    """Outward triangles of a tube of rings closed by a fan at each end.

    Vertices are ``n_rings`` rings of ``n_around`` (bottom to top, counter-clockwise seen
    from above), then the bottom centre, then the top centre.

    Returns
    -------
    (2 * n_around * n_rings, 3) int64
    """
    bottom, top = n_rings * n_around, n_rings * n_around + 1

    def vid(i, j):
        return i * n_around + (j % n_around)

    faces = []
    for i in range(n_rings - 1):
        for j in range(n_around):
            a, b = vid(i, j), vid(i, j + 1)
            c, d = vid(i + 1, j + 1), vid(i + 1, j)
            faces.append((a, b, c))
            faces.append((a, c, d))
    for j in range(n_around):
        faces.append((bottom, vid(0, j + 1), vid(0, j)))
        faces.append((top, vid(n_rings - 1, j), vid(n_rings - 1, j + 1)))
    return np.asarray(faces, dtype=np.int64)


def make_shape() -> tuple[np.ndarray, np.ndarray]:
    """The vase: ``(V, F)``, ``(n, 3)`` float64 and ``(m, 3)`` int64, closed, outward."""
    t = ring_heights()
    n_rings = len(t)
    theta = np.linspace(0.0, 2.0 * np.pi, N_AROUND, endpoint=False)
    T, TH = np.meshgrid(t, theta, indexing="ij")  # (rings, around)
    R = radius(T, TH)
    y = -0.5 * HEIGHT + HEIGHT * T
    ring_v = np.stack([R * np.cos(TH), y, -R * np.sin(TH)], axis=-1).reshape(-1, 3)
    bottom = np.array([[0.0, -0.5 * HEIGHT, 0.0]])
    top = np.array([[0.0, 0.5 * HEIGHT, 0.0]])
    V = np.concatenate([ring_v, bottom, top], axis=0)
    return V, capped_tube_faces(n_rings, N_AROUND)


def make_cage(margin: float = 0.09) -> tuple[np.ndarray, np.ndarray]:
    """An octagonal prism of ``CAGE_RINGS`` rings that loosely follows the vase's profile.

    Each ring's circumradius is chosen so that the polygon's inscribed circle clears the
    widest part of the shape between the neighbouring rings by ``margin``.

    Returns
    -------
    V : (CAGE_RINGS * CAGE_SIDES + 2, 3) float64
        Rings bottom to top, ``CAGE_SIDES`` vertices each, then the bottom and top centres.
    F : (m, 3) int64
        Outward-oriented triangles.
    """
    t_ring = np.linspace(0.0, 1.0, CAGE_RINGS)
    fine_t = np.linspace(0.0, 1.0, 2001)
    fine_th = np.linspace(0.0, 2.0 * np.pi, 721)
    rmax = radius(fine_t[:, None], fine_th[None, :]).max(axis=1)
    spacing = t_ring[1] - t_ring[0]
    radii = []
    for t in t_ring:
        near = np.abs(fine_t - t) <= spacing
        radii.append((rmax[near].max() + margin) / np.cos(np.pi / CAGE_SIDES))
    radii = np.asarray(radii)
    y_ring = (-0.5 - margin / HEIGHT) * HEIGHT + (HEIGHT + 2 * margin) * t_ring
    phi = np.linspace(0.0, 2.0 * np.pi, CAGE_SIDES, endpoint=False) + np.pi / CAGE_SIDES
    ring_v = np.stack(
        [
            radii[:, None] * np.cos(phi)[None, :],
            np.repeat(y_ring[:, None], CAGE_SIDES, axis=1),
            -radii[:, None] * np.sin(phi)[None, :],
        ],
        axis=-1,
    ).reshape(-1, 3)
    V = np.concatenate([ring_v, [[0.0, y_ring[0], 0.0]], [[0.0, y_ring[-1], 0.0]]], axis=0)
    return V, capped_tube_faces(CAGE_RINGS, CAGE_SIDES)


def deform_cage(V: np.ndarray) -> np.ndarray:
    """Bend the upper half of the cage towards +x, bulge its belly, taper its top.

    Rings are scaled about the y axis first (bulge ring 2 by 1.3, taper the top two),
    then every point above ``y0`` is bent on a circular arc (a bend deformer about an axis
    parallel to z), 40 degrees in all from ``y0`` to the top.
    """
    V = np.array(V, dtype=np.float64, copy=True)
    scale = np.array([1.0, 1.0, 1.3, 1.05, 0.85, 0.72])[:CAGE_RINGS]
    ring_scale = np.concatenate([np.repeat(scale, CAGE_SIDES), [scale[0], scale[-1]]])
    V[:, 0] *= ring_scale
    V[:, 2] *= ring_scale

    y0 = -0.1
    y_top = V[:, 1].max()
    angle = np.radians(40.0)
    R = (y_top - y0) / angle  # arc radius so that the top turns by `angle`
    s = np.clip(V[:, 1] - y0, 0.0, None)
    phi = s / R
    x, y = V[:, 0].copy(), V[:, 1].copy()
    above = V[:, 1] > y0
    # spine point at angle phi: (R - R cos phi, y0 + R sin phi); local x: (cos phi, -sin phi)
    V[above, 0] = R - R * np.cos(phi[above]) + x[above] * np.cos(phi[above])
    V[above, 1] = y0 + R * np.sin(phi[above]) - x[above] * np.sin(phi[above])
    V[~above, 1] = y[~above]
    return V


def write_obj(path: str, V: np.ndarray, F: np.ndarray, comment: str) -> None:
    """Write a triangle mesh as OBJ with full float64 precision (``%.17g``), atomically."""
    lines = [f"# {comment}", f"# {len(V)} vertices, {len(F)} faces; made by data/make_example.py"]
    lines += [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in np.asarray(V, float).tolist()]
    lines += [f"f {a} {b} {c}" for a, b, c in (np.asarray(F, np.int64) + 1).tolist()]
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="ascii", newline="\n") as fh:
        fh.write("\n".join(lines) + "\n")
    os.replace(tmp, path)


def signed_volume(V: np.ndarray, F: np.ndarray) -> float:
    """Signed volume of a closed triangle mesh; positive when its normals point outward."""
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def check(shape, cage, deformed) -> None:
    """Raise AssertionError unless the files have the properties the tests and demo use.

    Both meshes closed (no boundary edge) and edge-manifold with positive volume; every
    shape vertex inside the cage (libigl winding number 1); the deformed cage still
    positively oriented.
    """
    import igl

    parts = {"shape": shape, "cage": cage, "deformed cage": (deformed, cage[1])}
    for name, (V, F) in parts.items():
        assert len(igl.boundary_facets(F)[0]) == 0, f"{name} is not closed"
        assert igl.is_edge_manifold(F)[0], f"{name} is not edge-manifold"
        assert signed_volume(V, F) > 0, f"{name} is not outward oriented"
    w = igl.winding_number(cage[0], cage[1], shape[0])
    assert np.all(np.abs(w - 1.0) < 1e-6), f"cage does not enclose the shape ({w.min()})"


def main(argv=None) -> int:
    """Write the three example files; return the exit status."""
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join(here, "example"),
                        help="output folder (default: data/example next to this script)")
    parser.add_argument("--no-check", action="store_true", help="skip the libigl checks")
    args = parser.parse_args(argv)
    shape = make_shape()
    cage = make_cage()
    deformed = deform_cage(cage[0])
    if not args.no_check:
        check(shape, cage, deformed)
    os.makedirs(args.out, exist_ok=True)
    write_obj(os.path.join(args.out, "shape.obj"), *shape,
              "cagekit example: a fluted vase with a twisted band of knobs (y-up)")
    write_obj(os.path.join(args.out, "cage.obj"), *cage,
              "cagekit example: an octagonal 6-ring cage enclosing shape.obj")
    write_obj(os.path.join(args.out, "cage_deformed.obj"), deformed, cage[1],
              "cagekit example: cage.obj bent, bulged and tapered (same vertices and faces)")
    print(f"wrote {args.out}/shape.obj ({len(shape[0])} vertices, {len(shape[1])} faces), "
          f"cage.obj and cage_deformed.obj ({len(cage[0])} vertices, {len(cage[1])} faces)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
