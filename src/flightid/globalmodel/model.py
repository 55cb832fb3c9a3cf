"""Global aerodynamic models: per-coefficient results, predictions with intervals and support.

A ``GlobalModel`` holds one ``CoefficientModel`` per modelled coefficient over the same
explanatory variables. ``predict(points)`` gives, for every coefficient and point x₀ with
regressors φ₀ (the selected terms at x₀):

    ŷ₀         = φ₀ᵀ θ̂
    Var_mean   = φ₀ᵀ C φ₀                C = the coloured-residual covariance of θ̂
                                        (``LeastSquaresResult.covariance_default``)
    σ²_e(x₀)   = s² (``"global"``) or, for ``"local"``, the mean squared residual of the
                 local_k fitted samples nearest to x₀ (support coordinates) × N/(N − n_p)
    interval   = ŷ₀ ± t_{dof,(1+c)/2} · sqrt(Var_mean + σ²_e(x₀))   (a new observation)

and the interval of the coefficient itself, what a simulator or a control law needs (the
function interval: model error counts, measurement noise does not):

    σ²_model     = max(s² − σ²_noise, 0)                        (``"global"``)
    σ²_model(x₀) = max(σ²_e(x₀) − σ²_noise(x₀), σ²_model)       (``"local"``)
    function     = ŷ₀ ± t_{dof,(1+c)/2} · sqrt(Var_mean + min(σ²_model(x₀), σ²_e(x₀)))

with, for ``"local"``, σ²_noise(x₀) the mean half squared difference (below) of the same
local_k nearest samples as σ²_e(x₀): the noise of reconstructed coefficients changes over
the envelope with the dynamic pressure. The local difference rests on local_k samples only
and is noisy where the noise dominates the model error, so it widens the interval where
the model error is locally larger than its average σ²_model and never narrows it below.

σ²_noise, the measurement-noise variance, comes from the residuals' sample-to-sample
differences within each maneuver on every sample (before decimation), model free: for white
noise Var(Δr) = 2σ², while model error varies slowly along a trajectory and cancels in the
differences (``flightid.globalmodel.fit.difference_noise_variance``). Noise coloured at the
sample rate gives a low σ²_noise and so a wider function interval (conservative).
s² and σ²_noise for σ²_model are both taken over every sample (the selected model's residuals
before decimation; without decimation this s² is the fit's). The model error counts only
where s² − σ²_noise is significant against its own scatter (``fit.model_error_variance``);
otherwise σ²_model = 0 and the function interval is the mean band. Without a σ²_noise (no
maneuver with two samples, or a model saved without it) σ²_model = σ²_e: the function
interval is the prediction interval.

``std_mean`` = sqrt(Var_mean) (the band of the model's mean), ``std_function`` =
sqrt(Var_mean + σ²_model) and ``std_prediction`` = sqrt(Var_mean + σ²_e) are all returned.
The t quantile's degrees of freedom are dof = N_eff − n_p with the effective sample size of
autocorrelated residuals

    N_eff = N / (1 + 2 Σ_{k=1}^{L} ρ̂(k)),   clamped to [n_p + 5, N],

ρ̂ the residual autocorrelation within maneuvers and L the lag of the coloured-residual
correction (``flightid.coloured.automatic_lag``; N_eff = N for white residuals).

Each prediction also says whether x₀ is inside the data's support
(``flightid.globalmodel.support``): ``distance_ratio``, ``leverage_ratio``, ``outside``,
``reason``. For a table model a point where a table value without data acts is
``outside`` with the reason ``"empty-cell"`` (its value and intervals NaN), and one whose cell
touches a value filled by the smoothing with ``"filled"``.

A model written by ``to_dict`` / ``write`` predicts the same after ``from_dict`` /
``load_global_model``, without the data: it keeps θ̂, the covariances, (ΦᵀΦ)⁻¹, the scales,
the support reference set, σ²_noise and σ²_model and, for ``"local"``, the fitted samples'
coordinates and squared residuals.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from flightid.globalmodel.mof import MofPath
from flightid.globalmodel.settings import GlobalModelSettings
from flightid.globalmodel.support import Support, beyond_range, leverages
from flightid.globalmodel.tables import TableFit
from flightid.globalmodel.variables import GlobalModelError, Normalisation, points_matrix
from flightid.model.terms import Term, evaluate_terms, parse_term
from flightid.numbers import format_with_sigma
from flightid.regression.least_squares import LeastSquaresResult
from flightid.results import ResultSurface, check_level, finite_or_none, require_pandas

__all__ = [
    "CoefficientModel",
    "GlobalModel",
    "Prediction",
    "SourceInfo",
    "load_global_model",
    "FORMAT",
]

# version of the saved-model document
FORMAT = 1


def _nan(value) -> float:
    return float("nan") if value is None else float(value)


@dataclass(frozen=True)
class SourceInfo:
    """One maneuver a global model was fitted to.

    Attributes:
        maneuver: its name (or number).
        case: the case file it came from (``""`` when not from a case).
        conditions: flight-condition values recorded with it.
        n_samples: samples it contributed (before decimation).
    """

    maneuver: str
    case: str = ""
    conditions: Mapping[str, float] = field(default_factory=dict)
    n_samples: int = 0

    def to_dict(self) -> dict:
        return {
            "maneuver": self.maneuver,
            "case": self.case,
            "conditions": dict(self.conditions),
            "n_samples": int(self.n_samples),
        }

    @classmethod
    def from_dict(cls, entry: Mapping) -> SourceInfo:
        return cls(
            str(entry["maneuver"]),
            str(entry.get("case", "")),
            dict(entry.get("conditions") or {}),
            int(entry.get("n_samples", 0)),
        )


@dataclass(frozen=True, eq=False)
class Prediction(ResultSurface):
    """A coefficient predicted at points, with its intervals and data support (module
    docstring). Arrays have one entry per point.

    Attributes:
        response: the coefficient.
        points: the points, {variable: values} (signal units).
        value: ŷ.
        std_mean: σ of the model's mean at the point (coloured-residual covariance).
        std_prediction: σ of a new observation, sqrt(std_mean² + σ²_e).
        lower, upper: ŷ ∓ t·std_prediction at ``level`` (a new measurement).
        std_function: σ of the coefficient itself, sqrt(std_mean² + σ²_model).
        function_lower, function_upper: ŷ ∓ t·std_function (the function interval).
        level: the interval level c.
        dof: degrees of freedom of the t quantile, N_eff − n_p.
        distance_ratio: k-NN distance to the data / the data's own (``support``).
        leverage_ratio: h₀ / max h_ii of the fit.
        outside: the point is outside the data's support.
        reason: per point the support criteria that fired, ``"range"``, ``"distance"``,
            ``"leverage"`` joined by ``+`` (``""`` inside; ``flightid.globalmodel.support``).
    """

    response: str
    points: Mapping[str, np.ndarray]
    value: np.ndarray
    std_mean: np.ndarray
    std_prediction: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    level: float
    dof: float
    distance_ratio: np.ndarray
    leverage_ratio: np.ndarray
    outside: np.ndarray
    reason: tuple[str, ...]
    std_function: np.ndarray
    function_lower: np.ndarray
    function_upper: np.ndarray

    @property
    def quantile(self) -> float:
        """t_{dof,(1+c)/2}, the multiplier of both bands."""
        from scipy import stats

        return float(stats.t.ppf(0.5 * (1.0 + self.level), self.dof))

    def mean_interval(self) -> np.ndarray:
        """(n, 2) band of the model's mean: ŷ ∓ t·std_mean."""
        half = self.quantile * self.std_mean
        return np.column_stack([self.value - half, self.value + half])

    def function_interval(self) -> np.ndarray:
        """(n, 2) interval of the coefficient itself: ŷ ∓ t·std_function."""
        return np.column_stack([self.function_lower, self.function_upper])

    def _columns(self) -> dict[str, list]:
        columns = {name: np.asarray(v).tolist() for name, v in self.points.items()}
        columns.update(
            value=self.value.tolist(),
            lower=self.lower.tolist(),
            upper=self.upper.tolist(),
            std_mean=self.std_mean.tolist(),
            std_prediction=self.std_prediction.tolist(),
            function_lower=self.function_lower.tolist(),
            function_upper=self.function_upper.tolist(),
            std_function=self.std_function.tolist(),
            distance_ratio=self.distance_ratio.tolist(),
            leverage_ratio=self.leverage_ratio.tolist(),
            outside=[bool(x) for x in self.outside],
            reason=list(self.reason),
        )
        return columns

    def _frame_rows(self) -> list[dict]:
        columns = self._columns()
        return [
            {"name": str(i), **{key: values[i] for key, values in columns.items()}}
            for i in range(self.value.size)
        ]

    def to_dict(self) -> dict:
        """Plain Python: response, level, dof and one list per column."""
        return {
            "response": self.response,
            "level": self.level,
            "dof": float(self.dof),
            "n_points": int(self.value.size),
            "n_outside": int(np.count_nonzero(self.outside)),
            **self._columns(),
        }

    def to_frame(self):
        """One row per point (pandas; the ``pandas`` extra)."""
        pandas = require_pandas("Prediction.to_frame()")
        return pandas.DataFrame(self._columns())


