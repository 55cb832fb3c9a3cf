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


def build(data_dir: str | None) -> list[str]:
    return [
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
