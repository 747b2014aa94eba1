"""``cagekit eval``: CD, dCotLap and structure of a deformed shape (docs/architecture.md)."""

from __future__ import annotations

import click

from cagekit.cli.common import (
    debug_option,
    emit_json,
    json_option,
    start_command,
)
from cagekit.errors import InputError

_EVAL_ROLES = ("source", "target", "deformed")


@click.command(name="eval", short_help="CD, dCotLap and structure of a deformed shape.")
@click.argument("source", type=click.Path(dir_okay=False))
@click.argument("target", type=click.Path(dir_okay=False))
@click.argument("deformed", type=click.Path(dir_okay=False))
@click.option("--samples", default=5000, show_default=True,
              type=click.IntRange(min=1, max=1_000_000),
              help="Surface samples per shape for the Chamfer distance (at most 1,000,000).")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="Sampling seed (an integer >= 0).")
@json_option
@debug_option
@click.pass_context
def eval_(ctx: click.Context, source: str, target: str, deformed: str, samples: int, seed: int,
          as_json: bool) -> None:
    """Chamfer distance, dCotLap and structure of DEFORMED (a deformed SOURCE) vs TARGET.

    As the paper's evaluation: TARGET is normalised on its own and DEFORMED mapped by the
    same transform; the normalised SOURCE is the reference for distortion. SOURCE and
    DEFORMED must have the same vertices (count and order); TARGET may be a point cloud.
    Structure (SOURCE against DEFORMED): part non-affinity (each connected part of 30
    vertices or more against its best affine map, over its size), planarity (how far
    adjacent faces of planar regions turn, degrees), and the mirror symmetry kept when
    SOURCE has one. Lower is better for every figure.
    """
    import numpy as np

    from cagekit.io import load_shape
    from cagekit.metrics import evaluate

    start_command(ctx)
    paths = dict(zip(_EVAL_ROLES, (source, target, deformed)))
    src = load_shape(source)
    if len(src[1]) == 0:
        raise InputError("has no faces; the source must be a mesh (dCotLap needs faces)",
                         source)
    tgt = load_shape(target)
    dfm = load_shape(deformed)
    if len(dfm[0]) != len(src[0]):
        raise InputError(f"{deformed} has {len(dfm[0])} vertices but {source} has "
                         f"{len(src[0])}: DEFORMED must be SOURCE with moved vertices")
    for path, (V, _) in zip((source, target, deformed), (src, tgt, dfm)):
        if not np.ptp(V, axis=0).max() > 0:
            raise InputError("all its points coincide (zero extent); nothing to compare",
                             path)
    try:
        result = evaluate(*src, *tgt, dfm[0], n_samples=samples, seed=seed).as_dict()
    except InputError as exc:
        if exc.path is None:  # name the file(s) the message is about
            low = exc.problem.lower()
            named = [paths[r] for r in _EVAL_ROLES if r in low] or list(paths.values())
            raise InputError(exc.problem, ", ".join(dict.fromkeys(named))) from exc
        raise
    if as_json:
        emit_json({"source": source, "target": target, "deformed": deformed, **result})
        return
    click.echo(f"{'metric':<9}{'value':<14}as in the paper's tables")
    click.echo(f"{'CD':<9}{result['cd']:<14.6g}{result['cd_x1e2']:.4f} (x 1e2)")
    click.echo(f"{'dCotLap':<9}{result['dcotlap']:<14.6g}{result['dcotlap_x1e3']:.4f} (x 1e3)")
    click.echo(f"part non-affinity: median {100 * result['part_nonaffinity_median']:.3f}%, "
               f"worst {100 * result['part_nonaffinity_worst']:.3f}% over "
               f"{result['parts']} part(s)")
    click.echo(f"planarity: mean {result['planarity_mean_deg']:.3f} deg, 95th percentile "
               f"{result['planarity_p95_deg']:.3f} deg")
    if result["symmetry_axis"] is None:
        click.echo("symmetry: the source has no mirror symmetry about x, y or z")
    else:
        click.echo(f"symmetry about {result['symmetry_axis']}: error "
                   f"{100 * result['symmetry_error']:.3f}% of the size")
