"""Outliers in the residuals: which samples they are, and an estimate that leaves them out.

A single wild point (a telemetry glitch, a spike in a vane angle) pulls an output-error fit:
its residual enters the cost squared, so one sample 250 times the noise outweighs tens of
thousands of good ones, and the stated σ do not show it. The screen here works on the raw
residuals ν_ik = z_ik − y_ik of an estimate, per output k: on each residual's departure from
the running median of its neighbours (so that a smooth misfit — a transient from the initial
state, a slow model error — is not taken for wild points), against a robust scale that the
outliers themselves cannot inflate:

    d_ik = ν_ik − median(ν_(i−3…i+3),k)                     (7-sample running median)
    s_k  = 1.4826 · median_i |d_ik − median_i d_ik|         (MAD; a σ for Gaussian noise)
    z_ik = d_ik / s_k

and names every measurement with both |z_ik| and |ν_ik|/s_ν,k above ``threshold``
(s_ν,k the residuals' own robust scale, ``robust_scale``; default 6: a Gaussian sample exceeds
it with probability 2·10⁻⁹, so a clean record of 10⁶ measurements raises no false alarm),
stating its size as ν_ik / s_ν,k.

What to do about them (``OUTLIER_MODES``):

* ``"warn"``: name them, change nothing;
* ``"exclude"``: re-estimate with weight 0 on those measurements (``estimate(...,
  weights=...)``): they leave the cost, the information matrix, R̂ and N, so the σ are those
  of the remaining data; repeated while a re-estimate reveals new outliers;
* ``"huber"``: iteratively re-weighted estimation with Huber weights
  w_ik = min(1, k_H / |z_ik|), k_H = 1.345 (95 % efficiency on Gaussian noise), every
  measurement kept but the large ones down-weighted.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from flightid.data.flightdata import FlightData
from flightid.errors import FlightIdWarning, InputError
from flightid.estimation.result import Estimate

__all__ = [
    "DEFAULT_THRESHOLD",
    "HUBER_K",
    "OUTLIER_MODES",
    "Outlier",
    "OutlierScreen",
    "OutlierWarning",
    "estimate_robust",
    "find_outliers",
    "outlier_weights",
    "robust_scale",
    "screen_estimate",
]

OUTLIER_MODES = ("warn", "exclude", "huber")
# |ν|/s above which a measurement is named (module docstring)
DEFAULT_THRESHOLD = 6.0
# Huber's tuning constant: 95 % asymptotic efficiency under Gaussian noise
HUBER_K = 1.345
# MAD → σ for Gaussian noise: 1/Φ⁻¹(3/4)
MAD_TO_SIGMA = 1.482602218505602
# samples of the running median the spikes are measured from (``spike_sizes``)
SPIKE_WINDOW = 7
# the warning names at most this many outliers (the report lists all)
LISTED = 5


class OutlierWarning(FlightIdWarning):
    """Measurements whose residuals are far outside the noise; ``flightid`` prints it as
    ``flightid: warning: <message>``."""


@dataclass(frozen=True)
class Outlier:
    """One measurement far outside the noise.

    Attributes:
        maneuver: maneuver number (0-based, the order of the data).
        maneuver_name: its name (``FlightData.name``; ``""`` when unnamed).
        sample: sample number within the maneuver (0-based).
        time_s: its time (s).
        output: the output's name.
        residual: ν = z − y in the output's units.
        size_sigma: ν / s (signed), s the output's robust noise scale (``robust_scale``).
    """

    maneuver: int
    maneuver_name: str
    sample: int
    time_s: float
    output: str
    residual: float
    size_sigma: float

    def describe(self) -> str:
        label = f"'{self.maneuver_name}'" if self.maneuver_name else f"{self.maneuver}"
        return (
            f"maneuver {label} sample {self.sample} (t = {self.time_s:.4g} s), {self.output}: "
            f"residual {self.residual:+.4g} ({self.size_sigma:+.1f} σ)"
        )

    def to_dict(self) -> dict:
        return {
            "maneuver": self.maneuver,
            "maneuver_name": self.maneuver_name,
            "sample": self.sample,
            "time_s": self.time_s,
            "output": self.output,
            "residual": self.residual,
            "size_sigma": self.size_sigma,
        }


@dataclass(frozen=True)
class OutlierScreen:
    """The outliers of one estimate and what was done about them.

    Attributes:
        outliers: the named measurements, largest |size| first.
        threshold: the |ν|/s limit (robust σ).
        scale: s_k, the robust noise scale of each output's residuals (its units).
        output_names: the outputs.
        mode: ``"warn"``, ``"exclude"`` or ``"huber"``.
        weights: the weights (N, n_o) the reported estimate used (None: all 1).
        rounds: re-estimations made (0 for ``"warn"`` or a clean record).
        shift_sigma: per free parameter, (estimate with the weights − estimate without) / σ
            of the estimate with the weights; empty when nothing was re-estimated.
    """

    outliers: tuple[Outlier, ...]
    threshold: float
    scale: np.ndarray
    output_names: tuple[str, ...]
    mode: str = "warn"
    weights: np.ndarray | None = field(default=None, repr=False)
    rounds: int = 0
    shift_sigma: dict[str, float] = field(default_factory=dict)

    @property
    def excluded(self) -> int:
        """Measurements with weight 0."""
        return 0 if self.weights is None else int(np.count_nonzero(self.weights == 0.0))

    def messages(self) -> list[str]:
        """One line: the outliers (the first ``LISTED`` by size) and what was done."""
        if not self.outliers:
            return []
        named = "; ".join(o.describe() for o in self.outliers[:LISTED])
        more = len(self.outliers) - LISTED
        if more > 0:
            named += f"; and {more} more (all in the report)"
        return [f"{self._action()}: {named}"]

    def _action(self) -> str:
        count = len(self.outliers)
        if self.mode == "warn":
            return (
                f"{count} outlier(s) beyond {self.threshold:g} σ are in the fit and pull the "
                "estimates, and their σ do not show it (set [estimation] outliers = "
                '"exclude" or "huber" to leave them out or down-weight them)'
            )
        moved = ", ".join(f"{n} {s:+.2f} σ" for n, s in self._largest_shifts())
        what = (
            f"{self.excluded} measurement(s) excluded from the cost (weight 0; N and σ without "
            "them)"
            if self.mode == "exclude"
            else f"{count} outlier(s) down-weighted with Huber weights"
        )
        return f"{what}, the estimates moved {moved}" if moved else what

    def _largest_shifts(self, count: int = 3) -> list[tuple[str, float]]:
        ranked = sorted(self.shift_sigma.items(), key=lambda item: -abs(item[1]))
        return ranked[:count]

    def to_dict(self) -> dict:
        return {
            "mode": self.mode,
            "threshold_sigma": self.threshold,
            "scale": {n: float(s) for n, s in zip(self.output_names, self.scale, strict=True)},
            "outliers": [o.to_dict() for o in self.outliers],
            "excluded": self.excluded,
            "rounds": self.rounds,
            "shift_sigma": dict(self.shift_sigma),
        }


def spike_sizes(residuals: np.ndarray, maneuver_index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(z (N, n_o), s (n_o,)): each residual's departure from the running median of its
    maneuver, d_ik = ν_ik − median(ν_(i−h…i+h),k), in robust σ of d, z_ik = d_ik / s_k.

    The running median (``SPIKE_WINDOW`` samples, edges held) follows a smooth misfit — a
    transient from the initial state, a slow model error — so only wild points, isolated or
    in runs of up to h = ``SPIKE_WINDOW`` // 2 samples, stand out.
    """
    half = SPIKE_WINDOW // 2
    departure = np.empty_like(residuals)
    for m in np.unique(maneuver_index):
        rows = np.flatnonzero(maneuver_index == m)
        block = residuals[rows]
        padded = np.pad(block, ((half, half), (0, 0)), mode="edge")
        windows = np.lib.stride_tricks.sliding_window_view(padded, SPIKE_WINDOW, axis=0)
        # d_ik = ν_ik − median over the window centred on i
        departure[rows] = block - np.median(windows, axis=-1)
    scale = robust_scale(departure)
    return departure / scale, scale


