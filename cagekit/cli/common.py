"""What every command of ``cagekit`` (and every application in ``apps/``) shares.

Error handling, output checks, JSON, progress and the shared options. It imports only the
core (lazily, so that ``--help`` stays fast). The rules (docs/architecture.md):

- exit status 0 on success;
- bad input (a :class:`cagekit.errors.InputError`, or a usage error) exits with status 2
  and prints exactly one line on stderr that names the file and the problem; the
  traceback is shown only with ``--debug`` (accepted before or after the command name);
  a file given as a positional argument is named with it (``CAGE (2nd argument)
  cage.obj: ...``), and a missing ``-o`` whose value was left as a positional is suggested
  (``Did you mean `-o out.obj`?``);
- a shape more than :data:`OUTSIDE_LIMIT` outside the cage given for it is refused, with
  the likely cause (units, origin), unless ``--allow-outside`` (:func:`check_outside`);
- other expected failures (an ``OSError`` while writing, say) print one line and exit 1;
- an output that resolves to one of the inputs is refused (status 2) before any work;
- outputs are written atomically by the library (temporary file, then rename);
- NumPy floating-point warnings (overflow...) are silenced (``numpy.errstate``) so that
  stderr carries only these lines; the library's own checks report such input;
- every other warning is one line, ``cagekit CMD: warning: ...`` (cagekit's own
  :class:`~cagekit.errors.CagekitWarning`, or another library's, named after the message);
  ``--debug`` shows Python's usual form;
- SIGTERM (``kill``, ``timeout``) is taken as a SIGINT, with the line ``terminated`` and
  status 143;
- SIGINT (Ctrl-C) ends the command with one line, ``interrupted``, and status 130; outputs
  being written are removed (they are atomic), folders the command made are removed when
  empty; an error that an interrupt caused (native code that called Python back wraps it
  in a SystemError) is the interrupt; once the command has finished, a SIGINT while the
  process exits is ignored (Python would otherwise die by the signal, with no line);
- numba's threading layer and cache folder are set when a command starts
  (:func:`cagekit._numba_setup.configure`), so the processes it starts inherit them;
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
import shlex
import signal
import sys
import traceback
from collections.abc import Callable, Collection, Iterable, Sequence
from typing import TYPE_CHECKING, Any, Literal, NoReturn, overload

import click

from cagekit.errors import InputError, exception_chain
from cagekit.progress import bar_callback, progress_bar, progress_enabled

if TYPE_CHECKING:  # the command line imports no numpy at start-up
    from numpy.typing import ArrayLike

    from cagekit.typed import Faces, Vertices

__all__ = ["BIND_CHUNK", "COORDINATE_METHODS", "DEFORM_COORDINATE_METHODS", "FIT_METHODS",
           "TEMPLATE_FACES", "MIN_FACES", "MAX_FACES", "Command",
           "FiniteFloatRange", "Group", "Interrupted", "OneLineErrors", "OUTSIDE_LIMIT",
           "allow_outside_option", "bar_callback", "bind_with_progress", "check_outside",
           "check_output", "debug_option", "emit_json", "json_option",
           "one_line", "preview_up_option", "progress_bar", "progress_enabled", "same_file",
           "shape_writer", "start_command"]

#: points bound per step when a progress bar is shown
BIND_CHUNK = 20_000

#: choices of the library (:data:`cagekit.coords.binding.METHODS`,
#: :data:`cagekit.cage.fitting.METHODS`), listed here so that starting the command line imports
#: neither numba nor libigl (tests check that they match)
COORDINATE_METHODS = ("mvc", "green")
#: the coordinates ``cagekit deform``'s energy takes (:data:`cagekit.deformation.COORDS`)
DEFORM_COORDINATE_METHODS = ("mvc", "green")
FIT_METHODS = ("wrap", "template")
TEMPLATE_FACES = 80
#: the face budget's range (:data:`cagekit.cage.fitting.MIN_FACES`,
#: :data:`~cagekit.cage.fitting.MAX_FACES`)
MIN_FACES, MAX_FACES = 4, 100_000
#: share of a shape's points outside the cage given for it above which a command refuses
#: the pair (a cage in other units or placed elsewhere, most likely); ``--allow-outside``
#: deforms it anyway, with the warning
OUTSIDE_LIMIT = 0.5


def one_line(text: str) -> str:
    """Collapse any whitespace (newlines included) so a message fits on one line."""
    return " ".join(str(text).split())


def _debug_requested(args) -> bool:
    return "--debug" in args or os.environ.get("CAGEKIT_DEBUG", "") not in ("", "0")


class Interrupted(BaseException):
    """SIGINT, raised instead of KeyboardInterrupt so that click prints nothing for it."""


class OneLineErrors:
    """Mixin for a click command or group: errors are one line on stderr, with fixed exit
    statuses (0 success, 1 failure, 2 bad input or usage, 130 interrupted, 143 terminated
    by SIGTERM); ``--debug``
    (or ``CAGEKIT_DEBUG=1``) adds the traceback. Warnings are one line each, SIGINT one
    line. The applications in ``apps/`` use it too.
    """

    @overload
    def main(self, args: Sequence[str] | None = None, prog_name: str | None = None,
             complete_var: str | None = None, standalone_mode: Literal[True] = True,
             **extra: Any) -> NoReturn: ...
    @overload
    def main(self, args: Sequence[str] | None = None, prog_name: str | None = None,
             complete_var: str | None = None, standalone_mode: bool = ...,
             **extra: Any) -> int: ...

    def main(self, args: Sequence[str] | None = None, prog_name: str | None = None,
             complete_var: str | None = None, standalone_mode: bool = True,
             **extra: Any) -> int:
        """Run the command line; exit with 0, 1 (failure), 2 (bad input or usage), 130
        (interrupted) or 143 (SIGTERM)."""
        args = list(sys.argv[1:] if args is None else args)
        _CURRENT.clear()
        _ARGUMENTS.clear()
        debug = _debug_requested(args)
        prog = prog_name or "cagekit"
        _report_native_crashes()
        if standalone_mode:
            _ignore_sigint_at_exit()
        _TERMINATED.clear()
        with _one_line_warnings(prog, debug), _sigint_raises(Interrupted):
            try:
                code, error, message = self._outcome(args, prog, complete_var, debug, extra)
                if code == 130 and _TERMINATED:
                    code, message = 143, "terminated"
                if error is not None:
                    _print_error(code, error, message, debug, prog)
            except (click.Abort, KeyboardInterrupt, Interrupted) as exc:  # while reporting
                code = 143 if _TERMINATED else 130
                _print_error(code, exc, "terminated" if _TERMINATED else "interrupted",
                             debug, prog)
        if standalone_mode:
            sys.exit(code)
        return code

    def _outcome(self, args, prog, complete_var, debug, extra):
        """Run the command: (exit status, the exception or None, the error line or None)."""
        import numpy as np

        from cagekit.io.files import all_or_nothing

        try:
            try:  # a command that fails or is interrupted leaves no output (amplify and
                # train keep theirs as written: keep_outputs_as_written)
                with np.errstate(all="ignore"), all_or_nothing():  # no NumPy warnings
                    rv = super().main(args, prog_name=prog, complete_var=complete_var,
                                      standalone_mode=False, **extra)
            except click.exceptions.NoArgsIsHelpError as exc:
                click.echo(exc.ctx.get_help())
                rv = 0
        except (click.Abort, KeyboardInterrupt, Interrupted) as exc:
            return 130, exc, "interrupted"
        except Exception as exc:  # noqa: BLE001 - classified: one line each
            if _interrupt_in_chain(exc):  # raised while an interrupt unwound (or wrapping it)
                return 130, exc, "interrupted"
            return _classify(exc, debug, prog, args)
        return (rv if isinstance(rv, int) else 0), None, None


def _classify(exc: Exception, debug: bool, prog: str,
              args: Sequence[str] = ()) -> tuple[int, Exception, str]:
    """(exit status, exc, message) of a command's exception (``args``: the command line)."""
    if isinstance(exc, click.UsageError):
        where = exc.ctx.command_path if exc.ctx is not None else prog
        return (exc.exit_code, exc,
                f"{exc.format_message()}{_output_hint(exc, args)} (see '{where} --help')")
    if isinstance(exc, click.ClickException):
        return exc.exit_code, exc, exc.format_message()
    if isinstance(exc, InputError):
        return 2, exc, _naming_the_argument(exc)
    if isinstance(exc, OSError):
        return 1, exc, _os_error_message(exc)
    if isinstance(exc, MemoryError):
        return 1, exc, "out of memory"
    message = f"internal error: {type(exc).__name__}: {exc}"  # a bug: pointing at --debug
    if not debug:
        message += " (run with --debug for the traceback)"
    return 1, exc, message


