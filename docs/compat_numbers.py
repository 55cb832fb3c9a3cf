"""The measured numbers of docs/compat.md: the shipped flight-path reconstruction cases.

    python docs/compat_numbers.py [--data-dir DIR] [--record] [--write] [--check]

Runs ``attas_fpr_biases``, ``attas_fpr_segment_biases``, ``attas_fpr_scale_bias_delay`` and
``f18harv_dcmp_lon`` with ``flightid run CASE --json`` and prints, per case, the status,
Gauss–Newton passes and simulations, and each estimate ± its Cramér–Rao bound (the sensor
parameters, then the free initial states). About 1 minute on one core.
"""

from __future__ import annotations

import re

import case_numbers as cn


def _summary(entry: dict) -> str:
    return (
        f"{entry['status']} in {entry['iterations']} passes, "
        f"{entry['equivalent_evaluations']} simulations"
    )


def _cell(item: dict) -> str:
    return f"{cn.significant(item['value'], 6)} ± {cn.significant(item['std_cr'], 3)}"


def _free(entry: dict) -> list[dict]:
    return [p for p in entry["parameters"] if p["free"]]


def _unit(item: dict) -> str:
    return f" ({item['unit']})" if item.get("unit") else ""


def _is_initial_state(item: dict) -> bool:
    return item["name"].startswith("x0")


def single(case: str, data_dir: str | None) -> str:
    """The summary line, the sensor parameters and the free initial states of one case."""
    entry = cn.run(case, data_dir)["results"][-1]
    sensors = [p for p in _free(entry) if not _is_initial_state(p)]
    states = [p for p in _free(entry) if _is_initial_state(p)]
    rows = [[p["name"] + _unit(p), _cell(p)] for p in sensors]
    text = f"{_summary(entry)}:\n\n{cn.table(['parameter', 'estimate ± CR bound'], rows)}"
    if states:
        rows = [[p["name"] + _unit(p), _cell(p)] for p in states]
        text += "\n\n" + cn.table(["initial state", "estimate ± CR bound"], rows)
    return text


def per_segment(case: str, data_dir: str | None) -> str:
    """The biases per segment (``b_ax_1`` … ``b_r_3``) as one row per segment."""
    entry = cn.run(case, data_dir)["results"][-1]
    table: dict[str, dict[str, str]] = {}
    units: dict[str, str] = {}
    for item in _free(entry):
        match = re.fullmatch(r"(.+)_(\d+)", item["name"])
        if match is None:
            continue
        bias, segment = match.groups()
        table.setdefault(segment, {})[bias] = (
            f"{cn.significant(item['value'], 5)} ± {cn.significant(item['std_cr'], 2)}"
        )
        units[bias] = _unit(item)
    biases = list(units)
    maneuvers = [m.get("name", str(i + 1)) for i, m in enumerate(entry.get("maneuvers", []))]
    rows = []
    for index, (segment, values) in enumerate(sorted(table.items(), key=lambda s: int(s[0]))):
        label = f"{segment} {maneuvers[index]}" if index < len(maneuvers) else segment
        rows.append([label, *(values[b] for b in biases)])
    heading = ["segment", *(b + units[b] for b in biases)]
    return f"{_summary(entry)}:\n\n{cn.table(heading, rows)}"


def against_sidpac(data_dir: str | None) -> str:
    """``f18harv_compat_lon`` and ``_lat`` against SIDPAC's own results stored in the data
    files (``pc``, Cramér–Rao covariance ``crbc``, names ``p_names``): both estimates ± CR
    bound, their difference in SIDPAC's bounds and the ratio of the bounds."""
    import numpy as np
    import scipy.io

    from flightid.data.location import data_directory

    folder = data_directory(cn.CASES, None, data_dir)
    rows = []
    for short, case, file in (
        ("lon", "f18harv_compat_lon", "compat_lon_example.mat"),
        ("lat", "f18harv_compat_lat", "compat_lat_example.mat"),
    ):
        entry = cn.run(case, data_dir)["results"][-1]
        reference = scipy.io.loadmat(folder / "sidpac_f18harv" / file)
        sigmas = np.sqrt(np.diag(reference["crbc"]))
        names = [str(n).strip().replace(" ", "_") for n in reference["p_names"]]
        label = (
            f"{short} ({entry['iterations']} passes, {entry['equivalent_evaluations']} evaluations)"
        )
        for name, value, sigma in zip(names, reference["pc"].ravel(), sigmas, strict=True):
            item = cn.parameter(entry, name)
            # (θ_flightid − θ_SIDPAC) / σ_SIDPAC and σ_flightid / σ_SIDPAC
            difference = (item["value"] - value) / sigma
            rows.append(
                [
                    label,
                    name + _unit(item),
                    f"{cn.significant(item['value'], 6)} ± {cn.significant(item['std_cr'], 4)}",
                    f"{cn.significant(value, 6)} ± {cn.significant(sigma, 4)}",
                    f"{difference:+.3f}".replace("-", "−"),
                    f"{item['std_cr'] / sigma:.4f}",
                ]
            )
            label = ""
    heading = ["case", "parameter", "flightid", "SIDPAC", "Δ / σ", "σ ratio"]
    return cn.table(heading, rows)


def build(data_dir: str | None) -> list[str]:
    return [
        cn.region("compat-f18-against-sidpac", against_sidpac(data_dir)),
        cn.region("compat-attas-fpr-biases", single("attas_fpr_biases", data_dir)),
        cn.region(
            "compat-attas-fpr-segment-biases", per_segment("attas_fpr_segment_biases", data_dir)
        ),
        cn.region(
            "compat-attas-fpr-scale-bias-delay", single("attas_fpr_scale_bias_delay", data_dir)
        ),
        cn.region("compat-f18-dcmp-lon", single("f18harv_dcmp_lon", data_dir)),
    ]


if __name__ == "__main__":
    raise SystemExit(cn.main("compat.md", "compat_numbers", build))
