"""``cagekit deform``: deform a source onto a target by moving its cage (or by a model)."""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING

import click

from cagekit.cli.common import (
    DEFORM_COORDINATE_METHODS,
    MAX_FACES,
    MIN_FACES,
    allow_outside_option,
    bar_callback,
    check_output,
    check_outside,
    debug_option,
    emit_json,
    given,
    json_option,
    preview_up_option,
    progress_bar,
    progress_enabled,
    shape_writer,
    start_command,
)
from cagekit.errors import InputError

if TYPE_CHECKING:
    from numpy.typing import ArrayLike


def _parse_weights(ctx, param, values):
    """``NAME=VALUE`` pairs of --weight into a dict, names and values checked."""
    if not values:
        return {}
    from cagekit.deformation import DEFAULT_WEIGHTS

    weights = {}
    for text in values:
        name, sep, value = text.partition("=")
        name = name.strip()
        try:
            number = float(value)
        except ValueError:
            sep = ""
        if not sep:
            raise click.BadParameter(f"expected TERM=VALUE (for example cage=0.5), got {text!r}")
        if name not in DEFAULT_WEIGHTS:
            raise click.BadParameter(f"unknown term {name!r}; terms: "
                                     f"{', '.join(DEFAULT_WEIGHTS)}")
        if not (math.isfinite(number) and number >= 0):
            raise click.BadParameter(f"the weight of {name} must be finite and >= 0, "
                                     f"got {value!r}")
        weights[name] = number
    return weights


def _deform_figures(source, target, result):
    """CD and dCotLap of a result (dCotLap only for a source with faces), in the frames
    the deformation used (``cagekit eval``'s definitions: each shape's own unit frame)."""
    from cagekit.metrics import chamfer, evaluate

    if len(source[1]):
        return evaluate(*source, *target, result.vertices,
                        frames=(result.source_frame, result.target_frame)).as_dict()
    ft = result.target_frame
    cd = chamfer(ft.to_unit(result.vertices), None, ft.to_unit(target[0]), target[1])
    return {"cd": cd, "dcotlap": None, "cd_x1e2": cd * 1e2, "dcotlap_x1e3": None}


def _load_model(path):
    """(model, samples per shape) of a checkpoint; one clear line if torch is missing."""
    try:
        from cagekit_learn.train import load_model
    except ImportError as exc:
        raise InputError(f"--model needs the learned mode: pip install -e '.[learn]' ({exc})",
                         path) from None
    model, payload = load_model(path)
    return model, int(payload.get("config", {}).get("points", 1024))


def _deformed_cage_path(path: str) -> str:
    stem, ext = os.path.splitext(path)
    return f"{stem}_deformed{ext}"


def _load_landmark_pair(src_path, tgt_path):
    """The positions of the labels both files share, in the source file's order.

    Labels in one file only (real files misspell a few) are left out, listed in one
    warning line; fewer than 4 shared labels are refused.
    """
    import warnings

    from cagekit.errors import CagekitWarning
    from cagekit.io.landmarks import load_landmarks, match_landmarks

    match = match_landmarks(load_landmarks(src_path), load_landmarks(tgt_path),
                            source_name=src_path, target_name=tgt_path)
    unmatched = match.unmatched(src_path, tgt_path)
    if unmatched:
        warnings.warn(CagekitWarning(unmatched), stacklevel=2)
    return match.source, match.target


@click.command(short_help="Deform SOURCE to take TARGET's shape by moving its cage.")
@click.argument("source", type=click.Path(dir_okay=False))
@click.argument("target", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out", required=True, type=click.Path(dir_okay=False),
              help="Deformed source to write (in TARGET's frame and units).")
@click.option("--method", type=click.Choice(["cage", "scale", "nricp"]), default="cage",
              show_default=True,
              help="cage: optimise the cage; scale: map the bounding boxes; nricp: "
                   "trimesh's nricp_amberg (baselines).")
@click.option("--cage", "cage_path", type=click.Path(dir_okay=False), default=None,
              help="SOURCE's cage (closed, around it); fitted with fit-cage when left out.")
@allow_outside_option
@click.option("--faces", default=200, show_default=True,
              type=click.IntRange(min=MIN_FACES, max=MAX_FACES),
              help="Face budget of the fitted cage (without --cage; with --model, of "
                   "the cage fitted where the predicted one cannot be used).")
@click.option("--save-cage", type=click.Path(dir_okay=False), default=None,
              help="Write the source cage here and the deformed cage beside it "
                   "(name + '_deformed').")
