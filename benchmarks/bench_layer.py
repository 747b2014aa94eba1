"""Speed and accuracy of the differentiable MVC layer: compiled kernels, torch graph, paper.

Forward + backward of ``cagekit_learn.coords.mean_value_coordinates`` at the training
shape (issue 34): batch 8 x 1,024 points on the learned mode's template cage (the 42-vertex,
80-face icosphere of radius ``ModelConfig.template_radius``), points uniform in the
normalised box [-1, 1]^3, loss ``sum(G * W)`` with a fixed random ``G``. Rows:

- ``kernels``: the default on the CPU, :mod:`cagekit.coords.mvc_grad` through one autograd
  function (float64 inside for both dtypes);
- ``torch graph``: the same function with ``compiled_kernels(False)`` (the pure-torch graph,
  what CUDA tensors use; before issue 34 the CPU default too);
- ``paper formula``: the Neural Cages authors' approach, re-implemented here from Ju,
  Schaefer & Warren 2005 (their pseudo-code's ``theta_i = 2 asin(l_i / 2)``,
  ``c_i = 2 sin(h) sin(h - theta_i) / (sin theta_{i+1} sin theta_{i-1}) - 1``,
  ``s_i = sign(det) sqrt(1 - c_i^2)``, ``w_i += (theta_i - c_{i+1} theta_{i-1} - c_{i-1}
  theta_{i+1}) / (d_i sin(theta_{i+1}) s_{i-1})``), dense over (B, n, faces), faces with
  ``|s_i| <= eps`` skipped, no special rows.

Rates are point-face pairs per second (B x n x 80 / seconds), best of ``--repeats``; the
accuracy column is the largest weight error against the core's float64
:func:`cagekit.coords.mean_value_coordinates` on the same points (float32 inputs rounded
first).

``--train-steps N`` then trains the default model ``N`` steps at batch 8 on procedural
chairs (``synthetic:chairs:64``, 1,024 points, seed 0), once with the compiled code (MVC
kernels, libigl in the enclosure term) and once with the torch graph alone, and prints
each run's pairs/s and how far their logged losses differ: over the first 10 steps, and
between means over 20 steps (issue 34: training throughput, training curves unchanged).

Usage::

    python benchmarks/bench_layer.py [--repeats 5] [--threads N] [--train-steps 60]
        [--json FILE]
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import platform
import tempfile
import time

import numpy as np
import torch

from cagekit.cage.fitting import template_cage
from cagekit.coords import mean_value_coordinates as core_mvc
from cagekit_learn.coords import compiled_kernels, mean_value_coordinates
from cagekit_learn.networks import ModelConfig


def paper_mvc(points: torch.Tensor, cage_v: torch.Tensor, faces: torch.Tensor,
              eps: float = 1e-8) -> torch.Tensor:
    """Ju et al.'s MVC pseudo-code in torch: (B, n, 3), (B, k, 3), (m, 3) -> (B, n, k)."""
    B, n, _ = points.shape
    k = cage_v.shape[1]
    tri = cage_v[:, faces]                                             # (B, m, 3, 3)
    a = tri.unsqueeze(1) - points[:, :, None, None, :]                 # (B, n, m, 3, 3)
    d = a.norm(dim=-1)                                                 # (B, n, m, 3)
    u = a / d.unsqueeze(-1)
    nxt = [1, 2, 0]
    prv = [2, 0, 1]
    length = (u[..., nxt, :] - u[..., prv, :]).norm(dim=-1)            # l_i
    theta = 2.0 * torch.asin((length / 2).clamp(max=1.0))
    h = theta.sum(-1, keepdim=True) / 2
    sin_t = torch.sin(theta)
    c = (2 * torch.sin(h) * torch.sin(h - theta)) / (sin_t[..., nxt] * sin_t[..., prv]) - 1
    det = torch.linalg.det(u)                                          # (B, n, m)
    s = torch.sign(det).unsqueeze(-1) * torch.sqrt((1 - c * c).clamp(min=0.0))
    keep = (s.abs() > eps).all(-1, keepdim=True)
    s_safe = torch.where(keep, s, torch.ones_like(s))
    w = (theta - c[..., nxt] * theta[..., prv] - c[..., prv] * theta[..., nxt]) / (
        d * sin_t[..., nxt] * s_safe[..., prv])
    w = torch.where(keep, w, torch.zeros_like(w))
    W = torch.zeros(B, n, k, dtype=points.dtype).index_add_(
        2, faces.reshape(-1), w.reshape(B, n, -1))
    return W / W.sum(-1, keepdim=True)


def timed(fn, P, V, G, repeats):
    """Best seconds of forward + backward of ``sum(G * fn(P, V))``; the weights."""
    best = math.inf
    for _ in range(repeats + 1):  # the first call compiles / warms up
        p = P.detach().clone().requires_grad_()
        v = V.detach().clone().requires_grad_()
        start = time.perf_counter()
        w = fn(p, v)
        (w * G).sum().backward()
        best = min(best, time.perf_counter() - start)
    return best, w.detach()


