"""Frequency-domain versus time-domain output error on the ATTAS flight data.

Runs the time-domain standard cases (examples/cases/attas_short_period.toml,
attas_lateral.toml: output error, RK4, R estimated) and their frequency-domain
counterparts (*_frequency_domain.toml: output error on 0.1–1.5 Hz), and prints a markdown
table per case: value ± σ_CR (the Cramér–Rao bound, ``std_cr``) of each, the
coloured-residual σ of each, and
z = (θ_fd − θ_td)/sqrt(σ_fd² + σ_td²) twice: with the Cramér–Rao σ of both (z_CR) and with
the coloured-residual σ of both (z_col: the time domain's from ``flightid.accuracy``
(docs/accuracy.md), the frequency domain's from ``frequency.output_error``); |z| ≤ 2 is
"agrees". On real data whose residuals are not white (the ATTAS residuals fail the
Ljung–Box test on every output) the Cramér–Rao σ are too small on both sides and z_col is
the comparison that means what it says. Parameters the frequency domain does not estimate
(constants, biases) are listed as such.

Usage::

    python bench/frequency_comparison.py [--band LOW HIGH]

``--band`` reruns the frequency-domain cases on another band (a sensitivity check; the case
files' band is 0.1–1.5 Hz).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from flightid.cases import load_case
from flightid.cases.frequency_case import run_frequency_case
from flightid.cases.run import run_case

ROOT = Path(__file__).resolve().parents[1]
PAIRS = [
    ("attas_short_period.toml", "attas_short_period_frequency_domain.toml"),
    ("attas_lateral.toml", "attas_lateral_frequency_domain.toml"),
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--band", nargs=2, type=float, default=None)
    args = parser.parse_args()
    for td_name, fd_name in PAIRS:
        td_case = load_case(ROOT / "examples/cases" / td_name)
        fd_case = load_case(ROOT / "examples/cases" / fd_name)
        if args.band is not None:
            table = dict(fd_case.frequency_domain)
            table["band_hz"] = list(args.band)
            fd_case = replace(fd_case, frequency_domain=table)
        started = time.perf_counter()
        # accuracy "cr": the Cramér–Rao and coloured-residual σ (std_coloured)
        td = run_case(td_case, None, accuracy="cr").to_dict()
        td_time = time.perf_counter() - started
        started = time.perf_counter()
        fd = run_frequency_case(fd_case, None).to_dict()
        fd_time = time.perf_counter() - started
        band = fd["frequency_domain"]["band_hz"]
        print(
            f"\n{td_name} (time domain, {td_time:.1f} s) vs {fd_name} "
            f"(band {band[0]:g}-{band[1]:g} Hz, {fd_time:.1f} s)\n"
        )
        print(
            "| parameter | time domain ± σ_CR (σ_col) | frequency domain ± σ_CR (σ_col) | "
            "z_CR | z_col | agrees (z_CR / z_col) |"
        )
        print("|---|---|---|---|---|---|")
        td_rows = {p["name"]: p for p in td["parameters"]}
        agree = agree_coloured = total = 0
        for p in fd["parameters"]:
            t = td_rows[p["name"]]
            if not p["estimated"]:
                print(
                    f"| {p['name']} | {t['value']:.5g} ± {t['std_cr']:.2g} | not estimated | | | |"
                )
                continue
            # z = (θ_fd − θ_td) / sqrt(σ_fd² + σ_td²), with Cramér–Rao and coloured σ
            z = (p["value"] - t["value"]) / np.hypot(p["std_cr"], t["std_cr"])
            z_col = (p["value"] - t["value"]) / np.hypot(p["std_coloured"], t["std_coloured"])
            ok, ok_col = abs(z) <= 2.0, abs(z_col) <= 2.0
            agree += ok
            agree_coloured += ok_col
            total += 1
            print(
                f"| {p['name']} | {t['value']:.5g} ± {t['std_cr']:.2g} ({t['std_coloured']:.2g}) | "
                f"{p['value']:.5g} ± {p['std_cr']:.2g} ({p['std_coloured']:.2g}) | {z:+.2f} | "
                f"{z_col:+.2f} | {'yes' if ok else 'no'} / {'yes' if ok_col else 'no'} |"
            )
        print(
            f"\n{agree} of {total} estimated parameters within 2 combined Cramér–Rao σ, "
            f"{agree_coloured} of {total} within 2 combined coloured-residual σ"
        )


if __name__ == "__main__":
    main()
