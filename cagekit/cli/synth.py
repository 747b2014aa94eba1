"""``cagekit synth``: write procedural chairs, tables or vases to a folder."""

from __future__ import annotations

import os

import click

from cagekit.cli.common import (
    FiniteFloatRange,
    debug_option,
    emit_json,
    json_option,
    progress_bar,
    progress_enabled,
    start_command,
)
from cagekit.errors import InputError

#: the families of :data:`cagekit.datasets.synthetic.FAMILIES`, listed here so that
#: ``--help`` imports no geometry (a test checks they match)
FAMILIES = ("chairs", "tables", "vases")


@click.command(short_help="Write procedural chairs, tables or vases to a folder.")
@click.argument("family", type=click.Choice(FAMILIES), metavar="FAMILY")
@click.option("-n", "--count", "count", default=1, show_default=True,
              type=click.IntRange(min=1, max=100_000), help="Number of shapes.")
@click.option("-o", "--output", "out", required=True, type=click.Path(file_okay=False),
              help="Folder to write them to (created if missing).")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="Seed of the first shape; shape i is made with seed + i.")
@click.option("--format", "fmt", type=click.Choice(["obj", "ply", "off"]), default="obj",
              show_default=True, help="Mesh file format.")
@click.option("--resolution", default=1.0, show_default=True,
              type=FiniteFloatRange(min=0.1, max=10.0),
              help="Scales the vertex count by about its square (about 4,500 at 1).")
@json_option
@debug_option
@click.pass_context
def synth(ctx: click.Context, family: str, count: int, out: str, seed: int, fmt: str,
          resolution: float, as_json: bool) -> None:
    """Write N (-n) procedural shapes of FAMILY (chairs, tables or vases) into a folder.

    Files are named OUT/<chair|table|vase>_<i>.<format> (i = 0000, 0001...); shape i
    is made from seed --seed + i (cagekit.datasets.synthetic), y up, standing on y = 0,
    in metres. An existing file of that name is an error (status 2) and nothing is
    written.

    \b
    Example:
      cagekit synth chairs -n 10 -o chairs/ --seed 100
    """
    from cagekit.datasets.synthetic import FAMILIES as MAKERS
    from cagekit.io import save_mesh
    from cagekit.io.files import output_folder

    start_command(ctx)
    if os.path.exists(out) and not os.path.isdir(out):
        raise InputError("exists and is not a folder; give a folder for the shapes", out)
    singular = family[:-1]
    paths = [os.path.join(out, f"{singular}_{i:04d}.{fmt}") for i in range(count)]
    for path in paths:
        if os.path.lexists(path):
            raise InputError("already exists; remove it or write to another folder", path)
    make = MAKERS[family]
    vertices = []
    bar = progress_bar(family, "shape", total=count, enabled=progress_enabled() and count > 1)
    try:
        with output_folder(out):
            for i, path in enumerate(paths):
                V, F = make(seed=seed + i, resolution=resolution)
                save_mesh(path, V, F)
                vertices.append(len(V))
                bar.update(1)
    finally:
        bar.close()
    if as_json:
        emit_json({"family": family, "n": count, "seed": seed, "format": fmt,
                    "resolution": resolution, "output": out, "files": paths,
                    "vertices": vertices})
    else:
        click.echo(f"wrote {count} {family if count > 1 else singular} to {out} "
                   f"({os.path.basename(paths[0])}"
                   + (f" ... {os.path.basename(paths[-1])}" if count > 1 else "")
                   + f"; {min(vertices)}-{max(vertices)} vertices)")
