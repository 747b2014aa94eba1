"""Landmark-driven deformation transfer to a novel character ("Neural Cages", section 4.2).

The template (rest pose, cage ``C_s``, example poses as meshes) and a novel character (rest
pose, landmarks whose labels match the template's): the character's cage ``C_s'`` is fitted
once by MVC consistency (:func:`cagekit_learn.consistency.fit_cage_by_consistency`); each
pose's template cage ``C_(s->t)`` comes from a per-pair fit (classical) or a trained
fixed-source network (``--model``); the character moves with ``C_s' + A (C_(s->t) - C_s)``,
``A`` the linear part of the template-to-character alignment (``--align box``, default, or
``similarity``), so a taller character moves proportionally further. A pose with the
template's vertex count is taken to share its vertex order and is fitted exactly by linear
least squares with every vertex as a correspondence and a small cage-Laplacian term
(:data:`SMOOTHNESS`), which fits better than :func:`cagekit.deform`; other poses use
:func:`cagekit.deform` with Chamfer. Labels in one file only are reported, never dropped
silently; fewer than 4 shared labels is an error. Every input is checked before the fit,
outputs are written atomically at the end, and the report checks the fitted cage (also
warnings on stderr). See docs/architecture.md.

Usage::

    python -m apps.deformation_transfer TEMPLATE TEMPLATE_CAGE TEMPLATE_LANDMARKS \\
        CHARACTER CHARACTER_LANDMARKS POSE... -o OUT_DIR [--model RUN_DIR] [--grid PNG]

writes ``OUT_DIR/<pose name>.obj`` per pose, ``OUT_DIR/character_cage.obj`` and
``OUT_DIR/report.json``.
"""

from __future__ import annotations

import json
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import click
import numpy as np

from cagekit import io
from cagekit.cage import check_cage
from cagekit.cli.common import (
    Command,
    debug_option,
    emit_json,
    json_option,
    progress_bar,
    same_file,
)
from cagekit.coords import bind
from cagekit.coords.binding import warn_outside
from cagekit.deformation import deform
from cagekit.errors import CagekitWarning, InputError
from cagekit.files import atomic_output, output_folder
from cagekit.frame import normalize
from cagekit.geometry import as_vertices, cotangent_laplacian
from cagekit.landmarks import LandmarkMatch, load_landmarks, match_landmarks

__all__ = ["CharacterCage", "fit_character", "corresponds", "check_model",
           "check_fitted_cage", "template_cage_classical", "classical_fitter",
           "template_cage_learned", "transfer_cage", "transfer", "render_grid",
           "SMOOTHNESS"]

#: weight of the cage-Laplacian term of the classical template fit (the cage's own units)
SMOOTHNESS = 1e-2
#: L-BFGS evaluations of the Chamfer template fit (poses need more than the default 60)
TEMPLATE_EVALUATIONS = 200


@dataclass
class CharacterCage:
    """A novel character bound to its fitted cage.

    Attributes
    ----------
    vertices : (n, 3) float64
        The character in rest pose.
    faces : (m, 3) int64
    template_cage_v : (k, 3) float64
        ``C_s``, in the template's frame.
    cage_v : (k, 3) float64
        ``C_s'``, in the character's frame.
    cage_f : (f, 3) int64
    fit : cagekit_learn.consistency.ConsistencyFit
    match : cagekit.landmarks.LandmarkMatch
    weights : (n, k) float64
        The character's mean value coordinates in ``C_s'``.
    """

    vertices: np.ndarray
    faces: np.ndarray
    template_cage_v: np.ndarray
    cage_v: np.ndarray
    cage_f: np.ndarray
    fit: object
    match: LandmarkMatch
    weights: np.ndarray


