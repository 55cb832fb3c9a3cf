"""The measured numbers of docs/aircraft.md: the built-in HFB-320 model against the
hand-written module of the standard case.

    python docs/aircraft_numbers.py [--data-dir DIR] [--record] [--write] [--check]

Runs ``hfb320_longitudinal_builtin`` and ``hfb320_longitudinal`` with ``flightid run CASE
--json`` and prints each run's status, iterations, simulations and cost, and both estimates
± Cramér–Rao bound with their difference in bounds. About 30 seconds on one core.
"""

from __future__ import annotations

import case_numbers as cn

CASES = (("built-in", "hfb320_longitudinal_builtin"), ("module", "hfb320_longitudinal"))


def comparison(data_dir: str | None) -> str:
    entries = {label: cn.run(case, data_dir)["results"][-1] for label, case in CASES}
    lines = [
        f"{label}: {e['status']} in {e['iterations']} iterations, "
        f"{e['equivalent_evaluations']} simulations, cost {e['cost']:.6g}"
        for label, e in entries.items()
    ]
    builtin, module = entries["built-in"], entries["module"]
    rows = []
    for item in builtin["parameters"]:
        if not item["free"]:
            continue
        other = cn.parameter(module, item["name"])
        # (θ_built-in − θ_module) / σ_module, σ the Cramér–Rao bound
        difference = (item["value"] - other["value"]) / other["std_cr"]
        rows.append(
            [
                item["name"],
                f"{cn.significant(item['value'], 6)} ± {cn.significant(item['std_cr'], 3)}",
                f"{cn.significant(other['value'], 6)} ± {cn.significant(other['std_cr'], 3)}",
                f"{difference:+.4f}".replace("-", "−"),
            ]
        )
    table = cn.table(["parameter", "built-in", "module", "difference / σ"], rows)
    return "\n".join(f"* {line}" for line in lines) + "\n\n" + table


def build(data_dir: str | None) -> list[str]:
    return [cn.region("aircraft-hfb320-builtin", comparison(data_dir))]


if __name__ == "__main__":
    raise SystemExit(cn.main("aircraft.md", "aircraft_numbers", build))
