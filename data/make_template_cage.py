"""Write the paper's template cage, ``data/template_cage.obj``.

Run from the repository root::

    python data/make_template_cage.py                 # writes data/template_cage.obj
    python data/make_template_cage.py --out FILE.obj  # writes elsewhere

The cage is :func:`cagekit.template_cage`: the 42-vertex, 80-face icosphere of radius 1
(one loop subdivision of the icosahedron, vertices projected to the sphere), closed,
2-manifold, outward-oriented. ``cagekit fit-cage --method template`` fits it around a shape.
"""

from __future__ import annotations

import argparse
import os
import sys


def main(argv=None) -> None:
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    sys.path.insert(0, root)
    from cagekit import template_cage
    from cagekit.io import save_mesh

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join(root, "data", "template_cage.obj"))
    args = parser.parse_args(argv)
    v, f = template_cage()
    save_mesh(args.out, v, f)
    print(f"wrote {args.out}: {len(v)} vertices, {len(f)} faces")


if __name__ == "__main__":
    main()
