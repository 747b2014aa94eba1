"""Posed humanoids with ground truth for deformation transfer (files on disk).

Writes, from :mod:`cagekit.datasets.humanoid` and a seed, what ``cagekit transfer`` and
``cagekit train --fixed-source`` need, and the ground truth that judges a transfer::

    OUT_DIR/template.obj                 the template body in rest pose (T-pose)
    OUT_DIR/template_cage.obj            its cage (--cage artist: one tube per limb,
                                         cagekit.datasets.humanoid_cage; --cage fit:
                                         cagekit.fit_cage with --cage-faces faces)
    OUT_DIR/template_landmarks.json      --landmarks named landmarks on it
    OUT_DIR/characters/<body>.obj        bodies in the template's rest pose and mesh
    OUT_DIR/characters/<body>_landmarks.json   (the same landmark vertices)
    OUT_DIR/characters/<name>.obj        novel characters: rest poses, meshes and surface
    OUT_DIR/characters/<name>.picked     landmarks of their own (cagekit.datasets.characters)
    OUT_DIR/poses/pose_000.obj ...       the template in --poses test poses
    OUT_DIR/reverse/pose_00.obj ...      the template in rest-like poses (REVERSE_POSES),
    OUT_DIR/reverse/pose_00_cage.obj     with its cage and landmarks posed with it: the
    OUT_DIR/reverse/pose_00_landmarks.json   examples pose -> rest (target: the T-pose)
    OUT_DIR/truth/<body>/pose_000.obj    each body posed with the same joint rotations
    OUT_DIR/truth/<name>/t_pose.obj      each novel character in the template's rest pose
    OUT_DIR/train/pose_0000.ply ...      the template in --train-poses other poses

Test pose ``i`` is ``random_pose(TEST_POSE_SEED + i)`` and training pose ``i`` is
``random_pose(seed + i)`` (seeds below ``TEST_POSE_SEED``), so the two never share a pose.
The template's poses share its faces. The cage of a reverse pose is the template cage moved
by the rig's skinning (each cage vertex takes the mean weights of its 8 nearest template
vertices, the fingers' given to the wrist), as an artist's rigged cage would move; it is
checked (no self-intersection, the posed template inside). The test poses bend knees and
elbows too far for that (the skinned cage folds), so the reverse examples are rest-like
poses, as a template's rest pose and T-pose are. Usage::

    python -m apps.humanoid_data OUT_DIR [--poses 20] [--train-poses 1000] [--seed 0]
        [--characters NAME,...] [--no-truth] [--no-reverse]

Only what ``cagekit transfer`` reads, for one character (20 MB instead of 810)::

    python -m apps.humanoid_data OUT_DIR --characters relaxed --train-poses 0 --no-truth \
        --no-reverse
"""

from __future__ import annotations

import contextlib
import json
import re
from pathlib import Path

import click
import numpy as np

from cagekit import io
from cagekit.cli.common import Command, FiniteFloatRange, debug_option, emit_json, json_option
from cagekit.datasets import characters, humanoid, named_poses
from cagekit.errors import InputError
from cagekit.io.files import atomic_output, output_folder
from cagekit.io.landmarks import save_landmarks, save_picked

__all__ = ["REVERSE_POSES", "TEST_POSE_SEED", "choose_characters", "landmark_names",
           "landmarks_of", "posed_cage", "template_cage", "write"]

#: seed of the first test pose; training poses use seeds below it (the test poses are
#: named poses of ``cagekit transfer``: humanoid:pose_000, ...)
TEST_POSE_SEED = named_poses.TEST_POSE_SEED
#: the reverse examples' poses (rest-like, :func:`cagekit.datasets.characters.rest_pose`)
REVERSE_POSES = ({"arms": -30}, {"arms": 20, "legs": 5},
                 {"arms": -15, "legs": 10, "turn": -8}, {"arms": 35, "elbows": 20},
                 {"arms": -40, "legs": 3})


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


