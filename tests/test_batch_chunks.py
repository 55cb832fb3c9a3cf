"""Short cases run in chunks on Dask, and the workers load the batch's models before the
first case: the chunk plan (a pure function), each case of a chunk keeping its own outcome
(the same values and failures as serially), and the first real case on a fresh worker
compiling nothing (its model was loaded by the warm-up).

The cases are simulated (``tests/test_batch_engine._simulated_case``): no flight data needed.
The Dask tests need dask[distributed] and are skipped without it.
"""

from __future__ import annotations

import math

import pytest

from flightid.batch import plan_cases, run_batch
from flightid.batch.engine import CHUNK_TARGET_S, plan_chunks, run_chunk
from flightid.batch.task import CaseTask, model_tasks, run_task
from flightid.parallel import SerialEngine
from test_batch_engine import _simulated_case, _values

# ------------------------------------------------------------------ the chunk plan


@pytest.mark.parametrize(
    ("n_tasks", "workers", "task_s"),
    [(32, 2, 0.075), (32, 8, 0.075), (32, 4, 0.01), (7, 2, 0.01), (100, 3, 0.2), (5, 8, 0.01)],
)
def test_the_chunks_cover_every_task_once_balanced_and_sized_for_the_target(
    n_tasks, workers, task_s
):
    sizes = plan_chunks(n_tasks, workers, task_s)
    assert sum(sizes) == n_tasks and min(sizes) >= 1
    assert max(sizes) - min(sizes) <= 1  # balanced
    # never more tasks per chunk than the target work needs, ⌈0.5 s / t_task⌉
    assert max(sizes) <= math.ceil(CHUNK_TARGET_S / task_s)
    if n_tasks >= 2 * workers:  # at least two chunks per worker
        assert len(sizes) >= 2 * workers
    # a multiple of the workers, unless every task is a chunk of its own
    assert len(sizes) % workers == 0 or len(sizes) == n_tasks


def test_the_chunk_plan_of_the_benchmark_batch():
    # 32 cases of 0.075 s on 2 workers: ⌈0.5/0.075⌉ = 7 per chunk, ≤ ⌊32/4⌋ = 8; 5 chunks,
    # rounded up to 6 (a multiple of 2 workers): 32 = 2·6 + 4·5
    assert plan_chunks(32, 2, 0.075) == [6, 6, 5, 5, 5, 5]
    # on 8 workers: ≤ ⌊32/16⌋ = 2 per chunk
    assert plan_chunks(32, 8, 0.075) == [2] * 16


def test_long_or_unknown_tasks_are_not_chunked():
    assert plan_chunks(10, 2, 2.0) == [1] * 10  # each task holds the target work already
    assert plan_chunks(10, 2, None) == [1] * 10
    assert plan_chunks(10, 2, 0.0) == [1] * 10
    assert plan_chunks(0, 2, 0.1) == []


def test_a_chunk_keeps_each_items_own_outcome():
    def inverse(x: int) -> float:
        return 1.0 / x

    outcomes, chunk_s = run_chunk(inverse, [2, 0, 4])
    assert outcomes[0] == (0.5, None) and outcomes[2] == (0.25, None)
    assert outcomes[1][0] is None and isinstance(outcomes[1][1], ZeroDivisionError)
    assert chunk_s >= 0.0


def test_the_distinct_models_of_a_batch(tmp_path):
    other = tmp_path / "other.py"
    other.write_text((_simulated_case.__globals__["MODEL"]).read_text(), encoding="utf-8")
    paths = [_simulated_case(tmp_path, k) for k in range(3)]
    paths.append(_simulated_case(tmp_path, 3, model=other))
    cases = plan_cases(paths)
    tasks = [CaseTask(c, "fp", tmp_path / "out" / c.name) for c in cases]
    chosen = model_tasks(tasks)
    assert [t.case.name for t in chosen.values()] == [cases[0].name, cases[3].name]
    assert len(model_tasks(tasks, limit=1)) == 1


# ------------------------------------------------------------------ on Dask


