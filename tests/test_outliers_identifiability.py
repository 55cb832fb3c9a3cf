"""Warnings where the σ cannot be trusted: outliers in the residuals, and parameter
combinations the data barely determine.

The data come from an independent simulation (the exact first-order-hold discretisation of
the linear short period, scipy.linalg.expm), not from flightid's simulator; the weighted
optimum is checked against scipy.optimize.least_squares on that simulation with the excluded
residual row dropped.
"""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.linalg
import scipy.optimize

from flightid.accuracy.identifiability import (
    IdentifiabilityWarning,
    check_identifiability,
    weak_combinations,
)
from flightid.accuracy.outliers import OutlierWarning, estimate_robust
from flightid.cases import CaseError, load_case, run_case
from flightid.cases.spec import estimation_settings
from flightid.data import FlightData
from flightid.errors import FlightIdWarning, InputError
from flightid.estimation import estimate
from flightid.estimation.problem import OutputErrorProblem
from flightid.model import Parameter, Parameters, StateSpaceModel
from flightid.report.html import _trust_section

ROOT = Path(__file__).resolve().parents[1]
NAMES = ("Za", "Zq", "Zde", "Ma", "Mq", "Mde")
TRUTH = (-0.8, 0.05, -0.1, -4.5, -1.6, -7.0)
DT, N = 0.02, 501
NOISE_STD = (np.deg2rad(0.02), np.deg2rad(0.05))  # α (rad), q (rad/s)
SPIKE_SAMPLE = 250
SPIKE = np.deg2rad(5.0)  # 250 × the α noise


def _elevator():
    t = np.arange(N) * DT
    de = np.zeros(N)
    for start, length, sign in ((1.0, 1.5, 1), (2.5, 1.0, -1), (3.5, 0.5, 1), (4.0, 0.5, -1)):
        de[(t >= start) & (t < start + length)] = sign * np.deg2rad(2.0)
    return t, de


def exact_outputs(theta, de):
    """Independent simulation: exact first-order-hold discretisation, x0 = 0."""
    za, zq, zde, ma, mq, mde = theta
    aug = np.zeros((4, 4))
    aug[:2, :2] = [[za, 1.0 + zq], [ma, mq]]
    aug[:2, 2], aug[2, 3] = [zde, mde], 1.0 / DT
    phi_all = scipy.linalg.expm(aug * DT)
    phi, gamma_sum, gamma_ramp = phi_all[:2, :2], phi_all[:2, 2], phi_all[:2, 3]
    x = np.zeros(2)
    out = np.empty((de.size, 2))
    for k in range(de.size):
        out[k] = x
        if k + 1 < de.size:
            # x_{k+1} = Φ x_k + Γ_sum u_k + Γ_ramp (u_{k+1} − u_k)
            x = phi @ x + gamma_sum * de[k] + gamma_ramp * (de[k + 1] - de[k])
    return out


def short_period_f(t, x, u, theta):
    dx = np.empty(2)
    dx[0] = theta[0] * x[0] + (1.0 + theta[1]) * x[1] + theta[2] * u[0]
    dx[1] = theta[3] * x[0] + theta[4] * x[1] + theta[5] * u[0]
    return dx


def outputs_h(t, x, u, theta):
    return x.copy()


def short_period_model() -> StateSpaceModel:
    return StateSpaceModel(
        ("alpha", "q"),
        ("de",),
        ("alpha", "q"),
        short_period_f,
        outputs_h,
        Parameters([Parameter(n, v) for n, v in zip(NAMES, TRUTH, strict=True)]),
    )


@pytest.fixture(scope="module")
def records():
    """(clean record, the same with one 5° spike in α at t = 5 s)."""
    t, de = _elevator()
    rng = np.random.default_rng(1)
    z = exact_outputs(TRUTH, de) + rng.normal(0.0, NOISE_STD, (N, 2))
    spiked = z.copy()
    spiked[SPIKE_SAMPLE, 0] += SPIKE

    def record(values):
        return FlightData(t, {"de": de}, {"alpha": values[:, 0], "q": values[:, 1]}, name="sp")

    return record(z), record(spiked)


@pytest.fixture(scope="module")
def clean_estimate(records):
    return estimate(short_period_model(), records[0])


