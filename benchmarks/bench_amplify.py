"""Stock amplification at scale: ``cagekit.batch.amplify`` on real chairs, 1 worker, 2 workers
and a local Dask cluster of 2 workers, in one run.

The collection: the chairs of Debian's ``sweethome3d-furniture`` (the three furniture
catalogs, :func:`cagekit.datasets.sweethome3d.furniture_kind` "chair", at most 15,000
vertices), copied into ``OUT/chairs``. The same 40 variations (seed 0) are made three times
into fresh folders; the pool and the cluster are started and their workers have imported
cagekit before the clock starts (their start-up is in the engines table). Printed per mode:
variations per minute, the median seconds of an item, the peak resident memory of a worker
(sampled every 0.1 s with psutil; the main process for 1 worker), the share the filter
accepted. Then: how much faster a source's later pairs are than its first (the cage fitted
once, then reused), the time of a second run on the finished batch, and the engines' own
costs (start-up, per-task overhead on a trivial task) for the process pool, Dask distributed
and, when installed, Ray.
``--sheet`` draws the 1-worker batch's contact sheet afterwards, untimed.

Usage::

    python benchmarks/bench_amplify.py [--out out/bench_amplify] [--variations 40]
        [--sheet docs/images/amplify_sheet.png] [--json FILE]
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import json
import os
import shutil
import sys
import threading
import time
import warnings

import numpy as np
import psutil

sys.path.insert(0, os.path.dirname(__file__))

from bench_deform import MAX_REAL_VERTICES  # noqa: E402

from cagekit.batch.amplify import amplify, prepare_worker, process_pool  # noqa: E402
from cagekit.batch.cluster import close, connect  # noqa: E402
from cagekit.datasets.sweethome3d import furniture_kind  # noqa: E402
from cagekit.io import load_mesh  # noqa: E402


def chair_collection(folder) -> int:
    """Copy the real chairs into ``folder`` (one OBJ each); returns their number."""
    from cagekit.datasets.sweethome3d import FURNITURE_CATALOGS, models

    os.makedirs(folder, exist_ok=True)
    count = 0
    for model in models(catalogs=FURNITURE_CATALOGS):
        if furniture_kind(model.name) != "chair":
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if len(load_mesh(model.path)[0]) > MAX_REAL_VERTICES:
                continue
        stem = os.path.splitext(os.path.basename(model.path))[0]
        shutil.copyfile(model.path, os.path.join(folder, f"{model.catalog}-{stem}.obj"))
        count += 1
    return count


class PeakMemory:
    """The largest resident set of this process (no children) or of each child, sampled."""

    def __init__(self, children: bool):
        self.children, self.peak, self._stop = children, {}, threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)

    def _sample(self):
        me = psutil.Process()
        while not self._stop.is_set():
            procs = me.children(recursive=True) if self.children else [me]
            for p in procs:
                try:
                    rss = p.memory_info().rss
                except psutil.Error:
                    continue
                self.peak[p.pid] = max(self.peak.get(p.pid, 0), rss)
            self._stop.wait(0.1)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()

    def largest_mib(self) -> float:
        return max(self.peak.values(), default=0) / 2**20


def run_mode(name, collection, out, variations, **options):
    """One batch; its figures."""
    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    with PeakMemory(children=name != "1 worker") as memory:
        rows = amplify(collection, out, variations=variations, seed=0, **options)
    seconds = time.perf_counter() - t0
    return {"mode": name, "seconds": seconds, "per_minute": 60 * len(rows) / seconds,
            "item_median_s": float(np.median([r["seconds"] for r in rows])),
            "peak_worker_mib": memory.largest_mib(),
            "accepted": float(np.mean([r["status"] == "ok" for r in rows])),
            "failed": sum(r["status"] == "failed" for r in rows), "rows": rows}


def cage_reuse(rows) -> dict:
    """Seconds of each source's first item (cage fitted) against its later items."""
    first, later = [], []
    by_source = {}
    for row in rows:
        if row["status"] != "failed":
            by_source.setdefault(row["source"], []).append(row)
    for items in by_source.values():
        if len(items) < 2:
            continue
        first += [r["seconds"] for r in items if r["cage_seconds"] > 0]
        later += [r["seconds"] for r in items if r["cage_seconds"] == 0]
    return {"sources": sum(len(v) >= 2 for v in by_source.values()),
            "first_median_s": float(np.median(first)), "later_median_s":
            float(np.median(later)), "saving": 1 - float(np.median(later) / np.median(first))}


def _imports(seconds):
    """Import what an item runs (numba kernels load on first use in every mode)."""
    import cagekit.cage.fitting  # noqa: F401
    import cagekit.deformation  # noqa: F401
    import cagekit.metrics  # noqa: F401

    time.sleep(seconds)


def warm(executor, workers: int = 2):
    """Each worker imports the package (the sleep keeps one task from taking both)."""
    [f.result() for f in [executor.submit(_imports, 1.0) for _ in range(workers)]]


def _noop(x):
    return x


