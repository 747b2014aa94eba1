"""``cagekit amplify``: variations of a collection, on a process pool or a cluster."""

from __future__ import annotations

import os

import click

from cagekit.cli.common import (
    DEFORM_COORDINATE_METHODS,
    FiniteFloatRange,
    bar_callback,
    debug_option,
    emit_json,
    json_option,
    progress_bar,
    start_command,
)
from cagekit.errors import InputError

#: exit status when some items failed (each is recorded in the manifest)
SOME_FAILED = 3


def _pairs_option(ctx, param, value):
    if value is None or value == "all":
        return value
    if not os.path.isfile(value):
        raise InputError("no such pairs file (give a CSV of source,target names or 'all')",
                         value)
    return value


@click.command(short_help="Variations of a collection of shapes (stock amplification).")
@click.argument("collection", metavar="COLLECTION")
@click.option("-o", "--output", "out", required=True, type=click.Path(file_okay=False),
              help="Output folder, outside COLLECTION (created; a rerun into it resumes).")
@click.option("--variations", type=click.IntRange(min=1), default=None,
              help="Number of random (source, target) pairs, drawn with --seed.")
@click.option("--pairs", default=None, callback=_pairs_option, metavar="FILE|all",
              help="A CSV of source,target names (as the manifest names shapes), or 'all'.")
@click.option("--method", type=click.Choice(["cage", "scale", "model"]), default="cage",
              show_default=True, help="Per-pair cage optimisation, box scaling, or a "
              "trained model (--model).")
@click.option("--model", "model_path", type=click.Path(), default=None,
              help="Run folder or checkpoint of cagekit train, or a shipped model's name "
                   "(chairs, tables), with --method model.")
@click.option("--refine", is_flag=True, help="With --model: optimise each predicted cage.")
@click.option("--polish", type=click.IntRange(min=0, max=10_000), default=None,
              help="With --model: evaluations of the per-pair energy that polish each "
                   "network result (default 15, or 0 for a --fixed-source model; 0: none).")
@click.option("--coords", type=click.Choice(list(DEFORM_COORDINATE_METHODS)), default="mvc",
              show_default=True,
              help="Cage coordinates of --method cage (green: organic shapes; see "
                   "docs/benchmarks.md).")
@click.option("--category-by", type=click.Choice(["folder"]), default=None,
              help="Pair shapes only within the same top sub-folder.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="Seed of the pairs and of every item.")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Local worker processes, never more than the items to do or the cores "
                   "(a note says so) [default: every core].")
@click.option("--cluster", default=None, metavar="ADDRESS|local",
              help="Run on a Dask cluster (scheduler address, or 'local' for a local one "
                   "of --workers processes); needs pip install -e '.[cluster]'.")
@click.option("--max-nonaffinity", type=FiniteFloatRange(min=0.0), default=None,
              help="Reject a variation of a multi-part source whose worst part is farther "
                   "than this from an affine map (fraction of its size) [default: 0.02].")
@click.option("--max-cd", type=FiniteFloatRange(min=0.0), default=None,
              help="Reject a variation whose Chamfer distance to its target exceeds this "
                   "(target's unit frame) [default: 0.05].")
@click.option("--max-crossings", type=click.IntRange(min=0), default=None,
              help="Reject a variation in which more pairs of parts than this, apart in "
                   "the source, pass through each other (exact triangle test) [default: 0].")
@click.option("--drop-rejected", is_flag=True, help="Do not keep rejected meshes.")
@click.option("--contact-sheet", "sheet", type=click.Path(dir_okay=False), default=None,
              help="PNG: a grid of the first 24 items (variation, source, target, the "
                   "figures, the status and its reason).")
