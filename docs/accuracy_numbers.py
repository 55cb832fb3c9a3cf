"""The measured numbers of docs/accuracy.md: the residual whiteness of the shipped cases.

    python docs/accuracy_numbers.py [--data-dir DIR] [--record] [--write] [--check]

Runs six case files with ``flightid run CASE --json`` and prints, per case, whether its
residuals (innovations for filter error; per coefficient for a case whose first stage is a
regression or stepwise regression) are white,
and per output the lag-1 autocorrelation ρ(1), the lags of the autocorrelation outside the
white-noise band, and the Ljung–Box statistic Q with its p-value. About 1 minute on one
core. Then the measured coverage of every estimator family's σ, ``bench/sigma_coverage.py
--seeds 100`` without its per-family wall-time lines (about 7 minutes on one idle core).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys

import case_numbers as cn

CASES = (
    (
        "examples/csv_walkthrough/my_case.toml",
        "simulated, white noise, correct model; output error",
    ),
    ("attas_lateral", "flight data; output error"),
    ("twin_otter_stepwise", "flight data, equation error (stepwise stage)"),
    ("unstab_sp_equation_error_ls", "simulated; least squares"),
    ("y13aus_lateral_output_error", "simulated lateral motion in turbulence; output error"),
    ("y13aus_lateral_filter_error", "the same data; filter error, residuals = innovations"),
)


def _p(p: float) -> str:
    return "p < 1e-300" if p == 0.0 else f"p {p:.2g}"


def _outputs(whiteness: dict) -> str:
    lag = whiteness["max_lag"]
    return "; ".join(
        f"{name}: {o['rho_1']:.2f}, {o['lags_outside']}/{lag}, {o['ljung_box_q']:.4g}, "
        f"{_p(o['p_value'])}"
        for name, o in whiteness["outputs"].items()
    )


def _verdict(whitenesses: list[dict]) -> str:
    verdicts = [
        f"{name} {'white' if o['white'] else 'coloured'}"
        for w in whitenesses
        for name, o in w["outputs"].items()
    ]
    kinds = {v.split()[-1] for v in verdicts}
    return kinds.pop() if len(kinds) == 1 else ", ".join(verdicts)


def whiteness(data_dir: str | None) -> str:
    rows = []
    for case, what in CASES:
        path = cn.ROOT / case if case.endswith(".toml") else case
        output = cn.run(path, data_dir)
        if output["results"] and not output.get("stages", [{}])[0].get("coefficients"):
            found = [output["results"][-1]["whiteness"]]
        else:
            coefficients = output["stages"][0]["coefficients"].values()
            found = [c["whiteness"] for c in coefficients]
        label = f"`{case}` ({what}, N = {found[0]['n_samples']}, L = {found[0]['max_lag']})"
        rows.append([label, _verdict(found), "; ".join(_outputs(w) for w in found)])
    heading = ["case", "residuals", "output: ρ(1), lags outside, Ljung–Box Q(20), p"]
    return cn.table(heading, rows)


def coverage_block(output: str) -> str:
    """``bench/sigma_coverage.py``'s tables as a code block, without the wall-time lines."""
    lines = [line for line in output.splitlines() if not re.fullmatch(r"\([\d.]+ s\)", line)]
    return "```text\n" + "\n".join(lines).strip() + "\n```"


def coverage() -> str:
    environment = dict(os.environ, PYTHONPATH=str(cn.ROOT / "src"))
    command = [sys.executable, str(cn.ROOT / "bench" / "sigma_coverage.py"), "--seeds", "100"]
    done = subprocess.run(command, capture_output=True, text=True, env=environment, check=True)
    return coverage_block(done.stdout)


def build(data_dir: str | None) -> list[str]:
    return [
        cn.region("accuracy-whiteness", whiteness(data_dir)),
        cn.region("accuracy-coverage", coverage()),
    ]


if __name__ == "__main__":
    raise SystemExit(cn.main("accuracy.md", "accuracy_numbers", build))
