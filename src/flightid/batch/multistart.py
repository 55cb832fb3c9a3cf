"""Multistart estimation: one case from many start points on the batch engine, the optima
clustered.

A likelihood surface can hold more than one minimum (a nonlinear model, little excitation,
correlated parameters); a single Gauss–Newton run finds the one its start value leads to.
``multistart`` runs the case's estimation from ``n_starts`` start points — the case's own
start values first, then seeded random perturbations of its free parameters,

    θ_j⁽ᵏ⁾ = θ_j⁽⁰⁾ · (1 + s·z_jk)      (θ_j⁽⁰⁾ ≠ 0)
    θ_j⁽ᵏ⁾ = s·z_jk                      (θ_j⁽⁰⁾ = 0),   z_jk ~ N(0, 1), k = 1 … n − 1,

clipped to the parameter's bounds (parameter units; ``s`` = ``spread``, dimensionless) —
as independent tasks on the engine of ``flightid batch`` (serial or Dask), each through
``flightid.cases.run_case`` with the start values set in the case's ``[parameters]``, without
accuracy assessment. The optima are then clustered: sorted by the negative log-likelihood
−ln L = ½ J + ½ N ln det R + const (J the ML cost Σ νᵀR⁻¹ν, N samples per output: with R
estimated J is the same at every optimum and ln det R ranks them), a run joins the first
cluster whose best member differs from it by less than ``tol_sigma`` Cramér–Rao σ (of that
best member) in every free parameter; otherwise it starts a new cluster. One cluster holding
the converged runs says the start does not matter; several clusters, or a best cluster the
case's own start missed, say it does.

Per-maneuver parameters (``per_maneuver = true``) keep their start values.
"""

from __future__ import annotations

import copy
import math
import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from flightid.batch.plan import BatchError

__all__ = [
    "Cluster",
    "MultistartResult",
    "cluster_optima",
    "multistart",
    "start_points",
    "write_multistart_csv",
]


@dataclass(frozen=True)
class StartTask:
    """One start point of a multistart run (picklable)."""

    index: int
    raw: dict
    path: Path
    start: dict[str, float]
    data_dir: str | None = None


@dataclass(frozen=True)
class Cluster:
    """Runs that ended at the same optimum.

    Attributes:
        members: start indices, best (lowest −ln L) first.
        neg_log_likelihood: the best member's −ln L (up to a constant: ½ J + ½ N ln det R).
        values: the best member's estimates, free parameters (parameter units).
        std: their default σ (``Estimate.std``: coloured-residual σ where the residuals are
            coloured, else Cramér–Rao; parameter units).
    """

    members: tuple[int, ...]
    neg_log_likelihood: float
    values: dict[str, float]
    std: dict[str, float]


@dataclass(frozen=True)
class MultistartResult:
    """The runs (one dict per start: index, start, values, std, cost, converged, status,
    error) and their clusters, best first."""

    runs: tuple[dict[str, Any], ...]
    clusters: tuple[Cluster, ...] = field(default_factory=tuple)
    engine: str = ""

    def summary(self) -> str:
        """One line per cluster: members, cost, and the values of the best member."""
        ok = sum(r.get("error") is None for r in self.runs)
        lines = [f"{len(self.runs)} starts, {ok} finished, {len(self.clusters)} optimum/optima"]
        for i, c in enumerate(self.clusters, start=1):
            values = ", ".join(f"{k} {v:.5g}" for k, v in c.values.items())
            lines.append(
                f"  {i}: {len(c.members)} start(s) {list(c.members)}, "
                f"-ln L {c.neg_log_likelihood:.10g}"
            )
            lines.append(f"     {values}")
        return "\n".join(lines)


