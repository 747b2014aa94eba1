"""Deformation transfer to novel characters, against ground truth (issue 6).

Three novel body shapes x 20 poses of :mod:`cagekit.datasets.humanoid`: the template's
pose is transferred to each body, and the result is compared with the body posed directly
with the same joint rotations (the ground truth). Methods, all in one run:

- ``rest``: no transfer (the body in rest pose);
- ``nearest``: the template's displacement copied from its nearest vertex (after the same
  box alignment the transfer uses), scaled like the transfer's offsets;
- ``classical``: the per-pair cage fit of the template onto the pose, transferred through
  the character's cage fitted by MVC consistency (:mod:`apps.deformation_transfer`);
- ``learned``: the same, with the template's cage deformation predicted by a fixed-source
  network (trained here with the documented command unless ``--model`` is given).

Printed per method: mean vertex error against the ground truth relative to the body's
height (%), dCotLap x1e3 (the metric of :mod:`cagekit.metrics`: the body at rest
normalised on its own, the result mapped by the ground truth's normalisation), and
seconds per pose (template cage + transfer; the character's cage fit is timed apart).

Usage::

    python benchmarks/bench_transfer.py [--data out/humanoid] [--model RUN_DIR]
        [--train-steps 6000] [--json out/bench_transfer.json] [--grid PNG]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from apps import deformation_transfer as dt  # noqa: E402
from apps import humanoid_data  # noqa: E402
from cagekit import io  # noqa: E402
from cagekit.frame import normalize
from cagekit.landmarks import load_landmarks  # noqa: E402
from cagekit.metrics import dcotlap  # noqa: E402
from cagekit_learn.train import load_model  # noqa: E402

METHODS = ("rest", "nearest", "classical", "learned")


def train_command(data: Path, run_dir: Path, steps: int, seed: int) -> list[str]:
    """The documented training command of the fixed-source humanoid model."""
    return [sys.executable, "-m", "cagekit.cli", "train", str(data / "train"),
            "--fixed-source", str(data / "template.obj"),
            "--source-cage", str(data / "template_cage.obj"), "--align", "l2",
            "--no-augment", "--no-box-align", "--lr", "3e-3", "--max-steps", str(steps),
            "--epochs", "1000", "--seed", str(seed), "-o", str(run_dir)]


def nearest_vertices(template_v, character_v, alignment) -> np.ndarray:
    """(n,) index of each character vertex's nearest template vertex (aligned frames)."""
    return cKDTree(template_v).query(alignment.invert(character_v))[1]


def nearest_copy(template_v, pose_v, character_v, alignment, nn) -> np.ndarray:
    """Each character vertex moves like its nearest template vertex ``nn``."""
    return character_v + alignment.apply_vectors(pose_v[nn] - template_v[nn])


