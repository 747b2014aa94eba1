"""``cagekit render``: draw meshes and their cages side by side into a PNG."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import click

from cagekit.cli.common import (
    check_output,
    debug_option,
    emit_json,
    json_option,
    start_command,
)

if TYPE_CHECKING:
    from cagekit.typed import Faces, Vertices


def _parse_views(ctx, param, values):
    """``--view`` callback: ``"ELEV,AZIM"`` strings to float pairs."""
    views = []
    for text in values:
        try:
            elev, azim = (float(x) for x in text.replace(" ", "").split(","))
        except ValueError:
            raise click.BadParameter(f"expected ELEV,AZIM in degrees, got {text!r}") from None
        if not (math.isfinite(elev) and math.isfinite(azim)):
            raise click.BadParameter(f"angles must be finite, got {text!r}")
        views.append((elev, azim))
    return views


def _parse_size(ctx, param, text: str):
    """``--size`` callback: ``"WxH"`` (or ``"N"``) to a pair of ints."""
    try:
        parts = [int(x) for x in text.lower().split("x")]
    except ValueError:
        parts = []
    if len(parts) == 1:
        parts = parts * 2
    if len(parts) != 2 or min(parts) < 16 or max(parts) > 8192:
        raise click.BadParameter(f"expected WIDTHxHEIGHT in pixels (16..8192), got {text!r}")
    return tuple(parts)


@click.command(short_help="Draw meshes (and cages) side by side into a PNG.")
@click.argument("meshes", nargs=-1, required=True, metavar="MESH...",
                type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out", required=True, type=click.Path(dir_okay=False),
              help="PNG file to write.")
@click.option("--cage", "cages", multiple=True, type=click.Path(dir_okay=False),
              help="Cage of a mesh, drawn as a wireframe; once per mesh, in order "
                   "(later meshes without a --cage have none).")
@click.option("--title", "titles", multiple=True,
              help="Title of a panel; once per mesh, in order (default: file names).")
@click.option("--caption", default=None, help="A line of text under the picture.")
@click.option("--view", "views", multiple=True, default=("20,-60",), show_default=True,
              callback=_parse_views, metavar="ELEV,AZIM",
              help="Camera angles in degrees; repeat for more rows.")
@click.option("--size", default="480x480", show_default=True, callback=_parse_size,
              metavar="WxH", help="Panel size in pixels.")
@click.option("--up", type=click.Choice(["x", "y", "z"]), default="y", show_default=True,
              help="Vertical axis of the shapes.")
@click.option("--same-scale", is_flag=True,
              help="Draw all panels in one frame (shapes in the same units).")
@json_option
@debug_option
@click.pass_context
def render(ctx: click.Context, meshes: tuple[str, ...], out: str, cages: tuple[str, ...],
           titles: Sequence[str], caption: str | None, views: list[tuple[float, float]],
           size: tuple[int, int], up: str, same_scale: bool, as_json: bool) -> None:
    """Draw MESH... side by side (and their cages) into a PNG picture.

    Meshes are flat-shaded; point clouds are drawn as dots; each --cage is drawn as a
    wireframe over the mesh in the same position.

    \b
    Example:
      cagekit render shape.obj deformed.obj --cage cage.obj --cage cage_deformed.obj \\
          -o compare.png
    """
    from cagekit.io import load_mesh, load_shape
    from cagekit.render import render_meshes, shortest_unique_names

    start_command(ctx)
    if len(cages) > len(meshes):
        raise click.UsageError(f"{len(cages)} --cage options for {len(meshes)} meshes; "
                               "give at most one cage per mesh", ctx=ctx)
    if titles and len(titles) != len(meshes):
        raise click.UsageError(f"{len(titles)} --title options for {len(meshes)} meshes; "
                               "give one title per mesh", ctx=ctx)
    check_output(out, (*meshes, *cages), extensions={".png"})

    shapes = [load_shape(path) for path in meshes]
    cage_shapes: list[tuple[Vertices, Faces] | None] = [load_mesh(path) for path in cages]
    cage_shapes += [None] * (len(shapes) - len(cage_shapes))
    if not titles:
        titles = shortest_unique_names(meshes)  # girl/pose_3.obj, suit/pose_3.obj
    render_meshes(shapes, out, cages=cage_shapes, titles=list(titles), caption=caption,
                  views=views, size=size, up=up, same_scale=same_scale)
    if as_json:
        emit_json({"output": out, "panels": len(shapes), "rows": len(views),
                   "width": size[0] * len(shapes), "height": size[1] * len(views)})
        return
    rows = f", {len(views)} rows" if len(views) > 1 else ""
    click.echo(f"wrote {out}: {len(shapes)} panel(s){rows}")
