"""Frequency-domain output error for a linear state-space model.

Model (Morelli & Klein, *Aircraft System Identification*, 2nd ed., ch. 7): on each maneuver
of length T, the finite Fourier transforms X, U, Y of states, inputs and outputs at ω on the
band satisfy, exactly for ẋ = A x + B u + c, y = C x + D u + d,

    jω X(ω) + x(T) e^{−jωT} − x(0) = A X(ω) + B U(ω) + c E(ω)
    Y(ω) = C X(ω) + D U(ω) + d E(ω),                 E(ω) = ∫_0^T e^{−jωτ} dτ

so that the model output is

    Y(ω) = C (jωI − A)⁻¹ [B U(ω) + c E(ω) + x(0) − x(T) e^{−jωT}] + D U(ω) + d E(ω).

The boundary values x(0), x(T) and the constants c, d (what is left of biases after the
means were removed) enter linearly; they are estimated with the model parameters as
per-maneuver nuisance parameters (``boundary``, ``constants``), because data that do not
start and end at trim otherwise leave a transient the model cannot explain. With the
boundary values estimated, the state constants are redundant: from
(jωI − A)⁻¹/(jω) = [(jωI − A)⁻¹ − I/(jω)] A⁻¹ and E = (1 − e^{−jωT})/(jω),

    C (jωI − A)⁻¹ c E(ω) = C (jωI − A)⁻¹ A⁻¹c (1 − e^{−jωT}) − C A⁻¹c E(ω),

a boundary term with x(0) = x(T) = A⁻¹c plus an output constant d = −C A⁻¹c; so c is
estimated only when the boundary values are not (``boundary = false``). Kept, it would make
the information matrix exactly singular. With the
residuals ε(ω) = Z(ω) − Y(ω) the cost is

    J(θ) = Σ_ω ε(ω)ᴴ S⁻¹ ε(ω),        S = (1/K) Σ_ω ε(ω) ε(ω)ᴴ          (K frequencies)

minimised, for S fixed, by Gauss–Newton with a Levenberg–Marquardt safeguard
(``scipy.optimize.least_squares``, method "lm") on the real-stacked weighted residuals
r = [Re(Lᴴε); Im(Lᴴε)] with S⁻¹ = L Lᴴ; S is then re-estimated from the residuals and the
two steps alternate until S and J settle (as the time-domain output-error method does with
R). The sensitivities ∂Y/∂θ are central differences of the model response; those of the
nuisance parameters, in which Y is linear, are written out (``nuisance_sensitivities``).

Accuracy. For a circular complex residual with covariance S, each of the 2 n_y real
components of r has variance ½, so the Fisher information of independent frequencies is

    M = 2 Σ_ω Re[∂Yᴴ/∂θ S⁻¹ ∂Y/∂θ] = 2 J_rᵀ J_r = 2H ,      Cov(θ̂) ≈ M⁻¹     (Cramér–Rao)

(Morelli & Klein write the same matrix with the transform normalisation folded into S).
The transforms at frequencies closer than 1/T are correlated; a grid of step Δf < 1/T
holds only T·Δf of a record's independent frequencies per point, and the bound reported as
``std_cr`` is

    Cov_CR(θ̂) = ½ H⁻¹ [Σ_m c_m H_m] H⁻¹,       c_m = max(1, 1/(T_m Δf))

(maneuver m's part H_m of H; = c/(2H) for one maneuver), which does not shrink when the
grid is refined below 1/T (derivation: ``flightid.frequency.uncertainty``). Model error
colours the residuals across frequency; the coloured-residual σ (``std_coloured``) is the
sandwich

    Cov_c(θ̂) = H⁻¹ [Σ_k Σ_l J_kᵀ R̂(k − l) J_l] H⁻¹,
    R̂(m) = (1/K) Σ_k r_{k+m} r_kᵀ       (per maneuver, all lags; zero between maneuvers)

the frequency-index analogue of Morelli & Klein's correction of the least-squares and
output-error covariance for coloured residuals (their ch. 5 and 6; Morelli & Klein, "Determining
the accuracy of maximum likelihood parameter estimates with colored residuals", NASA
CR-194893, 1994). It measures the correlation of the grid and of the model error from the
residuals; with white residuals on a 1/T grid R̂(0) → ½I, R̂(m ≠ 0) → 0 and it reduces to
M⁻¹. The reported ``std`` is the larger of the coloured σ and ``std_cr``, per parameter:
frequency-domain residuals are correlated whenever the grid is finer than 1/T or the model
leaves anything unexplained, and where they are white the coloured σ is the Cramér–Rao σ
within its sampling error — taken alone it then falls below the bound about half the time.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from flightid.errors import EstimationError, InputError, describe
from flightid.frequency.arguments import (
    boolean_mask,
    checked_callable,
    finite_number,
    flag,
    name_list,
    positive_integer,
    real_array,
)
from flightid.frequency.fourier import ManeuverSpectra, spectra_list
from flightid.frequency.linear_system import LinearSystem
from flightid.frequency.uncertainty import (
    grid_corrected_inverse,
    grid_factors,
    sandwich_covariance,
)

__all__ = [
    "OutputErrorFit",
    "check_equation_count",
    "delayed_inputs",
    "model_response",
    "nuisance_names",
    "nuisance_sensitivities",
    "output_error",
]

SystemFunction = Callable[[np.ndarray], LinearSystem]


@dataclass(frozen=True)
class OutputErrorFit:
    """The frequency-domain output-error estimate.

    ``theta`` is the full model parameter vector (fixed ones at their given values);
    ``std`` (the reported σ: the larger of the coloured-residual one and ``std_cr``),
    ``std_cr`` (Cramér–Rao, corrected for grids finer than 1/T) and ``std_coloured`` are NaN
    for fixed parameters. Nuisance
    parameters (boundary values, constants) are listed separately, with Cramér–Rao σ.
    """

    theta: np.ndarray
    free: np.ndarray
    std: np.ndarray
    std_coloured: np.ndarray
    covariance: np.ndarray  # free model parameters, Cramér–Rao ½H⁻¹[Σ c_m H_m]H⁻¹
    covariance_coloured: np.ndarray
    nuisance_names: tuple[str, ...]
    nuisance: np.ndarray
    nuisance_std: np.ndarray
    S: np.ndarray
    cost: float
    noise_cycles: int
    iterations: int
    converged: bool
    message: str
    model_outputs: tuple[np.ndarray, ...]
    residuals: tuple[np.ndarray, ...]
    cost_history: tuple[float, ...] = field(default_factory=tuple)
    evaluation_history: tuple[int, ...] = field(default_factory=tuple)  # nfev per noise cycle
    std_cr: np.ndarray = field(default_factory=lambda: np.zeros(0))
    grid_factors: tuple[float, ...] = ()  # c_m = max(1, 1/(T_m Δf)) per maneuver


def nuisance_names(
    states: Sequence[str],
    outputs: Sequence[str],
    spectra: Sequence[ManeuverSpectra],
    *,
    boundary: bool = True,
    constants: bool = True,
) -> list[str]:
    """Names of the per-maneuver nuisance parameters, maneuver by maneuver: x(0) ``x0_s``,
    x(T) ``xT_s`` (one ``x0_xT_s`` = x(0) − x(T)e^{−jωT} where e^{−jωT} is the same at every
    frequency), state constants ``c_s``, output constants ``d_o`` (suffix ``_k``, k = 1...)."""
    names = []
    for k, s in enumerate(spectra, start=1):
        if boundary and s.end_phase_constant:
            names += [f"x0_xT_{x}_{k}" for x in states]
        elif boundary:
            names += [f"x0_{x}_{k}" for x in states] + [f"xT_{x}_{k}" for x in states]
        if constants and not boundary:
            names += [f"c_{x}_{k}" for x in states]
        if constants:
            names += [f"d_{o}_{k}" for o in outputs]
    return names


def _per_maneuver_count(
    n_x: int, n_y: int, boundary: bool, constants: bool, merged: bool = False
) -> int:
    boundary_count = (n_x if merged else 2 * n_x) if boundary else 0
    # state constants c only without boundary values (else redundant), output constants d
    return boundary_count + ((n_y if boundary else n_x + n_y) if constants else 0)


def delayed_inputs(system: LinearSystem, spectra: ManeuverSpectra) -> np.ndarray:
    """Transforms Ũ(ω) (K, n_u) of the inputs the model sees, ũ(t) = u(t − τ) on [0, T]
    with u(t) = u(0) held before the record (the time-domain convention):

        Ũ(ω) = e^{−jωτ} U(ω) + (1 − e^{−jωτ})/(jω) · [u(0) − u(T) e^{−jωT}]

    The first term is the delay; the second adds the held start value over [0, τ] and
    removes the last τ seconds of the record (taken as u(T) there), which the delayed input
    never reaches. Exact for the head, first order in τ·u̇ for the tail. Undelayed inputs:
    U(ω) unchanged. Without ``spectra.input_ends`` only the first term."""
    omega = spectra.omega_rad_s
    if not np.any(system.input_delays_s):
        return spectra.inputs
    phase = system.input_phase(omega)
    # e^{−jωτ} U(ω)
    delayed = spectra.inputs * phase
    if spectra.input_ends is not None:
        start, end = spectra.input_ends
        # + (1 − e^{−jωτ})/(jω) · [u(0) − u(T) e^{−jωT}]
        ends = start[None, :] - spectra.end_phase[:, None] * end[None, :]
        delayed = delayed + (1.0 - phase) / (1j * omega[:, None]) * ends
    return delayed


def model_response(
    system: LinearSystem,
    spectra: ManeuverSpectra,
    nuisance: np.ndarray | None = None,
    *,
    boundary: bool = True,
    constants: bool = True,
) -> np.ndarray:
    """Y(ω) (K, n_y) of one maneuver; ``nuisance`` holds this maneuver's x(0), x(T), c, d in
    the order of ``nuisance_names`` (zeros when None)."""
    if not isinstance(system, LinearSystem):
        raise InputError(f"system: expected a LinearSystem, got {describe(system)}")
    if not isinstance(spectra, ManeuverSpectra):
        raise InputError(
            f"spectra: expected one maneuver's ManeuverSpectra, got {describe(spectra)}"
        )
    A, B, C, D = system.A, system.B, system.C, system.D
    n_x, n_y = A.shape[0], C.shape[0]
    merged = spectra.end_phase_constant
    count = _per_maneuver_count(
        n_x, n_y, flag(boundary, "boundary"), flag(constants, "constants"), merged
    )
    if nuisance is None:
        nuisance = np.zeros(count)
    nuisance = real_array(nuisance, "nuisance", "nuisance values")
    if nuisance.shape != (count,):
        raise InputError(
            f"nuisance: expected {count} values (nuisance_names of this maneuver), got "
            f"{describe(nuisance)}"
        )
    omega = spectra.omega_rad_s
    inputs = delayed_inputs(system, spectra)
    # right-hand side B U(ω) (K, n_x)
    rhs = inputs @ B.T
    i = 0
    if boundary and merged:
        # + (x(0) − x(T) e^{−jωT}), one constant vector
        rhs = rhs + nuisance[None, :n_x]
        i += n_x
    elif boundary:
        x_start, x_end = nuisance[i : i + n_x], nuisance[i + n_x : i + 2 * n_x]
        i += 2 * n_x
        # + x(0) − x(T) e^{−jωT}
        rhs = rhs + x_start[None, :] - spectra.end_phase[:, None] * x_end[None, :]
    if constants and not boundary:
        c = nuisance[i : i + n_x]
        i += n_x
        # + c E(ω)
        rhs = rhs + spectra.constant[:, None] * c[None, :]
    if constants:
        d = nuisance[i : i + n_y]
    # X(ω) = (jωI − A)⁻¹ rhs(ω)
    resolvent = 1j * omega[:, None, None] * np.eye(n_x)[None] - A[None]
    states = np.linalg.solve(resolvent, rhs[:, :, None])[:, :, 0]
    # Y(ω) = e^{−jωτ_y} (C X + D U) (+ d E): a delayed constant stays a constant
    y = (states @ C.T + inputs @ D.T) * system.output_phase(omega)
    if constants:
        y = y + spectra.constant[:, None] * d[None, :]
    return y


def nuisance_sensitivities(
    system: LinearSystem,
    spectra: ManeuverSpectra,
    *,
    boundary: bool = True,
    constants: bool = True,
) -> np.ndarray:
    """∂Y/∂(nuisance) (K, n_y, count) of one maneuver, in ``nuisance_names`` order:

    ∂Y/∂x(0) = Φ C G,   ∂Y/∂x(T) = −e^{−jωT} Φ C G,   ∂Y/∂c = E Φ C G,   ∂Y/∂d = E I,
    G(ω) = (jωI − A)⁻¹,  Φ(ω) = diag(e^{−jωτ_y}) (the output delays).
    """
    A, C = system.A, system.C
    n_x, n_y = A.shape[0], C.shape[0]
    omega = spectra.omega_rad_s
    resolvent = 1j * omega[:, None, None] * np.eye(n_x)[None] - A[None]
    # Φ C G(ω) (K, n_y, n_x)
    cg = system.output_phase(omega)[:, :, None] * (C[None] @ np.linalg.inv(resolvent))
    blocks = []
    if boundary and spectra.end_phase_constant:
        blocks.append(cg)
    elif boundary:
        blocks += [cg, -spectra.end_phase[:, None, None] * cg]
    if constants and not boundary:
        blocks.append(spectra.constant[:, None, None] * cg)
    if constants:
        blocks.append(spectra.constant[:, None, None] * np.eye(n_y)[None])
    if not blocks:
        return np.zeros((omega.size, n_y, 0), dtype=complex)
    return np.concatenate(blocks, axis=2)


def _real_stack(weighted: np.ndarray) -> np.ndarray:
    # (K, n_y) complex → (K, 2 n_y) real: [Re, Im] per frequency
    return np.concatenate([weighted.real, weighted.imag], axis=1)


def checked_start(
    theta_start: np.ndarray, free: np.ndarray, spectra: Sequence[ManeuverSpectra]
) -> tuple[np.ndarray, np.ndarray]:
    """θ_start as finite floats and ``free`` as a boolean mask of its shape, with at least
    one maneuver's spectra (the arguments of ``output_error`` and ``equation_error``); else
    ``InputError`` saying what came."""
    theta_start = real_array(theta_start, "theta_start", "start values (numbers)")
    if theta_start.ndim != 1 or not np.all(np.isfinite(theta_start)):
        raise InputError(
            f"theta_start: expected a 1-D array of finite start values, got {describe(theta_start)}"
        )
    free = boolean_mask(free, "free", theta_start.size)
    spectra_list(spectra)
    return theta_start, free


def checked_model_arguments(
    system_of: SystemFunction,
    theta_start: np.ndarray,
    spectra: Sequence[ManeuverSpectra],
    states: Sequence[str],
    outputs: Sequence[str],
    boundary: bool,
    constants: bool,
) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Check ``system_of`` (θ → ``LinearSystem`` of len(states) states, len(outputs) outputs
    and the spectra's inputs), the names and the two flags; the names as tuples."""
    checked_callable(system_of, "system_of")
    states, outputs = name_list(states, "states"), name_list(outputs, "outputs")
    flag(boundary, "boundary")
    flag(constants, "constants")
    system = system_of(theta_start)
    if not isinstance(system, LinearSystem):
        raise InputError(f"system_of: expected a LinearSystem for θ, got {describe(system)}")
    n_u = system.B.shape[1]
    if system.A.shape[0] != len(states) or system.C.shape[0] != len(outputs):
        raise InputError(
            f"states/outputs: the system has {system.A.shape[0]} states and "
            f"{system.C.shape[0]} outputs, the names {len(states)} and {len(outputs)}"
        )
    for s in spectra:
        if s.inputs.shape[1] != n_u or s.outputs.shape[1] != len(outputs):
            raise InputError(
                f"spectra: maneuver {s.name!r} has {s.inputs.shape[1]} inputs and "
                f"{s.outputs.shape[1]} outputs, the system {n_u} and {len(outputs)}"
            )
    return states, outputs


