"""RP-1153 example 3: simulated nonlinear lateral model, ML/MNRES, three noise cases.

Reference values: RP-1153 table IV (noise levels) and table V (simulation values, and the
paper's estimates, which come from its own airplane and are not targets here).
"""

import json
import math

import numpy as np
import pytest

from flightid.errors import InputError
from flightid.paper import example3 as e3


@pytest.fixture(scope="module")
def case1():
    return e3.run_example3(1)


def test_simulation_values_are_table_v():
    # RP-1153 table V, "Simulation values" column (19 unknowns)
    assert len(e3.SIMULATION_VALUES) == 19
    assert e3.SIMULATION_VALUES["Cl_alpha_phat"] == 2.63  # garbled "C_l?p", read as C_lαp̂
    assert e3.SIMULATION_VALUES["Cn_alpha_rhat"] == 1.7  # garbled "C_n?r", read as C_nαr̂
    assert e3.SIMULATION_VALUES["CY_rhat"] == 0.63
    assert e3.PAPER_ESTIMATES[3]["Cn_alpha_rhat"] == 1.0118
    assert e3.example3_model().parameters.names == list(e3.SIMULATION_VALUES)


def test_data_noise_follows_table_iv_and_is_seeded():
    clean = e3.example3_data(1)
    noisy = e3.example3_data(3, seed=7)
    again = e3.example3_data(3, seed=7)
    other = e3.example3_data(3, seed=8)
    np.testing.assert_array_equal(noisy.outputs, again.outputs)
    assert not np.array_equal(noisy.outputs, other.outputs)
    assert clean.n_samples == 481 and clean.dt == pytest.approx(0.05)  # 24 s at 0.05 s
    noise = noisy.outputs - clean.outputs
    # table IV, case 3: β 0.02 rad, p 0.02, r 0.02 rad/s, Φ 0.01 rad, a_y 0.01 g
    expected = np.array([0.02, 0.02, 0.02, 0.01, 0.01])
    np.testing.assert_allclose(noise.std(axis=0), expected, rtol=0.15)
    with pytest.raises(InputError, match="case"):
        e3.example3_data(4)
    with pytest.raises(InputError, match="source"):
        e3.example3_data(1, source="wind tunnel")


def test_inputs_excite_the_nonlinear_terms():
    data = e3.example3_data(1)
    alpha = np.arctan2(data.input("w"), data.input("u"))
    # α must vary, or α·p̂ and α·r̂ would be collinear with p̂ and r̂
    assert np.ptp(alpha) > 0.05
    assert np.ptp(data.output("p")) > 1.0 and np.ptp(data.output("beta")) > 0.2


def test_case1_recovers_the_simulation_values(case1):
    result = case1["estimate"]
    assert result.converged, result.message
    for name, true in e3.SIMULATION_VALUES.items():
        value = result.value(name)
        if true == 0:
            assert abs(value) < 1e-4, name
        else:
            assert abs(value - true) <= 0.01 * abs(true), name
    assert case1["within_3sigma"] == 1.0


def test_case2_estimates_within_three_cr_bounds():
    run = e3.run_example3(2)
    result = run["estimate"]
    assert result.converged, result.message
    assert run["within_3sigma"] >= 0.9
    # the noise variances are recovered from the residuals (MAX policy), table IV case 2
    np.testing.assert_allclose(np.sqrt(result.r_diag), [0.01, 0.01, 0.01, 0.005, 0.005],
                               rtol=0.15)  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("seed", [3, 11, 12])
def test_case3_estimates_within_three_cr_bounds(seed):
    run = e3.run_example3(3, seed=seed)
    assert run["estimate"].converged, run["estimate"].message
    assert run["within_3sigma"] >= 0.9


def test_json_contract(case1):
    payload = e3.example3_json(1, run=case1)
    text = json.dumps(payload)  # serialisable
    assert json.loads(text)["example"] == 3
    assert payload["case"] == 1
    (entry,) = payload["results"]
    assert entry["method"] == "mnres"
    for key in ("converged", "status", "cost", "iterations", "equivalent_evaluations",
                "wall_time_s", "parameters"):  # fmt: skip
        assert key in entry
    names = [p["name"] for p in entry["parameters"]]
    assert names == list(e3.SIMULATION_VALUES)
    for parameter in entry["parameters"]:
        assert {"name", "value", "initial", "std", "free", "true"} <= set(parameter)
        assert parameter["true"] == e3.SIMULATION_VALUES[parameter["name"]]
        assert parameter["paper"] == e3.PAPER_ESTIMATES[1][parameter["name"]]
        assert parameter["std"] is not None and math.isfinite(parameter["std"])


def test_comparison_table_and_figures(case1, tmp_path):
    table = e3.comparison_table(case1)
    assert "Cl_alpha_phat" in table and "within 3 CR bounds" in table
    paths = e3.plot_example3(case1, tmp_path)
    assert [p.name for p in paths] == ["example3_case1_responses.png", "example3_inputs.png"]
    for path in paths:
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert path.stat().st_size > 20_000
