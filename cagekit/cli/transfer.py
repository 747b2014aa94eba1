"""``cagekit transfer``: carry a template's poses to a novel character given landmarks.

The work is :mod:`cagekit.transfer`; this module reads and checks every input
before any work, writes the outputs atomically at the end and reports. torch is imported
only with ``--model``.
"""

from __future__ import annotations

import json
import time
import warnings
from pathlib import Path

import click

from cagekit.cli.common import (
    COORDINATE_METHODS,
    check_writable,
    debug_option,
    emit_json,
    json_option,
    progress_bar,
    same_file,
    start_command,
)
from cagekit.errors import CagekitWarning, InputError

#: the TEMPLATE_CAGE argument that fits one (cagekit.fit_cage)
AUTO = "auto"
#: a template cage that reproduces one of the template's own poses no closer than this
#: (its largest miss over the template's bounding-box diagonal) is warned about: on 20
#: poses of apps.humanoid_data's template its artist cage misses by 1.5-3.6%, a fitted
#: 200-face cage, whose tubes the limbs share, by 3.8-10.5%, and the character's pose is
#: then visibly wrong (a thigh run into an arm); a fitted 1,000-face cage by 1.4-3.3%
TEMPLATE_MISS_WARN = 0.05


@click.command(name="transfer",
               short_help="Carry a template's poses to a novel character (landmarks).")
@click.argument("template", type=click.Path(dir_okay=False))
@click.argument("template_cage", type=click.Path(dir_okay=False))
@click.argument("template_landmarks", type=click.Path(dir_okay=False))
@click.argument("character", type=click.Path(dir_okay=False))
@click.argument("character_landmarks", type=click.Path(dir_okay=False))
@click.argument("poses", nargs=-1, required=True, type=click.Path())
@click.option("-o", "--output", "out_dir", required=True, type=click.Path(file_okay=False),
              help="Folder for the deformed characters, character_cage.obj and "
                   "report.json (created if missing).")
@click.option("--rule", type=click.Choice(["pose", "offsets"]), default="pose",
              show_default=True,
              help="pose: the template's joint rotations, whatever the character's rest "
                   "pose; offsets: the paper's C_c + A (C_st - C_s).")
@click.option("--root", type=click.Choice(["follow", "ground"]), default="follow",
              show_default=True,
              help="When the example moves the template's whole body (a jump, a crouch): "
                   "follow: the character moves with it, scaled; ground: its lowest point "
                   "stays where it was at rest (along +y).")
@click.option("--model", "model_path", type=click.Path(), default=None,
              help="A fixed-source run (folder or checkpoint.pt) predicts the template's "
                   "cage deformation instead of the per-pair fit.")
@click.option("--align", type=click.Choice(["box", "similarity"]), default="box",
              show_default=True, help="How the two rest poses are aligned before the fit.")
@click.option("--coords", type=click.Choice(list(COORDINATE_METHODS)), default="mvc",
              show_default=True,
              help="How the character follows its cage: mean value or Green coordinates "
                   "(the template's cage fit is the same either way).")
@click.option("--cage-faces", default=200, show_default=True,
              type=click.IntRange(min=80, max=10_000),
              help="Face budget when TEMPLATE_CAGE is 'auto' (the character fit takes "
                   "cages of up to 5,000 vertices).")
@click.option("--grid", "grid_path", type=click.Path(dir_okay=False), default=None,
              help="Also write a PNG: template poses above, transferred character below.")
