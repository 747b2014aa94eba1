"""Posed humanoids with ground truth for deformation transfer (files on disk).

Writes, from :mod:`cagekit.datasets.humanoid` and a seed, what
``python -m apps.deformation_transfer`` and ``cagekit train --fixed-source`` need, and the
ground truth that judges a transfer::

    OUT_DIR/template.obj                 the template body in rest pose (T-pose)
    OUT_DIR/template_cage.obj            its cage (cagekit.fit_cage, --cage-faces faces)
    OUT_DIR/template_landmarks.json      --landmarks named landmarks on it
    OUT_DIR/characters/<body>.obj        each novel body in rest pose
    OUT_DIR/characters/<body>_landmarks.json
    OUT_DIR/poses/pose_000.obj ...       the template in --poses test poses
    OUT_DIR/truth/<body>/pose_000.obj    each body posed with the same joint rotations
    OUT_DIR/train/pose_0000.ply ...      the template in --train-poses other poses

Test pose ``i`` is ``random_pose(TEST_POSE_SEED + i)`` and training pose ``i`` is
``random_pose(seed + i)`` (seeds below ``TEST_POSE_SEED``), so the two never share a pose.
Every mesh shares the template's faces and every body the same landmark labels. Usage::

    python -m apps.humanoid_data OUT_DIR [--poses 20] [--train-poses 1000] [--seed 0]
"""

from __future__ import annotations

import json
from pathlib import Path

import click
import numpy as np

from cagekit import io
from cagekit.cli.common import Command, FiniteFloatRange, debug_option, emit_json, json_option
from cagekit.datasets import humanoid
from cagekit.errors import InputError
from cagekit.files import atomic_output
from cagekit.landmarks import save_landmarks

__all__ = ["TEST_POSE_SEED", "landmark_names", "landmarks_of", "template_cage", "write"]

#: seed of the first test pose; training poses use seeds below it
TEST_POSE_SEED = 100_000


def landmark_names(count: int) -> list[str]:
    """``count`` landmark labels spread over the body, in a fixed order.

    Parameters
    ----------
    count : int
        4 <= count <= len(humanoid.LANDMARK_NAMES).

    Returns
    -------
    list of str
        Every ``len(LANDMARK_NAMES) / count``-th name (evenly strided), so any count
        covers all parts of the body.
    """
    names = humanoid.LANDMARK_NAMES
    if not 4 <= count <= len(names):
        raise InputError(f"landmark count must lie in [4, {len(names)}], got {count}")
    index = np.round(np.linspace(0, len(names) - 1, count)).astype(int)
    return [names[i] for i in index]


def landmarks_of(rig, names, vertices=None) -> dict[str, np.ndarray]:
    """Positions of named landmarks on a rig (rest pose unless ``vertices`` given)."""
    V = rig.vertices if vertices is None else vertices
    return {name: V[rig.landmarks[name]].copy() for name in names}


def template_cage(V, F, faces: int = 196, seed: int = 0):
    """A cage of about ``faces`` faces around a humanoid (:func:`cagekit.fit_cage`)."""
    from cagekit.fitting import fit_cage

    return fit_cage(V, F, faces=faces, seed=seed)


