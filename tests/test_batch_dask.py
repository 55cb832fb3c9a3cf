"""flightid batch on Dask distributed: a 2-worker LocalCluster gives the numbers of serial
runs, a killed worker does not lose a case, and the workers load the compiled kernels from
flightid's disk cache instead of compiling them again.

Needs dask[distributed] (the ``dask`` extra, in the ``test`` extra) and the real flight data
(../shared/data); skipped without them. The clusters are small (2 worker processes, 1 thread
each) and closed by their fixtures.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed", reason="dask[distributed] not installed (flightid[dask])")

from distributed import Client, LocalCluster  # noqa: E402

from flightid.batch import BatchCase, run_batch  # noqa: E402
from flightid.batch.engine import DaskEngine  # noqa: E402
from flightid.cases import load_case, run_case  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CASES = ROOT / "examples" / "cases"
MODEL = ROOT / "examples" / "models" / "attas_short_period.py"
DATA = Path(os.environ.get("FLIGHTID_DATA", ROOT / "../shared/data")).resolve()
pytestmark = pytest.mark.skipif(
    not (DATA / "fvsysid").is_dir() or not (DATA / "sidpac_twin_otter").is_dir(),
    reason=f"real flight data not found at {DATA} (set FLIGHTID_DATA)",
)

# a model module that kills the process importing it, once (the marker file says it did):
# the worker running the case dies mid-task, as on an out-of-memory kill
KILLER = """\
import os, signal
from pathlib import Path

_marker = Path({marker!r})
if not _marker.exists():
    _marker.write_text(str(os.getpid()))
    os.kill(os.getpid(), signal.SIGKILL)
