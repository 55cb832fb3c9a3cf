"""``Estimate``: the frozen result of an output-error (or filter-error) estimation.

Cramér–Rao bounds [RP-1153 3.47–3.49]: with M = Σ_i G_iᵀ R⁻¹ G_i at θ̂ (sensitivities by
central differences, computed once after the optimizer stops and counted separately in
``accuracy_evaluations``), σ_CR,j = √((M⁻¹)_jj) (``std_cr``). If M is singular the
undetermined parameters get σ = inf and the status message says which; they are never
reported as NaN estimates.

The default σ (``std``) is the one the residuals support (``flightid.coloured``):
the Cramér–Rao bound when the residuals are white, the coloured-residual σ when they are
autocorrelated — there the Cramér–Rao bound, which assumes white residuals, understates the
uncertainty (by 1.5–5× on flight data). ``std_kind`` says which one ``std`` is.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from flightid.coloured import COLOURED, CRAMER_RAO, complete_default_sigma, sigma_ratio
from flightid.errors import InputError
from flightid.model.parameters import Parameters
from flightid.model.statespace import StateSpaceModel
from flightid.results import (
    ResultSurface,
    check_method,
    contour_level,
    ellipsoid_intervals,
    render_summary,
    residual_variance_factor,
)

__all__ = ["Estimate"]


@dataclass(frozen=True, eq=False)
class Estimate(ResultSurface):
    """Result of ``estimate``. All arrays are read-only.

    The result surface (``flightid.results``): ``summary()``, ``to_dict()`` / ``to_json()``,
    ``to_frame()`` (pandas), ``conf_int(level, method="cr")`` and ``plot()``. Units: each
    parameter's ``Parameter.unit`` (``parameter_units``) and the outputs' units
    (``output_units``, from the data's channel units when known) appear in all of them.

    Attributes:
        names: parameter names (full vector, free and fixed).
        values: estimated values (fixed ones unchanged).
        initial: start values.
        free: mask of the estimated parameters.
        std: the default σ (1σ): ``std_cr`` when the residuals are white, the
            coloured-residual σ when they are not (``std_kind``); NaN for fixed parameters,
            inf where undetermined.
        std_cr: Cramér–Rao bounds √((M⁻¹)_jj), whatever the residuals.
        std_kind: ``"cramer_rao"`` or ``"coloured"``: which σ ``std`` is.
        residuals_white: every output's residual autocorrelation at lag 1 inside the
            white-noise band ±1.96/√N (then ``std`` = ``std_cr``); None when not tested.
        coloured_lag: lag L of the coloured-residual correction (samples; 0 when white).
        covariance: M⁻¹ over the free parameters (n_f × n_f), the Cramér–Rao covariance.
        covariance_default: the covariance behind ``std`` (n_f × n_f): ``covariance`` when
            the residuals are white, the coloured-residual sandwich otherwise.
        information_matrix: M at θ̂ (n_f × n_f).
        sensitivities: G at θ̂, (N, n_o, n_f).
        r_diag: noise variances R used at the end (n_o,).
        cost: J(θ̂) = Σ νᵀR⁻¹ν under ``r_diag``.
        cost_history: J after the start and each accepted pass, each under the R in force at
            that pass (``r_history``): the cost at fixed R, before any R update that follows
            the pass. Under the MAX / MAXLIK policies it drops within a stretch under one R
            and jumps at an R update; ``cost`` at the end, under the final R̂, is about N·n_o
            (J at R = R̂ is Σ_k N R̂_k/R̂_k), so neither judges convergence across updates.
        log_det_r_history: ln det R̂ = Σ_k ln R̂_kk at each entry of ``cost_history``, R̂ the
            covariance of that pass's residuals (innovations) [3.45]: the negative
            log-likelihood under an estimated R up to constants, the quantity that falls
            to its minimum as the estimate converges whatever R weights J (no jumps at R
            updates); NaN where a pass's residuals were not at hand, empty where the
            estimator does not record it (the filter error's reference schedule). The last
            entry equals ``log_det_r`` when R was re-estimated at the end point.
        r_history: the noise variances R (n_o,) each entry of ``cost_history`` is computed
            under.
        evaluation_history: equivalent evaluations spent at those points.
        equivalent_evaluations: system integrations used by the optimizer (incl. R cycles
            and the confirming passes): ``evaluations_to_optimum`` +
            ``confirmation_evaluations``.
        accuracy_evaluations: integrations for the final information matrix (the
            sensitivities at θ̂ that give the Cramér–Rao bounds and judge the confirmation).
        evaluations_to_optimum: integrations spent until the path first reached the optimum:
            the first recorded point θ_k (the start or an accepted pass) whose cost excess
            over the final cost, predicted under the final R by the quadratic model at θ̂,
            (θ_k − θ̂)ᵀM(θ_k − θ̂), is within the cost tolerance cost_rtol·J(θ̂) + cost_atol
            (``flightid.estimation.driver.evaluations_to_optimum``); None where the
            estimator does not record it.
        confirmation_evaluations: the optimizer's integrations after that point: the
            solver's own convergence checks and the confirming passes (None with
            ``evaluations_to_optimum``).
        iterations: passes (all noise cycles).
        noise_cycles: R re-estimations.
        noise_update_passes: for each R re-estimation, the index in ``cost_history`` of the
            first cost under the new R (the costs before it were computed under the old R;
            an index equal to ``len(cost_history)`` means no pass followed the update).
        converged, status, message: outcome (status: converged | max_iterations |
            max_evaluations | stalled).
        time, measured, predicted, residuals: (N,), (N, n_o) over all maneuvers.
        maneuver_index: (N,) maneuver number of each sample.
        output_names: the outputs.
        solver, solver_settings, noise_policy, method: what ran.
        wall_time_s: seconds.
        model: the model with the estimated values.
        output_units: unit of each output (``""`` where unknown; ``()`` when not given).
        optimality_sigma: √(ΔθᵀMΔθ) of the Gauss–Newton step from central differences at
            θ̂: how far (in Cramér–Rao σ) the linearised model puts the optimum; a converged
            estimate has it ≤ ``Convergence.confirm_sigma``.
        at_bound: free parameters that ended on a bound (their std is NaN).
        solved: free parameters whose value is solved from a constraint rather than
            estimated freely (the filter error method's process-noise elements solved from
            diag(KC)_i = 1); listed as "solved" in summaries, reports and estimates.csv.
        weights: the samples' weights (N, n_o) in the cost, or None when all are 1; with
            weights, ``residuals`` and ``sensitivities`` are √w·(z − y) and √w·∂y/∂θ, and a
            weight of 0 leaves the measurement out of ``n_data``.
    """

    names: tuple[str, ...]
    values: np.ndarray
    initial: np.ndarray
    free: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    information_matrix: np.ndarray
    sensitivities: np.ndarray
    r_diag: np.ndarray
    cost: float
    cost_history: tuple[float, ...]
    evaluation_history: tuple[int, ...]
    equivalent_evaluations: int
    accuracy_evaluations: int
    iterations: int
    noise_cycles: int
    converged: bool
    status: str
    message: str
    time: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    residuals: np.ndarray
    maneuver_index: np.ndarray
    output_names: tuple[str, ...]
    solver: str
    solver_settings: dict
    noise_policy: str
    method: str
    wall_time_s: float
    model: StateSpaceModel = field(repr=False)
    output_units: tuple[str, ...] = ()
    optimality_sigma: float = float("nan")
    input_interpolation: str = "linear"
    at_bound: tuple[str, ...] = ()
    noise_update_passes: tuple[int, ...] = ()
    weights: np.ndarray | None = None
    std_cr: np.ndarray | None = None
    covariance_default: np.ndarray | None = None
    std_kind: str = CRAMER_RAO
    residuals_white: bool | None = None
    coloured_lag: int = 0
    solved: tuple[str, ...] = ()
    log_det_r_history: tuple[float, ...] = ()
    r_history: tuple[tuple[float, ...], ...] = ()
    evaluations_to_optimum: int | None = None
    confirmation_evaluations: int | None = None

    def __post_init__(self) -> None:
        # without a separate default σ, the default is the Cramér–Rao σ
        complete_default_sigma(self, InputError)
        for name in (
            "values",
            "initial",
            "free",
            "std",
            "std_cr",
            "covariance",
            "covariance_default",
            "information_matrix",
            "sensitivities",
            "r_diag",
            "time",
            "measured",
            "predicted",
            "residuals",
            "maneuver_index",
        ):
            value = getattr(self, name)
            if isinstance(value, np.ndarray) and not value.flags.writeable:
                # already read-only (``estimate`` hands over its G so): kept, not copied — at
                # N = 10⁵ a copy of G would double the estimate's memory
                array = value
            else:
                array = np.array(value)
                array.flags.writeable = False
            object.__setattr__(self, name, array)
        if self.weights is not None:
            weights = np.array(self.weights, dtype=float)
            weights.flags.writeable = False
            object.__setattr__(self, "weights", weights)

    # ------------------------------------------------------------------ derived
    @property
    def free_names(self) -> list[str]:
        return [n for n, f in zip(self.names, self.free, strict=True) if f]

    @property
    def estimator(self) -> str:
        """``"filter_error"`` or ``"output_error"`` (the case key ``estimation.estimator``),
        told by the noise policy (``"filter_error/<relaxation>"`` for the filter error
        method)."""
        return "filter_error" if self.noise_policy.startswith("filter_error") else "output_error"

    @property
    def log_det_r(self) -> float:
        """ln det R = Σ_k ln R_kk of the final noise variances ``r_diag``."""
        return float(np.sum(np.log(self.r_diag)))

    def role(self, name: str) -> str:
        """How parameter ``name`` got its value: ``"fixed"``, ``"free"`` (estimated),
        ``"solved"`` (from a constraint: ``solved``) or ``"at_bound"`` (estimated, ended on
        a bound)."""
        if name in self.solved:
            return "solved"
        if name in self.at_bound:
            return "at_bound"
        return "free" if self.free[self.names.index(name)] else "fixed"

    @property
    def total_evaluations(self) -> int:
        """All integrations of the estimation: the optimizer's and the bounds'."""
        return int(self.equivalent_evaluations) + int(self.accuracy_evaluations)

    def evaluations_text(self) -> str:
        """The equivalent evaluations in words, split where the split is known: "32: 13 to
        the optimum, 7 confirming it, 12 for the information matrix"."""
        if self.evaluations_to_optimum is None or self.confirmation_evaluations is None:
            return (
                f"{self.equivalent_evaluations} (+{self.accuracy_evaluations} for the "
                "information matrix)"
            )
        return (
            f"{self.total_evaluations}: {self.evaluations_to_optimum} to the optimum, "
            f"{self.confirmation_evaluations} confirming it, {self.accuracy_evaluations} for "
            "the information matrix"
        )

    @property
    def parameters(self) -> Parameters:
        """The model's parameters with the estimated values."""
        return self.model.parameters

    @cached_property
    def correlation(self) -> np.ndarray:
        """Correlation matrix of the free estimates, from the covariance."""
        sigma = np.sqrt(np.diag(self.covariance))
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = self.covariance / np.outer(sigma, sigma)
        corr[~np.isfinite(corr)] = np.nan
        return corr

    @property
    def sigma_ratio(self) -> np.ndarray:
        """std / std_cr of the free parameters (n_f,): how much the Cramér–Rao bounds
        understate the default σ (1 for white residuals; NaN where either is not finite)."""
        free = np.asarray(self.free, dtype=bool)
        return sigma_ratio(np.asarray(self.std)[free], np.asarray(self.std_cr)[free])

    @property
    def n_data(self) -> int:
        """N·n_o, the number of scalar measurements (less those of weight 0)."""
        if self.weights is None:
            return int(self.measured.size)
        return int(np.count_nonzero(self.weights))

    @property
    def parameter_units(self) -> tuple[str, ...]:
        """Unit of each parameter in ``names`` (its ``Parameter.unit``; ``""`` if none)."""
        parameters = self.model.parameters
        return tuple(parameters[n].unit if n in parameters else "" for n in self.names)

    @property
    def output_unit_map(self) -> dict[str, str]:
        """{output name: unit}; ``""`` where the unit is not known."""
        units = tuple(self.output_units) or ("",) * len(self.output_names)
        return dict(zip(self.output_names, units, strict=True))

    @property
    def conf_int_names(self) -> list[str]:
        """The rows of ``conf_int``: the free parameters, in order."""
        return self.free_names

    def conf_int(
        self,
        level: float = 0.95,
        method: str = "cr",
        *,
        kind: str = "individual",
        distribution: str = "t",
        std: str = "default",
    ) -> np.ndarray:
        """Confidence intervals of the free parameters from the default σ or the CR bounds.

        The quadratic approximation of the likelihood region (``flightid.accuracy``, the
        functions ``residual_variance_factor``, ``contour_level`` and ``ellipsoid_intervals``
        — the same as ``AccuracyResult.ci_cr``, here at the estimate's own J(θ̂), without
        the polish of ``assess``):

            s² = J(θ̂)/(N·n_o − n_p)                                          [5.30]
            individual:   Δ = s² t²_{(1+c)/2}(N·n_o − n_p)  (Student t) or s² χ²_c(1)
            simultaneous: Δ = n_p s² F_c(n_p, N·n_o − n_p)  or s² χ²_c(n_p)   [5.20–5.25]
            interval_j = θ̂_j ± √(Δ·(M⁻¹)_jj)                                  [5.24–5.27]

        With coloured residuals the default (``std="default"``) replaces s²M⁻¹ by the
        coloured-residual covariance C_col, which carries the residual level itself:
        interval_j = θ̂_j ± √((Δ/s²)·C_col,jj) — θ̂_j ± t·σ_j for individual intervals, the
        same as ``AccuracyResult.ci_cr_coloured``.

        Args:
            level: confidence level c, e.g. 0.95.
            method: ``"cr"`` (the only one an estimate holds; ``flightid.accuracy.assess``
                gives coloured-residual, Beale, profile and search limits).
            kind: ``"individual"`` or ``"simultaneous"``.
            distribution: ``"t"`` (Student t / F quantiles with N·n_o − n_p degrees of
                freedom, default) or ``"normal"`` (χ², the large-sample limit).
            std: ``"default"`` (the σ in ``std``: coloured-residual when the residuals are
                coloured) or ``"cr"`` (the Cramér–Rao bounds, ``std_cr``).

        Returns:
            (n_f, 2) array [lower, upper] in the parameters' units, rows as in
            ``conf_int_names``; an undetermined parameter (σ = inf) gets (-inf, inf).
        """
        check_method(method, ("cr",))
        check_method(std, ("default", "cr"), "std")
        n_free = len(self.free_names)
        s2 = residual_variance_factor(self.cost, self.n_data, n_free)
        delta = contour_level(level, self.n_data, n_free, s2, kind, distribution)
        center = np.asarray(self.values, dtype=float)[np.asarray(self.free, dtype=bool)]
        if std == "default" and self.std_kind == COLOURED:
            # the coloured covariance carries the residual level itself: level Δ / s²
            return ellipsoid_intervals(center, self.covariance_default, delta / s2)
        return ellipsoid_intervals(center, self.covariance, delta)

    def _frame_rows(self) -> list[dict]:
        # the default intervals (95 %, individual, t); none without residual dof
        enough = self.n_data > len(self.free_names)
        intervals = dict(zip(self.free_names, self.conf_int(), strict=True)) if enough else {}
        rows = []
        for i, name in enumerate(self.names):
            free = bool(self.free[i])
            lower, upper = intervals.get(name, (np.nan, np.nan))
            rows.append(
                {
                    "name": name,
                    "value": float(self.values[i]),
                    "std": float(self.std[i]) if free else np.nan,
                    "std_cr": float(self.std_cr[i]) if free else np.nan,
                    "lower": float(lower),
                    "upper": float(upper),
                    "initial": float(self.initial[i]),
                    "free": free,
                    "unit": self.parameter_units[i],
                }
            )
        return rows

    def value(self, name: str) -> float:
        return float(self.values[self.names.index(name)])

    def stddev(self, name: str, std: str = "default") -> float:
        """σ of the parameter ``name``: the default σ (``std="default"``) or the Cramér–Rao
        bound (``std="cr"``)."""
        check_method(std, ("default", "cr"), "std")
        sigma = self.std if std == "default" else self.std_cr
        return float(sigma[self.names.index(name)])

    def fit_error(self) -> np.ndarray:
        """RMS residual per output, in the outputs' units."""
        return np.sqrt(np.mean(self.residuals**2, axis=0))

    # ------------------------------------------------------------------ the model in use
    def _covariance_for(self, std: str) -> np.ndarray:
        """The covariance of the free estimates behind ``std`` ("default" or "cr")."""
        check_method(std, ("default", "cr"), "std")
        return self.covariance_default if std == "default" else self.covariance

    def predict(self, data, x0=None, *, bands: bool = False, std: str = "default"):
        """The estimated model on other data: outputs, residuals and fit numbers (RMS error
        and R² per output), as the prediction check of a case reports them
        (``flightid.simulation.prediction``).

        Args:
            data: a ``FlightData`` (returns one ``Prediction``) or a list of them (returns a
                tuple, one per maneuver), with the model's inputs and outputs.
            x0: initial states: one value per state or ``{state: value}`` (or a list, one per
                maneuver); states not given start at the first sample of the data's channel
                of that name, else at the model's initial state.
            bands: also give ``Prediction.predicted_std``, σ of the outputs from the
                parameter covariance (delta method; ``Prediction.band(level)``).
            std: which covariance: ``"default"`` (the one behind ``std``) or ``"cr"``.
        """
        from flightid.simulation.prediction import predict_result

        return predict_result(
            self.model,
            data,
            x0,
            bands=bands,
            covariance=self._covariance_for(std) if bands else None,
            method=self.method,
            input_interpolation=self.input_interpolation,
        )

    def simulate(self, inputs, x0=None) -> np.ndarray:
        """Outputs (N_total, n_o) of the estimated model driven by the inputs of ``inputs``
        (a ``FlightData`` or a list; outputs are not needed), from the initial states ``x0``
        (as in ``predict``), with the estimation's integration and input interpolation."""
        from flightid.simulation.prediction import simulate_result

        return simulate_result(
            self.model,
            inputs,
            x0,
            method=self.method,
            input_interpolation=self.input_interpolation,
        )

    def linearize(self, at=None, *, std: str = "default"):
        """The estimated model linearized about an operating point, with the covariance of
        A, B, C, D from the parameter covariance (``flightid.model.linearization``).

        Args:
            at: the operating point: ``None`` — the initial state of the first estimation
                maneuver and all inputs 0 (exact for a model linear in x and u; for a
                nonlinear one give the point); a ``FlightData`` — the initial state of that
                maneuver (as ``predict`` starts it) and the mean of each input over it;
                or ``(x, u)`` — values per state and per input (sequences or mappings).
            std: which covariance: ``"default"`` or ``"cr"``. Where it is not finite (an
                undetermined parameter) the entries have no σ and ``notes`` says why.

        Returns:
            A ``LinearModel`` (``modes()``, ``to_scipy()``, ``to_control()``).
        """
        from flightid.simulation.prediction import linearize_result

        return linearize_result(
            self.model, at, covariance=self._covariance_for(std), units=self.output_unit_map
        )

    # ------------------------------------------------------------------ reports
    def summary(self) -> str:
        """A readable table of the estimates with their default σ (and the Cramér–Rao
        bounds beside it when the residuals are coloured)."""
        return render_summary(self)

    def to_dict(self) -> dict:
        """The JSON contract: method, converged, status, cost, iterations, evaluations, ..."""
        parameters = []
        for i, name in enumerate(self.names):
            std, std_cr = float(self.std[i]), float(self.std_cr[i])
            parameters.append(
                {
                    "name": name,
                    "value": float(self.values[i]),
                    "initial": float(self.initial[i]),
                    "std": std if (self.free[i] and np.isfinite(std)) else None,
                    "std_cr": std_cr if (self.free[i] and np.isfinite(std_cr)) else None,
                    "free": bool(self.free[i]),
                    "role": self.role(name),
                    "unit": self.parameter_units[i],
                }
            )
        return {
            "estimator": self.estimator,
            "method": self.solver,
            "converged": bool(self.converged),
            "status": self.status,
            "message": self.message,
            "cost": float(self.cost),
            "iterations": int(self.iterations),
            "equivalent_evaluations": int(self.equivalent_evaluations),
            "accuracy_evaluations": int(self.accuracy_evaluations),
            "evaluations_to_optimum": None
            if self.evaluations_to_optimum is None
            else int(self.evaluations_to_optimum),
            "confirmation_evaluations": None
            if self.confirmation_evaluations is None
            else int(self.confirmation_evaluations),
            "noise_cycles": int(self.noise_cycles),
            "noise_policy": self.noise_policy,
            "integration": self.method,
            "input_interpolation": self.input_interpolation,
            "wall_time_s": float(self.wall_time_s),
            "solver_settings": dict(self.solver_settings),
            "R": [float(r) for r in self.r_diag],
            "outputs": list(self.output_names),
            "output_units": list(self.output_unit_map.values()),
            "fit_rms": [float(e) for e in self.fit_error()],
            "optimality_sigma": float(self.optimality_sigma)
            if np.isfinite(self.optimality_sigma)
            else None,
            "at_bound": list(self.at_bound),
            "solved": list(self.solved),
            "std_kind": self.std_kind,
            "residuals_white": None if self.residuals_white is None else bool(self.residuals_white),
            "coloured_lag": int(self.coloured_lag),
            "cost_history": [float(c) for c in self.cost_history],
            "evaluation_history": [int(e) for e in self.evaluation_history],
            "noise_update_passes": [int(p) for p in self.noise_update_passes],
            "log_det_r": self.log_det_r,
            "log_det_r_history": [float(v) for v in self.log_det_r_history],
            "r_history": [[float(v) for v in r] for r in self.r_history],
            "parameters": parameters,
        }

    def to_json(self, indent: int | None = 2) -> str:
        """Strict JSON of ``to_dict()``: a non-finite number becomes null, listed under
        ``"nonfinite"`` (``flightid.jsonout``)."""
        from flightid.jsonout import dumps

        return dumps(self.to_dict(), indent=indent)

    def __repr__(self) -> str:
        return (
            f"Estimate({self.solver}, {self.status}, cost={self.cost:.6g}, "
            f"evaluations={self.equivalent_evaluations}, iterations={self.iterations})"
        )
