"""Build the installable Blender extension of cagekit: out/blender/cagekit-0.1.0-linux_x64.zip.

Why: the add-on (apps/blender/cagekit_blender) imports the cagekit library at run time, and
Blender's own Python has none of it. A Blender extension carries its Python dependencies as
wheels listed in its manifest; Blender installs them into the extensions' site-packages when
the extension is installed, without network access. So the zip holds the add-on, a wheel of
cagekit itself and the wheels of its dependencies, for Blender 5.0's Python (3.11) and with
the versions of apps/blender/constraints.txt (numpy 1.26.4, nlopt 2.7.1).

Steps:
1. a wheel of cagekit (``pip wheel --no-deps``, built from a copy of the sources, so the
   tree gets no build/ folder), then ``pip download`` of its dependencies' wheels for
   manylinux x86_64 and CPython 3.11, less what Blender ships itself (numpy, requests and
   the rest of ``BLENDER_BUNDLED``: a bundled copy would shadow Blender's). torch, the
   optional ``learn`` extra, is never bundled;
2. a staging copy of the add-on with those wheels in ``wheels/``, its blender_manifest.toml
   given the ``wheels`` list and ``platforms = ["linux-x64"]``;
3. Blender's own extension tool (the ``blender --command extension`` implementation,
   bl_pkg/cli/blender_ext.py, bundled with the bpy module) validates the staging folder,
   builds the zip (``--split-platforms``: named with its platform) and validates the zip;
4. prints the zip's path and size and the wheels' sizes (the biggest first).

With ``--check``, the zip is then installed into a throwaway Blender user folder
(BLENDER_USER_RESOURCES in a temporary folder) by ``bpy.ops.extensions.package_install_files``
in a fresh Python that holds only bpy and what Blender bundles, so that cagekit and its
dependencies can only come from the extension's wheels; it runs ``bpy.ops.cagekit.fit_cage``
on a sphere and checks where every dependency was imported from.

Only linux-x64 is built here: windows-x64 and macos-arm64 would need those platforms' wheels
(``pip download --platform win_amd64`` ...) and a Blender there to check them; not built or
tested. pymeshlab 2025.7.post1 exists only for manylinux_2_35, so the zip needs glibc 2.35
or newer (Blender 5.0 itself runs from glibc 2.28).

Needs network access to PyPI at build time (the add-on never downloads anything) and a Python
with the bpy module (for its bundled extension tool), i.e. the one of ``make blender-venv``.

Usage: .venv-blender/bin/python apps/blender/build_extension.py [--out DIR]
       [--python-version 3.11] [--keep-staging] [--check]
"""

from __future__ import annotations

import argparse
import configparser
import importlib.metadata
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ADDON = ROOT / "apps" / "blender" / "cagekit_blender"
CONSTRAINTS = ROOT / "apps" / "blender" / "constraints.txt"
PLATFORM = "linux-x64"

# What Blender 5.0's Python ships in its site-packages (the bpy module declares the same:
# cython, numpy, requests, zstandard, with requests' own dependencies). Never bundled.
BLENDER_BUNDLED = {"numpy", "requests", "certifi", "charset-normalizer", "idna", "urllib3",
                   "zstandard", "cython"}
# Never bundled: the optional `learn` extra (cagekit_learn), far too big for an extension.
NEVER_BUNDLED = {"torch"}

# manylinux x86_64 tags pip may take, newest glibc first. 2.35: pymeshlab 2025.7.post1 has
# no older wheel (Blender 5.0 itself needs glibc 2.28).
GLIBC_MAX = 35
MANYLINUX_TAGS = ([f"manylinux_2_{minor}_x86_64" for minor in range(GLIBC_MAX, 4, -1)]
                  + ["manylinux2014_x86_64", "manylinux2010_x86_64", "manylinux1_x86_64"])
LEGACY_GLIBC = {"manylinux2014": (2, 17), "manylinux2010": (2, 12), "manylinux1": (2, 5)}


def run(cmd: list[str], **kw) -> subprocess.CompletedProcess:
    """Runs ``cmd`` (shown first); a failure ends the build with its exit status."""
    cmd = [str(c) for c in cmd]
    print("+", " ".join(cmd), flush=True)
    done = subprocess.run(cmd, **kw)
    if done.returncode:
        raise SystemExit(f"failed (exit status {done.returncode}): {' '.join(cmd[:4])} ...")
    return done


