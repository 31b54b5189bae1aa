"""Work spread over processes and machines with Dask (``dask.distributed``).

The one place that starts or joins a cluster and maps a function over work items. Each
item is a Dask task; its result comes back to the calling process, which alone writes
files, so a worker that dies mid-task costs only a rerun of that task on another worker
(Dask's scheduler reschedules it): no item is lost, none is written twice. Serves
flame recordings (:mod:`lf_flame.recordings`) and dataset rendering (:mod:`lf_flame.learn.dataset`).
"""
from __future__ import annotations

from contextlib import contextmanager
from typing import Callable, Iterable, Iterator

from tqdm import tqdm


@contextmanager
def dask_client(scheduler: str | None = None, workers: int = 1, threads_per_worker: int = 1):
    """A ``distributed.Client``: on an existing cluster, or on a local one for the block.

    Parameters
    ----------
    scheduler : str or None
        Address of a running scheduler (``tcp://host:8786``) or the path of its scheduler
        file (``dask scheduler --scheduler-file F``); None starts a local cluster of
        worker processes, closed when the block ends.
    workers : int
        Local cluster only: worker processes (>= 1).
    threads_per_worker : int
        Local cluster only: threads per worker (>= 1), each running one task at a time
        with Numba's kernels on one thread (:func:`map_unordered`).

    Yields
    ------
    distributed.Client

    Raises
    ------
    ValueError
        ``workers`` or ``threads_per_worker`` below 1.
    OSError
        No scheduler answers at ``scheduler`` (Dask's own error, after its timeout).
    """
    from distributed import Client, LocalCluster
    if scheduler:
        kw = ({"scheduler_file": scheduler} if not str(scheduler).startswith(("tcp://", "tls://", "inproc://",
                                                                                "ucx://")) else
              {"address": scheduler})
        with Client(**kw) as client:
            yield client
        return
    if int(workers) < 1 or int(threads_per_worker) < 1:
        raise ValueError(f"workers and threads_per_worker must be >= 1. Received: {workers}, {threads_per_worker}")
    with LocalCluster(n_workers=int(workers), threads_per_worker=int(threads_per_worker), processes=True,
                      dashboard_address=":0") as cluster, Client(cluster) as client:
        yield client


def _pin_kernel_threads(nthreads: int) -> None:
    """Numba's kernels in this thread on one thread; where the process runs several tasks
    at once (``nthreads > 1``), a threading layer that takes concurrent kernels
    (``"threadsafe"``: TBB or OpenMP; Numba's own workqueue layer aborts on them), pinned
    before the first kernel starts it."""
    import numba
    from numba.np.ufunc import parallel
    if nthreads > 1 and not parallel._is_initialized:
        numba.config.THREADING_LAYER = "threadsafe"
    numba.set_num_threads(1)


def _pin_on_worker(dask_worker) -> None:
    _pin_kernel_threads(dask_worker.state.nthreads)


def prepare_workers(client) -> None:
    """Pin every worker's Numba threads (:func:`map_unordered`'s rule) before anything
    there runs a kernel, e.g. a warm-up through ``client.run``."""
    client.run(_pin_on_worker)


def _with_worker_threads(fn, item, *args):
    """Run ``fn(item, *args)`` with Numba's kernels on one thread: a worker of ``nthreads``
    threads runs that many tasks at once, so its cores are not oversubscribed."""
    from distributed import get_worker
    _pin_kernel_threads(get_worker().state.nthreads)
    return fn(item, *args)


def map_unordered(client, fn: Callable, items: Iterable, *args, name: str = "task", window: int | None = None,
                  progress: bool = True, total: int | None = None) -> Iterator[tuple]:
    """Yield ``(item, fn(item, *args))`` for every item, in the order tasks complete.

    At most ``window`` tasks are submitted ahead (default: twice the cluster's threads), so
    large results never pile up in the workers' memory. A task whose worker dies is rerun
    by Dask on another worker; each item is yielded exactly once. ``fn`` and ``args`` must
    pickle (module-level functions, plain data, or futures of data scattered to the
    workers, ``client.scatter``); a task's exception is raised here. Each task runs its
    Numba kernels on one thread (a worker of several threads runs as many tasks at once,
    on a thread-safe threading layer).

    Parameters
    ----------
    client : distributed.Client
    fn : callable ``fn(item, *args)``
    items : iterable of hashable work items (e.g. frame-chunk indices)
    name : str
        Prefix of the task keys (``name-item``) and label of the tqdm progress bar.
    window : int or None
    progress : bool
    total : int or None
        Number of items, for the progress bar.
    """
    from distributed import as_completed
    window = window or 2 * max(1, sum(client.nthreads().values()))
    it = iter(items)
    pending, owner = as_completed(), {}

    def submit():
        for item in it:
            fut = client.submit(_with_worker_threads, fn, item, *args, key=f"{name}-{item}", pure=False,
                                retries=0)
            owner[fut.key] = item
            pending.add(fut)
            return True
        return False

    for _ in range(window):
        if not submit():
            break
    with tqdm(total=total, desc=name, disable=not progress) as bar:
        for fut in pending:
            item = owner.pop(fut.key)
            result = fut.result()
            fut.release()
            bar.update()
            submit()
            yield item, result