def training_runs(steps: int) -> dict:
    """Pairs/s of ``steps`` training steps with the kernels and with the torch graph, and
    the largest relative difference of their logged losses at the same steps."""
    from cagekit_learn.train import TrainConfig, train

    runs, losses = {}, {}
    for name, enabled in (("kernels", True), ("torch graph", False)):
        with tempfile.TemporaryDirectory() as run_dir, compiled_kernels(enabled):
            config = TrainConfig(data="synthetic:chairs:64", run_dir=run_dir, seed=0,
                                 max_steps=steps, epochs=1_000_000)
            result = train(config, progress=False)
            with open(f"{run_dir}/log.csv", newline="") as handle:
                losses[name] = np.array([float(r["loss"]) for r in csv.DictReader(handle)])
        runs[name] = {"steps": result.step, "pairs_per_s": result.pairs_per_second}
    a, b = losses["kernels"], losses["torch graph"]
    window = min(20, len(a))
    means = [x[: len(x) // window * window].reshape(-1, window).mean(1) for x in (a, b)]
    return {"runs": runs,
            "first_10_steps_max_relative_loss_difference":
                float(np.max(np.abs(a[:10] - b[:10]) / np.abs(b[:10]))),
            "window": window,
            "window_means_max_relative_difference":
                float(np.max(np.abs(means[0] - means[1]) / np.abs(means[1])))}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--points", type=int, default=1024)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=None,
                        help="torch and numba threads (default: theirs)")
    parser.add_argument("--train-steps", type=int, default=0,
                        help="also time this many training steps each way")
    parser.add_argument("--json", default=None, help="write the figures here")
    args = parser.parse_args(argv)
    if args.threads:
        import numba
        torch.set_num_threads(args.threads)
        numba.set_num_threads(args.threads)

    v, f = template_cage()
    v = v * ModelConfig().template_radius
    rng = np.random.default_rng(0)
    pts = rng.uniform(-1.0, 1.0, (args.batch, args.points, 3))
    pairs = args.batch * args.points * len(f)
    faces_t = torch.as_tensor(f)

    def kernels(p, c):
        return mean_value_coordinates(p, c, f)

    def graph(p, c):
        with compiled_kernels(False):
            return mean_value_coordinates(p, c, f)

    def paper(p, c):
        return paper_mvc(p, c, faces_t)

    rows = []
    for dtype in (torch.float32, torch.float64):
        P = torch.tensor(pts, dtype=dtype)
        V = torch.tensor(np.broadcast_to(v, (args.batch,) + v.shape).copy(), dtype=dtype)
        G = torch.tensor(rng.normal(size=(args.batch, args.points, len(v))), dtype=dtype)
        p64 = P.double().numpy()
        ref = np.stack([core_mvc(p64[b], V[b].double().numpy(), f) for b in range(args.batch)])
        for name, fn in (("kernels", kernels), ("torch graph", graph), ("paper formula", paper)):
            seconds, w = timed(fn, P, V, G, args.repeats)
            err = float(np.nanmax(np.abs(w.double().numpy() - ref)))
            rows.append({"method": name, "dtype": str(dtype).removeprefix("torch."),
                         "ms": 1e3 * seconds, "mpairs_per_s": pairs / seconds / 1e6,
                         "max_weight_error": err,
                         "nonfinite_rows": int((~np.isfinite(w.numpy())).any(-1).sum())})

    print(f"MVC layer, forward + backward, batch {args.batch} x {args.points} points, "
          f"template cage ({len(v)} vertices, {len(f)} faces); "
          f"{platform.processor() or platform.machine()}, torch threads {torch.get_num_threads()}")
    print(f"{'method':<15} {'dtype':<8} {'ms':>9} {'M pairs/s':>10} {'max |W - core|':>15} "
          f"{'non-finite rows':>16}")
    for r in rows:
        print(f"{r['method']:<15} {r['dtype']:<8} {r['ms']:>9.1f} {r['mpairs_per_s']:>10.2f} "
              f"{r['max_weight_error']:>15.2e} {r['nonfinite_rows']:>16d}")
    base = {r["dtype"]: r["ms"] for r in rows if r["method"] == "torch graph"}
    for r in rows:
        if r["method"] == "kernels":
            print(f"kernels vs torch graph ({r['dtype']}): {base[r['dtype']] / r['ms']:.1f}x")
    training = training_runs(args.train_steps) if args.train_steps else None
    if training:
        runs = training["runs"]
        for name, run in runs.items():
            print(f"training, {name:<12} {run['steps']} steps, batch 8: "
                  f"{run['pairs_per_s']:.2f} pairs/s")
        print(f"training, kernels vs torch graph: "
              f"{runs['kernels']['pairs_per_s'] / runs['torch graph']['pairs_per_s']:.2f}x")
        print(f"training losses, kernels vs torch graph: the first 10 steps differ by "
              f"{training['first_10_steps_max_relative_loss_difference']:.1e} at most "
              f"(relative; rounding), means over {training['window']} steps by "
              f"{training['window_means_max_relative_difference']:.1%} (the runs part ways "
              f"later, as any two roundings of one SGD run do)")
    if args.json:
        with open(args.json, "w") as handle:
            json.dump({"rows": rows, "batch": args.batch, "points": args.points,
                       "training": training}, handle, indent=2)


if __name__ == "__main__":
    main()
