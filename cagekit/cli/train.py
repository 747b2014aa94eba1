"""``cagekit train``: train the learned cages; also ``torchrun -m cagekit.cli train``."""

from __future__ import annotations

import contextlib
import os

import click

from cagekit.cli.common import (
    FiniteFloatRange,
    debug_option,
    emit_json,
    given,
    json_option,
    progress_enabled,
    start_command,
)
from cagekit.errors import InputError

#: the largest ``--lr``: :data:`cagekit_learn.train.MAX_LR` (a test checks that they are
#: equal; not imported, so that starting the command line imports no torch)
MAX_LR = 1.0
#: the options a resumed run takes from its checkpoint, each with the setting it gives
#: (``model.NAME``: the model config's); given again, they must repeat the stored value
_STORED_OPTIONS = {
    "batch_size": "batch_size", "lr": "lr", "points": "points", "seed": "seed",
    "checkpoint_every": "checkpoint_every", "symmetry": "symmetry", "align": "align",
    "enclosure_weight": "alpha_enclosure", "parts_weight": "alpha_parts",
    "no_augment": "augment", "bottleneck": "model.bottleneck", "coords": "model.coords",
    "nc": "model.nc", "no_box_align": "model.box_align",
}


@click.command(short_help="Train the learned cages (N_c, N_d) on a folder of meshes.")
@click.argument("data", metavar="DATA_DIR")
@click.option("-o", "--output", "run_dir", required=True, type=click.Path(file_okay=False),
              help="Run folder: checkpoint.pt, log.csv (and tensorboard/ when installed).")
@click.option("--epochs", default=100, show_default=True, type=click.IntRange(min=1),
              help="Passes over the training pairs (--max-steps and --minutes stop sooner).")
@click.option("--batch-size", default=8, show_default=True, type=click.IntRange(min=1),
              help="Pairs per step (per process under torchrun).")
@click.option("--lr", default=1e-3, show_default=True,
              type=FiniteFloatRange(min=0, min_open=True, max=MAX_LR),
              help="Adam's learning rate, > 0 and at most 1 (N_c at a tenth of it).")
@click.option("--device", type=click.Choice(["auto", "cpu", "cuda"]), default="auto",
              show_default=True, help="Where to train (auto: a GPU when torch sees one).")
@click.option("--resume", is_flag=True,
              help="Continue the run in --output exactly where it stopped, with the "
                   "same number of processes, on the shapes of DATA_DIR. Its own "
                   "settings: --epochs, --max-steps, --minutes and --device given again "
                   "replace them; any other option given again must repeat its value.")
@click.option("--points", default=1024, show_default=True,
              type=click.IntRange(min=16, max=100_000),
              help="Samples per shape.")
@click.option("--bottleneck", default=256, show_default=True, type=click.IntRange(min=1),
              help="Size of the PointNet code.")
@click.option("--coords", type=click.Choice(["mvc", "green"]), default="mvc",
              show_default=True,
              help="Coordinates the model's cages bind the source with (in training and "
                   "at inference; green drops the paper's MVC term).")
@click.option("--nc", type=click.Choice(["learned", "identity", "source-invariant"]),
              default="learned", show_default=True, help="The N_c variant.")
@click.option("--fixed-source", type=click.Path(dir_okay=False), default=None,
              metavar="TEMPLATE_MESH",
              help="Train with one fixed source: every pair is (TEMPLATE_MESH, a shape of "
                   "DATA_DIR), each shape once per epoch (a character in rest pose and its "
                   "poses). With --align l2 it must share the shapes' vertex order. It is "
                   "never augmented; its samples are stored in the checkpoint.")
@click.option("--source-cage", type=click.Path(dir_okay=False), default=None,
              help="A fixed source cage (mesh file) instead of N_c, for a collection that "
                   "shares one source. With --fixed-source it is in TEMPLATE_MESH's own "
                   "frame (the cage drawn around it); without, in the paper's frame (the "
                   "source normalised to [-1, 1]).")
@click.option("--no-box-align", is_flag=True,
              help="N_d offsets the source cage itself, not its box-aligned stretch.")
@click.option("--symmetry", type=click.Choice(["x", "y", "z", "none"]), default="none",
              show_default=True, help="Add the symmetry loss about this axis.")
@click.option("--align", type=click.Choice(["chamfer", "l2"]), default="chamfer",
              show_default=True,
              help="Alignment loss; l2 needs a collection sampled in correspondence.")