def _independent_optimum(flight, dropped):
    """ML optimum (program MAX) by scipy on the exact simulation without the ``dropped``
    (sample, output) residual; its CR σ from the Jacobian, M = JᵀJ."""
    de = flight.input("de")
    z = np.column_stack([flight.output("alpha"), flight.output("q")])
    keep = np.ones(z.shape, dtype=bool)
    keep[dropped] = False
    theta, r = np.array(TRUTH), np.array(NOISE_STD) ** 2
    for _ in range(20):
        weight = 1.0 / np.sqrt(r)

        def residuals(p, weight=weight):
            return ((z - exact_outputs(p, de)) * weight)[keep]

        fit = scipy.optimize.least_squares(residuals, theta, xtol=1e-14, ftol=1e-14, gtol=1e-14)
        theta = fit.x
        nu = z - exact_outputs(theta, de)
        # R̂_k over the kept samples only
        new_r = np.array([np.mean(nu[keep[:, k], k] ** 2) for k in range(2)])
        if np.max(np.abs(new_r / r - 1)) < 1e-10:
            break
        r = new_r
    return theta, np.sqrt(np.diag(np.linalg.inv(fit.jac.T @ fit.jac)))


# ------------------------------------------------------------------ outliers


def test_spike_is_named_and_excluding_it_restores_the_estimate(records, clean_estimate):
    clean, spiked = records
    with pytest.warns(OutlierWarning) as caught:
        robust, screen = estimate_robust(short_period_model(), spiked, "exclude")
    # the spike alone is named: maneuver, sample, time, output, size
    assert len(screen.outliers) == 1
    spike = screen.outliers[0]
    assert (spike.maneuver_name, spike.sample, spike.output) == ("sp", SPIKE_SAMPLE, "alpha")
    assert spike.time_s == pytest.approx(SPIKE_SAMPLE * DT)
    # its size: 5° over the α noise σ = 0.02° (the noise drawn gives 250 ± a few σ)
    assert spike.size_sigma == pytest.approx(250.0, rel=0.05)
    text = " ".join(str(w.message) for w in caught)
    assert "sample 250" in text and "alpha" in text and "excluded" in text

    # the plain fit is pulled several σ (what the warning is about) ...
    plain = estimate(short_period_model(), spiked)
    ma = list(plain.names).index("Ma")
    assert abs(plain.values[ma] - clean_estimate.values[ma]) > 2.0 * clean_estimate.std[ma]
    # ... the fit without the spike is within 1σ of the spike-free one for every parameter
    shift = (robust.values - clean_estimate.values) / clean_estimate.std
    assert np.all(np.abs(shift) < 1.0), shift

    # the excluded measurement has weight 0, leaves N and enters neither J nor σ
    assert robust.weights[SPIKE_SAMPLE, 0] == 0.0 and robust.weights.sum() == 2 * N - 1
    assert robust.n_data == clean_estimate.n_data - 1
    theta, std = _independent_optimum(spiked, (SPIKE_SAMPLE, 0))
    np.testing.assert_allclose((robust.values - theta) / std, 0.0, atol=0.05)
    np.testing.assert_allclose(robust.std, std, rtol=0.02)


def test_huber_weights_keep_the_estimate_within_one_sigma(records, clean_estimate):
    with pytest.warns(OutlierWarning):
        robust, screen = estimate_robust(short_period_model(), records[1], "huber")
    assert screen.mode == "huber" and screen.rounds >= 1
    assert 0.0 < robust.weights[SPIKE_SAMPLE, 0] < 0.01  # k_H / 250
    shift = (robust.values - clean_estimate.values) / clean_estimate.std
    assert np.all(np.abs(shift) < 1.0), shift


def test_clean_record_raises_no_warning(records, clean_estimate):
    with warnings.catch_warnings():
        warnings.simplefilter("error", FlightIdWarning)
        robust, screen = estimate_robust(short_period_model(), records[0], "exclude")
        report = check_identifiability(clean_estimate, records[0])
    assert screen.outliers == () and screen.rounds == 0 and robust.weights is None
    assert report.combinations == () and report.messages() == []


def test_weights_are_checked(records):
    problem = OutputErrorProblem(short_period_model(), records[0])
    with pytest.raises(InputError, match=r"weights: expected \(501,\) or \(501, 2\)"):
        problem.set_weights(np.ones(500))
    with pytest.raises(InputError, match=r"between 0 and 1"):
        problem.set_weights(np.full(N, 2.0))
    zero_q = np.ones((N, 2))
    zero_q[:, 1] = 0.0
    with pytest.raises(InputError, match=r"every sample of the outputs \['q'\]"):
        problem.set_weights(zero_q)


