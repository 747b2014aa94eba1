"""Place 60 of the humanoid template's landmark labels on real characters (``data/characters/``).

For each character of Debian's ``sweethome3d-furniture`` named below, the template rig of
:mod:`cagekit.datasets.humanoid` is fitted to the character's surface (its height, a
width and depth scale, a centre, and the rest pose: arms raised or lowered, elbows, legs
apart; Powell on the symmetric Chamfer distance between the posed rig and 4,000 surface
samples; for each arm length of :data:`ARM_RATIOS`, the best kept: a long coat otherwise
draws the hands' landmarks down onto its hem), each wanted landmark of the fitted rig is
snapped to the nearest point of the character's surface that faces the same way (normals
within 70 degrees: an arm's inner point lands on the arm, not on the torso beside it), and
the points are written as a Thea ``.picked`` file (face index, barycentric coordinates,
label, position), the way a person clicking in Thea would. The template's own landmarks
of the same labels go to ``template.json`` (the vertices of ``apps.humanoid_data``'s
``template.obj`` that carry them), so that every label matches. A picture of each fit goes to
``out/characters/``. Run from the repository root::

    python data/place_character_landmarks.py          # writes data/characters/*.picked
                                                      # and template.json
    python data/place_character_landmarks.py --out DIR

Needs the package (``sudo apt-get install sweethome3d-furniture``); the models are CC BY
3.0, credited in ``data/README.md``. Deterministic (fixed sample seed).
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

#: catalog, model name (as the catalog names it), file stem written
CHARACTERS = (("Reallusion", "male02", "reallusion_male02"),
              ("Reallusion", "girlStanding", "reallusion_girl_standing"),
              ("KatorLegaz", "male-01-suit", "katorlegaz_male_01_suit"))
#: shoulder-to-wrist lengths tried (fractions of the height; the template's is 0.33)
ARM_RATIOS = (0.27, 0.30, 0.33)


def labels() -> list[str]:
    """The 60 labels placed (``cagekit.datasets.humanoid.PICKED_LANDMARK_NAMES``: 12 on
    the centre line, then 24 on the left and the same 24 on the right)."""
    from cagekit.datasets.humanoid import PICKED_LANDMARK_NAMES

    return list(PICKED_LANDMARK_NAMES)


def write_template(path: str) -> None:
    """The template's landmarks of :func:`labels` (JSON): the vertices of the humanoid
    template (``apps.humanoid_data``'s ``template.obj``, resolution 1) that carry them."""
    from cagekit.datasets import humanoid
    from cagekit.io.landmarks import save_landmarks

    rig = humanoid.rig("template")
    save_landmarks(path, {name: rig.vertices[rig.landmarks[name]] for name in labels()})


def find(catalog: str, stem: str):
    from cagekit.datasets.sweethome3d import models

    for model in models(catalogs=(catalog,)):
        if os.path.splitext(os.path.basename(model.path))[0] == stem:
            return model
    raise SystemExit(f"{catalog}/{stem} is not in the installed catalogs")


def fit_rig(V, F, seed: int = 0):
    """The template rig fitted to a character, the best of :data:`ARM_RATIOS`: (rig,
    parameters, posed rig vertices)."""
    from cagekit.geometry.sampling import sample_surface

    samples = sample_surface(V, F, 4000, seed=seed)  # the same for every arm length
    fits = [_fit_rig(V, samples, ratio) for ratio in ARM_RATIOS]
    for ratio, fit in zip(ARM_RATIOS, fits):
        print(f"  arm ratio {ratio}: Chamfer cost {fit[3]:.4g}")
    return min(fits, key=lambda fit: fit[3])[:3]


def _fit_rig(V, samples, arm_ratio: float):
    """(rig, parameters, posed rig vertices, Chamfer cost) for one arm length, against
    the character's surface samples."""
    from scipy.optimize import minimize
    from scipy.spatial import cKDTree

    from cagekit.datasets import characters, humanoid

    height = float(np.ptp(V[:, 1]))
    rig = humanoid.rig(humanoid.BodyShape(height=height, arm_ratio=arm_ratio),
                       resolution=0.5)
    tree = cKDTree(samples)
    centre = 0.5 * (V.max(axis=0) + V.min(axis=0))

    def posed(x):
        arms_l, arms_r, elbow_l, elbow_r, legs_l, legs_r, sx, sz, dx, dz = x
        pose = characters.rest_pose(arms=arms_l, legs=legs_l, elbows=elbow_l)
        right = characters.rest_pose(arms=arms_r, legs=legs_r, elbows=elbow_r)
        pose.update({k: v for k, v in right.items() if k.startswith("r_")})
        P = rig.pose(pose)
        c = 0.5 * (P.max(axis=0) + P.min(axis=0))
        P = (P - c) * np.array([sx, 1.0, sz]) + c
        return P + np.array([centre[0] - c[0] + dx, V[:, 1].min() - P[:, 1].min(),
                             centre[2] - c[2] + dz])

    def cost(x):
        P = posed(x)
        return (tree.query(P)[0] ** 2).mean() + (cKDTree(P).query(samples)[0] ** 2).mean()

    x0 = np.array([-60.0, -60.0, 10.0, 10.0, 5.0, 5.0, 1.0, 1.0, 0.0, 0.0])
    bounds = [(-85, 40)] * 2 + [(0, 120)] * 2 + [(-5, 30)] * 2 + [(0.6, 1.6)] * 2 \
        + [(-0.1 * height, 0.1 * height)] * 2
    best = minimize(cost, x0, method="Powell", bounds=bounds,
                    options={"maxfev": 4000, "xtol": 1e-3, "ftol": 1e-9})
    return rig, best.x, posed(best.x), float(best.fun)


def snap(V, F, points, normals, names, seed: int = 0):
    """SurfacePoint per name: the nearest surface point facing the same way (normals
    within 70 degrees), so that an arm's inner point lands on the arm, not the torso."""
    import igl
    from scipy.spatial import cKDTree

    from cagekit.geometry.sampling import sample_surface
    from cagekit.io.landmarks import SurfacePoint

    samples, faces = sample_surface(V, F, 200_000, seed=seed, return_faces=True)
    face_normals = np.asarray(igl.per_face_normals(V, F, np.array([0.0, 0.0, 1.0])))
    tree = cKDTree(samples)
    out = []
    for name, p, n in zip(names, points, normals):
        _, idx = tree.query(p, k=2000)
        ok = idx[face_normals[faces[idx]] @ n > np.cos(np.radians(70))]
        best = int(ok[0] if len(ok) else idx[0])
        f = int(faces[best])
        tri = V[F[f]]
        b = np.asarray(igl.barycentric_coordinates(samples[best][None], tri[0:1].copy(),
                                                   tri[1:2].copy(), tri[2:3].copy()))[0]
        b = np.clip(b, 0.0, 1.0)
        b /= b.sum()
        out.append(SurfacePoint(name, f, tuple(map(float, b)), tuple(map(float, b @ tri))))
    return out


def main(argv=None) -> None:
    from cagekit import io
    from cagekit.io.landmarks import save_picked
    from cagekit.render import render_meshes

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join(ROOT, "data", "characters"))
    parser.add_argument("--pictures", default=os.path.join(ROOT, "out", "characters"))
    args = parser.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    os.makedirs(args.pictures, exist_ok=True)
    names = labels()
    write_template(os.path.join(args.out, "template.json"))
    for catalog, stem, name in CHARACTERS:
        model = find(catalog, stem)
        V, F = io.load_mesh(model.path)
        rig, x, P = fit_rig(V, F)
        import igl

        index = [rig.landmarks[n] for n in names]
        normals = np.asarray(igl.per_vertex_normals(P, rig.faces))[index]
        points = snap(V, F, P[index], normals, names)
        save_picked(os.path.join(args.out, f"{name}.picked"), points)
        marks = np.array([p.position for p in points])
        render_meshes([(V, F), (P, rig.faces), (marks, None)],
                      os.path.join(args.pictures, f"{name}_landmarks.png"),
                      titles=[name, "fitted rig", "landmarks"], same_scale=True,
                      views=((10, -80),))
        print(f"{name}: {len(points)} landmarks; arms {x[0]:.0f}/{x[1]:.0f} deg, elbows "
              f"{x[2]:.0f}/{x[3]:.0f}, legs {x[4]:.0f}/{x[5]:.0f}, scale x {x[6]:.2f} z "
              f"{x[7]:.2f} ({model.credit})")


if __name__ == "__main__":
    main()
