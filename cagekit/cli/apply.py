"""``cagekit apply``: deform a shape by moving its cage (load, bind, map, write)."""

from __future__ import annotations

import time
import warnings

import click

from cagekit.cli.common import (
    COORDINATE_METHODS,
    allow_outside_option,
    bind_with_progress,
    check_output,
    check_outside,
    debug_option,
    emit_json,
    json_option,
    shape_writer,
    start_command,
)
from cagekit.errors import InputError


@click.command(short_help="Deform a mesh or point cloud by moving its cage.")
@click.argument("mesh", type=click.Path(dir_okay=False))
@click.argument("cage", type=click.Path(dir_okay=False))
@click.argument("deformed_cage", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out", required=True, type=click.Path(dir_okay=False),
              help="Deformed shape to write (mesh or point cloud, format from extension).")
@click.option("--coords", type=click.Choice(list(COORDINATE_METHODS)), default="mvc",
              show_default=True,
              help="Cage coordinates: mean value (affine-invariant) or Green (exact for "
                   "similarities; details keep their proportions under stretch).")
@allow_outside_option
@json_option
@debug_option
@click.pass_context
def apply(ctx: click.Context, mesh: str, cage: str, deformed_cage: str, out: str, coords: str,
          allow_outside: bool, as_json: bool) -> None:
    """Deform MESH by moving its CAGE to DEFORMED_CAGE.

    MESH is a mesh or a point cloud; CAGE a closed triangle mesh around it; DEFORMED_CAGE
    the same cage with moved vertices (same count and order; if it has faces they must
    be CAGE's). The points are bound once to CAGE with generalised barycentric
    coordinates and mapped through DEFORMED_CAGE; the result, with MESH's faces, is
    written to OUT. A DEFORMED_CAGE that intersects itself is used, with a warning: the
    motion folds the shape. A MESH mostly (more than half) outside CAGE is refused, with
    the likely cause (a cage in other units, another origin), unless --allow-outside.

    \b
    Example:
      cagekit apply shape.obj cage.obj cage_deformed.obj -o deformed.obj
    """
    from cagekit.cage import warn_self_intersecting

    start_command(ctx)
    check_output(out, (mesh, cage, deformed_cage))
    seconds = {}
    t0 = time.perf_counter()
    V, F, CV, faces, DV, write = _load(mesh, cage, deformed_cage, out)
    seconds["load"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as held:  # shown once binding succeeded, so
        warnings.simplefilter("always")  # that bad input stays one line
        outside = check_outside(V, CV, faces, shape=mesh, cage=cage, allow=allow_outside)
    seconds["check"] = time.perf_counter() - t0  # before binding: a refusal costs nothing

    t0 = time.perf_counter()
    deform = bind_with_progress(V, CV, faces, coords)
    seconds["bind"] = time.perf_counter() - t0
    for w in held:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)

    t0 = time.perf_counter()
    warn_self_intersecting(DV, faces, name=deformed_cage)  # the shape may fold there
    seconds["check"] += time.perf_counter() - t0

    t0 = time.perf_counter()
    out_v = deform(DV)
    seconds["deform"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    write(out, out_v, F)
    seconds["write"] = time.perf_counter() - t0
    _report(out, V, F, CV, coords, outside, seconds, as_json)


def _load(mesh, cage, deformed_cage, out):
    """The shape, the checked cage (vertices, oriented faces), the deformed cage and the
    writer of the output (its format checked before the cages are read)."""
    import numpy as np

    from cagekit import io
    from cagekit.cage import check_cage
    from cagekit.geometry import face_areas

    V, F = io.load_shape(mesh)
    write = shape_writer(out, has_faces=len(F) > 0, source=mesh)
    CV, CF = io.load_mesh(cage)
    try:
        face_areas(CV, CF)  # areas that overflow would be reported as "zero area" below
    except InputError as exc:
        raise InputError(exc.problem, cage) from None
    faces = check_cage(CV, CF, name=cage)  # closed, 2-manifold, oriented (flipped outward)
    DV, DF = io.load_shape(deformed_cage)
    if len(DV) != len(CV):
        raise InputError(f"has {len(DV)} vertices but {cage} (CAGE) has {len(CV)}: the "
                         "deformed cage must have the cage's vertices (same count and "
                         "order)", deformed_cage)
    if len(DF) and (DF.shape != CF.shape or not np.array_equal(DF, CF)):
        raise InputError(f"its faces differ from those of {cage}; the deformed cage must "
                         "be the same mesh with moved vertices", deformed_cage)
    return V, F, CV, faces, DV, write


def _report(out, V, F, CV, coords, outside, seconds, as_json):
    if as_json:
        emit_json({
            "output": out,
            "n_points": len(V),
            "n_faces": len(F),
            "n_cage_vertices": len(CV),
            "coords": coords,
            "encloses": outside == 0,
            "outside": outside,
            "seconds": seconds,
        })
    else:
        kind = "vertices" if len(F) else "points"
        click.echo(f"wrote {out}: {len(V)} {kind} deformed by a {len(CV)}-vertex cage "
                   f"({sum(seconds.values()):.2f} s)")