def _output_hint(exc: click.UsageError, args: Sequence[str]) -> str:
    """`` Did you mean `-o out.obj`?`` when ``-o`` is missing and its value seems given as
    a positional argument (``cagekit deform a.obj b.obj out.obj``), else ``""``."""
    param = getattr(exc, "param", None)
    if (exc.ctx is None or not isinstance(exc, click.MissingParameter)
            or not isinstance(param, click.Option) or "-o" not in param.opts):
        return ""
    stray = _stray_output(exc.ctx, _own_args(exc.ctx, args))
    return f" Did you mean `-o {shlex.quote(stray)}`?" if stray else ""


def _own_args(ctx: click.Context, args: Sequence[str]) -> list[str]:
    """The words of the command line that ``ctx``'s command parsed (those after its name
    when it is a subcommand)."""
    if ctx.parent is None:
        return list(args)
    words = list(args)
    return words[words.index(ctx.info_name) + 1:] if ctx.info_name in words else []


def _stray_output(ctx: click.Context, args: list[str]) -> str | None:
    """The last positional word the command has no argument for; or, after a variadic
    argument (``MESH...``), the last of its values when no such file exists."""
    try:
        values, extra, _ = ctx.command.make_parser(ctx).parse_args(args)
    except click.UsageError:
        return None
    if extra:
        return extra[-1]
    arguments = [p for p in ctx.command.params if isinstance(p, click.Argument)]
    if arguments and arguments[-1].nargs == -1:
        given: Sequence[str] = values.get(arguments[-1].name or "") or ()
        if len(given) > 1 and not os.path.exists(given[-1]):
            return given[-1]
    return None


