"""What a deformed result keeps of a real textured asset, and a picture of it.

``cagekit deform`` of a real textured artist chair (Debian's ``sweethome3d-furniture``,
BlendSwap-CC-0 ``antiqueChair``: 4,990 vertices, UVs, two materials with textures, four
objects) onto another chair, written as OBJ (a copy of the source file: the asset kept), as
GLB and as OFF (geometry only). Prints a table of what each result carries (UV, normal,
material and object records; textures trimesh finds from the result's folder) beside the
source, and renders the OBJ result with its texture (matplotlib: each face coloured by
the texture at its UV centroid, shaded) beside the OFF one.

Usage::

    python benchmarks/bench_keep_asset.py --picture docs/images/textured_result.png
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import trimesh  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from cagekit.datasets import sweethome3d  # noqa: E402

SOURCE, TARGET = "antiqueChair", "armchair"


def _find(name: str) -> str:
    for model in sweethome3d.models(catalogs=["BlendSwap-CC-0"]):
        if Path(model.path).stem == name:
            return model.path
    raise SystemExit(f"{name} not found in BlendSwap-CC-0")


def _records(path: Path) -> dict[str, int]:
    if path.suffix != ".obj":
        return {}
    counts: dict[str, int] = {}
    for line in path.read_text(errors="replace").splitlines():
        key = line.split(None, 1)[0] if line.strip() else ""
        if key in ("vt", "vn", "usemtl", "mtllib", "o", "g"):
            counts[key] = counts.get(key, 0) + 1
    return counts


def _textures(path: Path) -> int:
    """How many of the result's meshes carry a texture image trimesh could load."""
    loaded = trimesh.load(path)
    meshes = loaded.geometry.values() if isinstance(loaded, trimesh.Scene) else [loaded]
    count = 0
    for mesh in meshes:
        material = getattr(mesh.visual, "material", None)
        image = getattr(material, "image", None) or getattr(material, "baseColorTexture", None)
        count += image is not None and min(image.size) > 2
    return count


def _faces_coloured(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Triangles (m, 3, 3) and their colours (m, 3): the texture at each face's UV centroid
    where there is one, the material's colour or grey elsewhere."""
    loaded = trimesh.load(path)
    meshes = loaded.dump() if isinstance(loaded, trimesh.Scene) else [loaded]
    tris, colours = [], []
    for mesh in meshes:
        rgb = np.full((len(mesh.faces), 3), 0.75)
        visual = mesh.visual
        if isinstance(visual, trimesh.visual.TextureVisuals) and visual.uv is not None:
            vertex_rgba = visual.to_color().vertex_colors
            rgb = np.asarray(vertex_rgba, dtype=float)[mesh.faces, :3].mean(axis=1) / 255
        tris.append(np.asarray(mesh.vertices)[mesh.faces])
        colours.append(rgb)
    return np.concatenate(tris), np.concatenate(colours), np.asarray(loaded.bounds)


def _panel(ax, path: Path, title: str) -> None:
    tris, rgb, _ = _faces_coloured(path)
    tris = tris[:, :, [0, 2, 1]] * [1, -1, 1]  # y up in the file -> z up on screen
    normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-30)
    light = np.array([0.4, -0.6, 0.7]) / np.linalg.norm([0.4, -0.6, 0.7])
    shade = 0.45 + 0.55 * np.abs(normal @ light)
    ax.add_collection3d(Poly3DCollection(tris, facecolors=np.clip(rgb * shade[:, None], 0, 1),
                                         edgecolors="none"))
    lo, hi = tris.reshape(-1, 3).min(0), tris.reshape(-1, 3).max(0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2
    for axis, c in zip("xyz", centre):
        getattr(ax, f"set_{axis}lim")(c - half, c + half)
    ax.view_init(elev=15, azim=-60)
    ax.set_axis_off()
    ax.set_title(title, fontsize=10)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="out/keep_asset")
    parser.add_argument("--picture", default=None)
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    source, target = _find(SOURCE), _find(TARGET)
    results = {ext: out / f"{SOURCE}_on_{TARGET}{ext}" for ext in (".obj", ".glb", ".off")}
    for path in results.values():
        done = subprocess.run([sys.executable, "-m", "cagekit.cli", "deform", source, target,
                               "-o", str(path), "--seed", "0"], capture_output=True, text=True)
        if done.returncode != 0:
            raise SystemExit(done.stderr)
        said = [line for line in done.stderr.splitlines() if "not kept" in line]
        print(f"{path.name}: {said[0] if said else 'no warning'}")
    print("\n| file | vt | vn | usemtl | objects | textures found |")
    print("| --- | --- | --- | --- | --- | --- |")
    for name, path in [("source", Path(source)), *((p.name, p) for p in results.values())]:
        r = _records(path)
        textured = _textures(path) if path.suffix != ".off" else 0
        print(f"| {name} | {r.get('vt', '-')} | {r.get('vn', '-')} | {r.get('usemtl', '-')} "
              f"| {r.get('o', '-')} | {textured} |")
    if args.picture:
        fig = plt.figure(figsize=(12, 4.2))
        panels = [(Path(source), f"source {SOURCE}.obj (textured)"),
                  (results[".off"], "result as OFF: geometry only"),
                  (results[".obj"], "result as OBJ: UVs, materials, textures kept")]
        for k, (path, title) in enumerate(panels):
            _panel(fig.add_subplot(1, 3, k + 1, projection="3d"), path, title)
        fig.tight_layout()
        fig.savefig(args.picture, dpi=110)
        print(f"\nwrote {args.picture}")


if __name__ == "__main__":
    os.environ.setdefault("CAGEKIT_PROGRESS", "0")
    main()
