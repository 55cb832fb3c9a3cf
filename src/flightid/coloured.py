"""Cramér–Rao bounds corrected for coloured (autocorrelated) residuals.

The plain bound C = M⁻¹ assumes white residuals. Output-error residuals from flight data are
coloured (unmodelled dynamics, turbulence), and then C is optimistic. The correction used by
flight-test tools (Morelli & Klein, *Aircraft System Identification*, 2nd ed., §6.4: the
"residual autocorrelation" method) replaces the information matrix in the middle of a
sandwich by the covariance of the score under the estimated residual autocorrelation:

    Cov(θ̂) = M⁻¹ [ Σ_i Σ_j G_iᵀ R⁻¹ R̂_ν(i − j) R⁻¹ G_j ] M⁻¹
    R̂_ν(k) = (1/N) Σ_i ν_i ν_{i+k}ᵀ          (n_o × n_o, k ≥ 0;  R̂_ν(−k) = R̂_ν(k)ᵀ)

With A_i = R⁻¹ G_i the double sum is S_0 + Σ_{k=1}^{L} (S_k + S_kᵀ), S_k = Σ_i A_iᵀ R̂_ν(k) A_{i+k}.

Truncation. The sum runs over |i − j| ≤ L. Far lags are estimated from few products and only
add noise, so they are left out. ``max_lag="auto"`` (the default) keeps the lags before the
first lag at which every output's normalised residual autocorrelation R̂_ν,kk(k)/R̂_ν,kk(0)
lies inside the white-noise band ±1.96/√N; white residuals therefore give L = 0 and
Cov = M⁻¹ R̂_ν(0)-weighted, i.e. the plain bound (scaled by s² when R is not R̂). An integer
``max_lag`` fixes L. Products never pair samples of different maneuvers. Beyond 64 lags the
k ≥ 1 terms are one FFT correlation per maneuver instead of a loop over the lags (the same sum,
in N log N instead of N·L).

The default σ of a time-domain estimate (``default_sigma``). Every time-domain estimator
(output error, filter error, equation-error regression) reports by default the σ that its
residuals support: when the automatic lag is L = 0 (the residuals are white at the first
lag) that is the Cramér–Rao bound itself; when L > 0 it is the coloured-residual σ above,
scaled by N·n_o/(N·n_o − n_p) as s² [5.30] scales the plain bound. The Cramér–Rao σ is kept
beside it (``std_cr``) either way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightid.errors import InputError

__all__ = [
    "DefaultSigma",
    "automatic_lag",
    "coloured_covariance",
    "complete_default_sigma",
    "default_sigma",
    "residual_autocovariance",
    "sigma_ratio",
]

# the names of the two kinds of default σ
COLOURED = "coloured"
CRAMER_RAO = "cramer_rao"


def _segments(maneuver_index: np.ndarray | None, n: int) -> list[slice]:
    if maneuver_index is None:
        return [slice(0, n)]
    index = np.asarray(maneuver_index)
    edges = np.flatnonzero(np.diff(index) != 0) + 1
    bounds = np.concatenate([[0], edges, [n]])
    return [slice(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]


def residual_autocovariance(
    residuals: np.ndarray, max_lag: int, maneuver_index: np.ndarray | None = None
) -> np.ndarray:
    """R̂_ν(k) = (1/N) Σ_i ν_i ν_{i+k}ᵀ for k = 0 … max_lag: (max_lag + 1, n_o, n_o).

    Args:
        residuals: ν (N, n_o), output units.
        max_lag: largest lag, samples.
        maneuver_index: (N,) maneuver of each sample; products stay within a maneuver.
    """
    nu = np.asarray(residuals, dtype=float)
    n, n_o = nu.shape
    gamma = np.zeros((max_lag + 1, n_o, n_o))
    for segment in _segments(maneuver_index, n):
        part = nu[segment]
        m = part.shape[0]
        lags = min(max_lag, m - 1) + 1
        if lags <= 32:
            for k in range(lags):
                # R̂_ν(k) += Σ_i ν_i ν_{i+k}ᵀ over this maneuver
                gamma[k] += part[: m - k].T @ part[k:]
        else:
            # the same sums for all lags at once: Σ_i ν_i,o ν_{i+k},q = IFFT(conj(F_o) F_q)[k]
            size = 1 << int(np.ceil(np.log2(2 * m)))
            spectrum = np.fft.rfft(part, n=size, axis=0)
            cross = np.fft.irfft(
                np.conj(spectrum)[:, :, None] * spectrum[:, None, :], n=size, axis=0
            )
            gamma[:lags] += cross[:lags]
    return gamma / n


def _output_autocovariance(
    nu: np.ndarray, max_lag: int, maneuver_index: np.ndarray | None
) -> np.ndarray:
    """The diagonal of R̂_ν(k), k = 0 … max_lag: (max_lag + 1, n_o) — each output with itself
    only (the lag rule needs no cross products, which cost n_o times as much)."""
    n, n_o = nu.shape
    gamma = np.zeros((max_lag + 1, n_o))
    for segment in _segments(maneuver_index, n):
        part = nu[segment]
        m = part.shape[0]
        lags = min(max_lag, m - 1) + 1
        if lags <= 32:
            for k in range(lags):
                # R̂_ν,oo(k) += Σ_i ν_i,o ν_{i+k},o over this maneuver
                gamma[k] += np.einsum("io,io->o", part[: m - k], part[k:])
        else:
            # Σ_i ν_i,o ν_{i+k},o = IFFT(|F_o|²)[k]
            size = 1 << int(np.ceil(np.log2(2 * m)))
            spectrum = np.fft.rfft(part, n=size, axis=0)
            gamma[:lags] += np.fft.irfft(np.abs(spectrum) ** 2, n=size, axis=0)[:lags]
    return gamma / n


def automatic_lag(
    residuals: np.ndarray, maneuver_index: np.ndarray | None = None, cap: int | None = None
) -> int:
    """L = (first lag where all outputs' |ρ(k)| < 1.96/√N) − 1; at most ``cap`` (default N/2)."""
    nu = np.asarray(residuals, dtype=float)
    n = nu.shape[0]
    cap = n // 2 if cap is None else min(cap, n - 1)
    autocovariance = _output_autocovariance(nu, cap, maneuver_index)
    variance = autocovariance[0].copy()
    variance[variance <= 0] = np.inf
    # ρ_kk(k) = R̂_ν,kk(k) / R̂_ν,kk(0)
    rho = autocovariance / variance[None, :]
    band = 1.96 / np.sqrt(n)
    quiet = np.all(np.abs(rho[1:]) < band, axis=1)
    if not quiet.any():
        return cap
    return int(np.argmax(quiet))  # first quiet lag k = argmax + 1, so L = k − 1 = argmax


# above this many lags the k ≥ 1 terms of the sandwich are one FFT correlation instead of a
# loop over the lags: the loop costs N·L, which is hours at N = 10⁵ with a long lag
_DIRECT_LAGS = 64
# complex numbers per FFT block (2²² ≈ 64 MiB): the parameters are taken in groups
_FFT_BLOCK = 1 << 22


def _forward_terms(part: np.ndarray, gamma: np.ndarray, lags: int) -> np.ndarray:
    """F_i = Σ_{k=1}^{L} R̂_ν(k) A_{i+k} for one maneuver (A_{i+k} = 0 past its end).

    Args:
        part: A over the maneuver, output-major (n_o, m, n_p).
        gamma: R̂_ν(k), (≥ L + 1, n_o, n_o).
        lags: L.
    Returns:
        (n_o, m, n_p).
    """
    n_o, m, n_p = part.shape
    forward = np.zeros_like(part)
    if lags <= _DIRECT_LAGS:
        for k in range(1, lags + 1):
            shifted = gamma[k] @ part[:, k:, :].reshape(n_o, (m - k) * n_p)
            forward[:, : m - k, :] += shifted.reshape(n_o, m - k, n_p)
        return forward
    # F_o,i,r = Σ_q Σ_k h_oq(k) A_q,i+k,r, h(k) = R̂_ν(k) for 1 ≤ k ≤ L (0 at k = 0): a
    # correlation, IFFT(conj(ĥ_oq) Â_q,r) with zero padding to ≥ m + L (no wrap-around)
    size = 1 << int(np.ceil(np.log2(m + lags + 1)))
    kernel = np.zeros((size, n_o, n_o))
    kernel[1 : lags + 1] = gamma[1 : lags + 1]
    kernel_hat = np.conj(np.fft.rfft(kernel, axis=0))  # (F, n_o, n_o)
    block = max(1, _FFT_BLOCK // (n_o * (size // 2 + 1)))
    for start in range(0, n_p, block):
        columns = slice(start, min(start + block, n_p))
        a_hat = np.fft.rfft(part[:, :, columns], n=size, axis=1)  # (n_o, F, b)
        product = np.einsum("foq,qfr->ofr", kernel_hat, a_hat)
        forward[:, :, columns] = np.fft.irfft(product, n=size, axis=1)[:, :m, :]
    return forward


def coloured_covariance(
    sensitivities: np.ndarray,
    residuals: np.ndarray,
    r_diag: np.ndarray,
    covariance: np.ndarray,
    max_lag: int | str = "auto",
    maneuver_index: np.ndarray | None = None,
) -> tuple[np.ndarray, int]:
    """Sandwich covariance of θ̂ under autocorrelated residuals, and the lag L used.

    Args:
        sensitivities: G at θ̂ (N, n_o, n_f).
        residuals: ν at θ̂ (N, n_o).
        r_diag: the R used in the cost (n_o,).
        covariance: M⁻¹ (n_f × n_f); undetermined parameters (inf) stay inf.
        max_lag: ``"auto"`` or an integer L ≥ 0 (samples).
        maneuver_index: (N,) maneuver numbers.
    Returns:
        (covariance (n_f × n_f), L).
    """
    g = np.asarray(sensitivities, dtype=float)
    nu = np.asarray(residuals, dtype=float)
    n = nu.shape[0]
    if g.shape[:2] != nu.shape:
        raise InputError(
            f"sensitivities: expected shape ({n}, {nu.shape[1]}, n_f) to match the residuals, "
            f"got {g.shape}"
        )
    if isinstance(max_lag, str):
        if max_lag != "auto":
            raise InputError(f"max_lag: expected 'auto' or an integer ≥ 0, got {max_lag!r}")
        lag = automatic_lag(nu, maneuver_index)
    else:
        lag = int(max_lag)
        if lag < 0 or lag != max_lag:
            raise InputError(f"max_lag: expected 'auto' or an integer ≥ 0, got {max_lag!r}")
        lag = min(lag, n - 1)
    covariance = np.asarray(covariance, dtype=float)
    ok = np.isfinite(np.diag(covariance))
    result = np.full(covariance.shape, np.inf)
    if not ok.any():
        return result, lag
    c = covariance[np.ix_(ok, ok)]
    # A_i = R⁻¹ G_i
    a = g[:, :, ok] / np.asarray(r_diag, dtype=float)[None, :, None]
    gamma = residual_autocovariance(nu, lag, maneuver_index)
    n_o = a.shape[1]
    middle = np.zeros((int(ok.sum()),) * 2)
    for segment in _segments(maneuver_index, n):
        # output-major copy (n_o, m, n_f): the rows of one output at lags k … m−1 are one
        # contiguous block, so R̂_ν(k) A_{i+k} for all i is a single matrix product
        part = np.ascontiguousarray(a[segment].transpose(1, 0, 2))
        m, n_p = part.shape[1], part.shape[2]
        # H_i = Σ_{k=0}^{L} R̂_ν(k) A_{i+k}   (terms with i + k beyond the maneuver left out)
        h = (gamma[0] @ part.reshape(n_o, m * n_p)).reshape(n_o, m, n_p)
        # the k ≥ 1 terms of H_i
        forward = _forward_terms(part, gamma, min(lag, m - 1))
        # S_0 = Σ_i A_iᵀ R̂_ν(0) A_i,  Σ_{k≥1} S_k = Σ_i A_iᵀ Σ_{k≥1} R̂_ν(k) A_{i+k}
        flat = part.reshape(n_o * m, n_p)
        s_0 = flat.T @ h.reshape(n_o * m, n_p)
        s_forward = flat.T @ forward.reshape(n_o * m, n_p)
        # S_0 + Σ_{k=1}^{L} (S_k + S_kᵀ)
        middle += s_0 + s_forward + s_forward.T
    # Cov = M⁻¹ [Σ_i Σ_j G_iᵀ R⁻¹ R̂_ν(i − j) R⁻¹ G_j] M⁻¹
    sandwich = c @ middle @ c
    result[np.ix_(ok, ok)] = 0.5 * (sandwich + sandwich.T)
    return result, lag


@dataclass(frozen=True)
class DefaultSigma:
    """The σ a time-domain estimate reports by default, and the facts behind the choice.

    Attributes:
        covariance: covariance of the free parameters behind ``std`` (n_f × n_f): the
            coloured-residual sandwich when ``kind`` is ``"coloured"``, else the Cramér–Rao
            covariance given. NaN rows stay NaN (parameters held on a bound), inf rows inf
            (undetermined parameters).
        std: √diag(covariance), (n_f,), parameter units.
        kind: ``"coloured"`` (residuals autocorrelated, L > 0) or ``"cramer_rao"``.
        lag: the automatic lag L (samples); 0 for white residuals.
        residuals_white: L = 0: every output's lag-1 autocorrelation inside ±1.96/√N.
    """

    covariance: np.ndarray
    std: np.ndarray
    kind: str
    lag: int
    residuals_white: bool | None


def complete_default_sigma(result, error: type[Exception]) -> None:
    """Complete a frozen result's default-σ fields (``std_cr``, ``covariance_default``,
    ``std_kind``) in its ``__post_init__``: a result made without a separate default σ has
    its plain σ as the default (``std_cr = std``, ``covariance_default = covariance``); a
    ``std_kind`` other than ``"coloured"`` or ``"cramer_rao"`` raises ``error``."""
    if result.std_cr is None:
        object.__setattr__(result, "std_cr", result.std)
    if result.covariance_default is None:
        object.__setattr__(result, "covariance_default", result.covariance)
    if result.std_kind not in (CRAMER_RAO, COLOURED):
        raise error(f"std_kind: expected {CRAMER_RAO!r} or {COLOURED!r}, got {result.std_kind!r}")


def sigma_ratio(std: np.ndarray, std_cr: np.ndarray) -> np.ndarray:
    """std / std_cr, NaN where either is not finite: how much the Cramér–Rao (classical) σ
    understates the default σ."""
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.asarray(std, dtype=float) / np.asarray(std_cr, dtype=float)
    return np.where(np.isfinite(ratio), ratio, np.nan)


def _std_of(covariance: np.ndarray) -> np.ndarray:
    """√diag(C) keeping NaN (held) and inf (undetermined) as they are."""
    diagonal = np.diag(covariance)
    with np.errstate(invalid="ignore"):
        return np.where(np.isfinite(diagonal), np.sqrt(np.abs(diagonal)), diagonal)


def default_sigma(
    sensitivities: np.ndarray,
    residuals: np.ndarray,
    r_diag: np.ndarray,
    covariance: np.ndarray,
    maneuver_index: np.ndarray | None = None,
) -> DefaultSigma:
    """The default σ of an estimate: Cramér–Rao for white residuals, coloured otherwise.

    Args:
        sensitivities: G at θ̂ over the data rows (N, n_o, n_f).
        residuals: ν at θ̂ (N, n_o), output units.
        r_diag: the R of the cost (n_o,).
        covariance: the Cramér–Rao covariance M⁻¹ (n_f × n_f); NaN rows for parameters held
            on a bound, inf rows for undetermined ones.
        maneuver_index: (N,) maneuver numbers; lags never cross a maneuver.
    Returns:
        ``DefaultSigma``. Residuals that are not all finite give the Cramér–Rao σ with
        ``residuals_white`` False (nothing can be said about their colour).
    """
    cr = np.asarray(covariance, dtype=float)
    nu = np.asarray(residuals, dtype=float)
    if nu.ndim != 2 or nu.shape[0] < 3 or not np.all(np.isfinite(nu)):
        return DefaultSigma(cr, _std_of(cr), CRAMER_RAO, 0, False)
    lag = automatic_lag(nu, maneuver_index)
    if lag == 0:
        return DefaultSigma(cr, _std_of(cr), CRAMER_RAO, 0, True)
    active = ~np.isnan(np.diag(cr))
    result = np.full(cr.shape, np.nan)
    if active.any():
        g = np.asarray(sensitivities, dtype=float)[:, :, active]
        sandwich, _ = coloured_covariance(
            g, nu, r_diag, cr[np.ix_(active, active)], lag, maneuver_index
        )
        n_data, n_free = nu.size, cr.shape[0]
        # R̂_ν(0) divides by N·n_o; × N·n_o/(N·n_o − n_p) as s² [5.30] does for the bound
        result[np.ix_(active, active)] = sandwich * (n_data / max(n_data - n_free, 1))
    return DefaultSigma(result, _std_of(result), COLOURED, int(lag), False)