def _interrupt_in_chain(exc: BaseException) -> bool:
    """True if ``exc`` was caused by an interrupt, or raised while one unwound: a
    KeyboardInterrupt or :class:`Interrupted` in its cause/context chain (native code that
    calls Python back wraps one in a SystemError, "returned a result with an exception
    set"; a clean-up that fails chains it)."""
    return any(isinstance(e, (KeyboardInterrupt, Interrupted, click.Abort))
               for e in exception_chain(exc))


def _print_error(code: int, error: BaseException, message: str, debug: bool,
                 prog: str) -> None:
    """The error line on stderr, ``<command>: error: <message>`` (after the traceback with
    ``--debug``)."""
    if debug:
        traceback.print_exception(error, file=sys.stderr)
    ctx = error.ctx if isinstance(error, click.UsageError) else None
    where = _CURRENT.get("command", prog if ctx is None else ctx.command_path)
    # on a terminal, a carriage return overwrites the "^C" it echoed
    start = "\r" if code == 130 and progress_enabled() else ""
    click.echo(f"{start}{where}: error: {one_line(message)}", err=True)


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
    """Show every warning as one line, ``<command>: warning: <message>``, each line once
    (a file read twice, for the work and for a picture, says what it drops once)."""
    import warnings

    from cagekit.errors import CagekitWarning

    shown: set[str] = set()
    with warnings.catch_warnings():
        if not debug:
            def show(message, category, filename, lineno, file=None, line=None):
                text = one_line(message)
                if not issubclass(category, CagekitWarning):
                    text = f"{text} ({_package_of(filename)} {category.__name__})"
                line = f"{_CURRENT.get('command', prog)}: warning: {text}"
                if line not in shown:
                    shown.add(line)
                    click.echo(line, err=True)

            warnings.showwarning = show
        yield