@click.option("--symmetry", type=click.Choice(["x", "y", "z", "none"]), default="none",
              show_default=True, help="Axis normal to SOURCE's plane of symmetry.")
@click.option("--landmarks", nargs=2, type=click.Path(dir_okay=False), default=None,
              metavar="SRC TGT",
              help="Landmark files (.picked, .json, .csv) of SOURCE and TARGET; the labels "
                   "they share (4 at least) replace Chamfer as the alignment term.")
@click.option("--weight", "weights", multiple=True, callback=_parse_weights,
              metavar="TERM=VALUE",
              help="Energy weight (repeatable): chamfer, landmarks, p2f, normal, "
                   "symmetry, cage, parts (each part of a multi-part source kept affine; "
                   "parts=0 lets parts bend), detail (the change of the source's "
                   "cotangent Laplacian).")
@click.option("--reference", type=click.Choice(["aligned", "source"]), default="aligned",
              show_default=True,
              help="Shape and cage terms compare with the box-aligned source (stretch "
                   "is free) or with the source as given (the paper's; cage weight 1).")
@click.option("--target-kind", type=click.Choice(["full", "partial"]), default="full",
              show_default=True,
              help="partial: TARGET is a scan seen from one side (the alignment pulls every "
                   "scanned point onto SOURCE, SOURCE onto the scan at a tenth of the "
                   "weight, so SOURCE's unseen side is not squashed).")
@click.option("--coords", type=click.Choice(list(DEFORM_COORDINATE_METHODS)), default="mvc",
              show_default=True,
              help="Cage coordinates: mean value (affine-invariant) or Green (exact for "
                   "similarities; details keep their proportions under stretch).")
@click.option("--preview", type=click.Path(dir_okay=False), default=None,
              help="Draw source, target and result side by side (cages as wireframes) "
                   "into this PNG; a cage over 1.5x its shape's size (a model's) is cut "
                   "at the panels' edges, so that the shapes fill them.")
@click.option("--model", "model_path", type=click.Path(), default=None,
              help="A trained model (RUN_DIR or RUN_DIR/checkpoint.pt of `cagekit train`, "
                   "or a shipped model's name: chairs, tables; needs cagekit[learn]): "
                   "predict the cage and its deformation in one forward pass.")
@click.option("--refine", is_flag=True,
              help="With --model: then optimise the predicted cage per pair (as --method "
                   "cage, started from the prediction).")
@click.option("--polish", type=click.IntRange(min=0, max=10_000), default=None,
              help="With --model: evaluations of the per-pair energy that polish the "
                   "network's result (default 15 for a model of shapes, 0 for one "
                   "trained with --fixed-source; 0: the network's result as it is).")
@click.option("--keep-prediction", is_flag=True,
              help="With --model: write the network's (polished) result even where the "
                   "predicted cage scaled onto TARGET's box comes nearer TARGET (by "
                   "default that scaling is written instead, with a warning).")
@preview_up_option
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="Seed of the samples (and of the fitted cage).")
@json_option
@debug_option
@click.pass_context
def deform(ctx: click.Context, source: str, target: str, out: str, method: str,
           cage_path: str | None, allow_outside: bool, faces: int, save_cage: str | None,
           symmetry: str,
           landmarks: tuple[str, str] | None, weights: dict[str, float], reference: str,
           target_kind: str, coords: str, model_path: str | None, refine: bool,
           polish: int | None, keep_prediction: bool, preview: str | None, up: str, seed: int,
           as_json: bool) -> None:
    """Deform SOURCE so that it takes TARGET's shape, keeping SOURCE's detail.

    SOURCE is a mesh (or a point cloud, whose points move); TARGET a mesh or a point
    cloud (noisy or coarse; a scan seen from one side wants --target-kind partial). With
    --method cage (the default) SOURCE's cage is moved to minimise Chamfer distance to
    TARGET plus the paper's shape-preservation and cage terms (see
    cagekit/deformation/); the result is written in TARGET's frame and units. --json
    prints CD and dCotLap (as `cagekit eval`), each term's value, the iterations and
    seconds.

    \b
    Example:
      cagekit deform chair.obj tall_chair.obj -o out.obj --symmetry x --preview out.png
    """
    start_command(ctx)
    outputs = _check_options(ctx, source, target, out, method, cage_path, save_cage,
                             symmetry, landmarks, weights, model_path, refine, preview)
    if model_path and coords != "mvc":
        raise click.UsageError("--coords green applies to the per-pair optimisation only; "
                               "a trained model binds with the coordinates it was "
                               "trained with (cagekit train --coords)")
    if allow_outside and cage_path is None:
        raise click.UsageError("--allow-outside applies to a given --cage")
    if model_path and target_kind != "full":
        raise click.UsageError("--target-kind partial applies to the per-pair optimisation "
                               "only, not to --model")
    if keep_prediction and (not model_path or refine):
        raise click.UsageError("--keep-prediction applies to --model without --refine")
    if polish is not None and not model_path:
        raise click.UsageError("--polish polishes a prediction: it needs --model")
    if polish is not None and refine:
        raise click.UsageError("--polish applies to --model without --refine")
    from cagekit.deformation import DeformOptions

    model = _load_model(model_path) if model_path else None
    src, tgt, cage, pairs, write = _load_inputs(source, target, out, cage_path, landmarks,
                                                allow_outside)
    options = DeformOptions(method=method, symmetry=None if symmetry == "none" else symmetry,
                            weights=weights or None, reference=reference, coords=coords,
                            faces=faces, seed=seed, check=False, target_kind=target_kind)
    with progress_bar("deform", "eval",
                      enabled=progress_enabled() and method == "cage"
                      and (model is None or refine)) as bar:
        try:
            result = _run(src, tgt, cage, pairs, model, refine, options, bar_callback(bar),
                          keep_prediction, polish)
        except InputError as exc:
            raise _blamed(exc, source, target, cage_path, landmarks) from None
    figures = _checked_figures(src, tgt, result, source, out)
    write(out, result.vertices, result.faces)
    _report(src, tgt, result, figures, outputs, source, target, up, as_json)