def fit_character(template_v, cage_v, cage_f, template_landmarks, character_v,
                  character_f, character_landmarks, *, align: str = "box",
                  max_evaluations: int = 300, template_name=None,
                  character_name=None) -> CharacterCage:
    """Fit the template's cage to a character by MVC consistency and bind the character.

    Parameters
    ----------
    template_v : (n_s, 3) array_like of float
        The template in rest pose (for the box alignment).
    cage_v, cage_f : (k, 3) float, (f, 3) int
        The template's cage ``C_s``.
    template_landmarks, character_landmarks : mapping of str to (3,) float
        Named landmarks of the two rest poses; matched by label (at least 4 shared).
    character_v, character_f : (n, 3) float, (m, 3) int
        The novel character in rest pose.
    align : {"box", "similarity"}, default "box"
        How the rest poses are aligned before the fit (module docstring).
    max_evaluations : int, default 300
    template_name, character_name : str, optional
        The landmark files, named in errors.

    Returns
    -------
    CharacterCage
    """
    from cagekit.alignment import box_alignment, similarity_alignment
    from cagekit_learn.consistency import fit_cage_by_consistency

    match = match_landmarks(template_landmarks, character_landmarks,
                            source_name=template_name, target_name=character_name)
    cage_v = as_vertices(cage_v, "cage_v")
    cage_f = check_cage(cage_v, cage_f)
    character_v = as_vertices(character_v, "character_v")
    names = f"{template_name or 'the template'} and {character_name or 'the character'}"
    if align == "box":
        try:
            alignment = box_alignment(template_v, character_v)
        except InputError as exc:
            raise InputError(f"cannot align the rest poses of {names}: {exc}") from None
    elif align == "similarity":
        try:
            alignment = similarity_alignment(match.source, match.target)
        except InputError as exc:
            raise InputError(f"cannot align the landmarks of {names}: {exc}") from None
    else:
        raise InputError(f"align must be 'box' or 'similarity', got {align!r}")
    fit = fit_cage_by_consistency(cage_v, cage_f, match.source, match.target,
                                  alignment=alignment, max_evaluations=max_evaluations)
    # the fitted cage may fold: check_fitted_cage reports it (and the command warns)
    weights = bind(character_v, fit.cage_v, cage_f, check=False).weights
    return CharacterCage(vertices=character_v, faces=np.asarray(character_f, np.int64),
                         template_cage_v=cage_v, cage_v=fit.cage_v, cage_f=cage_f, fit=fit,
                         match=match, weights=weights)


def corresponds(template, pose) -> bool:
    """True if ``pose`` shares ``template``'s vertex order: same vertex count and, when
    both have faces, the same faces (poses of one rigged character)."""
    Vs, Fs = template[0], template[1] if len(template) > 1 else None
    Vp, Fp = pose[0], pose[1] if len(pose) > 1 else None
    if len(Vs) != len(Vp):
        return False
    if Fs is not None and Fp is not None and len(Fs) and len(Fp):
        return np.array_equal(np.asarray(Fs), np.asarray(Fp))
    return True


def check_model(model, template_v, cage_v, path=None) -> None:
    """Raise :class:`InputError` (naming ``path``) unless ``model`` was trained with
    ``template_v`` as its fixed source and ``cage_v`` as its fixed cage."""
    config = model.config
    if config.fixed_cage_v is None or getattr(config, "fixed_source_points", None) is None:
        raise InputError("the model was not trained with a fixed source and source cage "
                         "(cagekit train --fixed-source TEMPLATE --source-cage CAGE)", path)
    _, cs, ss = normalize(template_v)
    expected = (as_vertices(cage_v, "cage_v") - cs) / ss
    trained = np.asarray(config.fixed_cage_v, dtype=np.float64)
    if trained.shape != expected.shape or not np.allclose(trained, expected, atol=1e-6):
        raise InputError("the model was trained with another template cage (or another "
                         "template)", path)


def check_fitted_cage(character: CharacterCage) -> dict:
    """What could be wrong with a fitted character cage, for the report.

    Returns
    -------
    dict
        ``volume`` (signed, > 0 for an outward cage), ``self_intersecting_faces`` (count,
        pymeshlab), ``outside`` (fraction of the character's vertices with winding number
        below 0.5: there the coordinates extrapolate), and ``problems``: one line for
        each of a non-positive volume, self-intersections and vertices outside.
    """
    from cagekit.cage import self_intersecting_faces, signed_volume, winding_numbers

    volume = float(signed_volume(character.cage_v, character.cage_f))
    crossing = int(self_intersecting_faces(character.cage_v, character.cage_f).sum())
    outside = float(np.mean(winding_numbers(character.vertices, character.cage_v,
                                            character.cage_f) < 0.5))
    problems = []
    if volume <= 0:
        problems.append(f"is inverted (signed volume {volume:.3g})")
    if crossing:
        problems.append(f"intersects itself ({crossing} faces)")
    if outside > 0:
        problems.append(f"leaves {100 * outside:.2f}% of the character's vertices outside "
                        "(their coordinates extrapolate)")
    return {"volume": volume, "self_intersecting_faces": crossing, "outside": outside,
            "problems": problems}


