"""torch's intra-op threads: one for small work, and kept when numba runs in parallel."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import torch

__all__ = ["one_thread", "torch_threads_kept"]


@contextlib.contextmanager
def one_thread() -> Iterator[None]:
    """Run torch on one thread for the duration of the block, then restore the count.

    For tiny tensors (80 landmarks in a 100-vertex cage, a test's small model) one thread
    is the fastest and is immune to a busy machine (docs/benchmarks.md, "Design notes").

    Examples
    --------
    >>> with one_thread():
    ...     torch.get_num_threads()
    1
    """
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(before)


@contextlib.contextmanager
def torch_threads_kept() -> Iterator[None]:
    """Restore torch's intra-op thread count after the block, whatever ran in it.

    numba's OpenMP threading layer sets the OpenMP thread count it shares with torch when a
    parallel kernel (:mod:`cagekit.coords.mvc_grad`) launches: after the first kernel, torch
    would run on numba's thread count instead of the user's (``OMP_NUM_THREADS``,
    :func:`torch.set_num_threads`), and its sums would change order, so a run resumed from a
    checkpoint would no longer give the weights of an uninterrupted one.

    Examples
    --------
    >>> before = torch.get_num_threads()
    >>> with torch_threads_kept():
    ...     torch.set_num_threads(before + 1)
    >>> torch.get_num_threads() == before
    True
    """
    before = torch.get_num_threads()
    try:
        yield
    finally:
        if torch.get_num_threads() != before:
            torch.set_num_threads(before)