def robust_scale(residuals: np.ndarray) -> np.ndarray:
    """s_k = 1.4826 · MAD of each column of ``residuals`` (N, n_o); the RMS where the MAD is 0
    (more than half the residuals equal), and 1e-300 at the least."""
    residuals = np.asarray(residuals, dtype=float)
    centred = residuals - np.median(residuals, axis=0)
    # s_k = 1.4826 · median_i |ν_ik − median ν_k|
    scale = MAD_TO_SIGMA * np.median(np.abs(centred), axis=0)
    rms = np.sqrt(np.mean(residuals**2, axis=0))
    return np.maximum(np.where(scale > 0.0, scale, rms), 1e-300)


def find_outliers(
    residuals: np.ndarray,
    time: np.ndarray,
    maneuver_index: np.ndarray,
    output_names: Sequence[str],
    maneuver_names: Sequence[str] = (),
    threshold: float = DEFAULT_THRESHOLD,
) -> OutlierScreen:
    """The measurements with |ν_ik| / s_k > ``threshold`` (module docstring).

    Args:
        residuals: raw residuals z − y (N, n_o) over all maneuvers in order.
        time: (N,) sample times (s).
        maneuver_index: (N,) maneuver number of each sample.
        output_names: the n_o outputs.
        maneuver_names: names of the maneuvers (optional).
        threshold: the limit in robust σ (> 0).
    """
    residuals = np.asarray(residuals, dtype=float)
    time = np.asarray(time, dtype=float)
    maneuver_index = np.asarray(maneuver_index, dtype=int)
    threshold = _check_threshold(threshold)
    if residuals.ndim != 2 or residuals.shape[1] != len(output_names):
        raise InputError(
            f"residuals: expected (N, {len(output_names)}) residuals of the outputs "
            f"{list(output_names)}, got shape {residuals.shape}"
        )
    if time.shape != (residuals.shape[0],) or maneuver_index.shape != time.shape:
        raise InputError(
            f"time, maneuver_index: expected ({residuals.shape[0]},) each, got {time.shape} "
            f"and {maneuver_index.shape}"
        )
    departure, _ = spike_sizes(residuals, maneuver_index)
    # the size stated: ν_ik / s_k, s_k the robust noise scale of the residuals themselves
    scale = robust_scale(residuals)
    size = residuals / scale
    # wild against both its neighbours and the record's noise
    rows, columns = np.nonzero((np.abs(departure) > threshold) & (np.abs(size) > threshold))
    first_sample = {int(m): int(np.argmax(maneuver_index == m)) for m in np.unique(maneuver_index)}
    found = []
    for i, k in zip(rows, columns, strict=True):
        maneuver = int(maneuver_index[i])
        known = maneuver < len(maneuver_names)
        found.append(
            Outlier(
                maneuver=maneuver,
                maneuver_name=str(maneuver_names[maneuver]) if known else "",
                sample=int(i - first_sample[maneuver]),
                time_s=float(time[i]),
                output=str(output_names[k]),
                residual=float(residuals[i, k]),
                size_sigma=float(size[i, k]),
            )
        )
    found.sort(key=lambda o: -abs(o.size_sigma))
    return OutlierScreen(tuple(found), threshold, scale, tuple(output_names))


