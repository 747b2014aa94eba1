"""How closely each kind of template cage reproduces the template's own poses.

``cagekit transfer`` fits the template's cage to each pose of the template (the least-squares
fit of :func:`cagekit.transfer.classical_fitter`) and warns when the template moved by that
cage misses the pose by more than :data:`cagekit.cli.transfer.TEMPLATE_MISS_WARN` of the
template's size: a cage whose tubes the limbs share cannot move them apart, and the
character's poses miss as much or more. This prints, for the artist cage of
``apps.humanoid_data`` and for fitted cages of several face budgets, the largest miss over
the template's diagonal per pose (the range over the poses), its 95th percentile and mean,
and how many poses the warning would name, on two pose sets: the random test poses
(limbs swung about) and the named rest-like poses of ``cagekit transfer`` (``humanoid:t_pose``
... ``arms_down``: arms near or along the torso, legs together, where a cage whose faces the
limbs share does worst).

Usage::

    python benchmarks/bench_template_miss.py [--poses 20] [--faces 200 400 1000]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from apps import humanoid_data  # noqa: E402
from cagekit import io  # noqa: E402
from cagekit.cage.fitting import fit_cage  # noqa: E402
from cagekit.cli.transfer import TEMPLATE_MISS_WARN  # noqa: E402
from cagekit.datasets.named_poses import PREFIX, REST_POSES, posed_template  # noqa: E402
from cagekit.transfer import classical_fitter  # noqa: E402


def misses(template, cage, poses) -> np.ndarray:
    """(poses, 3): the largest, 95th-percentile and mean miss of each pose, over the
    template's bounding-box diagonal."""
    Vt, _ = template
    fitter = classical_fitter(Vt, *cage)
    size = np.linalg.norm(np.ptp(Vt, axis=0))
    rows = []
    for Vp in poses:
        miss = fitter.miss(Vp, fitter(Vp)) / size
        rows.append((miss.max(), np.percentile(miss, 95), miss.mean()))
    return np.array(rows)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=20, help="test poses of the template")
    parser.add_argument("--faces", type=int, nargs="+", default=[200, 400, 1000],
                        help="face budgets of the fitted cages")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder)
        humanoid_data.write(out, poses=args.poses, train_poses=0, bodies=(), novel=(),
                            truth=False, reverse=False)
        template = io.load_mesh(out / "template.obj")
        test = [io.load_mesh(p)[0] for p in sorted((out / "poses").glob("pose_*.obj"))]
        cages = {"artist": io.load_mesh(out / "template_cage.obj")}
    rest = [posed_template(PREFIX + name, *template) for name in REST_POSES]
    for faces in args.faces:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cage_v, cage_f, _ = fit_cage(*template, faces=faces, seed=0, report=False)
        cages[f"fit_cage {faces}"] = (cage_v, cage_f)
    table = {}
    for title, poses in ((f"{len(test)} test poses", test),
                         (f"the {len(rest)} named rest poses", rest)):
        print(f"{title}; misses in % of the template's diagonal; the warning is above "
              f"{100 * TEMPLATE_MISS_WARN:.0f}%")
        print(f"{'cage':<16} {'faces':>5} {'largest':>11} {'95th pct':>11} {'mean':>11} "
              f"{'warned':>7}")
        for name, cage in cages.items():
            m = 100 * misses(template, cage, poses)
            warned = int((m[:, 0] > 100 * TEMPLATE_MISS_WARN).sum())
            table[title, name] = {"faces": len(cage[1]), "warned": warned,
                                  "largest": [m[:, 0].min(), m[:, 0].max()]}
            print(f"{name:<16} {len(cage[1]):>5} {m[:, 0].min():>5.1f}-{m[:, 0].max():<5.1f} "
                  f"{m[:, 1].min():>5.1f}-{m[:, 1].max():<5.1f} {m[:, 2].min():>5.2f}-"
                  f"{m[:, 2].max():<5.2f} {warned:>4} of {len(poses)}")
    return table


if __name__ == "__main__":
    main()