def _bad_case(folder, index):
    """A case whose data file is missing: it fails with a named error, the others go on."""
    path = _simulated_case(folder, index)
    (folder / f"sim{index}.csv").unlink()
    return path


def test_chunked_cases_give_the_serial_values_and_failures(tmp_path):
    pytest.importorskip("distributed", reason="dask[distributed] not installed (flightid[dask])")
    from flightid.batch.engine import DaskEngine

    paths = [_simulated_case(tmp_path, k) for k in range(5)]
    paths.insert(2, _bad_case(tmp_path, 9))
    cases = plan_cases(paths)
    tasks = [CaseTask(c, "fp", tmp_path / "serial" / c.name) for c in cases]
    (tmp_path / "serial").mkdir()
    serial = {t.case.name: run_task(t) for t in tasks}
    chunked_tasks = [CaseTask(c, "fp", tmp_path / "dask" / c.name) for c in cases]
    (tmp_path / "dask").mkdir()
    with DaskEngine(1, warm=False) as engine:
        # t_task = 0.01 s: ⌈0.5/0.01⌉ = 50, ≤ ⌊6/2⌋ = 3 per chunk: two chunks of 3 cases
        finished = list(engine.map_unordered(run_task, chunked_tasks, task_s=0.01))
    assert plan_chunks(6, 1, 0.01) == [3, 3]
    assert sorted(t.case.name for t, _, _ in finished) == sorted(serial)
    for task, record, exc in finished:
        expected = serial[task.case.name]
        assert exc is None
        assert record["status"] == expected["status"] and record["rows"] == expected["rows"]
        assert record.get("error") == expected.get("error")
        assert (task.folder / "batch.json").is_file()  # its own folder, written
    failed = [t.case.name for t, r, _ in finished if r["status"] == "failed"]
    assert failed == [cases[2].name] and "no such file" in serial[cases[2].name]["error"]


def test_a_batch_on_dask_gives_the_serial_values_with_an_earlier_case_time(tmp_path):
    """A second batch into a folder knows its cases' time (the earlier records): chunks."""
    pytest.importorskip("distributed", reason="dask[distributed] not installed (flightid[dask])")
    paths = [_simulated_case(tmp_path, k) for k in range(8)]
    cases = plan_cases(paths)
    serial = run_batch(cases, tmp_path / "serial", engine=SerialEngine())
    out = tmp_path / "dask"
    run_batch(cases, out, engine=SerialEngine())
    messages: list[str] = []
    for path in paths:  # a changed case text (a comment): every case runs again, chunked
        path.write_text(path.read_text(encoding="utf-8") + "# again\n", encoding="utf-8")
    cases = plan_cases(paths)
    chunked = run_batch(cases, out, workers=2, progress=messages.append)
    assert "LocalCluster, 2 worker(s)" in chunked.engine
    assert len(chunked.ran) == 8 and not chunked.failed
    assert _values(chunked) == _values(serial)
    assert chunked.warm_s > 0 and any("loading models" in m for m in messages)
    # one progress line per case, with its name
    for case in cases:
        assert any(m.endswith(f"— {case.name}: converged") for m in messages)


def test_the_first_case_on_a_fresh_worker_compiles_nothing(tmp_path):
    """A fresh numba cache: the warm-up compiles the batch's model, the cases compile
    nothing (numba's compile events, counted in each case's record)."""
    pytest.importorskip("distributed", reason="dask[distributed] not installed (flightid[dask])")
    from distributed import Client, LocalCluster

    from flightid.batch.engine import DaskEngine

    cache = tmp_path / "numba-cache"
    cases = plan_cases([_simulated_case(tmp_path, k) for k in range(2)])
    with (
        LocalCluster(
            n_workers=1,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
            env={"NUMBA_CACHE_DIR": str(cache)},
        ) as cluster,
        Client(cluster) as client,
    ):
        result = run_batch(cases, tmp_path / "out", engine=DaskEngine(client=client))
    assert not result.failed and result.warm_s > 0 and result.startup_s == result.warm_s
    assert [r["numba_compilations"] for r in result.records] == [0, 0]
    assert any(cache.rglob("*.nbi"))  # the warm-up compiled into the fresh cache
