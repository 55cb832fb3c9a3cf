"""The batch engine's choice and life cycle: serial where Dask does not pay (with a note),
never more worker processes than tasks, workers started warm, a clean shutdown, and the
same numbers serially, on a LocalCluster of flightid's and on an external cluster reached by
its scheduler address.

The cases are simulated here (the ATTAS short-period model's response to a 3-2-1-1 elevator
input, computed with scipy.signal.lsim, seeded noise): no flight data needed. The Dask tests
need dask[distributed] and are skipped without it.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.signal

from flightid.batch import plan_cases, run_batch
from flightid.batch.engine import (
    MIN_DASK_TASKS,
    WARM_MODULES,
    choose_workers,
    estimated_startup_s,
    make_engine,
    worker_environment,
)
from flightid.cli.main import main
from flightid.errors import InputError
from flightid.parallel import SerialEngine

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "examples" / "models" / "attas_short_period.py"
# the simulated aircraft: α̇ = Zα α + (1 + Zq) q + Zδe δe, q̇ = Mα α + Mq q + Mδe δe
TRUE = {"Za": -0.5, "Zq": 0.1, "Zde": 0.7, "Ma": -5.0, "Mq": -2.0, "Mde": -7.0}
# a model module whose process sleeps 4.5 s on exit: longer than the 4 s a Dask nanny waits
# by default before it kills a worker ("Worker process still alive after 4.0 seconds")
SLOW_EXIT = "import atexit, time\natexit.register(time.sleep, 4.5)\n"


def _simulated_case(folder: Path, index: int, model: Path = MODEL) -> Path:
    """A case file and its CSV: 20 s of the short-period response, noise seeded by index."""
    t = np.arange(0.0, 20.0 + 1e-9, 0.02)
    de = np.zeros_like(t)
    for start, stop, level in ((1, 4, 0.02), (4, 6, -0.02), (6, 7, 0.02), (7, 8, -0.02)):
        de[(t >= start) & (t < stop)] = level
    p = TRUE
    a = np.array([[p["Za"], 1.0 + p["Zq"]], [p["Ma"], p["Mq"]]])
    b = np.array([[p["Zde"]], [p["Mde"]]])
    _, y, _ = scipy.signal.lsim((a, b, np.eye(2), np.zeros((2, 1))), de, t)
    y = y + np.random.default_rng(index).normal(0.0, 1.0, y.shape) * np.array([2e-4, 5e-4])
    data = folder / f"sim{index}.csv"
    np.savetxt(
        data, np.column_stack([t, de, y]), delimiter=",", header="time,de,alpha,q", comments=""
    )
    case = folder / f"sim{index}.toml"
    case.write_text(
        f'[data]\ndata_dir = "{folder}"\nfile = "{data.name}"\ntime = "time"\n'
        '[data.inputs]\nde = { column = "de" }\n'
        '[data.outputs]\nalpha = { column = "alpha" }\nq = { column = "q" }\n'
        f'[model]\nmodule = "{model}"\n[initial_state]\ndefault = "measured"\n'
        '[estimation]\nsolver = "mnres"\nmethod = "rk4"\nnoise = "max"\n'
        "[output]\nfigures = false\n",
        encoding="utf-8",
    )
    return case


def _values(result) -> dict[str, list[tuple[str, float, float | None]]]:
    return {
        r["case"]: [(p["parameter"], p["value"], p["std"]) for p in r["rows"]]
        for r in result.records
    }


# ------------------------------------------------------------------ the choice (no Dask)


def test_never_more_workers_than_tasks():
    choice = choose_workers(12, 2)
    assert choice.workers == 2
    assert "--workers 12 lowered to 2" in choice.note
    assert choose_workers(12, 1).workers == 1  # one case: serial
    assert choose_workers(3, 5).workers == 3  # asked, and fewer than tasks: as asked
    with pytest.raises(InputError, match="--workers: expected a number ≥ 1, got 0"):
        choose_workers(0, 4)


def test_a_small_batch_runs_serially_with_a_note_saying_why():
    choice = choose_workers(None, MIN_DASK_TASKS - 1, cores=8)
    assert choice.workers == 1
    assert f"fewer than {MIN_DASK_TASKS}" in choice.note and "--workers 3" in choice.note
    # asked for explicitly, the workers start (at most one per case)
    assert choose_workers(2, MIN_DASK_TASKS - 1, cores=8).workers == 2


def test_dask_only_where_the_saved_time_beats_the_start_up():
    # saved = t_task (n − ⌈n/N⌉): 8 tasks on 2 cores save 4 t_task; start-up 2.5 s here
    startup_s = estimated_startup_s(2, cores=2)
    assert startup_s == pytest.approx(2.5)
    below = choose_workers(None, 8, cores=2, task_s=0.6)  # saves 2.4 s < 2.5 s
    above = choose_workers(None, 8, cores=2, task_s=0.7)  # saves 2.8 s > 2.5 s
    assert below.workers == 1 and "would save about 2.4 s" in below.note
    assert above.workers == 2 and above.note == ""
    # a start-up measured by an earlier batch (by number of workers) replaces the estimate
    measured = choose_workers(None, 8, cores=2, task_s=0.7, startup_s={2: 10.0, 4: 0.1})
    assert measured.workers == 1 and "start-up (measured: 10 s)" in measured.note
    assert "start-up (estimated: 2.5 s)" in below.note
    # one worker per core, at most one per task
    assert choose_workers(None, 40, cores=4, task_s=1.0).workers == 4
    assert choose_workers(None, 6, cores=16, task_s=10.0).workers == 6


def test_make_engine_is_serial_for_a_small_batch(monkeypatch):
    monkeypatch.setattr(os, "cpu_count", lambda: 4)
    engine = make_engine(None, None, n_tasks=3)
    assert isinstance(engine, SerialEngine)
    assert "3 cases, fewer than 4" in engine.description


def test_the_cli_says_why_a_small_batch_runs_serially(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(os, "cpu_count", lambda: 4)
    cases = [str(_simulated_case(tmp_path, k)) for k in range(2)]
    assert main(["batch", *cases, "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert "engine serial (this process; 2 cases, fewer than 4" in err
    assert "--workers 2 starts them anyway" in err


def test_workers_get_the_kernel_cache_of_this_process(monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", "/somewhere/numba")
    monkeypatch.setenv("FLIGHTID_KERNEL_CACHE", "1")
    monkeypatch.delenv("NUMBA_NUM_THREADS", raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 8)
    env = worker_environment(4)
    assert env == {
        "NUMBA_CACHE_DIR": "/somewhere/numba",
        "FLIGHTID_KERNEL_CACHE": "1",
        "NUMBA_NUM_THREADS": "2",
    }


@pytest.mark.parametrize("name", WARM_MODULES)
def test_each_warm_up_module_exists(name):
    import importlib

    importlib.import_module(name)


def test_the_batch_records_its_earlier_case_times_as_the_estimate(tmp_path, monkeypatch):
    """A rerun of changed cases estimates a case's time from the earlier records."""
    from flightid.batch import engine as engine_module
    from flightid.batch import run as run_module

    seen = {}

    def spy(workers, scheduler, n_tasks, *, task_s=None, startup_s=None):
        seen["task_s"] = task_s
        return SerialEngine()

    cases = [_simulated_case(tmp_path, k) for k in range(2)]
    monkeypatch.setattr(run_module, "make_engine", spy)
    first = run_batch(plan_cases(cases), tmp_path / "out")
    assert seen["task_s"] is None  # nothing recorded yet: DEFAULT_TASK_S
    for case in cases:  # a changed text: the cases run again
        case.write_text(case.read_text(encoding="utf-8") + "# changed\n", encoding="utf-8")
    run_batch(plan_cases(cases), tmp_path / "out")
    walls = sorted(r["wall_s"] for r in first.records)
    assert seen["task_s"] == pytest.approx(0.5 * (walls[0] + walls[1]))
    assert engine_module.DEFAULT_TASK_S > 0


