"""cagekit's Blender add-on beside Blender's own cage modifiers, Mesh Deform and Surface Deform.

A Blender user who wants a cage deformation has Mesh Deform (harmonic coordinates on a
grid) and Surface Deform (each vertex carried by the nearest target faces) built in; the
add-on (``apps/blender/cagekit_blender``) is worth installing only if it binds faster at
equal or better accuracy and its live update keeps up with editing. This script measures
that in one Blender (``bpy``) process, on the same mesh and the same cage for every method.

The mesh is a bumpy closed ellipsoid made here (about 10k, 50k and 200k vertices, no
downloads); its cage is ``cagekit.fit_cage(V, F, faces=200)`` in world space, added as a
Blender mesh object. For each size and method, on fresh objects in an otherwise empty scene:

- bind s: the fastest of ``--binds`` binds (default 3), each on fresh objects:
  ``bpy.ops.cagekit.bind(coords="mvc"|"green")`` (its checks and winding numbers
  included), or ``bpy.ops.object.meshdeform_bind`` / ``surfacedeform_bind`` (run headless
  with a context override; in bpy 5.0 they bind at once, inside the operator);
- update ms: median over ``--edits`` edits (a few cage vertices moved) of the
  ``view_layer.update()`` that follows an edit: the depsgraph evaluation (the modifier, or
  the mesh the add-on wrote the edit before) and the add-on's ``depsgraph_update_post``
  handler, i.e. what one frame of dragging a cage vertex costs;
- gain: the largest mesh vertex displacement over the largest cage vertex displacement, over
  the edits (near 1 for a smooth interpolation; more when a method overshoots);
- rigid error: the cage's vertices turned 30 degrees about an oblique axis and shifted; the
  max and RMS distance of the deformed vertices from the rest vertices moved the same way,
  over the mesh's bounding-box diagonal (Blender stores float32: about 1e-7 is exact).

Surface Deform is not a volume method: it binds every vertex to the few cage faces around
the cage vertex nearest it and carries it with their local frames. That is exact for a
rigid motion (every frame moves alike), but a vertex inside the cage follows those faces
alone, not the whole cage, and a local edit can move it further than any cage vertex moved
(its gain). Mesh Deform's ``precision`` is its grid's depth (default 5); a step up costs far
more to bind (``--precisions 6``: about 20 s at 10k vertices on 2 cores, 50x precision 5).

Targets (issue 20): cagekit's MVC bind at least 10x faster than Mesh Deform (precision 5)
at equal or better rigid error; live update under 30 ms for 50k vertices.

Usage (Blender as a Python module, ``make blender-venv``)::

    .venv-blender/bin/python benchmarks/bench_blender.py [--sizes 10000 50000 200000]
        [--precisions 5 4] [--edits 10] [--max-meshdeform-vertices N] [--json FILE]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import statistics
import sys
import time
import warnings

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "apps", "blender"))

import bpy  # noqa: E402
import cagekit_blender  # noqa: E402
from cagekit_blender import live, meshes  # noqa: E402

import cagekit  # noqa: E402
from cagekit.cage import winding_numbers  # noqa: E402
from cagekit.io import load_mesh  # noqa: E402

TURN_DEGREES = 30.0
TURN_AXIS = (1.0, 2.0, 3.0)
SHIFT = (0.3, -0.2, 0.1)  # in bounding-box diagonals


def bumpy_shape(n: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed, bumpy ellipsoid with about ``n`` vertices: a latitude-longitude sphere
    (``r`` rings, ``2r`` segments) displaced along its radius by a coarse and a fine
    ripple. Returns ``(V (n, 3) float64, F (m, 3) int64)``, outward triangles."""
    rings = max(4, round(np.sqrt(n / 2)))
    segments = 2 * rings
    theta = np.linspace(0, np.pi, rings + 1)[1:-1]
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    T, P = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1)
    U = np.vstack([[0.0, 0.0, 1.0], ring.reshape(-1, 3), [0.0, 0.0, -1.0]])
    x, y, z = U.T
    radius = (1 + 0.08 * np.sin(5 * x) * np.sin(6 * y) * np.sin(4 * z)
              + 0.02 * np.sin(23 * x + 3) * np.sin(19 * y) * np.sin(29 * z + 1))
    V = U * radius[:, None] * [1.0, 0.7, 0.5]

    grid = 1 + np.arange((rings - 1) * segments).reshape(rings - 1, segments)
    a, b = grid[:-1], np.roll(grid[:-1], -1, axis=1)
    c, d = grid[1:], np.roll(grid[1:], -1, axis=1)
    band = np.concatenate([np.stack([a, c, b], -1), np.stack([b, c, d], -1)]).reshape(-1, 3)
    top, bottom = grid[0], grid[-1]
    south = len(V) - 1
    F = np.concatenate([np.stack([np.zeros_like(top), top, np.roll(top, -1)], -1), band,
                        np.stack([np.full_like(bottom, south), np.roll(bottom, -1), bottom],
                                 -1)])
    return V, F.astype(np.int64)