def test_outlier_case_keys_are_checked():
    with pytest.raises(CaseError, match=r"estimation.outliers: .*'drop'"):
        estimation_settings({"outliers": "drop"})
    with pytest.raises(CaseError, match=r"estimation.outlier_threshold: expected a positive"):
        estimation_settings({"outlier_threshold": -1.0})
    with pytest.raises(CaseError, match=r"filter error"):
        estimation_settings({"outliers": "exclude", "estimator": "filter_error"})


def test_case_excludes_the_spike_and_reports_it(tmp_path):
    walk = tmp_path / "walk"
    shutil.copytree(ROOT / "examples/csv_walkthrough", walk)
    csv = walk / "my_flight.csv"
    lines = csv.read_text().splitlines()
    t, de, aoa, q = lines[301].split(",")
    lines[301] = f"{t},{de},{float(aoa) + 5.0:.6f},{q}"  # +5° on AOA at sample 300
    csv.write_text("\n".join(lines) + "\n")
    case = walk / "my_case.toml"
    case.write_text(case.read_text() + 'outliers = "exclude"\n')
    with pytest.warns(OutlierWarning, match=r"excluded.*sample 300 \(t = 6 s\), alpha"):
        run = run_case(load_case(case))
    assert run.estimate.weights is not None and run.estimate.weights[300, 0] == 0.0
    assert run.to_dict()["outliers"]["excluded"] == 1
    section = _trust_section(run)
    assert "Where the σ cannot be trusted" in section and "alpha" in section


# ------------------------------------------------------------------ identifiability

# q̇ = Mα α + Mq q + Mα̇ α̇ + Mδe δe with α̇ = Zα α + q + Zδe δe − (g/V) θ: Mα̇ differs from
# Mq only through the small gravity term (g/V = 0.05 1/s), so the data barely split them
PAIR_NAMES = ("Za", "Zde", "Ma", "Mq", "Malphadot", "Mde")
PAIR_TRUTH = (0.0, -0.1, -4.5, -1.2, -0.6, -7.0)
G_OVER_V = 0.05


def pair_f(t, x, u, theta):
    dx = np.empty(3)
    alpha_dot = theta[0] * x[0] + x[1] + theta[1] * u[0] - G_OVER_V * x[2]
    dx[0] = alpha_dot
    dx[1] = theta[2] * x[0] + theta[3] * x[1] + theta[4] * alpha_dot + theta[5] * u[0]
    dx[2] = x[1]
    return dx


def pair_model() -> StateSpaceModel:
    parameters = [Parameter(n, v) for n, v in zip(PAIR_NAMES, PAIR_TRUTH, strict=True)]
    parameters[0] = Parameter("Za", PAIR_TRUTH[0], free=False)
    return StateSpaceModel(
        ("alpha", "q", "theta"),
        ("de",),
        ("alpha", "q", "theta"),
        pair_f,
        outputs_h,
        Parameters(parameters),
        x0=(0.0, 0.0, 0.0),
    )