def template_cage_classical(template, cage, pose, *, seed: int = 0,
                            smoothness: float = SMOOTHNESS, fitter=None,
                            max_evaluations: int = TEMPLATE_EVALUATIONS) -> np.ndarray:
    """The template's deformed cage ``C_(s->t)`` by a per-pair cage fit (no training).

    Parameters
    ----------
    template : (V, F) pair
        The template in rest pose.
    cage : (cage_v, cage_f) pair
        ``C_s`` in the template's frame.
    pose : (V, F) pair
        The template in the target pose. When it :func:`corresponds` to the template
        (same vertex count and faces), the cage is the linear least-squares fit
        ``min_C |W C - V_pose|^2 + smoothness |L (C - C_s)|^2`` (``W`` the template's
        mean value coordinates, ``L`` the cage's cotangent Laplacian): the L2 alignment
        with every vertex as a correspondence, solved exactly. Otherwise the pose is
        matched by :func:`cagekit.deform` (Chamfer distance, ``max_evaluations``).
    seed : int, default 0
    smoothness : float, default :data:`SMOOTHNESS`
    fitter : callable, optional
        :func:`classical_fitter` of this template and cage, when already built (for
        many poses).
    max_evaluations : int, default 200

    Returns
    -------
    (k, 3) float64
        ``C_(s->t)`` in the pose's frame (the template's, for poses of one character).
    """
    Vs, Vp = np.asarray(template[0], np.float64), np.asarray(pose[0], np.float64)
    cage_v, cage_f = as_vertices(cage[0], "cage_v"), cage[1]
    if not corresponds(template, pose):
        result = deform(template, pose, cage=cage, method="cage",
                        max_evaluations=max_evaluations, seed=seed)
        return result.deformed_cage_v
    if fitter is None:
        fitter = classical_fitter(Vs, cage_v, cage_f, smoothness=smoothness)
    return fitter(Vp)


def classical_fitter(template_v, cage_v, cage_f, *, smoothness: float = SMOOTHNESS):
    """The least-squares template fit of :func:`template_cage_classical`, factored once.

    ``min_C |W C - V_pose|^2 + smoothness |L (C - C_s)|^2`` has the same matrix for every
    pose of one template; its pseudo-inverse is computed here, and each pose then costs
    one matrix product.

    Parameters
    ----------
    template_v : (n_s, 3) array_like of float
        The template in rest pose.
    cage_v, cage_f : (k, 3) float, (f, 3) int
        ``C_s``.
    smoothness : float, default :data:`SMOOTHNESS`

    Returns
    -------
    callable
        ``fitter(pose_v)``: (n_s, 3) pose vertices in the template's vertex order ->
        (k, 3) float64 ``C_(s->t)``.
    """
    cage_v = as_vertices(cage_v, "cage_v")
    cage_f = check_cage(cage_v, cage_f)
    W = bind(as_vertices(template_v, "template_v"), cage_v, cage_f).weights
    L = cotangent_laplacian(cage_v, cage_f).toarray()
    r = np.sqrt(float(smoothness))
    solve = np.linalg.pinv(np.vstack([W, r * L]))
    anchor = r * (L @ cage_v)

    def fitter(pose_v) -> np.ndarray:
        C = solve @ np.vstack([np.asarray(pose_v, np.float64), anchor])
        if not np.isfinite(C).all():
            raise FloatingPointError("the cage fit produced NaN or inf positions")
        return C

    return fitter


