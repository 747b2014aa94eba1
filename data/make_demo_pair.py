"""Write the bundled demo pair: two chairs of one style with clearly different proportions.

Run from the repository root::

    python data/make_demo_pair.py            # writes data/example/chair_{source,target}.obj
    python data/make_demo_pair.py --out DIR  # writes elsewhere

Both chairs come from :func:`cagekit.datasets.synthetic.chair` with seed 7 (which draws
the seat and leg thicknesses) and the same style (square legs, four back slats,
stretchers); the proportions are fixed here:

- ``chair_source.obj``: tall and narrow, 0.42 x 0.42 seat at 0.48, back 0.55 above it
  (1.03 high);
- ``chair_target.obj``: low and wide, 0.60 x 0.52 seat at 0.40, back 0.32 above it
  (0.72 high).

y is up, both stand on y = 0, units are metres. Each is a union of closed, outward,
2-manifold parts. The script is deterministic: it rewrites the files (byte for byte on the
same CPU, to the last digit elsewhere).
"""

from __future__ import annotations

import argparse
import os
import sys

SEED = 7
STYLE = {"leg_style": "square", "back_style": "slats", "back_count": 4, "stretchers": True}
SOURCE = {"seat_width": 0.42, "seat_depth": 0.42, "seat_height": 0.48, "back_height": 0.55}
TARGET = {"seat_width": 0.60, "seat_depth": 0.52, "seat_height": 0.40, "back_height": 0.32}


def main(argv=None) -> int:
    """Write the two chairs; return the exit status."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    sys.path.insert(0, root)
    from cagekit.datasets.synthetic import chair
    from cagekit.io import save_mesh

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join(root, "data", "example"),
                        help="output folder (default: data/example)")
    args = parser.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    for name, proportions in (("chair_source", SOURCE), ("chair_target", TARGET)):
        V, F = chair(seed=SEED, **STYLE, **proportions)
        path = os.path.join(args.out, f"{name}.obj")
        save_mesh(path, V, F)
        size = V.max(axis=0) - V.min(axis=0)
        print(f"wrote {path}: {len(V)} vertices, {len(F)} faces, "
              f"{size[0]:.2f} x {size[1]:.2f} x {size[2]:.2f} m (x, y, z)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