def _package_of(filename: str) -> str:
    """The top-level package a source file belongs to (for warnings from libraries)."""
    parts = os.path.normpath(filename).split(os.sep)
    for marker in ("site-packages", "dist-packages"):
        if marker in parts[:-1]:
            return parts[parts.index(marker) + 1].removesuffix(".py")
    return os.path.basename(filename).removesuffix(".py")


def _ignore_sigint_at_exit() -> None:
    """Ignore SIGINT once the interpreter exits (registered with ``atexit`` once).

    When Python tears itself down it puts SIGINT back to the system's default, which kills
    the process (status -2, no line) if Ctrl-C comes while it frees its modules (numba's and
    LLVM's take a while); the command's work and its report are done by then. An ignored
    SIGINT stays ignored through that.
    """
    import atexit

    if not _EXIT_HOOK:
        _EXIT_HOOK.append(_ignore_sigint)
        atexit.register(_ignore_sigint)


def _ignore_sigint() -> None:
    """SIGINT ignored from now on (in the main thread; elsewhere Python cannot set it)."""
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextlib.contextmanager
def _sigint_raises(exception):
    """SIGINT raises ``exception`` in the main thread while the block runs; SIGTERM is
    noted in :data:`_TERMINATED` and sent on as a SIGINT, so that it stops the command
    where a Ctrl-C would (code that holds a Ctrl-C back, :mod:`cagekit.interrupts`, holds
    it back too) and leaves what a Ctrl-C leaves."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C while unwinding
        raise exception()

    def terminate(signum, frame):
        _TERMINATED.append(True)
        signal.raise_signal(signal.SIGINT)

    previous = signal.signal(signal.SIGINT, handler)
    previous_term = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        signal.signal(signal.SIGTERM, previous_term)


def _os_error_message(exc: OSError) -> str:
    """``path: problem`` for an OSError, when it carries a file name."""
    if exc.filename is not None:
        problem = exc.strerror or str(exc)
        return f"{os.fsdecode(exc.filename)}: {problem}"
    return str(exc)


#: the running command's name, for error lines ("cagekit apply: error: ...")
_CURRENT: dict[str, str] = {}
#: the running command's positional arguments: file given -> the arguments it was given as
_ARGUMENTS: dict[str, list[str]] = {}
#: the exit hook of :func:`_ignore_sigint_at_exit`, once registered
_EXIT_HOOK: list = []
#: not empty once a SIGTERM came (the command ends as a Ctrl-C ends it, status 143)
_TERMINATED: list = []


class Group(OneLineErrors, click.Group):
    """A click group with cagekit's error handling (the ``cagekit`` group)."""


class Command(OneLineErrors, click.Command):
    """A stand-alone click command with cagekit's error handling (``cls=Command``)."""


class FiniteFloatRange(click.FloatRange):
    """click's FloatRange that also refuses NaN and infinities (which pass its bounds)."""

    def convert(self, value: Any, param: click.Parameter | None,
                ctx: click.Context | None) -> float:
        """The number, or a usage error for NaN, inf or a value out of range."""
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number.", param, ctx)
        return number


def start_command(ctx: click.Context, keep_outputs: bool = False) -> None:
    """Start a command: its name for the error lines, and numba's settings
    (:func:`cagekit._numba_setup.configure`) before any kernel is defined, so that the
    processes the command starts inherit them. Outputs are kept only when the command
    completes (:func:`cagekit.io.files.all_or_nothing`), unless ``keep_outputs``: a
    resumable batch (``amplify``, ``train``) keeps each one as it is written."""
    from cagekit._numba_setup import configure
    from cagekit.io.files import keep_outputs_as_written

    if keep_outputs:
        keep_outputs_as_written()

    _CURRENT["command"] = ctx.command_path
    _ARGUMENTS.clear()
    _ARGUMENTS.update(_positional_files(ctx))
    configure()


