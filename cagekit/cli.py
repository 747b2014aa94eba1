"""The ``cagekit`` command line (click).

Parsing and error handling only; the work is done by the library (:mod:`cagekit.io`,
:mod:`cagekit.coords`, :mod:`cagekit.cage`, :mod:`cagekit.metrics`,
:mod:`cagekit.render`), imported lazily so that ``--help`` stays fast.

Rules shared by every command (DESIGN.md, "Command line"):

- exit status 0 on success;
- bad input (a :class:`cagekit.errors.InputError`, or a usage error) exits with status 2
  and prints exactly one line on stderr that names the file and the problem; the
  traceback is shown only with ``--debug`` (accepted before or after the command name);
- other expected failures (an ``OSError`` while writing, say) print one line and exit 1;
- an output that resolves to one of the inputs is refused (status 2) before any work;
- outputs are written atomically by the library (temporary file, then rename);
- NumPy floating-point warnings (overflow...) are silenced (``numpy.errstate``) so that
  stderr carries only these lines; the library's own checks report such input;
- every other warning is one line, ``cagekit CMD: warning: ...`` (cagekit's own
  :class:`~cagekit.errors.CagekitWarning`, or another library's, named after the message);
  ``--debug`` shows Python's usual form;
- SIGINT (Ctrl-C) ends the command with one line, ``interrupted``, and status 130; outputs
  being written are removed (they are atomic), folders the command made are removed when
  empty;
- a crash in native code (a segmentation fault in a compiled library, a bug) prints
  Python's fault handler report (the Python call that crashed) instead of dying silently;
- ``--json`` prints one JSON object on stdout and nothing else there;
- long work shows a progress bar on stderr, only when stderr is a terminal.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import sys
import time
import traceback

import click

from cagekit import __version__
from cagekit.errors import InputError

__all__ = ["main"]

#: points bound per step when a progress bar is shown
_BIND_CHUNK = 20_000

#: choices of the library (:data:`cagekit.coords.binding.METHODS`,
#: :data:`cagekit.fitting.METHODS`), listed here so that starting the command line imports
#: neither numba nor libigl (tests check that they match)
COORDINATE_METHODS = ("mvc",)
FIT_METHODS = ("wrap", "template")
TEMPLATE_FACES = 80


# ----------------------------------------------------------------------- error handling


def _one_line(text: str) -> str:
    """Collapse any whitespace (newlines included) so a message fits on one line."""
    return " ".join(str(text).split())


def _debug_requested(args) -> bool:
    return "--debug" in args or os.environ.get("CAGEKIT_DEBUG", "") not in ("", "0")


class Interrupted(BaseException):
    """SIGINT, raised instead of KeyboardInterrupt so that click prints nothing for it."""


class OneLineErrors:
    """Mixin for a click command or group: errors are one line on stderr, with fixed exit
    statuses (0 success, 1 failure, 2 bad input or usage, 130 interrupted); ``--debug``
    (or ``CAGEKIT_DEBUG=1``) adds the traceback. Warnings are one line each, SIGINT one
    line. The applications in ``apps/`` use it too.
    """

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True,
             **extra):
        """Run the command line; exit with 0, 1 (failure) or 2 (bad input or usage)."""
        import numpy as np

        args = list(sys.argv[1:] if args is None else args)
        _CURRENT.clear()
        debug = _debug_requested(args)
        prog = prog_name or "cagekit"
        where = prog
        _report_native_crashes()
        with _one_line_warnings(prog, debug), _sigint_raises(Interrupted):
            try:
                try:
                    with np.errstate(all="ignore"):  # no NumPy warnings on stderr
                        rv = super().main(args, prog_name=prog, complete_var=complete_var,
                                          standalone_mode=False, **extra)
                except click.exceptions.NoArgsIsHelpError as exc:
                    click.echo(exc.ctx.get_help())
                    rv = 0
                code = rv if isinstance(rv, int) else 0
            except click.UsageError as exc:
                if exc.ctx is not None:
                    where = exc.ctx.command_path
                hint = f" (see '{where} --help')"
                error, code, message = exc, exc.exit_code, f"{exc.format_message()}{hint}"
            except (click.Abort, KeyboardInterrupt, Interrupted) as exc:
                error, code, message = exc, 130, "interrupted"
            except click.ClickException as exc:
                error, code, message = exc, exc.exit_code, exc.format_message()
            except InputError as exc:
                error, code, message = exc, 2, str(exc)
            except OSError as exc:
                error, code, message = exc, 1, _os_error_message(exc)
            except MemoryError as exc:
                error, code, message = exc, 1, "out of memory"
            except Exception as exc:  # noqa: BLE001  (a bug: one line, pointing at --debug)
                error, code = exc, 1
                message = f"internal error: {type(exc).__name__}: {exc}"
                if not debug:
                    message += " (run with --debug for the traceback)"
            else:
                if standalone_mode:
                    sys.exit(code)
                return code
            if debug:
                traceback.print_exception(error, file=sys.stderr)
            where = _CURRENT.get("command", where)
            # on a terminal, a carriage return overwrites the "^C" it echoed
            start = "\r" if code == 130 and _progress_enabled() else ""
            click.echo(f"{start}{where}: error: {_one_line(message)}", err=True)
        if standalone_mode:
            sys.exit(code)
        return code


def _report_native_crashes() -> None:
    """Enable Python's fault handler on the real stderr (once), so that a crash inside a
    compiled library prints the Python call it happened in instead of nothing."""
    import faulthandler

    if faulthandler.is_enabled() or sys.__stderr__ is None:
        return
    try:
        faulthandler.enable(file=sys.__stderr__, all_threads=False)
    except (ValueError, OSError, AttributeError):  # no real file descriptor (embedded)
        pass


@contextlib.contextmanager
def _one_line_warnings(prog: str, debug: bool):
    """Show every warning as one line, ``<command>: warning: <message>``."""
    import warnings

    from cagekit.errors import CagekitWarning

    with warnings.catch_warnings():
        if not debug:
            def show(message, category, filename, lineno, file=None, line=None):
                text = _one_line(message)
                if not issubclass(category, CagekitWarning):
                    text = f"{text} ({_package_of(filename)} {category.__name__})"
                where = _CURRENT.get("command", prog)
                click.echo(f"{where}: warning: {text}", err=True)

            warnings.showwarning = show
        yield


def _package_of(filename: str) -> str:
    """The top-level package a source file belongs to (for warnings from libraries)."""
    parts = os.path.normpath(filename).split(os.sep)
    for marker in ("site-packages", "dist-packages"):
        if marker in parts[:-1]:
            return parts[parts.index(marker) + 1].removesuffix(".py")
    return os.path.basename(filename).removesuffix(".py")


@contextlib.contextmanager
def _sigint_raises(exception):
    """SIGINT raises ``exception`` in the main thread while the block runs."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C while unwinding
        raise exception()

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _os_error_message(exc: OSError) -> str:
    """``path: problem`` for an OSError, when it carries a file name."""
    if exc.filename is not None:
        problem = exc.strerror or str(exc)
        return f"{os.fsdecode(exc.filename)}: {problem}"
    return str(exc)