def start_points(
    names: Sequence[str],
    values: Sequence[float],
    n_starts: int,
    spread: float = 0.3,
    seed: int = 0,
    bounds: Sequence[tuple[float, float]] | None = None,
) -> list[dict[str, float]]:
    """The start points (name → value, parameter units): the given values first, then
    ``n_starts − 1`` seeded perturbations (see the module docstring).

    Raises:
        BatchError: ``n_starts`` < 1 or ``spread`` not a positive finite number.
    """
    if n_starts < 1:
        raise BatchError(f"n_starts: expected a number ≥ 1, got {n_starts}")
    if not (math.isfinite(spread) and spread > 0):
        raise BatchError(f"spread: expected a positive number, got {spread}")
    rng = np.random.default_rng(seed)
    theta0 = np.asarray(values, dtype=float)
    points = [dict(zip(names, theta0.tolist(), strict=True))]
    for _ in range(n_starts - 1):
        z = rng.standard_normal(theta0.size)
        theta = np.where(theta0 != 0.0, theta0 * (1.0 + spread * z), spread * z)
        if bounds is not None:
            theta = np.clip(theta, [b[0] for b in bounds], [b[1] for b in bounds])
        points.append(dict(zip(names, theta.tolist(), strict=True)))
    return points


def _run_start(task: StartTask) -> dict[str, Any]:
    """Estimate from one start point (on a worker); failures are data."""
    from flightid.cases.run import run_case
    from flightid.cases.spec import parse_case
    from flightid.errors import error_line

    record: dict[str, Any] = {"index": task.index, "start": task.start, "error": None}
    try:
        case = parse_case(task.raw, task.path)
        est = run_case(case, task.data_dir, accuracy="none").estimate
    except Exception as exc:  # a start that fails (diverges, ...) is recorded
        record["error"] = error_line(exc).removeprefix("flightid: error: ")
        return record
    free = [i for i, f in enumerate(est.free) if f]
    # −ln L up to a constant: ½ J + ½ N Σ_o ln R_oo, with J = Σ νᵀR⁻¹ν and N samples per
    # output; ranks the optima whether R was fixed (second term constant) or estimated
    # (program MAX: J = N·n_o at every optimum, the first term constant)
    r_diag = np.asarray(est.r_diag, dtype=float)
    n_samples = float(est.n_data) / max(r_diag.size, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        nll = 0.5 * float(est.cost) + 0.5 * n_samples * float(np.sum(np.log(r_diag)))
    record.update(
        values={est.names[i]: float(est.values[i]) for i in free},
        std={est.names[i]: float(est.std[i]) for i in free},
        cost=float(est.cost),
        neg_log_likelihood=nll if math.isfinite(nll) else math.inf,
        converged=bool(est.converged),
        status=str(est.status),
    )
    return record


def cluster_optima(runs: Sequence[dict[str, Any]], tol_sigma: float = 0.1) -> list[Cluster]:
    """Cluster the finished runs by their optimum (see the module docstring), best first."""
    done = sorted(
        (r for r in runs if r.get("error") is None and math.isfinite(r["neg_log_likelihood"])),
        key=lambda r: (r["neg_log_likelihood"], r["index"]),
    )
    groups: list[list[dict[str, Any]]] = []
    for run in done:
        for group in groups:
            best = group[0]
            if all(
                abs(run["values"][k] - v) <= tol_sigma * best["std"][k]
                if math.isfinite(best["std"][k]) and best["std"][k] > 0
                else run["values"][k] == v
                for k, v in best["values"].items()
            ):
                group.append(run)
                break
        else:
            groups.append([run])
    return [
        Cluster(
            tuple(r["index"] for r in g),
            g[0]["neg_log_likelihood"],
            dict(g[0]["values"]),
            dict(g[0]["std"]),
        )
        for g in groups
    ]


def multistart(
    case_path: str | Path,
    n_starts: int,
    *,
    spread: float = 0.3,
    seed: int = 0,
    tol_sigma: float = 0.1,
    engine: Any = None,
    workers: int | None = None,
    scheduler: str | None = None,
    data_dir: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
) -> MultistartResult:
    """Run a case from ``n_starts`` start points on the batch engine; cluster the optima.

    Args:
        case_path: the case file.
        n_starts: start points, the case's own first.
        spread: relative standard deviation of the perturbations (dimensionless).
        seed: seed of the perturbations.
        tol_sigma: clustering tolerance, Cramér–Rao σ of the best member.
        engine, workers, scheduler: as for ``run_batch`` (``flightid.batch.engine``).
        data_dir: the data directory (overrides the case's).
        progress: receives one-line progress messages.

    Raises:
        BatchError: bad arguments; CaseError and others from reading the case.
    """
    from flightid.batch.engine import make_engine
    from flightid.cases.run import prepare_case
    from flightid.cases.spec import load_case

    say = progress or (lambda message: None)
    path = Path(case_path).resolve()
    case = load_case(path)
    raw = tomllib.loads(path.read_text(encoding="utf-8"))
    section = raw.get("parameters", {})
    per_maneuver = {
        k for k, v in section.items() if isinstance(v, dict) and v.get("per_maneuver", False)
    }
    model = prepare_case(case, data_dir).model
    chosen = [
        p
        for p in model.parameters
        if p.free and p.name not in per_maneuver and p.name in model.parameters.names
    ]
    chosen = [p for p in chosen if not any(p.name.startswith(f"{m}_") for m in per_maneuver)]
    points = start_points(
        [p.name for p in chosen],
        [p.value for p in chosen],
        n_starts,
        spread,
        seed,
        [(p.lower, p.upper) for p in chosen],
    )
    directory = None if data_dir is None else str(Path(data_dir).expanduser().resolve())
    tasks = []
    for k, point in enumerate(points):
        variant = copy.deepcopy(raw)
        params = variant.setdefault("parameters", {})
        for name, value in point.items():
            entry = params.get(name)
            params[name] = {**entry, "value": value} if isinstance(entry, dict) else value
        tasks.append(StartTask(k, variant, path, point, directory))
    own = engine is None
    engine = engine or make_engine(workers, scheduler, len(tasks))
    say(f"multistart: {len(tasks)} start(s) of {len(chosen)} parameters; {engine.description}")
    runs = []
    try:
        for i, (_, record, exc) in enumerate(engine.map_unordered(_run_start, tasks), start=1):
            if exc is not None:
                raise exc
            runs.append(record)
            say(f"multistart: {i}/{len(tasks)} done")
    finally:
        if own:
            engine.close()
    runs.sort(key=lambda r: r["index"])
    return MultistartResult(tuple(runs), tuple(cluster_optima(runs, tol_sigma)), engine.description)


def write_multistart_csv(result: MultistartResult, path: Path) -> Path:
    """Write one row per start and free parameter: ``start`` (index), ``cluster`` (1 = the
    best optimum; empty for a failed start), ``parameter``, ``start_value``, ``value``,
    ``std`` (parameter units), ``neg_log_likelihood``, ``converged``, ``status``, ``error``.
    Written to a temporary name and renamed into place; returns ``path``."""
    import csv
    import io
    import os

    cluster_of = {m: i for i, c in enumerate(result.clusters, start=1) for m in c.members}
    columns = [
        "start",
        "cluster",
        "parameter",
        "start_value",
        "value",
        "std",
        "neg_log_likelihood",
        "converged",
        "status",
        "error",
    ]
    stream = io.StringIO()
    writer = csv.DictWriter(stream, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for run in result.runs:
        for name, start in run["start"].items():
            failed = run.get("error") is not None
            writer.writerow(
                {
                    "start": run["index"],
                    "cluster": cluster_of.get(run["index"], ""),
                    "parameter": name,
                    "start_value": start,
                    "value": "" if failed else run["values"].get(name, ""),
                    "std": "" if failed else run["std"].get(name, ""),
                    "neg_log_likelihood": "" if failed else run["neg_log_likelihood"],
                    "converged": "" if failed else run["converged"],
                    "status": "failed" if failed else run["status"],
                    "error": run.get("error") or "",
                }
            )
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(stream.getvalue(), encoding="utf-8")
    os.replace(tmp, path)
    return path