def _check_threshold(threshold: float) -> float:
    value = float(threshold)
    if not np.isfinite(value) or value <= 0.0:
        raise InputError(f"threshold: expected a positive number of σ, got {threshold!r}")
    return value


def _raw_residuals(estimate: Estimate) -> np.ndarray:
    """z − y of the estimate, without any weights it was made with."""
    return np.asarray(estimate.measured, dtype=float) - np.asarray(estimate.predicted, dtype=float)


def screen_estimate(
    estimate: Estimate,
    maneuver_names: Sequence[str] = (),
    threshold: float = DEFAULT_THRESHOLD,
) -> OutlierScreen:
    """``find_outliers`` on an output-error estimate's raw residuals z − y."""
    return find_outliers(
        _raw_residuals(estimate),
        estimate.time,
        estimate.maneuver_index,
        estimate.output_names,
        maneuver_names,
        threshold,
    )


def outlier_weights(
    residuals: np.ndarray,
    maneuver_index: np.ndarray,
    threshold: float,
    mode: str,
    previous: np.ndarray | None = None,
) -> np.ndarray:
    """Weights (N, n_o) for a re-estimate: 0 where |z| > ``threshold`` (``"exclude"``, on top
    of ``previous``), or Huber's min(1, k_H / |z|) (``"huber"``); z from ``spike_sizes``."""
    size = np.abs(spike_sizes(residuals, maneuver_index)[0])
    if mode == "exclude":
        weights = np.ones(residuals.shape) if previous is None else np.array(previous, dtype=float)
        # the screen's test (find_outliers): wild against the neighbours and the noise
        wild = (size > threshold) & (np.abs(residuals / robust_scale(residuals)) > threshold)
        weights[wild] = 0.0
        return weights
    if mode == "huber":
        # w = min(1, k_H / |z|)
        with np.errstate(divide="ignore"):
            return np.minimum(1.0, HUBER_K / size)
    raise InputError(f"outliers: expected 'exclude' or 'huber' to make weights, got {mode!r}")