def distribution_name(wheel: Path) -> str:
    """The normalized project name of a wheel file (PEP 503)."""
    return re.sub(r"[-_.]+", "-", wheel.name.split("-")[0]).lower()


def source_packages() -> list[str]:
    """The top-level packages setup.cfg's [options.packages.find] includes."""
    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "setup.cfg")
    names = cfg["options.packages.find"]["include"].split()
    return sorted({n.split(".")[0] for n in names})


def build_cagekit_wheel(dest: Path, work: Path) -> Path:
    """``pip wheel --no-deps`` of cagekit, from a copy of its sources (no build/ in the tree)."""
    src = work / "src"
    src.mkdir()
    for name in ("setup.cfg", "pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, src / name)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for package in source_packages():
        shutil.copytree(ROOT / package, src / package, ignore=ignore)
    run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", dest, src])
    (wheel,) = dest.glob("cagekit-*.whl")
    return wheel


def download_wheels(cagekit_wheel: Path, dest: Path, python_version: str) -> None:
    """The wheels of cagekit's dependencies for CPython ``python_version`` on manylinux."""
    abi = "cp" + python_version.replace(".", "")
    platforms = [arg for tag in MANYLINUX_TAGS for arg in ("--platform", tag)]
    run([sys.executable, "-m", "pip", "download", "-q", "--only-binary=:all:", *platforms,
         "--python-version", python_version, "--implementation", "cp", "--abi", abi,
         "-c", CONSTRAINTS, "-d", dest, cagekit_wheel])


def drop_unbundled(wheels: Path) -> list[str]:
    """Removes the wheels of what Blender ships; fails on one never to bundle."""
    dropped = []
    for wheel in sorted(wheels.glob("*.whl")):
        name = distribution_name(wheel)
        if name in NEVER_BUNDLED:
            raise SystemExit(f"{wheel.name} must never be bundled (the `learn` extra)")
        if name in BLENDER_BUNDLED:
            wheel.unlink()
            dropped.append(wheel.name)
    return dropped


def set_manifest_keys(text: str, values: dict[str, list[str]]) -> str:
    """``text`` (a blender_manifest.toml) with the top-level arrays ``values`` set."""
    for key, items in values.items():
        array = "[\n" + "".join(f'  "{item}",\n' for item in items) + "]"
        line = f"{key} = {array}"
        text, found = re.subn(rf"^{key}\s*=\s*\[[^\]]*\]", line, text, count=1, flags=re.M)
        if not found:  # before the first table, where top-level keys belong
            text, found = re.subn(r"^\[", line + "\n\n[", text, count=1, flags=re.M)
        if not found:
            text += "\n" + line + "\n"
    return text


def stage_addon(stage: Path, wheels: Path) -> Path:
    """The add-on copied to ``stage``, with ``wheels/`` and the manifest listing them."""
    addon = stage / "cagekit"
    shutil.copytree(ADDON, addon, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    shutil.copytree(wheels, addon / "wheels")
    names = sorted(w.name for w in (addon / "wheels").glob("*.whl"))
    manifest = addon / "blender_manifest.toml"
    text = set_manifest_keys(manifest.read_text(), {
        "wheels": [f"./wheels/{name}" for name in names], "platforms": [PLATFORM]})
    manifest.write_text(text)
    data = tomllib.loads(text)
    assert data["platforms"] == [PLATFORM] and len(data["wheels"]) == len(names)
    return addon


def blender_scripts() -> Path:
    """The scripts folder of the bpy module of this Python (without importing bpy)."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or spec.origin is None:
        raise SystemExit("no bpy module in this Python: run with .venv-blender/bin/python "
                         "(make blender-venv)")
    found = sorted(Path(spec.origin).parent.glob("*/scripts/addons_core/bl_pkg"))
    if not found:
        raise SystemExit(f"no bl_pkg (Blender's extension tool) next to {spec.origin}")
    return found[-1].parents[1]


def blender_ext(scripts: Path, *args) -> None:
    """Runs Blender's extension tool as ``blender --command extension`` does (with the valid
    tags Blender passes)."""
    tool = scripts / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"
    tags = scripts / "modules" / "_bpy_internal" / "extensions" / "tags.py"
    sub, *rest = args
    run([sys.executable, tool, sub, "--valid-tags", tags, *rest])


def build_zip(scripts: Path, addon: Path, out: Path) -> Path:
    """Validates the staged add-on, builds its zip into ``out`` and validates the zip."""
    manifest = tomllib.loads((addon / "blender_manifest.toml").read_text())
    blender_ext(scripts, "validate", addon)
    out.mkdir(parents=True, exist_ok=True)
    name = f"{manifest['id']}-{manifest['version']}-{PLATFORM.replace('-', '_')}.zip"
    zip_path = out / name
    zip_path.unlink(missing_ok=True)
    blender_ext(scripts, "build", "--source-dir", addon, "--output-dir", out,
                "--split-platforms")
    if not zip_path.is_file():
        raise SystemExit(f"Blender's extension tool did not write {zip_path}")
    blender_ext(scripts, "validate", zip_path)
    return zip_path


def glibc_needed(wheel: Path) -> tuple[int, int]:
    """The oldest glibc a wheel runs with: the lowest of its manylinux tags ((0, 0): any)."""
    needs = []
    for tag in wheel.stem.split("-")[-1].split("."):
        if m := re.fullmatch(r"manylinux_(\d+)_(\d+)_\w+", tag):
            needs.append((int(m[1]), int(m[2])))
        elif (legacy := tag.partition("_")[0]) in LEGACY_GLIBC:
            needs.append(LEGACY_GLIBC[legacy])
    return min(needs, default=(0, 0))


def report(zip_path: Path, wheels: Path, dropped: list[str], biggest: int = 6) -> None:
    mb = 1024 * 1024
    files = sorted(wheels.glob("*.whl"), key=lambda w: w.stat().st_size, reverse=True)
    total = sum(w.stat().st_size for w in files)
    newest = max(files, key=glibc_needed)
    glibc = ".".join(map(str, glibc_needed(newest)))
    print(f"\n{zip_path}  {zip_path.stat().st_size / mb:.1f} MB ({PLATFORM})")
    print(f"{len(files)} wheels, {total / mb:.1f} MB; the biggest:")
    for w in files[:biggest]:
        print(f"  {w.stat().st_size / mb:7.1f} MB  {w.name}")
    print(f"left to Blender's own Python: {', '.join(dropped) or 'nothing'}")
    print(f"needs glibc {glibc} or newer ({newest.name})")


# Run in a fresh Python holding only bpy and Blender's bundled packages. Step "install":
# installs the zip as a user extension (enabled, preferences saved); step "restart": a later
# start (the bpy module reads the saved preferences only when asked). Both then run fit_cage
# on a sphere and print, as JSON, where cagekit and its dependencies were imported from.
CHECK_SCRIPT = r'''
import json, os, sys
import bpy

zip_path, step = sys.argv[1:3]
if step == "install":
    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                             enable_on_install=True)
    bpy.ops.wm.save_userpref()
else:
    bpy.ops.wm.read_userpref()
enabled = [a.module for a in bpy.context.preferences.addons if "cagekit" in a.module]
assert enabled == ["bl_ext.user_default.cagekit"], enabled
assert "fit_cage" in dir(bpy.ops.cagekit), dir(bpy.ops.cagekit)

for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj)
bpy.ops.mesh.primitive_uv_sphere_add(segments=24, ring_count=12, location=(0.2, 0.0, 0.1))
sphere = bpy.context.active_object
result = bpy.ops.cagekit.fit_cage(faces=120)
cage = bpy.data.objects[sphere.name + "_cage"]

site = os.path.join(bpy.utils.user_resource("EXTENSIONS"), ".local")
modules = ["cagekit", "scipy", "igl", "pymeshlab", "trimesh", "rtree", "nlopt",
           "click", "tqdm", "matplotlib", "numba", "llvmlite", "ipctk", "threadpoolctl",
           "numpy"]
origins = {}
for name in modules:
    module = __import__(name)
    origins[name] = "extension" if module.__file__.startswith(site) else module.__file__
import numpy
print("CHECK " + json.dumps({
    "result": sorted(result), "cage_faces": len(cage.data.polygons),
    "sphere_faces": len(sphere.data.polygons), "numpy": numpy.__version__,
    "origins": origins, "extensions": bpy.utils.user_resource("EXTENSIONS")}))
'''


def blender_like_python(work: Path) -> Path:
    """A venv whose site-packages holds (links to) only bpy and Blender's bundled packages
    of this Python: what Blender's own Python has."""
    run([sys.executable, "-m", "venv", "--without-pip", work / "venv"])
    site = next((work / "venv" / "lib").glob("python3.*/site-packages"))
    for dist in ("bpy", *sorted(BLENDER_BUNDLED)):
        try:
            found = importlib.metadata.distribution(dist)
        except importlib.metadata.PackageNotFoundError:
            continue
        for top in {f.parts[0] for f in found.files or [] if f.parts[0] != ".."}:
            source = Path(found.locate_file(top))
            if source.exists() and not (site / top).exists():
                (site / top).symlink_to(source)
    return work / "venv" / "bin" / "python"


def run_check(python: Path, work: Path, zip_path: Path, step: str) -> dict:
    """One step of CHECK_SCRIPT, with every user folder in ``work``; its JSON result."""
    env = {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), "HOME": str(work / "home"),
           "BLENDER_USER_RESOURCES": str(work / "blender"),
           "XDG_CONFIG_HOME": str(work / "config"), "XDG_CACHE_HOME": str(work / "cache")}
    cmd = [str(python), "-I", str(work / "check.py"), str(zip_path.resolve()), step]
    print("+", " ".join(cmd), flush=True)
    done = subprocess.run(cmd, env=env, cwd=work, capture_output=True, text=True)
    line = next((s for s in done.stdout.splitlines() if s.startswith("CHECK ")), None)
    if done.returncode or line is None:
        print(done.stdout[-4000:], done.stderr[-4000:], sep="\n")
        raise SystemExit(f"check ({step}) failed: exit status {done.returncode}")
    return json.loads(line[len("CHECK "):])


