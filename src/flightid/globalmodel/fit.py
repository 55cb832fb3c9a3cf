"""The front door of global modelling: ``fit_global_model``.

For each coefficient: keep every ``decimate``-th sample of each maneuver, build the
candidates (``candidates``), select the terms by multivariate orthogonal functions and PSE
(``mof``), refit the selected raw terms by ``flightid.regression.least_squares`` (θ̂, the
coloured-residual covariance by maneuver, σ_cr, R², PSE), and attach what predictions need:
the effective sample size, the leverage bound, the data support, the measurement-noise and
model-error variances of the function interval (``noise_variance``, ``model_error_variance``)
and, for ``residual_variance="local"``, the residual and noise reference (``model``).

With ``method = "table"`` the selection and refit are replaced by ``fit_table_model`` on the
settings' tables (breakpoints given, or ``"auto"``: ``auto_breakpoints`` with a count or
``choose_breakpoints`` by PSE); its basis is the regressors and its fitted values the
parameters, and everything after the fit (N_eff, σ²_noise, σ²_model, support, leverage) is
the same code for both methods (``_completed``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from flightid.errors import describe
from flightid.globalmodel.candidates import candidate_columns, generate_candidates
from flightid.globalmodel.model import CoefficientModel, GlobalModel, SourceInfo
from flightid.globalmodel.mof import select_terms
from flightid.globalmodel.settings import GlobalModelSettings
from flightid.globalmodel.support import Support, leverages
from flightid.globalmodel.variables import GlobalModelError, Normalisation, check_series
from flightid.model.terms import Abs, Spline, Term, TermError, evaluate_terms, parse_term

__all__ = [
    "fit_global_model",
    "effective_sample_size",
    "decimated_indices",
    "difference_noise_variance",
    "half_squared_differences",
    "model_error_variance",
]

# N_eff is kept at least this many samples above the parameter count
_MIN_DOF = 5
# one-sided 5 % quantile of the standard normal: the model-error variance counts when it
# exceeds this many of its standard errors under white residuals
MODEL_ERROR_Z = 1.6449


def decimated_indices(maneuver_index: np.ndarray, decimate: int) -> np.ndarray:
    """Every ``decimate``-th sample of each maneuver (the first of each kept), in order."""
    maneuver_index = np.asarray(maneuver_index)
    if decimate == 1:
        return np.arange(maneuver_index.size)
    starts = np.concatenate([[0], np.flatnonzero(np.diff(maneuver_index) != 0) + 1])
    position = np.arange(maneuver_index.size) - np.repeat(
        starts, np.diff(np.concatenate([starts, [maneuver_index.size]]))
    )
    return np.flatnonzero(position % decimate == 0)


def effective_sample_size(
    residuals: np.ndarray, lag: int, maneuver_index: np.ndarray | None, n_parameters: int
) -> float:
    """N_eff = N / (1 + 2 Σ_{k=1}^{L} ρ̂(k)), clamped to [n_p + 5, N] (``model`` docstring)."""
    from flightid.coloured import residual_autocovariance

    n = residuals.size
    if lag <= 0:
        return float(n)
    gamma = residual_autocovariance(residuals[:, None], lag, maneuver_index)[:, 0, 0]
    if gamma[0] <= 0:
        return float(n)
    # ρ̂(k) = R̂(k) / R̂(0)
    rho = gamma[1:] / gamma[0]
    inflation = 1.0 + 2.0 * float(np.sum(rho))
    n_eff = n / inflation if inflation > 0 else float(n)
    return float(min(max(n_eff, n_parameters + _MIN_DOF), n))


def difference_noise_variance(
    residuals: np.ndarray, maneuver_index: np.ndarray
) -> tuple[float, int]:
    """The measurement-noise variance from the residuals' sample-to-sample differences, and
    the number of differences it rests on.

    For white noise e, Var(e_{i+1} − e_i) = 2σ²; model error varies slowly along a trajectory
    and cancels in the differences. So, over the samples in time order within each maneuver
    (a difference is taken only between neighbours of the same maneuver),

        σ²_noise = Σ_k Σ_i (r_{k,i+1} − r_{k,i})² / (2 Σ_k (n_k − 1)).

    Assumptions: the noise is white at the sample rate and the samples are in time order.
    Noise correlated from sample to sample (filtered or smoothed signals) gives a smaller
    difference variance, so σ²_noise comes out low and the model-error variance and the
    function interval high (conservative). Samples in no time order (scattered points) make
    the differences as large as the residuals: model error then counts as noise.

    Returns:
        (σ²_noise, number of differences); (NaN, 0) when no maneuver has two samples.
    """
    residuals = np.asarray(residuals, dtype=float)
    maneuver_index = np.asarray(maneuver_index)
    same = maneuver_index[1:] == maneuver_index[:-1]
    differences = np.diff(residuals)[same]
    if differences.size == 0:
        return float("nan"), 0
    # σ²_noise = Σ (Δr)² / (2 · number of differences)
    return float(np.sum(differences**2) / (2.0 * differences.size)), int(differences.size)


def half_squared_differences(
    residuals: np.ndarray, maneuver_index: np.ndarray, fill: float = float("nan")
) -> np.ndarray:
    """Per sample (N,) the half squared difference (r_{i+1} − r_i)²/2 to the next sample of
    its maneuver (to the previous one for a maneuver's last sample): each sample's share of
    ``difference_noise_variance``, averaged over neighbours for the local noise variance.
    ``fill`` where a maneuver has a single sample."""
    residuals = np.asarray(residuals, dtype=float)
    maneuver_index = np.asarray(maneuver_index)
    out = np.full(residuals.size, float(fill))
    same = maneuver_index[1:] == maneuver_index[:-1]
    # (r_{i+1} − r_i)² / 2 between neighbours of one maneuver
    half = 0.5 * np.diff(residuals) ** 2
    pairs = np.flatnonzero(same)
    out[pairs + 1] = half[pairs]  # the later sample of each pair: to its previous one
    out[pairs] = half[pairs]  # the earlier one: to its next (overrides where both exist)
    return out


def model_error_variance(
    residuals: np.ndarray, maneuver_index: np.ndarray, n_parameters: int
) -> tuple[float, float]:
    """(σ²_noise, σ²_model) of a fit's residuals r (time order per maneuver).

    σ²_model = max(s² − σ²_noise, 0) with s² = Σ r² / (N − n_p) and σ²_noise from the
    differences (``difference_noise_variance``). s² − σ²_noise is, up to end effects, the
    residuals' lag-one autocovariance, whose standard error under white residuals is
    σ²_noise / sqrt(number of differences). It is counted only where it exceeds
    ``MODEL_ERROR_Z`` (1.645) standard errors (one-sided test at 5 %), else σ²_model = 0:
    flooring the noisy difference at 0 alone would leave a positive bias of about
    0.4 σ²/sqrt(N), which for a correct model is larger than the variance of the mean itself.

    Returns:
        (σ²_noise, σ²_model); (NaN, NaN) when σ²_noise cannot be estimated (no maneuver with
        two samples).
    """
    residuals = np.asarray(residuals, dtype=float)
    noise, n_differences = difference_noise_variance(residuals, maneuver_index)
    if n_differences == 0 or residuals.size <= n_parameters:
        return float("nan"), float("nan")
    # s² = Σ r² / (N − n_p)
    s2 = float(np.sum(residuals**2) / (residuals.size - n_parameters))
    excess = s2 - noise
    # standard error of s² − σ²_noise under white residuals: σ²_noise / sqrt(n_differences)
    standard_error = noise / np.sqrt(n_differences)
    return noise, (excess if excess > MODEL_ERROR_Z * standard_error else 0.0)


def _xtx_inverse(Phi: np.ndarray) -> np.ndarray:
    """(ΦᵀΦ)⁻¹ through the QR factors of the unit-length columns."""
    norms = np.linalg.norm(Phi, axis=0)
    _, R = np.linalg.qr(Phi / norms)
    R_inv = np.linalg.solve(R, np.eye(R.shape[0]))
    # (ΦᵀΦ)⁻¹ = D⁻¹ R⁻¹ R⁻ᵀ D⁻¹
    return (R_inv @ R_inv.T) / np.outer(norms, norms)


def _parameter_unit(term: Term, response_unit: str, units: Mapping[str, str]) -> str:
    """Unit of a term's parameter: the response's unit over the term's signal units."""
    parts = []
    for key, power in term.factors:
        name = key.signal if isinstance(key, (Spline, Abs)) else key
        unit = units.get(name, "")
        if unit and unit not in ("-", "1"):
            parts.append(unit if power == 1 else f"{unit}^{power}")
    if not parts:
        return response_unit
    return f"{response_unit or '1'}/{'/'.join(parts)}"


def _checked_signals(
    signals: Mapping[str, object], channels: Sequence[str]
) -> tuple[dict[str, np.ndarray], int]:
    if not isinstance(signals, Mapping):
        raise GlobalModelError(
            f"signals: expected a mapping {{channel: series}}, got {describe(signals)}"
        )
    missing = [c for c in channels if c not in signals]
    if missing:
        raise GlobalModelError(
            f"signals: expected channels {missing} (variables and responses), available: "
            f"{sorted(signals)}"
        )
    first = check_series(signals[channels[0]], f"signals[{channels[0]!r}]")
    n = first.size
    out = {channels[0]: first}
    for channel in channels[1:]:
        out[channel] = check_series(signals[channel], f"signals[{channel!r}]", n)
    return out, n


def _responses(responses) -> dict[str, str]:
    if isinstance(responses, str):
        responses = [responses]
    if isinstance(responses, Mapping):
        pairs = dict(responses)
    elif isinstance(responses, Sequence):
        pairs = {r: r for r in responses}
    else:
        raise GlobalModelError(
            f"responses: expected channel names or {{coefficient: channel}}, got "
            f"{describe(responses)}"
        )
    if not pairs or not all(isinstance(k, str) and isinstance(v, str) for k, v in pairs.items()):
        raise GlobalModelError(
            f"responses: expected at least one coefficient name → channel name, got {pairs!r}"
        )
    return pairs


def _variables(variables, responses: Mapping[str, str]) -> tuple[str, ...]:
    if isinstance(variables, str) or not isinstance(variables, Sequence) or not variables:
        raise GlobalModelError(
            f"variables: expected a non-empty list of channel names, got {describe(variables)}"
        )
    names = tuple(variables)
    if not all(isinstance(v, str) for v in names) or len(set(names)) != len(names):
        raise GlobalModelError(f"variables: expected distinct channel names, got {list(names)}")
    both = sorted(set(names) & set(responses.values()))
    if both:
        raise GlobalModelError(f"variables: {both} are also responses")
    return names


def _settings_for(settings, coefficients: Sequence[str]) -> dict[str, GlobalModelSettings]:
    if settings is None or isinstance(settings, GlobalModelSettings):
        chosen = settings or GlobalModelSettings()
        return {c: chosen for c in coefficients}
    if not isinstance(settings, Mapping):
        raise GlobalModelError(
            "settings: expected GlobalModelSettings or {coefficient: GlobalModelSettings}, got "
            f"{describe(settings)}"
        )
    unknown = sorted(set(settings) - set(coefficients))
    if unknown:
        raise GlobalModelError(
            f"settings: expected coefficients from {coefficients}, got {unknown}"
        )
    out = {}
    for c in coefficients:
        value = settings.get(c, GlobalModelSettings())
        if not isinstance(value, GlobalModelSettings):
            raise GlobalModelError(
                f"settings[{c!r}]: expected GlobalModelSettings, got {describe(value)}"
            )
        out[c] = value
    return out


def _maneuver_index(maneuver_index, n: int) -> np.ndarray:
    if maneuver_index is None:
        return np.zeros(n, dtype=int)
    index = np.asarray(maneuver_index)
    if index.shape != (n,):
        raise GlobalModelError(
            f"maneuver_index: expected one entry per sample ({n}), got {describe(index)}"
        )
    return index


def _candidates(variables, settings: GlobalModelSettings) -> tuple[list[Term], list[str]]:
    """The candidate terms (forced terms first, added when not generated) and forced labels."""
    terms = list(
        generate_candidates(
            variables,
            settings.orders,
            settings.max_order,
            settings.knots,
            settings.spline_order,
            settings.cross_with,
            settings.cross_order,
            settings.max_candidates,
        )
    )
    try:
        forced = [parse_term(text) for text in settings.forced]
    except TermError as error:
        raise GlobalModelError(f"forced: {error}") from None
    labels = [t.label for t in terms]
    for term in forced:
        if term.label not in labels:
            terms.append(term)
            labels.append(term.label)
    if len(terms) > settings.max_candidates:
        raise GlobalModelError(
            f"candidates: expected at most max_candidates = {settings.max_candidates} "
            f"candidate terms, got {len(terms)}"
        )
    return terms, [t.label for t in forced]


def _fit_coefficient(
    name: str,
    channel: str,
    z_all: np.ndarray,
    X_all: np.ndarray,
    maneuver_index: np.ndarray,
    normalisation: Normalisation,
    settings: GlobalModelSettings,
    dt: float | None,
    units: Mapping[str, str],
) -> CoefficientModel:
    """One coefficient's model (module docstring): the method's fit, then what predictions
    need (``_completed``), the same for every method."""
    rows = decimated_indices(maneuver_index, settings.decimate)
    data = _FitData(name, channel, z_all, X_all, maneuver_index, rows, normalisation)
    if settings.method == "table":
        fitted = _table_fit(data, settings, units)
    else:
        fitted = _mof_fit(data, settings, units)
    return _completed(data, fitted, settings, dt)


class _FitData:
    """The samples of one coefficient's fit: every sample (``*_all``) and the decimated rows."""

    def __init__(self, name, channel, z_all, X_all, maneuver_index, rows, normalisation):
        self.name, self.channel = name, channel
        self.z_all, self.X_all, self.index_all = z_all, X_all, maneuver_index
        self.rows = rows
        self.X, self.z, self.index = X_all[rows], z_all[rows], maneuver_index[rows]
        self.normalisation = normalisation
        self.variables = normalisation.names

    def signals(self, every: bool = False) -> dict[str, np.ndarray]:
        X = self.X_all if every else self.X
        return {v: X[:, k] for k, v in enumerate(self.variables)}


def _mof_fit(data: _FitData, settings: GlobalModelSettings, units) -> dict:
    """MOF: candidates, term selection by PSE, least squares on the selected raw terms."""
    from flightid.regression.least_squares import least_squares

    terms, forced = _candidates(data.variables, settings)
    if data.z.size <= len(terms) + _MIN_DOF:
        raise GlobalModelError(
            f"signals[{data.channel!r}]: expected more samples than the {len(terms)} candidate "
            f"terms + {_MIN_DOF} after decimate = {settings.decimate}, got {data.z.size}"
        )
    signals = data.signals()
    columns = candidate_columns(terms, signals, data.normalisation)
    path = select_terms(
        data.z,
        columns,
        [t.label for t in terms],
        forced=forced,
        sigma2_max=settings.sigma2_max,
        ranking=settings.ranking,
        max_terms=settings.max_terms,
        patience=settings.patience,
        tol=settings.tol,
    )
    selected = [terms[j] for j in path.indices[: path.n_terms]]
    Phi = evaluate_terms(selected, signals)
    parameters = tuple(f"{data.name}_{t.identifier}" for t in selected)
    response_unit = units.get(data.channel, "")
    parameter_units = {
        p: _parameter_unit(t, response_unit, units)
        for p, t in zip(parameters, selected, strict=True)
    }
    fit = least_squares(
        Phi,
        data.z,
        parameters,
        sigma2_max=path.sigma2_max,
        units=parameter_units,
        maneuver_index=data.index,
    )
    spread = float(np.sum((data.z - data.z.mean()) ** 2))
    return {
        "fit": fit,
        "Phi": Phi,
        "xtx_inv": _xtx_inverse(Phi),
        "fitted_all": evaluate_terms(selected, data.signals(every=True))
        @ np.asarray(fit.estimates),
        "terms": tuple(t.label for t in selected),
        "parameters": parameters,
        "units": tuple(parameter_units[p] for p in parameters),
        "n_parameters": len(selected),
        "extra": {
            "sigma2_max": float(path.sigma2_max),
            "path_table": tuple(path.to_dict()),
            "cost_share": tuple(float(x) for x in path.cost_share(spread)[: path.n_terms]),
            "n_candidates": len(terms),
            "path": path,
        },
    }


def _breakpoints_for(data: _FitData, settings: GlobalModelSettings, variable: str, entry):
    """The breakpoints of ``variable``: as given, or ``"auto"`` (module ``tables``)."""
    from flightid.globalmodel.tables import TableError, auto_breakpoints, choose_breakpoints

    given = settings.breakpoints[variable]
    if not isinstance(given, str):
        return np.array(given, dtype=float)
    x = data.signals()[variable]
    try:
        if settings.breakpoint_count is not None:
            return auto_breakpoints(x, settings.breakpoint_count)
        signals = data.signals()
        choice = choose_breakpoints(
            data.z, variable, signals, times=entry["times"], degree=entry["degree"],
            smoothing=settings.smoothing, min_weight=settings.min_weight,
            maneuver_index=data.index,
        )  # fmt: skip
    except TableError as error:
        raise GlobalModelError(f"breakpoints[{variable!r}]: {error}") from None
    return choice.breakpoints


def _table_components(data: _FitData, settings: GlobalModelSettings):
    """The ``TableComponent``s of the settings' tables; table variables and ``times`` signals
    must be among the model's variables (predictions see only those)."""
    from flightid.globalmodel.tables import TableComponent, TableError

    used = {v for t in settings.tables for v in (*t["by"], t["times"]) if v is not None}
    unknown = sorted(used - set(data.variables))
    if unknown:
        raise GlobalModelError(
            f"tables: expected variables and times signals from the model's variables "
            f"{list(data.variables)}, got {unknown}"
        )
    breakpoints = {}
    for entry in settings.tables:
        for v in entry["by"]:
            if v not in breakpoints:
                breakpoints[v] = _breakpoints_for(data, settings, v, entry)
    try:
        return [
            TableComponent(t["by"], breakpoints, t["times"], t["degree"]) for t in settings.tables
        ]
    except TableError as error:
        raise GlobalModelError(f"tables: {error}") from None


def _table_sigma2_max(settings: GlobalModelSettings, z: np.ndarray) -> float:
    """PSE's σ²_max for a table fit: a number as given, else the variance of z about its mean
    (the bound of ``"response"``; ``"full"`` has no candidate set to fit here)."""
    if isinstance(settings.sigma2_max, str):
        return float(np.mean((z - z.mean()) ** 2))
    return float(settings.sigma2_max)


def _table_fit(data: _FitData, settings: GlobalModelSettings, units) -> dict:
    """Tables: ``fit_table_model`` on the decimated samples; the regressors are the table
    basis (``TableFit.regressors``), the estimates the fitted table coefficients."""
    from flightid.globalmodel.tables import TableError, fit_table_model

    components = _table_components(data, settings)
    sigma2_max = _table_sigma2_max(settings, data.z)
    try:
        table = fit_table_model(
            data.z, components, data.signals(), smoothing=settings.smoothing,
            min_weight=settings.min_weight, maneuver_index=data.index, sigma2_max=sigma2_max,
        )  # fmt: skip
    except TableError as error:
        raise GlobalModelError(f"signals[{data.channel!r}]: {error}") from None
    fit = table.fit
    n_p = len(table.names)
    if data.z.size <= n_p + _MIN_DOF:
        raise GlobalModelError(
            f"signals[{data.channel!r}]: expected more samples than the {n_p} table values "
            f"+ {_MIN_DOF} after decimate = {settings.decimate}, got {data.z.size}"
        )
    Phi = table.regressors(data.signals())
    # (ΦᵀΦ)⁻¹ for the leverage: Cov_cr / s² ((ΦᵀΦ)⁻¹ without smoothing, A⁻¹ΦᵀΦA⁻¹ with it)
    covariance_cr = np.asarray(fit.covariance, dtype=float)
    xtx_inv = covariance_cr / fit.s2 if fit.s2 > 0 else _xtx_inverse(Phi)
    effective = getattr(fit, "effective_parameters", float("nan"))
    response_unit = units.get(data.channel, "")
    return {
        "fit": fit,
        "Phi": Phi,
        "xtx_inv": xtx_inv,
        "fitted_all": table.evaluate(data.signals(every=True)),
        "terms": tuple(table.names),
        "parameters": tuple(f"{data.name}_{label}" for label in table.names),
        "units": tuple(_table_unit(label, response_unit, units) for label in table.names),
        "n_parameters": effective if np.isfinite(effective) and settings.smoothing > 0 else n_p,
        "extra": {
            "sigma2_max": sigma2_max,
            "n_candidates": n_p,
            "tables": table,
        },
    }


def _table_unit(label: str, response_unit: str, units: Mapping[str, str]) -> str:
    """Unit of a table value: the response's, over the ``times`` signal's unit if any."""
    head = label.partition("[")[0]
    times = head.partition("*")[0] if "*" in head else None
    unit = units.get(times, "") if times else ""
    if not unit or unit in ("-", "1"):
        return response_unit
    return f"{response_unit or '1'}/{unit}"


def _completed(data: _FitData, fitted: dict, settings: GlobalModelSettings, dt) -> CoefficientModel:
    """The ``CoefficientModel`` of a method's fit: N_eff, σ²_noise and σ²_model from the
    residuals on every sample, the leverage bound, the support and the local reference."""
    fit, Phi, n_p = fitted["fit"], fitted["Phi"], fitted["n_parameters"]
    z, index = data.z, data.index
    # the residuals of the model on every sample (before decimation), in time order; a
    # sample where the model is undefined (a table value without data) is left out
    residuals_all = data.z_all - fitted["fitted_all"]
    defined = np.isfinite(residuals_all)
    noise_variance, error_variance = model_error_variance(
        residuals_all[defined], data.index_all[defined], n_p
    )
    shares = np.full(residuals_all.size, noise_variance)
    shares[defined] = half_squared_differences(
        residuals_all[defined], data.index_all[defined], noise_variance
    )
    noise_shares = shares[data.rows]
    n_eff = effective_sample_size(np.asarray(fit.residuals), fit.coloured_lag, index, n_p)
    xtx_inv = fitted["xtx_inv"]
    V = data.normalisation.support_coordinates(data.X)
    support = Support.from_data(
        V,
        index,
        None if dt is None else dt * settings.decimate,
        k=settings.support_k,
        spacing_s=settings.spacing_s,
        quantile=settings.support_quantile,
        factor=settings.support_factor,
    )
    local = settings.residual_variance == "local"
    local_k = settings.local_k or max(100, z.size // 50)
    return CoefficientModel(
        response=data.name,
        channel=data.channel,
        method=settings.method,
        normalisation=data.normalisation,
        terms=fitted["terms"],
        parameters=fitted["parameters"],
        estimates=np.array(fit.estimates),
        covariance=np.array(fit.covariance_default),
        covariance_cr=np.array(fit.covariance),
        xtx_inv=xtx_inv,
        units=fitted["units"],
        s2=float(fit.s2),
        n_samples=int(z.size),
        n_eff=n_eff,
        dof=n_eff - n_p,
        coloured_lag=int(fit.coloured_lag),
        std_kind=fit.std_kind,
        residuals_white=fit.residuals_white,
        r2=float(fit.r2),
        pse=float(fit.pse),
        rms_fit=float(np.sqrt(fit.rss / z.size)),
        leverage_max=float(np.nanmax(leverages(Phi, xtx_inv))),
        noise_variance=noise_variance,
        model_error_variance=error_variance,
        residual_variance=settings.residual_variance,
        local_k=int(min(local_k, z.size)),
        local_reference=V if local else np.zeros((0, len(data.variables))),
        local_squared_residuals=np.asarray(fit.residuals) ** 2 if local else np.zeros(0),
        local_noise_variances=noise_shares if local else np.zeros(0),
        support=support,
        settings=settings,
        fit=fit,
        **fitted["extra"],
    )


def _sources(sources, index: np.ndarray) -> tuple[SourceInfo, ...]:
    if sources:
        if not all(isinstance(s, SourceInfo) for s in sources):
            raise GlobalModelError(f"sources: expected SourceInfo entries, got {describe(sources)}")
        return tuple(sources)
    values, counts = np.unique(index, return_counts=True)
    return tuple(SourceInfo(str(v), n_samples=int(c)) for v, c in zip(values, counts, strict=True))


def fit_global_model(
    signals: Mapping[str, object],
    responses: Sequence[str] | Mapping[str, str],
    variables: Sequence[str],
    *,
    settings: GlobalModelSettings | Mapping[str, GlobalModelSettings] | None = None,
    maneuver_index: object | None = None,
    dt: float | None = None,
    units: Mapping[str, str] | None = None,
    sources: Sequence[SourceInfo] = (),
) -> GlobalModel:
    """Fit a global model of each response over the explanatory ``variables``.

    Args:
        signals: {channel: series (N,)} — the variables and the responses, many maneuvers
            end to end, signal units.
        responses: channel names, or {coefficient name: channel} (``{"CL": "CL_meas"}``).
        variables: the explanatory channels (``["alpha", "Mach", "qhat", "de"]``).
        settings: one ``GlobalModelSettings`` for all coefficients, or one per coefficient
            (a coefficient not listed gets the defaults).
        maneuver_index: (N,) maneuver of each sample (default one maneuver): decimation is
            per maneuver, residual correlations stay within a maneuver.
        dt: sampling interval, s (thins the support reference set to one sample per
            ``spacing_s``; without it every sample is a reference sample).
        units: {channel: unit} for the parameters' units and the report.
        sources: the maneuvers, for the record (default one per ``maneuver_index`` value).

    Returns:
        A ``GlobalModel``; ``predict(points)`` gives each coefficient with its prediction
        interval and data support.

    Raises:
        GlobalModelError: a channel missing, series of different lengths or with non-finite
            values, too few samples for the candidates, too many candidates, or a malformed
            setting; the message names the key.
    """
    pairs = _responses(responses)
    names = _variables(variables, pairs)
    checked, n = _checked_signals(signals, [*names, *dict.fromkeys(pairs.values())])
    index = _maneuver_index(maneuver_index, n)
    if dt is not None and not (isinstance(dt, (int, float)) and np.isfinite(dt) and dt > 0):
        raise GlobalModelError(f"dt: expected a positive number of seconds, got {dt!r}")
    units = dict(units or {})
    per_coefficient = _settings_for(settings, list(pairs))
    normalisation = Normalisation.from_data(checked, names, units)
    X = np.column_stack([checked[v] for v in names])
    models = {
        coefficient: _fit_coefficient(
            coefficient,
            channel,
            checked[channel],
            X,
            index,
            normalisation,
            per_coefficient[coefficient],
            dt,
            units,
        )
        for coefficient, channel in pairs.items()
    }
    return GlobalModel(models, normalisation, _sources(sources, index))
