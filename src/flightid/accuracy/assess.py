"""``assess(estimate, data)``: the one entry point of the accuracy analysis.

Given an ``Estimate`` and the data it came from, ``assess`` rebuilds the output-error problem
from ``estimate.model`` (which carries the estimated values and the free/fixed pattern), holds
R at the estimate's ``r_diag`` and reports, for every free parameter:

* ``cr`` (always): intervals from the information matrix — ellipsoid projections at the
  chosen level, individual and simultaneous [5.24–5.27]; the coloured-residual correction;
  the Beale-corrected level [5.28]; the correlation matrix with warnings;
* Beale's nonlinearity measure N_φ (always; 2·n_p + 1 integrations);
* ``profile``: profile-likelihood limits (Gauss–Newton, ``profile``);
* ``search``: random-search limits (Mereau & Raymond, ``search``), seeded, within ``budget``.

Typical use::

    result = estimate(model, data, MNRES())
    accuracy = assess(result, data, level=0.95, methods=("cr", "profile"))
    print(accuracy.summary())
    document = accuracy_json(result, accuracy)
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from flightid.accuracy.coloured import coloured_covariance
from flightid.accuracy.contour import Contour, polish_minimum
from flightid.accuracy.intervals import correlation_matrix, correlation_warnings, emit
from flightid.accuracy.nonlinearity import beale_nonlinearity
from flightid.accuracy.result import AccuracyResult
from flightid.data.flightdata import FlightData
from flightid.errors import InputError, InputTypeError, describe
from flightid.estimation.problem import OutputErrorProblem
from flightid.estimation.result import Estimate
from flightid.results import (
    DISTRIBUTIONS,
    KINDS,
    check_level,
    contour_level,
    ellipsoid_intervals,
    residual_variance_factor,
)

__all__ = ["METHODS", "assess", "problem_for", "region_contour"]

METHODS = ("cr", "profile", "search")


def _methods(methods: str | Iterable[str]) -> tuple[str, ...]:
    if isinstance(methods, str):
        methods = (methods,)
    chosen = set()
    for name in methods:
        if name == "all":
            chosen.update(METHODS)
        elif name in METHODS:
            chosen.add(name)
        else:
            raise InputError(f"methods: expected names from {METHODS} or 'all', got {name!r}")
    chosen.add("cr")
    if "search" in chosen:
        # the profile costs a small fraction of the search and is its reference
        chosen.add("profile")
    return tuple(m for m in METHODS if m in chosen)


def problem_for(
    estimate: Estimate,
    data: FlightData | Sequence[FlightData] | OutputErrorProblem,
    compiled: bool = True,
) -> OutputErrorProblem:
    """The output-error problem of ``estimate`` on ``data`` (same model, integration method,
    input interpolation, sample weights)."""
    if isinstance(data, OutputErrorProblem):
        problem = data
    else:
        problem = OutputErrorProblem(
            estimate.model,
            data,
            method=estimate.method,
            compiled=compiled,
            input_interpolation=estimate.input_interpolation,
        )
    weights = getattr(estimate, "weights", None)
    if weights is not None and problem.weights is None:
        # the region of the weighted cost the estimate minimised (excluded samples stay out)
        problem.set_weights(weights)
    expected = list(estimate.free_names)
    if list(problem.free_names) != expected:
        raise InputError(
            f"data: the problem's free parameters {list(problem.free_names)} differ from the "
            f"estimate's {expected}"
        )
    if problem.measured.shape != estimate.measured.shape:
        raise InputError(
            f"data: expected the {estimate.measured.shape[0]} samples × "
            f"{estimate.measured.shape[1]} outputs the estimate was made from, got "
            f"{problem.measured.shape}"
        )
    return problem


def _profile_subset(parameters: Sequence[str] | None, names: tuple[str, ...]) -> list[int] | None:
    """Indices (among the free parameters) of the ``parameters`` to profile; None for all."""
    if parameters is None:
        return None
    unknown = [p for p in parameters if p not in names]
    if unknown:
        raise InputError(f"parameters: {unknown} are not free parameters; free: {list(names)}")
    return [names.index(p) for p in parameters]


def _profile_messages(profile, names: tuple[str, ...]) -> list[str]:
    """One message per profile limit that did not end on the contour."""
    messages = []
    for j, (lower, upper) in enumerate(profile.statuses):
        for side, status in (("lower", lower), ("upper", upper)):
            if status in ("open", "max_iterations", "failed"):
                messages.append(
                    f"profile {side} limit of {names[j]}: {status}"
                    + (" (the region does not close on this side)" if status == "open" else "")
                )
    return messages


def assess(
    estimate: Estimate,
    data: FlightData | Sequence[FlightData] | OutputErrorProblem,
    *,
    level: float = 0.95,
    methods: str | Iterable[str] = ("cr", "profile"),
    kind: str = "individual",
    distribution: str = "t",
    seed: int = 0,
    budget: int = 50_000,
    perturbation: float = 1.0,
    max_lag: int | str = "auto",
    beale_corrected: bool = False,
    polish: bool = True,
    progress: bool | None = None,
    compiled: bool = True,
    warn: bool = True,
    parameters: Sequence[str] | None = None,
    engine: Any = None,
) -> AccuracyResult:
    """Accuracy of ``estimate``: Cramér–Rao, coloured-residual, Beale, profile, search.

    Args:
        estimate: the result of ``flightid.estimation.estimate``.
        data: the data it was estimated from (``FlightData`` or list of maneuvers), or an
            ``OutputErrorProblem`` already built on them with ``estimate.model``.
        level: confidence level 1 − α.
        methods: any of ``"cr"``, ``"profile"``, ``"search"`` or ``"all"`` (``"cr"`` and N_φ
            are always computed; ``"search"`` brings ``"profile"`` with it).
        kind: ``"individual"`` (one parameter at a time, default) or ``"simultaneous"`` (the
            paper's joint region, k = n_p F_α(n_p, N n_o − n_p)); applies to ``ci_cr``, profile
            and search alike.
        distribution: ``"t"`` (F quantiles, the paper's) or ``"normal"`` (χ² quantiles).
        seed: random-search seed.
        budget: random-search budget, equivalent evaluations.
        perturbation: Beale points at θ̂ ± perturbation·s·σ_j (default one standard error).
        max_lag: coloured-residual correction lag, ``"auto"`` or samples.
        beale_corrected: trace profile and search at the Beale-corrected level Δ_B.
        polish: refine the minimum with Gauss–Newton passes at fixed R before tracing the
            region (recommended: the estimation's 10⁻³ tests leave J above its minimum).
        progress: progress bar on stderr for the search (None: when stderr is a terminal).
        compiled: numba kernels for the rebuilt problem.
        warn: issue the warnings as ``AccuracyWarning`` (they are in the result either way).
        parameters: free-parameter names whose profile limits to compute (default all; the
            others get NaN profile intervals). The search always covers all.
        engine: a ``flightid.batch`` engine (``flightid.batch.make_engine(workers,
            scheduler)``) on which the profile (one task per parameter) and the search (its
            chunks and refinement tasks) run; None: in this process. The numbers do not
            depend on it. The caller closes it.

    Returns:
        ``AccuracyResult``.
    """
    if not isinstance(estimate, Estimate):
        raise InputTypeError(f"estimate: expected an Estimate, got {describe(estimate)}")
    level = check_level(level)
    chosen = _methods(methods)
    if kind not in KINDS:
        raise InputError(f"kind: expected one of {KINDS}, got {kind!r}")
    if distribution not in DISTRIBUTIONS:
        raise InputError(f"distribution: expected one of {DISTRIBUTIONS}, got {distribution!r}")
    if int(budget) < 1:
        raise InputError(f"budget: expected a positive number of evaluations, got {budget!r}")
    names = tuple(estimate.free_names)
    subset = _profile_subset(parameters, names)
    problem = problem_for(estimate, data, compiled=compiled)
    n_free = len(names)
    n_data = int(estimate.n_data)
    r_diag = np.asarray(estimate.r_diag, dtype=float)
    center = np.asarray(estimate.values, dtype=float)[np.asarray(estimate.free)]
    covariance = np.array(estimate.covariance, dtype=float)
    std = np.sqrt(np.abs(np.diag(covariance)))
    messages: list[str] = []
    evaluations: dict[str, int] = {}

    # ---- the minimum the region is measured from
    if polish:
        theta_min, cost_min, outputs_min, spent = polish_minimum(problem, r_diag, center)
        evaluations["polish"] = spent
    else:
        outputs_min = problem.outputs(center[None, :])[0]
        theta_min, cost_min = center.copy(), float(problem.cost(outputs_min, r_diag))
        evaluations["polish"] = 1

    # ---- levels [5.20–5.30]
    s2 = residual_variance_factor(cost_min, n_data, n_free)
    delta = contour_level(level, n_data, n_free, s2, kind, distribution)
    delta_simultaneous = contour_level(level, n_data, n_free, s2, "simultaneous", distribution)

    # ---- Beale's N_φ [5.31–5.43]
    # standard errors s·σ_j: the perturbation unit of the Beale points (σ_j alone is not one
    # when R is not the residual estimate, e.g. R = I)
    std_scaled = np.sqrt(s2) * std
    nonlinearity = beale_nonlinearity(
        problem, center, estimate.sensitivities, r_diag, std_scaled, s2, perturbation
    )
    evaluations["beale"] = nonlinearity.evaluations
    factor = nonlinearity.beale_factor if np.isfinite(nonlinearity.beale_factor) else 1.0
    # Δ_B = Δ · [1 + N n_o (n_p + 2)/((N n_o − n_p) n_p) N_φ]            [5.28–5.29]
    delta_beale = delta * factor

    # ---- intervals from the information matrix [5.24–5.27]
    ci_cr = ellipsoid_intervals(center, covariance, delta)
    ci_simultaneous = ellipsoid_intervals(center, covariance, delta_simultaneous)
    ci_beale = ellipsoid_intervals(center, covariance, delta_beale)
    covariance_coloured, lag = coloured_covariance(
        estimate.sensitivities,
        estimate.residuals,
        r_diag,
        covariance,
        max_lag=max_lag,
        maneuver_index=estimate.maneuver_index,
    )
    # R̂_ν(0) divides by N; scale by N·n_o/(N·n_o − n_p) as s² [5.30] does for the plain bound
    covariance_coloured = covariance_coloured * (n_data / (n_data - n_free))
    std_coloured = np.sqrt(np.abs(np.diag(covariance_coloured)))
    # the coloured covariance carries the residual level itself, so its level is Δ / s²
    ci_coloured = ellipsoid_intervals(center, covariance_coloured, delta / s2)
    correlation = correlation_matrix(covariance)
    messages += correlation_warnings(list(names), covariance)

    # ---- the likelihood region
    trace_level = delta_beale if beale_corrected else delta
    contour = Contour(problem, r_diag, theta_min, cost_min, trace_level, outputs_min)
    profile = search = None
    # the profile and the search are imported where they run: a Cramér–Rao-only assessment
    # (the default) does not load them
    if "profile" in chosen:
        from flightid.accuracy.profile import profile_limits

        before = contour.evaluations
        profile = profile_limits(contour, covariance, parameters=subset, engine=engine)
        evaluations["profile"] = contour.evaluations - before
        messages += _profile_messages(profile, names)
    if "search" in chosen:
        from flightid.accuracy.search import random_search

        before = contour.evaluations
        search = random_search(
            contour,
            covariance,
            budget=int(budget),
            seed=seed,
            progress=progress,
            engine=engine,
        )
        evaluations["search"] = contour.evaluations - before
        if not search.settled.all():
            messages.append(
                f"random search: the budget of {budget} evaluations ran out before "
                f"{int((~search.settled).sum())} of {search.settled.size} extremes settled; "
                "its limits are inner bounds"
            )
    if contour.lowest_excess < -1e-6 * max(contour.delta, 1.0):
        messages.append(
            f"a point with J {-contour.lowest_excess:.3g} below J(θ̂) was met: the estimate is "
            "not at the minimum of J; re-estimate with tighter convergence"
        )
    if warn:
        emit(messages, stacklevel=3)
    return AccuracyResult(
        names=names,
        level=level,
        kind=kind,
        distribution=distribution,
        center=center,
        theta_min=theta_min,
        cost_min=float(cost_min),
        s2=float(s2),
        n_data=n_data,
        n_free=n_free,
        delta=float(delta),
        delta_beale=float(delta_beale),
        std=std,
        std_scaled=std_scaled,
        std_coloured=std_coloured,
        coloured_lag=int(lag),
        covariance=covariance,
        covariance_coloured=covariance_coloured,
        correlation=correlation,
        ci_cr=ci_cr,
        ci_cr_simultaneous=ci_simultaneous,
        ci_cr_coloured=ci_coloured,
        ci_cr_beale=ci_beale,
        nonlinearity=nonlinearity,
        profile=profile,
        search=search,
        evaluations=evaluations,
        warnings=tuple(messages),
        units=tuple(u for u, f in zip(estimate.parameter_units, estimate.free, strict=True) if f),
    )


def region_contour(
    estimate: Estimate,
    data: FlightData | Sequence[FlightData] | OutputErrorProblem,
    accuracy: AccuracyResult,
    beale_corrected: bool = False,
) -> Contour:
    """The ``Contour`` an ``AccuracyResult`` was traced on (for profiles and slices)."""
    problem = problem_for(estimate, data)
    delta = accuracy.delta_beale if beale_corrected else accuracy.delta
    return Contour(problem, estimate.r_diag, accuracy.theta_min, accuracy.cost_min, delta)