def template_cage_learned(model, template_v, cage_v, pose) -> np.ndarray:
    """The template's deformed cage ``C_(s->t)`` predicted by a fixed-source network.

    Parameters
    ----------
    model : cagekit_learn.networks.NeuralCages
        Trained with ``cagekit train --fixed-source TEMPLATE --source-cage CAGE``.
    template_v : (n_s, 3) array_like of float
        The template in rest pose (the model's fixed source).
    cage_v : (k, 3) array_like of float
        ``C_s``; must be the cage the model was trained with.
    pose : (V, F) pair
        The template in the target pose; sampled at the training's vertex rows when it
        has the trained template's vertex count and the model was trained with them
        (L2), otherwise on its surface.

    Returns
    -------
    (k, 3) float64
        ``C_(s->t)`` in the pose's frame.

    Raises
    ------
    InputError
        The model has no fixed source or was trained with another cage.
    """
    from cagekit_learn.inference import predict_cages

    check_model(model, template_v, cage_v)
    points = len(model.config.fixed_source_points)
    return predict_cages(model, np.asarray(template_v, np.float64), pose, points=points)[1]


def transfer_cage(template_cage_v, deformed_template_cage_v, character_cage_v,
                  alignment) -> np.ndarray:
    """``C_(s'->t') = C_s' + A(C_(s->t) - C_s)``, A the alignment's linear part.

    Parameters
    ----------
    template_cage_v, deformed_template_cage_v, character_cage_v : (k, 3) array_like
        ``C_s``, ``C_(s->t)`` (template frame) and ``C_s'`` (character frame).
    alignment : cagekit.alignment.Similarity
        Template frame -> character frame.

    Returns
    -------
    (k, 3) float64

    Examples
    --------
    >>> from cagekit.alignment import Similarity
    >>> A = Similarity(2.0, np.eye(3), np.zeros(3))
    >>> transfer_cage(np.zeros((1, 3)), np.ones((1, 3)), np.full((1, 3), 5.0), A).tolist()
    [[7.0, 7.0, 7.0]]
    """
    offsets = (as_vertices(deformed_template_cage_v, "deformed_template_cage_v")
               - as_vertices(template_cage_v, "template_cage_v"))
    return as_vertices(character_cage_v, "character_cage_v") + alignment.apply_vectors(offsets)


def transfer(character: CharacterCage, deformed_template_cage_v) -> np.ndarray:
    """The character deformed like the template: (n, 3) float64 vertices.

    Parameters
    ----------
    character : CharacterCage
        From :func:`fit_character`.
    deformed_template_cage_v : (k, 3) array_like of float
        ``C_(s->t)`` from :func:`template_cage_classical` or :func:`template_cage_learned`.
    """
    cage = transfer_cage(character.template_cage_v, deformed_template_cage_v,
                         character.cage_v, character.fit.alignment)
    X = character.weights @ cage
    if not np.isfinite(X).all():
        raise FloatingPointError("the transfer produced NaN or inf positions")
    return X


# ------------------------------------------------------------------------------ command


def _pose_paths(poses) -> list[Path]:
    from cagekit_learn.data import find_meshes

    paths: list[Path] = []
    for given in poses:
        path = Path(given)
        if path.is_dir():
            found = find_meshes(path)
            if not found:
                raise InputError("holds no mesh files", path)
            paths.extend(found)
        else:
            paths.append(path)
    return paths


def _output_names(paths) -> list[str]:
    names, seen = [], {}
    for path in paths:
        name = f"{path.stem}.obj"
        if name in seen:
            raise InputError(f"two poses would both be written as {name} ({seen[name]} and "
                             f"{path}): rename one", path)
        seen[name] = path
        names.append(name)
    return names


def render_grid(path, rows, titles=None, labels=None, panel=(240, 300)) -> None:
    """Rows of meshes in one PNG (atomic): for example template poses above, the
    transferred character below.

    Parameters
    ----------
    path : str or os.PathLike
    rows : sequence of sequences of (V, F)
        Each row drawn side by side in one frame (:func:`cagekit.render.render_meshes`
        with ``same_scale=True``), the rows stacked top to bottom.
    titles : sequence of str, optional
        Column titles, above the first row.
    labels : sequence of str, optional
        One caption per row, below it.
    panel : (int, int)
        Width and height of one panel in pixels.
    """
    from cagekit.render import render_grid as grid

    grid(path, rows, titles=[titles] + [None] * (len(rows) - 1) if titles else None,
         captions=labels, size=panel, same_scale=True, views=((10, -70),))


