"""The engines a batch runs on: this process (serial) or Dask distributed.

Both take the same tasks (``flightid.batch.task.CaseTask``) and the same function
(``run_task``) and yield the records as the tasks finish, so a batch gives the same results
on either; only the order of completion differs.

* ``SerialEngine``: one task after the other in this process.
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
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any

from flightid.errors import InputError, TaskError, error_line

__all__ = [
    "DaskEngine",
    "SerialEngine",
    "Shared",
    "dask_available",
    "make_engine",
    "map_ordered",
]


def dask_available() -> bool:
    """True when ``dask.distributed`` can be imported."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


class SerialEngine:
    """Runs the tasks one after the other in this process."""

    def __init__(self, note: str = "") -> None:
        self.description = "serial (this process" + (f"; {note})" if note else ")")
        self.workers = 1

    def map_unordered(
        self, fn: Callable[[Any], Any], tasks: Iterable[Any]
    ) -> Iterator[tuple[Any, Any, BaseException | None]]:
        """Yield ``(task, fn(task), None)`` for each task in order, ``(task, None, exc)`` where
        ``fn`` raised an ``Exception``."""
        for task in tasks:
            try:
                yield task, fn(task), None
            except Exception as exc:
                yield task, None, exc

    def close(self) -> None:
        """Nothing to release."""


def worker_environment(n_workers: int) -> dict[str, str]:
    """Environment of the LocalCluster's worker processes: numba's thread pool (the parallel
    batch kernels of ``flightid.simulate.kernels``) shares the cores among the workers,
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


def map_ordered(
    engine: SerialEngine | DaskEngine | None,
    fn: Callable[[Any], Any],
    tasks: Sequence[Any],
    labels: Sequence[str] | None = None,
    done: Callable[[int], None] | None = None,
) -> list[Any]:
    """``[fn(task) for task in tasks]`` on ``engine`` (None: in this process, one after the
    other), in task order whatever the order of completion — so a computation split into
    fixed tasks gives the same list on any number of workers.

    Args:
        engine: a ``SerialEngine`` / ``DaskEngine`` (anything with ``map_unordered``), or None.
        fn: a module-level function (picklable for Dask; Dask ships it with cloudpickle).
        tasks: its arguments, one per task (picklable for Dask).
        labels: a name per task for the error message (default ``task i``).
        done: called with the number of tasks finished after each one (progress).

    Raises:
        TaskError: a task raised or could not run (after all tasks ended): names the first
            such task in task order, its exception is the ``__cause__``.
    """
    tasks = list(tasks)
    labels = list(labels) if labels is not None else [f"task {i}" for i in range(len(tasks))]
    results: list[Any] = [None] * len(tasks)
    failures: dict[int, BaseException] = {}
    indexed = list(enumerate(tasks))
    if engine is None:
        engine = SerialEngine()
    call: Callable[[Any], Any] = _CallIndexed(fn)
    if not isinstance(engine, SerialEngine):
        # ship the tasks as bytes, loaded inside the task: a task that cannot be loaded on a
        # worker fails as a task (a TaskError here) instead of breaking the worker's stream
        indexed = [(i, _pickled(fn, task)) for i, task in indexed]
        call = _call_pickled
    finished = 0
    for (i, _task), result, exc in engine.map_unordered(call, indexed):
        if exc is not None:
            failures[i] = exc
        else:
            results[i] = result
        finished += 1
        if done is not None:
            done(finished)
    if failures:
        first = min(failures)
        exc = failures[first]
        message = error_line(exc).removeprefix("flightid: error: ")
        if type(exc).__name__ == "KilledWorker":  # distributed.KilledWorker
            message = "the worker processes running it died each time it ran"
        more = f" ({len(failures) - 1} more task(s) failed)" if len(failures) > 1 else ""
        raise TaskError(f"{labels[first]} failed: {message}{more}") from exc
    return results


class _CallIndexed:
    """``(i, task) -> fn(task)`` (a picklable function object)."""

    def __init__(self, fn: Callable[[Any], Any]) -> None:
        self.fn = fn

    def __call__(self, item: tuple[int, Any]) -> Any:
        return self.fn(item[1])


def _pickled(fn: Callable[[Any], Any], task: Any) -> tuple[dict[str, str], bytes]:
    """(model modules, cloudpickle of ``(fn, task)``): the case files' model modules
    (``flightid_user_model_*``, imported from a file) by name and file, for a worker to
    import from the same path before it loads the task."""
    import sys

    import cloudpickle

    modules = {
        name: str(module.__file__)
        for name, module in list(sys.modules.items())
        if name.startswith("flightid_user_model_") and getattr(module, "__file__", None)
    }
    return modules, cloudpickle.dumps((fn, task))


def _call_pickled(item: tuple[int, tuple[dict[str, str], bytes]]) -> Any:
    """``(i, (modules, pickled (fn, task))) -> fn(task)``, importing the modules first."""
    import importlib.util
    import pickle
    import sys

    modules, blob = item[1]
    for name, path in modules.items():
        if name not in sys.modules:
            spec = importlib.util.spec_from_file_location(name, path)
            if spec is None or spec.loader is None:
                continue  # the task's loading names the missing module
            module = importlib.util.module_from_spec(spec)
            sys.modules[name] = module
            try:
                spec.loader.exec_module(module)
            except Exception:
                del sys.modules[name]
    fn, task = pickle.loads(blob)
    return fn(task)


class Shared:
    """An object many tasks carry (e.g. the likelihood contour: problem, data, compiled
    kernels): pickled once here, and loaded once per worker process — tasks that arrive
    with the same pickle (by its SHA-1) get the object already loaded there, so its kernels
    are loaded once per worker, not once per task. ``.obj`` is the object (in this process,
    the original). Tasks must not depend on state the object keeps between them."""

    def __init__(self, obj: Any) -> None:
        self.obj = obj
        self._key: str | None = None
        self._blob: bytes | None = None

    def __reduce__(self) -> tuple:
        if self._blob is None:
            import hashlib

            import cloudpickle

            self._blob = cloudpickle.dumps(self.obj)
            self._key = hashlib.sha1(self._blob).hexdigest()
        return (_load_shared, (self._key, self._blob))


_LOADED: dict[str, Any] = {}  # per worker process: SHA-1 of the pickle → object
_LOADED_MAX = 8


def _load_shared(key: str, blob: bytes) -> Shared:
    import pickle

    obj = _LOADED.get(key)
    if obj is None:
        obj = pickle.loads(blob)
        if len(_LOADED) >= _LOADED_MAX:
            _LOADED.pop(next(iter(_LOADED)))
        _LOADED[key] = obj
    shared = Shared(obj)
    shared._key, shared._blob = key, blob
    return shared
