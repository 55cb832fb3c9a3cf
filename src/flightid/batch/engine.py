"""The engines a batch runs on: this process (serial) or Dask distributed.

Both take the same tasks (``flightid.batch.task.CaseTask``) and the same function
(``run_task``) and yield the records as the tasks finish, so a batch gives the same results
on either; only the order of completion differs.

* ``SerialEngine`` (``flightid.parallel``, where the engine-agnostic ``map_ordered`` and
  ``Shared`` live too): one task after the other in this process.
* ``DaskEngine``: a ``dask.distributed.Client`` on a ``LocalCluster(n_workers=N,
  threads_per_worker=1)`` (one process per worker: the estimation holds the GIL in Python
  and numba code alike, so threads would not run in parallel; numba's own thread pool for
  the parallel batch kernels gets ``cores // N`` threads per worker, ``worker_environment``)
  or on a running scheduler
  (``--scheduler tcp://host:8786``). Each case is one task (``pure=False``: every submission
  runs). A worker that dies (killed, out of memory) is replaced by its nanny, and the
  scheduler runs its tasks again elsewhere (up to ``distributed.scheduler.allowed-failures``
  times, 3 by default): a task's result folder is written atomically, so a task killed
  half-way leaves nothing behind and its rerun starts clean.

``make_engine(workers, scheduler, n_tasks)`` picks one: Dask when a scheduler is given or
``workers`` is more than 1 (None: one worker per core, at most one per task), serial for
``workers=1`` (or one task, or one core) or when Dask is not installed
(``pip install flightid[dask]``); ``engine.description`` says which ran, for the progress
line.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from typing import Any

from flightid.errors import InputError
from flightid.parallel import SerialEngine

__all__ = ["DaskEngine", "dask_available", "make_engine", "worker_environment"]


def dask_available() -> bool:
    """True when ``dask.distributed`` can be imported."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


def worker_environment(n_workers: int) -> dict[str, str]:
    """Environment of the LocalCluster's worker processes: numba's thread pool (the parallel
    batch kernels of ``flightid.simulation.kernels``) shares the cores among the workers,
    ``NUMBA_NUM_THREADS = max(1, cores // n_workers)``, unless it is set already. Without
    it, N workers would each start one thread per core and contend for them."""
    if "NUMBA_NUM_THREADS" in os.environ:
        return {}
    return {"NUMBA_NUM_THREADS": str(max(1, (os.cpu_count() or 1) // n_workers))}


class DaskEngine:
    """Runs the tasks on a Dask distributed cluster (a LocalCluster, or a scheduler address).

    Args:
        workers: worker processes of the LocalCluster (ignored with ``scheduler``).
        scheduler: address of a running scheduler (``tcp://host:8786``), or None.
        client: an existing ``distributed.Client`` to use (not closed by ``close``).
    """

    def __init__(
        self, workers: int | None = None, scheduler: str | None = None, client: Any = None
    ) -> None:
        from distributed import Client, LocalCluster

        self._own = client is None
        self._cluster = None
        if client is not None:
            self.client = client
        elif scheduler is not None:
            try:
                self.client = Client(scheduler, timeout="20s")
            except (OSError, TimeoutError) as exc:
                raise InputError(
                    f"--scheduler {scheduler}: no Dask scheduler answered ({exc})"
                ) from None
        else:
            n = workers or os.cpu_count() or 1
            self._cluster = LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                dashboard_address=":0",
                env=worker_environment(n),
            )
            self.client = Client(self._cluster)
        self.workers = len(self.client.scheduler_info().get("workers", {}))
        where = scheduler or ("LocalCluster" if self._cluster is not None else "client")
        self.description = f"dask distributed ({where}, {self.workers} worker(s))"

    def map_unordered(
        self, fn: Callable[[Any], Any], tasks: Iterable[Any]
    ) -> Iterator[tuple[Any, Any, BaseException | None]]:
        """Submit ``fn(task)`` for every task; yield ``(task, result, None)`` as they finish,
        ``(task, None, exc)`` for a task that raised or could not run (``KilledWorker`` after
        too many lost workers)."""
        from distributed import as_completed

        tasks = list(tasks)
        futures = [self.client.submit(fn, task, pure=False) for task in tasks]
        of = {future.key: task for future, task in zip(futures, tasks, strict=True)}
        try:
            for future in as_completed(futures):
                try:
                    yield of[future.key], future.result(), None
                except Exception as exc:
                    yield of[future.key], None, exc
        finally:
            for future in futures:
                future.cancel()

    def close(self) -> None:
        """Close the client and the LocalCluster this engine made."""
        if self._own:
            self.client.close()
            if self._cluster is not None:
                self._cluster.close()


def make_engine(
    workers: int | None = None, scheduler: str | None = None, n_tasks: int | None = None
) -> SerialEngine | DaskEngine:
    """The engine for ``--workers`` / ``--scheduler`` (see the module docstring). Without
    either, a LocalCluster of ``min(cores, n_tasks)`` workers (serial where that is 1: one
    case to run, or one core).

    Raises:
        InputError: ``workers`` < 1, both options given, or a scheduler without Dask.
    """
    if workers is not None and workers < 1:
        raise InputError(f"--workers: expected a number ≥ 1, got {workers}")
    if workers is not None and scheduler is not None:
        raise InputError("give --workers or --scheduler, not both")
    if scheduler is None and workers == 1:
        return SerialEngine("--workers 1")
    if scheduler is None and workers is None:
        workers = max(1, min(os.cpu_count() or 1, n_tasks or os.cpu_count() or 1))
        if workers == 1:
            return SerialEngine("one case to run" if n_tasks == 1 else "one core")
    if not dask_available():
        if scheduler is not None:
            raise InputError(
                f"--scheduler {scheduler}: Dask is not installed (pip install 'flightid[dask]')"
            )
        return SerialEngine("Dask is not installed: pip install 'flightid[dask]'")
    return DaskEngine(workers, scheduler)