def _positional_files(ctx: click.Context) -> dict[str, list[str]]:
    """Each value of the command's positional arguments -> the arguments it was given as,
    ``"CAGE (2nd argument)"`` (a variadic argument's values each by their position)."""
    found: dict[str, list[str]] = {}
    position = 0
    for param in ctx.command.params:
        if not isinstance(param, click.Argument):
            continue
        value = ctx.params.get(param.name or "")
        values = value if isinstance(value, (tuple, list)) else (value,)
        name = (param.metavar or (param.name or "").upper()).rstrip(".")
        for item in values:
            position += 1
            if isinstance(item, str):
                found.setdefault(item, []).append(f"{name} ({_ordinal(position)} argument)")
    return found


def _ordinal(n: int) -> str:
    """``1st``, ``2nd``, ``3rd``, ``4th``, ... ``11th``, ``21st``."""
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


def _naming_the_argument(exc: InputError) -> str:
    """The error line, prefixed with the positional argument(s) its file was given as:
    ``CAGE (2nd argument) cage.obj: not closed``."""
    if exc.path is None:
        return str(exc)
    labels = _ARGUMENTS.get(exc.path) or next(
        (names for given, names in _ARGUMENTS.items() if same_file(given, exc.path)), None)
    return f"{' and '.join(labels)} {exc}" if labels else str(exc)


def same_file(a: str, b: str) -> bool:
    """True if paths ``a`` and ``b`` name the same file (following links)."""
    try:
        if os.path.exists(a) and os.path.exists(b):
            return os.path.samefile(a, b)
    except OSError:
        pass
    return os.path.realpath(a) == os.path.realpath(b)


def check_output(out: str, inputs: Iterable[str | None],
                 extensions: Collection[str] | None = None) -> None:
    """Refuse (InputError) an output that is an input, a folder, or in a missing folder."""
    for path in inputs:
        if path is not None and same_file(out, path):
            raise InputError(f"refusing to overwrite the input file {path}; choose another "
                             "output path", out)
    if os.path.isdir(out):
        raise InputError("is a folder; give an output file name", out)
    folder = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(folder):
        raise InputError(f"output folder {folder} does not exist", out)
    check_writable(out)
    if extensions is not None:
        ext = os.path.splitext(out)[1].lower()
        if ext not in extensions:
            raise InputError(f"unknown output format {ext or '(no extension)'!r}; "
                             f"use one of {', '.join(sorted(extensions))}", out)


def check_writable(out: str | os.PathLike) -> None:
    """Refuse (InputError), before any work, an output whose folder, or the nearest folder
    above it that exists (where the missing ones would be made), cannot be written: a
    read-only file system, no permission."""
    folder = os.path.dirname(os.path.abspath(out))
    while not os.path.exists(folder) and os.path.dirname(folder) != folder:
        folder = os.path.dirname(folder)
    if os.path.isdir(folder) and not os.access(folder, os.W_OK):
        raise InputError(f"cannot write in {folder} (a read-only file system or no "
                         "permission)", out)


def given(ctx: click.Context, name: str) -> bool:
    """Whether option ``name`` was given (on the command line or in the environment), not
    left at its default."""
    source = ctx.get_parameter_source(name)
    return source not in (click.core.ParameterSource.DEFAULT,
                          click.core.ParameterSource.DEFAULT_MAP)


def shape_writer(out: str, has_faces: bool,
                 source: str | None = None) -> Callable[[str, ArrayLike, ArrayLike], None]:
    """The :mod:`cagekit.io` function that writes ``out``, checked before any work.

    A mesh goes to ``save_mesh`` when the extension is a mesh format, else to
    ``save_points`` (its vertices only, with a warning) when it is a point-cloud format
    (``.xyz``, ``.npy``...); a point cloud goes to ``save_points``. Anything else is an InputError.
    With ``source`` (the mesh file whose vertices the result moves), a mesh goes to
    :func:`cagekit.io.save_deformed`, which keeps the source's UVs, materials, groups,
    colours and normals where the output's format can. Returns ``writer(path, V, F)``.
    """
    from cagekit import io

    ext = os.path.splitext(out)[1].lower()
    mesh_exts = set(io.WRITTEN_MESH_EXTENSIONS)
    point_exts = set(io.SUPPORTED_POINT_EXTENSIONS)
    if has_faces and ext in mesh_exts:
        if source is not None:
            return lambda path, V, F: io.save_deformed(path, V, F, source)
        return io.save_mesh
    if ext in point_exts:
        if has_faces:
            return lambda path, V, F: _save_vertices_of_mesh(path, V, ext)
        return lambda path, V, F: io.save_points(path, V)
    allowed = (mesh_exts | point_exts) if has_faces else point_exts
    kind = "a mesh" if has_faces else "a point cloud"
    raise InputError(f"cannot write {kind} as {ext or '(no extension)'!r}; use one of "
                     f"{', '.join(sorted(allowed))}", out)


