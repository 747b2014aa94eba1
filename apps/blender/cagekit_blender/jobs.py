"""The operators' common frame: read the scene, compute without Blender, write the scene.

An operator reads and checks what it needs from the scene (``gather``, main thread),
computes with cagekit on plain arrays (``compute``, no ``bpy``), then adds its results to
the scene (``apply``, main thread). Called from a script (``bpy.ops.cagekit.<name>()``) it
runs the three in turn. Started from the panel (``invoke``), ``compute`` runs in a thread
while Blender stays responsive: the status bar shows its progress, Esc cancels (the scene
is left as it was; a computation already inside one cagekit call finishes in the
background and its result is dropped). Errors are one line in Blender's report, never a
traceback dialog.
"""

from __future__ import annotations

import threading


class Cancelled(Exception):
    """Raised by :class:`Progress` once the user cancelled."""


class Progress:
    """``progress(done, total, what)``: records progress, raises :class:`Cancelled` once
    :meth:`cancel` was called (compute calls it between steps)."""

    def __init__(self):
        self.done, self.total, self.what = 0, 0, ""
        self.cancelled = threading.Event()

    def __call__(self, done, total, what: str = "") -> None:
        if self.cancelled.is_set():
            raise Cancelled
        self.done, self.total = done, total
        if what:
            self.what = what

    def cancel(self) -> None:
        self.cancelled.set()

    def text(self, label: str) -> str:
        share = f" {100 * self.done / self.total:.0f}%" if self.total else ""
        return f"cagekit: {label}{share} {self.what} (Esc to cancel)".strip()


def one_line(exc: BaseException) -> str:
    """An exception as one line of text (:func:`cagekit.io.files.one_line`), named by its type
    unless it is one of cagekit's errors, which are written for people."""
    from cagekit.errors import InputError
    from cagekit.io.files import one_line as line

    text = line(exc)
    if isinstance(exc, (InputError, FloatingPointError)) or text == type(exc).__name__:
        return text
    return f"{type(exc).__name__}: {text}"


class Job:
    """Mixin for an operator, which defines ``gather(context) -> inputs`` (main thread;
    raises on bad input), ``compute(inputs, progress) -> result`` (no ``bpy``; calls
    ``progress(done, total, what)`` between steps) and ``apply(context, result)`` (main
    thread), and a ``label`` for the status bar."""

    bl_options = {"REGISTER", "UNDO"}
    label = "working"

    def _fail(self, exc) -> set:
        self.report({"ERROR"}, one_line(exc))
        return {"CANCELLED"}

    def execute(self, context):
        try:
            result = self.compute(self.gather(context), Progress())
            self.apply(context, result)
        except Exception as exc:  # noqa: BLE001 - every error is one line in the report
            return self._fail(exc)
        return {"FINISHED"}

    def invoke(self, context, event):
        try:
            inputs = self.gather(context)
        except Exception as exc:  # noqa: BLE001
            return self._fail(exc)
        self._progress = Progress()
        self._outcome = {}

        def work():
            try:
                self._outcome["result"] = self.compute(inputs, self._progress)
            except BaseException as exc:  # noqa: BLE001 - handed to the main thread
                self._outcome["error"] = exc

        self._thread = threading.Thread(target=work, daemon=True)
        self._thread.start()
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _finish(self, context) -> None:
        context.window_manager.event_timer_remove(self._timer)
        if context.workspace is not None:
            context.workspace.status_text_set(None)

    def modal(self, context, event):
        if event.type == "ESC":
            self._progress.cancel()
            self._finish(context)
            self.report({"WARNING"}, f"cagekit: {self.label} cancelled; nothing changed")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        if self._thread.is_alive():
            if context.workspace is not None:
                context.workspace.status_text_set(self._progress.text(self.label))
            return {"RUNNING_MODAL"}
        self._finish(context)
        if "error" in self._outcome:
            return self._fail(self._outcome["error"])
        try:
            self.apply(context, self._outcome["result"])
        except Exception as exc:  # noqa: BLE001
            return self._fail(exc)
        return {"FINISHED"}


def selected_and_active(context, role_selected: str, role_active: str):
    """``(the selected objects other than the active one, the active one)``; an error
    naming what is missing."""
    from cagekit.errors import InputError

    active = context.active_object
    others = [o for o in context.selected_objects if o is not active]
    if active is None:
        raise InputError(f"no active object: make the {role_active} active")
    if not others:
        raise InputError(f"select the {role_selected} too (the {role_active} active)")
    return others, active
