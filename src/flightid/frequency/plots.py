"""Figures of a frequency-domain result (matplotlib, imported lazily).

``bode_figure``: gain (dB) and phase (deg) of the identified model's transfer functions
C(jωI − A)⁻¹B + D for each output/input pair, with the empirical response Z(ω)/U(ω) (ratio
of the finite Fourier transforms, per maneuver) where the maneuver has one input.
``spectra_figure``: |Z(ω)| measured and |Ŷ(ω)| model per output, the quantities the
output-error cost compares.
"""

from __future__ import annotations

import numpy as np

__all__ = ["bode_figure", "spectra_figure"]


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def bode_figure(result, *, max_pairs: int = 6):
    """Bode plot of the model responses (and the data's where one input drives the
    maneuver); ``result`` is a ``FrequencyResult``."""
    plt = _pyplot()
    pairs = [
        (j, k)
        for j in range(len(result.outputs))
        for k in range(len(result.inputs))
        if result.model_response_has_signal(j, k)
    ][:max_pairs]
    fig, axes = plt.subplots(2, len(pairs), figsize=(3.2 * len(pairs), 5.0), squeeze=False)
    f_dense = np.linspace(result.frequencies_hz.min(), result.frequencies_hz.max(), 200)
    H = result.model_transfer(f_dense)
    for col, (j, k) in enumerate(pairs):
        gain, phase = axes[0, col], axes[1, col]
        h = H[:, j, k]
        gain.semilogx(f_dense, 20 * np.log10(np.abs(h)), "k-", lw=1.2, label="model")
        phase.semilogx(f_dense, np.rad2deg(np.unwrap(np.angle(h))), "k-", lw=1.2)
        if len(result.inputs) == 1:
            for m, (f, z, u) in enumerate(result.transforms()):
                ratio = z[:, j] / u[:, 0]
                ref = np.rad2deg(np.angle(result.model_transfer(f)[:, j, k]))
                # the data's phase, taken to the branch nearest the model's
                ph = np.rad2deg(np.angle(ratio))
                ph = ph + 360.0 * np.round((np.rad2deg(np.unwrap(np.deg2rad(ref))) - ph) / 360.0)
                label = f"data Z/U (maneuver {m + 1})"
                gain.semilogx(f, 20 * np.log10(np.abs(ratio)), ".", ms=4, label=label)
                phase.semilogx(f, ph, ".", ms=4)
        gain.set_title(f"{result.outputs[j]} / {result.inputs[k]}", fontsize=9)
        gain.set_ylabel("gain, dB")
        phase.set_ylabel("phase, deg")
        phase.set_xlabel("frequency, Hz")
        gain.grid(True, which="both", alpha=0.3)
        phase.grid(True, which="both", alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(f"{result.title}: frequency responses", fontsize=10)
    fig.tight_layout()
    return fig


def spectra_figure(result):
    """|Z(ω)| (measured) and |Ŷ(ω)| (model) per output, all maneuvers."""
    plt = _pyplot()
    n_y = len(result.outputs)
    fig, axes = plt.subplots(n_y, 1, figsize=(6.0, 1.8 * n_y + 0.6), squeeze=False, sharex=True)
    for m, (f, z, y) in enumerate(result.output_transforms()):
        for j in range(n_y):
            ax = axes[j, 0]
            ax.plot(f, np.abs(z[:, j]), ".", ms=4, label=f"measured {m + 1}")
            ax.plot(f, np.abs(y[:, j]), "-", lw=1.0, label=f"model {m + 1}")
            ax.set_ylabel(f"|{result.outputs[j]}|", fontsize=8)
            ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=7, ncol=2)
    axes[-1, 0].set_xlabel("frequency, Hz")
    fig.suptitle(f"{result.title}: output transforms", fontsize=10)
    fig.tight_layout()
    return fig
