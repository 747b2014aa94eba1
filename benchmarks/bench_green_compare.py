"""Green coordinates against mean value coordinates on the same deformations, in one run.

(b) The variations benchmark: every pair of ``bench_deform.py`` (procedural chairs,
tables and vases; the CGAL animals; the real furniture of ``sweethome3d-furniture``),
``cagekit.deform`` with ``coords="mvc"`` and ``coords="green"`` on the same fitted cage:
CD x1e2, dCotLap x1e3, the worst part's non-affinity (%), planarity p95 (degrees), the
conformal distortion of the result's faces (:func:`cagekit.metrics.conformal_distortion`,
area-weighted mean of each face's singular-value ratio) and seconds; medians per group.

(c) A large articulation: a bumpy procedural limb (a cylinder with surface detail) in a
tube-shaped cage whose far half turns 90 degrees about the joint (each cage vertex
rotated by an angle that ramps from 0 to 90 degrees across the joint); the limb's
conformal distortion and its volume change under each coordinates; ``--picture`` draws
the rest limb and both results with their cages.

(a) The transfer benchmark: the characters of ``bench_transfer.py``'s data set
(``apps.humanoid_data``, written when missing), forward direction (template rest -> its
example poses, ground truth the character posed by the rig), each character's cage
fitted once and the character bound to it by each coordinates
(:func:`cagekit.transfer.surface_binding.bind_surface` with ``coords``); the pose rule on the
classical template cage, refined (the command's default) and unrefined (the cage's result
as it is): vertex error (% of height), dCotLap x1e3, the conformal distortion of the
result's faces, torn edges per mille.

Usage::

    python benchmarks/bench_green_compare.py [--cache /tmp/cgal] [--picture PNG]
        [--humanoid out/humanoid] [--poses 20] [--transfer-picture PNG]
        [--only limb|transfer|variations] [--json FILE]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))

from bench_deform import group, pairs  # noqa: E402

import cagekit  # noqa: E402
from cagekit.errors import InputError  # noqa: E402
from cagekit.metrics import conformal_distortion  # noqa: E402

COORDS = ("mvc", "green")
KEYS = ("cd", "dcotlap", "part_worst", "planar_p95", "conformal", "seconds")


def compare_pair(source, target, symmetry):
    """Both coordinates on one pair, the cage fitted once (by the MVC run; none given to it)."""
    rows, cage = {}, (None, None)
    for coords in COORDS:
        t0 = time.perf_counter()
        try:
            result = cagekit.deform(*source, *target, *cage,
                                    options=cagekit.DeformOptions(coords=coords,
                                                                  symmetry=symmetry, seed=0))
        except InputError as exc:
            print(f"  {coords} failed: {exc}", file=sys.stderr)
            rows[coords] = dict.fromkeys(KEYS, float("nan"))
            continue
        seconds = time.perf_counter() - t0
        cage = (result.cage_v, result.cage_f)
        figures = cagekit.evaluate(*source, *target, result.vertices)
        rows[coords] = {
            "cd": figures.cd_x1e2, "dcotlap": figures.dcotlap_x1e3,
            "part_worst": 100 * figures.part_nonaffinity_worst,
            "planar_p95": figures.planarity_p95_deg,
            "conformal": conformal_distortion(source[0], source[1], result.vertices)["mean"],
            "seconds": seconds}
    return rows


def variations(cache):
    rows = []
    header = "".join(f"{c + ' ' + k:>17}" for c in COORDS for k in KEYS)
    print(f"{'pair':<46}{header}")
    for name, source, target, symmetry in pairs(cache):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            row = compare_pair(source, target, symmetry)
        row["name"], row["group"] = name, group(name)
        rows.append(row)
        print(f"{name[:45]:<46}" + "".join(f"{row[c][k]:>17.3f}" for c in COORDS for k in KEYS),
              flush=True)
    print(f"\nmedians{'':<9}" + "".join(f"{k:>12}" for k in KEYS))
    for name in ("procedural", "animals", "real furniture"):
        sel = [r for r in rows if r["group"] == name]
        if not sel:
            continue
        for c in COORDS:
            print(f"{name + ' ' + c:<23}" + "".join(
                f"{np.nanmedian([r[c][k] for r in sel]):>12.3f}" for k in KEYS)
                + f"   ({len(sel)} pairs)")
    return rows


def limb(resolution: int = 48):
    """A bumpy cylinder along x (length 2, radius 0.2) and a tube cage around it."""
    import trimesh

    from cagekit.cage.shapes import box_cage

    mesh = trimesh.creation.cylinder(radius=0.2, height=2.0, sections=resolution)
    mesh = mesh.subdivide_to_size(0.04)
    V = np.asarray(mesh.vertices)[:, [2, 0, 1]]  # along x
    F = np.asarray(mesh.faces)
    normals = np.asarray(trimesh.Trimesh(V, F, process=False).vertex_normals)
    bumps = 0.015 * np.sin(18 * V[:, 0]) * np.sin(6 * np.arctan2(V[:, 2], V[:, 1]))
    V = V + bumps[:, None] * normals
    cage_v, cage_f = box_cage(8, half_extent=(1.15, 0.32, 0.32))
    return (V, F), (cage_v, cage_f)


def bend(points, degrees=90.0, half_width=0.25):
    """Rotate about the z axis through the origin by an angle that ramps from 0 (x <=
    -half_width) to ``degrees`` (x >= half_width)."""
    t = np.clip((points[:, 0] + half_width) / (2 * half_width), 0.0, 1.0)
    angle = np.radians(degrees) * (3 * t**2 - 2 * t**3)
    c, s = np.cos(angle), np.sin(angle)
    out = points.copy()
    out[:, 0] = c * points[:, 0] - s * points[:, 1]
    out[:, 1] = s * points[:, 0] + c * points[:, 1]
    return out


def articulation(picture=None):
    import trimesh

    (V, F), (cv, cf) = limb()
    moved = bend(cv)
    out = {"vertices": len(V), "cage_faces": len(cf)}
    results = {}
    rest_volume = trimesh.Trimesh(V, F, process=False).volume
    for coords in COORDS:
        deformed = cagekit.bind(V, cv, cf, method=coords).deform(moved)
        results[coords] = deformed
        distortion = conformal_distortion(V, F, deformed)
        volume = trimesh.Trimesh(deformed, F, process=False).volume / rest_volume
        out[coords] = {"conformal_mean": distortion["mean"], "conformal_p95": distortion["p95"],
                       "volume_ratio": volume}
        print(f"limb bent 90 degrees, {coords:<6}: conformal distortion mean "
              f"{distortion['mean']:.3f}, p95 {distortion['p95']:.3f}, max "
              f"{distortion['max']:.3f}; volume x{volume:.3f}")
    if picture:
        from cagekit.render import render_meshes

        render_meshes([(V, F), (results["mvc"], F), (results["green"], F)], picture,
                      cages=[(cv, cf), (moved, cf), (moved, cf)],
                      titles=["rest", f"MVC: conformal {out['mvc']['conformal_mean']:.2f}",
                              f"Green: conformal {out['green']['conformal_mean']:.2f}"],
                      size=(360, 360), views=((0, -90),), up="y")
        print(f"picture: {picture}")
    return out


def transfers(data: Path, poses: int, picture=None, shown="arms_down"):
    """(a): every character of the humanoid data set, forward, MVC beside Green;
    ``picture``: the ground truth, MVC's and Green's transfers (refined) of character
    ``shown`` in the first four poses."""
    import bench_transfer as bt

    from apps import humanoid_data
    from cagekit import io
    from cagekit.coords import bind
    from cagekit.io.landmarks import load_landmarks
    from cagekit.transfer import character as dt
    from cagekit.transfer.surface_binding import bind_surface

    if not (data / "manifest.json").exists():
        humanoid_data.write(data, seed=0)
    manifest = json.loads((data / "manifest.json").read_text())
    template = io.load_mesh(data / "template.obj")
    cage_v, cage_f = io.load_mesh(data / "template_cage.obj")
    marks_t = load_landmarks(data / "template_landmarks.json")
    pose_paths = sorted((data / "poses").glob("pose_???.obj"))[:poses]
    examples = [io.load_mesh(p) for p in pose_paths]
    cages = [c["classical"] for c in bt.template_cages(template, (cage_v, cage_f), examples,
                                                       None, 0)]
    methods = [(c, refine) for c in COORDS for refine in (True, False)]
    keys = ("error_pct", "dcotlap_x1e3", "conformal", "torn_permille", "seconds")
    rows, pictured = [], {}
    names = list(manifest["bodies"]) + list(manifest.get("characters", []))
    print(f"\n(a) transfer, forward, {len(examples)} poses: mean over poses")
    print(f"{'character':<12}{'method':<16}" + "".join(f"{k:>14}" for k in keys))
    for name in names:
        (Vc, Fc), marks_c = bt.load_character(data, name)
        truths = [io.load_mesh(data / "truth" / name / p.name)[0] for p in pose_paths]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                char = dt.fit_character(template[0], cage_v, cage_f, marks_t, Vc, Fc, marks_c)
            except Exception as exc:  # a character whose cage cannot be fitted: listed
                print(f"{name:<12}cage fit failed: {exc}")
                continue
            mvc = bind(Vc, char.cage_v, char.cage_f, check=False).weights  # as fit_character
            chars = {"mvc": char, "green": dataclasses.replace(char, binding=bind_surface(
                Vc, Fc, char.cage_v, char.cage_f, weights=mvc, coords="green"))}
            if picture and name == shown:
                pictured["truth"] = [(truth, Fc) for truth in truths[:4]]
            for coords, refine in methods:
                per = []
                for i, (cage, truth) in enumerate(zip(cages, truths)):
                    t0 = time.perf_counter()
                    X = dt.transfer(chars[coords], cage, "pose", refine=refine)
                    seconds = time.perf_counter() - t0
                    if picture and name == shown and refine and i < 4:
                        pictured.setdefault(coords, []).append((X, Fc))
                    per.append({**bt.scores(Vc, Fc, truth, X), "seconds": seconds,
                                "conformal": conformal_distortion(Vc, Fc, X)["mean"]})
                row = {k: float(np.mean([p[k] for p in per])) for k in keys}
                row.update(character=name, coords=coords, refine=refine)
                rows.append(row)
                method = f"{coords} {'refined' if refine else 'unrefined'}"
                print(f"{name:<12}{method:<16}" + "".join(f"{row[k]:>14.3f}" for k in keys),
                      flush=True)
    print(f"{'mean':<12}")
    for coords, refine in methods:
        sel = [r for r in rows if r["coords"] == coords and r["refine"] == refine]
        method = f"{coords} {'refined' if refine else 'unrefined'}"
        print(f"{'':<12}{method:<16}" + "".join(
            f"{np.mean([r[k] for r in sel]):>14.3f}" for k in keys))
    if pictured:
        dt.render_grid(picture, [pictured["truth"], pictured["mvc"], pictured["green"]],
                       titles=[p.stem for p in pose_paths[:4]],
                       labels=[f"{shown}: ground truth", "MVC (refined)", "Green (refined)"])
        print(f"picture: {picture}")
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", default="/tmp/cgal")
    parser.add_argument("--picture", default=None)
    parser.add_argument("--json", default=None)
    parser.add_argument("--humanoid", default="out/humanoid", type=Path)
    parser.add_argument("--poses", default=20, type=int)
    parser.add_argument("--transfer-picture", default=None)
    parser.add_argument("--only", choices=("limb", "transfer", "variations"), default=None)
    args = parser.parse_args()
    report = {}
    if args.only in (None, "limb"):
        report["articulation"] = articulation(args.picture)
    if args.only in (None, "transfer"):
        report["transfer"] = transfers(args.humanoid, args.poses, args.transfer_picture)
    if args.only in (None, "variations"):
        report["variations"] = variations(args.cache)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(report, fh, indent=1, default=float)


if __name__ == "__main__":
    main()
