"""Frequency-domain equation error: complex least squares with real parameters.

For a linear model with measured states, each state equation holds at every frequency ω of
the band (Morelli & Klein, *Aircraft System Identification*, 2nd ed., ch. 7):

    jω X_i(ω) + x_i(T) e^{−jωT} − x_i(0) = Σ_j A_ij X_j(ω) + Σ_k B_ik U_k(ω) + c_i E(ω)

where X, U are finite Fourier transforms (``flightid.frequency.fourier``) and E the
transform of the constant 1. The model parameters θ enter [A B] affinely,
row_i(θ) = r_i0 + Σ_p θ_p g_ip, so each equation is a complex linear regression

    z(ω) = jω X_i(ω) − r_i0 [X; U](ω) = Σ_p θ_p g_ip [X; U](ω) + x_i(0) − x_i(T) e^{−jωT}
           + c_i E(ω) + ε(ω)

with real unknowns. Stacking real and imaginary parts, the least-squares estimate and its
covariance are

    θ̂ = [Re(XᴴX)]⁻¹ Re(Xᴴz),      Cov(θ̂) = σ̂² [Re(XᴴX)]⁻¹,
    σ̂² = Σ_ω |ε(ω)|² / (2K − n_p)

(2K real equations; each real component of a circular complex residual of variance s has
variance s/2, which is what σ̂² estimates). That is the Cramér–Rao-type σ (``std_cr``) of
white, equal residuals at independent frequencies; on a grid finer than 1/T it becomes
σ̂² N⁻¹ [Σ_m c_m N_m] N⁻¹, N = Re(XᴴX), c_m = max(1, 1/(T_m Δf)) (maneuver m's rows N_m;
``flightid.frequency.uncertainty``), so that refining the grid does not shrink it. The
equation-error residual is never white and equal: it carries jω times the measurement
noise of X, growing with frequency, and the noise of the regressors. The reported ``std``
is therefore the coloured-residual sandwich on the real-stacked rows [Re x_k; Im x_k],

    Cov_c(θ̂) = N⁻¹ [Σ_k Σ_l x_kᵀ R̂(k − l) x_l] N⁻¹,   R̂(m) = (1/K) Σ_k r_{k+m} r_kᵀ

per maneuver, all lags (``flightid.frequency.uncertainty.sandwich_covariance``), which
reduces to σ̂² N⁻¹ for white, equal residuals. The boundary values and constants are per-maneuver
nuisance regressors. Output equations y_o = C_o x + D_o u + d_o whose parameters appear in
no state equation (e.g. a_y = Y_p p + ... of the lateral model) are fitted the same way with
Z_o(ω) as the response; outputs whose parameters the state equations already determine (ṗ,
ṙ) are not refitted.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from flightid.errors import InputError, describe
from flightid.frequency.arguments import boolean_mask, checked_callable, name_list, real_array
from flightid.frequency.fourier import ManeuverSpectra
from flightid.frequency.linear_system import LinearSystem
from flightid.frequency.output_error import (
    checked_model_arguments,
    checked_start,
    delayed_inputs,
)
from flightid.frequency.uncertainty import (
    grid_corrected_inverse,
    grid_factors,
    sandwich_covariance,
)

__all__ = [
    "ComplexRegression",
    "complex_least_squares",
    "EquationErrorFit",
    "equation_error",
    "equation_error_structure",
]


@dataclass(frozen=True)
class ComplexRegression:
    """θ̂ (p,), σ̂², residuals ε (K,) of one complex regression, with the coloured-residual
    covariance ``covariance`` (the reported one) and the Cramér–Rao-type
    ``covariance_cr`` = σ̂² N⁻¹[Σ c_m N_m]N⁻¹ (module docstring), both (p, p)."""

    theta: np.ndarray
    covariance: np.ndarray
    sigma2: float
    residuals: np.ndarray
    r_squared: float
    covariance_cr: np.ndarray

    @property
    def std(self) -> np.ndarray:
        """Reported σ: the coloured-residual sandwich."""
        return np.sqrt(np.abs(np.diag(self.covariance)))

    @property
    def std_cr(self) -> np.ndarray:
        """Cramér–Rao-type σ: sqrt diag(σ̂² N⁻¹[Σ c_m N_m]N⁻¹)."""
        return np.sqrt(np.diag(self.covariance_cr))


def complex_least_squares(
    regressors: np.ndarray,
    response: np.ndarray,
    *,
    segments: Sequence[int] | None = None,
    factors: Sequence[float] | None = None,
) -> ComplexRegression:
    """Real θ minimising Σ|z − Xθ|² for complex X (K, p) and z (K,).

    ``segments``: the number of rows of each maneuver, in order (default: one maneuver);
    residual lags of the coloured covariance never cross from one to the next.
    ``factors``: c_m = max(1, 1/(T_m Δf)) per maneuver (default 1: independent frequencies).
    """
    try:
        X = np.asarray(regressors, dtype=complex)
        z = np.asarray(response, dtype=complex).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(
            f"regressors/response: expected complex numbers, got {describe(regressors)} and "
            f"{describe(response)}"
        ) from None
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(z))):
        raise InputError("regressors/response: expected finite values")
    if X.ndim != 2 or X.shape[0] != z.shape[0]:
        raise InputError(
            f"regressors: expected a (K, p) array with K = {z.shape[0]} rows, got {X.shape}"
        )
    k, p = X.shape
    if 2 * k <= p:
        raise InputError(f"regressors: {2 * k} real equations cannot determine {p} parameters")
    # Re(XᴴX) θ = Re(Xᴴz)
    normal = np.real(X.conj().T @ X)
    try:
        inverse = np.linalg.inv(normal)
    except np.linalg.LinAlgError:
        raise InputError(
            "regressors: Re(XᴴX) is singular; a parameter has no independent regressor on this band"
        ) from None
    theta = inverse @ np.real(X.conj().T @ z)
    residuals = z - X @ theta
    # σ̂² = Σ|ε|² / (2K − p)
    sigma2 = float(np.sum(np.abs(residuals) ** 2) / (2 * k - p))
    total = float(np.sum(np.abs(z - z.mean()) ** 2))
    r2 = 1.0 - float(np.sum(np.abs(residuals) ** 2)) / total if total > 0 else float("nan")
    counts = _checked_segments(segments, k)
    factors = np.ones(len(counts)) if factors is None else np.asarray(factors, dtype=float)
    if factors.shape != (len(counts),) or not np.all(factors >= 1.0):
        raise InputError(
            f"factors: expected {len(counts)} grid factors >= 1, one per segment, got "
            f"{describe(factors)}"
        )
    # real-stacked rows per frequency: x_k = [Re x_k; Im x_k] (2, p), r_k = [Re ε_k, Im ε_k]
    stacked = np.stack([X.real, X.imag], axis=1)
    stacked_residuals = np.stack([residuals.real, residuals.imag], axis=1)
    edges = np.concatenate([[0], np.cumsum(counts)])
    jac_blocks = [stacked[a:b] for a, b in zip(edges[:-1], edges[1:], strict=True)]
    res_blocks = [stacked_residuals[a:b] for a, b in zip(edges[:-1], edges[1:], strict=True)]
    # Cov_CR = σ̂² N⁻¹ [Σ_m c_m N_m] N⁻¹   (= σ̂² N⁻¹ on grids of step ≥ 1/T)
    covariance_cr = sigma2 * grid_corrected_inverse(jac_blocks, factors)
    # Cov_c = N⁻¹ [Σ_k Σ_l x_kᵀ R̂(k − l) x_l] N⁻¹
    covariance = sandwich_covariance(jac_blocks, res_blocks)
    return ComplexRegression(theta, covariance, sigma2, residuals, r2, covariance_cr)


def _checked_segments(segments: Sequence[int] | None, rows: int) -> list[int]:
    """Row counts per maneuver summing to ``rows`` (one segment of all rows for None)."""
    if segments is None:
        return [rows]
    try:
        counts = [int(c) for c in segments]
    except (TypeError, ValueError):
        raise InputError(f"segments: expected row counts, got {describe(segments)}") from None
    if not counts or any(c < 1 for c in counts) or sum(counts) != rows:
        raise InputError(f"segments: expected positive row counts summing to {rows}, got {counts}")
    return counts


@dataclass(frozen=True)
class EquationErrorFit:
    """Estimates of the model parameters (full vector; fixed and undetermined ones keep
    their start values and have NaN std) and one regression per fitted equation."""

    theta: np.ndarray
    std: np.ndarray  # reported σ: coloured-residual sandwich
    estimated: np.ndarray  # boolean mask: the parameters some regression determined
    equations: dict[str, ComplexRegression]
    std_cr: np.ndarray  # Cramér–Rao-type σ̂² N⁻¹[Σ c_m N_m]N⁻¹, NaN where not estimated


def _affine_rows(
    system_of: Callable[[np.ndarray], LinearSystem], theta: np.ndarray, free: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """[A B] and [C D] at θ with the free parameters zeroed, and their slopes per free θ_p."""

    def blocks(th):
        s = system_of(th)
        return np.hstack([s.A, s.B]), np.hstack([s.C, s.D])

    base = theta.copy()
    base[free] = 0.0
    ab0, cd0 = blocks(base)
    slopes_ab, slopes_cd = [], []
    for j in np.flatnonzero(free):
        unit = base.copy()
        unit[j] = 1.0
        ab, cd = blocks(unit)
        slopes_ab.append(ab - ab0)
        slopes_cd.append(cd - cd0)
    rng = np.random.default_rng(7)
    probe = theta.copy()
    probe[free] = rng.standard_normal(int(free.sum()))
    ab, cd = blocks(probe)
    ab_lin = ab0 + np.tensordot(probe[free], np.array(slopes_ab), axes=1) if slopes_ab else ab0
    cd_lin = cd0 + np.tensordot(probe[free], np.array(slopes_cd), axes=1) if slopes_cd else cd0
    if not (np.allclose(ab, ab_lin, atol=1e-9) and np.allclose(cd, cd_lin, atol=1e-9)):
        raise InputError(
            "model: frequency-domain equation error needs A, B, C, D affine in the free "
            'parameters (use method = "output_error")'
        )
    return ab0, cd0, np.array(slopes_ab), np.array(slopes_cd)


def _measured_outputs(
    system: LinearSystem, cd0: np.ndarray, g_cd: np.ndarray, states, outputs
) -> list[int]:
    """The output that measures each state (a row [C D] = e_i that no free parameter
    moves), without output delay; else ``InputError``."""
    if np.any(system.output_delays_s):
        raise InputError(
            "model: frequency-domain equation error needs the states measured without delay; "
            f"the model delays outputs by {system.output_delays_s.tolist()} s "
            '(use method = "output_error")'
        )
    measured = []
    for i, state in enumerate(states):
        unit = np.zeros(cd0.shape[1])
        unit[i] = 1.0
        rows = [
            o
            for o in range(cd0.shape[0])
            if np.allclose(cd0[o], unit) and not (g_cd.size and np.any(g_cd[:, o]))
        ]
        if not rows:
            raise InputError(
                f"model: equation error needs every state measured; no output equals state "
                f'{state!r} (outputs: {list(outputs)}); use method = "output_error"'
            )
        measured.append(rows[0])
    return measured


def equation_error_structure(
    system_of: Callable[[np.ndarray], LinearSystem],
    theta_start: np.ndarray,
    free: np.ndarray,
    states: Sequence[str],
    outputs: Sequence[str],
) -> np.ndarray:
    """The free parameters equation error can determine (boolean mask over θ), found from
    the model's structure alone: those in a state equation's row of [A B], or in the row
    of [C D] of an output that measures no state. Raises the ``InputError`` of
    ``equation_error`` for a model it cannot take (not affine in the free parameters, a
    state not measured, delayed outputs)."""
    theta_start = real_array(theta_start, "theta_start", "start values (numbers)")
    free = boolean_mask(free, "free", theta_start.size)
    states, outputs = name_list(states, "states"), name_list(outputs, "outputs")
    ab0, cd0, g_ab, g_cd = _affine_rows(checked_callable(system_of, "system_of"), theta_start, free)
    measured = _measured_outputs(system_of(theta_start), cd0, g_cd, states, outputs)
    determined = np.zeros(theta_start.size, dtype=bool)
    for q, j in enumerate(np.flatnonzero(free)):
        in_states = bool(np.any(g_ab[q, : len(states)]))
        in_outputs = any(np.any(g_cd[q, o]) for o in range(cd0.shape[0]) if o not in measured)
        determined[j] = in_states or in_outputs
    return determined


# a maneuver's constant column is left out where the band cannot see a constant: the
# transform of 1, (1 − e^{−jωT})/(jω), vanishes at multiples of 1/T (to rounding, ~1e-16·T);
# a column of rounding noise would take a coefficient of ~1e13 and move the estimates
INVISIBLE_CONSTANT = 1e-9


def constant_visible(spectra: ManeuverSpectra) -> bool:
    """Whether the band sees a constant of this maneuver: max |F{1}(ω)| > 1e-9·T."""
    return bool(np.max(np.abs(spectra.constant)) > INVISIBLE_CONSTANT * spectra.duration_s)


def equation_error(
    system_of: Callable[[np.ndarray], LinearSystem],
    theta_start: np.ndarray,
    free: np.ndarray,
    spectra: Sequence[ManeuverSpectra],
    states: Sequence[str],
    outputs: Sequence[str],
    *,
    boundary: bool = True,
    constants: bool = True,
) -> EquationErrorFit:
    """Estimate the free parameters by frequency-domain equation error.

    Every state must be measured: an output whose row of [C D] is the unit vector of that
    state (the output named like the state, typically). Input delays enter at their values
    in ``theta_start`` (``delayed_inputs``); a delay is not linear in the regression, so a
    free delay parameter is left undetermined (``estimated`` False); output delays are refused.
    """
    theta_start, free = checked_start(theta_start, free, spectra)
    states, outputs = checked_model_arguments(
        system_of, theta_start, spectra, states, outputs, boundary, constants
    )
    n_x = len(states)
    ab0, cd0, g_ab, g_cd = _affine_rows(system_of, theta_start, free)
    delays = system_of(theta_start)
    measured = _measured_outputs(delays, cd0, g_cd, states, outputs)
    free_index = np.flatnonzero(free)
    n_m = len(spectra)

    def nuisance_columns(
        k: int, s: ManeuverSpectra, total_rows: int, row0: int
    ) -> list[np.ndarray]:
        cols = []
        basis = []
        if boundary:
            # x(0) − x(T) e^{−jωT}: one column when e^{−jωT} is the same at every ω
            basis += [np.ones_like(s.constant)] + ([] if s.end_phase_constant else [-s.end_phase])
        if constants and constant_visible(s):
            basis += [s.constant]
        for b in basis:
            col = np.zeros(total_rows, dtype=complex)
            col[row0 : row0 + b.size] = b
            cols.append(col)
        return cols

    total = sum(s.frequencies_hz.size for s in spectra)
    theta = theta_start.copy()
    std = np.full(theta.size, np.nan)
    std_cr = np.full(theta.size, np.nan)
    estimated = np.zeros(theta.size, dtype=bool)
    segments = [s.frequencies_hz.size for s in spectra]
    factors = grid_factors(spectra)
    equations: dict[str, ComplexRegression] = {}
    # measured state and input transforms [X; U] per maneuver, stacked (total, n_z)
    # (inputs delayed by the model's input delays at θ_start: ``delayed_inputs``)
    xu = np.concatenate(
        [np.hstack([s.outputs[:, measured], delayed_inputs(delays, s)]) for s in spectra],
        axis=0,
    )
    jw = np.concatenate([1j * s.omega_rad_s for s in spectra])
    state_params: set[int] = set()
    for i, state in enumerate(states):
        used = [q for q in range(free_index.size) if np.any(g_ab[q, i])]
        state_params.update(used)
        # z = jω X_i − r_i0 [X; U]
        response = jw * xu[:, i] - xu @ ab0[i]
        columns = [xu @ g_ab[q, i] for q in used]
        row0 = 0
        for k, s in enumerate(spectra):
            columns += nuisance_columns(k, s, total, row0)
            row0 += s.frequencies_hz.size
        fit = complex_least_squares(
            np.column_stack(columns), response, segments=segments, factors=factors
        )
        equations[f"d{state}/dt"] = fit
        for col, q in enumerate(used):
            j = free_index[q]
            theta[j] = fit.theta[col]
            std[j] = fit.std[col]
            std_cr[j] = fit.std_cr[col]
            estimated[j] = True
    for o, output in enumerate(outputs):
        if o in measured:
            continue
        used = [q for q in range(free_index.size) if np.any(g_cd[q, o])]
        own = [q for q in used if q not in state_params]
        if not own:
            continue  # its parameters come from the state equations (ṗ = f_p, ...)
        known = theta.copy()
        known[free_index[own]] = 0.0
        # contribution of everything but its own parameters: [C D](θ with own = 0) [X; U]
        cd_known = cd0[o] + sum(known[free_index[q]] * g_cd[q, o] for q in range(free_index.size))
        z_o = np.concatenate([s.outputs[:, o] for s in spectra])
        response = z_o - xu @ cd_known
        columns = [xu @ g_cd[q, o] for q in own]
        if constants:
            row0 = 0
            for s in spectra:
                if constant_visible(s):
                    col = np.zeros(total, dtype=complex)
                    col[row0 : row0 + s.frequencies_hz.size] = s.constant
                    columns.append(col)
                row0 += s.frequencies_hz.size
        fit = complex_least_squares(
            np.column_stack(columns), response, segments=segments, factors=factors
        )
        equations[output] = fit
        for col, q in enumerate(own):
            j = free_index[q]
            theta[j] = fit.theta[col]
            std[j] = fit.std[col]
            std_cr[j] = fit.std_cr[col]
            estimated[j] = True
    del n_x, n_m
    return EquationErrorFit(theta, std, estimated, equations, std_cr)