def scores(rest_v, faces, truth_v, out_v) -> tuple[float, float]:
    """(mean vertex error / height in %, dCotLap x1e3)."""
    height = float(np.ptp(rest_v[:, 1]))
    err = float(np.linalg.norm(out_v - truth_v, axis=1).mean() / height * 100)
    src_n = normalize(rest_v)[0]
    _, c, s = normalize(truth_v)
    return err, dcotlap(src_n, faces, (out_v - c) / s) * 1e3


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", default="out/humanoid", type=Path)
    parser.add_argument("--model", default=None, type=Path,
                        help="A trained fixed-source run; default: train one in "
                             "DATA/run_<steps> (reused when there).")
    parser.add_argument("--train-steps", default=6000, type=int)
    parser.add_argument("--poses", default=20, type=int)
    parser.add_argument("--landmarks", default=80, type=int)
    parser.add_argument("--seed", default=0, type=int)
    parser.add_argument("--json", default=None)
    parser.add_argument("--grid", default=None, help="PNG: template poses, ground truth, "
                        "classical and learned transfers of the robot.")
    args = parser.parse_args(argv)
    data = args.data
    if not (data / "manifest.json").exists():
        t0 = time.perf_counter()
        humanoid_data.write(data, poses=args.poses, landmarks=args.landmarks,
                            seed=args.seed)
        print(f"wrote the data set to {data} in {time.perf_counter() - t0:.0f} s")
    run_dir = args.model or data / f"run_{args.train_steps}"
    train_seconds = None
    if not (Path(run_dir) / "checkpoint.pt").exists():
        command = train_command(data, Path(run_dir), args.train_steps, args.seed)
        print("training:", " ".join(command[1:]))
        t0 = time.perf_counter()
        subprocess.run(command, check=True)
        train_seconds = time.perf_counter() - t0
    model = load_model(run_dir)[0]

    Vt, Ft = io.load_mesh(data / "template.obj")
    cage_v, cage_f = io.load_mesh(data / "template_cage.obj")
    marks_t = load_landmarks(data / "template_landmarks.json")
    manifest = json.loads((data / "manifest.json").read_text())
    bodies = manifest["bodies"]
    poses = sorted((data / "poses").glob("pose_*.obj"))[:args.poses]

    deformed, timing = {"classical": [], "learned": []}, {"classical": [], "learned": []}
    pose_meshes = []
    fitter = dt.classical_fitter(Vt, cage_v, cage_f)
    for path in poses:
        Vp, Fp = io.load_mesh(path)
        pose_meshes.append((Vp, Fp))
        t0 = time.perf_counter()
        deformed["classical"].append(dt.template_cage_classical(
            (Vt, Ft), (cage_v, cage_f), (Vp, Fp), seed=args.seed, fitter=fitter))
        t1 = time.perf_counter()
        deformed["learned"].append(dt.template_cage_learned(model, Vt, cage_v, (Vp, Fp)))
        t2 = time.perf_counter()
        timing["classical"].append(t1 - t0)
        timing["learned"].append(t2 - t1)

    rows, fits, grid = [], {}, None
    for body in bodies:
        Vc, Fc = io.load_mesh(data / "characters" / f"{body}.obj")
        marks_c = load_landmarks(data / "characters" / f"{body}_landmarks.json")
        char = dt.fit_character(Vt, cage_v, cage_f, marks_t, Vc, Fc, marks_c)
        fit = char.fit
        fits[body] = {"seconds": fit.seconds, "loss": fit.loss, "mvc_term": fit.mvc_term,
                      "laplacian_term": fit.laplacian_term, "converged": fit.converged,
                      "evaluations": fit.evaluations, "landmarks": len(char.match.labels),
                      "max_landmark_error_pct": float(fit.landmark_errors.max()
                                                      / np.ptp(Vc[:, 1]) * 100)}
        nn = nearest_vertices(Vt, Vc, fit.alignment)
        shown = {name: [] for name in ("truth", "classical", "learned")}
        for i, (path, (Vp, _)) in enumerate(zip(poses, pose_meshes)):
            truth, _ = io.load_mesh(data / "truth" / body / path.name)
            outs = {}
            t0 = time.perf_counter()
            outs["rest"] = Vc
            t1 = time.perf_counter()
            outs["nearest"] = nearest_copy(Vt, Vp, Vc, fit.alignment, nn)
            t2 = time.perf_counter()
            extra = {"rest": t1 - t0, "nearest": t2 - t1}
            for method in ("classical", "learned"):
                t3 = time.perf_counter()
                outs[method] = dt.transfer(char, deformed[method][i])
                extra[method] = timing[method][i] + time.perf_counter() - t3
            for method in METHODS:
                err, dcl = scores(Vc, Fc, truth, outs[method])
                rows.append({"body": body, "pose": path.stem, "method": method,
                             "error_pct": err, "dcotlap_x1e3": dcl,
                             "seconds": extra[method]})
            if body == bodies[-1] and i < 5:
                shown["truth"].append((truth, Fc))
                shown["classical"].append((outs["classical"], Fc))
                shown["learned"].append((outs["learned"], Fc))
        if body == bodies[-1]:
            grid = shown

    print(f"\n{len(bodies)} bodies x {len(poses)} poses, {manifest['landmarks']} landmarks, "
          f"template cage {len(cage_v)} vertices / {len(cage_f)} faces; means")
    print(f"{'method':<10} {'error % height':>15} {'dCotLap x1e3':>13} {'s/pose':>8}")
    summary = {}
    for method in METHODS:
        sel = [r for r in rows if r["method"] == method]
        summary[method] = {k: float(np.mean([r[k] for r in sel]))
                           for k in ("error_pct", "dcotlap_x1e3", "seconds")}
        s = summary[method]
        print(f"{method:<10} {s['error_pct']:>15.3f} {s['dcotlap_x1e3']:>13.4f} "
              f"{s['seconds']:>8.3f}")
    print("\nper body (error % height: rest / nearest / classical / learned)")
    for body in bodies:
        errs = [np.mean([r["error_pct"] for r in rows
                         if r["body"] == body and r["method"] == m]) for m in METHODS]
        print(f"  {body:<8} " + " / ".join(f"{e:.3f}" for e in errs))
    print("\ncage fit by MVC consistency (per body)")
    for body, f in fits.items():
        print(f"  {body:<8} {f['seconds']:.2f} s, {f['evaluations']} evaluations, "
              f"L_consistency {f['loss']:.3g} (MVC {f['mvc_term']:.3g}, Laplacian "
              f"{f['laplacian_term']:.3g}), < 1e-5: {f['converged']}, max landmark error "
              f"{f['max_landmark_error_pct']:.2f}% of height")
    rest = summary["rest"]["error_pct"]
    checks = {
        "classical_3x_below_rest": summary["classical"]["error_pct"] * 3 <= rest,
        "learned_3x_below_rest": summary["learned"]["error_pct"] * 3 <= rest,
        "classical_dcotlap_below_nearest":
            summary["classical"]["dcotlap_x1e3"] < summary["nearest"]["dcotlap_x1e3"],
        "learned_dcotlap_below_nearest":
            summary["learned"]["dcotlap_x1e3"] < summary["nearest"]["dcotlap_x1e3"],
        "fit_under_10s": max(f["seconds"] for f in fits.values()) < 10.0,
    }
    print("\ntargets: " + ", ".join(f"{k} {'met' if v else 'MISSED'}"
                                    for k, v in checks.items()))
    if args.grid and grid is not None:
        dt.render_grid(args.grid, [pose_meshes[:5], grid["truth"], grid["classical"],
                                   grid["learned"]],
                       titles=[p.stem for p in poses[:5]],
                       labels=["template (input pose)", f"{bodies[-1]}: ground truth",
                               f"{bodies[-1]}: classical transfer",
                               f"{bodies[-1]}: learned transfer"])
        print(f"wrote {args.grid}")
    result = {"summary": summary, "fits": fits, "checks": checks, "rows": rows,
              "train_seconds": train_seconds, "model": str(run_dir),
              "train_command": " ".join(train_command(data, Path(run_dir), args.train_steps,
                                                      args.seed)[1:]),
              "cpu_count": os.cpu_count()}
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