def _save_vertices_of_mesh(path: str, V: ArrayLike, ext: str) -> None:
    """A mesh's vertices written to a point-cloud format, saying that its faces are not."""
    import warnings

    from cagekit import io
    from cagekit.errors import MeshFileWarning

    warnings.warn(MeshFileWarning(
        f"{path}: {ext[1:].upper()} is a point-cloud format: the mesh's vertices are "
        "written, its faces (and UVs, materials, groups) are not; write .obj, .ply or "
        ".off to keep them"), stacklevel=2)
    io.save_points(path, V)


def bind_with_progress(points: Vertices, cage_v: Vertices, cage_f: Faces,
                       method: str) -> Callable[[ArrayLike], Vertices]:
    """Bind points to a cage checked already; on a terminal, in chunks behind a progress bar.

    Returns a function mapping new cage vertices ``(k, 3)`` to deformed points ``(n, 3)``.
    The coordinates of a point do not depend on the other points, so chunking changes
    nothing but the bar.
    """
    import numpy as np

    from cagekit.coords import bind

    if not progress_enabled() or len(points) <= BIND_CHUNK:
        return bind(points, cage_v, cage_f, method=method, check=False).deform
    bindings = []
    with progress_bar("binding", "pt", total=len(points)) as bar:
        for start in range(0, len(points), BIND_CHUNK):
            chunk = points[start:start + BIND_CHUNK]
            bindings.append(bind(chunk, cage_v, cage_f, method=method, check=False))
            bar.update(len(chunk))
    return lambda new_v: np.concatenate([b.deform(new_v) for b in bindings], axis=0)


def check_outside(points: Vertices, cage_v: Vertices, cage_f: Faces, *, shape: str,
                  cage: str, allow: bool) -> float:
    """The share of ``points`` outside a checked cage, refused above :data:`OUTSIDE_LIMIT`.

    :func:`cagekit.coords.binding.warn_outside` with the command line's rule: a warning
    for a few points outside; more than :data:`OUTSIDE_LIMIT` of them is an
    :class:`~cagekit.errors.OutsideCageError` (exit 2) that gives the likely cause (units,
    origin), unless ``allow`` (``--allow-outside``). ``shape`` and ``cage`` are the file
    names.
    """
    from cagekit.coords.binding import warn_outside
    from cagekit.errors import OutsideCageError

    try:
        return warn_outside(points, cage_v, cage_f, shape=shape, cage=cage,
                            refuse_above=1.0 if allow else OUTSIDE_LIMIT)
    except OutsideCageError as exc:
        stop = " " if exc.problem.endswith("?") else ". "  # "a different origin? More..."
        raise OutsideCageError(f"{exc.problem}{stop}More than {OUTSIDE_LIMIT:.0%} outside is "
                               "refused; --allow-outside deforms it anyway", exc.path) from None


def emit_json(obj: dict[str, Any]) -> None:
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


debug_option = click.option(
    "--debug", is_flag=True, expose_value=False, is_eager=True,
    help="Show the full traceback on errors.",
)
preview_up_option = click.option(
    "--up", type=click.Choice(["x", "y", "z"]), default="y", show_default=True,
    help="Vertical axis of the shapes in the preview.",
)
allow_outside_option = click.option(
    "--allow-outside", is_flag=True,
    help=f"Deform the shape even when more than {OUTSIDE_LIMIT:.0%} of it lies outside the "
         "cage (refused by default: most likely a cage in other units or placed elsewhere); "
         "a warning says how much.",
)
json_option = click.option(
    "--json", "as_json", is_flag=True,
    help="Print one JSON object with the results on stdout (and nothing else there).",
)