"""


def _fast(name: str, text: str | None = None) -> BatchCase:
    """A shipped case without figures (faster reports), lying where the shipped file lies."""
    path = CASES / f"{name}.toml"
    text = path.read_text(encoding="utf-8") if text is None else text
    if "\nfigures = true\n" in text:  # the case's own [output] asks for figures
        text = text.replace("\nfigures = true\n", "\nfigures = false\n", 1)
    elif "\n[output]\n" in text:  # the case has its own [output] table: add the key to it
        text = text.replace("\n[output]\n", "\n[output]\nfigures = false\n", 1)
    else:
        text += "\n[output]\nfigures = false\n"
    return BatchCase(name, text, path, {}, path)


@pytest.fixture(scope="module")
def client():
    cluster = LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    )
    client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def _values(record: dict) -> tuple[list[str], np.ndarray, np.ndarray]:
    rows = record["rows"]
    return (
        [r["parameter"] for r in rows],
        np.array([r["value"] for r in rows], dtype=float),
        np.array([np.nan if r["std"] is None else r["std"] for r in rows], dtype=float),
    )


def test_two_workers_give_the_serial_numbers(client, tmp_path):
    # the five standard cases of docs/cases.md
    names = (
        "hfb320_longitudinal",
        "attas_lateral",
        "attas_lateral_two_maneuvers",
        "attas_short_period",
        "twin_otter_longitudinal",
    )
    messages: list[str] = []
    result = run_batch(
        [_fast(n) for n in names],
        tmp_path / "out",
        engine=DaskEngine(client=client),
        data_dir=DATA,
        progress=messages.append,
    )
    assert any("engine dask distributed" in m and "2 worker(s)" in m for m in messages)
    assert result.failed == () and set(result.ran) == set(names)
    for record, name in zip(result.records, names, strict=True):
        # the independent path: run_case in this process
        direct = run_case(load_case(CASES / f"{name}.toml"), DATA).estimate
        parameters, values, std = _values(record)
        assert parameters == list(direct.names)
        np.testing.assert_array_equal(values, direct.values)
        np.testing.assert_array_equal(std, np.where(direct.free, direct.std, np.nan))
        assert record["status"] == direct.status and record["converged"] == direct.converged
        assert record["worker_pid"] != os.getpid()


def test_a_killed_worker_does_not_lose_a_case(client, tmp_path):
    marker = tmp_path / "killed"
    module = tmp_path / "attas_killer.py"
    module.write_text(KILLER.format(marker=str(marker)) + MODEL.read_text(encoding="utf-8"))
    text = (CASES / "attas_short_period.toml").read_text(encoding="utf-8")
    text = text.replace('"../models/attas_short_period.py"', f'"{module}"')
    assert str(module) in text
    cases = [_fast("attas_short_period", text), _fast("twin_otter_longitudinal")]
    result = run_batch(cases, tmp_path / "out", engine=DaskEngine(client=client), data_dir=DATA)
    killed_pid = int(marker.read_text())  # the module did kill a worker
    assert killed_pid != os.getpid()
    assert result.failed == () and len(result.records) == 2
    attas = result.records[0]
    assert attas["case"] == "attas_short_period" and attas["worker_pid"] != killed_pid
    direct = run_case(load_case(CASES / "attas_short_period.toml"), DATA).estimate
    np.testing.assert_array_equal(_values(attas)[1], direct.values)
    assert (tmp_path / "out" / "cases" / "attas_short_period" / "report.html").is_file()
    # the nanny replaced the worker: the cluster has 2 workers again
    client.wait_for_workers(2, timeout=30)


def test_workers_load_kernels_from_the_shared_disk_cache(tmp_path):
    """A fresh numba cache: the first batch compiles (in its warm-up), fresh worker processes
    then load."""
    cache = tmp_path / "numba-cache"
    cluster = LocalCluster(
        n_workers=1,
        threads_per_worker=1,
        processes=True,
        dashboard_address=":0",
        env={"NUMBA_CACHE_DIR": str(cache)},
    )
    client = Client(cluster)
    try:
        case = [_fast("attas_short_period")]
        first = run_batch(case, tmp_path / "a", engine=DaskEngine(client=client), data_dir=DATA)
        client.restart()  # new worker processes: nothing compiled in memory
        second = run_batch(case, tmp_path / "b", engine=DaskEngine(client=client), data_dir=DATA)
    finally:
        client.close()
        cluster.close()
    assert first.records[0]["worker_pid"] != second.records[0]["worker_pid"]
    # the first batch's warm-up compiled the model into the fresh cache, before its case
    assert first.warm_s > 0 and any(cache.rglob("*.nbi"))
    assert first.records[0]["numba_compilations"] == 0
    assert second.records[0]["numba_compilations"] == 0
    assert second.records[0]["rows"] == first.records[0]["rows"]


def test_cli_on_a_running_scheduler(client, tmp_path, capsys):
    from flightid.cli.main import main

    case = tmp_path / "attas_short_period.toml"
    case.write_text(
        _fast("attas_short_period").text.replace('"../models/attas_short_period.py"', f'"{MODEL}"')
    )
    address = client.scheduler.address
    argv = ["batch", str(case), "--scheduler", address, "--out", str(tmp_path / "out")]
    assert main([*argv, "--data-dir", str(DATA)]) == 0
    captured = capsys.readouterr()
    assert f"engine dask distributed ({address}" in captured.err
    assert "1 case(s): 1 run, 0 skipped (up to date), 0 failed" in captured.out
    assert (tmp_path / "out" / "estimates.csv").is_file()


def test_a_case_that_kills_every_worker_is_recorded_failed(tmp_path):
    """A case whose worker dies each time (here: at once, no retry allowed) is recorded as
    failed with what happened; the other case finishes."""
    import dask

    module = tmp_path / "attas_always_kills.py"
    module.write_text("import os, signal\nos.kill(os.getpid(), signal.SIGKILL)\n")
    text = (CASES / "attas_short_period.toml").read_text(encoding="utf-8")
    text = text.replace('"../models/attas_short_period.py"', f'"{module}"')
    cases = [_fast("attas_short_period", text), _fast("twin_otter_longitudinal")]
    cases[0] = BatchCase("killer", cases[0].text, cases[0].path, {}, None)
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        cluster = LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
        )
    client = Client(cluster)
    try:
        client.wait_for_workers(2, timeout=30)
        # one task per worker: the killer's deaths do not touch the other case's worker
        result = run_batch(cases, tmp_path / "out", engine=DaskEngine(client=client), data_dir=DATA)
    finally:
        client.close()
        cluster.close()
    assert result.failed == ("killer",)
    killer, other = result.records
    assert "the worker processes running it died" in killer["error"]
    assert other["status"] == "converged"
    # a lost task leaves no folder: the next batch runs it again
    assert not (tmp_path / "out" / "cases" / "killer").exists()