def _check_options(ctx, source, target, out, method, cage_path, save_cage, symmetry,
                   landmarks, weights, model_path, refine, preview):
    """Refuse option combinations and outputs before any work; returns the output paths."""
    from cagekit import io

    inputs = (source, target, cage_path, model_path, *(landmarks or ()))
    check_output(out, inputs)
    if method != "cage" and (cage_path or save_cage or landmarks or weights
                             or symmetry != "none" or model_path):
        raise click.UsageError("--cage, --save-cage, --landmarks, --weight, --symmetry and "
                               "--model apply to --method cage only")
    if given(ctx, "faces") and (cage_path or method != "cage"):
        raise click.UsageError("--faces sets the fitted cage's budget: it does not apply "
                               "to a given --cage or to --method scale or nricp")
    if refine and not model_path:
        raise click.UsageError("--refine refines a prediction: it needs --model")
    if model_path and (cage_path or landmarks):
        raise click.UsageError("--model predicts the cage: --cage and --landmarks do not "
                               "apply")
    tuned = (weights or symmetry != "none"
             or given(ctx, "reference"))
    if model_path and tuned and not refine:
        raise click.UsageError("--weight, --symmetry and --reference tune the per-pair "
                               "optimisation: with --model they need --refine")
    outputs = {"out": out, "save_cage": save_cage, "preview": preview}
    if save_cage is not None:
        mesh_exts = set(io.WRITTEN_MESH_EXTENSIONS)
        for path in (save_cage, _deformed_cage_path(save_cage)):
            check_output(path, inputs, extensions=mesh_exts)
    if preview is not None:
        check_output(preview, inputs, extensions={".png"})
    paths = [out] + ([save_cage, _deformed_cage_path(save_cage)] if save_cage else []) + (
        [preview] if preview else [])
    if len({os.path.realpath(p) for p in paths}) < len(paths):
        raise InputError("two outputs would be the same file", out)
    return outputs


def _load_inputs(source, target, out, cage_path, landmarks, allow_outside=False):
    """The two shapes, the checked cage (or None: refused when the source is mostly
    outside it, unless ``allow_outside``), the landmark pair (or None) and the writer of
    the output (its format checked before the target is read)."""
    from cagekit import io
    from cagekit.cage import check_cage

    src = io.load_shape(source)
    write = shape_writer(out, has_faces=len(src[1]) > 0, source=source)
    tgt = io.load_shape(target)
    cage = None
    if cage_path is not None:
        cage_v, cage_f = io.load_mesh(cage_path)
        cage = (cage_v, check_cage(cage_v, cage_f, name=cage_path))
        check_outside(src[0], *cage, shape=source, cage=cage_path, allow=allow_outside)
    pairs = _load_landmark_pair(*landmarks) if landmarks else None
    return src, tgt, cage, pairs, write


