"""What each part of the character-cage fit and binding buys (issue 16): an ablation.

Every character of ``apps.humanoid_data`` (the 3 bodies sharing the template's rest pose,
the 6 novel characters) from the template's rest pose, and the 6 novel characters from each
reverse example (the template in a rest-like pose): 39 fits. Variants, all in one run:

- ``paper``: the paper's MVC consistency (``cagekit_learn.consistency``, torch gradients,
  L-BFGS, 300 evaluations, box alignment), nothing else;
- ``landmarks``: ``cagekit.transfer.character_cage`` with no enclosure round (the as-similar-as-
  possible landmark fit alone, with the self-contact barrier);
- ``full``: with the enclosure rounds (what ``cagekit transfer`` runs).

Printed per variant: valid cages (closed, no crossing face, every vertex inside), mean and
worst share of vertices outside, fits with crossing faces, median and worst seconds.

Then arms closing on the body: the template and the stocky body with their arms 45 to 84
degrees below the T (the hands reach the hips), each fitted, bound by plain mean value
coordinates, by :func:`cagekit.transfer.surface_binding.bind_surface` (``mended``) and with its
robust ARAP refinement (``refined``, the default of ``cagekit transfer``), and carried into
5 test poses by the pose rule: cage valid, share of vertices bound through folds, vertex error
against the truth in % of the height (mean, 99th percentile, largest).

Usage::

    python benchmarks/bench_character_cage.py [--data out/humanoid] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from apps import humanoid_data  # noqa: E402
from cagekit import io  # noqa: E402
from cagekit.errors import CageFitError  # noqa: E402
from cagekit.geometry.alignment import box_alignment  # noqa: E402
from cagekit.io.landmarks import load_landmarks, match_landmarks  # noqa: E402
from cagekit.transfer import character_cage as cc  # noqa: E402

VARIANTS = ("paper", "landmarks", "full")
#: (body, arms below the T in degrees) of the closing-arms sweep
SWEEP = [(body, arms) for body in ("template", "stocky")
         for arms in (-45, -60, -70, -76, -82, -84)]


def cases(data: Path):
    """(name, template (V, F), cage (V, F), template marks, character (V, F), marks)."""
    manifest = json.loads((data / "manifest.json").read_text())
    template = io.load_mesh(data / "template.obj")
    cage = io.load_mesh(data / "template_cage.obj")
    marks_t = load_landmarks(data / "template_landmarks.json")
    reverse = sorted((data / "reverse").glob("pose_??.obj"))
    for name in [*manifest["bodies"], *manifest["characters"]]:
        picked = data / "characters" / f"{name}.picked"
        marks = load_landmarks(picked if picked.exists()
                               else data / "characters" / f"{name}_landmarks.json")
        character = io.load_mesh(data / "characters" / f"{name}.obj")
        yield f"{name} forward", template, cage, marks_t, character, marks
        if name in manifest["bodies"]:
            continue
        for path in reverse:
            yield (f"{name} {path.stem}", io.load_mesh(path),
                   io.load_mesh(path.with_name(f"{path.stem}_cage.obj")),
                   load_landmarks(path.with_name(f"{path.stem}_landmarks.json")), character,
                   marks)


def fit(variant, cage, P, Q, X, alignment):
    """(cage_v in the character's frame, seconds); CageFitError's cage when refused."""
    t0 = time.perf_counter()
    if variant == "paper":
        from cagekit_learn.consistency import fit_cage_by_consistency

        C = fit_cage_by_consistency(cage[0], cage[1], P, Q, alignment=alignment).cage_v
        return C, time.perf_counter() - t0
    options = {"landmarks": {"rounds": 0}, "full": {}}[variant]
    try:
        C = cc.fit_character_cage(cage[0], cage[1], P, Q, X, alignment=alignment,
                                  **options).cage_v
    except CageFitError as exc:
        C = exc.cage[0]
    return C, time.perf_counter() - t0


def arms_sweep(poses: int = 5) -> list[dict]:
    """The closing-arms sweep (module docstring): one row per body and angle."""
    from cagekit.coords import bind
    from cagekit.datasets import characters, humanoid
    from cagekit.transfer import character as dt
    from cagekit.transfer.rules import transfer_cage
    from cagekit.transfer.surface_binding import bind_surface

    rig = humanoid.rig("template")
    cage_v, cage_f = humanoid_data.template_cage(rig)
    marks_t = humanoid_data.landmarks_of(rig, humanoid.LANDMARK_NAMES)
    rotations = [humanoid.random_pose(humanoid_data.TEST_POSE_SEED + i) for i in range(poses)]
    fitter = dt.classical_fitter(rig.vertices, cage_v, cage_f)
    posed_cages = [fitter(rig.pose(r)) for r in rotations]
    rows = []
    print("\narms closing on the body: pose-rule error % height, mean / 99th percentile / "
          "largest vertex, over 5 poses")
    print(f"{'body':<9} {'arms':>5} {'cage':>6} {'seconds':>8} {'coupled %':>10} "
          f"{'mvc':>18} {'mended':>18} {'refined':>18}")
    for body, arms in SWEEP:
        name = f"{body}_arms{arms}"
        characters.CHARACTERS[name] = (body, 0.9, {"arms": arms}, "remeshed")
        try:
            char = characters.character(name)
        finally:
            del characters.CHARACTERS[name]
        marks_c = {m.label: np.array(m.position) for m in char.landmarks}
        match = match_landmarks(marks_t, marks_c)
        A = box_alignment(rig.vertices, char.vertices)
        t0 = time.perf_counter()
        try:
            fit = cc.fit_character_cage(cage_v, cage_f, match.source, match.target,
                                        char.vertices, alignment=A)
        except CageFitError as exc:
            rows.append({"body": body, "arms": arms, "valid": False, "error": str(exc)})
            print(f"{body:<9} {arms:>5} {'none':>6}  {exc}")
            continue
        seconds = time.perf_counter() - t0
        W = bind(char.vertices, fit.cage_v, fit.cage_f, check=False).weights
        mended = bind_surface(char.vertices, char.faces, fit.cage_v, fit.cage_f, weights=W)
        height = float(np.ptp(char.vertices[:, 1]))
        row = {"body": body, "arms": arms, "valid": True, "seconds": seconds,
               "coupled": mended.coupled, "mended": float(mended.mended.mean())}
        for label, deform in (("mvc", partial(np.matmul, W)),
                              ("mended", partial(mended.deform, refine=False)),
                              ("refined", mended.deform)):
            err = np.concatenate([
                np.linalg.norm(deform(transfer_cage("pose", cage_v, C, fit.cage_v, fit.cage_f,
                                                    A)) - char.truth(r), axis=1)
                for r, C in zip(rotations, posed_cages)]) / height * 100
            row[label] = {"mean": float(err.mean()), "p99": float(np.quantile(err, 0.99)),
                          "max": float(err.max())}
        rows.append(row)
        cells = [f"{row[k]['mean']:.2f} / {row[k]['p99']:.1f} / {row[k]['max']:.1f}"
                 for k in ("mvc", "mended", "refined")]
        print(f"{body:<9} {arms:>5} {'valid':>6} {seconds:>8.1f} "
              f"{100 * row['coupled']:>10.2f} {cells[0]:>18} {cells[1]:>18} {cells[2]:>18}",
              flush=True)
    return rows


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", default="out/humanoid", type=Path)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    if not (args.data / "manifest.json").exists():
        humanoid_data.write(args.data)
    rows = []
    for name, template, cage, marks_t, character, marks_c in cases(args.data):
        match = match_landmarks(marks_t, marks_c)
        alignment = box_alignment(template[0], character[0])
        for variant in VARIANTS:
            C, seconds = fit(variant, cage, match.source, match.target, character[0],
                             alignment)
            checks = cc.cage_checks(character[0], C, cage[1])
            rows.append({"case": name, "variant": variant, "seconds": seconds,
                         "valid": checks["valid"], "outside": checks["outside"],
                         "crossing": checks["self_intersecting_faces"]})
        print(name, " ".join(f"{r['variant']}:{'ok' if r['valid'] else 'bad'}"
                             for r in rows[-len(VARIANTS):]), flush=True)
    print(f"\n{len(rows) // len(VARIANTS)} fits")
    print(f"{'variant':<10} {'valid':>6} {'outside mean %':>15} {'worst %':>8} "
          f"{'crossing fits':>14} {'median s':>9} {'worst s':>8}")
    summary = {}
    for variant in VARIANTS:
        sel = [r for r in rows if r["variant"] == variant]
        summary[variant] = s = {
            "valid": sum(r["valid"] for r in sel), "fits": len(sel),
            "outside_mean": 100 * float(np.mean([r["outside"] for r in sel])),
            "outside_worst": 100 * max(r["outside"] for r in sel),
            "crossing_fits": sum(r["crossing"] > 0 for r in sel),
            "median_seconds": float(np.median([r["seconds"] for r in sel])),
            "worst_seconds": max(r["seconds"] for r in sel)}
        print(f"{variant:<10} {s['valid']:>3}/{s['fits']:<2} {s['outside_mean']:>15.2f} "
              f"{s['outside_worst']:>8.2f} {s['crossing_fits']:>14} "
              f"{s['median_seconds']:>9.2f} {s['worst_seconds']:>8.2f}")
    result = {"rows": rows, "summary": summary, "arms_sweep": arms_sweep()}
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