#: the running command's name, for error lines ("cagekit apply: error: ...")
_CURRENT: dict[str, str] = {}


class _Group(OneLineErrors, click.Group):
    """The ``cagekit`` group."""


class Command(OneLineErrors, click.Command):
    """A stand-alone click command with cagekit's error handling (``cls=Command``)."""


class FiniteFloatRange(click.FloatRange):
    """click's FloatRange that also refuses NaN and infinities (which pass its bounds)."""

    def convert(self, value, param, ctx):
        """The number, or a usage error for NaN, inf or a value out of range."""
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number.", param, ctx)
        return number


def _start(ctx: click.Context) -> None:
    _CURRENT["command"] = ctx.command_path


# ---------------------------------------------------------------------------- helpers


def _same_file(a: str, b: str) -> bool:
    """True if paths ``a`` and ``b`` name the same file (following links)."""
    try:
        if os.path.exists(a) and os.path.exists(b):
            return os.path.samefile(a, b)
    except OSError:
        pass
    return os.path.realpath(a) == os.path.realpath(b)


def _check_output(out: str, inputs, extensions=None) -> None:
    """Refuse (InputError) an output that is an input, a folder, or in a missing folder."""
    for path in inputs:
        if path is not None and _same_file(out, path):
            raise InputError(f"refusing to overwrite the input file {path}; choose another "
                             "output path", out)
    if os.path.isdir(out):
        raise InputError("is a folder; give an output file name", out)
    folder = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(folder):
        raise InputError(f"output folder {folder} does not exist", out)
    if extensions is not None:
        ext = os.path.splitext(out)[1].lower()
        if ext not in extensions:
            raise InputError(f"unknown output format {ext or '(no extension)'!r}; "
                             f"use one of {', '.join(sorted(extensions))}", out)


