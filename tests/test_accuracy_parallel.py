"""Parallel accuracy (issue 15, part 4): profile limits, random search and the Monte Carlo
coverage study on the batch engine give the serial numbers on any number of workers.

The Dask tests run the ATTAS short-period case (its model is a case-file module, imported by
the workers from its file) on a 2-worker ``LocalCluster``, closed by its fixture; they need
the flight data (../shared/data) and ``distributed``, and are skipped without them.
"""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from flightid.accuracy import assess, region_contour
from flightid.accuracy.profile import profile_limits
from flightid.accuracy.search import CHUNK, random_search
from flightid.errors import InputError, TaskError
from flightid.parallel import SerialEngine, map_ordered

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "examples" / "cases" / "attas_short_period.toml"
DATA = Path(os.environ.get("FLIGHTID_DATA", ROOT / "../shared/data")).resolve()
needs_data = pytest.mark.skipif(
    not (DATA / "fvsysid").is_dir(), reason=f"flight data not found at {DATA}"
)


class ShuffledEngine(SerialEngine):
    """Runs the tasks in this process in reverse order and says it has 7 workers: what a
    result may not depend on (completion order, worker count)."""

    def __init__(self) -> None:
        super().__init__("shuffled")
        self.workers = 7

    def map_unordered(self, fn, tasks):
        yield from reversed(list(super().map_unordered(fn, list(tasks))))


def _exp_contour():
    from test_accuracy_models import exp_estimate

    result, data = exp_estimate(sigma=0.1, seed=3)
    accuracy = assess(result, data, methods="cr", warn=False)
    return region_contour(result, data, accuracy), accuracy.covariance


def _case_contour():
    from flightid.cases.run import run_case

    run = run_case(CASE, accuracy="none")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        accuracy = assess(run.estimate, run.maneuvers, methods="cr", warn=False)
    return region_contour(run.estimate, run.maneuvers, accuracy), accuracy.covariance


def _same_search(one, two) -> None:
    np.testing.assert_array_equal(one.intervals, two.intervals)
    np.testing.assert_array_equal(one.extreme_points, two.extreme_points)
    np.testing.assert_array_equal(one.settled, two.settled)
    assert (one.evaluations, one.inside) == (two.evaluations, two.inside)


def _same_profile(one, two) -> None:
    np.testing.assert_array_equal(one.intervals, two.intervals)
    np.testing.assert_array_equal(one.evaluations, two.evaluations)
    assert one.statuses == two.statuses


def test_search_streams_do_not_depend_on_the_workers_or_the_completion_order():
    contour, covariance = _exp_contour()
    serial = random_search(contour, covariance, budget=3000, seed=5)
    shuffled = random_search(contour, covariance, budget=3000, seed=5, engine=ShuffledEngine())
    _same_search(serial, shuffled)
    # the streams are the seed's: another seed, other points
    other = random_search(contour, covariance, budget=3000, seed=6)
    assert not np.array_equal(other.extreme_points, serial.extreme_points)
    # the global phase is int(0.1·budget) simulations in chunks of CHUNK; the refinement spends
    # the rest (each task may overshoot its share by less than one round)
    assert CHUNK == 256 and 3000 <= serial.evaluations < 3000 + 6 * 8 * 8 + 6 * 8


def test_profile_limits_in_task_order_whatever_the_completion_order():
    contour, covariance = _exp_contour()
    before = contour.evaluations
    serial = profile_limits(contour, covariance)
    assert contour.evaluations - before == serial.total_evaluations
    shuffled = profile_limits(contour, covariance, engine=ShuffledEngine())
    _same_profile(serial, shuffled)
    # a subset: the others stay NaN / skipped
    subset = profile_limits(contour, covariance, parameters=[2], engine=ShuffledEngine())
    np.testing.assert_array_equal(subset.intervals[2], serial.intervals[2])
    assert np.isnan(subset.intervals[:2]).all() and subset.statuses[0] == ("skipped", "skipped")


def _boom(task: int) -> int:
    if task == 2:
        raise InputError("task two is broken")
    return task * 10


def test_a_failing_task_is_a_named_error():
    assert map_ordered(None, _boom, [0, 1, 3]) == [0, 10, 30]
    with pytest.raises(TaskError, match=r"^realisation 2 failed: task two is broken$") as info:
        map_ordered(ShuffledEngine(), _boom, [0, 1, 2, 3], [f"realisation {i}" for i in range(4)])
    assert isinstance(info.value.__cause__, InputError)


# ---------------------------------------------------------------- on a 2-worker LocalCluster


@pytest.fixture(scope="module")
def dask_engine():
    pytest.importorskip("distributed", reason="dask[distributed] not installed (flightid[dask])")
    from flightid.batch.engine import DaskEngine

    engine = DaskEngine(workers=2)
    try:
        yield engine
    finally:
        engine.close()


@needs_data
def test_two_workers_give_the_serial_profile_and_search(dask_engine):
    contour, covariance = _case_contour()
    serial_profile = profile_limits(contour, covariance)
    before = contour.evaluations
    dask_profile = profile_limits(contour, covariance, engine=dask_engine)
    _same_profile(serial_profile, dask_profile)
    # the workers' integrations are counted on this side's contour
    assert contour.evaluations - before == dask_profile.total_evaluations > 0
    serial_search = random_search(contour, covariance, budget=2500, seed=7)
    before = contour.evaluations
    dask_search = random_search(contour, covariance, budget=2500, seed=7, engine=dask_engine)
    _same_search(serial_search, dask_search)
    assert contour.evaluations - before == dask_search.evaluations


def test_a_failing_task_on_dask_is_a_named_error_not_a_hang(dask_engine):
    with pytest.raises(TaskError, match=r"^chunk 2 failed: task two is broken$"):
        map_ordered(dask_engine, _boom, [0, 1, 2], [f"chunk {i}" for i in range(3)])


def test_coverage_study_tables_are_the_same_on_two_workers(dask_engine):
    import cloudpickle

    sys.path.insert(0, str(ROOT / "bench"))
    import coverage_study

    cloudpickle.register_pickle_by_value(coverage_study)
    serial = coverage_study.study(["exp"], 3, 1000, None, quiet=True)
    parallel = coverage_study.study(["exp"], 3, 1000, dask_engine, quiet=True)
    assert [r["seed"] for r in parallel["exp"]] == [1000, 1001, 1002]
    assert coverage_study._table("exp", serial["exp"]) == coverage_study._table(
        "exp", parallel["exp"]
    )
    assert serial == parallel


@needs_data
def test_flightid_run_workers_2_prints_the_serial_profile_limits(capsys, monkeypatch):
    pytest.importorskip("distributed", reason="dask[distributed] not installed (flightid[dask])")
    import json

    import flightid.accuracy.profile as profile_module
    from flightid.cli.main import main

    used = []
    original = profile_module.map_ordered

    def spy(engine, *args, **kwargs):
        used.append(type(engine).__name__)
        return original(engine, *args, **kwargs)

    monkeypatch.setattr(profile_module, "map_ordered", spy)
    outputs = []
    for workers in ("1", "2"):
        assert main(["run", str(CASE), "--accuracy", "profile", "--json", "--quiet",
                     "--workers", workers]) == 0  # fmt: skip
        entry = json.loads(capsys.readouterr().out)["results"][0]
        outputs.append([(p["name"], p["ci_profile"]) for p in entry["parameters"]])
    assert outputs[0] == outputs[1] and len(outputs[0]) == 8
    # --workers 1 ran the profile here, --workers 2 on the LocalCluster
    assert used == ["NoneType", "DaskEngine"]