def check_equation_count(
    spectra: Sequence[ManeuverSpectra],
    n_free: int,
    n_states: int,
    n_outputs: int,
    *,
    boundary: bool = True,
    constants: bool = True,
) -> np.ndarray:
    """Where each maneuver's nuisance parameters start in the nuisance vector (n_m + 1
    offsets), after checking that the 2·n_y·K real equations outnumber the unknowns (free
    parameters plus nuisance); else ``InputError`` saying how many of each."""
    counts = [
        _per_maneuver_count(n_states, n_outputs, boundary, constants, s.end_phase_constant)
        for s in spectra
    ]
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(int)
    n_total_freq = sum(s.frequencies_hz.size for s in spectra)
    n_unknowns = n_free + int(starts[-1])
    if 2 * n_outputs * n_total_freq <= n_unknowns:
        raise InputError(
            f"band_hz/step_hz: {n_total_freq} frequencies give {2 * n_outputs * n_total_freq} "
            f"real equations for {n_unknowns} unknowns; widen the band or refine the step"
        )
    return starts


def output_error(
    system_of: SystemFunction,
    theta_start: np.ndarray,
    free: np.ndarray,
    spectra: Sequence[ManeuverSpectra],
    states: Sequence[str],
    outputs: Sequence[str],
    *,
    boundary: bool = True,
    constants: bool = True,
    max_noise_cycles: int = 30,
    tolerance: float = 1e-6,
    scales: np.ndarray | None = None,
) -> OutputErrorFit:
    """Estimate the free entries of θ by frequency-domain output error.

    Args:
        system_of: θ (full vector) → ``LinearSystem``.
        theta_start: start values (n_p,); fixed entries keep theta_start.
        free: boolean mask (n_p,).
        spectra: the maneuvers' transforms (``maneuver_spectra``), all on n_y outputs.
        states: state names (for the nuisance names).
        outputs: output names (for the nuisance names and messages).
        boundary: estimate x(0), x(T) per maneuver; constants: estimate the output
            constants d per maneuver (and the state constants c when boundary is False).
        max_noise_cycles: alternations of the S update and the fit.
        tolerance: relative change of J and of diag S that ends the alternation.
        scales: typical magnitudes of θ (for the difference steps); default max(|θ|, 0.01).
    """
    theta_start, free = checked_start(theta_start, free, spectra)
    states, outputs = checked_model_arguments(
        system_of, theta_start, spectra, states, outputs, boundary, constants
    )
    max_noise_cycles = positive_integer(max_noise_cycles, "max_noise_cycles")
    tolerance = finite_number(tolerance, "tolerance", positive=True)
    if tolerance >= 1.0:
        raise InputError(f"tolerance: expected a relative change in (0, 1), got {tolerance!r}")
    if scales is not None:
        scales = real_array(scales, "scales", "typical magnitudes of θ")
        if scales.shape != theta_start.shape or not np.all(np.isfinite(scales) & (scales > 0)):
            raise InputError(
                f"scales: expected {theta_start.size} finite magnitudes > 0, one per "
                f"parameter, got {describe(scales)}"
            )
    n_x, n_y = len(states), len(outputs)
    n_free = int(free.sum())
    starts = check_equation_count(spectra, n_free, n_x, n_y, boundary=boundary, constants=constants)
    n_nuisance = int(starts[-1])
    nuis_names = nuisance_names(states, outputs, spectra, boundary=boundary, constants=constants)
    scales = np.maximum(np.abs(theta_start), 0.01) if scales is None else scales

    def unpack(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        theta = theta_start.copy()
        theta[free] = p[:n_free]
        return theta, p[n_free:]

    def responses(p: np.ndarray) -> list[np.ndarray]:
        theta, nuis = unpack(p)
        system = system_of(theta)
        out = []
        for k, s in enumerate(spectra):
            out.append(
                model_response(
                    system,
                    s,
                    nuis[starts[k] : starts[k + 1]],
                    boundary=boundary,
                    constants=constants,
                )
            )
        return out

    def residual_blocks(p: np.ndarray) -> list[np.ndarray]:
        # ε(ω) = Z(ω) − Y(ω)
        return [s.outputs - y for s, y in zip(spectra, responses(p), strict=True)]

    def weighted(p: np.ndarray, factor: np.ndarray) -> np.ndarray:
        # r = [Re(Lᴴε); Im(Lᴴε)],  S⁻¹ = L Lᴴ
        blocks = [_real_stack(e @ factor.conj()) for e in residual_blocks(p)]
        return np.concatenate(blocks, axis=0).reshape(-1)

    steps = 1e-6 * scales[free]

    def jacobian(p: np.ndarray, factor: np.ndarray) -> np.ndarray:
        columns = []
        for j in range(n_free):
            h = steps[j]
            plus, minus = p.copy(), p.copy()
            plus[j] += h
            minus[j] -= h
            # ∂r/∂θ_j ≈ (r(θ + h e_j) − r(θ − h e_j)) / 2h
            columns.append((weighted(plus, factor) - weighted(minus, factor)) / (2.0 * h))
        model_part = np.column_stack(columns) if columns else np.zeros((0, 0))
        # nuisance: Y is linear in them, ∂ε/∂p = −∂Y/∂p exactly (nuisance_sensitivities)
        system = system_of(unpack(p)[0])
        nuisance_part = np.zeros((model_part.shape[0], n_nuisance))
        row = 0
        for k, s in enumerate(spectra):
            sens = nuisance_sensitivities(system, s, boundary=boundary, constants=constants)
            w = np.einsum("kyq,yz->kzq", -sens, factor.conj())
            block = np.concatenate([w.real, w.imag], axis=1).reshape(-1, sens.shape[2])
            nuisance_part[row : row + block.shape[0], starts[k] : starts[k + 1]] = block
            row += block.shape[0]
        return np.hstack([model_part, nuisance_part]) if n_free else nuisance_part

    p = np.concatenate([theta_start[free], np.zeros(n_nuisance)])
    S = np.eye(n_y, dtype=complex)
    history: list[float] = []
    evaluations: list[int] = []
    iterations = 0
    converged = False
    message = ""
    cycle = 0
    for cycle in range(1, max_noise_cycles + 1):
        # S⁻¹ = L Lᴴ; a row εᵀ becomes (Lᴴε)ᵀ = εᵀ L̄
        factor = np.linalg.cholesky(np.linalg.inv(S))
        solution = least_squares(
            lambda q, L=factor: weighted(q, L),
            p,
            jac=lambda q, L=factor: jacobian(q, L),
            method="lm",
            x_scale="jac",
            xtol=1e-12,
            ftol=1e-12,
            gtol=1e-12,
            max_nfev=200 * (p.size + 1),
        )
        iterations += int(solution.nfev)
        evaluations.append(int(solution.nfev))
        if cycle == 1:
            previous = p.copy()
        if not np.all(np.isfinite(solution.x)):
            raise EstimationError("output_error: the fit left non-finite parameter values")
        p = solution.x
        eps = np.concatenate(residual_blocks(p), axis=0)
        # S = (1/K) Σ ε εᴴ
        S_new = eps.T @ eps.conj() / eps.shape[0]
        if not np.all(np.isfinite(S_new)) or np.min(np.linalg.eigvalsh(S_new)) <= 0.0:
            raise EstimationError(
                "output_error: the residual spectral covariance S is singular (an output "
                "fitted exactly?); S diagonal = " + str(np.real(np.diag(S_new)))
            )
        cost = float(np.real(np.einsum("ki,ij,kj->", eps.conj(), np.linalg.inv(S_new), eps)))
        history.append(cost)
        change = np.max(
            np.abs(np.real(np.diag(S_new)) - np.real(np.diag(S))) / np.real(np.diag(S_new))
        )
        S = S_new
        moved = (
            np.max(np.abs(solution.x[:n_free] - previous[:n_free]) / scales[free])
            if n_free
            else 0.0
        )
        previous = solution.x.copy()
        if cycle > 1 and (change < tolerance or moved < tolerance):
            converged = True
            message = (
                f"converged in noise cycle {cycle}: S changed by {change:.2g} (relative), "
                f"the parameters by {moved:.2g} (relative to their scales)"
            )
            break
    if not converged:
        message = f"not converged: S still changing after {max_noise_cycles} noise cycles"
    factor = np.linalg.cholesky(np.linalg.inv(S))
    Jr = jacobian(p, factor)
    r = weighted(p, factor)
    if not (np.all(np.isfinite(Jr)) and np.all(np.isfinite(r))):
        raise EstimationError(
            "output_error: non-finite residuals or sensitivities at the estimate (a model "
            "pole on the band?)"
        )
    H = Jr.T @ Jr
    # scaled to unit diagonal before judging the condition: parameters differ in size
    diagonal = np.sqrt(np.diag(H))
    if np.any(diagonal == 0.0) or np.linalg.cond(H / np.outer(diagonal, diagonal)) > 1e13:
        raise EstimationError(
            "output_error: the information matrix is singular; a parameter (or nuisance "
            "parameter) is not determined by the data on this band"
        )
    # per maneuver: the rows J_k (K, 2n_y, n_free + n_nuisance) and residuals r_k (K, 2n_y)
    width = 2 * n_y
    bounds = np.concatenate([[0], np.cumsum([s.frequencies_hz.size for s in spectra])]) * width
    jac_blocks = [
        Jr[a:b].reshape(-1, width, Jr.shape[1])
        for a, b in zip(bounds[:-1], bounds[1:], strict=True)
    ]
    res_blocks = [r[a:b].reshape(-1, width) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    factors = grid_factors(spectra)
    # Cov_CR = ½ H⁻¹ [Σ_m c_m H_m] H⁻¹   (= M⁻¹ = (2H)⁻¹ on grids of step ≥ 1/T)
    cov_all = 0.5 * grid_corrected_inverse(jac_blocks, factors)
    # coloured correction: H⁻¹ [Σ_k Σ_l J_kᵀ R̂(k − l) J_l] H⁻¹, per maneuver
    cov_col_all = sandwich_covariance(jac_blocks, res_blocks)
    n_p = theta_start.size
    std_cr = np.full(n_p, np.nan)
    std_col = np.full(n_p, np.nan)
    std_cr[free] = np.sqrt(np.diag(cov_all)[:n_free])
    std_col[free] = np.sqrt(np.abs(np.diag(cov_col_all)[:n_free]))
    # the reported σ: the coloured one, never below the (grid-corrected) Cramér–Rao bound —
    # with white residuals the all-lag sandwich scatters about the bound by its sampling
    # error and, taken alone, covered the truth 83–91 % of the time (bench/sigma_coverage.py)
    std = np.fmax(std_cr, std_col)
    theta, nuis = unpack(p)
    model_outputs = tuple(responses(p))
    return OutputErrorFit(
        theta=theta,
        free=free,
        std=std,
        std_coloured=std_col,
        covariance=cov_all[:n_free, :n_free],
        covariance_coloured=cov_col_all[:n_free, :n_free],
        nuisance_names=tuple(nuis_names),
        nuisance=nuis,
        nuisance_std=np.sqrt(
            np.where(np.diag(cov_all)[n_free:] > 0, np.diag(cov_all)[n_free:], np.nan)
        ),
        S=S,
        cost=history[-1],
        noise_cycles=cycle,
        iterations=iterations,
        converged=converged,
        message=message,
        model_outputs=model_outputs,
        residuals=tuple(s.outputs - y for s, y in zip(spectra, model_outputs, strict=True)),
        cost_history=tuple(history),
        evaluation_history=tuple(evaluations),
        std_cr=std_cr,
        grid_factors=tuple(float(c) for c in factors),
    )
