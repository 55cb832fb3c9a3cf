"""The 16 recursive case files of CASES.md §8 on the book data (skipped if the data are absent),
the ``[recursive]`` key checks and the results.json entry.

Reference values: the time-domain estimates of the SAME data by this project's other
estimators, as documented in docs/ (CR bound σ_ref beside each):

* ATTAS lateral p, r — output error ``attas_lateral_two_maneuvers`` (docs/cases.md,
  "Measured results of the standard cases"): the same model and data; the recursive run joins
  the two files into one record (Q11) where OEM restarts at each, a small difference.
* ATTAS short period — output error ``attas_short_period`` (docs/cases.md, same table).
* unstable aircraft — stabilized output error 3d ``unstab_sp_stabilized_output_error``
  (docs/unstable.md, "Measured comparison"): the optimum that every stabilised method finds;
  the plain OEM 3a stops in a local minimum (ln det R −10.4) and is no reference.
* HFB-320 — filter error ``hfb320_longitudinal_filter_error`` (docs/turbulence.md, "Other
  cases"): the recursive HFB-320 set-up has large per-step process noise on V (Q_V = 1.29),
  a process-noise model like the filter error method's; the output-error estimates of the
  same data (docs/cases.md: CLa 3.21, Cmq −27.1) belong to a model without process noise and
  differ from both by far more than their σ.

Tolerance |θ_rec − θ_ref| ≤ 0.2·|θ_ref| + 5·σ_ref: a single filter pass is not the ML
optimum (Jategaonkar ch. 7 reports recursive estimates close to, not equal to, the OEM ones),
and the σ term covers parameters near zero (CMV, z0). Loose on purpose, it still fails for
a wrong sign, a swapped or misnamed parameter, a wrong unit conversion or a filter that did
not move from its start values (each case checks that too).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from flightid.cases import CaseError, load_case, parse_case
from flightid.cases.recursive_case import recursive_settings, run_recursive_case

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("FLIGHTID_DATA", ROOT / "../shared/data"))
needs_data = pytest.mark.skipif(
    not (DATA / "fvsysid").is_dir(), reason=f"book data not found at {DATA} (set FLIGHTID_DATA)"
)

# name: (value, CR bound) of the reference estimator (module docstring)
ATTAS_LATERAL_OEM = {  # docs/cases.md, attas_lateral_two_maneuvers
    "Lp": (-2.06748, 0.00435),
    "Lr": (1.02928, 0.00867),
    "Ldla": (-6.30585, 0.0108),
    "Ldlr": (1.14524, 0.0211),
    "Lbeta": (-3.84437, 0.0147),
    "L0": (0.0103848, 0.000359),
    "Np": (-0.183851, 0.00246),
    "Nr": (-0.485603, 0.00467),
    "Ndla": (-0.391212, 0.0064),
    "Ndlr": (-1.76091, 0.0111),
    "Nbeta": (3.03139, 0.00919),
    "N0": (0.0345849, 0.000156),
}
ATTAS_SP_OEM = {  # docs/cases.md, attas_short_period
    "z0": (-0.00888317, 0.000693),
    "zalfa": (-0.483001, 0.00702),
    "zq": (0.102703, 0.00586),
    "zdele": (0.675922, 0.0127),
    "m0": (0.476371, 0.00152),
    "malfa": (-4.93515, 0.0172),
    "mq": (-2.01213, 0.0123),
    "mdele": (-7.22658, 0.0272),
}
UNSTAB_3D = {  # docs/unstable.md, 3d stabilized OEM
    "zw": (-1.4268, 0.00013),
    "zeta": (-6.1711, 0.001),
    "mw": (0.21702, 1.4e-05),
    "mq": (-3.7201, 0.00026),
    "meta": (-12.815, 0.0011),
}
HFB320_FEM = {  # docs/turbulence.md, hfb320_longitudinal_filter_error
    "CD0": (0.122704, 0.003),
    "CDV": (-0.0645118, 0.00254),
    "CDAL": (0.32005, 0.00721),
    "CL0": (-0.0932517, 0.0195),
    "CLV": (0.148898, 0.0165),
    "CLAL": (4.32941, 0.0467),
    "CM0": (0.112217, 0.00366),
    "CMV": (0.00367764, 0.00325),
    "CMAL": (-0.968075, 0.0108),
    "CMQ": (-34.605, 0.786),
    "CMDE": (-1.52794, 0.0194),
}

# Regression values (not an independent reference): the reported values this code printed
# for the default-suite cases (`flightid run CASE --json`, flightid at 2026-11-26, commit
# after c18c7a0). They catch an unintended change of a filter's arithmetic, which the loose
# time-domain tolerance above would let through; change them only with a reason.
REGRESSION = {
    "unstab_sp_recursive_ekf": {
        "zw": -1.4252284,
        "zeta": -6.2621708,
        "mw": 0.21751591,
        "mq": -3.7372622,
        "meta": -12.824723,
    },
    "unstab_sp_recursive_ukf": {
        "zw": -1.4251618,
        "zeta": -6.265294,
        "mw": 0.21713069,
        "mq": -3.7343184,
        "meta": -12.812162,
    },
    "unstab_sp_recursive_ukf_aug": {
        "zw": -1.4259743,
        "zeta": -6.225515,
        "mw": 0.21713721,
        "mq": -3.7284951,
        "meta": -12.819879,
    },
    "hfb320_longitudinal_recursive_ekf": {
        "CD0": 0.12351803,
        "CDV": -0.06519189,
        "CDAL": 0.31909848,
        "CL0": -0.085328268,
        "CLV": 0.14397604,
        "CLAL": 4.3027128,
        "CM0": 0.11153423,
        "CMV": 0.004608886,
        "CMAL": -0.97115841,
        "CMQ": -34.937241,
        "CMDE": -1.5328113,
    },
    "attas_short_period_recursive_efrls": {
        "z0": -0.0074845707,
        "zalfa": -0.50049201,
        "zq": 0.10915812,
        "zdele": 0.66930253,
        "m0": 0.46512108,
        "malfa": -4.8464182,
        "mq": -1.9719929,
        "mdele": -7.1295737,
    },
    "attas_short_period_recursive_ftr": {
        "zalfa": -0.47720332,
        "zq": 0.10478641,
        "zdele": 0.6652711,
        "malfa": -4.9296108,
        "mq": -2.031226,
        "mdele": -7.2542523,
    },
}

# (case, reference, number of reported parameters): the default suite runs one case per
# method on the shortest records; the rest are slow
FAST = [
    ("unstab_sp_recursive_ekf", UNSTAB_3D, 5),
    ("unstab_sp_recursive_ukf", UNSTAB_3D, 5),
    ("unstab_sp_recursive_ukf_aug", UNSTAB_3D, 5),
    ("hfb320_longitudinal_recursive_ekf", HFB320_FEM, 11),
    ("attas_short_period_recursive_efrls", ATTAS_SP_OEM, 8),
    ("attas_short_period_recursive_ftr", ATTAS_SP_OEM, 6),
]
SLOW = [
    ("hfb320_longitudinal_recursive_ukf", HFB320_FEM, 11),
    ("hfb320_longitudinal_recursive_ukf_aug", HFB320_FEM, 11),
    ("attas_short_period_recursive_ekf", ATTAS_SP_OEM, 8),
    ("attas_short_period_recursive_ukf", ATTAS_SP_OEM, 8),
    ("attas_short_period_recursive_ukf_aug", ATTAS_SP_OEM, 8),
    ("attas_lateral_pr_recursive_ekf", ATTAS_LATERAL_OEM, 12),
    ("attas_lateral_pr_recursive_ukf", ATTAS_LATERAL_OEM, 12),
    ("attas_lateral_pr_recursive_ukf_aug", ATTAS_LATERAL_OEM, 12),
    ("attas_lateral_pr_recursive_efrls", ATTAS_LATERAL_OEM, 12),
    ("attas_lateral_pr_recursive_ftr", ATTAS_LATERAL_OEM, 10),
]
CASES = [pytest.param(*c, id=c[0]) for c in FAST] + [
    pytest.param(*c, id=c[0], marks=pytest.mark.slow) for c in SLOW
]


def test_all_sixteen_case_files_are_listed():
    shipped = sorted(p.stem for p in (ROOT / "examples/cases").glob("*_recursive_*.toml"))
    assert shipped == sorted(c[0] for c in FAST + SLOW)
    assert len(shipped) == 16


@needs_data
@pytest.mark.parametrize("name, reference, n_parameters", CASES)
def test_case_runs_and_lands_near_the_time_domain_estimates(name, reference, n_parameters):
    case = load_case(ROOT / "examples/cases" / f"{name}.toml")
    result = run_recursive_case(case, DATA)
    assert len(result.parameter_names) == n_parameters
    assert set(result.parameter_names) <= set(reference)
    assert np.all(np.isfinite(result.values))
    if result.method == "efrls":
        # no standard error: the RLS scale is reported beside a NaN std
        assert np.all(np.isnan(result.std)) and np.all(result.rls_scale > 0)
    else:
        assert np.all(np.isfinite(result.std)) and np.all(result.std > 0)
    for j, name_j in enumerate(result.parameter_names):
        ref, sigma = reference[name_j]
        tolerance = 0.2 * abs(ref) + 5 * sigma
        assert abs(result.values[j] - ref) <= tolerance, (name_j, result.values[j], ref)
    if result.initial is not None:
        # the filter moved: some estimate changed by more than 20 % of its start value
        initial = np.asarray(result.initial)
        shift = np.abs(result.values - initial) / np.maximum(np.abs(initial), 1e-3)
        assert np.max(shift) > 0.2, shift
    if name in REGRESSION:
        # regression values (above): rounding of BLAS and libm may differ between machines
        expected = [REGRESSION[name][n] for n in result.parameter_names]
        np.testing.assert_allclose(result.values, expected, rtol=1e-5, atol=1e-9)
    entry = result.to_dict()
    assert [p["name"] for p in entry["parameters"]] == list(result.parameter_names)


@needs_data
def test_results_entry_follows_the_schema_and_files_are_written(tmp_path):
    jsonschema = pytest.importorskip("jsonschema")
    case = load_case(ROOT / "examples/cases/unstab_sp_recursive_ekf.toml")
    result = run_recursive_case(case, DATA)
    from flightid.report.estimator_reports import write_recursive_files

    path = write_recursive_files(result, tmp_path)
    # report.html stands alone: the figure embedded, the files linked
    assert path.name == "report.html"
    page = path.read_text()
    assert "data:image/png;base64," in page and "href='parameter_histories.csv'" in page
    assert "zw" in page  # the summary table
    document = json.loads((tmp_path / "results.json").read_text())
    schema = json.loads((ROOT / "docs/schema/results.schema.json").read_text())
    jsonschema.validate(document, schema)
    entry = document["results"][0]
    assert entry["method"] == "ekf" and entry["recursive"]["report"] == "last_10"
    zw = entry["parameters"][0]
    assert zw["name"] == "zw" and zw["initial"] == pytest.approx(-1.22871)
    # reported value = mean of the last 10 filtered values; last_filtered = the last one
    assert zw["value"] == pytest.approx(np.mean(result.theta_history[-10:, 0]), rel=1e-12)
    assert zw["last_filtered"] == result.theta_history[-1, 0]
    header = (tmp_path / "parameter_histories.csv").read_text().splitlines()[0]
    assert header.startswith("time_s,sample,zw,zw_std")
    assert (tmp_path / "figures/parameter_histories.png").stat().st_size > 1000


def _case(recursive: dict, model: bool = True):
    raw = {
        "data": {"file": "x.asc", "inputs": {"de": 5}, "outputs": {"az": 6}},
        "model": {"module": "../models/unstab_sp_rpe.py"},
        "recursive": recursive,
    }
    return parse_case(raw, ROOT / "examples/cases/fake.toml")


# a complete FTR table (the others' errors are those of one changed key)
_FTR_TABLE = {
    "method": "ftr",
    "states": ["q"],
    "inputs": ["de"],
    "update_every_s": 1.0,
    "frequencies_hz": {"start": 0.2, "stop": 1.5, "step": 0.04},
}


@pytest.mark.parametrize(
    "table, message",
    [
        ({}, "recursive: expected a table with at least 'method'"),
        ({"p0": 1}, "recursive.method: missing"),
        ({"method": "kalman"}, "recursive.method: expected one of"),
        ({"method": "ekf", "p0": 10, "q_states": 1e-7, "r0": 1e-4, "gain": 1}, "recursive.gain"),
        ({"method": "ekf", "p0": 10, "r0": 1e-4}, "recursive.q_states: missing"),
        (
            {"method": "ukf", "p0": 10, "q_states": 1e-7, "r0": 1e-4, "jacobian_step": 1e-4},
            "recursive.jacobian_step: unknown key",
        ),  # fmt: skip
        ({"method": "ekf", "p0": -1, "q_states": 1e-7, "r0": 1e-4}, "recursive.p0"),
        ({"method": "ekf", "p0": 1, "q_states": 1e-7, "r0": [1e-4, 0]}, r"recursive.r0\[1\]"),
        ({"method": "ekf", "p0": 1, "q_states": "big", "r0": 1}, "recursive.q_states"),
        ({"method": "efrls", "forgetting": 1.2}, "recursive.forgetting"),
        ({"method": "ekf", "p0": 1, "q_states": 1, "r0": 1, "report": "mean"}, "recursive.report"),
        (
            {
                "method": "ftr",
                "states": ["q"],
                "inputs": ["de"],
                "update_every_s": 1.0,
                "frequencies_hz": {"start": 0.2, "stop": 1.5},
            },
            "recursive.frequencies_hz.step",
        ),  # fmt: skip
        (
            {"method": "efrls", "jacobian_step": [1e-7]},
            r"recursive.jacobian_step: the EFRLS step is relative, one number; got \[1e-07\]",
        ),
        ({**_FTR_TABLE, "states": []}, r"recursive.states: expected at least one state channel"),
        (
            {**_FTR_TABLE, "frequencies_hz": [0.2, 1.5]},
            r"recursive.frequencies_hz: expected a table \{start, stop, step\} \(Hz\)",
        ),
        (
            {**_FTR_TABLE, "update_every_s": 0},
            r"recursive.update_every_s: expected a time > 0 \(s\), got 0.0",
        ),
        (
            {**_FTR_TABLE, "parameter_names": "Zw"},
            "recursive.parameter_names: expected a list of lists of names, got 'Zw'",
        ),
        (
            {**_FTR_TABLE, "offsets": [1.0]},
            r"recursive.offsets: expected a table name = number, got \[1.0\]",
        ),
        (
            {**_FTR_TABLE, "input_delays_s": 0.05},
            r"recursive.input_delays_s: expected a table input channel = delay \(s\), got 0.05",
        ),
    ],
)
def test_bad_recursive_keys_are_case_errors_naming_the_key(table, message):
    with pytest.raises(CaseError, match=message):
        recursive_settings(_case(table).recursive)


@needs_data
def test_setting_lengths_are_checked_against_the_model():
    raw = load_case(ROOT / "examples/cases/unstab_sp_recursive_ekf.toml").raw
    raw = {**raw, "recursive": {**raw["recursive"], "q_states": [1e-9, 1e-9, 1e-9]}}
    case = parse_case(raw, ROOT / "examples/cases/unstab_sp_recursive_ekf.toml")
    with pytest.raises(CaseError, match="recursive.q_states: expected a number or a list of 2"):
        run_recursive_case(case, DATA)


def test_flightid_validate_checks_the_recursive_table(tmp_path, capsys):
    # `flightid validate` runs the [recursive] checks too: a misspelt key is a one-line error
    # naming it (exit 1), before any data is read
    from flightid.cli.main import main

    case = tmp_path / "bad.toml"
    case.write_text(
        '[data]\nfile = "x.csv"\n[data.outputs]\ny = { column = 2 }\n[model]\n'
        'module = "m.py"\n[recursive]\nmethod = "ekf"\nforgeting = 0.9\n'
    )
    assert main(["validate", str(case)]) == 1
    assert "recursive.forgeting: unknown key" in capsys.readouterr().err