def choose_characters(chosen: str | None) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The bodies and the novel characters named by ``--characters``.

    Parameters
    ----------
    chosen : str or None
        Comma-separated names of bodies (``humanoid.NOVEL_BODIES``, ``UNLIKE_BODIES``) and
        novel characters (``characters.CHARACTERS``); None: all of them.

    Returns
    -------
    (tuple of str, tuple of str)
        The bodies, then the novel characters, each in the order given.

    Raises
    ------
    InputError
        A name that is neither, or no name at all.

    Examples
    --------
    >>> choose_characters("relaxed,stocky")
    (('stocky',), ('relaxed',))
    """
    bodies = (*humanoid.NOVEL_BODIES, *humanoid.UNLIKE_BODIES)
    novel = tuple(characters.CHARACTERS)
    if chosen is None:
        return bodies, novel
    names = [name.strip() for name in chosen.split(",") if name.strip()]
    unknown = [name for name in names if name not in (*bodies, *novel)]
    if unknown or not names:
        raise InputError(f"--characters: unknown {', '.join(unknown) or 'empty list'}; "
                         f"choose from {', '.join((*bodies, *novel))}")
    return (tuple(n for n in names if n in bodies), tuple(n for n in names if n in novel))


def landmarks_of(rig, names, vertices=None) -> dict[str, np.ndarray]:
    """Positions of named landmarks on a rig (rest pose unless ``vertices`` given)."""
    V = rig.vertices if vertices is None else vertices
    return {name: V[rig.landmarks[name]].copy() for name in names}


def template_cage(rig, *, kind: str = "artist", faces: int = 196, seed: int = 0):
    """The template's cage: ``"artist"`` (one tube per limb,
    :func:`cagekit.datasets.humanoid_cage.humanoid_cage`) or ``"fit"``
    (:func:`cagekit.fit_cage` with about ``faces`` faces)."""
    if kind == "artist":
        from cagekit.datasets.humanoid_cage import humanoid_cage

        return humanoid_cage(rig)
    if kind == "fit":
        from cagekit.cage.fitting import fit_cage

        cage = fit_cage(rig.vertices, rig.faces, faces=faces, seed=seed, report=False)
        return cage.vertices, cage.faces
    raise InputError(f"cage must be 'artist' or 'fit', got {kind!r}")


def posed_cage(rig, cage_v, cage_f, pose, neighbours: int = 8) -> np.ndarray:
    """The cage moved by the rig's skinning into ``pose`` (module docstring), checked.

    Parameters
    ----------
    rig : cagekit.datasets.humanoid.Rig
    cage_v : (k, 3) array_like of float
        The cage around the rig's rest pose.
    cage_f : (m, 3) array_like of int
    pose : dict[str, array_like]
        Joint rotations, as :meth:`~cagekit.datasets.humanoid.Rig.pose` takes them.
    neighbours : int, default 8
        Template vertices whose mean skinning weights a cage vertex takes.

    Returns
    -------
    (k, 3) float64

    Raises
    ------
    CageError
        The posed cage intersects itself or leaves the posed rig outside.
    """
    from scipy.spatial import cKDTree

    from cagekit.cage import cage_encloses, check_cage
    from cagekit.errors import CageError

    _, nearest = cKDTree(rig.vertices).query(cage_v, k=neighbours)
    weights = rig.weights[nearest].mean(axis=1)
    for j, name in enumerate(humanoid.JOINTS):
        side, base = name[:2], name[2:]
        if side in ("l_", "r_") and base[:-1] in characters.FINGERS:
            weights[:, humanoid.JOINTS.index(side + "wrist")] += weights[:, j]
            weights[:, j] = 0.0
    skinned = humanoid.Rig(rig.shape, np.asarray(cage_v, np.float64), None, rig.joints,
                           weights, {}, {})
    posed = skinned.pose(pose)
    check_cage(posed, cage_f)
    if not cage_encloses(rig.pose(pose), posed, cage_f):
        raise CageError("the skinned cage leaves part of the posed template outside")
    return posed


def write(out_dir, *, poses: int = 20, train_poses: int = 1000, seed: int = 0,
          landmarks: int = 100, cage: str = "artist", cage_faces: int = 196,
          resolution: float = 1.0, bodies=(*humanoid.NOVEL_BODIES, *humanoid.UNLIKE_BODIES),
          novel=tuple(characters.CHARACTERS), reverse: bool = True,
          truth: bool = True) -> dict:
    """Write the data set described in the module docstring.

    Parameters
    ----------
    out_dir : str or os.PathLike
        Created if missing; files already there are replaced (atomically), and the
        numbered poses of an earlier run beyond this run's counts are removed.
    poses, train_poses : int
        Test poses (with ground truth per body) and training poses of the template.
    seed : int
        Seed of the training poses and the cage fit; ``seed + train_poses`` must stay
        below :data:`TEST_POSE_SEED`.
    landmarks : int
        Landmarks written per body (:func:`landmark_names`).
    cage : {"artist", "fit"}
        The template's cage (:func:`template_cage`); ``cage_faces`` is the budget of "fit".
    resolution : float
        Mesh resolution of the template and the bodies sharing its mesh.
    bodies : sequence of str
        Bodies in the template's rest pose and mesh (names of ``humanoid.BODY_SHAPES``).
    novel : sequence of str
        Novel characters (names of :data:`cagekit.datasets.characters.CHARACTERS`).
    reverse : bool
        Write the reverse examples (:data:`REVERSE_POSES`).
    truth : bool
        Write the ground truth (``truth/``: each body and novel character in each test
        pose, the novel characters in the T-pose).

    Returns
    -------
    dict
        Counts and the template cage's size.
    """
    if seed < 0 or seed + train_poses > TEST_POSE_SEED:
        raise InputError(f"--seed plus --train-poses must stay in [0, {TEST_POSE_SEED}]")
    names = landmark_names(landmarks)
    out = Path(out_dir)
    with output_folder(out), contextlib.ExitStack() as made:  # a failed run removes them
        for folder in ("characters", "poses", *(["reverse"] if reverse else []),
                       *(["train"] if train_poses else []),
                       *(f"truth/{b}" for b in ((*bodies, *novel) if truth else ()))):
            made.enter_context(output_folder(out / folder))
        template = humanoid.rig("template", resolution=resolution)
        io.save_mesh(out / "template.obj", template.vertices, template.faces)
        cage_v, cage_f = template_cage(template, kind=cage, faces=cage_faces, seed=seed)
        io.save_mesh(out / "template_cage.obj", cage_v, cage_f)
        save_landmarks(out / "template_landmarks.json", landmarks_of(template, names))
        posable = _write_characters(out, names, bodies, novel, resolution, template.faces,
                                    seed, truth)
        _write_test_poses(out, template, posable if truth else {}, poses)
        if reverse:
            _write_reverse_examples(out, template, (cage_v, cage_f), names)
        for i in range(train_poses):
            pose = humanoid.random_pose(seed + i)
            io.save_mesh(out / "train" / f"pose_{i:04d}.ply", template.pose(pose),
                         template.faces)
    _remove_stale_poses(out, poses, train_poses)
    summary = {"out_dir": str(out), "bodies": list(bodies), "characters": list(novel),
               "poses": poses, "reverse_poses": len(REVERSE_POSES) if reverse else 0,
               "train_poses": train_poses, "landmarks": len(names), "cage": cage,
               "template_vertices": len(template.vertices),
               "cage_vertices": len(cage_v), "cage_faces": len(cage_f), "seed": seed,
               "truth": truth, "resolution": resolution}
    with atomic_output(out / "manifest.json") as tmp, open(tmp, "w") as fh:
        json.dump(summary, fh, indent=2)
        fh.write("\n")
    return summary


def _remove_stale_poses(out: Path, poses: int, train_poses: int) -> list[Path]:
    """Remove the numbered poses an earlier run into ``out`` wrote beyond this run's counts
    (``poses/pose_005.obj`` after a rerun with ``--poses 5``): ``cagekit transfer ...
    poses/`` would take them for this run's. Only files named as this module names them go.
    Returns the files removed."""
    def numbered(folder: Path, ext: str, digits: int, count: int) -> list[Path]:
        name = re.compile(rf"pose_(\d{{{digits},}}){ext}")  # as f"pose_{i:0{digits}d}"
        return [f for f in folder.glob(f"pose_*{ext}")
                if (m := name.fullmatch(f.name)) and int(m.group(1)) >= count]

    stale = [f for folder in [out / "poses", *sorted((out / "truth").glob("*"))]
             for f in numbered(folder, ".obj", 3, poses)]
    stale += numbered(out / "train", ".ply", 4, train_poses)
    for f in stale:
        f.unlink()
    return stale


def _write_characters(out, names, bodies, novel, resolution, faces, seed, truth) -> dict:
    """The bodies (template mesh) and the novel characters in rest pose, their landmarks
    and (with ``truth``) the novel ones' T-pose; returns name -> (pose function, faces)."""
    posable = {}
    for body in bodies:
        rig = humanoid.rig(body, resolution=resolution)
        io.save_mesh(out / "characters" / f"{body}.obj", rig.vertices, faces)
        save_landmarks(out / "characters" / f"{body}_landmarks.json", landmarks_of(rig, names))
        posable[body] = (rig.pose, faces)
    for name in novel:
        char = characters.character(name, labels=names, seed=seed)
        io.save_mesh(out / "characters" / f"{name}.obj", char.vertices, char.faces)
        save_picked(out / "characters" / f"{name}.picked", char.landmarks)
        if truth:
            io.save_mesh(out / "truth" / name / "t_pose.obj", char.truth({}), char.faces)
        posable[name] = (char.truth, char.faces)
    return posable