@pytest.fixture(scope="module")
def pair_case():
    t, de = _elevator()
    a = np.array([[0.0, 1.0, -G_OVER_V], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    # q̇ row: Mα α + Mq q + Mα̇ α̇ with α̇ from the first row
    a[1] = np.array([-4.5, -1.2, 0.0]) + (-0.6) * a[0]
    b = np.array([-0.1, -7.0 + (-0.6) * (-0.1), 0.0])
    # independent simulation: exact zero-order-hold discretisation (scipy), inputs held
    phi = scipy.linalg.expm(np.block([[a, b[:, None]], [np.zeros((1, 4))]]) * DT)
    x, out = np.zeros(3), np.empty((N, 3))
    for k in range(N):
        out[k] = x
        x = phi[:3, :3] @ x + phi[:3, 3] * de[k]
    rng = np.random.default_rng(3)
    z = out + rng.normal(0.0, np.deg2rad([0.02, 0.05, 0.02]), out.shape)
    flight = FlightData(
        t, {"de": de}, {"alpha": z[:, 0], "q": z[:, 1], "theta": z[:, 2]}, name="pair"
    )
    return flight, estimate(pair_model(), flight, input_interpolation="zoh")


def test_barely_separated_pair_is_named_with_rho_eigenvector_and_profile(pair_case):
    flight, est = pair_case
    with pytest.warns(IdentifiabilityWarning) as caught:
        report = check_identifiability(est, flight)
    assert len(report.combinations) == 1
    weak = report.combinations[0]
    assert weak.names == ("Mq", "Malphadot")
    # ρ and the eigenvector, recomputed here with plain numpy from the information matrix
    m = np.asarray(est.information_matrix)
    covariance = np.linalg.inv(m)
    j, k = est.free_names.index("Mq"), est.free_names.index("Malphadot")
    rho = covariance[j, k] / np.sqrt(covariance[j, j] * covariance[k, k])
    assert abs(rho) > 0.999
    assert weak.correlations[0][2] == pytest.approx(rho, abs=1e-6)
    d = np.sqrt(np.diag(m))
    values, vectors = np.linalg.eigh(m / np.outer(d, d))
    smallest = vectors[:, 0] * np.sign(vectors[j, 0])
    expected = smallest[[j, k]] / np.linalg.norm(smallest[[j, k]])
    np.testing.assert_allclose(weak.undetermined, expected, atol=1e-6)
    assert np.dot(weak.undetermined, weak.determined) == pytest.approx(0.0, abs=1e-12)
    assert weak.condition == pytest.approx(values[-1] / values[0], rel=1e-6)
    message = str(caught[0].message)
    assert "Mq and Malphadot are barely told apart" in message
    # as many decimals as keep ρ off ±1 (at least 4)
    digits = max(4, int(np.ceil(-np.log10(1.0 - abs(rho)))) + 1)
    assert f"ρ = {rho:+.{digits}f}" in message
    assert "is determined" in message and "is not" in message
    # the profile interval of each, beside the CR σ; this model is linear in Mq and Mα̇ along
    # the valley, so the profile keeps to the quadratic interval (N_φ ≪ 1)
    assert [p.name for p in report.profiled] == ["Mq", "Malphadot"]
    for p in report.profiled:
        assert p.ci_profile[0] < p.value < p.ci_profile[1]
        assert p.std_profile == pytest.approx(p.std_cr, rel=0.1)
    assert "Mq = " in message and "profile-likelihood 95% interval" in message


def test_weak_direction_without_a_pair_is_named_by_its_condition():
    # three parameters, pairs not considered (threshold above 1), θ1 + θ2 + θ3 undetermined
    v = np.array([1.0, 1.0, 1.0]) / np.sqrt(3.0)
    u, _ = np.linalg.qr(np.column_stack([v, [1.0, -1.0, 0.0], [1.0, 1.0, -2.0]]))
    m = u @ np.diag([1e-6, 1.0, 1.0]) @ u.T
    found = weak_combinations(("a", "b", "c"), m, correlation_threshold=1.01)
    assert len(found) == 1 and found[0].names == ("a", "b", "c")
    np.testing.assert_allclose(found[0].undetermined, v, atol=1e-9)
    assert found[0].condition == pytest.approx(1e6, rel=1e-6)
    assert found[0].describe().startswith("the combination 0.58·a + 0.58·b + 0.58·c is barely")


def test_trust_section_is_empty_without_findings(clean_estimate):
    assert _trust_section(SimpleNamespace(outliers=None, identifiability=None)) == ""


def test_only_serious_findings_are_terminal_warnings():
    """A direction named by its condition alone, and a pair below |ρ| = 0.999 whose profile
    agrees with the quadratic interval, stay in the report; a pair at |ρ| ≥ 0.999, or one
    whose profile departs from the quadratic interval, is a warning."""
    from flightid.accuracy.identifiability import (
        WARN_CORRELATION,
        IdentifiabilityReport,
        ProfiledParameter,
        WeakCombination,
    )

    def pair(rho: float) -> WeakCombination:
        return WeakCombination(("a", "b"), (0.7, 0.7), (0.7, -0.7), 1e5, (("a", "b", rho),))

    def profiled(name: str, lower: float) -> ProfiledParameter:
        # quadratic interval 1 ± 0.2; profile [lower, 1.2]
        return ProfiledParameter(name, 1.0, 0.1, 0.1, (0.8, 1.2), (lower, 1.2), 0.1)

    condition_only = WeakCombination(("a", "b", "c"), (0.58, 0.58, 0.58), condition=1e6)
    agreeing = (profiled("a", 0.8), profiled("b", 0.8))
    quiet = IdentifiabilityReport((condition_only, pair(0.995)), agreeing)
    assert len(quiet.messages()) == 2 and quiet.warning_messages() == []
    strong = IdentifiabilityReport((pair(WARN_CORRELATION),), agreeing)
    assert len(strong.warning_messages()) == 1
    departing = IdentifiabilityReport((pair(0.995),), (profiled("a", 0.5), profiled("b", 0.8)))
    assert len(departing.warning_messages()) == 1
    assert "the quadratic approximation fails" in departing.warning_messages()[0]
