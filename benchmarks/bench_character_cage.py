"""What each part of the character-cage fit buys (issue 16): an ablation on the humanoid set.

Every character of ``apps.humanoid_data`` (the 3 bodies sharing the template's rest pose,
the 5 novel characters) from the template's rest pose, and the 5 novel characters from each
reverse example (the template in a rest-like pose): 33 fits. Variants, all in one run:

- ``paper``: the paper's MVC consistency (``cagekit_learn.consistency``, torch gradients,
  L-BFGS, 300 evaluations, box alignment), nothing else;
- ``landmarks``: ``cagekit.character_cage`` with no enclosure contacts and no repair
  (the as-similar-as-possible landmark fit alone);
- ``+contacts``: with the enclosure contacts, no repair;
- ``full``: contacts and the repair rounds (what ``cagekit transfer`` runs).

Printed per variant: valid cages (closed, no crossing face, every vertex inside), mean and
worst share of vertices outside, fits with crossing faces, median and worst seconds.

Usage::

    python benchmarks/bench_character_cage.py [--data out/humanoid] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from apps import humanoid_data  # noqa: E402
from cagekit import character_cage as cc  # noqa: E402
from cagekit import io  # noqa: E402
from cagekit.alignment import box_alignment  # noqa: E402
from cagekit.errors import CageFitError  # noqa: E402
from cagekit.landmarks import load_landmarks, match_landmarks  # noqa: E402

VARIANTS = ("paper", "landmarks", "+contacts", "full")


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
    options = {"landmarks": {"repair_rounds": 0}, "+contacts": {"repair_rounds": 0},
               "full": {}}[variant]
    weight = cc.CONTACT_WEIGHT
    if variant == "landmarks":
        cc.CONTACT_WEIGHT = 0.0
    try:
        C = cc.fit_character_cage(cage[0], cage[1], P, Q, X, alignment=alignment,
                                  **options).cage_v
    except CageFitError as exc:
        C = exc.cage[0]
    finally:
        cc.CONTACT_WEIGHT = weight
    return C, time.perf_counter() - t0


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
    result = {"rows": rows, "summary": summary}
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
