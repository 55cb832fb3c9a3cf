"""Frequency responses from data: auto/cross spectra, single- and multiple-input responses,
ordinary, partial and multiple coherence.

Smoothed spectral estimates come from Welch's method (``scipy.signal.csd``: segments of
``segment_s`` seconds, a Hann window, 50 % overlap), one-sided, so that for inputs u and
outputs y (Bendat & Piersol, *Random Data*, ch. 7; Tischler & Remple, *Aircraft and
Rotorcraft System Identification*, ch. 7–9; Morelli & Klein, ch. 10):

    single input (H1):   H(f) = G_uy(f) / G_uu(f)
    ordinary coherence:  γ²_uy(f) = |G_uy|² / (G_uu G_yy)      (1 for a noise-free linear system)

For several correlated inputs, the responses are the conditioned estimates

    H(f) = G_yu(f) G_uu(f)⁻¹        (n_y × n_u; G_uu the input cross-spectral matrix)

with the multiple coherence of an output with all inputs,

    γ²_y:u = G_yu G_uu⁻¹ G_uy / G_yy,

and the partial coherence of input i with y once the other inputs o are removed,

    G_ab·o = G_ab − G_ao G_oo⁻¹ G_ob,      γ²_iy·o = |G_iy·o|² / (G_ii·o G_yy·o).

Here G_ab is the cross-spectrum E[A* B] (scipy's ``csd(a, b)``), so that G_uy/G_uu is the
response of y to u.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import csd

from flightid.errors import InputError
from flightid.frequency.arguments import finite_number, real_array

__all__ = ["FrequencyResponse", "frequency_response", "spectral_matrix"]


@dataclass(frozen=True)
class FrequencyResponse:
    """Estimated responses and coherences.

    Attributes:
        frequencies_hz: (F,) Hz.
        response: (F, n_y, n_u) complex, output unit per input unit.
        coherence: (F, n_y, n_u) ordinary coherence γ²_{u_k y_j}.
        partial_coherence: (F, n_y, n_u) (equals ``coherence`` for one input).
        multiple_coherence: (F, n_y).
    """

    frequencies_hz: np.ndarray
    response: np.ndarray
    coherence: np.ndarray
    partial_coherence: np.ndarray
    multiple_coherence: np.ndarray

    @property
    def gain_db(self) -> np.ndarray:
        """20 log10 |H| (F, n_y, n_u), dB."""
        return 20.0 * np.log10(np.abs(self.response))

    @property
    def phase_deg(self) -> np.ndarray:
        """Phase of H, unwrapped along frequency (F, n_y, n_u), deg."""
        return np.rad2deg(np.unwrap(np.angle(self.response), axis=0))


def _channels(values: np.ndarray, argument: str, n: int | None = None) -> np.ndarray:
    x = real_array(values, argument, "real samples")
    x = x[:, None] if x.ndim == 1 else x
    if x.ndim != 2 or (n is not None and x.shape[0] != n):
        want = f"({n},) or ({n}, channels)" if n is not None else "(N,) or (N, channels)"
        raise InputError(f"{argument}: expected an array of shape {want}, got {np.shape(values)}")
    if not np.all(np.isfinite(x)):
        raise InputError(f"{argument}: expected finite samples")
    return x


def spectral_matrix(
    signals: np.ndarray, dt_s: float, segment_s: float, *, window: str = "hann"
) -> tuple[np.ndarray, np.ndarray]:
    """Welch estimates G (F, n, n), G[f, a, b] = E[A* B] one-sided, of the columns of
    ``signals`` (N, n), and the frequencies (F,) Hz."""
    x = _channels(signals, "signals")
    dt_s = finite_number(dt_s, "dt_s", positive=True)
    segment_s = finite_number(segment_s, "segment_s", positive=True)
    if not isinstance(window, str):
        raise InputError(f"window: expected a scipy.signal window name, got {window!r}")
    n_per_segment = int(round(segment_s / dt_s))
    if n_per_segment < 8 or n_per_segment > x.shape[0]:
        raise InputError(
            f"segment_s: expected a segment between {8 * dt_s:.3g} s and the record length "
            f"{x.shape[0] * dt_s:.3g} s, got {segment_s!r}"
        )
    n = x.shape[1]
    freqs = None
    G = None
    for a in range(n):
        for b in range(n):
            f, g = csd(
                x[:, a],
                x[:, b],
                fs=1.0 / dt_s,
                window=window,
                nperseg=n_per_segment,
                detrend="constant",
            )
            if G is None:
                freqs, G = f, np.empty((f.size, n, n), dtype=complex)
            G[:, a, b] = g
    return freqs, G


def frequency_response(
    inputs: np.ndarray,
    outputs: np.ndarray,
    dt_s: float,
    *,
    segment_s: float = 20.0,
    band_hz: tuple[float, float] | None = None,
    window: str = "hann",
) -> FrequencyResponse:
    """Frequency responses of ``outputs`` (N, n_y) to ``inputs`` (N, n_u) from Welch
    spectra with segments of ``segment_s`` s; ``band_hz`` keeps [low, high] only."""
    u = _channels(inputs, "inputs")
    y = _channels(outputs, "outputs", u.shape[0])
    n_u, n_y = u.shape[1], y.shape[1]
    freqs, G = spectral_matrix(np.hstack([u, y]), dt_s, segment_s, window=window)
    keep = freqs > 0
    if band_hz is not None:
        band = real_array(band_hz, "band_hz", "[low, high] in Hz")
        if band.shape != (2,) or not np.all(np.isfinite(band)) or not band[0] < band[1]:
            raise InputError(f"band_hz: expected [low, high] in Hz, low < high, got {band_hz!r}")
        lo, hi = band
        keep &= (freqs >= lo) & (freqs <= hi)
    if not keep.any():
        raise InputError(f"band_hz: no spectral line of the estimate falls in {band_hz}")
    freqs, G = freqs[keep], G[keep]
    Guu = G[:, :n_u, :n_u]
    Guy = G[:, :n_u, n_u:]  # E[U* Y]
    Gyy = np.real(np.einsum("fii->fi", G[:, n_u:, n_u:]))
    guu = np.real(np.einsum("fii->fi", Guu))
    if np.any(np.linalg.cond(Guu) > 1e12):
        raise InputError(
            "inputs: the input spectral matrix is singular at some frequency (inputs fully "
            "correlated or without power there); the responses cannot be separated"
        )
    # H(f) = G_yu G_uu⁻¹ with G_yu = G_uyᴴ … written as Hᵀ = G_uu⁻ᵀ... solve G_uuᵀ Hᵀ = G_uy
    # (G_uy[k, j] = E[U_k* Y_j]; H[j, k] solves Σ_k G_uu[l, k] H[j, k] = G_uy[l, j])
    H = np.linalg.solve(Guu, Guy).transpose(0, 2, 1)
    # γ²_uy = |G_uy|² / (G_uu G_yy)
    coherence = (np.abs(Guy) ** 2 / (guu[:, :, None] * Gyy[:, None, :])).transpose(0, 2, 1)
    # γ²_y:u = G_yu G_uu⁻¹ G_uy / G_yy
    multiple = np.real(np.einsum("fkj,fkj->fj", Guy.conj(), np.linalg.solve(Guu, Guy))) / Gyy
    partial = np.empty_like(coherence)
    for i in range(n_u):
        others = [k for k in range(n_u) if k != i]
        if not others:
            partial[:, :, i] = coherence[:, :, i]
            continue
        for j in range(n_y):
            full = np.concatenate([others, [i, n_u + j]])
            sub = G[:, full][:, :, full]
            o = len(others)
            Goo = sub[:, :o, :o]
            Gor = sub[:, :o, o:]  # others × (i, y)
            # G_ab·o = G_ab − G_ao G_oo⁻¹ G_ob
            cond = sub[:, o:, o:] - np.einsum("foa,fob->fab", Gor.conj(), np.linalg.solve(Goo, Gor))
            partial[:, j, i] = np.abs(cond[:, 0, 1]) ** 2 / (
                np.real(cond[:, 0, 0]) * np.real(cond[:, 1, 1])
            )
    return FrequencyResponse(freqs, H, coherence, partial, multiple)