def _run(src, tgt, cage, pairs, model, refine, options, progress, keep_prediction=False,
         polish=None):
    """The deformation: per-pair (``cagekit.deform``) or by the model."""
    import warnings

    from cagekit.deformation import deform
    from cagekit.errors import OutsideCageWarning

    if model is not None:
        from cagekit_learn.inference import deform_with_model

        net, points = model
        return deform_with_model(net, *src, *tgt, points=points, seed=options.seed,
                                 refine=refine, options=options, progress=progress,
                                 scaling_fallback=not keep_prediction, polish=polish)
    # a given cage was checked by _load_inputs, with its file name in the messages
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OutsideCageWarning)
        return deform(*src, *tgt, *((None, None) if cage is None else cage), options,
                      landmarks=pairs, progress=progress)


def _blamed(exc, source, target, cage_path, landmarks):
    """The library's error with the file it is about (named by its first words)."""
    if exc.path is not None:
        return exc
    low = exc.problem.lower()
    for role, index, shape in (("source", 0, source), ("target", 1, target)):
        if low.startswith(f"the {role} landmarks") and landmarks:
            problem = exc.problem.replace(f"the {role} shape's", f"{shape}'s")
            return InputError(problem, landmarks[index])
    for role, shape in (("source", source), ("target", target)):
        if low.startswith(f"the {role}:"):  # the file names the shape: drop the role
            return InputError(exc.problem[len(f"the {role}:"):].strip(), shape)
    blamed = (cage_path or source) if "cage" in low else f"{source}, {target}"
    return InputError(exc.problem, blamed)


def _checked_figures(src, tgt, result, source, out):
    """The result's figures, computed before anything is written: a result that cannot be
    measured (its surface collapsed to no area, as when one vertex of the source lies
    orders of magnitude beyond the rest) is refused, naming the source."""
    try:
        return _deform_figures(src, tgt, result)
    except InputError as exc:
        raise InputError(f"the deformed shape is degenerate ({exc.problem}), so nothing "
                         f"was written to {out}; check its coordinates (a vertex far "
                         "from the rest?)", source) from None


#: a cage whose box diagonal exceeds its source's this many times is framed out of the
#: preview (a learned model's predicted cage is about 3x; a fitted one 1.05-1.3x)
LOOSE_CAGE = 1.5


def _loose(cage_v: ArrayLike, V: ArrayLike) -> bool:
    """Whether the cage's bounding-box diagonal is over :data:`LOOSE_CAGE` times its
    shape's (``(k, 3)`` and ``(n, 3)`` float arrays)."""
    from cagekit.geometry.frame import bounding_box, bounding_box_diagonal

    def diagonal(X: ArrayLike) -> float:
        return bounding_box_diagonal(bounding_box(X)[1])

    return diagonal(cage_v) > LOOSE_CAGE * diagonal(V)


def _report(src, tgt, result, figures, outputs, source, target, up, as_json):
    """Write the cages and the preview, then print the figures (a line or JSON)."""
    from cagekit import io

    save_cage, preview = outputs["save_cage"], outputs["preview"]
    if save_cage is not None:
        io.save_mesh(save_cage, result.cage_v, result.cage_f)
        io.save_mesh(_deformed_cage_path(save_cage), result.deformed_cage_v, result.cage_f)
    dcot = figures["dcotlap_x1e3"]
    method = result.method
    caption = (f"{method}: CD x1e2 = {figures['cd_x1e2']:.3f}"
               + ("" if dcot is None else f", dCotLap x1e3 = {dcot:.4f}")
               + f" ({result.seconds:.2f} s)")
    if preview is not None:
        from cagekit.render import render_meshes

        has_cage = result.cage_v is not None
        render_meshes(
            [src, tgt, (result.vertices, result.faces)], preview,
            cages=[(result.cage_v, result.cage_f) if has_cage else None, None,
                   (result.deformed_cage_v, result.cage_f) if has_cage else None],
            titles=[f"source: {os.path.basename(source)}",
                    f"target: {os.path.basename(target)}", f"result ({method})"],
            caption=caption, up=up,
            frame_cages=not (has_cage and _loose(result.cage_v, src[0])))
    if as_json:
        emit_json({"source": source, "target": target, "output": outputs["out"],
                   "method": method,
                   **{k: figures[k] for k in ("cd", "dcotlap", "cd_x1e2", "dcotlap_x1e3")},
                   "losses": result.losses, "weights": result.weights,
                   "energy": result.energy, "iterations": result.iterations,
                   "cage_faces": None if result.cage_f is None else len(result.cage_f),
                   "seconds": result.seconds})
    else:
        click.echo(f"wrote {outputs['out']}: {caption}")
