"""Measured coverage: seeded Monte Carlo of every estimator family's stated σ.

For each family, ``--seeds`` noise realisations (seeds ``--seed`` … ``--seed + N − 1``) are
drawn from a simulator written here with scipy, independently of flightid's simulator:

* a linear short-period model ẋ = A x + B δe (α, q; δe a 3-2-1-1 and a doublet), discretised
  exactly (``scipy.linalg.expm`` of the system augmented with the input and its slope) for an
  input linear between samples;
* with process noise ẋ = A x + B δe + F w (w unit white noise): the discrete process noise
  Q_d = ∫₀^Δt e^{Aτ} FFᵀ e^{Aᵀτ} dτ by Van Loan's matrix exponential (``scipy.linalg.expm``);
* measurement noise white, or coloured (first-order autoregressive, ``scipy.signal.lfilter``);
* for equation error, the regression z = X θ + v on the simulated (noise-free) states.
* for the ``airplane_*`` families, a nonlinear longitudinal airplane (body-axis rigid-body
  equations, linear aerodynamic coefficients) integrated by its own RK4 (four steps per
  sample), flown through a first-order Dryden vertical gust (the exactly sampled output of
  σ_w √(2V/(πL)) / (s + V/L)), white noise on V, α, q and θ; estimated with flightid models
  of the calm-air equations (output error), of the equations with the gust as a state
  (filter error, process noise on the gust's shaping filter) or with white process noise on
  the w equation.

Each realisation is estimated from start values 20 % off the truth (or, for the linear
closed-form families, from no start at all), and for every free parameter and every σ the
result offers — ``std``, and where present ``std_cr`` and ``std_coloured`` (read with
``getattr``, so the script runs before and after the coloured-residual σ becomes the
default) — the study prints:

* ``cover``: the fraction of realisations with |θ̂ − θ| ≤ 2σ (goal 0.90–0.98; 0.954 for a
  Gaussian estimate with an exact σ; its binomial standard error over N runs is √(0.954·0.046/N),
  0.027 at N = 60, 0.015 at N = 200);
* ``ratio``: the empirical spread of θ̂ over the realisations (standard deviation) divided by
  the mean stated σ (goal 0.8–1.25);
* ``bias``: (mean θ̂ − θ) / spread, to tell a biased estimate from a wrong σ.

For the time-domain output-error families a fourth σ, ``sandwich``, is the
coloured-residual covariance computed here from the result's sensitivities and residuals
(``flightid.accuracy.coloured_covariance``, automatic lag). For ``design`` the σ is the
Cramér–Rao σ predicted before the flight (``flightid.design.predict_accuracy`` at the truth)
against the spread of the output-error estimates of the same realisations.

Usage::

    python bench/sigma_coverage.py [--family NAME ...] [--seeds N] [--seed S] [--quick]

``--quick`` runs the fast subset (``QUICK``) with 60 seeds unless ``--seeds`` says otherwise;
it is the subset ``tests/test_coverage_quick.py`` asserts. The tables are the same on every
machine for the same options (seeded, serial).
"""

from __future__ import annotations

import argparse
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.signal

# ---------------------------------------------------------------- the independent simulator

DT_S = 0.02
#: short-period truth: A = [[Za, 1], [Ma, Mq]], B = [Zde, Mde] (1/s, 1/s², …)
TRUTH = {"Za": -1.0, "Zde": -0.10, "Ma": -6.0, "Mq": -2.0, "Mde": -9.0}
NAMES = tuple(TRUTH)
#: measurement noise σ of (α rad, q rad/s)
NOISE_STD = np.array([1.0e-3, 3.0e-3])


