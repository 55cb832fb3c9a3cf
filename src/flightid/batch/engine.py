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
  or on a running scheduler (``--scheduler tcp://host:8786``: any Dask cluster, e.g. one
  of dask-jobqueue on an HPC batch system, is used and never started or closed here). Short
  cases go in chunks, several cases per Dask task (``plan_chunks``, ``run_chunk``: each task
  about ``CHUNK_TARGET_S`` of work, each case keeping its own outcome), long ones one per
  task (``pure=False``: every submission runs). A worker that dies (killed, out
  of memory) is replaced by its nanny, and the scheduler runs its tasks again elsewhere (up
  to ``distributed.scheduler.allowed-failures`` times, 3 by default): a task's result folder
  is written atomically, so a task killed half-way leaves nothing behind and its rerun
  starts clean.

**Warm workers.** ``DaskEngine`` starts its workers warm: one warm-up task per worker
(``warm_up``) imports the case, estimation and report code and numba before the first case
arrives, so no case pays the imports; its time is part of the measured start-up
(``DaskEngine.startup_s``: cluster start + warm-up). ``warm_models`` then has every worker
run the first case of each of the batch's distinct models once (``run_batch`` calls it with
``flightid.batch.task.warm_case``), so that the model's kernels are loaded before the first
case; its time is added to ``startup_s``. Compiled kernels come from flightid's
disk cache (``flightid.model.kernel_cache``, in numba's cache folder), which the worker
processes share with this one: ``NUMBA_CACHE_DIR`` and ``FLIGHTID_KERNEL_CACHE`` of this
process are passed on to the LocalCluster's workers.

**Clean shutdown.** ``close`` waits for the worker processes to exit by themselves
(``CLOSE_TIMEOUT_S``) before the cluster is closed, so a worker that is slow to exit (a
loaded machine) is not killed by its nanny.

**Serial or Dask.** ``choose_workers`` decides, before anything starts: ``--workers 1`` is
serial; ``--workers N`` starts ``min(N, tasks)`` worker processes (never more than tasks, with
a note); without ``--workers``, Dask runs only where it pays — at least ``MIN_DASK_TASKS``
tasks, and the time the workers save, ``t_task (n − ⌈n/N⌉)``, more than their start-up
(measured by an earlier batch into the same folder, else ``estimated_startup_s``) —
otherwise the batch runs serially with a note saying why.
``make_engine`` builds the engine it chose; ``engine.description`` says which ran, for the
progress line.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import os
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any

from flightid.errors import InputError
from flightid.parallel import SerialEngine

__all__ = [
    "CLOSE_TIMEOUT_S",
    "DEFAULT_TASK_S",
    "MIN_DASK_TASKS",
    "WARM_MODULES",
    "DaskEngine",
    "EngineChoice",
    "CHUNK_TARGET_S",
    "CHUNKS_PER_WORKER",
    "choose_workers",
    "plan_chunks",
    "dask_available",
    "estimated_startup_s",
    "make_engine",
    "warm_up",
    "worker_environment",
]

# the assumed wall time of one case (s) where no earlier record of the batch folder says
# (the shipped cases take 0.2–2 s each in a fresh process, kernels loaded from the disk cache)
DEFAULT_TASK_S = 1.0
# fewer tasks than this never start worker processes unless --workers asks for them
MIN_DASK_TASKS = 4
# how long a worker process may take to exit by itself when the engine closes (s)
CLOSE_TIMEOUT_S = 60.0
# start-up of a warm LocalCluster (cluster, then one warm-up task per worker), measured on
# 2 cores: about 1 s for the scheduler and the processes, and about 1.5 s of imports per
# worker, of which the cores run ``cores`` at once
STARTUP_BASE_S = 1.0
STARTUP_IMPORT_S = 1.5
# the work one Dask task should hold where cases are short (s): Dask's round trip per task
# (scheduling, pickling the record back) is some milliseconds, a short case a few tens of them
CHUNK_TARGET_S = 0.5
# chunks per worker the chunking keeps where the cases allow, so that a slow chunk does not
# leave the other workers idle at the end
CHUNKS_PER_WORKER = 2
# the environment variables that point the worker processes at this process's kernel cache
CACHE_VARIABLES = ("NUMBA_CACHE_DIR", "FLIGHTID_KERNEL_CACHE")


def dask_available() -> bool:
    """True when ``dask.distributed`` can be imported."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


def worker_environment(n_workers: int) -> dict[str, str]:
    """Environment of the LocalCluster's worker processes.

    * numba's thread pool (the parallel batch kernels of ``flightid.simulation.kernels``)
      shares the cores among the workers, ``NUMBA_NUM_THREADS = max(1, cores //
      n_workers)``, unless it is set already: without it, N workers would each start one
      thread per core and contend for them;
    * ``NUMBA_CACHE_DIR`` and ``FLIGHTID_KERNEL_CACHE``, where set here, so that the
      workers load the kernels this process (and every earlier run) compiled.
    """
    env = {name: os.environ[name] for name in CACHE_VARIABLES if name in os.environ}
    if "NUMBA_NUM_THREADS" not in os.environ:
        env["NUMBA_NUM_THREADS"] = str(max(1, (os.cpu_count() or 1) // n_workers))
    return env


def estimated_startup_s(n_workers: int, cores: int | None = None) -> float:
    """Start-up of a warm LocalCluster of ``n_workers`` processes on ``cores`` cores (s):
    ``STARTUP_BASE_S + STARTUP_IMPORT_S · ⌈n_workers / cores⌉`` (the workers import
    flightid at the same time, ``cores`` of them at once)."""
    cores = max(1, cores or os.cpu_count() or 1)
    # t_start = t_base + t_import · ⌈N / cores⌉
    return STARTUP_BASE_S + STARTUP_IMPORT_S * math.ceil(n_workers / cores)


@dataclass(frozen=True)
class EngineChoice:
    """What ``choose_workers`` decided.

    Attributes:
        workers: worker processes to start (1: serial, in this process).
        note: why (the progress line prints it; "" where nothing needs saying).
    """

    workers: int
    note: str = ""


def choose_workers(
    requested: int | None,
    n_tasks: int | None,
    *,
    cores: int | None = None,
    task_s: float | None = None,
    startup_s: dict[int, float] | None = None,
) -> EngineChoice:
    """How many worker processes a batch of ``n_tasks`` tasks starts (1: serial).

    Args:
        requested: ``--workers`` (None: decide).
        n_tasks: tasks to run (None: unknown; no clamp, no estimate).
        cores: cores of this machine (None: ``os.cpu_count()``).
        task_s: estimated wall time of one task (None: ``DEFAULT_TASK_S``).
        startup_s: measured start-ups of earlier clusters by their number of workers (s);
            ``estimated_startup_s`` for a number without one.

    ``requested`` N > 1 gives ``min(N, n_tasks)`` (a worker per task at most). Without it,
    N = min(cores, n_tasks), and the batch runs serially where N is 1, where it has fewer
    than ``MIN_DASK_TASKS`` tasks, or where the time N workers save,
    ``t_task (n − ⌈n/N⌉)``, is not more than their start-up.

    Raises:
        InputError: ``requested`` < 1.
    """
    if requested is not None and requested < 1:
        raise InputError(f"--workers: expected a number ≥ 1, got {requested}")
    if requested == 1:
        return EngineChoice(1, "--workers 1")
    if requested is not None:
        if n_tasks is None or requested <= n_tasks:
            return EngineChoice(requested)
        n = max(1, n_tasks)
        note = f"--workers {requested} lowered to {n}: never more worker processes than cases"
        return EngineChoice(n, note if n > 1 else "one case to run")
    cores = max(1, cores or os.cpu_count() or 1)
    if n_tasks is None:
        return EngineChoice(cores, "" if cores > 1 else "one core")
    n = min(cores, n_tasks)
    if n <= 1:
        return EngineChoice(1, "one case to run" if n_tasks <= 1 else "one core")
    if n_tasks < MIN_DASK_TASKS:
        return EngineChoice(
            1,
            f"{n_tasks} cases, fewer than {MIN_DASK_TASKS}: starting worker processes would "
            f"take longer than it saves; --workers {n} starts them anyway",
        )
    task_s = DEFAULT_TASK_S if task_s is None else task_s
    measured = (startup_s or {}).get(n)
    start_s = estimated_startup_s(n, cores) if measured is None else measured
    # time saved by N workers: t_task · (n − ⌈n/N⌉)
    saved_s = task_s * (n_tasks - math.ceil(n_tasks / n))
    if saved_s <= start_s:
        how = "estimated" if measured is None else "measured"
        return EngineChoice(
            1,
            f"{n_tasks} cases of about {task_s:.2g} s would save about {saved_s:.2g} s on "
            f"{n} workers, not more than their start-up ({how}: {start_s:.2g} s); "
            f"--workers {n} starts them anyway",
        )
    return EngineChoice(n)


def plan_chunks(
    n_tasks: int,
    workers: int,
    task_s: float | None,
    *,
    target_s: float = CHUNK_TARGET_S,
    per_worker: int = CHUNKS_PER_WORKER,
) -> list[int]:
    """The sizes of the chunks (consecutive tasks run as one Dask task) for ``n_tasks`` tasks of
    about ``task_s`` seconds each on ``workers`` workers.

    Each chunk holds ``k = ⌈target_s / task_s⌉`` tasks, but no more than
    ``⌊n_tasks / (per_worker · workers)⌋`` (at least ``per_worker`` chunks per worker where
    the tasks allow it); the number of chunks is rounded up to a multiple of ``workers``
    (as the tasks allow) and the sizes differ by one at most, so that the workers finish
    together. One task per chunk where ``task_s`` is None (unknown) or not positive.
    """
    if n_tasks <= 0:
        return []
    workers = max(1, workers)
    if task_s is None or not task_s > 0.0:
        return [1] * n_tasks
    # tasks per chunk for the target work: k = ⌈t_target / t_task⌉
    size = max(1, math.ceil(target_s / task_s))
    # at least per_worker chunks per worker: k ≤ ⌊n / (per_worker · N)⌋
    size = max(1, min(size, n_tasks // (per_worker * workers)))
    n_chunks = math.ceil(n_tasks / size)
    # a multiple of the workers: n_chunks = N ⌈n_chunks / N⌉ (at most one chunk per task)
    n_chunks = min(n_tasks, workers * math.ceil(n_chunks / workers))
    base, extra = divmod(n_tasks, n_chunks)
    return [base + 1] * extra + [base] * (n_chunks - extra)


def run_chunk(
    fn: Callable[[Any], Any], items: list[Any]
) -> tuple[list[tuple[Any, BaseException | None]], float]:
    """Run ``fn`` on each item of a chunk, one after the other, on a worker: ``([(result,
    None) or (None, exception) per item], wall time of the chunk in s)``. An item that
    raises is recorded with its exception and the chunk goes on: each item keeps its own
    outcome, as if it had been a task of its own."""
    started = time.perf_counter()
    outcomes: list[tuple[Any, BaseException | None]] = []
    for item in items:
        try:
            outcomes.append((fn(item), None))
        except Exception as exc:
            outcomes.append((None, exc))
    return outcomes, time.perf_counter() - started


def warm_items(fn: Callable[[Any], Any], items: list[Any]) -> int:
    """A worker's model warm-up task: ``fn(item)`` for each item (a failure is passed over: the
    case that fails names its error when it runs). Returns the process id."""
    for item in items:
        try:
            fn(item)
        except Exception:
            continue
    return os.getpid()


# what a case's task imports (the case, estimation, accuracy and report code): a worker's
# warm-up imports them before its first case (tests/test_batch_engine.py checks each exists)
WARM_MODULES = (
    "flightid.batch.task",
    "flightid.cases.run",
    "flightid.cases.stagespec",
    "flightid.accuracy.profile",
    "flightid.model.kernel_cache",
    "flightid.model.linearization",
    "flightid.model.modes",
    "flightid.data.pipeline",
    "flightid.data.coefficients",
    "flightid.compat",
    "flightid.export",
    "flightid.jsonout",
    "flightid.report.folder",
    "flightid.report.histories",
    "flightid.report.html",
)


def warm_up() -> int:
    """A worker's warm-up task: import what a case needs (``WARM_MODULES``, numba with
    them) so that the first case does not pay the imports. A module that cannot be
    imported is passed over: the case that needs it names the error. Returns the process
    id."""
    import importlib

    for name in WARM_MODULES:
        try:
            importlib.import_module(name)
        except ImportError:
            continue
    return os.getpid()


async def _close_workers(cluster: Any, timeout_s: float) -> None:
    """Ask every worker process of ``cluster`` to close and wait up to ``timeout_s`` for it
    to exit by itself (the nanny's own wait, 4 s, kills a worker that is slow to exit)."""
    nannies = list(getattr(cluster, "workers", {}).values())
    await asyncio.gather(
        *(nanny.close(timeout=timeout_s) for nanny in nannies), return_exceptions=True
    )


# the longest a warm-up on every worker is waited for (s): warming is a saving, not a result;
# a model that kills every worker it runs on must not hold the batch up (its cases fail alone)
WARM_UP_TIMEOUT_S = 120.0


class DaskEngine:
    """Runs the tasks on a Dask distributed cluster (a LocalCluster, or a scheduler address).

    Args:
        workers: worker processes of the LocalCluster (ignored with ``scheduler``).
        scheduler: address of a running scheduler (``tcp://host:8786``), or None; its
            cluster is used as it is, never started or closed here.
        client: an existing ``distributed.Client`` to use (not closed by ``close``).
        warm: run the warm-up task (``warm_up``) on every worker before the first task.

    Attributes:
        workers: the workers the cluster has.
        startup_s: the measured start-up (s): connecting or starting the cluster, and the
            warm-up of its workers.
        description: which cluster ran, for the progress line.

    Raises:
        InputError: no scheduler answered at ``scheduler``.
    """

    def __init__(
        self,
        workers: int | None = None,
        scheduler: str | None = None,
        client: Any = None,
        *,
        warm: bool = True,
    ) -> None:
        from distributed import Client, LocalCluster

        started = time.perf_counter()
        self._own = client is None
        self._cluster = None
        self._interrupted = False  # a map_unordered left before all its tasks finished
        self._warmed: set[str] = set()  # keys of the items warm_models ran on every worker
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
        try:
            if self._cluster is not None:
                self.client.wait_for_workers(n, timeout=120)
            addresses = list(self.client.scheduler_info().get("workers", {}))
            self.workers = len(addresses)
            if warm and addresses:
                self._warm_up(addresses)
        except BaseException:
            self._interrupted = True
            self.close()  # what this engine started, and only that
            raise
        self.startup_s = time.perf_counter() - started
        where = scheduler or ("LocalCluster" if self._cluster is not None else "client")
        self.description = f"dask distributed ({where}, {self.workers} worker(s))"

    @property
    def started_cluster(self) -> bool:
        """True where this engine started its cluster (a LocalCluster)."""
        return self._cluster is not None

    def _on_every_worker(self, fn: Callable[..., Any], *args: Any, pinned: bool = True) -> None:
        """``fn(*args)`` once on each worker, waited for. ``pinned=False`` lets the scheduler
        move the task of a worker that died (its replacement, or another worker, runs it)
        instead of waiting for a worker that is gone; a task that kills every worker it runs
        on ends as ``KilledWorker``, which is waited for like a result."""
        from distributed import wait

        addresses = list(self.client.scheduler_info().get("workers", {}))
        futures = [
            self.client.submit(
                fn, *args, pure=False, workers=[address], allow_other_workers=not pinned
            )
            for address in addresses
        ]
        try:
            wait(futures, timeout=WARM_UP_TIMEOUT_S)
            lost = any(future.status == "error" for future in futures)
        except TimeoutError:  # a task rescheduled on replacement after replacement: give up
            self.client.cancel(futures)
            lost = True
        for future in futures:
            future.release()
        if lost:  # a worker died under it: wait for its nanny's new worker before the cases
            with contextlib.suppress(TimeoutError, OSError):
                self.client.wait_for_workers(len(addresses), timeout=60)

    def _warm_up(self, addresses: list[str]) -> None:
        """One ``warm_up`` task on each worker (its imports), waited for."""
        self._on_every_worker(warm_up)

    def warm_models(self, fn: Callable[[Any], Any], items: dict[str, Any]) -> float:
        """Run ``fn(item)`` for each item on every worker (``warm_items``), for the items whose
        key has not been warmed by this engine yet: the batch's distinct models load their
        compiled kernels before the first case. Returns the time it took (s), which is added
        to ``startup_s``."""
        todo = {key: item for key, item in items.items() if key not in self._warmed}
        if not todo:
            return 0.0
        started = time.perf_counter()
        # not pinned: a case whose model kills its worker must not hold the batch up here
        self._on_every_worker(warm_items, fn, list(todo.values()), pinned=False)
        self._warmed.update(todo)
        elapsed_s = time.perf_counter() - started
        self.startup_s += elapsed_s
        return elapsed_s

    def map_unordered(
        self, fn: Callable[[Any], Any], tasks: Iterable[Any], task_s: float | None = None
    ) -> Iterator[tuple[Any, Any, BaseException | None]]:
        """Submit ``fn(task)`` for every task; yield ``(task, result, None)`` as they finish,
        ``(task, None, exc)`` for a task that raised or could not run (``KilledWorker`` after
        too many lost workers: every task of the chunk it was in).

        Short tasks go in chunks (``plan_chunks``, run by ``run_chunk``): with ``task_s``
        (the expected time of one task, s) the chunks are planned at once; without it, the
        first task of each worker runs alone and the rest are planned from the time per task
        of the first one to finish."""
        from distributed import as_completed

        tasks = list(tasks)
        of: dict[str, list[Any]] = {}
        futures: list[Any] = []

        def submit(chunk: list[Any]) -> Any:
            future = self.client.submit(run_chunk, fn, chunk, pure=False)
            of[future.key] = chunk
            futures.append(future)
            return future

        def submit_planned(rest: list[Any], per_task_s: float | None) -> list[Any]:
            submitted, start = [], 0
            for size in plan_chunks(len(rest), self.workers, per_task_s):
                submitted.append(submit(rest[start : start + size]))
                start += size
            return submitted

        if task_s is None:
            first = [submit([task]) for task in tasks[: self.workers]]
            pending = tasks[self.workers :]
        else:
            first, pending = submit_planned(tasks, task_s), []
        completed = as_completed(first)
        self._interrupted = True  # until every task has finished
        try:
            for future in completed:
                chunk = of[future.key]
                try:
                    outcomes, chunk_s = future.result()
                except Exception as exc:
                    outcomes, chunk_s = [(None, exc)] * len(chunk), None
                if pending:
                    # t_task = t_chunk / tasks in the chunk, from the first chunk that finished
                    per_task_s = None if chunk_s is None else chunk_s / len(chunk)
                    completed.update(submit_planned(pending, per_task_s))
                    pending = []
                for task, (result, exc) in zip(chunk, outcomes, strict=True):
                    yield task, result, exc
            self._interrupted = False
        finally:
            for future in futures:
                future.cancel()

    def close(self) -> None:
        """Close what this engine made: the client, and the LocalCluster with its worker
        processes, each given ``CLOSE_TIMEOUT_S`` to exit by itself (no nanny kills it).
        After an interrupted run (tasks still running: Ctrl-C, an error) the workers get
        Dask's own few seconds instead, so that the interrupt is not held up by the cases
        still running. A cluster reached by its scheduler address, or a client handed in,
        stays open."""
        if not self._own:
            return
        cluster, self._own = self._cluster, False
        try:
            self.client.close()
        finally:
            if cluster is not None and self._interrupted:
                cluster.close()
            elif cluster is not None:
                try:
                    cluster.sync(_close_workers, cluster, CLOSE_TIMEOUT_S)
                finally:
                    cluster.close(timeout=CLOSE_TIMEOUT_S)

    def __enter__(self) -> DaskEngine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def make_engine(
    workers: int | None = None,
    scheduler: str | None = None,
    n_tasks: int | None = None,
    *,
    task_s: float | None = None,
    startup_s: dict[int, float] | None = None,
) -> SerialEngine | DaskEngine:
    """The engine for ``--workers`` / ``--scheduler`` (see the module docstring): the
    scheduler's cluster, or ``choose_workers(workers, n_tasks, task_s=task_s)`` worker
    processes of a LocalCluster (serial where that is 1, or where Dask is not installed);
    ``task_s`` and ``startup_s`` as for ``choose_workers``.
    A note of ``choose_workers`` (serial because it does not pay, workers lowered to the
    tasks) is in ``engine.description``.

    Raises:
        InputError: ``workers`` < 1, both options given, or a scheduler without Dask.
    """
    if workers is not None and scheduler is not None:
        raise InputError("give --workers or --scheduler, not both")
    if scheduler is not None:
        if not dask_available():
            raise InputError(
                f"--scheduler {scheduler}: Dask is not installed (pip install 'flightid[dask]')"
            )
        return DaskEngine(scheduler=scheduler)
    choice = choose_workers(workers, n_tasks, task_s=task_s, startup_s=startup_s)
    if choice.workers == 1:
        return SerialEngine(choice.note)
    if not dask_available():
        return SerialEngine("Dask is not installed: pip install 'flightid[dask]'")
    engine = DaskEngine(choice.workers)
    if choice.note:
        engine.description += f"; {choice.note}"
    return engine