# ------------------------------------------------------------------ on Dask


@pytest.fixture(scope="module")
def dask_engine():
    pytest.importorskip("distributed", reason="dask[distributed] not installed (flightid[dask])")
    from flightid.batch.engine import DaskEngine

    engine = DaskEngine(2)
    try:
        yield engine
    finally:
        engine.close()


def test_workers_start_warm(dask_engine):
    """Before any case ran, each worker has imported the case and report code."""
    imported = dask_engine.client.run(
        lambda: [name for name in WARM_MODULES if name not in sys.modules]
    )
    assert len(imported) == 2 and all(missing == [] for missing in imported.values())
    assert dask_engine.startup_s > 0


def test_same_numbers_serially_on_our_cluster_and_on_an_external_one(tmp_path):
    pytest.importorskip("distributed", reason="dask[distributed] not installed (flightid[dask])")
    from distributed import Client, LocalCluster

    cases = plan_cases([_simulated_case(tmp_path, k) for k in range(3)])
    serial = run_batch(cases, tmp_path / "serial", engine=SerialEngine())
    ours = run_batch(cases, tmp_path / "ours", workers=2)  # the LocalCluster of flightid batch
    assert "LocalCluster, 2 worker(s)" in ours.engine and ours.startup_s > 0
    # its measured start-up is kept for the next batch's choice of serial or Dask
    from flightid.batch.run import _read_startups

    assert _read_startups(tmp_path / "ours") == {2: pytest.approx(ours.startup_s, abs=1e-3)}
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as cluster:
        messages: list[str] = []
        external = run_batch(
            cases,
            tmp_path / "external",
            scheduler=cluster.scheduler_address,
            progress=messages.append,
        )
        # the external cluster is used, not closed: its worker still answers
        with Client(cluster.scheduler_address) as client:
            assert len(client.scheduler_info()["workers"]) == 1
            assert client.submit(sum, [1, 2]).result() == 3
    assert any(f"engine dask distributed ({cluster.scheduler_address}" in m for m in messages)
    assert external.startup_s > 0
    assert os.getpid() not in {r["worker_pid"] for r in ours.records}
    assert _values(ours) == _values(serial) and _values(external) == _values(serial)
    # and near the simulated truth (an independent check that the cases ran): within 5 σ
    for rows in _values(serial).values():
        for name, value, std in rows:
            if name in TRUE:
                assert abs(value - TRUE[name]) < 5 * std, (name, value, std)