def _shape_writer(out: str, has_faces: bool):
    """The :mod:`cagekit.io` function that writes ``out``, checked before any work.

    A mesh goes to ``save_mesh`` when the extension is a mesh format, else to
    ``save_points`` (its vertices only) when it is a point-cloud format (``.xyz``,
    ``.npy``...); a point cloud goes to ``save_points``. Anything else is an InputError.
    Returns ``writer(path, V, F)``.
    """
    from cagekit import io

    ext = os.path.splitext(out)[1].lower()
    mesh_exts = set(io.SUPPORTED_MESH_EXTENSIONS) - {".gltf"}  # save_mesh writes no GLTF
    point_exts = set(io.SUPPORTED_POINT_EXTENSIONS)
    if has_faces and ext in mesh_exts:
        return io.save_mesh
    if ext in point_exts:
        return lambda path, V, F: io.save_points(path, V)
    allowed = (mesh_exts | point_exts) if has_faces else point_exts
    kind = "a mesh" if has_faces else "a point cloud"
    raise InputError(f"cannot write {kind} as {ext or '(no extension)'!r}; use one of "
                     f"{', '.join(sorted(allowed))}", out)


def _progress_enabled() -> bool:
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


def _terminal_size() -> tuple[int, int]:
    """(columns, lines) of the terminal on stderr, (80, 24) where it reports none.

    A pseudo-terminal with no size set (``script``, CI runners) reports 0 x 0, and tqdm
    then draws nothing at all.
    """
    try:
        size = os.get_terminal_size(sys.stderr.fileno())
        columns, lines = size.columns, size.lines
    except (OSError, ValueError, AttributeError):
        columns, lines = 0, 0
    return (columns if columns > 0 else 80), (lines if lines > 0 else 24)


def _bind(points, cage_v, cage_f, method: str):
    """Bind points to a cage checked already; on a terminal, in chunks behind a progress bar.

    Returns a function mapping new cage vertices ``(k, 3)`` to deformed points ``(n, 3)``.
    The coordinates of a point do not depend on the other points, so chunking changes
    nothing but the bar.
    """
    import numpy as np

    from cagekit.coords import bind

    if not _progress_enabled() or len(points) <= _BIND_CHUNK:
        return bind(points, cage_v, cage_f, method=method, check=False).deform
    from tqdm import tqdm

    columns, lines = _terminal_size()
    bindings = []
    with tqdm(total=len(points), desc="binding", unit="pt", file=sys.stderr,
              leave=False, ncols=columns, nrows=lines) as bar:
        for start in range(0, len(points), _BIND_CHUNK):
            chunk = points[start:start + _BIND_CHUNK]
            bindings.append(bind(chunk, cage_v, cage_f, method=method, check=False))
            bar.update(len(chunk))
    return lambda new_v: np.concatenate([b.deform(new_v) for b in bindings], axis=0)


def _emit_json(obj) -> None:
    """Print one JSON object on stdout (non-finite floats become null)."""

    def clean(x):
        if isinstance(x, float) and not math.isfinite(x):
            return None
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        return x

    click.echo(json.dumps(clean(obj), allow_nan=False))


_debug_option = click.option(
    "--debug", is_flag=True, expose_value=False, is_eager=True,
    help="Show the full traceback on errors.",
)
_preview_up_option = click.option(
    "--up", type=click.Choice(["x", "y", "z"]), default="y", show_default=True,
    help="Vertical axis of the shapes in the preview.",
)
_json_option = click.option(
    "--json", "as_json", is_flag=True,
    help="Print one JSON object with the results on stdout (and nothing else there).",
)


# ---------------------------------------------------------------------------- commands


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "--version", prog_name="cagekit",
                      message="%(prog)s %(version)s")
@click.option("--debug", is_flag=True, help="Show full tracebacks on errors (any command).")
def main(debug: bool) -> None:
    """Detail-preserving shape deformation with cages (after Neural Cages, CVPR 2020).

    Bad input exits with status 2 and one line on stderr naming the file; --debug shows
    the traceback.
    """


@main.command(short_help="Deform a mesh or point cloud by moving its cage.")
@click.argument("mesh", type=click.Path(dir_okay=False))
@click.argument("cage", type=click.Path(dir_okay=False))
@click.argument("deformed_cage", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out", required=True, type=click.Path(dir_okay=False),
              help="Deformed shape to write (mesh or point cloud, format from extension).")
@click.option("--coords", type=click.Choice(list(COORDINATE_METHODS)), default="mvc",
              show_default=True, help="Cage coordinates (mean value coordinates).")
