"""``cagekit fit-cage``: build a guaranteed cage around a mesh or point cloud."""

from __future__ import annotations

import os
import time
from typing import TYPE_CHECKING, cast

import click

from cagekit.cli.common import (
    FIT_METHODS,
    MAX_FACES,
    MIN_FACES,
    TEMPLATE_FACES,
    check_output,
    debug_option,
    emit_json,
    json_option,
    preview_up_option,
    same_file,
    start_command,
)
from cagekit.errors import InputError

if TYPE_CHECKING:
    from cagekit.cage.fitting import CageReport


@click.command(name="fit-cage", short_help="Build a guaranteed cage around a mesh or cloud.")
@click.argument("mesh", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out", required=True, type=click.Path(dir_okay=False),
              help="Cage mesh to write (OBJ, OFF, PLY, STL, GLB).")
@click.option("--faces", default=200, show_default=True,
              type=click.IntRange(min=MIN_FACES, max=MAX_FACES),
              help="Largest number of cage faces (method wrap; the template has 80).")
@click.option("--method", type=click.Choice(list(FIT_METHODS)), default="wrap",
              show_default=True,
              help="wrap: alpha wrap + intersection-free decimation; template: the paper's "
                   "42-vertex icosphere shrunk around the shape.")
@click.option("--components", default=1, show_default=True, type=click.IntRange(min=1),
              help="Largest number of cage components (wrap).")
@click.option("--preview", type=click.Path(dir_okay=False), default=None,
              help="Also draw the shape and the cage (wireframe) from two viewpoints "
                   "into this PNG.")
@preview_up_option
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="Seed of the surface samples checked for enclosure.")
@json_option
@debug_option
@click.pass_context
def fit_cage(ctx: click.Context, mesh: str, out: str, faces: int, method: str, components: int,
             preview: str | None, up: str, seed: int, as_json: bool) -> None:
    """Build a cage around MESH (a mesh or a point cloud) and write it to OUT.

    Every cage written is closed, 2-manifold, outward-oriented, free of self-intersection,
    encloses every vertex and a dense surface sample of MESH (winding number >= 0.5), cuts
    no face of MESH and has at most --faces faces; when no such cage is found the command
    exits with status 2 and writes nothing. --json prints each check and the tightness
    figures (volume ratio to the shape, or to its convex hull when it is open or a cloud;
    largest cage-to-shape distance over the bounding-box diagonal).

    \b
    Example:
      cagekit fit-cage shape.obj -o cage.obj --faces 200 --preview cage.png
    """
    from cagekit import io
    from cagekit.cage.fitting import fit_cage as fit

    start_command(ctx)
    if method == "template" and faces < TEMPLATE_FACES:
        raise click.BadParameter(f"the template cage has {TEMPLATE_FACES} faces, more than "
                                 f"{faces}: give --faces {TEMPLATE_FACES} or more, or --method "
                                 "wrap", param_hint="'--faces'")
    check_output(out, (mesh,), extensions=set(io.WRITTEN_MESH_EXTENSIONS))
    if preview is not None:
        if same_file(preview, out):
            raise InputError("the preview and the cage would be the same file", preview)
        check_output(preview, (mesh,), extensions={".png"})
    V, F = io.load_shape(mesh)
    t0 = time.perf_counter()
    try:
        cage_v, cage_f, report = fit(V, F, faces=faces, method=method,
                                     components=components, seed=seed)
    except InputError as exc:
        raise InputError(exc.problem, mesh) from None
    report = cast("CageReport", report)  # made: fit's report=True is the default
    seconds = time.perf_counter() - t0
    io.save_mesh(out, cage_v, cage_f)
    if preview is not None:
        from cagekit.render import render_meshes

        render_meshes([(V, F)], preview, cages=[(cage_v, cage_f)],
                      titles=[f"{os.path.basename(mesh)}: {len(cage_f)}-face cage"],
                      views=((20, -60), (20, 120)), up=up)
    if as_json:
        emit_json({"input": mesh, "output": out, "method": method, "seconds": seconds,
                    **report.as_dict()})
    else:
        ratio = report.volume_ratio
        volume = ("the shape has no volume" if ratio is None else
                  f"volume {ratio:.3f} x the {report.volume_reference}'s")
        click.echo(f"wrote {out}: {report.faces}-face cage, every check passed; {volume}, "
                   f"largest distance {report.max_distance:.4f} x the diagonal "
                   f"({seconds:.2f} s)")