def system_matrices(values: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of the short-period model at ``values``."""
    a = np.array([[values["Za"], 1.0], [values["Ma"], values["Mq"]]])
    b = np.array([[values["Zde"]], [values["Mde"]]])
    return a, b


def elevator(duration_s: float, dt: float = DT_S) -> tuple[np.ndarray, np.ndarray]:
    """(t, δe) sampled every ``dt`` (s): a 3-2-1-1 of 0.4 s pulses (amplitude 0.03 rad) at
    1 s and a doublet of 1 s pulses (0.02 rad) at 6 s, zero elsewhere; held constant over
    each sample interval."""
    t = np.arange(int(round(duration_s / dt))) * dt
    de = np.zeros_like(t)
    start, width = 1.0, 0.4
    for pulses, sign in ((3, 1), (2, -1), (1, 1), (1, -1)):
        de[(t >= start - 1e-9) & (t < start + pulses * width - 1e-9)] = 0.03 * sign
        start += pulses * width
    de[(t >= 6.0 - 1e-9) & (t < 7.0 - 1e-9)] = 0.02
    de[(t >= 7.0 - 1e-9) & (t < 8.0 - 1e-9)] = -0.02
    return t, de


def discrete_process_noise(a: np.ndarray, f_matrix: np.ndarray, dt: float) -> np.ndarray:
    """Q_d = ∫₀^Δt e^{Aτ} FFᵀ e^{Aᵀτ} dτ by Van Loan: expm([[−A, FFᵀ], [0, Aᵀ]] Δt) =
    [[·, Φ⁻¹Q_d], [0, Φᵀ]]."""
    n = a.shape[0]
    block = np.zeros((2 * n, 2 * n))
    block[:n, :n] = -a
    block[:n, n:] = f_matrix @ f_matrix.T
    block[n:, n:] = a.T
    e = scipy.linalg.expm(block * dt)
    phi = e[n:, n:].T
    q_d = phi @ e[:n, n:]
    return 0.5 * (q_d + q_d.T)


def input_hold_matrices(a: np.ndarray, b: np.ndarray, dt: float) -> tuple[np.ndarray, ...]:
    """(Φ, Γ₀, Γ₁) of the exact discretisation for an input linear between samples:
    x_{k+1} = Φ x_k + Γ₀ u_k + Γ₁ (u_{k+1} − u_k)/Δt, from
    expm([[A, B, 0], [0, 0, I], [0, 0, 0]] Δt) = [[Φ, Γ₀, Γ₁], …]."""
    n, m = b.shape
    block = np.zeros((n + 2 * m, n + 2 * m))
    block[:n, :n] = a
    block[:n, n : n + m] = b
    block[n : n + m, n + m :] = np.eye(m)
    e = scipy.linalg.expm(block * dt)
    return e[:n, :n], e[:n, n : n + m], e[:n, n + m :]


def simulate_states(
    values: dict[str, float],
    de: np.ndarray,
    rng: np.random.Generator | None = None,
    process_std: np.ndarray | None = None,
) -> np.ndarray:
    """States (N, 2) from x_1 = 0 for δe linear between samples (what flightid's simulator
    and its Fourier transforms assume), exactly discretised; with process noise w_k,
    Cov w = Q_d of F = diag(``process_std``), when given."""
    a, b = system_matrices(values)
    phi, gamma0, gamma1 = input_hold_matrices(a, b, DT_S)
    chol = None
    if process_std is not None:
        chol = np.linalg.cholesky(discrete_process_noise(a, np.diag(process_std), DT_S))
    x = np.zeros((de.size, 2))
    for k in range(de.size - 1):
        # x_{k+1} = Φ x_k + Γ₀ δe_k + Γ₁ (δe_{k+1} − δe_k)/Δt
        x[k + 1] = phi @ x[k] + gamma0[:, 0] * de[k] + gamma1[:, 0] * (de[k + 1] - de[k]) / DT_S
        if chol is not None:
            x[k + 1] += chol @ rng.standard_normal(2)
    return x


def measurement_noise(rng: np.random.Generator, n: int, std: np.ndarray, pole: float = 0.0):
    """(n, len(std)) noise of standard deviation ``std``: white (pole 0) or first order
    autoregressive v_k = pole v_{k−1} + √(1 − pole²) e_k (stationary, same σ)."""
    white = rng.standard_normal((n, std.size))
    if pole == 0.0:
        return white * std
    coloured = scipy.signal.lfilter([np.sqrt(1.0 - pole**2)], [1.0, -pole], white, axis=0)
    # start from the stationary distribution: v_0 = e_0 (variance 1), not √(1 − pole²) e_0
    coloured += np.outer(pole ** np.arange(n), white[0]) * (1 - np.sqrt(1 - pole**2))
    return coloured * std


# ---------------------------------------------------------------- flightid models


def _f_short_period(t, x, u, theta):
    dx = np.empty(2)
    dx[0] = theta[0] * x[0] + x[1] + theta[1] * u[0]
    dx[1] = theta[2] * x[0] + theta[3] * x[1] + theta[4] * u[0]
    return dx


def _h_states(t, x, u, theta):
    y = np.empty(2)
    y[0] = x[0]
    y[1] = x[1]
    return y


def short_period_model(values: dict[str, float], process_noise: dict[str, float] | None = None):
    """flightid's model of the same system (x0 = 0 known); process-noise elements appended
    as parameters F11, F22 when given."""
    from flightid.model.parameters import Parameter, Parameters
    from flightid.model.statespace import StateSpaceModel

    parameters = [Parameter(n, values[n]) for n in NAMES]
    parameters += [Parameter(n, v) for n, v in (process_noise or {}).items()]
    return StateSpaceModel(
        ("alpha", "q"),
        ("de",),
        ("alpha", "q"),
        _f_short_period,
        _h_states,
        Parameters(parameters),
        x0=(0.0, 0.0),
        function_parameters=NAMES,
    )


def flight_data(t: np.ndarray, de: np.ndarray, z: np.ndarray):
    from flightid.data.flightdata import FlightData

    return FlightData(t, {"de": de}, {"alpha": z[:, 0], "q": z[:, 1]})


START = {n: 1.2 * v for n, v in TRUTH.items()}


# ---------------------------------------------------------------- one realisation per family


@dataclass
class Draw:
    """One realisation's estimates and the σ it states, by kind (same order as names)."""

    names: tuple[str, ...]
    values: np.ndarray
    sigmas: dict[str, np.ndarray] = field(default_factory=dict)


STATED = ("std", "std_cr", "std_coloured")


def _stated(result, names: tuple[str, ...], index: list[int]) -> dict[str, np.ndarray]:
    """Every σ the result offers, for the parameters ``index`` of its vectors."""
    sigmas = {}
    for kind in STATED:
        value = getattr(result, kind, None)
        if value is None or callable(value):
            continue
        value = np.asarray(value, dtype=float)
        if value.ndim == 1 and value.size > max(index):
            sigmas[kind] = value[index]
    return sigmas


def _from_estimate(result, names: tuple[str, ...], sandwich: bool = True) -> Draw:
    """Draw of a time-domain ``Estimate``; with the coloured-residual sandwich added for
    output error (``sandwich``; not for filter error, whose innovations are white when the
    model is right and whose pinned F elements have no column in the sensitivities)."""
    from flightid.accuracy.coloured import coloured_covariance

    index = [result.names.index(n) for n in names]
    draw = Draw(names, np.asarray(result.values, dtype=float)[index], _stated(result, names, index))
    if not sandwich:
        return draw
    free = [n for n, f in zip(result.names, result.free, strict=True) if f]
    covariance, _ = coloured_covariance(
        result.sensitivities,
        result.residuals,
        result.r_diag,
        result.covariance,
        maneuver_index=result.maneuver_index,
    )
    draw.sigmas["sandwich"] = np.sqrt(np.diag(covariance))[[free.index(n) for n in names]]
    return draw


def _measured(seed: int, duration_s: float = 10.0, pole: float = 0.0, process=None, noise_std=None):
    """(t, δe, z) of realisation ``seed``: states from the exact discretisation (process
    noise ``process`` when given) plus measurement noise (σ ``noise_std``, default
    ``NOISE_STD``; AR(1) pole ``pole``)."""
    rng = np.random.default_rng(seed)
    t, de = elevator(duration_s)
    x = simulate_states(TRUTH, de, rng, process)
    noise_std = NOISE_STD if noise_std is None else noise_std
    z = x + measurement_noise(rng, t.size, noise_std, pole)
    return t, de, z


def output_error_draw(seed: int, pole: float = 0.0) -> Draw:
    """Output error (MNR, R estimated) from 20 % off the truth."""
    from flightid.estimation import MNR, estimate

    t, de, z = _measured(seed, pole=pole)
    result = estimate(short_period_model(START), flight_data(t, de, z), MNR())
    return _from_estimate(result, NAMES)


#: filter-error study: process noise F = diag(α, q) (rad/√s, rad/s/√s)
PROCESS_STD = np.array([0.02, 0.05])
#: α measured without noise (10⁻⁵ rad): the optimum lies on diag(KC)_α = 1 in about half
#: of the realisations, where F11 is solved from the constraint
CONSTRAINED_NOISE_STD = np.array([1.0e-5, 3.0e-3])


def filter_error_draw(seed: int, noise_std=None, gradients: str = "analytic") -> Draw:
    """Filter error (fixed-point relaxation, MNR, analytic gradients) on 20 s with process
    noise, from 20 % off the truth and F = 0.03."""
    from flightid.estimation import MNR
    from flightid.estimation.filter_error import estimate_filter_error

    t, de, z = _measured(seed, duration_s=20.0, process=PROCESS_STD, noise_std=noise_std)
    model = short_period_model(START, {"F11": 0.03, "F22": 0.03})
    result = estimate_filter_error(
        model,
        flight_data(t, de, z),
        {"alpha": "F11", "q": "F22"},
        MNR(),
        gradients=gradients,
    )
    return _from_estimate(result, (*NAMES, "F11", "F22"), sandwich=False)


def _signals(seed: int, duration_s: float = 20.0, pole: float = 0.0):
    """Noise-free states x, the elevator, and seeded noise for the regression families."""
    rng = np.random.default_rng(seed)
    t, de = elevator(duration_s)
    x = simulate_states(TRUTH, de)
    return rng, t, de, x


#: equation-error response noise σ (rad/s²) on q̇ = Ma α + Mq q + Mde δe
QDOT_NOISE_STD = 0.05
EE_NAMES = ("Ma", "Mq", "Mde")


def equation_error_draw(seed: int, pole: float = 0.0) -> Draw:
    """Least squares of q̇ on (α, q, δe): regressors the noise-free simulated states,
    the response q̇ = A₂ x + B₂ δe (closed form) plus white or AR(1) noise."""
    from flightid.regression import least_squares

    rng, t, de, x = _signals(seed)
    a, b = system_matrices(TRUTH)
    qdot = x @ a[1] + b[1, 0] * de
    z = qdot + measurement_noise(rng, t.size, np.array([QDOT_NOISE_STD]), pole)[:, 0]
    fit = least_squares(np.column_stack([x, de]), z, list(EE_NAMES))
    return Draw(EE_NAMES, np.asarray(fit.estimates), _stated(fit, EE_NAMES, [0, 1, 2]))


def stepwise_draw(seed: int) -> Draw:
    """Stepwise regression of the same q̇ over (α, q, δe, α², α·δe, q·δe) with a constant
    forced; the true terms are always selected here, spurious ones now and then."""
    from flightid.regression import stepwise

    rng, t, de, x = _signals(seed)
    a, b = system_matrices(TRUTH)
    z = x @ a[1] + b[1, 0] * de + QDOT_NOISE_STD * rng.standard_normal(t.size)
    signals = {"alpha": x[:, 0], "q": x[:, 1], "de": de}
    result = stepwise(z, ["alpha", "q", "de", "alpha^2", "alpha*de", "q*de"], signals)
    fit = result.fit
    index = [list(fit.names).index(n) for n in ("alpha", "q", "de")]
    return Draw(EE_NAMES, np.asarray(fit.estimates)[index], _stated(fit, EE_NAMES, index))


def _linear_system(theta: np.ndarray):
    from flightid.frequency import LinearSystem

    za, zde, ma, mq, mde = theta
    a = np.array([[za, 1.0], [ma, mq]])
    b = np.array([[zde], [mde]])
    return LinearSystem(a, b, np.eye(2), np.zeros((2, 1)), np.zeros(2), np.zeros(2))


def frequency_draw(seed: int, method: str, oversampling: int = 1) -> Draw:
    """Frequency-domain equation or output error on 0.1–1.5 Hz of a 20 s record, frequency
    step 1/T (independent frequencies) or 1/(oversampling·T); boundary values and constants
    as nuisance parameters (the defaults)."""
    from flightid.frequency import (
        equation_error,
        frequency_grid,
        maneuver_spectra,
        output_error,
    )

    t, de, z = _measured(seed, duration_s=20.0)
    band = frequency_grid((0.1, 1.5), 1.0 / (t.size * DT_S * oversampling))
    spectra = [maneuver_spectra(t, de, z, band)]
    start = np.array([START[n] for n in NAMES])
    fit_function = equation_error if method == "equation_error" else output_error
    fit = fit_function(
        _linear_system, start, np.ones(5, bool), spectra, ("alpha", "q"), ("alpha", "q")
    )
    return Draw(NAMES, np.asarray(fit.theta), _stated(fit, NAMES, list(range(5))))


def recursive_draw(seed: int, method: str) -> Draw:
    """EKF / UKF / EFRLS (parameters as constant augmented states, from 20 % off the truth,
    P0 = 10 (EFRLS: 10³, λ = 1), no process noise on the states, R = the true noise
    variances) or FTR (0.1 to
    1.5 Hz in 0.05 Hz steps) over 20 s; the reported value and σ: mean of the last 10."""
    from flightid.recursive import (
        AugmentedModel,
        ExtendedForgettingRLS,
        ExtendedKalmanFilter,
        FourierTransformRegression,
        UnscentedKalmanFilter,
        run_recursive,
    )

    t, de, z = _measured(seed, duration_s=20.0)
    if method == "ftr":
        frequencies = np.arange(0.1, 1.5 + 1e-9, 0.05)
        estimator = FourierTransformRegression(2, 1, frequencies, update_every=50)
        result = run_recursive(estimator, t, de[:, None], z)
        names = ("A11", "B11", "A21", "A22", "B21")
        index = [list(result.parameter_names).index(n) for n in names]
        return Draw(names, np.asarray(result.values)[index], _stated(result, names, index))
    augmented = AugmentedModel(short_period_model(START), [0.0, 0.0])
    if method == "ekf":
        estimator = ExtendedKalmanFilter(augmented, 10.0, 0.0, NOISE_STD**2)
    elif method == "ukf":
        estimator = UnscentedKalmanFilter(augmented, 10.0, 0.0, NOISE_STD**2)
    else:
        estimator = ExtendedForgettingRLS(augmented, 1.0e3, forgetting=1.0)
    result = run_recursive(estimator, t, de[:, None], z)
    index = [list(result.parameter_names).index(n) for n in NAMES]
    return Draw(NAMES, np.asarray(result.values)[index], _stated(result, NAMES, index))


_PREDICTED: dict[str, np.ndarray] = {}


def design_draw(seed: int) -> Draw:
    """The output-error estimate of the white-noise realisation against the σ predicted
    before the flight: ``predict_accuracy`` at the truth for the same input and noise σ."""
    if "std" not in _PREDICTED:
        from flightid.design.information import predict_accuracy

        t, de = elevator(10.0)
        prediction = predict_accuracy(
            short_period_model(TRUTH), flight_data(t, de, np.zeros((t.size, 2))), NOISE_STD
        )
        _PREDICTED["std"] = np.array([prediction.std_of(n) for n in NAMES])
    draw = output_error_draw(seed)
    return Draw(NAMES, draw.values, {"predicted": _PREDICTED["std"]})


# ------------------------------------------------------- a nonlinear airplane in turbulence
#
# Longitudinal rigid-body equations in body axes (p = r = v = φ = 0):
#   u̇ = −q w − g sinθ + X/m,   ẇ = q u + g cosθ + Z/m,   q̇ = M/I_y,   θ̇ = q,
# X = q̄ S CX, Z = q̄ S CZ, M = q̄ S c̄ Cm, q̄ = ½ ρ V_a², with the air-relative velocity
# (u, w − w_g) of a vertical gust w_g: α_a = atan((w − w_g)/u), V_a = √(u² + (w − w_g)²), and
#   CX = CX0 + CXa α_a,   CZ = CZ0 + CZa α_a + CZq q c̄/(2V_a) + CZde δe,
#   Cm = Cm0 + Cma α_a + Cmq q c̄/(2V_a) + Cmde δe.

#: a light airplane: mass (kg), pitch inertia (kg m²), wing area (m²), chord (m), air density
#: (kg/m³), gravity (m/s²)
AIRPLANE_MASS_KG = 1000.0
AIRPLANE_IYY_KGM2 = 1500.0
AIRPLANE_AREA_M2 = 16.0
AIRPLANE_CHORD_M = 1.5
AIR_DENSITY_KGM3 = 1.225
GRAVITY_MS2 = 9.81
#: trim: level flight at 50 m/s, α = θ = 0.05 rad, δe = 0 (CX0, CZ0, Cm0 chosen for it)
TRIM_SPEED_MS = 50.0
TRIM_ALPHA_RAD = 0.05
_TRIM_QBAR_S_N = 0.5 * AIR_DENSITY_KGM3 * TRIM_SPEED_MS**2 * AIRPLANE_AREA_M2
#: held fixed at the truth in the estimates (the phugoid is barely excited in 15 s)
AIRPLANE_FIXED = {"CXa": 0.30, "CZq": -5.0}
AIRPLANE_FIXED["CX0"] = (
    AIRPLANE_MASS_KG * GRAVITY_MS2 * np.sin(TRIM_ALPHA_RAD) / _TRIM_QBAR_S_N
    - AIRPLANE_FIXED["CXa"] * TRIM_ALPHA_RAD
)
AIRPLANE_TRUTH = {"CZa": -4.8, "CZde": -0.35, "Cma": -0.7, "Cmq": -10.0, "Cmde": -1.1}
# trim: Z/m = −g cosθ, M = 0 at α = θ = α₀, q = 0, δe = 0
AIRPLANE_TRUTH["CZ0"] = (
    -AIRPLANE_MASS_KG * GRAVITY_MS2 * np.cos(TRIM_ALPHA_RAD) / _TRIM_QBAR_S_N
    - AIRPLANE_TRUTH["CZa"] * TRIM_ALPHA_RAD
)
AIRPLANE_TRUTH["Cm0"] = -AIRPLANE_TRUTH["Cma"] * TRIM_ALPHA_RAD
AIRPLANE_NAMES = ("CZ0", "CZa", "CZde", "Cm0", "Cma", "Cmq", "Cmde")
#: body-axis trim state (u m/s, w m/s, q rad/s, θ rad)
AIRPLANE_X0 = (
    TRIM_SPEED_MS * np.cos(TRIM_ALPHA_RAD),
    TRIM_SPEED_MS * np.sin(TRIM_ALPHA_RAD),
    0.0,
    TRIM_ALPHA_RAD,
)
AIRPLANE_DT_S = 0.04
AIRPLANE_DURATION_S = 15.0
#: Dryden vertical gust: σ_w (m/s), scale length L_w (m)
GUST_STD_MS = 0.5
GUST_LENGTH_M = 100.0
#: measurement noise σ of (V m/s, α rad, q rad/s, θ rad)
AIRPLANE_NOISE_STD = np.array([0.2, 2.0e-3, 5.0e-3, 3.0e-3])
AIRPLANE_SUBSTEPS = 4


def airplane_derivative(
    x: np.ndarray, de: float, w_gust: float, values: dict[str, float]
) -> np.ndarray:
    """d(u, w, q, θ)/dt of the airplane in a vertical gust ``w_gust`` (m/s, body z)."""
    u, w, q, theta = x
    w_air = w - w_gust
    # α_a = atan((w − w_g)/u), V_a = √(u² + (w − w_g)²)
    alpha = np.arctan2(w_air, u)
    speed = np.hypot(u, w_air)
    qbar_s = 0.5 * AIR_DENSITY_KGM3 * speed**2 * AIRPLANE_AREA_M2
    q_hat = q * AIRPLANE_CHORD_M / (2.0 * speed)
    c_x = AIRPLANE_FIXED["CX0"] + AIRPLANE_FIXED["CXa"] * alpha
    c_z = values["CZ0"] + values["CZa"] * alpha + AIRPLANE_FIXED["CZq"] * q_hat
    c_z += values["CZde"] * de
    c_m = values["Cm0"] + values["Cma"] * alpha + values["Cmq"] * q_hat + values["Cmde"] * de
    return np.array(
        [
            # u̇ = −q w − g sinθ + X/m
            -q * w - GRAVITY_MS2 * np.sin(theta) + qbar_s * c_x / AIRPLANE_MASS_KG,
            # ẇ = q u + g cosθ + Z/m
            q * u + GRAVITY_MS2 * np.cos(theta) + qbar_s * c_z / AIRPLANE_MASS_KG,
            # q̇ = M/I_y
            qbar_s * AIRPLANE_CHORD_M * c_m / AIRPLANE_IYY_KGM2,
            q,
        ]
    )


def dryden_vertical_gust(rng: np.random.Generator, n: int, dt: float) -> np.ndarray:
    """w_g (m/s) at the n samples: the output of the Dryden filter σ_w √(2V/(πL)) / (s + V/L)
    driven by white noise, sampled exactly (a first-order Gauss–Markov process of variance
    σ_w² and time constant L/V): w_{k+1} = e^{−VΔt/L} w_k + σ_w √(1 − e^{−2VΔt/L}) ξ_k,
    from w_0 = 0."""
    decay = np.exp(-TRIM_SPEED_MS * dt / GUST_LENGTH_M)
    drive = GUST_STD_MS * np.sqrt(1.0 - decay**2) * rng.standard_normal(n)
    gust = np.zeros(n)
    for k in range(n - 1):
        gust[k + 1] = decay * gust[k] + drive[k]
    return gust


def simulate_airplane(
    values: dict[str, float], de: np.ndarray, gust: np.ndarray | None = None
) -> np.ndarray:
    """Outputs (N, 4) = (V m/s, α rad, q rad/s, θ rad) of the inertial motion, by classical
    RK4 with ``AIRPLANE_SUBSTEPS`` steps per sample, δe linear and the gust held between
    samples."""
    n = de.size
    gust = np.zeros(n) if gust is None else gust
    h = AIRPLANE_DT_S / AIRPLANE_SUBSTEPS
    x = np.array(AIRPLANE_X0, dtype=float)
    states = np.empty((n, 4))
    states[0] = x
    for k in range(n - 1):
        for j in range(AIRPLANE_SUBSTEPS):
            # δe at the substep's start, middle and end, linear between samples
            s0, s1 = j / AIRPLANE_SUBSTEPS, (j + 1) / AIRPLANE_SUBSTEPS
            d0, dm, d1 = (de[k] + s * (de[k + 1] - de[k]) for s in (s0, (s0 + s1) / 2, s1))
            k1 = airplane_derivative(x, d0, gust[k], values)
            k2 = airplane_derivative(x + 0.5 * h * k1, dm, gust[k], values)
            k3 = airplane_derivative(x + 0.5 * h * k2, dm, gust[k], values)
            k4 = airplane_derivative(x + h * k3, d1, gust[k], values)
            x = x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        states[k + 1] = x
    u, w, q, theta = states.T
    return np.column_stack([np.hypot(u, w), np.arctan2(w, u), q, theta])


_CX0, _CXA, _CZQ = AIRPLANE_FIXED["CX0"], AIRPLANE_FIXED["CXa"], AIRPLANE_FIXED["CZq"]


def _f_airplane(t, x, u, theta):
    # θ = (CZ0, CZa, CZde, Cm0, Cma, Cmq, Cmde); x = (u, w, q, θ); u = (δe,)
    speed = np.sqrt(x[0] ** 2 + x[1] ** 2)
    alpha = np.arctan(x[1] / x[0])
    qbar_s = 0.5 * AIR_DENSITY_KGM3 * speed * speed * AIRPLANE_AREA_M2
    q_hat = x[2] * AIRPLANE_CHORD_M / (2.0 * speed)
    c_x = _CX0 + _CXA * alpha
    c_z = theta[0] + theta[1] * alpha + _CZQ * q_hat + theta[2] * u[0]
    c_m = theta[3] + theta[4] * alpha + theta[5] * q_hat + theta[6] * u[0]
    dx = np.empty(4)
    dx[0] = -x[2] * x[1] - GRAVITY_MS2 * np.sin(x[3]) + qbar_s * c_x / AIRPLANE_MASS_KG
    dx[1] = x[2] * x[0] + GRAVITY_MS2 * np.cos(x[3]) + qbar_s * c_z / AIRPLANE_MASS_KG
    dx[2] = qbar_s * AIRPLANE_CHORD_M * c_m / AIRPLANE_IYY_KGM2
    dx[3] = x[2]
    return dx


def _h_airplane(t, x, u, theta):
    y = np.empty(4)
    y[0] = np.sqrt(x[0] ** 2 + x[1] ** 2)
    y[1] = np.arctan(x[1] / x[0])
    y[2] = x[2]
    y[3] = x[3]
    return y


def airplane_model(values: dict[str, float], process_noise: dict[str, float] | None = None):
    """flightid's model of the same airplane without turbulence (x0 = trim, known;
    CX0, CXa, CZq fixed at the truth); process-noise elements appended when given."""
    from flightid.model.parameters import Parameter, Parameters
    from flightid.model.statespace import StateSpaceModel

    parameters = [Parameter(n, values[n]) for n in AIRPLANE_NAMES]
    parameters += [Parameter(n, v) for n, v in (process_noise or {}).items()]
    return StateSpaceModel(
        ("u", "w", "q", "theta"),
        ("de",),
        ("V", "alpha", "q", "theta"),
        _f_airplane,
        _h_airplane,
        Parameters(parameters),
        x0=AIRPLANE_X0,
        function_parameters=AIRPLANE_NAMES,
    )


def airplane_data(t: np.ndarray, de: np.ndarray, z: np.ndarray):
    from flightid.data.flightdata import FlightData

    return FlightData(
        t, {"de": de}, {k: z[:, i] for i, k in enumerate(("V", "alpha", "q", "theta"))}
    )


AIRPLANE_START = {n: 1.2 * v for n, v in AIRPLANE_TRUTH.items()}


def _airplane_measured(seed: int, turbulence: bool = True):
    """(t, δe, z) of realisation ``seed``: the airplane through Dryden turbulence (or calm
    air) plus white measurement noise."""
    rng = np.random.default_rng(seed)
    t, de = elevator(AIRPLANE_DURATION_S, AIRPLANE_DT_S)
    gust = dryden_vertical_gust(rng, t.size, AIRPLANE_DT_S) if turbulence else None
    y = simulate_airplane(AIRPLANE_TRUTH, de, gust)
    return t, de, y + rng.standard_normal(y.shape) * AIRPLANE_NOISE_STD


def airplane_output_error_draw(seed: int, turbulence: bool = True) -> Draw:
    """Output error (MNR, R estimated) with the calm-air model, from 20 % off the truth."""
    from flightid.estimation import MNR, estimate

    t, de, z = _airplane_measured(seed, turbulence)
    result = estimate(airplane_model(AIRPLANE_START), airplane_data(t, de, z), MNR())
    return _from_estimate(result, AIRPLANE_NAMES, sandwich=False)


_GUST_BREAK_RAD_S = TRIM_SPEED_MS / GUST_LENGTH_M


def _f_airplane_gust(t, x, u, theta):
    # x = (u, w, q, θ, w_g): the rigid body at the air-relative velocity (u, w − w_g), and
    # the Dryden shaping filter ẇ_g = −(V/L) w_g (+ its process noise)
    w_air = x[1] - x[4]
    speed = np.sqrt(x[0] ** 2 + w_air**2)
    alpha = np.arctan(w_air / x[0])
    qbar_s = 0.5 * AIR_DENSITY_KGM3 * speed * speed * AIRPLANE_AREA_M2
    q_hat = x[2] * AIRPLANE_CHORD_M / (2.0 * speed)
    c_x = _CX0 + _CXA * alpha
    c_z = theta[0] + theta[1] * alpha + _CZQ * q_hat + theta[2] * u[0]
    c_m = theta[3] + theta[4] * alpha + theta[5] * q_hat + theta[6] * u[0]
    dx = np.empty(5)
    dx[0] = -x[2] * x[1] - GRAVITY_MS2 * np.sin(x[3]) + qbar_s * c_x / AIRPLANE_MASS_KG
    dx[1] = x[2] * x[0] + GRAVITY_MS2 * np.cos(x[3]) + qbar_s * c_z / AIRPLANE_MASS_KG
    dx[2] = qbar_s * AIRPLANE_CHORD_M * c_m / AIRPLANE_IYY_KGM2
    dx[3] = x[2]
    dx[4] = -_GUST_BREAK_RAD_S * x[4]
    return dx


def _h_airplane_gust(t, x, u, theta):
    y = np.empty(4)
    y[0] = np.sqrt(x[0] ** 2 + x[1] ** 2)
    y[1] = np.arctan(x[1] / x[0])
    y[2] = x[2]
    y[3] = x[3]
    return y


def airplane_gust_model(values: dict[str, float], gust_intensity: float):
    """The airplane with the vertical gust w_g as a fifth state (its shaping filter, the
    first-order Dryden filter); its process noise ``Fg`` (m/s/√s, truth σ_w √(2V/L)) is
    estimated by filter error."""
    from flightid.model.parameters import Parameter, Parameters
    from flightid.model.statespace import StateSpaceModel

    parameters = [Parameter(n, values[n]) for n in AIRPLANE_NAMES]
    parameters.append(Parameter("Fg", gust_intensity))
    return StateSpaceModel(
        ("u", "w", "q", "theta", "wg"),
        ("de",),
        ("V", "alpha", "q", "theta"),
        _f_airplane_gust,
        _h_airplane_gust,
        Parameters(parameters),
        x0=(*AIRPLANE_X0, 0.0),
        function_parameters=AIRPLANE_NAMES,
    )


#: the gust state's process noise that gives w_g the variance σ_w²: F = σ_w √(2V/L)
GUST_INTENSITY = GUST_STD_MS * np.sqrt(2.0 * _GUST_BREAK_RAD_S)


def airplane_filter_error_draw(seed: int) -> Draw:
    """Filter error (fixed-point relaxation, MNR, gradients by differences) of the airplane
    with the gust state, from 20 % off the truth and Fg 1.2× its truth."""
    from flightid.estimation import MNR
    from flightid.estimation.filter_error import estimate_filter_error

    t, de, z = _airplane_measured(seed)
    model = airplane_gust_model(AIRPLANE_START, 1.2 * GUST_INTENSITY)
    result = estimate_filter_error(model, airplane_data(t, de, z), {"wg": "Fg"}, MNR())
    return _from_estimate(result, (*AIRPLANE_NAMES, "Fg"), sandwich=False)


def airplane_filter_error_w_draw(seed: int) -> Draw:
    """Filter error with the calm-air model and white process noise ``Fw`` on the w (α)
    equation only: a process-noise model that does not match the turbulence (coloured, and
    entering the pitching moment too), from 20 % off the truth and Fw = 0.1 m/s/√s."""
    from flightid.estimation import MNR
    from flightid.estimation.filter_error import estimate_filter_error

    t, de, z = _airplane_measured(seed)
    model = airplane_model(AIRPLANE_START, {"Fw": 0.1})
    result = estimate_filter_error(model, airplane_data(t, de, z), {"w": "Fw"}, MNR())
    return _from_estimate(result, AIRPLANE_NAMES, sandwich=False)


FTR_TRUTH = {
    "A11": TRUTH["Za"],
    "B11": TRUTH["Zde"],
    "A21": TRUTH["Ma"],
    "A22": TRUTH["Mq"],
    "B21": TRUTH["Mde"],
}
EE_TRUTH = {n: TRUTH[n] for n in EE_NAMES}
FAMILY_TRUTH = {
    "filter_error": {**TRUTH, "F11": PROCESS_STD[0], "F22": PROCESS_STD[1]},
}


# ---------------------------------------------------------------- the study


@dataclass(frozen=True)
class Family:
    """A family: the draw of seed ``s``, the truth, and the note printed with the table."""

    draw: Callable[[int], Draw]
    truth: dict[str, float]
    note: str = ""


FAMILIES: dict[str, Family] = {
    "output_error_white": Family(
        output_error_draw, TRUTH, "short period, white measurement noise, 10 s"
    ),
    "output_error_coloured": Family(
        lambda s: output_error_draw(s, pole=0.9),
        TRUTH,
        "short period, AR(1) measurement noise (pole 0.9), 10 s",
    ),
    "filter_error": Family(
        filter_error_draw,
        FAMILY_TRUTH["filter_error"],
        "short period with process noise F = diag(0.02, 0.05), 20 s",
    ),
    "filter_error_constrained": Family(
        lambda s: filter_error_draw(s, CONSTRAINED_NOISE_STD),
        FAMILY_TRUTH["filter_error"],
        "as filter_error, α measured without noise: diag(KC)_α = 1 active in part of the runs",
    ),
    "equation_error": Family(
        equation_error_draw, EE_TRUTH, "least squares of q̇ on (α, q, δe), white residuals"
    ),
    "equation_error_coloured": Family(
        lambda s: equation_error_draw(s, pole=0.9),
        EE_TRUTH,
        "least squares of q̇ on (α, q, δe), AR(1) residuals (pole 0.9)",
    ),
    "stepwise": Family(
        stepwise_draw, EE_TRUTH, "stepwise over (α, q, δe, α², α·δe, q·δe), true terms"
    ),
    "frequency_equation_error": Family(
        lambda s: frequency_draw(s, "equation_error"),
        TRUTH,
        "0.1–1.5 Hz, step 1/T, white noise on α and q (noisy regressors)",
    ),
    "frequency_output_error": Family(
        lambda s: frequency_draw(s, "output_error"), TRUTH, "0.1–1.5 Hz, step 1/T, white noise"
    ),
    "frequency_output_error_x4": Family(
        lambda s: frequency_draw(s, "output_error", oversampling=4),
        TRUTH,
        "0.1–1.5 Hz, step 1/(4T): a 4× oversampled grid",
    ),
    "ekf": Family(lambda s: recursive_draw(s, "ekf"), TRUTH, "augmented EKF, 20 s"),
    "ukf": Family(lambda s: recursive_draw(s, "ukf"), TRUTH, "augmented UKF, 20 s"),
    "efrls": Family(
        lambda s: recursive_draw(s, "efrls"), TRUTH, "extended forgetting RLS, λ = 1, 20 s"
    ),
    "ftr": Family(lambda s: recursive_draw(s, "ftr"), FTR_TRUTH, "Fourier transform regression"),
    "airplane_calm": Family(
        lambda s: airplane_output_error_draw(s, turbulence=False),
        AIRPLANE_TRUTH,
        "nonlinear longitudinal airplane (RK4), calm air, output error, 15 s at 25 Hz",
    ),
    "airplane_turbulence": Family(
        airplane_output_error_draw,
        AIRPLANE_TRUTH,
        "as airplane_calm in Dryden turbulence (σ_w 0.5 m/s, L 100 m), output error",
    ),
    "airplane_turbulence_fem": Family(
        airplane_filter_error_draw,
        {**AIRPLANE_TRUTH, "Fg": GUST_INTENSITY},
        "as airplane_turbulence, filter error, the gust a state (Dryden filter, noise Fg)",
    ),
    "airplane_turbulence_fem_w": Family(
        airplane_filter_error_w_draw,
        AIRPLANE_TRUTH,
        "as airplane_turbulence, filter error, calm-air model, white noise on w only",
    ),
    "design": Family(
        design_draw, TRUTH, "predicted Cramér–Rao σ (predict_accuracy) vs output-error spread"
    ),
}
QUICK = ("output_error_white",)


@dataclass
class Row:
    family: str
    name: str
    kind: str
    n: int
    cover: float
    ratio: float
    bias: float


def coverage_rows(family: str, draws: list[Draw]) -> list[Row]:
    """Coverage and spread ratio per parameter and σ kind."""
    truth = FAMILIES[family].truth
    names = draws[0].names
    values = np.array([d.values for d in draws])
    true = np.array([truth[n] for n in names])
    spread = values.std(axis=0, ddof=1)
    bias = (values.mean(axis=0) - true) / spread
    rows = []
    for kind in draws[0].sigmas:
        sigma = np.array([d.sigmas[kind] for d in draws])
        inside = np.abs(values - true) <= 2.0 * sigma
        for j, name in enumerate(names):
            rows.append(
                Row(
                    family,
                    name,
                    kind,
                    len(draws),
                    float(inside[:, j].mean()),
                    float(spread[j] / sigma[:, j].mean()),
                    float(bias[j]),
                )
            )
    return rows


def run_family(family: str, seeds: int, seed: int = 1000) -> tuple[list[Row], list[str]]:
    """The family's rows over realisations ``seed … seed + seeds − 1`` (warnings silenced),
    and one line per realisation whose estimator raised (left out of the rows)."""
    from flightid.errors import FlightIdError

    draws, failures = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i in range(seeds):
            try:
                draws.append(FAMILIES[family].draw(seed + i))
            except FlightIdError as exc:
                failures.append(f"seed {seed + i}: {type(exc).__name__}: {str(exc)[:100]}")
    return coverage_rows(family, draws), failures


def format_rows(rows: list[Row]) -> str:
    lines = [
        f"{'family':24s} {'parameter':10s} {'σ':13s} {'runs':>4s} {'cover':>6s} "
        f"{'ratio':>6s} {'bias':>6s}"
    ]
    for r in rows:
        flag = "" if (0.90 <= r.cover <= 0.98 and 0.8 <= r.ratio <= 1.25) else "  *"
        lines.append(
            f"{r.family:24s} {r.name:10s} {r.kind:13s} {r.n:4d} {r.cover:6.3f} "
            f"{r.ratio:6.2f} {r.bias:6.2f}{flag}"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--family", nargs="+", choices=sorted(FAMILIES), default=None)
    parser.add_argument("--seeds", type=int, default=None, help="realisations per family")
    parser.add_argument("--seed", type=int, default=1000, help="first noise seed")
    parser.add_argument("--quick", action="store_true", help="the fast subset, 60 seeds")
    args = parser.parse_args(argv)
    families = args.family or (list(QUICK) if args.quick else list(FAMILIES))
    seeds = args.seeds or (60 if args.quick else 200)
    for family in families:
        started = time.perf_counter()
        rows, failures = run_family(family, seeds, args.seed)
        print(f"# {family}: {FAMILIES[family].note}")
        print(format_rows(rows))
        for line in failures:
            print(f"  failed, left out: {line}")
        print(f"({time.perf_counter() - started:.1f} s)\n", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
