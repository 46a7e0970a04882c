"""The one Dask set-up of the package, for studies and the tuning alike.

An embedded :class:`distributed.LocalCluster` by default, one single-threaded process per
core (the closed loop is CPU-bound Python and C). It listens on this machine only
(:data:`LOOPBACK`): its scheduler, its workers and its dashboard. A scheduler's address sends
the work to a real cluster instead, whose workers must see the output folders; a client of
your own is used as it is and left open (for example one made with Dask's TLS
``Security``, for a cluster reached over a network).
"""

from __future__ import annotations

import contextlib
import os

LOOPBACK = "127.0.0.1"
"""The address every socket of the embedded cluster binds to."""


@contextlib.contextmanager
def dask_client(workers: int | None = None, scheduler: str | None = None, client=None,
                log=print):
    """Context yielding a Dask client: ``client`` itself when given (never closed here);
    else one connected to ``scheduler``; else an embedded cluster of ``workers`` processes
    (default: one per core). The client and cluster made here are closed on exit."""
    if client is not None:
        yield client
        return
    from distributed import Client, LocalCluster

    cluster = None
    if scheduler is not None:
        own = Client(scheduler)
    else:
        cluster = LocalCluster(n_workers=workers or (os.cpu_count() or 1),
                               threads_per_worker=1, processes=True, host=LOOPBACK,
                               dashboard_address=f"{LOOPBACK}:0", silence_logs=40)
        own = Client(cluster)
    log(f"dask: {len(own.scheduler_info()['workers'])} worker(s), dashboard "
        f"{own.dashboard_link}")
    try:
        yield own
    finally:
        own.close()
        if cluster is not None:
            cluster.close()