def check_install(zip_path: Path) -> None:
    """Installs ``zip_path`` in a throwaway Blender user folder, runs fit_cage there and
    again in a later start; cagekit's dependencies must come from the extension's wheels,
    numpy from Blender's own Python."""
    with tempfile.TemporaryDirectory(prefix="cagekit-ext-check-") as tmp:
        work = Path(tmp)
        python = blender_like_python(work)
        (work / "check.py").write_text(CHECK_SCRIPT)
        for step in ("install", "restart"):
            found = run_check(python, work, zip_path, step)
            wrong = {k: v for k, v in found["origins"].items()
                     if (v == "extension") == (k == "numpy")}
            print(f"check ({step}): fit_cage {found['result']}, a {found['cage_faces']}-face "
                  f"cage around a {found['sphere_faces']}-face sphere; numpy "
                  f"{found['numpy']} from Blender's Python, {len(found['origins']) - 1} "
                  f"modules from the extension's wheels ({found['extensions']})")
            if wrong or found["result"] != ["FINISHED"]:
                raise SystemExit(f"check ({step}) failed: imported from the wrong place: {wrong}")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "blender",
                        help="folder of the built zip (default: out/blender)")
    parser.add_argument("--python-version", default="3.11",
                        help="Blender's Python version the wheels are for (default: 3.11)")
    parser.add_argument("--keep-staging", action="store_true",
                        help="keep the staging folder (wheels and staged add-on), print it")
    parser.add_argument("--check", action="store_true",
                        help="then install the zip in a throwaway Blender user folder and "
                             "run bpy.ops.cagekit.fit_cage")
    args = parser.parse_args(argv)

    scripts = blender_scripts()
    stage = Path(tempfile.mkdtemp(prefix="cagekit-blender-ext-"))
    try:
        wheels = stage / "wheels"
        cagekit_wheel = build_cagekit_wheel(stage / "dist", stage)
        download_wheels(cagekit_wheel, wheels, args.python_version)
        dropped = drop_unbundled(wheels)
        addon = stage_addon(stage / "staging", wheels)
        zip_path = build_zip(scripts, addon, args.out)
        report(zip_path, wheels, dropped)
    finally:
        if args.keep_staging:
            print(f"staging kept in {stage}")
        else:
            shutil.rmtree(stage, ignore_errors=True)
    if args.check:
        check_install(zip_path)


if __name__ == "__main__":
    main()