@_json_option
@_debug_option
@click.pass_context
def apply(ctx, mesh, cage, deformed_cage, out, coords, as_json):
    """Deform MESH by moving its CAGE to DEFORMED_CAGE.

    MESH is a mesh or a point cloud; CAGE a closed triangle mesh around it; DEFORMED_CAGE
    the same cage with moved vertices (same count and order; if it has faces they must
    be CAGE's). The points are bound once to CAGE with generalised barycentric
    coordinates and mapped through DEFORMED_CAGE; the result, with MESH's faces, is
    written to OUT.

    \b
    Example:
      cagekit apply shape.obj cage.obj cage_deformed.obj -o deformed.obj
    """
    import numpy as np

    from cagekit import io
    from cagekit.cage import check_cage
    from cagekit.coords.binding import warn_outside
    from cagekit.geometry import face_areas

    _start(ctx)
    _check_output(out, (mesh, cage, deformed_cage))
    seconds = {}

    t0 = time.perf_counter()
    V, F = io.load_shape(mesh)
    write = _shape_writer(out, has_faces=len(F) > 0)
    CV, CF = io.load_mesh(cage)
    try:
        face_areas(CV, CF)  # areas that overflow would be reported as "zero area" below
    except InputError as exc:
        raise InputError(exc.problem, cage) from None
    faces = check_cage(CV, CF, name=cage)  # closed, 2-manifold, oriented (flipped outward)
    DV, DF = io.load_shape(deformed_cage)
    if len(DV) != len(CV):
        raise InputError(f"{deformed_cage} has {len(DV)} vertices but {cage} has "
                         f"{len(CV)}: the deformed cage must have the cage's vertices "
                         "(same count and order)")
    if len(DF) and (DF.shape != CF.shape or not np.array_equal(DF, CF)):
        raise InputError(f"its faces differ from those of {cage}; the deformed cage must "
                         "be the same mesh with moved vertices", deformed_cage)
    seconds["load"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    deform = _bind(V, CV, faces, coords)
    seconds["bind"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    outside = warn_outside(V, CV, faces, shape=mesh, cage=cage)
    seconds["check"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    out_v = deform(DV)
    seconds["deform"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    write(out, out_v, F)
    seconds["write"] = time.perf_counter() - t0

    if as_json:
        _emit_json({
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


_EVAL_ROLES = ("source", "target", "deformed")


@main.command(name="eval", short_help="Chamfer distance and dCotLap of a deformed shape.")
@click.argument("source", type=click.Path(dir_okay=False))
@click.argument("target", type=click.Path(dir_okay=False))
@click.argument("deformed", type=click.Path(dir_okay=False))
@click.option("--samples", default=5000, show_default=True,
              type=click.IntRange(min=1, max=1_000_000),
              help="Surface samples per shape for the Chamfer distance (at most 1,000,000).")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="Sampling seed (an integer >= 0).")
@_json_option
@_debug_option
@click.pass_context
def eval_(ctx, source, target, deformed, samples, seed, as_json):
    """Chamfer distance and dCotLap distortion of DEFORMED (a deformed SOURCE) vs TARGET.

    As the paper's evaluation: TARGET is normalised on its own and DEFORMED mapped by the
    same transform; the normalised SOURCE is the reference for distortion. SOURCE and
    DEFORMED must have the same vertices (count and order); TARGET may be a point cloud.
    Lower is better for both figures.
    """
    import numpy as np

    from cagekit.io import load_shape
    from cagekit.metrics import evaluate

    _start(ctx)
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
        result = evaluate(src, tgt, dfm, n_samples=samples, seed=seed)
    except InputError as exc:
        if exc.path is None:  # name the file(s) the message is about
            low = exc.problem.lower()
            named = [paths[r] for r in _EVAL_ROLES if r in low] or list(paths.values())
            raise InputError(exc.problem, ", ".join(dict.fromkeys(named))) from exc
        raise
    if as_json:
        _emit_json({"source": source, "target": target, "deformed": deformed, **result})
        return
    click.echo(f"{'metric':<9}{'value':<14}as in the paper's tables")
    click.echo(f"{'CD':<9}{result['cd']:<14.6g}{result['cd_x1e2']:.4f} (x 1e2)")
    click.echo(f"{'dCotLap':<9}{result['dcotlap']:<14.6g}{result['dcotlap_x1e3']:.4f} (x 1e3)")


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


@main.command(short_help="Draw meshes (and cages) side by side into a PNG.")
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
@_debug_option
@click.pass_context
def render(ctx, meshes, out, cages, titles, caption, views, size, up, same_scale):
    """Draw MESH... side by side (and their cages) into a PNG picture.

    Meshes are flat-shaded; point clouds are drawn as dots; each --cage is drawn as a
    wireframe over the mesh in the same position.

    \b
    Example:
      cagekit render shape.obj deformed.obj --cage cage.obj --cage cage_deformed.obj \\
          -o compare.png
    """
    from cagekit.io import load_mesh, load_shape
    from cagekit.render import render_meshes

    _start(ctx)
    if len(cages) > len(meshes):
        raise click.UsageError(f"{len(cages)} --cage options for {len(meshes)} meshes; "
                               "give at most one cage per mesh", ctx=ctx)
    if titles and len(titles) != len(meshes):
        raise click.UsageError(f"{len(titles)} --title options for {len(meshes)} meshes; "
                               "give one title per mesh", ctx=ctx)
    _check_output(out, (*meshes, *cages), extensions={".png"})

    shapes = [load_shape(path) for path in meshes]
    cage_shapes = [load_mesh(path) for path in cages]
    cage_shapes += [None] * (len(shapes) - len(cage_shapes))
    if not titles:
        titles = [os.path.basename(path) for path in meshes]
    render_meshes(shapes, out, cages=cage_shapes, titles=list(titles), caption=caption,
                  views=views, size=size, up=up, same_scale=same_scale)


@main.command(name="fit-cage", short_help="Build a guaranteed cage around a mesh or cloud.")
@click.argument("mesh", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out", required=True, type=click.Path(dir_okay=False),
              help="Cage mesh to write (OBJ, OFF, PLY, STL, GLB).")
@click.option("--faces", default=200, show_default=True,
              type=click.IntRange(min=4, max=100_000),
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
@_preview_up_option
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="Seed of the surface samples checked for enclosure.")
@_json_option
@_debug_option
@click.pass_context
def fit_cage(ctx, mesh, out, faces, method, components, preview, up, seed, as_json):
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
    from cagekit.fitting import fit_cage as fit

    _start(ctx)
    if method == "template" and faces < TEMPLATE_FACES:
        raise click.BadParameter(f"the template cage has {TEMPLATE_FACES} faces, more than "
                                 f"{faces}: give --faces {TEMPLATE_FACES} or more, or --method "
                                 "wrap", param_hint="'--faces'")
    _check_output(out, (mesh,), extensions=set(io.SUPPORTED_MESH_EXTENSIONS) - {".gltf"})
    if preview is not None:
        _check_output(preview, (mesh, out), extensions={".png"})
        if _same_file(preview, out):
            raise InputError("the preview and the cage would be the same file", preview)
    V, F = io.load_shape(mesh)
    t0 = time.perf_counter()
    try:
        cage_v, cage_f, report = fit(V, F, faces=faces, method=method,
                                     components=components, seed=seed, return_report=True)
    except InputError as exc:
        raise InputError(exc.problem, mesh) from None
    seconds = time.perf_counter() - t0
    io.save_mesh(out, cage_v, cage_f)
    if preview is not None:
        from cagekit.render import render_meshes

        render_meshes([(V, F)], preview, cages=[(cage_v, cage_f)],
                      titles=[f"{os.path.basename(mesh)}: {len(cage_f)}-face cage"],
                      views=((20, -60), (20, 120)), up=up)
    if as_json:
        _emit_json({"input": mesh, "output": out, "method": method, "seconds": seconds,
                    **report})
    else:
        ratio = report["volume_ratio"]
        ratio_text = "n/a" if ratio is None else f"{ratio:.3f}"
        click.echo(f"wrote {out}: {report['faces']}-face cage, every check passed; volume "
                   f"{ratio_text} x the {report['volume_reference']}'s, largest distance "
                   f"{report['max_distance']:.4f} x the diagonal ({seconds:.2f} s)")


#: the families of :mod:`cagekit.datasets.synthetic` (its ``FAMILIES``), listed here so that
#: ``--help`` imports nothing
_SYNTH_FAMILIES = ("chairs", "tables", "vases")


@main.command(short_help="Write procedural chairs, tables or vases to a folder.")
@click.argument("family", type=click.Choice(_SYNTH_FAMILIES), metavar="FAMILY")
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
@_json_option
@_debug_option
@click.pass_context
def synth(ctx, family, count, out, seed, fmt, resolution, as_json):
    """Write N (-n) procedural shapes of FAMILY (chairs, tables or vases) into a folder.

    Files are named OUT/<chair|table|vase>_<i>.<format> (i = 0000, 0001...); shape i
    is made from seed --seed + i (cagekit.datasets.synthetic), y up, standing on y = 0,
    in metres. An existing file of that name is an error (status 2) and nothing is
    written.

    \b
    Example:
      cagekit synth chairs -n 10 -o chairs/ --seed 100
    """
    from cagekit.datasets.synthetic import FAMILIES
    from cagekit.files import output_folder
    from cagekit.io import save_mesh

    _start(ctx)
    if os.path.exists(out) and not os.path.isdir(out):
        raise InputError("exists and is not a folder; give a folder for the shapes", out)
    singular = family[:-1]
    paths = [os.path.join(out, f"{singular}_{i:04d}.{fmt}") for i in range(count)]
    for path in paths:
        if os.path.lexists(path):
            raise InputError("already exists; remove it or write to another folder", path)
    make = FAMILIES[family]
    vertices = []
    bar = None
    if _progress_enabled() and count > 1:
        from tqdm import tqdm

        columns, lines = _terminal_size()
        bar = tqdm(total=count, desc=family, unit="shape", file=sys.stderr, leave=False,
                   ncols=columns, nrows=lines)
    try:
        with output_folder(out):
            for i, path in enumerate(paths):
                V, F = make(seed=seed + i, resolution=resolution)
                save_mesh(path, V, F)
                vertices.append(len(V))
                if bar is not None:
                    bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    if as_json:
        _emit_json({"family": family, "n": count, "seed": seed, "format": fmt,
                    "resolution": resolution, "output": out, "files": paths,
                    "vertices": vertices})
    else:
        click.echo(f"wrote {count} {family if count > 1 else singular} to {out} "
                   f"({os.path.basename(paths[0])}"
                   + (f" ... {os.path.basename(paths[-1])}" if count > 1 else "")
                   + f"; {min(vertices)}-{max(vertices)} vertices)")


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
    """CD and dCotLap of a result (dCotLap only for a source with faces)."""
    from cagekit.frame import normalize
    from cagekit.metrics import chamfer, evaluate

    if len(source[1]):
        return evaluate(source, target, (result.vertices, source[1]))
    Vt_n, center, scale = normalize(target[0])
    cd = chamfer((result.vertices - center) / scale, None, Vt_n, target[1])
    return {"cd": cd, "dcotlap": None, "cd_x1e2": cd * 1e2, "dcotlap_x1e3": None}


def _bar_updater(bar):
    """A ``progress(done, total)`` callback that moves a tqdm bar."""

    def update(done, total):
        bar.total = total
        bar.n = min(done, total)
        bar.refresh()

    return update


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
    from cagekit.landmarks import load_landmarks, match_landmarks

    match = match_landmarks(load_landmarks(src_path), load_landmarks(tgt_path),
                            source_name=src_path, target_name=tgt_path)
    unmatched = match.unmatched(src_path, tgt_path)
    if unmatched:
        warnings.warn(CagekitWarning(unmatched), stacklevel=2)
    return match.source, match.target


@main.command(short_help="Deform SOURCE to take TARGET's shape by moving its cage.")
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
@click.option("--faces", default=200, show_default=True,
              type=click.IntRange(min=4, max=100_000),
              help="Face budget of the fitted cage (without --cage).")
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
                   "symmetry, cage.")
@click.option("--reference", type=click.Choice(["aligned", "source"]), default="aligned",
              show_default=True,
              help="Shape and cage terms compare with the box-aligned source (stretch "
                   "is free) or with the source as given (the paper's; cage weight 1).")
@click.option("--coords", type=click.Choice(list(COORDINATE_METHODS)), default="mvc",
              show_default=True, help="Cage coordinates.")
@click.option("--preview", type=click.Path(dir_okay=False), default=None,
              help="Draw source, target and result side by side (cages as wireframes) "
                   "into this PNG.")
@click.option("--model", "model_path", type=click.Path(), default=None,
              help="A trained model (RUN_DIR or RUN_DIR/checkpoint.pt of `cagekit train`, "
                   "needs cagekit[learn]): predict the cage and its deformation in one "
                   "forward pass.")
@click.option("--refine", is_flag=True,
              help="With --model: then optimise the predicted cage per pair (as --method "
                   "cage, started from the prediction).")
@_preview_up_option
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="Seed of the samples (and of the fitted cage).")
@_json_option
@_debug_option
@click.pass_context
def deform(ctx, source, target, out, method, cage_path, faces, save_cage, symmetry,
           landmarks, weights, reference, coords, model_path, refine, preview, up, seed,
           as_json):
    """Deform SOURCE so that it takes TARGET's shape, keeping SOURCE's detail.

    SOURCE is a mesh (or a point cloud, whose points move); TARGET a mesh or a point
    cloud (noisy or coarse; a partial scan squashes SOURCE towards its seen side). With
    --method cage (the default) SOURCE's cage is moved to minimise Chamfer distance to
    TARGET plus the paper's shape-preservation and cage terms (see
    cagekit/deformation.py); the result is written in TARGET's frame and units. --json
    prints CD and dCotLap (as `cagekit eval`), each term's value, the iterations and
    seconds.

    \b
    Example:
      cagekit deform chair.obj tall_chair.obj -o out.obj --symmetry x --preview out.png
    """
    import warnings

    import numpy as np

    from cagekit import io
    from cagekit.cage import check_cage
    from cagekit.coords.binding import warn_outside
    from cagekit.deformation import deform as run
    from cagekit.errors import OutsideCageWarning
    from cagekit.frame import normalize

    _start(ctx)
    inputs = (source, target, cage_path, model_path, *(landmarks or ()))
    _check_output(out, inputs)
    outputs = [out]
    if method != "cage" and (cage_path or save_cage or landmarks or weights
                             or symmetry != "none" or model_path):
        raise click.UsageError("--cage, --save-cage, --landmarks, --weight, --symmetry and "
                               "--model apply to --method cage only")
    if refine and not model_path:
        raise click.UsageError("--refine refines a prediction: it needs --model")
    if model_path and (cage_path or landmarks):
        raise click.UsageError("--model predicts the cage: --cage and --landmarks do not "
                               "apply")
    tuned = (weights or symmetry != "none"
             or ctx.get_parameter_source("reference") != click.core.ParameterSource.DEFAULT)
    if model_path and tuned and not refine:
        raise click.UsageError("--weight, --symmetry and --reference tune the per-pair "
                               "optimisation: with --model they need --refine")
    model = _load_model(model_path) if model_path else None
    if save_cage is not None:
        mesh_exts = set(io.SUPPORTED_MESH_EXTENSIONS) - {".gltf"}
        for path in (save_cage, _deformed_cage_path(save_cage)):
            _check_output(path, inputs, extensions=mesh_exts)
            outputs.append(path)
    if preview is not None:
        _check_output(preview, inputs, extensions={".png"})
        outputs.append(preview)
    if len({os.path.realpath(p) for p in outputs}) < len(outputs):
        raise InputError("two outputs would be the same file", out)

    src = io.load_shape(source)
    write = _shape_writer(out, has_faces=len(src[1]) > 0)
    tgt = io.load_shape(target)
    cage = None
    if cage_path is not None:
        cage_v, cage_f = io.load_mesh(cage_path)
        cage = (cage_v, check_cage(cage_v, cage_f, name=cage_path))
        warn_outside(src[0], *cage, shape=source, cage=cage_path)
    frames = {}
    for path, (V, _) in ((source, src), (target, tgt)):
        try:
            frames[path] = normalize(V)[1:]
        except InputError as exc:
            raise InputError(exc.problem, path) from None
    pairs = _load_landmark_pair(*landmarks) if landmarks else None
    for path, points, shape in zip(landmarks or (), pairs or (), (source, target)):
        center, scale = frames[shape]
        if np.abs((points - center) / scale).max() > 1.35:  # 10% of the diagonal out
            raise InputError(f"landmarks lie far outside {shape}'s bounding box (more than "
                             "10% of its diagonal): wrong file or units?", path)
    bar = None
    if _progress_enabled() and method == "cage" and (model_path is None or refine):
        from tqdm import tqdm

        columns, lines = _terminal_size()
        bar = tqdm(desc="deform", unit="eval", file=sys.stderr, leave=False, ncols=columns,
                   nrows=lines)
    try:
        options = {"symmetry": None if symmetry == "none" else symmetry,
                   "weights": weights or None, "reference": reference, "coords": coords,
                   "progress": None if bar is None else _bar_updater(bar)}
        if model is not None:
            from cagekit_learn.inference import deform_with_model

            net, points = model
            result = deform_with_model(net, src, tgt, points=points, seed=seed,
                                       refine=refine, **(options if refine else {}))
            method = result.method
        else:
            # a given cage was checked above, with its file name in the messages
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", OutsideCageWarning)
                result = run(src, tgt, cage, method=method, landmarks=pairs, faces=faces,
                             seed=seed, check=False, **options)
    except InputError as exc:
        if exc.path is None:
            low = exc.problem.lower()
            if low.startswith("the source:"):
                blamed = source
            elif low.startswith("the target:"):
                blamed = target
            else:
                blamed = (cage_path or source) if "cage" in low else f"{source}, {target}"
            raise InputError(exc.problem, blamed) from None
        raise
    finally:
        if bar is not None:
            bar.close()
    write(out, result.vertices, result.faces)
    if save_cage is not None:
        io.save_mesh(save_cage, result.cage_v, result.cage_f)
        io.save_mesh(_deformed_cage_path(save_cage), result.deformed_cage_v, result.cage_f)
    figures = _deform_figures(src, tgt, result)
    dcot = figures["dcotlap_x1e3"]
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
            caption=caption, up=up)
    if as_json:
        _emit_json({"source": source, "target": target, "output": out, "method": method,
                    **{k: figures[k] for k in ("cd", "dcotlap", "cd_x1e2", "dcotlap_x1e3")},
                    "losses": result.losses, "weights": result.weights,
                    "energy": result.energy, "iterations": result.iterations,
                    "cage_faces": None if result.cage_f is None else len(result.cage_f),
                    "seconds": result.seconds})
    else:
        click.echo(f"wrote {out}: {caption}")


@main.command(short_help="Train the learned cages (N_c, N_d) on a folder of meshes.")
@click.argument("data", metavar="DATA_DIR")
@click.option("-o", "--output", "run_dir", required=True, type=click.Path(file_okay=False),
              help="Run folder: checkpoint.pt, log.csv (and tensorboard/ when installed).")
@click.option("--epochs", default=100, show_default=True, type=click.IntRange(min=1))
@click.option("--batch-size", default=8, show_default=True, type=click.IntRange(min=1),
              help="Pairs per step (per process under torchrun).")
@click.option("--lr", default=1e-3, show_default=True, type=FiniteFloatRange(min=0,
              min_open=True), help="Adam's learning rate (N_c at a tenth of it).")
@click.option("--device", type=click.Choice(["auto", "cpu", "cuda"]), default="auto",
              show_default=True)
@click.option("--resume", is_flag=True,
              help="Continue the run in --output exactly where it stopped, with the "
                   "same number of processes (its own settings; --epochs, --max-steps, "
                   "--minutes and --device given again replace them).")
@click.option("--points", default=1024, show_default=True,
              type=click.IntRange(min=16, max=100_000),
              help="Samples per shape.")
@click.option("--bottleneck", default=256, show_default=True, type=click.IntRange(min=1),
              help="Size of the PointNet code.")
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
@click.option("--checkpoint-every", default=200, show_default=True,
              type=click.IntRange(min=1), help="Steps between checkpoints.")
@click.option("--max-steps", default=None, type=click.IntRange(min=1),
              help="Stop after this many steps in all.")
@click.option("--minutes", default=None, type=FiniteFloatRange(min=0, min_open=True),
              help="Stop (with a checkpoint) after this much training time.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0))
@_json_option
@_debug_option
@click.pass_context
def train(ctx, data, run_dir, epochs, batch_size, lr, device, resume, points, bottleneck,
          nc, fixed_source, source_cage, no_box_align, symmetry, align, no_augment,
          checkpoint_every, max_steps, minutes, seed, as_json):
    """Train N_c and N_d (the paper's networks) on the meshes under DATA_DIR.

    DATA_DIR is searched recursively for meshes (ShapeNet's layout works as is); each is
    normalised and sampled once, cached in DATA_DIR/.cagekit-cache. `synthetic:chairs:300`
    (or tables, vases) trains on procedural shapes instead. Scale out with
    `torchrun --nproc-per-node N -m cagekit_learn.train DATA_DIR -o RUN_DIR`.

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
    _start(ctx)
    try:
        from cagekit_learn.networks import ModelConfig
        from cagekit_learn.train import TrainConfig, load_source_cage
        from cagekit_learn.train import train as run
    except ImportError as exc:
        raise InputError(f"training needs the learned mode: pip install -e '.[learn]' "
                         f"({exc})") from None
    model = ModelConfig(bottleneck=bottleneck, nc=nc, box_align=not no_box_align)
    if source_cage is not None and not resume:  # a resumed run keeps its own cage
        model.fixed_cage_v, model.fixed_cage_f = load_source_cage(source_cage,
                                                                  template=fixed_source)
    if os.path.exists(os.path.join(run_dir, "checkpoint.pt")) and not resume:
        raise InputError("holds a checkpoint already: --resume to continue it, or choose "
                         "another folder", run_dir)
    if resume:  # what was not given again stays as the stopped run had it
        default = click.core.ParameterSource.DEFAULT
        if ctx.get_parameter_source("epochs") == default:
            epochs = None
        if ctx.get_parameter_source("device") == default:
            device = None
    config = TrainConfig(
        data=data, run_dir=run_dir, epochs=epochs, batch_size=batch_size, lr=lr,
        points=points, seed=seed, device=device, checkpoint_every=checkpoint_every,
        symmetry=None if symmetry == "none" else symmetry, align=align,
        augment=not no_augment, max_steps=max_steps, max_minutes=minutes,
        model=model.to_dict(), fixed_source=fixed_source)
    from cagekit.files import output_folder

    with output_folder(run_dir):  # a run that fails before writing leaves no empty folder
        result = run(config, resume=resume, progress=_progress_enabled())
    figures = {"run_dir": run_dir, "steps": result.step, "epochs": result.epoch,
               "skipped_steps": result.skipped, "losses": result.last_losses,
               "seconds": result.seconds, "pairs_per_second": result.pairs_per_second}
    if int(os.environ.get("RANK", "0")) != 0:
        return
    if as_json:
        _emit_json(figures)
    else:
        loss = result.last_losses.get("loss", float("nan"))
        click.echo(f"trained {result.step} steps ({result.pairs_per_second:.1f} pairs/s, "
                   f"{result.skipped} skipped); last loss {loss:.4g}; wrote "
                   f"{os.path.join(run_dir, 'checkpoint.pt')}")


if __name__ == "__main__":
    main()