@click.option("--no-augment", is_flag=True, help="No anisotropic scaling augmentation.")
@click.option("--enclosure-weight", default=10.0, show_default=True,
              type=FiniteFloatRange(min=0),
              help="Weight of the term that keeps every source point inside its predicted "
                   "cage (0: the paper's loss, whose cages may leave the source out).")
@click.option("--parts-weight", default=60.0, show_default=True,
              type=FiniteFloatRange(min=0),
              help="Weight of the term that keeps each part of a source mesh (a connected "
                   "component: a leg, a seat) an affine map of itself, as cagekit deform's "
                   "(0: off, the paper's loss, which may bend legs and sag seats).")
@click.option("--checkpoint-every", default=200, show_default=True,
              type=click.IntRange(min=1), help="Steps between checkpoints.")
@click.option("--max-steps", default=None, type=click.IntRange(min=1),
              help="Stop after this many steps in all.")
@click.option("--minutes", default=None, type=FiniteFloatRange(min=0, min_open=True),
              help="Stop (with a checkpoint) after this much training time.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="Seed of the weights, the pairs' order and the samples.")
@json_option
@debug_option
@click.pass_context
def train(ctx: click.Context, data: str, run_dir: str, epochs: int | None, batch_size: int,
          lr: float, device: str | None, resume: bool, points: int, bottleneck: int,
          coords: str, nc: str, fixed_source: str | None, source_cage: str | None,
          no_box_align: bool, symmetry: str, align: str, no_augment: bool,
          enclosure_weight: float, parts_weight: float,
          checkpoint_every: int, max_steps: int | None, minutes: float | None, seed: int,
          as_json: bool) -> None:
    """Train N_c and N_d (the paper's networks) on the meshes under DATA_DIR.

    DATA_DIR is searched recursively for meshes (ShapeNet's layout works as is); each is
    normalised and sampled once, cached in DATA_DIR/.cagekit-cache. `synthetic:chairs:300`
    (or tables, vases) trains on procedural shapes instead. Scale out with
    `torchrun --nproc-per-node N -m cagekit.cli train DATA_DIR -o RUN_DIR`.

    With --fixed-source TEMPLATE_MESH the template is the source of every pair and the
    shapes of DATA_DIR are the targets (the paper's human setting: poses of one character
    with a consistent vertex order, --align l2); --source-cage is then a cage around the
    template in the template's own frame.

    \b
    Example:
      cagekit train synthetic:chairs:300 -o runs/chairs --epochs 50
      cagekit deform a.obj b.obj --model runs/chairs -o out.obj
      cagekit train poses/ --fixed-source rest.obj --source-cage rest_cage.obj \\
          --align l2 -o runs/human
    """
    start_command(ctx, keep_outputs=True)
    try:
        from cagekit_learn.networks import ModelConfig
        from cagekit_learn.train import TrainConfig, load_source_cage
        from cagekit_learn.train import train as run
    except ImportError as exc:
        raise InputError(f"training needs the learned mode: pip install -e '.[learn]' "
                         f"({exc})") from None
    model = ModelConfig(bottleneck=bottleneck, nc=nc, box_align=not no_box_align,
                        coords=coords)
    if source_cage is not None and not resume:  # a resumed run keeps its own cage
        model.fixed_cage_v, model.fixed_cage_f = load_source_cage(source_cage,
                                                                  template=fixed_source)
    if os.path.exists(os.path.join(run_dir, "checkpoint.pt")) and not resume:
        raise InputError("holds a checkpoint already: --resume to continue it, or choose "
                         "another folder", run_dir)
    if resume:  # what was not given again stays as the stopped run had it
        if not given(ctx, "epochs"):
            epochs = None
        if not given(ctx, "device"):
            device = None
    # epochs None (resumed, not given again) keeps the checkpoint's, as train() documents
    config = TrainConfig(
        data=data, run_dir=run_dir, epochs=epochs, batch_size=batch_size, lr=lr,
        points=points, seed=seed, device=device, checkpoint_every=checkpoint_every,
        symmetry=None if symmetry == "none" else symmetry, align=align,
        augment=not no_augment, max_steps=max_steps, max_minutes=minutes,
        alpha_enclosure=enclosure_weight, alpha_parts=parts_weight, model=model.to_dict(),
        fixed_source=fixed_source)
    if resume:
        _refuse_contradictions(ctx, config, source_cage)
    from cagekit.io.files import missing_folders, output_folder

    made = missing_folders(run_dir)
    try:
        with output_folder(run_dir):  # a run that fails before writing leaves no empty folder
            result = run(config, resume=resume, progress=progress_enabled())
    except BaseException:
        _unmake_if_no_checkpoint(run_dir, made)
        raise
    figures = {"run_dir": run_dir, "steps": result.step, "epochs": result.epoch,
               "skipped_steps": result.skipped, "losses": result.last_losses,
               "seconds": result.seconds, "pairs_per_second": result.pairs_per_second}
    if int(os.environ.get("RANK", "0")) != 0:
        return
    if as_json:
        emit_json(figures)
    else:
        loss = result.last_losses.get("loss", float("nan"))
        click.echo(f"trained {result.step} steps ({result.pairs_per_second:.1f} pairs/s, "
                   f"{result.skipped} skipped); last loss {loss:.4g}; wrote "
                   f"{os.path.join(run_dir, 'checkpoint.pt')}")


def _unmake_if_no_checkpoint(run_dir: str, made: list[str]) -> None:
    """After a failed or interrupted run: when it made the run folder (``made``, deepest
    first, from :func:`cagekit.io.files.missing_folders`) and wrote no checkpoint there
    (nothing to resume: a run saves one every ``--checkpoint-every`` steps), remove what
    it wrote (the log, TensorBoard's folder) and the folders it made, each only when then
    empty. A folder that was there before is left as it is; a failure here never hides the
    run's own error."""
    import shutil

    from cagekit.io.files import remove_empty_folders
    from cagekit_learn.checkpoint import CHECKPOINT_NAME
    from cagekit_learn.train import LOG_NAME

    run_dir = os.path.realpath(run_dir)
    if not made or os.path.exists(os.path.join(run_dir, CHECKPOINT_NAME)):
        return
    try:
        with contextlib.suppress(FileNotFoundError):
            os.remove(os.path.join(run_dir, LOG_NAME))
        shutil.rmtree(os.path.join(run_dir, "tensorboard"), ignore_errors=True)
        remove_empty_folders(made)  # another run's files keep their folder
    except Exception:  # noqa: BLE001 - the run's own error is the one to report
        return


def _setting(config, key: str):
    """A setting of a TrainConfig: a field, or ``model.NAME`` of its model config."""
    if key.startswith("model."):
        from cagekit_learn.networks import ModelConfig

        return getattr(ModelConfig.from_dict(config.model), key.removeprefix("model."))
    return getattr(config, key)


def _shown(value) -> str:
    """A setting as its option writes it (``none`` for no symmetry)."""
    return "none" if value is None else str(value)


def _refuse_contradictions(ctx: click.Context, config, source_cage) -> None:
    """InputError (naming the checkpoint) for an option given with ``--resume`` that
    contradicts the checkpoint in ``config.run_dir``.

    Parameters
    ----------
    ctx : click.Context
        The command's, which says which options were given.
    config : cagekit_learn.train.TrainConfig
        The config the options make.
    source_cage : str or None
        ``--source-cage``.

    Raises
    ------
    InputError
        One line: the option, its value and the checkpoint's; or a checkpoint that cannot
        be resumed (:func:`cagekit_learn.train.resume_config`).
    """
    from cagekit_learn.checkpoint import CHECKPOINT_NAME
    from cagekit_learn.train import fixed_source_matches, resume_config, source_cage_matches

    path = os.path.join(config.run_dir, CHECKPOINT_NAME)
    stored = resume_config(config.run_dir)
    params = {param.name: param for param in ctx.command.params}
    for name, key in _STORED_OPTIONS.items():
        if not given(ctx, name):
            continue  # not given: the checkpoint's is taken, nothing to compare
        asked, kept = _setting(config, key), _setting(stored, key)
        if asked == kept:
            continue
        option = params[name].opts[0]
        if getattr(params[name], "is_flag", False):
            raise InputError(f"{option} contradicts the checkpoint's "
                             f"{key.removeprefix('model.')}={kept}", path)
        raise InputError(f"{option} {ctx.params[name]} contradicts the checkpoint's "
                         f"{_shown(kept)}", path)
    if config.fixed_source is not None and not fixed_source_matches(config.fixed_source,
                                                                    stored.model):
        raise InputError(f"--fixed-source {config.fixed_source} contradicts the "
                         f"checkpoint's {_shown(stored.fixed_source)}", path)
    if source_cage is not None and not source_cage_matches(source_cage, stored.model):
        kept = "none" if stored.model.get("fixed_cage_v") is None else "fixed cage"
        raise InputError(f"--source-cage {source_cage} contradicts the checkpoint's {kept}",
                         path)
