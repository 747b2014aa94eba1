"""Connect to a Dask cluster for batches that outgrow one machine (``amplify --cluster``).

Dask distributed was chosen over Ray by measurement (docs/benchmarks.md, "Stock
amplification"): it installs in a few megabytes of pure Python, a local cluster of two
workers starts in about two seconds, and a user points it at an existing cluster with
the scheduler's address. Its ``Client.get_executor()`` is a ``concurrent.futures``
executor, so :func:`cagekit.batch.amplify.amplify` runs the same loop on it as on a process
pool. Imported only when a cluster is asked for; the ``cluster`` extra installs it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from cagekit.batch.amplify import worker_count
from cagekit.errors import InputError

if TYPE_CHECKING:
    from distributed import Client

__all__ = ["close", "connect"]


def connect(address: str, workers: int | None = None,
            setup: Callable[[], object] | None = None) -> Client:
    """A Dask client: of a new local cluster (``"local"``) or of a running scheduler.

    Parameters
    ----------
    address : str
        ``"local"``, or a scheduler address such as ``tcp://10.0.0.5:8786``.
    workers : int, optional
        Worker processes of a local cluster (one thread each); default 2, never more than
        the cores (a :class:`~cagekit.errors.CagekitWarning` says so when a number asked
        for is cut). Ignored for a running scheduler (its workers are what they are).
    setup : callable, optional
        Run once in the main thread of every worker, today's and those that join later
        (a Dask worker plugin), for example :func:`cagekit.batch.amplify.prepare_worker`.

    Returns
    -------
    distributed.Client
        Close it with :func:`close`.

    Raises
    ------
    InputError
        Dask distributed is not installed, or the scheduler cannot be reached.

    Examples
    --------
    >>> client = connect("local", workers=2)  # doctest: +SKIP
    >>> executor = client.get_executor(pure=False)  # doctest: +SKIP
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise InputError("--cluster needs Dask distributed: pip install -e '.[cluster]'"
                         ) from None
    if address == "local":
        import dask


        # Dask's nannies set MALLOC_TRIM_THRESHOLD_=65536 in their workers (and in this
        # process): glibc then hands freed memory back at once and faults it in again,
        # which made an item 12% slower; unset, it is the process pool's speed
        with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_":
                              None}):
            cluster = LocalCluster(n_workers=worker_count(workers, default=2),
                                   threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    else:
        try:
            client = Client(address, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise InputError(f"cannot reach the Dask scheduler at {address} ({exc})"
                             ) from None
    if setup is not None:
        client.register_plugin(_Setup(setup))
    return client


def _Setup(function):
    """A Dask worker plugin that calls ``function()`` as each worker starts (in its event
    loop's thread, the worker process's main thread)."""
    from distributed.diagnostics.plugin import WorkerPlugin

    class Setup(WorkerPlugin):
        name = "cagekit-setup"

        def setup(self, worker):
            function()

    return Setup()


def close(client: Client) -> None:
    """Close a client from :func:`connect`, and its local cluster if it made one."""
    cluster = client.cluster
    client.close()
    if cluster is not None:
        cluster.close()
