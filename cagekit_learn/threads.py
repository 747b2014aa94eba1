"""torch's intra-op threads for small work."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import torch

__all__ = ["one_thread"]


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