def write(out_dir, *, poses: int = 20, train_poses: int = 1000, seed: int = 0,
          landmarks: int = 80, cage_faces: int = 196, resolution: float = 1.0,
          bodies=humanoid.NOVEL_BODIES) -> dict:
    """Write the data set described in the module docstring.

    Parameters
    ----------
    out_dir : str or os.PathLike
        Created if missing; files already there are replaced (atomically).
    poses, train_poses : int
        Test poses (with ground truth per body) and training poses of the template.
    seed : int
        Seed of the training poses and the cage fit; ``seed + train_poses`` must stay
        below :data:`TEST_POSE_SEED`.
    landmarks : int
        Landmarks written per body (:func:`landmark_names`).
    cage_faces : int
        Face budget of the template's cage.
    resolution : float
        Mesh resolution of the bodies.
    bodies : sequence of str
        Novel bodies (names of ``humanoid.BODY_SHAPES``).

    Returns
    -------
    dict
        Counts and the template cage's size.
    """
    if seed < 0 or seed + train_poses > TEST_POSE_SEED:
        raise InputError(f"--seed plus --train-poses must stay in [0, {TEST_POSE_SEED}]")
    names = landmark_names(landmarks)
    out = Path(out_dir)
    for folder in ("characters", "poses", "train", *(f"truth/{b}" for b in bodies)):
        (out / folder).mkdir(parents=True, exist_ok=True)
    template = humanoid.rig("template", resolution=resolution)
    F = template.faces
    io.save_mesh(out / "template.obj", template.vertices, F)
    cage_v, cage_f = template_cage(template.vertices, F, cage_faces, seed)
    io.save_mesh(out / "template_cage.obj", cage_v, cage_f)
    save_landmarks(out / "template_landmarks.json", landmarks_of(template, names))
    rigs = {body: humanoid.rig(body, resolution=resolution) for body in bodies}
    for body, rig in rigs.items():
        io.save_mesh(out / "characters" / f"{body}.obj", rig.vertices, F)
        save_landmarks(out / "characters" / f"{body}_landmarks.json",
                       landmarks_of(rig, names))
    for i in range(poses):
        pose = humanoid.random_pose(TEST_POSE_SEED + i)
        io.save_mesh(out / "poses" / f"pose_{i:03d}.obj", template.pose(pose), F)
        for body, rig in rigs.items():
            io.save_mesh(out / "truth" / body / f"pose_{i:03d}.obj", rig.pose(pose), F)
    for i in range(train_poses):
        pose = humanoid.random_pose(seed + i)
        io.save_mesh(out / "train" / f"pose_{i:04d}.ply", template.pose(pose), F)
    summary = {"out_dir": str(out), "bodies": list(bodies), "poses": poses,
               "train_poses": train_poses, "landmarks": len(names),
               "template_vertices": len(template.vertices),
               "cage_vertices": len(cage_v), "cage_faces": len(cage_f), "seed": seed}
    with atomic_output(out / "manifest.json") as tmp, open(tmp, "w") as fh:
        json.dump(summary, fh, indent=2)
        fh.write("\n")
    return summary


@click.command(cls=Command, context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("out_dir", type=click.Path(file_okay=False))
@click.option("--poses", default=20, show_default=True, type=click.IntRange(min=0),
              help="Test poses of the template, each with ground truth for every body.")
@click.option("--train-poses", default=1000, show_default=True, type=click.IntRange(min=0),
              help="Training poses of the template (for cagekit train --fixed-source).")
@click.option("--landmarks", default=80, show_default=True, type=click.IntRange(min=4),
              help="Landmarks per body.")
@click.option("--cage-faces", default=196, show_default=True, type=click.IntRange(min=20),
              help="Face budget of the template's cage (196 faces: 100 vertices).")
@click.option("--resolution", default=1.0, show_default=True,
              type=FiniteFloatRange(min=0.25, max=4.0), help="Mesh resolution of the bodies.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0))
@json_option
@debug_option
def main(out_dir, poses, train_poses, landmarks, cage_faces, resolution, seed, as_json):
    """Write posed humanoids with ground truth to OUT_DIR (see the module docstring)."""
    summary = write(out_dir, poses=poses, train_poses=train_poses, seed=seed,
                    landmarks=landmarks, cage_faces=cage_faces, resolution=resolution)
    if as_json:
        emit_json(summary)
    else:
        click.echo(f"wrote {out_dir}: template ({summary['template_vertices']} vertices, "
                   f"cage of {summary['cage_vertices']} vertices), {len(summary['bodies'])} "
                   f"bodies, {poses} test poses, {train_poses} training poses")


if __name__ == "__main__":
    main(prog_name="python -m apps.humanoid_data")
