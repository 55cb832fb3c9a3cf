"""The measured numbers of docs/turbulence.md: output error against filter error in turbulence,
MNR against MNRES, the generic against the linear filter, and the other filter-error cases.

    python docs/turbulence_numbers.py [--data-dir DIR] [--record] [--write] [--check]

Runs with ``flightid run CASE --json``: ``y13aus_lateral_output_error``,
``y13aus_lateral_filter_error`` (fixed point with MNR, with MNRES, and with the reference's
relaxation schedule), ``y13aus_lateral_filter_error_linear``, ``hfb320_longitudinal_filter_
error`` and ``unstab_sp_filter_error`` (each with MNR and MNRES). About 4 minutes on one
core. Wall times (the whole process's) are not compared by the tests.
"""

from __future__ import annotations

import case_numbers as cn

MNRES = {'solver = "mnr"': 'solver = "mnres"'}
REFERENCE = {'relaxation = "fixed_point"': 'relaxation = "reference"'}


def _entry(output: dict) -> dict:
    return output["results"][-1]


def _evaluations(entry: dict, bounds: bool = True) -> str:
    text = str(entry["equivalent_evaluations"])
    if bounds and entry.get("accuracy_evaluations"):
        text += f" (+ {entry['accuracy_evaluations']} for the bounds)"
    return text


def _ln_det(entry: dict, digits: int = 6) -> str:
    return cn.significant(cn.ln_det_r(entry), digits)


def y13aus(data_dir: str | None) -> list[str]:
    runs = {
        "output error, MNR": cn.run("y13aus_lateral_output_error", data_dir),
        "filter error, fixed point, MNR": cn.run("y13aus_lateral_filter_error", data_dir),
        "filter error, fixed point, MNRES": cn.run(
            "y13aus_lateral_filter_error", data_dir, MNRES, allow_failure=True
        ),
        "filter error, reference schedule": cn.run(
            "y13aus_lateral_filter_error", data_dir, REFERENCE
        ),
    }
    heading = ["run", "status", "filter passes / evaluations", "ln det R", "wall (s)"]
    rows = []
    for name, output in runs.items():
        if "error" in output:
            rows.append([name, "fails", "—", "—", "—"])
            continue
        entry = _entry(output)
        rows.append([name, entry["status"], _evaluations(entry), _ln_det(entry)])
        rows[-1].append(f"{output['wall_s']:.1f}")
    named = list(runs.values())
    oe, fe, reference = _entry(named[0]), _entry(named[1]), _entry(named[3])
    estimates = []
    for item in fe["parameters"]:
        if not item["free"]:
            continue
        name = item["name"]
        oe_item = next((p for p in oe["parameters"] if p["name"] == name), None)
        # (θ_OE − θ_FE) / σ_FE, σ_FE the filter error's Cramér–Rao bound
        z = "—"
        if oe_item is not None:
            z = f"{(oe_item['value'] - item['value']) / item['std_cr']:+.1f}"
        estimates.append(
            [
                name,
                "—" if oe_item is None else cn.estimate(oe_item),
                cn.estimate(item),
                cn.estimate(cn.parameter(reference, name)),
                z.replace("-", "−"),
            ]
        )
    heading_estimates = ["parameter", "output error", "filter error (fixed point, MNR)"]
    heading_estimates += ["filter error (reference)", "(OE − FE)/σ_FE"]
    return [
        cn.region("turbulence-y13aus-runs", cn.table(heading, rows)),
        cn.region("turbulence-y13aus-estimates", cn.table(heading_estimates, estimates)),
    ]


def solvers(data_dir: str | None) -> tuple[str, dict]:
    rows, kept = [], {}
    for case in (
        "y13aus_lateral_filter_error",
        "hfb320_longitudinal_filter_error",
        "unstab_sp_filter_error",
    ):
        mnr = _entry(cn.run(case, data_dir))
        mnres_output = cn.run(case, data_dir, MNRES, allow_failure=True)
        kept[case] = mnr
        free = sum(p["free"] for p in mnr["parameters"])
        row = [f"{case} ({free} free parameters)", str(mnr["equivalent_evaluations"])]
        if "error" in mnres_output:
            row += ["fails", mnres_output["error"].removeprefix("flightid: error: ")]
        else:
            mnres = _entry(mnres_output)
            difference = abs(cn.ln_det_r(mnr) - cn.ln_det_r(mnres))
            row += [str(mnres["equivalent_evaluations"]), f"ln det R differ by {difference:.0e}"]
        rows.append(row)
    table = cn.table(["case", "MNR", "MNRES", "same optimum"], rows)
    return cn.region("turbulence-mnr-mnres", table), kept


def linear(data_dir: str | None, generic: dict) -> str:
    output = cn.run("y13aus_lateral_filter_error_linear", data_dir)
    analytic = _entry(output)
    largest, where = 0.0, []
    for item in analytic["parameters"]:
        if not item["free"]:
            continue
        # |θ_generic − θ_linear| / σ_linear
        d = abs(cn.parameter(generic, item["name"])["value"] - item["value"]) / item["std_cr"]
        if d > largest + 5e-4:
            largest, where = d, [item["name"]]
        elif abs(d - largest) <= 5e-4:
            where.append(item["name"])
    rows = [
        ["status", *(f"{e['status']}, {e['noise_cycles']} R cycles" for e in (generic, analytic))],
        ["Gauss–Newton iterations", str(generic["iterations"]), str(analytic["iterations"])],
        [
            "filter passes (optimiser)",
            str(generic["equivalent_evaluations"]),
            str(analytic["equivalent_evaluations"]),
        ],
        ["cost Σ eᵀR⁻¹e at the end", f"{generic['cost']:.8g}", f"{analytic['cost']:.8g}"],
        ["largest difference of estimates", "", f"{largest:.2g} σ ({', '.join(where)})"],
    ]
    return cn.region(
        "turbulence-linear", cn.table(["", "generic (RK4, differences)", "linear, analytic"], rows)
    )


def estimates_table(entry: dict) -> str:
    rows = [
        [p["name"], f"{cn.significant(p['value'], 6)} ± {cn.significant(p['std_cr'], 3)}"]
        for p in entry["parameters"]
        if p["free"]
    ]
    return cn.table(["parameter", "estimate ± CR bound"], rows)


def build(data_dir: str | None) -> list[str]:
    regions = y13aus(data_dir)
    region, kept = solvers(data_dir)
    regions.append(region)
    regions.append(linear(data_dir, kept["y13aus_lateral_filter_error"]))
    for case, name in (
        ("hfb320_longitudinal_filter_error", "turbulence-hfb320"),
        ("unstab_sp_filter_error", "turbulence-unstab"),
    ):
        entry = kept[case]
        line = (
            f"{entry['status']}, {entry['equivalent_evaluations']} filter passes, "
            f"ln det R = {_ln_det(entry)}"
        )
        regions.append(cn.region(name, f"{line}\n\n{estimates_table(entry)}"))
    return regions


if __name__ == "__main__":
    raise SystemExit(cn.main("turbulence.md", "turbulence_numbers", build))
