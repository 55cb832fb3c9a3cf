"""examples/tutorial.ipynb runs from start to end and reaches the truth of its flight.

The notebook is executed as a reader would run it (a Jupyter kernel, working folder holding
the notebook and ``csv_walkthrough/``), in a temporary folder so that its report folder is
written there. One cell is appended that saves the notebook's variables as JSON for the
assertions below.
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import nbformat
import numpy as np
import pytest
from nbclient import NotebookClient

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
NOTEBOOK = EXAMPLES / "tutorial.ipynb"

# Independent source: examples/csv_walkthrough/make_flight.py (TRUE), which simulated
# my_flight.csv with these values: (Za, Zq, Zde, Ma, Mq, Mde).
TRUTH = {"Za": -0.8, "Zq": 0.05, "Zde": -0.1, "Ma": -4.5, "Mq": -1.6, "Mde": -7.0}

CHECK_CELL = """
import json as _json
_json.dump(
    {
        "names": list(result.names),
        "values": [float(v) for v in result.values],
        "std": [float(v) for v in result.std],
        "converged": bool(result.converged),
        "case_values": [float(v) for v in run.estimate.values],
        "ci_cr": [[float(a), float(b)] for a, b in accuracy.ci_cr],
        "report": str(report_path.resolve()),
    },
    open("tutorial_check.json", "w"),
)
"""


def _outputs_text(cell) -> str:
    return "".join(
        o.get("text", "") for o in cell.get("outputs", []) if o["output_type"] == "stream"
    )


def test_tutorial_notebook_runs_and_recovers_the_truth(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # a reader may have FLIGHTID_DATA set for the real data sets: the notebook must not
    # depend on it (the kernel inherits this environment)
    monkeypatch.setenv("FLIGHTID_DATA", str(tmp_path / "no_data_here"))
    shutil.copytree(EXAMPLES / "csv_walkthrough", tmp_path / "csv_walkthrough")
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    notebook.cells.append(nbformat.v4.new_code_cell(CHECK_CELL))
    started = time.perf_counter()
    NotebookClient(
        notebook,
        timeout=120,  # s per cell: a cold numba cache compiles the model in the first estimate
        kernel_name="python3",
        resources={"metadata": {"path": str(tmp_path)}},
    ).execute()  # raises CellExecutionError when any cell fails
    elapsed_s = time.perf_counter() - started

    check = json.loads((tmp_path / "tutorial_check.json").read_text())
    assert check["converged"], "the notebook's estimate did not converge"
    values = dict(zip(check["names"], check["values"], strict=True))
    sigma = dict(zip(check["names"], check["std"], strict=True))
    for name, true_value in TRUTH.items():
        assert abs(values[name] - true_value) <= 3.0 * sigma[name], (
            f"{name}: estimate {values[name]:.5f} is more than 3 CR bounds ({sigma[name]:.5f}) "
            f"from the truth {true_value}"
        )
    # the case file describes the same estimation as the notebook's cells
    np.testing.assert_allclose(check["case_values"], check["values"], rtol=1e-9, atol=1e-12)
    # each 95 % Cramér–Rao interval holds its estimate
    for (lower, upper), value in zip(check["ci_cr"], check["values"], strict=True):
        assert lower < value < upper

    report = Path(check["report"])
    assert report.name == "report.html"
    assert report.parent.parent == tmp_path.resolve()
    html = report.read_text(encoding="utf-8")
    assert "My flight: short period from a CSV file" in html  # the case title
    assert (report.parent / "results.json").is_file()

    printed = "\n".join(_outputs_text(c) for c in notebook.cells if c.cell_type == "code")
    assert "status: converged" in printed  # the summary the reader sees
    assert "profile" in printed  # the accuracy table with its profile-likelihood column
    assert elapsed_s < 60, f"the tutorial took {elapsed_s:.1f} s to run (expected seconds)"