def test_make_engine_starts_no_more_workers_than_tasks():
    pytest.importorskip("distributed", reason="dask[distributed] not installed (flightid[dask])")
    with make_engine(12, None, n_tasks=2) as engine:
        assert engine.workers == 2
        assert len(engine.client.scheduler_info()["workers"]) == 2
        assert "--workers 12 lowered to 2" in engine.description


def test_cli_batch_on_two_workers_shuts_down_cleanly(tmp_path):
    """Worker processes slow to exit (4.5 s here, a loaded machine) are waited for, not
    killed: stderr holds no Dask warning, and the numbers are the serial ones."""
    pytest.importorskip("distributed", reason="dask[distributed] not installed (flightid[dask])")
    model = tmp_path / "slow_exit_model.py"
    model.write_text(SLOW_EXIT + MODEL.read_text(encoding="utf-8"), encoding="utf-8")
    cases = [str(_simulated_case(tmp_path, k, model)) for k in range(2)]
    code = "import sys; from flightid.cli.main import main; sys.exit(main())"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    argv = [sys.executable, "-c", code, "batch", *cases, "--workers", "2"]
    run = subprocess.run(
        [*argv, "--out", str(tmp_path / "out")], capture_output=True, text=True, env=env
    )
    assert run.returncode == 0, run.stderr
    assert "engine dask distributed (LocalCluster, 2 worker(s))" in run.stderr
    warnings = [line for line in run.stderr.splitlines() if "WARNING" in line or "killing" in line]
    assert warnings == []
    # the serial run on the same data with the shipped model module (this process must not
    # import the slow-exit one), against the CLI's records read back
    (tmp_path / "plain").mkdir()
    plain = [_simulated_case(tmp_path / "plain", k) for k in range(2)]
    serial = run_batch(plan_cases(plain), tmp_path / "serial", engine=SerialEngine())
    from flightid.batch.task import read_record

    on_dask = {k: read_record(tmp_path / "out" / "cases" / k) for k in ("sim0", "sim1")}
    assert {
        k: [(p["parameter"], p["value"], p["std"]) for p in r["rows"]] for k, r in on_dask.items()
    } == _values(serial)


def _sleep_s(seconds: float) -> float:
    import time

    time.sleep(seconds)
    return seconds


def test_an_interrupted_run_is_not_held_up_by_the_running_tasks():
    """Ctrl-C during a batch: the engine closes in Dask's few seconds, without waiting the
    60 s a worker gets to exit after a finished batch (its task would run 60 s more)."""
    pytest.importorskip("distributed", reason="dask[distributed] not installed (flightid[dask])")
    import time

    from flightid.batch.engine import CLOSE_TIMEOUT_S, DaskEngine

    engine = DaskEngine(2, warm=False)
    outcomes = engine.map_unordered(_sleep_s, [0.01, 60.0])
    task, result, exc = next(outcomes)  # the short task; the long one is running
    assert (task, result, exc) == (0.01, 0.01, None)
    started = time.perf_counter()
    outcomes.close()  # the interrupt leaves the loop of map_unordered
    engine.close()
    assert time.perf_counter() - started < CLOSE_TIMEOUT_S / 2


def test_a_warm_up_that_does_not_end_does_not_hold_the_batch(monkeypatch):
    """The warm-up on every worker is waited for at most WARM_UP_TIMEOUT_S, then cancelled
    (a model that kills each worker it runs on is rescheduled on replacement after
    replacement)."""
    distributed = pytest.importorskip("distributed")
    import time

    from flightid.batch import engine as engine_module

    monkeypatch.setattr(engine_module, "WARM_UP_TIMEOUT_S", 0.5)
    with distributed.LocalCluster(
        n_workers=1, processes=False, threads_per_worker=1, dashboard_address=None
    ) as cluster:
        engine = engine_module.DaskEngine(scheduler=cluster.scheduler_address)
        try:
            started = time.perf_counter()
            engine._on_every_worker(time.sleep, 4.0)
            assert time.perf_counter() - started < 3.0
        finally:
            engine.close()