@click.command(cls=Command, context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("template", type=click.Path(dir_okay=False))
@click.argument("template_cage", type=click.Path(dir_okay=False))
@click.argument("template_landmarks", type=click.Path(dir_okay=False))
@click.argument("character", type=click.Path(dir_okay=False))
@click.argument("character_landmarks", type=click.Path(dir_okay=False))
@click.argument("poses", nargs=-1, required=True, type=click.Path())
@click.option("-o", "--output", "out_dir", required=True, type=click.Path(file_okay=False),
              help="Folder for the deformed characters, character_cage.obj and "
                   "report.json (created if missing).")
@click.option("--model", "model_path", type=click.Path(), default=None,
              help="A fixed-source run (folder or checkpoint.pt) predicts the template's "
                   "cage deformation instead of the per-pair fit.")
@click.option("--align", type=click.Choice(["box", "similarity"]), default="box",
              show_default=True, help="How the two rest poses are aligned before the fit.")
@click.option("--grid", "grid_path", type=click.Path(dir_okay=False), default=None,
              help="Also write a PNG: template poses above, transferred character below.")
@click.option("--max-evaluations", default=300, show_default=True,
              type=click.IntRange(min=1), help="L-BFGS evaluations of the cage fit.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0))
@json_option
@debug_option
def main(template, template_cage, template_landmarks, character, character_landmarks, poses,
         out_dir, model_path, align, grid_path, max_evaluations, seed, as_json):
    """Transfer the TEMPLATE's POSES to a novel CHARACTER given matching landmarks.

    TEMPLATE and CHARACTER are meshes in rest pose; TEMPLATE_CAGE encloses TEMPLATE;
    the landmark files (.picked, .json or .csv) name points on each, matched by label.
    POSE is a mesh of the template in a new pose, or a folder of them.

    \b
    Example:
      python -m apps.deformation_transfer template.obj template_cage.obj template.json \\
          robot.obj robot.json poses/ -o out/robot --grid out/robot.png
    """
    start = time.perf_counter()
    pose_paths = _pose_paths(poses)
    names = _output_names(pose_paths)
    out = Path(out_dir)
    _check_outputs(out, names, grid_path, [template, template_cage, template_landmarks,
                                           character, character_landmarks,
                                           *map(str, pose_paths)])
    inputs = _load(template, template_cage, template_landmarks, character,
                   character_landmarks, pose_paths, model_path)
    loaded = time.perf_counter()
    Vt, Ft, cage_v, cage_f, marks_t, Vc, Fc, marks_c, pose_meshes, model = inputs
    char = fit_character(Vt, cage_v, cage_f, marks_t, Vc, Fc, marks_c, align=align,
                         max_evaluations=max_evaluations, template_name=template_landmarks,
                         character_name=character_landmarks)
    unmatched = char.match.unmatched(template_landmarks, character_landmarks)
    if unmatched:
        warnings.warn(CagekitWarning(unmatched), stacklevel=1)
    cage_check = check_fitted_cage(char)
    for problem in cage_check["problems"]:
        warnings.warn(CagekitWarning(f"the fitted character cage {problem}"), stacklevel=1)
    fitted = time.perf_counter()
    results = _transfer_poses(char, (Vt, Ft), (cage_v, cage_f), pose_meshes, model, seed)
    rows = _write(out, char, pose_paths, names, results, pose_meshes, grid_path)
    seconds = {"load": loaded - start, "fit": fitted - loaded,
               "transfer": time.perf_counter() - fitted}
    _report(out, char, rows, cage_check, seconds, start, template, character, model, align,
            grid_path, as_json)


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
        for given in inputs:
            if same_file(str(output), given):
                raise InputError(f"refusing to overwrite the input file {given}; choose "
                                 "another output folder", output)


def _load(template, template_cage, template_landmarks, character, character_landmarks,
          pose_paths, model_path):
    """Every input, read and checked before any work (the model too, when given)."""
    Vt, Ft = io.load_mesh(template)
    cage_v, cage_f = io.load_mesh(template_cage)
    cage_f = check_cage(cage_v, cage_f, name=template_cage)
    warn_outside(Vt, cage_v, cage_f, shape=template, cage=template_cage)
    marks_t = load_landmarks(template_landmarks)
    Vc, Fc = io.load_mesh(character)
    marks_c = load_landmarks(character_landmarks)
    pose_meshes = [io.load_mesh(path) for path in pose_paths]
    model = None
    if model_path:
        from cagekit_learn.train import load_model

        model = load_model(model_path)[0]
        check_model(model, Vt, cage_v, model_path)
    return Vt, Ft, cage_v, cage_f, marks_t, Vc, Fc, marks_c, pose_meshes, model


def _transfer_poses(char, template, template_cage, pose_meshes, model, seed):
    """(transferred vertices, seconds) per pose, classical or learned."""
    (Vt, Ft), (cage_v, cage_f) = template, template_cage
    fitter = classical_fitter(Vt, cage_v, cage_f) if model is None else None
    results = []
    with progress_bar("poses", "pose", total=len(pose_meshes)) as bar:
        for (Vp, Fp) in pose_meshes:
            t0 = time.perf_counter()
            if model is None:
                deformed = template_cage_classical((Vt, Ft), (cage_v, cage_f), (Vp, Fp),
                                                   seed=seed, fitter=fitter)
            else:
                deformed = template_cage_learned(model, Vt, cage_v, (Vp, Fp))
            results.append((transfer(char, deformed), time.perf_counter() - t0))
            bar.update(1)
    return results


def _write(out, char, pose_paths, names, results, pose_meshes, grid_path):
    """The transferred poses, the character's cage and the picture; a row per pose."""
    with output_folder(out):
        rows = []
        for path, name, (X, seconds) in zip(pose_paths, names, results):
            io.save_mesh(out / name, X, char.faces)
            rows.append({"pose": str(path), "output": str(out / name), "seconds": seconds})
        io.save_mesh(out / "character_cage.obj", char.cage_v, char.cage_f)
        if grid_path is not None:
            transferred = [(X, char.faces) for X, _ in results[:8]]
            render_grid(grid_path, [pose_meshes[:8], transferred],
                        titles=[Path(p).stem for p in pose_paths[:8]],
                        labels=["template", "transferred character"])
    return rows


def _report(out, char, rows, cage_check, seconds, start, template, character, model, align,
            grid_path, as_json):
    """report.json, then one line (or the report as JSON) on stdout."""
    fit = char.fit
    report = {
        "template": template, "character": character,
        "mode": "learned" if model is not None else "classical", "align": align,
        "landmarks": {"matched": len(char.match.labels),
                      "template_only": char.match.source_only,
                      "character_only": char.match.target_only},
        "consistency": {"loss": fit.loss, "mvc_term": fit.mvc_term,
                        "laplacian_term": fit.laplacian_term,
                        "initial_loss": fit.initial_loss, "converged": fit.converged,
                        "tolerance": fit.tolerance, "evaluations": fit.evaluations,
                        "seconds": fit.seconds, "alignment": fit.alignment.to_dict()},
        "landmark_errors": dict(zip(char.match.labels, fit.landmark_errors.tolist())),
        "character_cage": cage_check,
        "poses": rows,
        "seconds": {**seconds, "total": time.perf_counter() - start},
        "outputs": {"cage": str(out / "character_cage.obj"),
                    "report": str(out / "report.json"), "grid": grid_path},
    }
    with atomic_output(out / "report.json") as tmp, open(tmp, "w") as fh:
        json.dump(report, fh, indent=2, allow_nan=False)
        fh.write("\n")
    if as_json:
        emit_json(report)
    else:
        state = "reached" if fit.converged else "NOT reached"
        click.echo(f"wrote {len(rows)} pose(s), character_cage.obj and report.json to "
                   f"{out}; L_consistency {fit.loss:.3g} (< {fit.tolerance:g} {state}), "
                   f"max landmark error {fit.landmark_errors.max():.3g}")


if __name__ == "__main__":
    main(prog_name="python -m apps.deformation_transfer")