def rigid_motion(points, center, diagonal) -> np.ndarray:
    """``points`` (n, 3) turned ``TURN_DEGREES`` about ``TURN_AXIS`` through ``center``
    and shifted by ``SHIFT`` bounding-box diagonals."""
    axis = np.asarray(TURN_AXIS) / np.linalg.norm(TURN_AXIS)
    angle = np.radians(TURN_DEGREES)
    K = np.cross(np.eye(3), axis)  # cross-product matrix of the axis
    R = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    return (points - center) @ R.T + center + np.asarray(SHIFT) * diagonal


def cage_edits(cage_v, count: int, diagonal, seed: int = 0) -> list[np.ndarray]:
    """``count + 1`` edits of the cage (the first is a warm-up): each moves 8 of its
    vertices from rest by about 2% of the diagonal."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count + 1):
        C = cage_v.copy()
        moved = rng.choice(len(C), size=min(8, len(C)), replace=False)
        C[moved] += rng.normal(scale=0.02 * diagonal, size=(len(moved), 3))
        out.append(C)
    return out


# --- the scene --------------------------------------------------------------------------


def add_mesh(name, V, F, *, wire=False):
    return meshes.new_object(name, V, F, bpy.context.scene.collection, wire=wire)


def set_vertices(obj, V) -> None:
    """Write world-space ``V`` into ``obj``'s mesh (its world matrix is the identity), as
    an edit of its vertices in object mode does."""
    obj.data.vertices.foreach_set("co", np.asarray(V, dtype=np.float32).ravel())
    obj.data.update()


def clear_scene() -> None:
    """Remove every object and mesh (a bound mesh is unbound first: the add-on keeps its
    coordinates in memory until then)."""
    for obj in list(bpy.data.objects):
        if live.is_bound(obj):
            live.unbind_object(obj)
        bpy.data.objects.remove(obj)
    for mesh in list(bpy.data.meshes):
        bpy.data.meshes.remove(mesh)


def evaluated_vertices(obj) -> np.ndarray:
    """(n, 3) float64: the vertices of ``obj`` after its modifiers, in world space."""
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    out = np.empty(3 * len(mesh.vertices), dtype=np.float32)
    mesh.vertices.foreach_get("co", out)
    evaluated.to_mesh_clear()
    return meshes.to_world(out.reshape(-1, 3).astype(np.float64), meshes.matrix(obj))


# --- the methods: each binds (obj, cage) and says how to read the deformed vertices -----


def cagekit_method(coords: str):
    def bind(obj, cage):
        for o in bpy.context.view_layer.objects:
            o.select_set(o in (obj, cage))
        bpy.context.view_layer.objects.active = cage
        with contextlib.redirect_stdout(io.StringIO()):  # its report, "Info: ... bound"
            result = bpy.ops.cagekit.bind(coords=coords)
        if result != {"FINISHED"} or not live.is_bound(obj):
            raise RuntimeError(f"cagekit.bind: {result}")

    return f"cagekit {'MVC' if coords == 'mvc' else 'Green'}", bind, meshes.world_vertices


def modifier_method(kind: str, precision: int = 0):
    def bind(obj, cage):
        mod = obj.modifiers.new(kind.lower(), type=kind)
        if kind == "MESH_DEFORM":
            mod.object, mod.precision = cage, precision
            operator = bpy.ops.object.meshdeform_bind
        else:
            mod.target = cage
            operator = bpy.ops.object.surfacedeform_bind
        with bpy.context.temp_override(object=obj, active_object=obj):
            operator(modifier=mod.name)  # binds now: the operator evaluates the object
        if not mod.is_bound:
            raise RuntimeError(f"{kind} did not bind")

    label = f"Mesh Deform p{precision}" if kind == "MESH_DEFORM" else "Surface Deform"
    return label, bind, evaluated_vertices


def measure(method, shape, cage_mesh, edits, diagonal, binds: int = 3) -> dict:
    """Bind ``shape`` to ``cage_mesh`` with ``method`` on fresh objects, ``binds`` times (the
    fastest is its bind time: a single bind varies by a third from one try to the next);
    time the last one's update after each edit; its gain and rigid error."""
    label, bind, read = method
    V, F = shape
    cage_v, cage_f = cage_mesh
    bind_s = np.inf
    for _ in range(binds):
        clear_scene()
        obj, cage = add_mesh("shape", V, F), add_mesh("cage", cage_v, cage_f, wire=True)
        bpy.context.view_layer.update()
        t = time.perf_counter()
        bind(obj, cage)
        bpy.context.view_layer.update()
        bind_s = min(bind_s, time.perf_counter() - t)

    update_ms, gain = [], 0.0
    for i, C in enumerate(edits):
        set_vertices(cage, C)
        t = time.perf_counter()
        bpy.context.view_layer.update()
        if i:  # the first edit is a warm-up
            update_ms.append(1e3 * (time.perf_counter() - t))
        moved = np.linalg.norm(read(obj) - V, axis=1).max()
        gain = max(gain, moved / np.linalg.norm(C - cage_v, axis=1).max())

    center = (V.min(axis=0) + V.max(axis=0)) / 2
    set_vertices(cage, rigid_motion(cage_v, center, diagonal))
    bpy.context.view_layer.update()
    error = np.linalg.norm(read(obj) - rigid_motion(V, center, diagonal), axis=1) / diagonal
    clear_scene()
    return {"method": label, "vertices": len(V), "bind_s": bind_s,
            "update_ms": statistics.median(update_ms), "gain": gain,
            "rigid_max": float(error.max()), "rigid_rms": float(np.sqrt(np.mean(error**2)))}


