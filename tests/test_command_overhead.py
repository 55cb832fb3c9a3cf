"""The fixed cost of a command: what a run imports, how its figures are drawn.

* A command imports a heavy module only on the path that uses it: ``flightid run --json`` and
  ``flightid validate`` import neither matplotlib nor scipy.stats (nor pandas, dask, pyarrow,
  jinja2); importing ``flightid.cases`` or ``flightid.accuracy.levels`` imports no numerical
  module at all (fresh interpreters, read from ``python -X importtime``).
* The time histories of the report are drawn through their min/max envelope per pixel
  column: every column's extremes, and so every peak, survive (checked against the samples
  themselves).
* The figures drawn in worker processes are byte for byte those drawn in the command's own
  process, and the result folder lists the same files.
* The normal quantile taken from scipy.special and the whiteness test's χ² survival function
  are scipy.stats' (the independent reference).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "examples" / "csv_walkthrough" / "my_case.toml"
HEAVY = ("matplotlib", "scipy.stats", "pandas", "dask", "pyarrow", "jinja2")


def _env(**extra: str) -> dict[str, str]:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", **extra)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "src"), env.get("PYTHONPATH")]))
    return env


def _imported(argv: list[str], **env: str) -> tuple[set[str], subprocess.CompletedProcess]:
    """Every module a fresh interpreter imported running ``argv`` (``-X importtime``)."""
    done = subprocess.run(
        [sys.executable, "-X", "importtime", *argv],
        capture_output=True,
        text=True,
        env=_env(**env),
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    names = {
        line.split("|")[-1].strip()
        for line in done.stderr.splitlines()
        if line.startswith("import time:")
    }
    assert names, "the import-time listing was not read"
    return names, done


def _heavy(names: set[str]) -> list[str]:
    return sorted(n for n in names if any(n == h or n.startswith(h + ".") for h in HEAVY))


def test_run_json_imports_neither_matplotlib_nor_scipy_stats():
    names, done = _imported(["-m", "flightid.cli.main", "run", str(CASE), "--json", "--quiet"])
    assert '"results"' in done.stdout
    assert "flightid.estimation" in names  # it did estimate
    assert _heavy(names) == []


def test_validate_imports_neither_matplotlib_nor_scipy_stats():
    names, done = _imported(["-m", "flightid.cli.main", "validate", str(CASE)])
    assert done.stdout.strip().endswith("valid")
    assert _heavy(names) == []


@pytest.mark.parametrize("module", ["flightid.cases", "flightid.accuracy.levels"])
def test_importing_a_package_imports_no_numerical_module(module):
    names, _ = _imported(["-c", f"import {module}"])
    assert module in names
    numerical = ("numpy", "scipy", "numba", *HEAVY)
    assert sorted(n for n in names if n.split(".")[0] in numerical) == []


def test_package_names_still_resolve_on_first_use():
    import flightid.accuracy as accuracy
    import flightid.cases as cases
    from flightid.accuracy.assess import assess
    from flightid.cases.run import run_case

    assert accuracy.assess is assess and cases.run_case is run_case
    # a submodule of an export's name, imported, leaves the export in place
    import flightid.accuracy.assess  # noqa: F401
    import flightid.cases.load_run  # noqa: F401
    from flightid.cases.load_run import load_run

    assert accuracy.assess is assess and cases.load_run is load_run
    assert set(accuracy.__all__) <= set(dir(accuracy))
    for name in (*accuracy.__all__, *cases.__all__):
        assert getattr(accuracy if name in accuracy.__all__ else cases, name) is not None
    with pytest.raises(AttributeError, match="no attribute 'nonsense'"):
        _ = cases.nonsense


# ------------------------------------------------------------------------------ decimation


def _bins(n: int, bins: int) -> list[np.ndarray]:
    edges = (np.arange(bins + 1) * n) // bins
    return [np.arange(edges[b], edges[b + 1]) for b in range(bins)]


@pytest.mark.parametrize(("n", "bins"), [(10_000, 300), (1502, 633), (4001, 1000)])
def test_envelope_keeps_every_pixel_columns_min_and_max(n, bins):
    from flightid.report.figures import envelope_indices

    rng = np.random.default_rng(11)
    values = np.cumsum(rng.normal(size=n))
    # single-sample spikes, up and down, in 12 different pixel columns
    columns = _bins(n, bins)
    spikes = [rng.choice(columns[b]) for b in rng.choice(bins, size=12, replace=False)]
    values[spikes] += rng.choice([-80.0, 80.0], size=12)
    kept = envelope_indices(values, bins)
    assert np.all(np.diff(kept) > 0)
    assert kept.size <= 2 * bins
    assert set(spikes) <= set(kept)
    assert values[kept].max() == values.max() and values[kept].min() == values.min()
    for rows in _bins(n, bins):
        inside = kept[(kept >= rows[0]) & (kept <= rows[-1])]
        assert values[inside].min() == values[rows].min()
        assert values[inside].max() == values[rows].max()


def test_envelope_keeps_everything_when_the_pixels_show_every_sample():
    from flightid.report.figures import envelope_indices

    values = np.sin(np.arange(600.0))
    assert np.array_equal(envelope_indices(values, 300), np.arange(600))
    assert np.array_equal(envelope_indices(values, 5000), np.arange(600))


def test_envelope_keeps_the_gaps_of_missing_samples():
    from flightid.report.figures import envelope_indices

    values = np.cos(np.arange(5000.0) / 50.0)
    values[[100, 2500, 2501]] = np.nan
    kept = envelope_indices(values, 200)
    assert {100, 2500, 2501} <= set(kept)
    assert np.nanmax(values[kept]) == np.nanmax(values)


def test_maneuver_figure_draws_each_columns_peaks_with_fewer_points():
    from flightid.report.figures import maneuver_figure

    rng = np.random.default_rng(3)
    n = 6000
    time = np.arange(n) * 0.01
    inputs = rng.normal(size=(n, 1))
    measured = rng.normal(size=(n, 2))
    measured[4321, 0] = 25.0
    measured[17, 1] = -30.0
    predicted = 0.5 * measured
    figure = maneuver_figure(time, inputs, ["de"], measured, predicted, ["a", "q"], {}, "t", dpi=96)
    lines = [line for ax in figure.axes for line in ax.get_lines() if len(line.get_xdata()) > 2]
    # inputs, then per output: measured, predicted, residual
    series = [inputs[:, 0]]
    for j in range(2):
        series += [measured[:, j], predicted[:, j], measured[:, j] - predicted[:, j]]
    assert len(lines) == len(series)
    for line, values in zip(lines, series, strict=True):
        drawn = np.asarray(line.get_ydata(), dtype=float)
        assert drawn.size < n // 2
        assert drawn.max() == values.max() and drawn.min() == values.min()


# ------------------------------------------------------------------------------ figures


def _run_out(tmp_path: Path, name: str, workers: str) -> Path:
    out = tmp_path / name
    done = subprocess.run(
        [sys.executable, "-m", "flightid.cli.main", "run", str(CASE), "--out", str(out)]
        + ["--figure-format", "png"],
        capture_output=True,
        text=True,
        env=_env(FLIGHTID_FIGURE_WORKERS=workers),
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return out


def _files(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


def test_figures_drawn_by_workers_are_those_drawn_here(tmp_path):
    here = _run_out(tmp_path, "here", "0")
    workers = _run_out(tmp_path, "workers", "2")
    # the result folder of the output-error run (the files it listed before)
    expected = [
        ".flightid-run",
        "estimates.csv",
        "figures/autocorrelation.png",
        "figures/convergence.png",
        "figures/fit_1_my_flight.png",
        "report.html",
        "results.json",
        "time_histories.csv",
    ]
    assert _files(here) == expected
    assert _files(workers) == expected
    for name in expected:
        if name.startswith("figures/") or name.endswith(".csv"):
            assert (here / name).read_bytes() == (workers / name).read_bytes(), name


def test_a_bad_figure_worker_count_is_refused(tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "flightid.cli.main", "run", str(CASE), "--out", str(tmp_path / "o")]
        + ["--figure-format", "png"],
        capture_output=True,
        text=True,
        env=_env(FLIGHTID_FIGURE_WORKERS="two"),
        timeout=300,
    )
    assert done.returncode == 1
    assert "FLIGHTID_FIGURE_WORKERS: expected a whole number" in done.stderr
    assert "'two'" in done.stderr


def test_draw_in_a_pool_returns_the_jobs_in_order():
    from flightid.report.drawing import FigureJob, FigurePool, draw

    jobs = [
        FigureJob("cost_history_figure", ([5.0, 3.0, 2.9],), {}, 40.0, 1.0),
        FigureJob(
            "autocorrelation_figure",
            (np.eye(4, 2), 0.2, 0.1, ["a", "b"]),
            {},
            40.0,
            2.0,
        ),
    ]
    here = draw(jobs)
    pool = FigurePool.start(workers=2)
    if pool is None:
        pytest.skip("no fork start method here")
    try:
        assert draw(jobs, pool) == here
    finally:
        pool.close()
    with pytest.raises(ValueError, match="expected one of"):
        FigureJob("savefig", ())


# ------------------------------------------------------------------------------ quantiles


def test_interval_quantile_is_the_normal_quantile():
    from scipy import stats

    from flightid.report.html import interval_half_widths

    std = np.array([0.5, 2.0, 0.0])
    for level in (0.68, 0.9, 0.95, 0.999):
        expected = 1.5 * stats.norm.ppf(0.5 * (1 + level)) * std
        assert np.allclose(interval_half_widths(std, level, 1.5), expected, rtol=1e-14, atol=0)


def test_whiteness_p_value_is_the_chi_square_survival_function():
    from scipy import stats

    from flightid.accuracy.whiteness import residual_whiteness

    rng = np.random.default_rng(5)
    residuals = rng.normal(size=(400, 2))
    residuals[:, 1] = np.convolve(residuals[:, 1], np.ones(5) / 5, mode="same")
    result = residual_whiteness(residuals, ["a", "b"])
    expected = stats.chi2.sf(result.ljung_box, result.ljung_box_lags)
    # scipy's own error here is up to 2e-14 (tests/test_chi_square.py: both against the
    # exact value)
    assert np.allclose(result.p_value, expected, rtol=1e-12, atol=0)


def test_each_figure_is_drawn_once_and_embedded_as_written(tmp_path, monkeypatch):
    import base64
    import dataclasses

    from flightid.cases import load_case, run_case
    from flightid.report import drawing
    from flightid.report.html import write_files

    run = run_case(load_case(CASE))
    case = dataclasses.replace(run.case, output={**run.case.output, "figure_format": "png"})
    run = dataclasses.replace(run, case=case)
    drawn = []
    original = drawing.draw_job
    monkeypatch.setattr(
        drawing, "draw_job", lambda job: drawn.append(job.function) or original(job)
    )
    write_files(run, tmp_path)
    assert sorted(drawn) == ["autocorrelation_figure", "cost_history_figure", "maneuver_figure"]
    page = (tmp_path / "report.html").read_text(encoding="utf-8")
    for png in sorted((tmp_path / "figures").glob("*.png")):
        # the page embeds the very bytes of the file (one drawing for both)
        assert base64.b64encode(png.read_bytes()).decode("ascii") in page, png.name


def test_ctrl_c_while_workers_draw_ends_in_one_line_and_leaves_no_process(tmp_path):
    # the whole process group gets SIGINT (as from a terminal) once the figures are handed
    # to the workers: they ignore it, the command answers with its one line and ends them
    target = tmp_path / "run"
    pids = tmp_path / "workers.txt"
    script = (
        "import os, signal, sys, time\n"
        "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
        "from flightid.report import drawing\n"
        "real = drawing.FigurePool.submit\n"
        "def submit(self, job):\n"
        "    future = real(self, job)\n"
        f"    open({str(pids)!r}, 'w').write(' '.join(map(str, self._executor._processes)))\n"
        "    os.killpg(0, signal.SIGINT)\n"
        "    time.sleep(30)\n"
        "    return future\n"
        "drawing.FigurePool.submit = submit\n"
        "from flightid.cli.main import main\n"
        f"sys.exit(main(['run', {str(CASE)!r}, '--out', {str(target)!r}, '--quiet', "
        "'--figure-format', 'png']))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        env=_env(FLIGHTID_FIGURE_WORKERS="2"),
        timeout=300,
        start_new_session=True,
    )
    assert done.returncode == 130, done.stderr[-3000:]
    lines = [line for line in done.stderr.splitlines() if "warning" not in line]
    assert lines[-1] == "flightid: interrupted"
    assert "Traceback" not in done.stderr and "KeyboardInterrupt" not in done.stderr
    assert not target.exists()
    workers = [int(pid) for pid in pids.read_text().split()]
    assert len(workers) == 2
    for pid in workers:
        # ended (and reaped): no such process
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)