def engines(tasks: int = 200) -> list[dict]:
    """Start-up (to the first result) and per-task overhead of each engine, 2 workers."""
    import multiprocessing

    out = []
    t0 = time.perf_counter()
    with cf.ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        pool.submit(_noop, 0).result()
        start = time.perf_counter() - t0
        t0 = time.perf_counter()
        list(pool.map(_noop, range(tasks)))
        out.append({"engine": "process pool", "start_s": start,
                    "per_task_ms": 1e3 * (time.perf_counter() - t0) / tasks})
    t0 = time.perf_counter()
    client = connect("local", workers=2)
    executor = client.get_executor(pure=False)
    executor.submit(_noop, 0).result()
    start = time.perf_counter() - t0
    t0 = time.perf_counter()
    [f.result() for f in [executor.submit(_noop, i) for i in range(tasks)]]
    out.append({"engine": "dask distributed", "start_s": start,
                "per_task_ms": 1e3 * (time.perf_counter() - t0) / tasks})
    close(client)
    try:
        import ray
    except ImportError:
        print("ray is not installed: its row is skipped", file=sys.stderr)
        return out
    t0 = time.perf_counter()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    remote = ray.remote(_noop)
    ray.get(remote.remote(0))
    start = time.perf_counter() - t0
    t0 = time.perf_counter()
    ray.get([remote.remote(i) for i in range(tasks)])
    out.append({"engine": "ray", "start_s": start,
                "per_task_ms": 1e3 * (time.perf_counter() - t0) / tasks})
    ray.shutdown()
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/bench_amplify")
    parser.add_argument("--variations", type=int, default=40)
    parser.add_argument("--sheet", default=None, help="contact sheet PNG of the 1-worker run")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    collection = os.path.join(args.out, "chairs")
    count = chair_collection(collection)
    print(f"{count} real chairs in {collection}; {args.variations} variations (seed 0)")
    modes = [run_mode("1 worker", collection, os.path.join(args.out, "one"),
                      args.variations, workers=1)]
    # both engines started and warmed before the clock starts (their start-up is the
    # engines table's); amplify(workers=2) starts the same pool itself
    with process_pool(2) as pool:
        warm(pool)
        modes.append(run_mode("2 workers", collection, os.path.join(args.out, "two"),
                              args.variations, executor=pool, workers=2))
    client = connect("local", workers=2, setup=prepare_worker)
    try:
        executor = client.get_executor(pure=False)
        warm(executor)
        modes.append(run_mode("dask, 2 workers", collection, os.path.join(args.out, "dask"),
                              args.variations, executor=executor, workers=2))
    finally:
        close(client)
    print(f"\n{'mode':<18}{'s':>8}{'per min':>9}{'item s':>8}{'peak MiB':>10}"
          f"{'accepted':>10}{'failed':>8}")
    for m in modes:
        print(f"{m['mode']:<18}{m['seconds']:>8.1f}{m['per_minute']:>9.1f}"
              f"{m['item_median_s']:>8.2f}{m['peak_worker_mib']:>10.0f}"
              f"{100 * m['accepted']:>9.0f}%{m['failed']:>8}")
    one, two, dask = modes
    same = all(a["cd"] == b["cd"] == c["cd"]
               for a, b, c in zip(one["rows"], two["rows"], dask["rows"]))
    print(f"2 workers / 1 worker: {two['per_minute'] / one['per_minute']:.2f}x (target >= "
          f"1.7); dask / pool: {dask['per_minute'] / two['per_minute']:.2f} (target >= "
          f"0.85); identical figures in the three runs: {same}")
    reuse = cage_reuse(one["rows"])
    print(f"cage reuse ({reuse['sources']} sources with 2+ items, 1 worker): first item "
          f"{reuse['first_median_s']:.2f} s, later items {reuse['later_median_s']:.2f} s "
          f"(median): {100 * reuse['saving']:.0f}% faster (target >= 30%)")
    t0 = time.perf_counter()
    amplify(collection, os.path.join(args.out, "one"), variations=args.variations, seed=0,
            workers=1)
    rerun = time.perf_counter() - t0
    print(f"second run on the finished batch: {rerun:.2f} s (target < 5 s)")
    if args.sheet:
        amplify(collection, os.path.join(args.out, "one"), variations=args.variations,
                seed=0, workers=1, contact_sheet_path=args.sheet)
        print(f"contact sheet of the 1-worker batch: {args.sheet}")
    figures = np.array([[r["cd"], r["part_nonaffinity_worst"]] for r in one["rows"]
                        if r["status"] != "failed"])
    print("CD (unit frame) percentiles 50/90/100: "
          + " / ".join(f"{q:.4f}" for q in np.percentile(figures[:, 0], [50, 90, 100]))
          + "; worst part % 50/90/100: "
          + " / ".join(f"{100 * q:.2f}" for q in np.percentile(figures[:, 1], [50, 90, 100])))
    print(f"\n{'engine':<18}{'start s':>9}{'per task ms':>13}")
    costs = engines()
    for e in costs:
        print(f"{e['engine']:<18}{e['start_s']:>9.2f}{e['per_task_ms']:>13.2f}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"modes": modes, "reuse": reuse, "rerun_s": rerun, "engines": costs},
                      fh, indent=1)


if __name__ == "__main__":
    main()
