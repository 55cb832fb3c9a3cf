"""The reconstructed, corrected signals of a kinematic-model run, and their CSV files.

For each maneuver, at the estimated parameters θ̂ (``Reconstruction.columns``, in order):

* ``t [s]``: time;
* the corrected sensor inputs, named as the inputs (``ax`` … ``r``): the sensor model
  inverted, x = (m − x_ref − s·b)/f + x_ref (s = +1 or −1 by ``bias_convention``; b = 0 and
  f = 1 for a sensor without parameters);
* the other input channels as measured (``pdot`` …, measured kinematic quantities), and
  any further input channel the case declares (controls such as ``de``), carried along for
  the next case;
* the corrected measured outputs, named as the outputs (``V``, ``α`` …):
  z_corr(t) = (z(t + τ) − y_ref − s·b)/f + y_ref, where z(t + τ) undoes an output delay τ
  by linear interpolation between samples (the end samples held);
* ``<q>_rec``: the reconstruction: the integrated states u v w (when integrated) and the
  outputs V α β φ θ ψ h without sensor errors or delays, from the integrated and measured
  kinematic quantities (only those the model can compute);
* ``<o>_fit``: the model outputs as fitted to the data (sensor errors and delays included).

Units in brackets in the header (``α [rad]``); the next case reads the file as a CSV with
named columns (``column = "α_rec"``).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flightid.compat.kinematic import GROUND_OUTPUTS, OUTPUTS, SENSOR_INPUTS, KinematicSpec
from flightid.data.flightdata import FlightData
from flightid.errors import InputError
from flightid.model.statespace import StateSpaceModel
from flightid.simulation import simulate

__all__ = ["Reconstruction", "reconstruct", "write_reconstruction", "reconstruction_file_name"]


@dataclass(frozen=True)
class Reconstruction:
    """The signals of one maneuver: ``columns`` (header name → values) in file order."""

    maneuver: str
    columns: dict[str, np.ndarray]

    def write_csv(self, path: Path) -> Path:
        """Write the columns as CSV (header row ``name [unit]``, full precision)."""
        names = list(self.columns)
        data = np.column_stack([self.columns[n] for n in names]).astype(float)
        # every number as repr(float): the shortest text that reads back as the same double;
        # the rows converted a matrix at a time (tolist), not one numpy scalar at a time
        lines = [",".join(map(repr, row)) for row in data.tolist()]
        with open(path, "w", encoding="utf-8", newline="") as stream:
            stream.write(",".join(names) + "\n")
            if lines:
                stream.write("\n".join(lines) + "\n")
        return path


def _output_computable(spec: KinematicSpec, output: str) -> bool:
    """True when every kinematic quantity ``output`` reads is integrated or measured (the
    ground speeds and positions only in a model that has them)."""
    available = set(spec.states) | set(spec.inputs)
    if output in GROUND_OUTPUTS and not spec.has_ground:
        return False
    if output in ("V", "α", "β"):
        needs: tuple[str, ...] = (
            ("u", "v", "w", "φ", "θ", "ψ") if spec.has_wind else ("u", "v", "w")
        )
    elif output in GROUND_OUTPUTS[2:]:
        needs = ("u", "v", "w", "φ", "θ", "ψ")
    else:
        needs = (output,)
    return all(q in available for q in needs)


def _undelay(time: np.ndarray, values: np.ndarray, tau: float) -> np.ndarray:
    # z(t + τ), linear interpolation, the end samples held
    return np.interp(time + tau, time, values)


def reconstruct(
    spec: KinematicSpec,
    model: StateSpaceModel,
    maneuvers: Sequence[FlightData],
    theta: np.ndarray | None = None,
    *,
    method: str = "rk4",
    input_interpolation: str = "linear",
    compiled: bool = True,
) -> list[Reconstruction]:
    """The reconstructed, corrected signals of each maneuver (module docstring).

    Args:
        spec: the kinematic tables (``kinematic_spec``) of ``model``'s base model.
        model: the estimated model (its f may carry case wrappers; the base model's inputs
            and parameters must come first, as ``flightid.cases.build`` arranges them).
        maneuvers: the maneuvers the model was fitted to.
        theta: full parameter vector (default: the model's values).
        method: integration method, as in ``flightid.simulation``.
        input_interpolation: "linear" or "zoh", as in ``flightid.simulation``.
        compiled: run the compiled kernel.
    """
    theta = model.parameters.values if theta is None else np.asarray(theta, dtype=float)
    if len(model.parameters) < len(spec.parameters) or tuple(
        model.inputs[: len(spec.inputs)]
    ) != tuple(spec.inputs):
        raise InputError(
            "model: expected the kinematic model of spec (its inputs and parameters first), "
            f"got inputs {list(model.inputs)}"
        )
    names = spec.reconstruction_names
    # the same model (states, x0, wrappers, per-maneuver parameters, input delays) with h
    # returning the states, the error-free outputs and the corrected inputs, the outputs
    # undelayed; an input delay stays: the integration and the corrected inputs are those
    # of the fit (the inputs as the model read them, u(t − τ))
    changes = {
        "h": spec.reconstruction_function(),
        "outputs": tuple(f"rec_{i}" for i in range(len(names))),
        "output_delays": None,
    }
    auxiliary = dataclasses.replace(model, **changes)
    rec = simulate(
        auxiliary,
        list(maneuvers),
        theta,
        method=method,
        compiled=compiled,
        input_interpolation=input_interpolation,
    )
    fit = simulate(
        model,
        list(maneuvers),
        theta,
        method=method,
        compiled=compiled,
        input_interpolation=input_interpolation,
    )
    delays = {o: theta[model.parameters.index(p)] for o, p in model.output_delays.items()}
    n_x = len(spec.states)
    results = []
    start = 0
    for i, maneuver in enumerate(maneuvers):
        n = maneuver.n_samples
        block = rec[start : start + n]
        fitted = fit[start : start + n]
        # θ as f and h see it in maneuver i (per-maneuver parameters substituted)
        substitutes = getattr(model, "substitutes_parameters", False)
        theta_f = theta[model.function_theta_map(i)] if substitutes else theta
        start += n
        unit = spec.unit
        columns: dict[str, np.ndarray] = {"t [s]": np.asarray(maneuver.time, dtype=float)}
        for j, name in enumerate(SENSOR_INPUTS):
            columns[f"{name} [{unit(name)}]"] = block[:, n_x + len(OUTPUTS) + j]
        for name in spec.inputs[len(SENSOR_INPUTS) :]:
            columns[f"{name} [{unit(name)}]"] = np.asarray(maneuver.channel(name), dtype=float)
        # further input channels of the case (controls ...), carried along as measured
        for name in maneuver.input_names:
            if name not in model.inputs:
                label = maneuver.units.get(name, "")
                key = f"{name} [{label}]" if label else name
                columns[key] = np.asarray(maneuver.channel(name), dtype=float)
        for name in spec.outputs:
            z = np.asarray(maneuver.channel(name), dtype=float)
            if name in delays:
                z = _undelay(maneuver.time, z, float(delays[name]))
            columns[f"{name} [{unit(name)}]"] = spec.invert_output(name, z, theta_f)
        for j, name in enumerate(spec.states):
            if name in ("u", "v", "w"):  # (x_N, y_E come as x_N_rec, y_E_rec below)
                columns[f"{name}_rec [{unit(name)}]"] = block[:, j]
        for j, name in enumerate(OUTPUTS):
            if _output_computable(spec, name):
                columns[f"{name}_rec [{unit(name)}]"] = block[:, n_x + j]
        for j, name in enumerate(model.outputs):
            columns[f"{name}_fit [{unit(name)}]"] = fitted[:, j]
        results.append(Reconstruction(maneuver.name or f"maneuver_{i + 1}", columns))
    return results


def reconstruction_file_name(maneuver: str) -> str:
    """``reconstructed_<maneuver>.csv`` with characters other than letters, digits, ``-``,
    ``_`` and ``.`` replaced by ``_``."""
    return f"reconstructed_{re.sub(r'[^A-Za-z0-9_.-]', '_', maneuver)}.csv"


def write_reconstruction(run, directory: Path) -> list[Path]:
    """Write ``reconstructed_<maneuver>.csv`` for each maneuver of a kinematic case run
    (``flightid.cases.CaseRun``) into ``directory``; returns the paths (none for other
    models). The run carries the parsed case: ``run.kinematic_spec`` (the ``KinematicSpec``
    of its ``[model]``, None for other models) and ``run.input_interpolation``."""
    spec = run.kinematic_spec
    if spec is None:
        return []
    estimate = run.estimate
    theta = run.model.parameters.with_values(
        dict(zip(estimate.names, estimate.values, strict=True))
    ).values
    reconstructions = reconstruct(
        spec,
        run.model,
        run.maneuvers,
        theta,
        method=run.case.estimation.get("method", "rk4"),
        input_interpolation=run.input_interpolation,
        compiled=bool(run.case.estimation.get("compiled", True)),
    )
    return [
        r.write_csv(Path(directory) / reconstruction_file_name(r.maneuver)) for r in reconstructions
    ]
