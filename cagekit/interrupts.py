"""A Ctrl-C held back until the code reaches a point where it may stop.

Python raises a SIGINT's exception at whichever bytecode the main thread runs next. In code
that must not be cut short there, it breaks things: raised inside a callback of nlopt's C
code it is lost or turned into an error (:mod:`cagekit.deformation.solver`); raised inside
``concurrent.futures.wait`` while that held its futures' locks, it left a lock held, and
the interpreter's exit then waited for ever on the pool's manager thread
(:mod:`cagekit.batch.amplify`). :func:`sigint_deferred` lets the code say where.

Examples
--------
>>> import os, signal
>>> with sigint_deferred() as pending:
...     os.kill(os.getpid(), signal.SIGINT)  # noted, not raised
...     try:
...         pending()  # raised here
...     except KeyboardInterrupt:
...         print("stopped where the code chose")
stopped where the code chose
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from types import FrameType

__all__ = ["sigint_deferred"]


@contextlib.contextmanager
def sigint_deferred() -> Iterator[Callable[[], None]]:
    """While the block runs, a SIGINT only takes note; yields ``pending()``, which calls
    the SIGINT handler that was installed (it may raise) if one arrived since the last call.
    Several that arrive between two calls count as one.

    Only in the main thread (where Python runs signal handlers) and only when the installed
    handler is a Python function (``SIG_DFL`` and ``SIG_IGN`` raise nothing). The handler
    is put back when the block ends, unless the handler replaced itself meanwhile (the
    command line's ignores a second Ctrl-C while the first unwinds).
    """
    previous = signal.getsignal(signal.SIGINT)
    if not callable(previous) or threading.current_thread() is not threading.main_thread():
        yield lambda: None
        return
    arrived: list[FrameType | None] = []

    def pending():
        if arrived:
            frame = arrived.pop()
            arrived.clear()
            previous(signal.SIGINT, frame)

    def note(signum, frame):
        arrived.append(frame)

    signal.signal(signal.SIGINT, note)
    try:
        yield pending
    finally:
        if signal.getsignal(signal.SIGINT) is note:
            signal.signal(signal.SIGINT, previous)
        pending()  # one that came after the last call is not lost (it wins over an error)
