"""Many cases at once: ``flightid batch`` on Dask distributed or serially.

Modules, one job each:

* ``plan``: the case list — case files, and case templates filled from a table;
* ``fingerprint``: what a case's result depends on (skip and resume);
* ``task``: one case on a worker — run it, write its folder and record;
* ``engine``: serial or Dask distributed execution of the tasks;
* ``table``: estimates.csv / estimates.parquet, one row per case and parameter;
* ``plots``: carpet plots of each derivative against a flight-condition column;
* ``index``: index.html linking every case's report;
* ``run``: ``run_batch``, which ties them together;
* ``multistart``: one case from many start points on the same engine, optima clustered.

See docs/batch.md.
"""

from flightid.batch.plan import BatchCase, BatchError, expand_template, plan_cases
from flightid.batch.run import BatchResult, run_batch

__all__ = [
    "BatchCase",
    "BatchError",
    "BatchResult",
    "expand_template",
    "plan_cases",
    "run_batch",
]