@dataclass(frozen=True, eq=False)
class CoefficientModel(ResultSurface):
    """The global model of one coefficient (module docstring).

    Attributes:
        response: the coefficient's name (``"CL"``).
        channel: the data channel it was fitted to.
        method: ``"mof"`` or ``"table"``.
        normalisation: the variables' scales and box.
        terms: the selected terms, raw signal units, in the order selected.
        parameters: parameter names (``CL_alpha2``).
        estimates: θ̂ (raw units).
        covariance: the default (coloured-residual) covariance of θ̂.
        covariance_cr: the classical covariance s²(ΦᵀΦ)⁻¹.
        xtx_inv: (ΦᵀΦ)⁻¹ of the fitted samples (leverage).
        units: unit of each parameter (``""`` where unknown).
        s2: fit error variance RSS/(N − n_p).
        n_samples, n_eff, dof: N, the effective sample size and N_eff − n_p.
        coloured_lag: lag of the coloured-residual correction (0: white).
        std_kind: which σ ``covariance`` gives (``"coloured"`` or ``"cramer_rao"``).
        residuals_white: the whiteness verdict of the fit.
        r2, pse, sigma2_max, rms_fit: the fit's R², PSE, PSE's σ²_max and RMS residual.
        leverage_max: max h_ii of the fitted samples.
        noise_variance: σ²_noise, the measurement-noise variance from the residuals'
            sample-to-sample differences (NaN: not estimated).
        model_error_variance: σ²_model = max(s² − σ²_noise, 0), 0 where not significant
            (module docstring; NaN: not estimated).
        residual_variance: ``"global"`` or ``"local"``; local_k its neighbours.
        local_reference, local_squared_residuals, local_noise_variances: fitted samples in
            support coordinates, their squared residuals and their half squared residual
            differences (r_{i+1} − r_i)²/2 (``"local"`` only, else empty).
        support: the data support.
        settings: the settings it was fitted with.
        path_table: the MOF path (n_terms, term, mse, pse per step).
        cost_share: ΔJ of each selected term as a fraction of ½Σ(z − z̄)² (NaN for the
            constant, whose ΔJ = ½Nz̄² is not part of that spread).
        n_candidates: candidates offered.
        path: the ``MofPath`` (None after reloading).
        fit: the ``LeastSquaresResult`` of the selected terms (None after reloading).
        tables: (method ``"table"``) the ``TableFit``: the tables' breakpoints, values, σ,
            filled and dropped values; ``terms`` and ``parameters`` are then its basis labels
            (``"alpha:de[2,3]"``) and the regressors its basis.
    """

    response: str
    channel: str
    method: str
    normalisation: Normalisation
    terms: tuple[str, ...]
    parameters: tuple[str, ...]
    estimates: np.ndarray
    covariance: np.ndarray
    covariance_cr: np.ndarray
    xtx_inv: np.ndarray
    units: tuple[str, ...]
    s2: float
    n_samples: int
    n_eff: float
    dof: float
    coloured_lag: int
    std_kind: str
    residuals_white: bool | None
    r2: float
    pse: float
    sigma2_max: float
    rms_fit: float
    leverage_max: float
    residual_variance: str
    local_k: int
    local_reference: np.ndarray
    local_squared_residuals: np.ndarray
    support: Support
    settings: GlobalModelSettings
    noise_variance: float = float("nan")
    model_error_variance: float = float("nan")
    local_noise_variances: np.ndarray = field(default_factory=lambda: np.zeros(0))
    path_table: tuple[dict, ...] = ()
    cost_share: tuple[float, ...] = ()
    n_candidates: int = 0
    path: MofPath | None = None
    fit: LeastSquaresResult | None = None
    tables: TableFit | None = None

    @property
    def variables(self) -> tuple[str, ...]:
        return self.normalisation.names

    @property
    def std(self) -> np.ndarray:
        """Default σ of θ̂ (coloured-residual where the residuals are coloured)."""
        return np.sqrt(np.diag(self.covariance))

    @property
    def std_cr(self) -> np.ndarray:
        """Classical σ of θ̂."""
        return np.sqrt(np.diag(self.covariance_cr))

    @cached_property
    def parsed_terms(self) -> tuple[Term, ...]:
        return tuple(parse_term(t) for t in self.terms)

    def regressors(self, points: Mapping[str, object] | np.ndarray) -> np.ndarray:
        """φ of the selected terms at the points (n, n_p); ``points`` a mapping
        {variable: values} or an (n, m) matrix in variable order."""
        X = self._matrix(points)
        signals = {name: X[:, k] for k, name in enumerate(self.variables)}
        if self.tables is not None:
            return self.tables.regressors(signals)
        return evaluate_terms(self.parsed_terms, signals)

    def _cell_flags(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(empty, filled) per point: a table value without data acts there (the model is
        NaN), or a value filled by the smoothing does; both False for MOF."""
        if self.tables is None:
            none = np.zeros(X.shape[0], dtype=bool)
            return none, none
        signals = {name: X[:, k] for k, name in enumerate(self.variables)}
        return self.tables.cell_flags(signals)

    def _matrix(self, points) -> np.ndarray:
        if isinstance(points, Mapping):
            return points_matrix(points, self.variables)
        X = np.asarray(points, dtype=float)
        if X.ndim != 2 or X.shape[1] != len(self.variables):
            raise GlobalModelError(
                f"points: expected an (n, {len(self.variables)}) matrix of {list(self.variables)}"
                f", got shape {X.shape}"
            )
        return X

    def _local_neighbours(self, V: np.ndarray) -> np.ndarray:
        """Indices (n, k) of the local_k fitted samples nearest to points V."""
        from scipy.spatial import cKDTree

        k = min(self.local_k, self.local_reference.shape[0])
        _, index = cKDTree(self.local_reference).query(V, k=k)
        return index.reshape(V.shape[0], -1)

    def residual_variance_at(self, V: np.ndarray) -> np.ndarray:
        """σ²_e at points in support coordinates (n,) (module docstring)."""
        n = V.shape[0]
        if self.residual_variance == "global":
            return np.full(n, self.s2)
        index = self._local_neighbours(V)
        n_p = len(self.terms)
        # σ²_e = mean of the k nearest squared residuals × N/(N − n_p)
        return self.local_squared_residuals[index].mean(axis=1) * (
            self.n_samples / (self.n_samples - n_p)
        )

    def model_error_variance_at(self, V: np.ndarray, sigma2_e: np.ndarray) -> np.ndarray:
        """σ²_model at points V (support coordinates) whose σ²_e is ``sigma2_e`` (n,)
        (module docstring)."""
        if not (np.isfinite(self.noise_variance) and np.isfinite(self.model_error_variance)):
            # no σ²_noise: all of σ²_e counts (the function interval is the prediction interval)
            return np.array(sigma2_e, dtype=float)
        if self.model_error_variance <= 0.0:
            return np.zeros_like(sigma2_e)
        if self.residual_variance == "global":
            model_error = np.full_like(sigma2_e, self.model_error_variance)
        else:
            noise = self.noise_variance
            if self.local_noise_variances.size == self.local_reference.shape[0] > 0:
                # σ²_noise(x₀) = mean of the k nearest half squared differences
                noise = self.local_noise_variances[self._local_neighbours(V)].mean(axis=1)
            # σ²_model(x₀) = max(σ²_e(x₀) − σ²_noise(x₀), σ²_model (global))
            model_error = np.maximum(sigma2_e - noise, self.model_error_variance)
        return np.minimum(model_error, sigma2_e)

    def predict(self, points: Mapping[str, object], level: float | None = None) -> Prediction:
        """The coefficient at ``points`` with its intervals and support (module docstring)."""
        from scipy import stats

        level = self.settings.level if level is None else check_level(level)
        X = self._matrix(points)
        phi = self.regressors(X)
        # ŷ₀ = φ₀ᵀ θ̂
        value = phi @ self.estimates
        # Var_mean = φ₀ᵀ C φ₀
        var_mean = np.maximum(np.einsum("ij,jk,ik->i", phi, self.covariance, phi), 0.0)
        V = self.normalisation.support_coordinates(X)
        sigma2_e = self.residual_variance_at(V)
        std_prediction = np.sqrt(var_mean + sigma2_e)
        std_function = np.sqrt(var_mean + self.model_error_variance_at(V, sigma2_e))
        # q = t_{dof,(1+c)/2}
        q = float(stats.t.ppf(0.5 * (1.0 + level), self.dof))
        leverage_ratio = leverages(phi, self.xtx_inv) / self.leverage_max
        norm = self.normalisation
        out_of_range = beyond_range(X, norm.low, norm.high, self.settings.support_margin)
        empty, filled = self._cell_flags(X)
        distance_ratio, leverage_ratio, outside, reason = self.support.measure(
            V, np.where(empty, 0.0, leverage_ratio), out_of_range
        )
        leverage_ratio = np.where(empty, np.nan, leverage_ratio)
        outside = outside | empty | filled
        reason = tuple(
            "+".join(x for x in (r, "empty-cell" if e else "", "filled" if f else "") if x)
            for r, e, f in zip(reason, empty, filled, strict=True)
        )
        return Prediction(
            response=self.response,
            points={name: X[:, k].copy() for k, name in enumerate(self.variables)},
            value=value,
            std_mean=np.sqrt(var_mean),
            std_prediction=std_prediction,
            lower=value - q * std_prediction,
            upper=value + q * std_prediction,
            level=level,
            dof=float(self.dof),
            distance_ratio=distance_ratio,
            leverage_ratio=leverage_ratio,
            outside=outside,
            reason=reason,
            std_function=std_function,
            function_lower=value - q * std_function,
            function_upper=value + q * std_function,
        )

    # ---------------------------------------------------------------- reports
    def _frame_rows(self) -> list[dict]:
        return [
            {
                "name": name,
                "coefficient": self.response,
                "term": term,
                "value": float(self.estimates[j]),
                "std": float(self.std[j]),
                "std_cr": float(self.std_cr[j]),
                "unit": self.units[j] if self.units else "",
            }
            for j, (name, term) in enumerate(zip(self.parameters, self.terms, strict=True))
        ]

    def summary(self) -> str:
        """Text table: the selected terms with value, σ (default) and σ_cr, and the fit."""
        what = (
            f"{len(self.tables.components)} tables, {len(self.terms)} fitted values"
            if self.tables is not None
            else f"{len(self.terms)} of {self.n_candidates} candidate terms"
        )
        lines = [
            f"{self.response} ({self.method}, {self.channel}): {what}",
            f"N = {self.n_samples}  N_eff = {self.n_eff:.1f}  R² = {self.r2:.6f}  "
            f"s = {np.sqrt(self.s2):.4g}  PSE = {self.pse:.4g} (σ²_max = {self.sigma2_max:.4g})"
            f"  residual lag {self.coloured_lag}",
            f"σ_noise = {np.sqrt(self.noise_variance):.4g} (measurement noise, from sample "
            f"differences)  σ_model = {np.sqrt(self.model_error_variance):.4g} (model error; "
            f"function interval: σ_mean and σ_model)",
            f"{'parameter':<24s}{'term':<28s}{'value':>14s}{'σ':>12s}{'σ_cr':>12s}",
        ]
        for j, (name, term) in enumerate(zip(self.parameters, self.terms, strict=True)):
            value_text, std_text = format_with_sigma(self.estimates[j], self.std[j])
            lines.append(
                f"{name:<24s}{term:<28s}{value_text:>14s}{std_text:>12s}{self.std_cr[j]:>12.2g}"
            )
        if self.tables is not None:
            lines += self._table_lines()
        return "\n".join(lines)

    def _table_lines(self) -> list[str]:
        """Each table's breakpoints and the number of values filled or dropped."""
        lines = []
        for c, component in enumerate(self.tables.components):
            marks = (
                f"{int(self.tables.filled[c].sum())} filled, "
                f"{int(self.tables.dropped[c].sum())} without data"
            )
            lines.append(f"table {component.label} (degree {component.degree}; {marks})")
            for v in component.variables:
                points = ", ".join(f"{b:.4g}" for b in component.breakpoints[v])
                lines.append(f"  {v}: [{points}]")
        return lines

    def to_dict(self) -> dict:
        """Plain Python (JSON-ready, strict JSON through ``flightid.jsonout``); reloadable."""
        order = list(range(1, len(self.terms) + 1))
        shares = list(self.cost_share) or [None] * len(self.terms)
        return {
            "response": self.response,
            "channel": self.channel,
            "method": self.method,
            "n_samples": int(self.n_samples),
            "n_eff": float(self.n_eff),
            "dof": float(self.dof),
            "n_candidates": int(self.n_candidates),
            "sigma2_max": float(self.sigma2_max),
            "pse": float(self.pse),
            "s2": float(self.s2),
            "r2": finite_or_none(self.r2),
            "rms_fit": float(self.rms_fit),
            "residual_variance": self.residual_variance,
            "local_k": int(self.local_k),
            "coloured_lag": int(self.coloured_lag),
            "std_kind": self.std_kind,
            "residuals_white": self.residuals_white,
            "leverage_max": float(self.leverage_max),
            "noise_variance": float(self.noise_variance),
            "model_error_variance": float(self.model_error_variance),
            "terms": [
                {
                    "term": term,
                    "parameter": name,
                    "unit": self.units[j] if self.units else "",
                    "value": float(self.estimates[j]),
                    "std": float(self.std[j]),
                    "std_cr": float(self.std_cr[j]),
                    "std_kind": self.std_kind,
                    "order_selected": order[j],
                    "cost_share": shares[j],
                }
                for j, (name, term) in enumerate(zip(self.parameters, self.terms, strict=True))
            ],
            "path": [dict(entry) for entry in self.path_table],
            "covariance": self.covariance.tolist(),
            "covariance_cr": self.covariance_cr.tolist(),
            "xtx_inv": self.xtx_inv.tolist(),
            "support": self.support.to_dict(),
            "local_reference": self.local_reference.tolist(),
            "local_squared_residuals": self.local_squared_residuals.tolist(),
            "local_noise_variances": self.local_noise_variances.tolist(),
            "settings": self.settings.to_dict(),
            "tables": None if self.tables is None else self.tables.to_dict(),
        }

    @classmethod
    def from_dict(cls, entry: Mapping, normalisation: Normalisation) -> CoefficientModel:
        """The model ``to_dict`` wrote (without ``fit`` and ``path``)."""
        terms = entry["terms"]
        m = len(normalisation.names)
        return cls(
            response=str(entry["response"]),
            channel=str(entry["channel"]),
            method=str(entry["method"]),
            normalisation=normalisation,
            terms=tuple(t["term"] for t in terms),
            parameters=tuple(t["parameter"] for t in terms),
            estimates=np.array([float(t["value"]) for t in terms]),
            covariance=np.array(entry["covariance"], dtype=float).reshape(len(terms), -1),
            covariance_cr=np.array(entry["covariance_cr"], dtype=float).reshape(len(terms), -1),
            xtx_inv=np.array(entry["xtx_inv"], dtype=float).reshape(len(terms), -1),
            units=tuple(str(t.get("unit", "")) for t in terms),
            s2=float(entry["s2"]),
            n_samples=int(entry["n_samples"]),
            n_eff=float(entry["n_eff"]),
            dof=float(entry["dof"]),
            coloured_lag=int(entry["coloured_lag"]),
            std_kind=str(entry["std_kind"]),
            residuals_white=entry.get("residuals_white"),
            r2=_nan(entry.get("r2")),
            pse=float(entry["pse"]),
            sigma2_max=float(entry["sigma2_max"]),
            rms_fit=float(entry["rms_fit"]),
            leverage_max=float(entry["leverage_max"]),
            noise_variance=_nan(entry.get("noise_variance")),
            model_error_variance=_nan(entry.get("model_error_variance")),
            residual_variance=str(entry["residual_variance"]),
            local_k=int(entry["local_k"]),
            local_reference=np.array(entry["local_reference"], dtype=float).reshape(-1, m),
            local_squared_residuals=np.array(entry["local_squared_residuals"], dtype=float),
            local_noise_variances=np.array(entry.get("local_noise_variances", []), dtype=float),
            support=Support.from_dict(entry["support"]),
            settings=GlobalModelSettings.from_dict(entry["settings"]),
            path_table=tuple(dict(e) for e in entry.get("path", ())),
            cost_share=tuple(_nan(t.get("cost_share")) for t in terms),
            n_candidates=int(entry.get("n_candidates", 0)),
            tables=None if entry.get("tables") is None else TableFit.from_dict(entry["tables"]),
        )


@dataclass(frozen=True, eq=False)
class GlobalModel(ResultSurface):
    """Global models of several coefficients over the same variables.

    Attributes:
        coefficients: {coefficient: CoefficientModel}.
        normalisation: the variables' scales and box (``variables`` their names).
        sources: the maneuvers fitted.
    """

    coefficients: Mapping[str, CoefficientModel]
    normalisation: Normalisation
    sources: tuple[SourceInfo, ...] = ()

    @property
    def variables(self) -> tuple[str, ...]:
        return self.normalisation.names

    def __getitem__(self, coefficient: str) -> CoefficientModel:
        if coefficient not in self.coefficients:
            raise KeyError(
                f"no coefficient {coefficient!r} in this model; it has {list(self.coefficients)}"
            )
        return self.coefficients[coefficient]

    def predict(
        self, points: Mapping[str, object], level: float | None = None
    ) -> dict[str, Prediction]:
        """{coefficient: Prediction} at ``points`` ({variable: values}, signal units); the
        interval level defaults to each coefficient's settings (0.95)."""
        return {name: model.predict(points, level) for name, model in self.coefficients.items()}

    def parameter_values(self) -> dict[str, float]:
        """{parameter name: θ̂} over every coefficient."""
        return {
            name: float(value)
            for model in self.coefficients.values()
            for name, value in zip(model.parameters, model.estimates, strict=True)
        }

    def aero_model(self):
        """The selected terms as a ``flightid.aircraft.aero.AeroModel`` (parameter names as
        here; values from ``parameter_values()``). Coefficients must be aerodynamic
        coefficient names (CX, CY, CZ, CD, CL, Cl, Cm, Cn)."""
        from flightid.aircraft.aero import COEFFICIENTS, AeroModel

        unknown = [c for c in self.coefficients if c not in COEFFICIENTS]
        if unknown:
            raise GlobalModelError(
                f"aero_model: expected coefficients from {list(COEFFICIENTS)}, got {unknown}"
            )
        tabled = [c for c, m in self.coefficients.items() if m.tables is not None]
        if tabled:
            raise GlobalModelError(
                f"aero_model: expected term models, got table models for {tabled} (tables are "
                "no terms of an AeroModel; export them with write_jsbsim_global)"
            )
        return AeroModel(
            {
                name: dict(zip(model.parameters, model.terms, strict=True))
                for name, model in self.coefficients.items()
            }
        )

    def _frame_rows(self) -> list[dict]:
        return [row for model in self.coefficients.values() for row in model._frame_rows()]

    def summary(self) -> str:
        """Text: the variables' ranges, then each coefficient's table."""
        norm = self.normalisation
        ranges = ", ".join(
            f"{name} [{norm.low[k]:.4g}, {norm.high[k]:.4g}]" + (f" {unit}" if unit else "")
            for k, (name, unit) in enumerate(zip(norm.names, norm.units, strict=True))
        )
        parts = [f"Global model over {ranges}; {len(self.sources)} maneuvers"]
        parts += [model.summary() for model in self.coefficients.values()]
        return "\n\n".join(parts)

    def to_dict(self) -> dict:
        """Plain Python, reloadable with ``GlobalModel.from_dict`` (strict JSON: ``to_json``)."""
        return {
            "kind": "global_model",
            "format": FORMAT,
            "variables": self.normalisation.to_dict(),
            "sources": [s.to_dict() for s in self.sources],
            "coefficients": {name: m.to_dict() for name, m in self.coefficients.items()},
        }

    @classmethod
    def from_dict(cls, document: Mapping) -> GlobalModel:
        """The model ``to_dict`` (or ``write``) produced; it predicts as the original did."""
        if not isinstance(document, Mapping) or document.get("kind") != "global_model":
            raise GlobalModelError(
                "global model: expected a document with kind 'global_model', got "
                f"{type(document).__name__}"
                + (f" of kind {document.get('kind')!r}" if isinstance(document, Mapping) else "")
            )
        if document.get("format") != FORMAT:
            raise GlobalModelError(
                f"global model: expected format {FORMAT}, got {document.get('format')!r}"
            )
        normalisation = Normalisation.from_dict(document["variables"])
        return cls(
            coefficients={
                name: CoefficientModel.from_dict(entry, normalisation)
                for name, entry in document["coefficients"].items()
            },
            normalisation=normalisation,
            sources=tuple(SourceInfo.from_dict(s) for s in document.get("sources", ())),
        )

    def write(self, path: str | Path) -> Path:
        """Write the model as strict JSON (``load_global_model`` reads it back)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(self.to_json(indent=None), encoding="utf-8")
        return path


def load_global_model(path: str | Path) -> GlobalModel:
    """The global model ``GlobalModel.write`` wrote to ``path``."""
    import json

    try:
        document = json.loads(Path(path).read_text(encoding="utf-8"))
    except json.JSONDecodeError as error:
        raise GlobalModelError(f"{path}: expected a global-model JSON file, got {error}") from None
    return GlobalModel.from_dict(document)