def warm_up(cage_v, cage_f) -> None:
    """Compile (or load) cagekit's kernels once, outside the timings."""
    points = cage_v.mean(axis=0) + 0.01 * (cage_v[:64] - cage_v.mean(axis=0))
    for coords in ("mvc", "green"):
        cagekit.bind(points, cage_v, cage_f, method=coords)
    winding_numbers(points, cage_v, cage_f)


def print_row(r) -> None:
    print(f"{r['vertices']:>9,} {r['method']:<17}{r['bind_s']:>9.3f}{r['update_ms']:>10.1f}"
          f"{r['gain']:>7.2f}{r['rigid_max']:>11.1e}{r['rigid_rms']:>11.1e}", flush=True)


def print_targets(rows) -> None:
    by = {r["method"]: r for r in rows}
    if "cagekit MVC" not in by:
        return
    mvc, mdef = by["cagekit MVC"], by.get("Mesh Deform p5")
    n = f"{mvc['vertices']:,}"
    if mdef is None:
        print(f"  {n}: Mesh Deform p5 not run: no bind comparison")  # skipped or failed
    else:
        speedup = mdef["bind_s"] / mvc["bind_s"]
        as_good = mvc["rigid_max"] <= mdef["rigid_max"] and mvc["rigid_rms"] <= mdef["rigid_rms"]
        print(f"  {n}: MVC bind {mvc['bind_s']:.2f} s, Mesh Deform p5 {mdef['bind_s']:.2f} s: "
              f"speed-up {speedup:.1f}x (target >= 10x: {'met' if speedup >= 10 else 'NOT met'})"
              f"; rigid error max {mvc['rigid_max']:.1e} vs {mdef['rigid_max']:.1e} (equal or "
              f"better: {'met' if as_good else 'NOT met'})")
    verdict = ""
    if abs(mvc["vertices"] - 50_000) <= 10_000:
        verdict = ": met" if mvc["update_ms"] < 30 else ": NOT met"
    print(f"  {n}: MVC live update {mvc['update_ms']:.1f} ms (target < 30 ms at 50k "
          f"vertices{verdict})")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="*", default=[10_000, 50_000, 200_000],
                        help="approximate vertex counts of the mesh")
    parser.add_argument("--precisions", type=int, nargs="+", default=[5, 4],
                        help="Mesh Deform precisions to run (grid depth; default 5)")
    parser.add_argument("--edits", type=int, default=10, help="cage edits timed per method")
    parser.add_argument("--binds", type=int, default=3,
                        help="fresh binds per method; the fastest is reported")
    parser.add_argument("--mesh", nargs="*", default=[],
                        help="real mesh files to run too (OBJ, PLY, ...: an artist's chair, say)")
    parser.add_argument("--max-meshdeform-vertices", type=int, default=None,
                        help="skip Mesh Deform on meshes with more vertices than this")
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")

    cagekit_blender.register()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    print(f"# bpy {bpy.app.version_string}, {os.cpu_count()} cpus; mesh: bumpy ellipsoid; "
          f"cage: cagekit.fit_cage(faces=200)")
    print(f"# update: median of {args.edits} edits; gain: max mesh / max cage displacement; "
          f"rigid error over the bounding-box diagonal")
    results, skipped = [], []
    cases = [(f"bumpy ellipsoid ~{size:,}", *bumpy_shape(size)) for size in args.sizes]
    cases += [(os.path.basename(path), *load_mesh(path)) for path in args.mesh]
    for name, V, F in cases:
        diagonal = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
        t = time.perf_counter()
        cage_v, cage_f, _ = cagekit.fit_cage(V, F, faces=200, seed=0)
        print(f"\n# {name}: {len(V):,} vertices, {len(F):,} faces; cage {len(cage_v)} vertices, "
              f"{len(cage_f)} faces (fit_cage {time.perf_counter() - t:.1f} s)")
        print(f"{'vertices':>9} {'method':<17}{'bind s':>9}{'update ms':>10}{'gain':>7}"
              f"{'rigid max':>11}{'rigid RMS':>11}", flush=True)
        warm_up(cage_v, cage_f)
        methods = [cagekit_method("mvc"), cagekit_method("green")]
        if args.max_meshdeform_vertices is None or len(V) <= args.max_meshdeform_vertices:
            methods += [modifier_method("MESH_DEFORM", p) for p in args.precisions]
        else:
            skipped.append(len(V))
        methods.append(modifier_method("SURFACE_DEFORM"))
        edits = cage_edits(cage_v, args.edits, diagonal)
        rows = []
        for method in methods:
            try:
                row = measure(method, (V, F), (cage_v, cage_f), edits, diagonal, args.binds)
            except RuntimeError as exc:  # a modifier that refuses this cage, say
                row = {"method": method[0], "vertices": len(V), "error": str(exc)}
                print(f"{len(V):>9,} {method[0]:<17}failed: {' '.join(str(exc).split())}")
            else:
                print_row(row)
            rows.append(row)
        print_targets([r for r in rows if "error" not in r])
        results += rows
    if skipped:
        print(f"\nMesh Deform skipped at {', '.join(f'{n:,}' for n in skipped)} vertices "
              f"(--max-meshdeform-vertices {args.max_meshdeform_vertices})")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"argv": sys.argv[1:] if argv is None else argv,
                       "bpy": bpy.app.version_string, "cpus": os.cpu_count(),
                       "skipped_meshdeform": skipped, "results": results}, fh, indent=1)


if __name__ == "__main__":
    main()
