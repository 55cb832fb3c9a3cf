"""Low-order equivalent system of the ATTAS short period from the frequency-domain estimate.

Fits q/δe = K_q (s + 1/T_θ2) e^{−τs} / (s² + 2ζω s + ω²) (``flightid.frequency.loes``,
MIL-STD-1797A cost) to two responses on 0.1–1.5 Hz:

* the identified model's q/δe, C(jωI − A)⁻¹B from
  examples/cases/attas_short_period_frequency_domain.toml (a second-order model: the fit
  should be exact with τ ≈ 0, and ω_sp, ζ_sp equal to the eigenvalues of A);
* the measured ratio Q(ω)/Δe(ω) of the finite Fourier transforms of both maneuvers.

Usage::

    python bench/frequency_loes.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from flightid.cases import load_case
from flightid.cases.frequency_case import run_frequency_case
from flightid.frequency import short_period_loes

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    result = run_frequency_case(
        load_case(ROOT / "examples/cases/attas_short_period_frequency_domain.toml")
    )
    f = result.frequencies_hz
    omega = 2 * np.pi * f
    q_index = result.outputs.index("q")
    model = result.model_transfer(f)[:, q_index, 0]
    eigenvalues = np.linalg.eigvals(result.system.A)
    wn = float(np.sqrt(np.prod(eigenvalues).real))
    zeta = float(-np.sum(eigenvalues).real / (2 * wn))
    print(f"eigenvalues of the identified A: omega_sp = {wn:.4f} rad/s, zeta_sp = {zeta:.4f}")
    fit, values = short_period_loes(omega, model, gain_start=-7.0, frequency_start_rad_s=2.0)
    print("LOES fit to the identified model's q/de:", _text(values), f"J = {fit.cost:.3g}")
    w_all = np.concatenate([omega for _ in result.spectra])
    ratio = np.concatenate([s.outputs[:, q_index] / s.inputs[:, 0] for s in result.spectra])
    order = np.argsort(w_all, kind="stable")
    fit, values = short_period_loes(
        w_all[order], ratio[order], gain_start=-7.0, frequency_start_rad_s=2.0
    )
    print("LOES fit to the measured Q/De ratio:", _text(values), f"J = {fit.cost:.3g}")


def _text(values: dict) -> str:
    return ", ".join(f"{k} = {v:.4g}" for k, v in values.items())


if __name__ == "__main__":
    main()
