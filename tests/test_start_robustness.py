"""Start-value robustness and tolerances, the fast part of bench/start_robustness.py
(issue 10 §2; the full table is in docs/benchmarks.md).

"Converged" means converged: a run either ends within 0.1 Cramér–Rao σ of the optimum or
says that it is not converged. The optimum θ* and its σ come from a separate run of the same
problem by MNR from the case's own start with tight tolerances (cost_rtol = param_rtol =
1e-8): an independent path to the same minimum, not a stored number.

Real flight data (../shared/data, skipped if absent, as tests/test_cases_real.py):
- ATTAS short period and Twin Otter from (a) every aerodynamic parameter 0 and (c) one
  parameter 1e3× off (the one with the largest |start|/σ: M0 and CZo), MNRES and MNR;
- the book's unstable aircraft set-ups 3c (equation decoupling) and 3e (eigenvalue
  transformation) of ../shared/reference/CASES.md §3: default tolerances within 0.05 σ of
  the tight optimum (they stopped 0.45–0.65 σ short before the confirmation existed).
- ATTAS lateral from zeros under MNRES: its surface leads it into a separate local minimum
  (Nr = -76.6, ln det R = -36.1 against -43.8 at the optimum), where it claims convergence
  68.8 σ from an optimum; the driver then runs MNR from the start values as a second
  opinion and reports the higher likelihood, the optimum;
- HFB-320 from Cmde × 1e3 ends with a status (it used to raise from the finite differences
  of a later iterate, losing the estimation).

Checked by breaking the core (monkeypatched in a throw-away plugin, at 6858593): with
``Convergence.confirmed`` always true, 11 tests fail (Twin Otter (a) and (c) under both
solvers, ATTAS lateral, HFB-320, 3c/3e, which then stop 0.45–0.65 σ short, all
"converged"); with it always false, all fail (the references do not converge either).
Run time ≈ 15 s on 2 cores with OPENBLAS_NUM_THREADS=1, ≈ 35–40 s with OpenBLAS's default
threads (the ATTAS lateral run alone takes 11 s then, 2.5 s on one thread).
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import numpy as np
import pytest

from flightid.cases import load_case, prepare_case
from flightid.data import FlightData
from flightid.estimation import MNR, MNRES, Convergence, estimate
from flightid.model import Parameter, Parameters, StateSpaceModel
from flightid.simulation import simulate

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("FLIGHTID_DATA", ROOT / "../shared/data"))
pytestmark = pytest.mark.skipif(
    not (DATA / "fvsysid").is_dir() or not (DATA / "sidpac_twin_otter").is_dir(),
    reason=f"real flight data not found at {DATA} (set FLIGHTID_DATA)",
)

TIGHT = Convergence(cost_rtol=1e-8, param_rtol=1e-8, max_iterations=300)
SOLVERS = {"mnres": MNRES(), "mnr": MNR()}
# (c): the aerodynamic parameter with the largest |start|/σ (bench/start_robustness.py)
OFF = {"attas_short_period": "M0", "twin_otter_longitudinal": "CZo"}


@functools.cache
def _case(name: str):
    """(model at the case's start values, maneuvers, aerodynamic parameter names)."""
    prepared = prepare_case(load_case(ROOT / "examples/cases" / f"{name}.toml"), DATA)
    # aerodynamic: the model module's parameters, not biases or initial states added by the case
    module_names = set(prepared.base.parameters.names)
    aero = tuple(n for n in prepared.model.parameters.free_names if n in module_names)
    return prepared.model, list(prepared.maneuvers), aero


def _estimate(model, data, solver, convergence):
    # the standard cases' settings: RK4, noise "max", linear input interpolation
    return estimate(model, data, solver, method="rk4", noise="max", convergence=convergence)


@functools.cache
def _reference(name: str):
    """θ* and σ (free parameters) of the tight MNR run from the case's start."""
    model, data, _ = _case(name)
    ref = _estimate(model, data, MNR(), TIGHT)
    assert ref.converged, ref.message
    return ref.values[ref.free], ref.std[ref.free]


@functools.cache
def _run(name: str, start: str, solver: str):
    model, data, aero = _case(name)
    if start == "zeros":
        values = dict.fromkeys(aero, 0.0)
    else:
        values = {OFF[name]: 1e3 * model.parameters[OFF[name]].value}
    model = model.with_parameters(model.parameters.with_values(values))
    return _estimate(model, data, SOLVERS[solver], Convergence())


def _distance(result, theta, sigma) -> float:
    """max_j |θ̂_j − θ*_j| / σ_j over the free parameters."""
    return float(np.max(np.abs(result.values[result.free] - theta) / sigma))


RUNS = [
    (name, start, solver)
    for name in ("attas_short_period", "twin_otter_longitudinal")
    for start in ("zeros", "off")
    for solver in SOLVERS
]


@pytest.mark.parametrize(("name", "start", "solver"), RUNS)
def test_converged_means_within_a_tenth_sigma(name, start, solver):
    result = _run(name, start, solver)
    theta, sigma = _reference(name)
    if result.converged:
        assert _distance(result, theta, sigma) <= 0.1, result.message
        assert result.optimality_sigma <= Convergence().confirm_sigma
    else:
        assert result.status != "converged"
        assert "not converged" in result.message or "stopped" in result.message


@pytest.mark.parametrize(("name", "start", "solver"), RUNS)
def test_these_starts_do_converge(name, start, solver):
    # measured (bench/start_robustness.py): every one of these runs reaches the optimum, so
    # the test above cannot pass by reporting "not converged" everywhere
    result = _run(name, start, solver)
    assert result.converged, result.message


def test_attas_lateral_from_zeros_mnres():
    # Before the trust-region MNRES (issue 13) MNRES alone ended in a separate local minimum
    # (ln det R = -36.1) and the second opinion (MNR from the start values) found the optimum
    # (-43.8); since then MNRES reaches it itself. Either way the optimum is reported.
    theta, sigma = _reference("attas_lateral")
    result = _run("attas_lateral", "zeros", "mnres")
    assert result.converged, result.message
    assert _distance(result, theta, sigma) <= 0.1, result.message


@pytest.mark.parametrize("solver", ["mnres", "mnr"])
def test_hfb320_far_start_ends_with_a_status(solver):
    model, data, _ = _case("hfb320_longitudinal")
    start = model.with_parameters(model.parameters.with_values({"Cmde": -990.687}))
    simulate(start, data)  # the start itself simulates (no error here)
    result = _estimate(start, data, SOLVERS[solver], Convergence())
    theta, sigma = _reference("hfb320_longitudinal")
    assert (not result.converged) or _distance(result, theta, sigma) <= 0.1, result.message


# ----------------------------------------------------------------- unstable aircraft, §3
U0 = 44.5695  # m/s (CASES.md §3)
SHIFT = 0.7  # 1/s, σ of the eigenvalue transformation (3e)
START = {  # CASES.md §3; Zq fixed at −1.4768
    "Zw": -1.22871,
    "Zq": -1.4768,
    "Zde": -4.20491,
    "Mw": 0.116197,
    "Mq": -2.70670,
    "Mde": -18.7718,
}


def _f_decoupled(t, x, u, theta):
    dx = np.empty(2)
    # ẇ = Zw w + u0 q + Zq q_m + Zδe δe   (u = δe, w_m, q_m)
    dx[0] = theta[0] * x[0] + U0 * x[1] + theta[1] * u[2] + theta[2] * u[0]
    # q̇ = Mw w_m + Mq q + Mδe δe
    dx[1] = theta[3] * u[1] + theta[4] * x[1] + theta[5] * u[0]
    return dx


def _f_shifted(t, x, u, theta):
    dx = np.empty(2)
    # ẇ = (Zw − σ) w + (u0 + Zq) q + Zδe δe
    dx[0] = (theta[0] - SHIFT) * x[0] + (U0 + theta[1]) * x[1] + theta[2] * u[0]
    # q̇ = Mw w + (Mq − σ) q + Mδe δe
    dx[1] = theta[3] * x[0] + (theta[4] - SHIFT) * x[1] + theta[5] * u[0]
    return dx


def _h(t, x, u, theta):
    y = np.empty(3)
    # a_z = Zw w + Zq q + Zδe δe (integrated w, q); y2 = w, y3 = q
    y[0] = theta[0] * x[0] + theta[1] * x[1] + theta[2] * u[0]
    y[1] = x[0]
    y[2] = x[1]
    return y


@functools.cache
def _unstable(setup: str):
    table = np.loadtxt(DATA / "fvsysid/unStabAC_sim.asc")
    # t_k = (k − 1)·0.05 s; columns 3 w (m/s), 4 q (rad/s), 5 δe (rad), 6 a_z (m/s²)
    t = np.arange(table.shape[0]) * 0.05
    w, q, de, az = table[:, 2], table[:, 3], table[:, 4], table[:, 5]
    parameters = Parameters(Parameter(n, v, free=n != "Zq") for n, v in START.items())
    if setup == "3c":
        data = FlightData(t, {"de": de, "w_m": w, "q_m": q}, {"az": az, "w": w, "q": q})
        inputs, f = ("de", "w_m", "q_m"), _f_decoupled
    else:
        # 3e: all measured signals, δe included, × e^(−σ t)
        e = np.exp(-SHIFT * t)
        data = FlightData(t, {"de": de * e}, {"az": az * e, "w": w * e, "q": q * e})
        inputs, f = ("de",), _f_shifted
    model = StateSpaceModel(
        states=("w", "q"),
        inputs=inputs,
        outputs=("az", "w", "q"),
        f=f,
        h=_h,
        parameters=parameters,
        x0=(0.0, 0.0),
    )
    ref = _estimate(model, data, MNR(), TIGHT)
    assert ref.converged, ref.message
    return model, data, ref.values[ref.free], ref.std[ref.free]


@pytest.mark.parametrize("solver", ["mnres", "mnr"])
@pytest.mark.parametrize("setup", ["3c", "3e"])
def test_unstable_aircraft_default_tolerances_reach_the_optimum(setup, solver):
    model, data, theta, sigma = _unstable(setup)
    result = _estimate(model, data, SOLVERS[solver], Convergence())
    assert result.converged, result.message
    assert _distance(result, theta, sigma) <= 0.05
