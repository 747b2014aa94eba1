"""Learned cages against the per-pair methods, on held-out synthetic chairs.

Trains :mod:`cagekit_learn` (N_c + N_d, default settings, batch 8) on procedural chairs
(``cagekit.datasets.synthetic``, seeds 0..N-1) for a fixed CPU time budget, then on
held-out pairs of chairs the training never saw (seeds from 10,000 on) prints, per method,
the median CD x 10^2 and dCotLap x 10^3 (docs/architecture.md definitions, ``cagekit.evaluate``) and
seconds per pair:

- ``scale``: the bounding boxes mapped onto each other (``cagekit.deform(method="scale")``);
- ``cage``: the per-pair optimisation (``cagekit.deform``, 200-face fitted cage);
- ``learned``: one forward pass and the full mesh bound to the predicted cage, or the
  predicted cage box-scaled where that comes nearer the target (``cagekit deform
  --model``'s fall back; the count is printed);
- ``learned+refine``: the per-pair optimisation started from the prediction.

Then the training throughput (pairs per second at batch 8, measured over the whole
training), and the learned inference time for a ~10,000-vertex source (a chair at
resolution 1.55): the forward pass with sampling, and the full-mesh binding and
deformation, median of 5, the model already loaded.

Usage::

    python benchmarks/bench_learn.py [--minutes 20] [--train 300] [--pairs 50]
                                     [--run-dir DIR] [--reuse] [--json FILE]

``--reuse`` evaluates the checkpoint already in ``--run-dir`` instead of training.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np
import torch

import cagekit
from cagekit.datasets import synthetic
from cagekit_learn.data import ShapeCollection
from cagekit_learn.inference import deform_with_model
from cagekit_learn.train import TrainConfig, load_model, train

METHODS = ("scale", "cage", "learned", "learned+refine")
HELD_OUT_SEED = 10_000


def held_out_pairs(n_pairs):
    """``n_pairs`` (source, target) meshes from 2 n_pairs unseen chairs."""
    shapes = list(synthetic.family("chairs", 2 * n_pairs, seed=HELD_OUT_SEED))
    return [(shapes[2 * i], shapes[2 * i + 1]) for i in range(n_pairs)]


def run_method(name, model, source, target, points):
    start = time.perf_counter()
    if name in ("scale", "cage"):
        result = cagekit.deform(*source, *target, options=cagekit.DeformOptions(method=name))
    else:
        result = deform_with_model(model, *source, *target, points=points,
                                   refine=name == "learned+refine")
    seconds = time.perf_counter() - start
    figures = cagekit.evaluate(*source, *target, result.vertices)
    return {"cd_x1e2": figures.cd_x1e2, "dcotlap_x1e3": figures.dcotlap_x1e3,
            "seconds": seconds, "method": result.method}


def inference_timing(model, points, repeats=5):
    """Median seconds of the learned deformation of a ~10,000-vertex chair."""
    source = synthetic.chair(seed=HELD_OUT_SEED + 999, resolution=1.55)
    target = synthetic.chair(seed=HELD_OUT_SEED + 998)
    deform_with_model(model, *source, *target, points=points)  # warm up
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        deform_with_model(model, *source, *target, points=points)
        times.append(time.perf_counter() - start)
    return len(source[0]), float(np.median(times))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=20.0,
                        help="training time budget (default 20)")
    parser.add_argument("--train", type=int, default=300, help="training chairs")
    parser.add_argument("--pairs", type=int, default=50, help="held-out pairs")
    parser.add_argument("--run-dir", default="out/bench_learn")
    parser.add_argument("--reuse", action="store_true",
                        help="evaluate the checkpoint in --run-dir, do not train")
    parser.add_argument("--json", default=None, help="write all figures here")
    args = parser.parse_args(argv)
    torch.set_num_threads(max(1, os.cpu_count() or 1))
    info = {"threads": torch.get_num_threads(), "train_shapes": args.train}
    if not args.reuse:
        start = time.perf_counter()
        shapes = ShapeCollection.synthetic("chairs", args.train, seed=0, points=1024)
        info["sampling_seconds"] = time.perf_counter() - start
        if os.path.exists(os.path.join(args.run_dir, "checkpoint.pt")):
            os.remove(os.path.join(args.run_dir, "checkpoint.pt"))
        config = TrainConfig(data=f"synthetic:chairs:{args.train}", run_dir=args.run_dir,
                             epochs=100_000, batch_size=8, max_minutes=args.minutes,
                             device="cpu", checkpoint_every=500)
        result = train(config, progress=sys.stderr.isatty(), collection=shapes)
        info.update(steps=result.step, epochs=result.step * 8 / args.train,
                    train_seconds=result.seconds, pairs_per_second=result.pairs_per_second,
                    skipped=result.skipped, last_losses=result.last_losses)
        print(f"trained {result.step} steps ({info['epochs']:.1f} epochs of {args.train} "
              f"chairs) in {result.seconds / 60:.1f} min: {result.pairs_per_second:.1f} "
              f"pairs/s at batch 8, {result.skipped} skipped; last losses "
              + ", ".join(f"{k} {v:.4g}" for k, v in result.last_losses.items()))
    model, payload = load_model(args.run_dir)
    points = int(payload["config"]["points"])
    rows = {m: [] for m in METHODS}
    for i, (source, target) in enumerate(held_out_pairs(args.pairs)):
        for name in METHODS:
            rows[name].append(run_method(name, model, source, target, points))
        line = "  ".join(f"{m} {rows[m][-1]['cd_x1e2']:.3f}/{rows[m][-1]['dcotlap_x1e3']:.4f}"
                         for m in METHODS)
        print(f"pair {i:2d}: {line}", flush=True)
    medians = {m: {k: float(np.median([r[k] for r in rows[m]]))
                   for k in ("cd_x1e2", "dcotlap_x1e3", "seconds")} for m in METHODS}
    n_vertices, seconds = inference_timing(model, points)
    info.update(inference_vertices=n_vertices, inference_seconds=seconds)
    print(f"\n{args.pairs} held-out chair pairs, medians (CD x1e2, dCotLap x1e3, s/pair)")
    print(f"{'method':<16}{'CD x1e2':>10}{'dCotLap x1e3':>14}{'s/pair':>9}")
    for m in METHODS:
        r = medians[m]
        print(f"{m:<16}{r['cd_x1e2']:>10.3f}{r['dcotlap_x1e3']:>14.4f}{r['seconds']:>9.3f}")
    scale, cage = medians["scale"], medians["cage"]
    learned, refined = medians["learned"], medians["learned+refine"]
    print(f"\nlearned CD / scale CD = {learned['cd_x1e2'] / scale['cd_x1e2']:.2f} "
          "(target <= 0.8); learned handed on box scaling on "
          f"{sum(r['method'] == 'scale' for r in rows['learned'])} of {args.pairs} pairs")
    print(f"learned inference, {n_vertices}-vertex source: {seconds:.3f} s (target < 0.1)")
    print(f"learned+refine vs cage: CD {refined['cd_x1e2']:.3f} vs {cage['cd_x1e2']:.3f}, "
          f"dCotLap {refined['dcotlap_x1e3']:.4f} vs {cage['dcotlap_x1e3']:.4f} "
          "(target: CD no worse at equal or lower dCotLap)")
    if "pairs_per_second" in info:
        print(f"training throughput at batch 8: {info['pairs_per_second']:.1f} pairs/s "
              f"({info['threads']} threads)")
    if args.json:
        with open(args.json, "w") as handle:
            json.dump({"info": info, "medians": medians, "pairs": rows}, handle, indent=1)


if __name__ == "__main__":
    main()
