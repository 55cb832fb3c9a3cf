"""Report figures drawn as PNG bytes, in this process or in worker processes started early.

A figure job names a figure function of ``flightid.report.figures`` (``maneuver_figure``,
``autocorrelation_figure``, ``cost_history_figure``), its arguments (plain arrays, names and
numbers) and the dpi; ``draw(jobs, pool)`` returns the PNG bytes of each job, in job order,
each figure drawn once.

``FigurePool.start()`` forks its workers at once (POSIX), before the estimation: each
imports matplotlib and the figure module while the estimation runs, and draws the figures
handed to it afterwards, two figures at a time on two cores. The command line starts one
for ``flightid run --out``; the library draws in the calling process. The PNG bytes are the
same either way (the same code on the same arrays).

The workers ignore SIGINT and take SIGTERM's default action, so that Ctrl-C in a terminal,
which reaches the whole process group, is answered by the command alone (one line, its
clean-up); ``close()`` ends them, also on an interrupt.
"""

from __future__ import annotations

import contextlib
import gc
import multiprocessing
import signal
from collections.abc import Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Any

__all__ = ["FigureJob", "FigurePool", "draw"]

# the figure functions a job may name (flightid.report.figures)
FIGURE_FUNCTIONS = ("maneuver_figure", "autocorrelation_figure", "cost_history_figure")


# the pool ``draw`` uses when given none: the command line's, while its run writes its files
_ACTIVE: list[FigurePool] = []


@dataclass(frozen=True)
class FigureJob:
    """One figure: ``flightid.report.figures.<function>(*args, **kwargs)`` drawn at ``dpi``;
    ``weight`` orders the jobs handed to workers (largest first: the longest draws start
    first)."""

    function: str
    args: tuple
    kwargs: dict = field(default_factory=dict)
    dpi: float = 96.0
    weight: float = 1.0

    def __post_init__(self) -> None:
        if self.function not in FIGURE_FUNCTIONS:
            raise ValueError(f"function: expected one of {FIGURE_FUNCTIONS}, got {self.function!r}")


def draw_job(job: FigureJob) -> bytes:
    """The PNG bytes of one job (in this process)."""
    from flightid.report import figures

    figure = getattr(figures, job.function)(*job.args, **job.kwargs)
    return figures.png_bytes(figure, job.dpi)


@contextlib.contextmanager
def _heap_frozen():
    """The objects that exist now left out of the garbage collector's passes while the
    figures are drawn (``gc.freeze``): a figure makes tens of thousands of objects, which
    set off full collections that would walk the whole heap of numpy, scipy, numba and
    matplotlib each time (0.08 s of a report's 0.5 s of figures, measured). Nothing is
    lost: the frozen objects are handed back to the collector afterwards. Left alone where
    the caller froze the heap itself."""
    if gc.get_freeze_count():
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def _worker_start() -> None:
    """A worker's set-up: signals as the module docstring says, matplotlib imported now
    (while the parent estimates), and the heap as it then is frozen (``_heap_frozen``: the
    worker only draws)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    import flightid.report.figures  # noqa: F401

    gc.freeze()


def _ready() -> bool:
    return True


class FigurePool:
    """Worker processes that draw figure jobs (see the module docstring)."""

    def __init__(self, executor: ProcessPoolExecutor, workers: int) -> None:
        self._executor = executor
        self.workers = workers

    @classmethod
    def start(cls, workers: int = 2) -> FigurePool | None:
        """Fork ``workers`` processes now; None where processes cannot be forked (no
        ``fork`` start method) or started."""
        if workers < 1 or "fork" not in multiprocessing.get_all_start_methods():
            return None
        # SIGINT ignored while forking: a Ctrl-C then would reach a worker before its set-up
        previous = signal.getsignal(signal.SIGINT)
        blocked = _set_signal(signal.SIGINT, signal.SIG_IGN)
        try:
            executor = ProcessPoolExecutor(
                max_workers=workers,
                mp_context=multiprocessing.get_context("fork"),
                initializer=_worker_start,
            )
            # the first job forks every worker (fork start method); each imports matplotlib
            executor.submit(_ready)
        except OSError:
            return None
        finally:
            if blocked:
                _set_signal(signal.SIGINT, previous)
        return cls(executor, workers)

    def activate(self) -> None:
        """Make this the pool ``draw`` uses when it is given none (until ``close``)."""
        _ACTIVE[:] = [self]

    def submit(self, job: FigureJob) -> Future:
        return self._executor.submit(draw_job, job)

    def close(self) -> None:
        """End the workers: at once, dropping jobs not started (after the figures, or on an
        interrupt)."""
        if _ACTIVE and _ACTIVE[0] is self:
            _ACTIVE.clear()
        processes = list((getattr(self._executor, "_processes", None) or {}).values())
        self._executor.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            with contextlib.suppress(Exception):
                process.terminate()
        for process in processes:
            with contextlib.suppress(Exception):
                process.join(timeout=5.0)


def _set_signal(signum: int, handler: Any) -> bool:
    """Set a signal handler where this thread may (the main thread); whether it was set."""
    try:
        signal.signal(signum, handler)
    except (ValueError, OSError, TypeError):
        return False
    return True


def draw(jobs: Sequence[FigureJob], pool: FigurePool | None = None) -> list[bytes]:
    """The PNG bytes of every job, in job order: in the workers of ``pool``, else of the
    active pool (``FigurePool.activate``), largest job first; else here. A worker that fails
    raises its error here."""
    pool = pool or (_ACTIVE[0] if _ACTIVE else None)
    if pool is None:
        with _heap_frozen():
            return [draw_job(job) for job in jobs]
    order = sorted(range(len(jobs)), key=lambda k: -jobs[k].weight)
    try:
        futures = {k: pool.submit(jobs[k]) for k in order}
        return [futures[k].result() for k in range(len(jobs))]
    except BrokenProcessPool:
        # a worker died (killed, out of memory): the figures are drawn here instead
        return [draw_job(job) for job in jobs]
