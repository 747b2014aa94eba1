"""Progress bars on stderr, shown only when stderr is a terminal.

One set-up for every long loop (binding, synthesis, the deform optimiser, training, the
transfer's poses): a tqdm bar sized to the terminal, or a disabled one that does nothing,
so callers never test for a bar.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from tqdm import tqdm

__all__ = ["progress_enabled", "progress_bar", "bar_callback"]


def progress_enabled() -> bool:
    """True when stderr is a terminal (where a progress bar belongs)."""
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


def progress_bar(desc: str, unit: str, total: int | None = None, initial: int = 0,
                 enabled: bool | None = None, leave: bool = False) -> tqdm:
    """A tqdm bar on stderr; disabled (a no-op with the same methods) when not wanted.

    Parameters
    ----------
    desc, unit : str
        Label and unit (``"deform"``, ``"eval"``).
    total : int, optional
    initial : int, default 0
        Where the bar starts (a resumed run).
    enabled : bool, optional
        Show it (True) or not (False); default :func:`progress_enabled`, which is what
        the command line uses.
    leave : bool, default False
        Keep the finished bar on screen (training, sampling) instead of clearing it.

    Returns
    -------
    tqdm.tqdm
        Use ``update``, ``close`` or a ``with`` block; :func:`bar_callback` adapts it to a
        ``progress(done, total)`` callback.

    Examples
    --------
    >>> with progress_bar("work", "item", total=3, enabled=False) as bar:
    ...     bar.update(3)
    """
    from tqdm import tqdm

    show = progress_enabled() if enabled is None else bool(enabled)
    columns, lines = _terminal_size()
    return tqdm(total=total, initial=initial, desc=desc, unit=unit, file=sys.stderr,
                leave=leave, ncols=columns, nrows=lines, disable=not show)


def bar_callback(bar: tqdm) -> Callable[[int, int], None]:
    """A ``progress(done, total)`` callback that moves ``bar`` (for library functions)."""

    def update(done: int, total: int) -> None:
        bar.total = total
        bar.n = min(done, total)
        bar.refresh()

    return update