@json_option
@debug_option
@click.pass_context
def amplify(ctx: click.Context, collection: str, out: str, variations: int | None,
            pairs: str | None, method: str, model_path: str | None, refine: bool,
            polish: int | None, coords: str,
            category_by: str | None, seed: int, workers: int | None, cluster: str | None,
            max_nonaffinity: float | None, max_cd: float | None,
            max_crossings: int | None, drop_rejected: bool,
            sheet: str | None, as_json: bool) -> None:
    """Deform sources of COLLECTION onto targets of it: many plausible variations.

    COLLECTION is a folder of meshes (searched recursively; ShapeNet's
    <synset>/<id>/model.obj works) or synthetic:<family>:<count>. Outputs:
    OUT/variations/<source>__<target>.obj (each shape's shortest distinctive name:
    chairs/oak/oak.obj is oak), OUT/rejected/ (variations the filter rejects),
    OUT/cages/ (each source's cage, fitted once), OUT/manifest.csv and
    OUT/manifest.json (one row per item, rewritten after each). Running the same
    command again redoes only missing items and items whose input files changed.

    The filter rejects a variation whose Chamfer distance to its target exceeds
    --max-cd, whose worst part bends beyond --max-nonaffinity, or in which parts
    (connected pieces of the source, numbered in file order) that were apart in the
    source pass through each other (a chair's legs crossed into a V): the manifest's
    reason column says why ("parts cross: 2 and 3"), crossing_parts and
    crossing_pairs give the pairs.
    Exit status 0 when every item is ok or rejected, 3 when some failed (see the
    manifest's error column), 2 for bad arguments.

    \b
    Example:
      cagekit amplify chairs/ -o variations/ --variations 40 --contact-sheet sheet.png
    """
    from cagekit.batch.amplify import MAX_CD, MAX_CROSSINGS, MAX_NONAFFINITY
    from cagekit.batch.amplify import amplify as run_batch

    start_command(ctx, keep_outputs=True)
    if (variations is None) == (pairs is None):
        raise click.UsageError("give one of --variations N and --pairs FILE|all")
    if (method == "model") != (model_path is not None):
        raise click.UsageError("--method model and --model RUN_DIR go together")
    if refine and method != "model":
        raise click.UsageError("--refine applies to --method model")
    if polish is not None and method != "model":
        raise click.UsageError("--polish polishes a model's predictions: it needs --method "
                               "model")
    if polish is not None and refine:
        raise click.UsageError("--polish applies to --method model without --refine")
    if coords != "mvc" and method != "cage":
        raise click.UsageError("--coords green applies to --method cage")
    if os.path.exists(out) and not os.path.isdir(out):
        raise InputError("exists and is not a folder", out)
    deformer = _deformer(model_path, refine, polish) if method == "model" else None
    with _executor(cluster, workers) as executor, \
            progress_bar("amplify", "item") as bar:
        rows = run_batch(collection, out, variations=variations, pairs=pairs, method=method,
                         deformer=deformer, category_by=category_by, seed=seed,
                         workers=workers, executor=executor,
                         max_nonaffinity=MAX_NONAFFINITY if max_nonaffinity is None
                         else max_nonaffinity,
                         max_cd=MAX_CD if max_cd is None else max_cd,
                         max_crossings=MAX_CROSSINGS if max_crossings is None
                         else max_crossings,
                         drop_rejected=drop_rejected, contact_sheet_path=sheet,
                         progress=bar_callback(bar), coords=coords)
    counts = {status: sum(r["status"] == status for r in rows)
              for status in ("ok", "rejected", "failed")}
    if as_json:
        emit_json({"output": out, "items": len(rows), **counts,
                   "manifest": os.path.join(out, "manifest.csv"), "contact_sheet": sheet})
    else:
        click.echo(f"{len(rows)} items: {counts['ok']} ok, {counts['rejected']} rejected, "
                   f"{counts['failed']} failed; manifest {os.path.join(out, 'manifest.csv')}"
                   + (f"; contact sheet {sheet}" if sheet else ""))
    if counts["failed"]:
        ctx.exit(SOME_FAILED)


def _deformer(model_path, refine, polish=None):
    """The model's deformer; the checkpoint is read here once, so a bad one exits 2."""
    try:
        from cagekit_learn.inference import ModelDeformer
        from cagekit_learn.train import load_model
    except ImportError as exc:
        raise InputError(f"--model needs the learned mode: pip install -e '.[learn]' ({exc})",
                         model_path) from None
    load_model(model_path)
    return ModelDeformer(model_path, refine, polish=polish)


class _executor:
    """The cluster's executor for ``--cluster`` (closed afterwards), else None."""

    def __init__(self, cluster, workers):
        self.cluster, self.workers, self.client = cluster, workers, None

    def __enter__(self):
        if self.cluster is None:
            return None
        from cagekit.batch.amplify import prepare_worker
        from cagekit.batch.cluster import connect

        self.client = connect(self.cluster, self.workers, setup=prepare_worker)
        return self.client.get_executor(pure=False)

    def __exit__(self, *exc):
        if self.client is not None:
            from cagekit.batch.cluster import close

            close(self.client)
        return False
