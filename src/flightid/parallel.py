"""Tasks run in this process or on an engine handed in, gathered in task order.

``map_ordered(engine, fn, tasks)`` is ``[fn(task) for task in tasks]`` on any engine that has
``map_unordered`` (``SerialEngine`` here, one task after the other; the Dask engine of
``flightid.batch.engine``, built by ``make_engine`` above this layer and handed in by the
caller), in task order whatever the order of completion — so a computation split into fixed
tasks gives the same list on any number of workers. ``Shared`` carries an object many tasks
need (a likelihood contour with its compiled kernels) so that it is loaded once per worker
process, not once per task.

No engine is built here and nothing of Dask is imported: cloudpickle (a Dask dependency) is
imported only when a task is shipped to an engine other than ``SerialEngine``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any, Protocol

from flightid.errors import TaskError, error_line

__all__ = ["Engine", "SerialEngine", "Shared", "map_ordered"]


class Engine(Protocol):
    """What ``map_ordered`` needs of an engine: ``map_unordered(fn, tasks)`` yielding
    ``(task, fn(task), None)`` or ``(task, None, exception)`` as each task finishes."""

    def map_unordered(
        self, fn: Callable[[Any], Any], tasks: Iterable[Any]
    ) -> Iterator[tuple[Any, Any, BaseException | None]]: ...


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

    def __enter__(self) -> SerialEngine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def map_ordered(
    engine: Engine | None,
    fn: Callable[[Any], Any],
    tasks: Sequence[Any],
    labels: Sequence[str] | None = None,
    done: Callable[[int], None] | None = None,
) -> list[Any]:
    """``[fn(task) for task in tasks]`` on ``engine`` (None: in this process, one after the
    other), in task order whatever the order of completion — so a computation split into
    fixed tasks gives the same list on any number of workers.

    Args:
        engine: a ``SerialEngine``, a ``flightid.batch.engine.DaskEngine`` (anything with
            ``map_unordered``), or None.
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
