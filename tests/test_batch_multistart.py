"""Multistart estimation on the batch engine (flightid.batch.multistart): seeded start
points, clustering of optima, and a run of the ATTAS short-period case from four starts
(serial, and on a 2-worker LocalCluster with the same results)."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from flightid.batch import BatchError
from flightid.batch.multistart import cluster_optima, multistart, start_points
from flightid.cases import load_case, run_case

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "examples" / "cases" / "attas_short_period.toml"
DATA = Path(os.environ.get("FLIGHTID_DATA", ROOT / "../shared/data")).resolve()
needs_data = pytest.mark.skipif(
    not (DATA / "fvsysid").is_dir(), reason=f"real flight data not found at {DATA}"
)


def test_start_points_are_seeded_perturbations_within_bounds():
    names, values = ["a", "b", "c"], [2.0, 0.0, -1.0]
    bounds = [(-math.inf, math.inf), (-0.1, 0.1), (-1.2, -0.8)]
    points = start_points(names, values, 50, spread=0.5, seed=3, bounds=bounds)
    assert points[0] == {"a": 2.0, "b": 0.0, "c": -1.0}  # the case's own start first
    assert points == start_points(names, values, 50, spread=0.5, seed=3, bounds=bounds)
    assert points != start_points(names, values, 50, spread=0.5, seed=4, bounds=bounds)
    a = np.array([p["a"] for p in points[1:]])
    b = np.array([p["b"] for p in points[1:]])
    c = np.array([p["c"] for p in points[1:]])
    # relative spread around a nonzero value, absolute around zero, clipped to the bounds
    assert 0.6 < np.std(a / 2.0 - 1.0) / 0.5 < 1.4
    assert b.min() >= -0.1 and b.max() <= 0.1 and np.any(np.abs(b) == 0.1)
    assert c.min() >= -1.2 and c.max() <= -0.8
    with pytest.raises(BatchError, match="n_starts"):
        start_points(names, values, 0)
    with pytest.raises(BatchError, match="spread"):
        start_points(names, values, 3, spread=-1.0)


def _run(index, nll, a, std=0.1, error=None):
    if error is not None:
        return {"index": index, "error": error}
    return {
        "index": index,
        "error": None,
        "neg_log_likelihood": nll,
        "values": {"a": a},
        "std": {"a": std},
    }


def test_clusters_group_runs_within_the_tolerance_best_first():
    runs = [
        _run(0, 10.0, 1.000),
        _run(1, 5.0, 3.000),  # the better optimum, away from the first
        _run(2, 10.0 + 1e-9, 1.005),  # 0.05 σ from run 0: the same optimum
        _run(3, 5.0 + 1e-9, 3.02),  # 0.2 σ from run 1: another cluster at tol 0.1
        _run(4, 0, 0, error="diverged"),
    ]
    clusters = cluster_optima(runs, tol_sigma=0.1)
    assert [c.members for c in clusters] == [(1,), (3,), (0, 2)]
    assert clusters[0].values == {"a": 3.0} and clusters[0].neg_log_likelihood == 5.0
    assert [c.members for c in cluster_optima(runs, tol_sigma=0.5)] == [(1, 3), (0, 2)]


@needs_data
def test_four_starts_of_the_short_period_case_find_one_optimum():
    result = multistart(CASE, 4, spread=0.3, seed=0, workers=1, data_dir=DATA)
    assert "serial" in result.engine
    assert [r["index"] for r in result.runs] == [0, 1, 2, 3]
    assert all(r["error"] is None and r["converged"] for r in result.runs)
    (cluster,) = result.clusters
    assert sorted(cluster.members) == [0, 1, 2, 3]
    direct = run_case(load_case(CASE), DATA, accuracy="none").estimate
    # start 0 is the case's own start: the same run as run_case
    first = result.runs[0]
    assert first["values"] == dict(zip(direct.names, direct.values.tolist(), strict=True))
    # the starts differ (perturbed), the optimum does not (within 0.1 σ)
    assert result.runs[1]["start"] != first["start"]
    for name, value in cluster.values.items():
        assert abs(value - first["values"][name]) <= 0.1 * first["std"][name]
    assert "1 optimum" in result.summary()


@needs_data
def test_multistart_on_two_workers_equals_serial():
    distributed = pytest.importorskip("distributed")
    from flightid.batch.engine import DaskEngine

    serial = multistart(CASE, 3, spread=0.3, seed=1, workers=1, data_dir=DATA)
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    )
    client = distributed.Client(cluster)
    try:
        parallel = multistart(
            CASE, 3, spread=0.3, seed=1, engine=DaskEngine(client=client), data_dir=DATA
        )
    finally:
        client.close()
        cluster.close()
    assert "dask" in parallel.engine
    assert parallel.runs == serial.runs
    assert parallel.clusters == serial.clusters


@needs_data
def test_cli_multistart_writes_the_table(tmp_path, capsys):
    import csv

    from flightid.cli.main import main

    argv = ["batch", str(CASE), "--multistart", "2", "--workers", "1", "--seed", "5"]
    assert main([*argv, "--out", str(tmp_path), "--data-dir", str(DATA), "--quiet"]) == 0
    assert "2 starts, 2 finished, 1 optimum" in capsys.readouterr().out
    with (tmp_path / "multistart.csv").open() as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 2 * 8 and {r["cluster"] for r in rows} == {"1"}
    assert {r["start"] for r in rows} == {"0", "1"}
    # two case files are refused with one line
    assert main(["batch", str(CASE), str(CASE), "--multistart", "2", "--out", str(tmp_path)]) == 1
    assert capsys.readouterr().err.strip() == (
        "flightid: error: --multistart: expected one case file, got 2"
    )