def _write_test_poses(out, template, posable, poses) -> None:
    """The template in each test pose, and every character in it (the ground truth)."""
    for i in range(poses):
        pose = humanoid.random_pose(TEST_POSE_SEED + i)
        io.save_mesh(out / "poses" / f"pose_{i:03d}.obj", template.pose(pose), template.faces)
        for name, (pose_of, faces) in posable.items():
            io.save_mesh(out / "truth" / name / f"pose_{i:03d}.obj", pose_of(pose), faces)


def _write_reverse_examples(out, template, cage, names) -> None:
    """Each of :data:`REVERSE_POSES`: the posed template, its skinned cage, its landmarks."""
    cage_v, cage_f = cage
    for i, angles in enumerate(REVERSE_POSES):
        pose = characters.rest_pose(**angles)
        posed = template.pose(pose)
        stem = out / "reverse" / f"pose_{i:02d}"
        io.save_mesh(f"{stem}.obj", posed, template.faces)
        io.save_mesh(f"{stem}_cage.obj", posed_cage(template, cage_v, cage_f, pose), cage_f)
        save_landmarks(f"{stem}_landmarks.json", landmarks_of(template, names, posed))


@click.command(cls=Command, context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("out_dir", type=click.Path(file_okay=False))
@click.option("--poses", default=20, show_default=True, type=click.IntRange(min=0),
              help="Test poses of the template, each with ground truth for every body.")
@click.option("--train-poses", default=1000, show_default=True, type=click.IntRange(min=0),
              help="Training poses of the template (for cagekit train --fixed-source).")
@click.option("--landmarks", default=100, show_default=True, type=click.IntRange(min=4),
              help="Landmarks per body.")
@click.option("--cage", type=click.Choice(["artist", "fit"]), default="artist",
              show_default=True, help="The template's cage: one tube per limb, or "
                                      "cagekit.fit_cage.")
@click.option("--cage-faces", default=196, show_default=True, type=click.IntRange(min=20),
              help="Face budget of --cage fit (196 faces: 100 vertices).")
@click.option("--characters", "chosen", default=None, metavar="NAME[,NAME...]",
              help="Only these bodies and novel characters (default: all of them).")
@click.option("--truth/--no-truth", default=True, show_default=True,
              help="Write the ground truth (truth/).")
@click.option("--reverse/--no-reverse", default=True, show_default=True,
              help="Write the reverse examples (reverse/).")
@click.option("--resolution", default=1.0, show_default=True,
              type=FiniteFloatRange(min=0.25, max=4.0), help="Mesh resolution of the bodies.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0))
@json_option
@debug_option
def main(out_dir, poses, train_poses, landmarks, cage, cage_faces, chosen, truth, reverse,
         resolution, seed, as_json):
    """Write posed humanoids with ground truth to OUT_DIR (see the module docstring)."""
    bodies, novel = choose_characters(chosen)
    summary = write(out_dir, poses=poses, train_poses=train_poses, seed=seed,
                    landmarks=landmarks, cage=cage, cage_faces=cage_faces,
                    resolution=resolution, bodies=bodies, novel=novel, truth=truth,
                    reverse=reverse)
    if as_json:
        emit_json(summary)
    else:
        click.echo(f"wrote {out_dir}: template ({summary['template_vertices']} vertices, "
                   f"cage of {summary['cage_vertices']} vertices), {len(summary['bodies'])} "
                   f"bodies, {len(summary['characters'])} novel characters, {poses} test "
                   f"poses, {train_poses} training poses")


if __name__ == "__main__":
    main(prog_name="python -m apps.humanoid_data")