@click.option("--match-shape", is_flag=True,
              help="A POSE that is another mesh than the template's (other vertex count "
                   "or faces) is matched by its shape (Chamfer distance, cagekit.deform; "
                   "less exact) instead of refused.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0))
@json_option
@debug_option
@click.pass_context
def transfer(ctx: click.Context, template: str, template_cage: str, template_landmarks: str,
             character: str, character_landmarks: str, poses: tuple[str, ...], out_dir: str,
             rule: str, root: str, model_path: str | None, align: str, coords: str,
             cage_faces: int, grid_path: str | None, match_shape: bool, seed: int,
             as_json: bool) -> None:
    """Transfer the TEMPLATE's POSES to a novel CHARACTER given matching landmarks.

    TEMPLATE and CHARACTER are meshes in rest pose (any mesh format cagekit reads, any
    number of parts, open or closed); TEMPLATE_CAGE encloses TEMPLATE, or is 'auto' to fit
    one.
    The landmark files (.picked with 9 or 10 columns, .json or .csv) name points on each,
    matched by label; labels in one file only are reported. POSE is a mesh of the
    template in a new pose (its vertices moved: same count and order, as a rig exports
    it), a folder of them, or a named pose of the humanoid template of python -m
    apps.humanoid_data (humanoid:t_pose, a_pose, arms_up, relaxed, arms_down,
    humanoid:pose_000 ...). The character's cage is checked
    (closed, no self-intersection, every vertex inside); when no valid cage can be
    fitted the command exits with status 2 and writes nothing.

    \b
    Example:
      cagekit transfer template.obj template_cage.obj template.json \\
          robot.obj robot.picked poses/ -o out/robot --grid out/robot.png
    """
    from cagekit.transfer import character as dt

    start_command(ctx)
    start = time.perf_counter()
    pose_paths = _pose_paths(poses)
    names = _output_names(pose_paths, character)
    out = Path(out_dir)
    inputs = [template, template_landmarks, character, character_landmarks,
              *map(str, pose_paths)] + ([] if template_cage == AUTO else [template_cage])
    _check_outputs(out, names, grid_path, inputs)
    loaded = _load(template, template_cage, template_landmarks, character,
                   character_landmarks, pose_paths, model_path, cage_faces, seed)
    t_loaded = time.perf_counter()
    (Vt, Ft), (cage_v, cage_f), marks_t, (Vc, Fc), marks_c, pose_meshes, model = loaded
    if model is None and not match_shape:
        _check_poses_correspond(pose_paths, pose_meshes, (Vt, Ft), template)
    try:
        char = dt.fit_character(Vt, cage_v, cage_f, marks_t, Vc, Fc, marks_c, align=align,
                                coords=coords, template_name=template_landmarks,
                                character_name=character_landmarks)
    except InputError as exc:
        if exc.path is not None:
            raise
        raise type(exc)(exc.problem, character) from None  # name the character
    unmatched = char.match.unmatched(template_landmarks, character_landmarks)
    if unmatched:
        warnings.warn(CagekitWarning(unmatched), stacklevel=1)
    t_fitted = time.perf_counter()
    results = _transfer_poses(char, (Vt, Ft), (cage_v, cage_f), pose_paths, pose_meshes, model,
                              rule, root, seed)
    rows = _write(out, char, character, pose_paths, names, results, pose_meshes, grid_path)
    left_out = _grid(grid_path, (Vt, Ft), char, pose_meshes, results, names)
    seconds = {"load": t_loaded - start, "fit": t_fitted - t_loaded,
               "transfer": time.perf_counter() - t_fitted}
    report = _report(out, char, rows, seconds, start, template, template_cage, character,
                     model, rule, root, align, coords, grid_path, left_out)
    if as_json:
        emit_json(report)
    else:
        fit = char.fit
        click.echo(f"wrote {len(rows)} pose(s), character_cage.obj and report.json to "
                   f"{out}; character cage valid ({fit.rounds} enclosure round(s)), "
                   f"largest landmark error {fit.landmark_errors.max():.3g}"
                   + _binding_summary(fit.checks["coupled"], fit.checks["mended"])
                   + (f"; grid {grid_path}" if grid_path else "")
                   + (f"; the grid leaves out {len(left_out)} of {len(rows)} poses "
                      f"({', '.join(left_out)})" if left_out else ""))


def _binding_summary(coupled: float, mended: float) -> str:
    """The shares bound through folds (with the refusal's threshold) and mended along the
    mesh, one word each; empty when neither.

    Examples
    --------
    >>> _binding_summary(0.082, 0.233)
    '; vertices bound through folds 8.2% (refused above 20%), mended along the mesh 23.3%'
    >>> _binding_summary(0.0, 0.0)
    ''
    """
    from cagekit.transfer.surface_binding import MAX_COUPLED

    if not (coupled or mended):
        return ""
    return (f"; vertices bound through folds {100 * coupled:.1f}% (refused above "
            f"{100 * MAX_COUPLED:.0f}%), mended along the mesh {100 * mended:.1f}%")


def _pose_paths(poses) -> list[Path]:
    from cagekit.datasets.named_poses import is_named_pose, named_pose
    from cagekit_learn.data import find_meshes

    paths: list[Path] = []
    for given in poses:
        path = Path(given)
        if is_named_pose(given) and not path.exists():
            named_pose(given)  # an unknown name is refused before any work
            paths.append(path)
        elif path.is_dir():
            found = find_meshes(path)
            if not found:
                raise InputError("holds no mesh files", path)
            paths.extend(found)
        else:
            paths.append(path)
    return paths


def _output_names(paths, character) -> list[str]:
    """``<pose name><ext>``, in the format that keeps the character's asset (OBJ, PLY or
    GLB: :func:`cagekit.io.kept_extension`)."""
    from cagekit.datasets.named_poses import PREFIX
    from cagekit.io.assets import kept_extension

    ext = kept_extension(character)
    names: list[str] = []
    seen: dict[str, int] = {}
    for path in paths:
        name = f"{path.stem.removeprefix(PREFIX)}{ext}"
        if name in seen:
            raise InputError(f"two poses would both be written as {name} ({seen[name]} and "
                             f"{path}): rename one", path)
        seen[name] = path
        names.append(name)
    return names


def _check_outputs(out, names, grid_path, inputs):
    """Refuse outputs that are inputs and a picture path that cannot be written."""
    outputs = [out / name for name in names] + [out / "character_cage.obj",
                                                 out / "report.json"]
    if grid_path is not None:
        outputs.append(Path(grid_path))
        if not Path(grid_path).resolve().parent.is_dir():
            raise InputError("the picture's folder does not exist", grid_path)
        if Path(grid_path).suffix.lower() != ".png":
            raise InputError("the picture is written as PNG: give a .png file name",
                             grid_path)
    for output in outputs:
        check_writable(output)
        for given in inputs:
            if same_file(str(output), given):
                raise InputError(f"refusing to overwrite the input file {given}; choose "
                                 "another output folder", output)


def _load(template, template_cage, template_landmarks, character, character_landmarks,
          pose_paths, model_path, cage_faces, seed):
    """Every input, read and checked before any work (the model too, when given)."""
    from cagekit import io
    from cagekit.cage import check_cage
    from cagekit.coords.binding import warn_outside
    from cagekit.io.landmarks import load_landmarks

    Vt, Ft = io.load_mesh(template)
    marks_t = load_landmarks(template_landmarks)
    Vc, Fc = io.load_mesh(character)
    marks_c = load_landmarks(character_landmarks)
    pose_meshes = [_load_pose(path, Vt, Ft, template) for path in pose_paths]
    if template_cage == AUTO:
        from cagekit.cage.fitting import fit_cage

        try:
            cage_v, cage_f, _ = fit_cage(Vt, Ft, faces=cage_faces, seed=seed,
                                         report=False)
        except InputError as exc:
            raise InputError(f"cannot fit a cage to the template: {exc.problem}",
                             template) from None
    else:
        cage_v, cage_f = io.load_mesh(template_cage)
        cage_f = check_cage(cage_v, cage_f, name=template_cage)
        warn_outside(Vt, cage_v, cage_f, shape=template, cage=template_cage)
    model = None
    if model_path:
        from cagekit_learn.train import load_model
        from cagekit_learn.transfer import check_model

        model = load_model(model_path)[0]
        check_model(model, Vt, cage_v, model_path)
    return ((Vt, Ft), (cage_v, cage_f), marks_t, (Vc, Fc), marks_c, pose_meshes, model)


def _load_pose(path, Vt, Ft, template):
    """A pose: its mesh file, or the humanoid template in a named pose (at the resolution
    of the manifest.json beside TEMPLATE, written by apps.humanoid_data; else 1)."""
    from cagekit import io
    from cagekit.datasets.named_poses import is_named_pose, posed_template

    if not is_named_pose(str(path)) or path.exists():
        return io.load_mesh(path)
    manifest = Path(template).with_name("manifest.json")
    resolution = 1.0
    if manifest.is_file():
        try:
            resolution = float(json.loads(manifest.read_text()).get("resolution", 1.0))
        except (ValueError, TypeError, AttributeError):
            resolution = 1.0
    try:
        return posed_template(str(path), Vt, Ft, resolution=resolution), Ft
    except InputError as exc:
        raise InputError(exc.problem, template) from None


def _check_poses_correspond(pose_paths, pose_meshes, template_mesh, template) -> None:
    """Refuse a pose that is not the template's mesh moved (other vertex count or faces)."""
    from cagekit.transfer.character import corresponds

    Vt, Ft = template_mesh
    for path, (Vp, Fp) in zip(pose_paths, pose_meshes):
        if not corresponds(Vt, Ft, Vp, Fp):
            what = (f"has {len(Vp)} vertices, the template {len(Vt)}" if len(Vp) != len(Vt)
                    else "has the template's vertex count but other faces")
            raise InputError(f"{what} ({template}): a pose must be the template's mesh "
                             "moved (same vertices, same order, as a rig exports it); "
                             "--match-shape matches another mesh by its shape instead",
                             path)


def _transfer_poses(char, template, template_cage, pose_paths, pose_meshes, model, rule,
                    root, seed):
    """(transferred vertices, seconds) per pose, classical or learned."""
    import numpy as np

    from cagekit.transfer import character as dt

    if model is not None:
        from cagekit_learn.transfer import template_cage_learned
    (Vt, Ft), (cage_v, cage_f) = template, template_cage
    fitter = dt.classical_fitter(Vt, cage_v, cage_f) if model is None else None
    size = float(np.linalg.norm(np.ptp(Vt, axis=0)))
    results = []
    with progress_bar("poses", "pose", total=len(pose_meshes)) as bar:
        for path, (Vp, Fp) in zip(pose_paths, pose_meshes):
            t0 = time.perf_counter()
            miss = None
            try:
                if model is None:
                    deformed = dt.template_cage_classical(Vt, Ft, cage_v, cage_f,
                                                          Vp, Fp, seed=seed, fitter=fitter)
                    if fitter is not None and dt.corresponds(Vt, Ft, Vp, Fp):
                        miss = float(fitter.miss(Vp, deformed).max()) / size
                else:
                    deformed = template_cage_learned(model, Vt, cage_v, (Vp, Fp))
                X = dt.transfer(char, deformed, rule, root=root)
            except InputError as exc:
                raise InputError(exc.problem, path) from None  # name the pose
            results.append((X, time.perf_counter() - t0, miss))
            bar.update(1)
    _warn_template_misses(pose_paths, [miss for _, _, miss in results])
    return results


def _warn_template_misses(pose_paths, misses) -> None:
    """One warning when the template's cage cannot reproduce some of its own poses."""
    measured = [(m, path) for m, path in zip(misses, pose_paths) if m is not None]
    over = [(m, path) for m, path in measured if m > TEMPLATE_MISS_WARN]
    if not over:
        return
    worst, where = max(over, key=lambda pair: pair[0])
    warnings.warn(CagekitWarning(
        f"the template's cage misses {len(over)} of the template's {len(measured)} "
        f"pose(s) by more than {100 * TEMPLATE_MISS_WARN:.0f}% of its size (worst "
        f"{Path(where).name}: {100 * worst:.1f}%): where limbs share its faces it cannot "
        "move them apart, and the character's poses miss as much or more; give a cage with "
        "a tube around each limb, or a larger --cage-faces for 'auto' (each pose's miss is "
        "in report.json)"),
        stacklevel=1)


def _write(out, char, character, pose_paths, names, results, pose_meshes, grid_path):
    """The transferred poses, the character's cage and the picture; a row per pose."""
    from cagekit import io
    from cagekit.io.files import output_folder

    with output_folder(out):
        rows = []
        for path, name, (X, seconds, miss) in zip(pose_paths, names, results):
            io.save_deformed(out / name, X, char.faces, character)  # keeps UVs, materials
            rows.append({"pose": str(path), "output": str(out / name), "seconds": seconds,
                         "template_miss": miss})
        io.save_mesh(out / "character_cage.obj", char.cage_v, char.cage_f)
    return rows


def _grid(grid_path, template, char, pose_meshes, results, names) -> list[str]:
    """Draw the picture (rest poses first) when asked; the names of the poses it leaves
    out."""
    from cagekit.transfer.grid import transfer_grid

    if grid_path is None:
        return []
    return transfer_grid(grid_path, template, (char.vertices, char.faces), pose_meshes,
                         [(X, char.faces) for X, _, _ in results],
                         [Path(name).stem for name in names])


def _report(out, char, rows, seconds, start, template, template_cage, character, model,
            rule, root, align, coords, grid_path, left_out=()) -> dict:
    """Write report.json and return it."""
    from cagekit.io.files import atomic_output
    from cagekit.transfer.surface_binding import MAX_COUPLED

    fit = char.fit
    report = {
        "template": template, "template_cage": template_cage, "character": character,
        "mode": "learned" if model is not None else "classical", "rule": rule, "root": root,
        "align": align, "coords": coords,
        "landmarks": {"matched": len(char.match.labels),
                      "template_only": char.match.source_only,
                      "character_only": char.match.target_only},
        "character_cage_fit": {
            "consistency": fit.consistency, "initial_consistency": fit.initial_consistency,
            "iterations": fit.iterations, "rounds": fit.rounds,
            "contacts": fit.contacts, "seconds": fit.seconds,
            "alignment": fit.alignment.to_dict()},
        "landmark_errors": dict(zip(char.match.labels, fit.landmark_errors.tolist())),
        "character_cage": {**fit.checks, "coupled_limit": MAX_COUPLED},
        "poses": rows,
        "seconds": {**seconds, "total": time.perf_counter() - start},
        "outputs": {"cage": str(out / "character_cage.obj"),
                    "report": str(out / "report.json"), "grid": grid_path},
        "grid_left_out": list(left_out),
    }
    with atomic_output(out / "report.json") as tmp, open(tmp, "w") as fh:
        json.dump(report, fh, indent=2, allow_nan=False)
        fh.write("\n")
    return report
