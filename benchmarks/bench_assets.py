"""Every real model of Debian's ``sweethome3d-furniture``: loaded, caged, or a clear error.

The package ships 820 OBJ models by real artists (:mod:`cagekit.datasets.sweethome3d`):
line elements in face lists, degenerate faces, hundreds of components, unreferenced
vertices, materials and groups. For each model this script runs, in a worker process (so
that a native crash is seen, counted and named instead of ending the run):

1. ``cagekit.io.load_mesh`` (faces with fewer than 3 vertices dropped, with a warning);
2. ``cagekit.fit_cage(V, F, faces=200)`` (method wrap), then an independent
   ``cagekit.cage_report`` with another seed of samples: "fitted" means every guarantee
   held in both.

It prints one table (loaded / fitted with every guarantee / clear error / crash or
timeout, median and worst seconds) per catalog and over all, the failures by name, and
writes the cages, a JSON file and a contact sheet of fitted cages (``--sheet``) for
looking at. Targets (issue 14): 100% loaded, at least 98% fitted, a clear error for the
rest, no crash.

Usage::

    python benchmarks/bench_assets.py [--faces 200] [--workers 2] [--limit N]
        [--catalogs KatorLegaz ... | --game-art N] [--json out/bench_assets.json]
        [--sheet out/assets_sheet.png] [--timeout 600]

``--game-art N`` runs the same on N meshes of Debian's ``0ad-data`` instead (the game
0 A.D.'s PMD meshes: props, plants, buildings, skinned bodies; every k-th of its sorted
list, :func:`cagekit.datasets.zero_ad.meshes`), a table per folder.

``make bench-assets`` installs the package when missing (as root) and runs it.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import selectors
import statistics
import subprocess
import sys
import time


def _worker() -> None:
    """Read one JSON job a line on stdin, answer one JSON line on stdout."""
    import warnings

    import cagekit
    from cagekit import io
    from cagekit.errors import InputError

    for line in sys.stdin:
        job = json.loads(line)
        row = {"path": job["path"]}
        t0 = time.perf_counter()
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                V, F = io.load_mesh(job["path"])
            row.update(status="loaded", vertices=len(V), faces=len(F),
                       load_s=time.perf_counter() - t0,
                       warnings=[str(w.message) for w in caught])
        except InputError as exc:
            row.update(status="unloadable", error=str(exc), load_s=time.perf_counter() - t0)
        if row["status"] == "loaded":
            t1 = time.perf_counter()
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    cv, cf, report = cagekit.fit_cage(V, F, faces=job["faces"])
                    fit_s = time.perf_counter() - t1
                    again = cagekit.cage_report(V, F, cv, cf, faces=job["faces"], seed=1)
                ok = report.ok and again.ok
                row.update(status="fitted" if ok else "unguaranteed", fit_s=fit_s,
                           cage_faces=len(cf), volume_ratio=report.volume_ratio,
                           volume_reference=report.volume_reference,
                           max_distance=report.max_distance,
                           failed_checks=[k for k, v in again.checks.items() if not v])
                if job.get("cage"):
                    io.save_mesh(job["cage"], cv, cf)
            except InputError as exc:
                row.update(status="error", error=str(exc), fit_s=time.perf_counter() - t1)
        row["seconds"] = time.perf_counter() - t0
        print(json.dumps(row, default=float), flush=True)


class _Pool:
    """Worker processes fed one job at a time; a worker that dies is replaced."""

    def __init__(self, workers: int, timeout: float):
        self.timeout = timeout
        self.selector = selectors.DefaultSelector()
        self.idle = [self._start() for _ in range(workers)]
        self.busy = {}  # process -> (job, started)

    def _start(self):
        env = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
        proc = subprocess.Popen([sys.executable, __file__, "--worker"], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                text=True, bufsize=1, env=env)
        return proc

    def submit(self, job) -> None:
        proc = self.idle.pop()
        proc.stdin.write(json.dumps(job) + "\n")
        proc.stdin.flush()
        self.busy[proc] = (job, time.perf_counter())
        self.selector.register(proc.stdout, selectors.EVENT_READ, proc)

    def collect(self):
        """Wait for one finished job: its row (crashes and timeouts included)."""
        while True:
            deadline = min(start + self.timeout for _, start in self.busy.values())
            events = self.selector.select(max(0.0, deadline - time.perf_counter()))
            if events:
                proc = events[0][0].data
                line = proc.stdout.readline()
                return self._finish(proc, json.loads(line) if line else None)
            for proc, (job, start) in list(self.busy.items()):
                if time.perf_counter() - start > self.timeout:
                    proc.kill()
                    proc.wait()
                    return self._finish(proc, {"path": job["path"], "status": "timeout",
                                               "seconds": self.timeout})

    def _finish(self, proc, row):
        job, start = self.busy.pop(proc)
        self.selector.unregister(proc.stdout)
        if row is None or row.get("status") == "timeout":  # died (or killed): a crash
            code = proc.wait()
            if row is None:
                row = {"path": job["path"], "status": "crash", "exit_code": code,
                       "seconds": time.perf_counter() - start}
            proc = self._start()
        self.idle.append(proc)
        return row

    def close(self) -> None:
        for proc in self.idle + list(self.busy):
            proc.stdin.close()
            proc.wait()


def _table(rows, title) -> list[str]:
    n = len(rows)
    count = {s: sum(r["status"] == s for r in rows)
             for s in ("fitted", "unguaranteed", "error", "unloadable", "crash", "timeout")}
    loaded = n - count["unloadable"]
    seconds = [r["seconds"] for r in rows if r["status"] not in ("crash", "timeout")]
    median = statistics.median(seconds) if seconds else float("nan")
    worst = max(seconds) if seconds else float("nan")
    return [f"| {title} | {n} | {loaded} ({100 * loaded / n:.1f}%) | "
            f"{count['fitted']} ({100 * count['fitted'] / n:.1f}%) | "
            f"{count['error'] + count['unguaranteed'] + count['unloadable']} | "
            f"{count['crash'] + count['timeout']} | {median:.2f} | {worst:.1f} |"]


def _sheet(sheet, rows, models_by_path, cage_dir, count) -> None:
    """Models with their cages: the slowest, the loosest and the rest by catalog order."""
    from cagekit import io
    from cagekit.render import render_grid

    fitted = [r for r in rows if r["status"] == "fitted"]
    by_time = sorted(fitted, key=lambda r: -r["fit_s"])[: count // 4]
    by_volume = sorted(fitted, key=lambda r: -(r["volume_ratio"] or 0))[: count // 4]
    chosen = list(dict.fromkeys([r["path"] for r in by_time + by_volume]
                                + [r["path"] for r in fitted[:: max(1, len(fitted) // count)]]))
    chosen = chosen[:count]
    panels = []
    for model_path in chosen:
        row = next(r for r in rows if r["path"] == model_path)
        model = models_by_path[model_path]
        V, F = io.load_mesh(model_path)
        cage = io.load_mesh(os.path.join(cage_dir, _cage_name(model)))
        by = f" by {model.creator}" if model.creator else ""
        title = f"{model.name}{by}: {row['fit_s']:.1f} s"
        panels.append(((V, F), cage, title))
    per_row = 4
    grid = [panels[i:i + per_row] for i in range(0, len(panels), per_row)]
    render_grid(sheet, [[p[0] for p in r] for r in grid],
                cages=[[p[1] for p in r] for r in grid],
                titles=[[p[2] for p in r] for r in grid], size=(300, 300))


def _cage_name(model) -> str:
    stem = os.path.splitext(os.path.basename(model.path))[0]
    return f"{model.catalog}__{stem}.obj"


def main(argv=None) -> int:
    """Run the benchmark; prints the table and returns 0."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--faces", type=int, default=200)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--catalogs", nargs="*", default=None)
    parser.add_argument("--limit", type=int, default=None, help="First N models only.")
    parser.add_argument("--timeout", type=float, default=600.0, help="Seconds per model.")
    parser.add_argument("--cache", default="out/sweethome3d")
    parser.add_argument("--cages", default="out/bench_assets_cages")
    parser.add_argument("--json", default=None)
    parser.add_argument("--sheet", default=None, help="Contact sheet PNG of fitted cages.")
    parser.add_argument("--sheet-count", type=int, default=16)
    parser.add_argument("--game-art", type=int, default=None, metavar="N",
                        help="instead: N meshes of Debian's 0ad-data, spread evenly over its "
                             "4,010 (cagekit.datasets.zero_ad.meshes), by folder")
    args = parser.parse_args(argv)
    if args.worker:
        _worker()
        return 0

    from cagekit.datasets import sweethome3d, zero_ad

    if args.game_art:
        models = zero_ad.meshes(args.game_art)[: args.limit]
        catalogs = tuple(dict.fromkeys(m.catalog for m in models))
        source = "0ad-data"
    else:
        catalogs = tuple(args.catalogs) if args.catalogs else sweethome3d.CATALOGS
        models = sweethome3d.models(catalogs, cache=args.cache)[: args.limit]
        source = "sweethome3d-furniture"
    by_path = {m.path: m for m in models}
    os.makedirs(args.cages, exist_ok=True)
    pool = _Pool(max(1, args.workers), args.timeout)
    jobs = [{"path": m.path, "faces": args.faces,
             "cage": os.path.join(args.cages, _cage_name(m))} for m in models]
    rows, start = [], time.perf_counter()
    pending = list(reversed(jobs))
    while pending or pool.busy:
        while pending and pool.idle:
            pool.submit(pending.pop())
        row = pool.collect()
        model = by_path[row["path"]]
        row.update(catalog=model.catalog, name=model.name, category=model.category,
                   creator=model.creator)
        rows.append(row)
        print(f"[{len(rows):4d}/{len(jobs)}] {row['status']:>12} {row['seconds']:7.2f} s  "
              f"{model.catalog}/{os.path.basename(model.path)}"
              + (f": {row['error']}" if "error" in row else ""), flush=True)
    pool.close()
    wall = time.perf_counter() - start
    order = {m.path: i for i, m in enumerate(models)}
    rows.sort(key=lambda r: order[r["path"]])

    lines = [f"{source}, fit_cage(faces={args.faces}), {len(rows)} models, "
             f"{args.workers} workers, {platform.processor() or platform.machine()}, "
             f"wall {wall / 60:.1f} min", "",
             "| catalog | models | loaded | fitted, every guarantee | clear error | "
             "crash or timeout | median s | worst s |",
             "|---|---|---|---|---|---|---|---|"]
    for catalog in catalogs:
        part = [r for r in rows if r["catalog"] == catalog]
        if part:
            lines += _table(part, catalog)
    lines += _table(rows, "all")
    failures = [r for r in rows if r["status"] != "fitted"]
    lines += ["", f"not fitted ({len(failures)}):"]
    lines += [f"- {r['catalog']}/{os.path.basename(r['path'])} ({r['name']}): {r['status']}"
              + (f", {r['error']}" if "error" in r else "")
              + (f", failed {r['failed_checks']}" if r.get("failed_checks") else "")
              for r in failures]
    dropped = [r for r in rows if r.get("warnings")]
    lines += ["", f"loaded with a warning ({len(dropped)}): "
              + ", ".join(os.path.basename(r["path"]) for r in dropped[:30])]
    print("\n".join(lines))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"rows": rows, "table": lines, "faces": args.faces}, fh, indent=1)
        print(f"wrote {args.json}")
    if args.sheet:
        _sheet(args.sheet, rows, by_path, args.cages, args.sheet_count)
        print(f"wrote {args.sheet}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
