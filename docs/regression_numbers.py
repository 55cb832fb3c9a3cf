"""The measured numbers of docs/regression.md: least squares on the unstable aircraft, and the
Twin Otter stepwise regression carried into output error.

    python docs/regression_numbers.py [--data-dir DIR] [--record] [--write] [--check]

Runs ``unstab_sp_equation_error_ls``, ``unstab_sp_equation_error_tls`` and
``twin_otter_stepwise`` with ``flightid run CASE --json`` and prints: the OLS and TLS
estimates ± the regression standard error √diag(s²(XᵀX)⁻¹) and TLS's errors-in-variables σ;
per coefficient of the stepwise stage the selected terms, R², s², PSE, each term's estimate,
standard error and partial F (= t², t = estimate / standard error) and the steps of the
selection; the output-error stage's status and its estimates ± Cramér–Rao bound beside the
regression's. About 30 seconds on one core.
"""

from __future__ import annotations

import case_numbers as cn

TERMS = {
    "1": "1",
    "alpha": "α",
    "qhat": "q̂",
    "de": "δe",
    "alpha^2": "α²",
    "alpha*de": "α·δe",
    "alpha*qhat": "α·q̂",
}
UNSTABLE_NAMES = ("Zw", "Zq", "Zδe", "Mw", "Mq", "Mδe")


def _coefficients(output: dict) -> dict:
    items = {}
    for coefficient in output["stages"][0]["coefficients"].values():
        items.update({p["name"]: p for p in coefficient["parameters"]})
    return items


def least_squares(data_dir: str | None) -> str:
    ols = _coefficients(cn.run("unstab_sp_equation_error_ls", data_dir))
    tls = _coefficients(cn.run("unstab_sp_equation_error_tls", data_dir))
    rows = []
    for name in UNSTABLE_NAMES:
        a, b = ols[name], tls[name]
        rows.append(
            [
                name,
                f"{cn.significant(a['value'], 7)} ± {cn.significant(a['std_cr'], 2)}",
                f"{cn.significant(b['value'], 7)} ± {cn.significant(b['std_ols'], 2)}",
                cn.significant(b["std_eiv"], 2),
            ]
        )
    return cn.table(["parameter", "OLS (3g)", "TLS (3h)", "σ_eiv (TLS)"], rows)


def _term(name: str) -> str:
    return TERMS.get(name, name)


def stepwise(coefficient: dict, label: str) -> str:
    """Summary line, term table and steps of one coefficient's stepwise selection."""
    selected = ", ".join(_term(t) for t in coefficient["selected"])
    head = (
        f"**{label}** — selected {selected}; R² = {coefficient['r2']:.6g}, "
        f"s² = {coefficient['s2']:.4g}, PSE = {coefficient['pse']:.4g}:"
    )
    rows = []
    for item in coefficient["parameters"]:
        # partial F = t², t = θ̂ / σ̂ (σ̂ = √diag(s²(XᵀX)⁻¹))
        partial_f = (item["value"] / item["std_cr"]) ** 2
        rows.append(
            [
                _term(item["name"]),
                cn.significant(item["value"], 5),
                cn.significant(item["std_cr"], 3),
                cn.significant(partial_f, 4),
            ]
        )
    steps = []
    for step in coefficient["steps"]:
        if step["action"] == "start":
            continue
        verb = "enters" if step["action"] == "enter" else "leaves"
        steps.append(f"{_term(step['term'])} {verb} (F {cn.significant(step['partial_f'], 4)})")
    table = cn.table(["term", "estimate", "std error", "partial F"], rows)
    return f"{head}\n\n{table}\n\nSteps: {', '.join(steps)}."


def twin_otter(data_dir: str | None) -> list[str]:
    output = cn.run("twin_otter_stepwise", data_dir)
    coefficients = output["stages"][0]["coefficients"]
    regions = [
        cn.region("regression-twin-otter-cm", stepwise(coefficients["Cm"], "C_m")),
        cn.region("regression-twin-otter-cz", stepwise(coefficients["CZ"], "C_Z")),
    ]
    entry = output["results"][-1]
    regression = {}
    for name, coefficient in coefficients.items():
        for item, ml_name in zip(
            coefficient["parameters"],
            [p for p in output["stages"][1]["start"] if p.startswith(name + "_")],
            strict=True,
        ):
            regression[ml_name] = item
    rows = []
    for item in entry["parameters"]:
        if not item["free"]:
            continue
        start = regression[item["name"]]
        rows.append(
            [
                item["name"],
                f"{cn.significant(start['value'], 5)} ± {cn.significant(start['std_cr'], 3)}",
                f"{cn.significant(item['value'], 5)} ± {cn.significant(item['std_cr'], 3)}",
            ]
        )
    line = (
        f"{entry['status']} in {entry['iterations']} iterations, "
        f"{entry['equivalent_evaluations']} equivalent evaluations "
        f"(+{entry['accuracy_evaluations']} for the information matrix):"
    )
    table = cn.table(["parameter", "regression ± std", "ML ± CR bound"], rows)
    regions.append(cn.region("regression-twin-otter-ml", f"{line}\n\n{table}"))
    return regions


def build(data_dir: str | None) -> list[str]:
    return [cn.region("regression-unstable-ls", least_squares(data_dir)), *twin_otter(data_dir)]


if __name__ == "__main__":
    raise SystemExit(cn.main("regression.md", "regression_numbers", build))