def estimate_robust(
    model,
    data: FlightData | Sequence[FlightData],
    outliers: str = "exclude",
    *,
    threshold: float = DEFAULT_THRESHOLD,
    max_rounds: int = 5,
    warn: bool = True,
    first: Estimate | None = None,
    estimator=None,
    **options,
) -> tuple[Estimate, OutlierScreen]:
    """``estimate(model, data, **options)`` with its outliers screened and, as ``outliers``
    says, excluded or down-weighted (module docstring).

    Args:
        model: the state-space model (as ``estimate``).
        data: one maneuver or a list.
        outliers: ``"warn"``, ``"exclude"`` or ``"huber"``.
        threshold: the outlier limit in robust σ.
        max_rounds: re-estimations at most (exclusion stops as soon as no new outlier
            appears; Huber weights when the weights settle to 1 %).
        warn: issue the screen's messages as ``OutlierWarning``.
        first: the plain estimate when already made (saves the first estimation).
        estimator: the estimation function, called as ``estimator(model, data, weights=...,
            **options)`` (default ``flightid.estimation.estimate``); None with ``first``
            and ``outliers="warn"`` screens ``first`` only.
        options: passed to the estimator (not ``weights``).

    Returns:
        (the estimate to report, the screen of its raw residuals with what was done).
    """
    from flightid.estimation.driver import estimate

    estimator = estimate if estimator is None else estimator
    if outliers not in OUTLIER_MODES:
        raise InputError(f"outliers: expected one of {OUTLIER_MODES}, got {outliers!r}")
    if "weights" in options:
        raise InputError("weights: estimate_robust makes the weights; pass them to estimate")
    maneuvers = [data] if isinstance(data, FlightData) else list(data)
    names = [m.name or "" for m in maneuvers]
    plain = estimator(model, maneuvers, **options) if first is None else first
    screen = screen_estimate(plain, names, threshold)
    result, weights, rounds = plain, None, 0
    if outliers != "warn" and screen.outliers:
        result, weights, rounds = _reweighted(
            estimator, model, maneuvers, plain, screen, outliers, max_rounds, options
        )
        screen = screen_estimate(result, names, threshold)
    free = np.asarray(plain.free)
    with np.errstate(divide="ignore", invalid="ignore"):
        # (θ̂_weighted − θ̂_plain) / σ_weighted: the plain σ are inflated by the outliers' R̂
        shift = (result.values[free] - plain.values[free]) / result.std[free]
    screen = OutlierScreen(
        screen.outliers,
        screen.threshold,
        screen.scale,
        screen.output_names,
        mode=outliers,
        weights=weights,
        rounds=rounds,
        shift_sigma=(
            {n: float(s) for n, s in zip(plain.free_names, shift, strict=True)} if rounds else {}
        ),
    )
    if warn:
        for message in screen.messages():
            warnings.warn(message, OutlierWarning, stacklevel=2)
    return result, screen


def _reweighted(estimator, model, maneuvers, plain, screen, mode, max_rounds, options):
    """Re-estimate with outlier weights until they settle; (estimate, weights, rounds)."""
    result, weights = plain, None
    for rounds in range(1, max(int(max_rounds), 1) + 1):
        residuals = _raw_residuals(result)
        new = outlier_weights(residuals, result.maneuver_index, screen.threshold, mode, weights)
        settled = weights is not None and (
            np.array_equal(new, weights)
            if mode == "exclude"
            else float(np.max(np.abs(new - weights))) <= 0.01
        )
        if settled:
            return result, weights, rounds - 1
        weights = new
        # from the previous estimate: the outliers moved it little, the start is close
        start = model.with_parameters(model.parameters.with_values(result.values))
        result = estimator(start, maneuvers, weights=weights, **options)
    return result, weights, max(int(max_rounds), 1)
