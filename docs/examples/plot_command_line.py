"""
The command line
================

The README's "Command line" section on the bundled chairs: ``cagekit fit-cage`` builds a
checked cage around the source, and ``cagekit deform`` deforms the source onto the
target's proportions (its cage fitted the same way), each with its ``--preview``
picture. It runs from the repository root, where ``data/example`` is, and writes into
``out/gallery/``.
"""

# sphinx_gallery_start_ignore
# ruff: noqa: E402 (the example follows after this hidden part)
import os as _os
from pathlib import Path as _Path

_os.chdir(_Path.cwd().parents[1])
# sphinx_gallery_end_ignore
import os
import subprocess
import sys

import matplotlib.pyplot as plt


def cagekit(*args):
    """Run a cagekit command (as ``cagekit ARGS`` in a shell) and print what it says."""
    done = subprocess.run([sys.executable, "-m", "cagekit.cli", *args],
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"cagekit {' '.join(args)}: exit {done.returncode}: {done.stderr.strip()}")
    print(done.stdout.strip())


os.makedirs("out/gallery", exist_ok=True)   # cagekit writes into folders that exist
cagekit("fit-cage", "data/example/chair_source.obj", "-o", "out/gallery/chair_cage.obj",
        "--faces", "120", "--preview", "out/gallery/chair_cage.png")
cagekit("deform", "data/example/chair_source.obj", "data/example/chair_target.obj",
        "-o", "out/gallery/chair.obj", "--symmetry", "x",
        "--preview", "out/gallery/chair.png")

for picture in ("out/gallery/chair_cage.png", "out/gallery/chair.png"):
    image = plt.imread(picture)
    height, width = image.shape[:2]
    plt.figure(figsize=(6 * min(1.5, width / height), 6 * min(1.0, height / width)))
    plt.imshow(image)
    plt.axis("off")
