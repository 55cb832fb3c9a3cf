"""Start-value robustness and tolerances: does every run reach the optimum or say it did not?

    python -P bench/start_robustness.py [--quick] [--only NAME ...]

Issue 10 §2. ``estimate`` reports ``converged`` only when the Gauss–Newton step from
central-difference sensitivities at the end point is at most ``Convergence.confirm_sigma``
(0.02) Cramér–Rao σ long, √(ΔθᵀMΔθ) ≤ 0.02. This script checks that promise from the
outside, against a reference optimum θ* computed once per problem by MNR with tight
tolerances, Convergence(cost_rtol=1e-8, param_rtol=1e-8, max_iterations=300), from the
problem's reference start; σ_j are that reference's Cramér–Rao bounds.

Part 1, start values. The five standard cases (examples/cases/*.toml except the stepwise
regression, on the real flight data) and RP-1153 example 3 cases 2 and 3 are
started from

  (a) zeros:  every aerodynamic parameter 0. "Aerodynamic" = every parameter of the case's
      model module (derivatives and the constant terms Z0, M0, L0, N0, C·0, C·o), never the
      state / output biases the case file adds (bx_*, by_*) nor initial states (x0_*);
      example 3: all 19 (its model has nothing else free);
  (b) ±50 %:  every free parameter of the reference start × (1 ± 0.5), half the signs +,
      half −, in an order shuffled by ``numpy.random.default_rng(SEED)``; and "+50 %": all
      × 1.5;
  (c) ×1e3:   one aerodynamic parameter × 1000: the one with the largest |θ_start,j|/σ_j
      (the start furthest from the optimum in σ after the change); when that start does not
      simulate (the estimation is refused at once), also (c′): the next parameter in that
      order whose × 1000 start does simulate;

each with MNRES (default settings) and MNR, under the problem's own settings (case file:
RK4, noise "max", Convergence(); example 3: ``run_example3``'s noise "max",
Convergence(max_iterations=200)). Verdict per run, d = max_j |θ̂_j − θ*_j|/σ_j:

  converged and d ≤ 0.1           reached (≤ 0.1 σ)
  not converged                   reported not converged (OK)
  converged and d > 0.1           WRONG: converged but > 0.1 σ      (a failure)
  a flightid error at the start   refused with a named error (OK: the start does not simulate)
  a flightid error later          ERROR DURING THE RUN (named)      (no wrong answer, but the
                                  estimation is lost instead of ending with a status)
  any other exception             UNNAMED ERROR                     (a failure)

Part 2, tolerances. Default Convergence() (MNRES and MNR) against the tight reference, for
every standard case, RP-1153 examples 1, 2 (cases 1, 2; Euler, R = I fixed as in the paper)
and 3 (cases 2, 3), and the book's unstable aircraft set-ups 3c ``unstab_sp_equation_
decoupling`` and 3e ``unstab_sp_eigenvalue_transform`` (the book's unstable-aircraft
case; data fvsysid/unStabAC_sim.asc; written below as f/h functions; noise "max"). Required:
d ≤ 0.05. For examples 1 and 2, whose R = I is fixed while the data's noise is 0 or
1e-4 / 1e-3, σ under that R says little; the table also gives d in σ computed with R̂ from
the reference's residuals (column "d, R̂"; for the noise-free example 1 that σ is at
rounding level).

``--quick``: ATTAS short period and Twin Otter only (starts a, c), and the tolerance study
on those two, examples 1–2 and 3c/3e. Wall times are per ``estimate`` call, numba kernels
compiled beforehand, one BLAS thread.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Iterator, Sequence  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from flightid.cases import load_case, prepare_case  # noqa: E402
from flightid.cases.build import build_convergence, build_solver  # noqa: E402
from flightid.cases.run import input_interpolation  # noqa: E402
from flightid.data import FlightData  # noqa: E402
from flightid.data.location import data_directory  # noqa: E402
from flightid.errors import FlightIdError  # noqa: E402
from flightid.estimation import MNR, MNRES, Convergence, Estimate, estimate  # noqa: E402
from flightid.estimation.gauss_newton import information_matrix  # noqa: E402
from flightid.model import Parameter, Parameters, StateSpaceModel  # noqa: E402
from flightid.simulation import simulate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DATA = data_directory(ROOT / "examples" / "cases")  # $FLIGHTID_DATA, else the cases' default
STANDARD_CASES = (
    "attas_short_period",
    "twin_otter_longitudinal",
    "hfb320_longitudinal",
    "attas_lateral",
    "attas_lateral_two_maneuvers",
)
QUICK_CASES = ("attas_short_period", "twin_otter_longitudinal")
TIGHT = Convergence(cost_rtol=1e-8, param_rtol=1e-8, max_iterations=300)
SEED = 10  # signs of the ±50 % start
REACHED_SIGMA = 0.1  # part 1: a converged run must be this close to θ* (σ)
TOLERANCE_SIGMA = 0.05  # part 2: default tolerances must stop this close to θ* (σ)
OFF_FACTOR = 1e3  # start (c)


@dataclass
class Problem:
    """One estimation problem: the model at its reference start, data and settings."""

    label: str
    model: StateSpaceModel
    data: list[FlightData]
    noise: str = "max"
    method: str = "rk4"
    R: Sequence[float] | None = None
    convergence: Convergence = field(default_factory=Convergence)
    interpolation: str = "linear"
    aero: tuple[str, ...] = ()  # the aerodynamic parameters (start a, c)

    def run(self, model: StateSpaceModel, solver, convergence: Convergence) -> Estimate:
        return estimate(
            model,
            self.data,
            solver,
            method=self.method,
            noise=self.noise,
            R=self.R,
            convergence=convergence,
            input_interpolation=self.interpolation,
        )

    def simulates(self, values: dict) -> bool:
        """Whether the model with these start values simulates finitely on the data."""
        model = self.model.with_parameters(self.model.parameters.with_values(values))
        try:
            y = simulate(
                model, self.data, method=self.method, input_interpolation=self.interpolation
            )
        except FlightIdError:
            return False
        return bool(np.all(np.isfinite(y)))

    def warm(self) -> None:
        """Compile the numba kernel (so compile time is not in any wall time)."""
        simulate(self.model, self.data, method=self.method, input_interpolation=self.interpolation)


# ---------------------------------------------------------------------------- problems


def case_problem(name: str) -> Problem:
    case = load_case(ROOT / "examples/cases" / f"{name}.toml")
    prepared = prepare_case(case, DATA)
    base = set(prepared.base.parameters.names)
    model = prepared.model
    # aerodynamic: the model module's parameters (not the case's biases / initial states)
    aero = tuple(n for n in model.parameters.free_names if n in base)
    solver = build_solver(case)
    if not isinstance(solver, MNRES):
        raise SystemExit(f"{name}: expected the case to run MNRES, it runs {solver!r}")
    return Problem(
        label=name,
        model=model,
        data=list(prepared.maneuvers),
        noise=case.estimation.get("noise", "max"),
        method=case.estimation.get("method", "rk4"),
        R=case.estimation.get("R"),
        convergence=build_convergence(case),
        interpolation=input_interpolation(case),
        aero=aero,
    )


def example3_problem(case: int) -> Problem:
    from flightid.paper.example3 import example3_data, example3_model

    model = example3_model()
    return Problem(
        label=f"example 3 case {case}",
        model=model,
        data=[example3_data(case)],
        convergence=Convergence(max_iterations=200),  # as run_example3
        aero=tuple(model.parameters.free_names),
    )


def examples12_problems() -> Iterator[Problem]:
    from flightid.paper.examples12 import example1_data, example2_data, example_model

    yield Problem(
        "example 1", example_model(), [example1_data()], noise="fixed", method="euler", R=None
    )
    for case in (1, 2):
        yield Problem(
            f"example 2 case {case}",
            example_model(),
            [example2_data(case)],
            noise="fixed",
            method="euler",
        )


# The book's unstable aircraft (Jategaonkar 2015): short period, states w, q.
UNSTAB_U0 = 44.5695  # m/s, constant
UNSTAB_SIGMA = 0.7  # 1/s, eigenvalue shift of 3e
UNSTAB_START = {  # the reference's start values; Zq fixed
    "Zw": -1.22871,
    "Zq": -1.4768,
    "Zde": -4.20491,
    "Mw": 0.116197,
    "Mq": -2.70670,
    "Mde": -18.7718,
}


def unstab_3c_f(t, x, u, theta):
    w, q = x[0], x[1]
    de, w_m, q_m = u[0], u[1], u[2]
    dx = np.empty(2)
    # ẇ = Zw w + u0 q + Zq q_m + Zδe δe        (3c: Zq on the measured q)
    dx[0] = theta[0] * w + UNSTAB_U0 * q + theta[1] * q_m + theta[2] * de
    # q̇ = Mw w_m + Mq q + Mδe δe              (3c: Mw on the measured w)
    dx[1] = theta[3] * w_m + theta[4] * q + theta[5] * de
    return dx


def unstab_h(t, x, u, theta):
    """Outputs of 3c and 3e (the same in both)."""
    w, q = x[0], x[1]
    y = np.empty(3)
    # a_z = Zw w + Zq q + Zδe δe (integrated w, q); y2 = w, y3 = q
    y[0] = theta[0] * w + theta[1] * q + theta[2] * u[0]
    y[1] = w
    y[2] = q
    return y


def unstab_3e_f(t, x, u, theta):
    w, q = x[0], x[1]
    de = u[0]
    dx = np.empty(2)
    # ẇ = (Zw − σ) w + (u0 + Zq) q + Zδe δe
    dx[0] = (theta[0] - UNSTAB_SIGMA) * w + (UNSTAB_U0 + theta[1]) * q + theta[2] * de
    # q̇ = Mw w + (Mq − σ) q + Mδe δe
    dx[1] = theta[3] * w + (theta[4] - UNSTAB_SIGMA) * q + theta[5] * de
    return dx


def unstab_problems(data_dir: Path = DATA) -> Iterator[Problem]:
    """3c (equation decoupling) and 3e (eigenvalue transformation), noise "max"."""
    table = np.loadtxt(data_dir / "fvsysid/unStabAC_sim.asc")
    # the file's time base: t_k = (k − 1)·dt, dt = 0.05 s; cols 3 w, 4 q, 5 δe, 6 a_z
    t = np.arange(table.shape[0]) * 0.05
    w, q, de, az = table[:, 2], table[:, 3], table[:, 4], table[:, 5]
    parameters = Parameters(Parameter(n, v, free=n != "Zq") for n, v in UNSTAB_START.items())
    decoupling = FlightData(
        t, {"de": de, "w_m": w, "q_m": q}, {"az": az, "w": w, "q": q}, name="unStabAC_sim"
    )
    yield Problem(
        "3c equation decoupling",
        StateSpaceModel(
            states=("w", "q"),
            inputs=("de", "w_m", "q_m"),
            outputs=("az", "w", "q"),
            f=unstab_3c_f,
            h=unstab_h,
            parameters=parameters,
            x0=(0.0, 0.0),
            name="unstab_sp_equation_decoupling",
        ),
        [decoupling],
        aero=tuple(parameters.free_names),
    )
    # 3e: every measured signal, the input δe included, × e^(−σ t_k)
    weight = np.exp(-UNSTAB_SIGMA * t)
    transformed = FlightData(
        t,
        {"de": de * weight},
        {"az": az * weight, "w": w * weight, "q": q * weight},
        name="unStabAC_sim × exp(-0.7 t)",
    )
    yield Problem(
        "3e eigenvalue transform",
        StateSpaceModel(
            states=("w", "q"),
            inputs=("de",),
            outputs=("az", "w", "q"),
            f=unstab_3e_f,
            h=unstab_h,
            parameters=parameters,
            x0=(0.0, 0.0),
            name="unstab_sp_eigenvalue_transform",
        ),
        [transformed],
        aero=tuple(parameters.free_names),
    )


# ---------------------------------------------------------------------------- runs


@dataclass
class Reference:
    theta: np.ndarray  # θ* (free parameters)
    sigma: np.ndarray  # Cramér–Rao σ at θ* (R of the reference run)
    sigma_rhat: np.ndarray  # σ with R̂ from the reference's residuals
    names: list[str]
    estimate: Estimate


def reference(problem: Problem) -> Reference:
    result = problem.run(problem.model, MNR(), TIGHT)
    if not result.converged:
        raise SystemExit(f"{problem.label}: the tight reference did not converge: {result.message}")
    free = result.free
    r_hat = np.maximum(np.mean(result.residuals**2, axis=0), np.finfo(float).tiny)
    with np.errstate(over="ignore", invalid="ignore"):
        # M(R̂) = Σ GᵀR̂⁻¹G; σ_j = √(M⁻¹)_jj (σ = 0 where R̂ is at rounding level)
        m_hat = information_matrix(result.sensitivities, r_hat)
        if np.all(np.isfinite(m_hat)):
            sigma_rhat = np.sqrt(np.abs(np.diag(np.linalg.pinv(m_hat))))
        else:
            sigma_rhat = np.zeros(m_hat.shape[0])
    return Reference(
        result.values[free],
        result.std[free],
        sigma_rhat,
        list(np.array(result.names)[free]),
        result,
    )


def deviation(result: Estimate, ref: Reference, sigma: np.ndarray) -> tuple[float, str]:
    """max_j |θ̂_j − θ*_j|/σ_j and the parameter where it occurs."""
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.abs(result.values[result.free] - ref.theta) / sigma
    d = np.where(sigma > 0, d, np.nan)  # σ = 0 (noise-free residuals): no measure
    if not np.any(np.isfinite(d)):
        return float("nan"), ""
    j = int(np.nanargmax(d))
    return float(d[j]), ref.names[j]


def starts(problem: Problem, ref: Reference, quick: bool) -> list[tuple[str, dict, str]]:
    """(label, {name: start value}, description) of the start values of part 1."""
    params = problem.model.parameters
    free = params.free_names
    start = {n: params[n].value for n in free}
    out = [
        (
            "(a) zeros",
            {n: 0.0 for n in problem.aero},
            f"{len(problem.aero)} aerodynamic parameters 0",
        )
    ]
    if not quick:
        rng = np.random.default_rng(SEED)
        # half +, half − (alternating), in a seeded order
        signs = np.where(np.arange(len(free)) % 2 == 0, 1.0, -1.0)
        signs = rng.permutation(signs)
        out.append(
            (
                "(b) ±50 %",
                {n: start[n] * (1 + 0.5 * s) for n, s in zip(free, signs, strict=True)},
                "+: " + ", ".join(n for n, s in zip(free, signs, strict=True) if s > 0),
            )
        )
        out.append(("(b) +50 %", {n: 1.5 * start[n] for n in free}, "all × 1.5"))
    # (c) the aerodynamic parameter with the largest |θ_start,j|/σ_j; when its ×1e3 start
    # makes the simulation diverge, also (c′): the next in that order whose start simulates
    index = {n: ref.names.index(n) for n in problem.aero}
    ratio = {n: abs(start[n]) / ref.sigma[index[n]] for n in problem.aero}
    ranked = sorted((n for n in problem.aero if start[n] != 0), key=ratio.get, reverse=True)
    for k, chosen in enumerate(ranked):
        values = {chosen: OFF_FACTOR * start[chosen]}
        finite = problem.simulates(values)
        text = (
            f"{chosen} = {OFF_FACTOR * start[chosen]:.4g} (start {start[chosen]:.4g}, "
            f"start/σ = {ratio[chosen]:.3g} in magnitude, rank {k + 1})"
        )
        if k == 0:
            out.append(("(c) ×1e3", values, text))
        elif finite:
            out.append(("(c′) ×1e3", values, text + "; the first whose start simulates"))
        if finite:
            break
    return out


@dataclass
class Row:
    problem: str
    start: str
    solver: str
    status: str
    converged: bool | None
    evaluations: int | None
    wall_s: float
    optimality: float
    d: float
    at: str
    verdict: str


def verdict(result: Estimate, d: float) -> str:
    if result.converged:
        return "reached (≤ 0.1 σ)" if d <= REACHED_SIGMA else "WRONG: converged but > 0.1 σ"
    return "reported not converged (OK)"


def robustness_run(problem: Problem, ref: Reference, label: str, values: dict, solver) -> Row:
    model = problem.model.with_parameters(problem.model.parameters.with_values(values))
    started = time.perf_counter()
    try:
        result = problem.run(model, solver, problem.convergence)
    except FlightIdError as exc:
        wall = time.perf_counter() - started
        if problem.simulates(values):
            # the start simulates: the error came from a later point and the run is lost
            text = f"ERROR DURING THE RUN (named): {type(exc).__name__}: {str(exc)[:140]}"
        else:
            text = f"refused with a named error: {type(exc).__name__}: {str(exc)[:140]}"
        return Row(
            problem.label, label, solver.name, "error", None, None, wall, np.nan, np.nan, "", text
        )
    except Exception as exc:  # noqa: BLE001 - a failure of the requirement, reported
        wall = time.perf_counter() - started
        text = f"UNNAMED ERROR {type(exc).__name__}: {str(exc)[:140]}"
        return Row(
            problem.label, label, solver.name, "error", None, None, wall, np.nan, np.nan, "", text
        )
    d, at = deviation(result, ref, ref.sigma)
    return Row(
        problem.label,
        label,
        solver.name,
        result.status,
        result.converged,
        result.equivalent_evaluations,
        result.wall_time_s,
        result.optimality_sigma,
        d,
        at,
        verdict(result, d),
    )


def _fmt(value: float, spec: str) -> str:
    return "–" if value is None or not np.isfinite(value) else format(value, spec)


def print_robustness(rows: list[Row]) -> None:
    print(
        "| problem | start | solver | status | converged | evaluations | wall, s | "
        "opt. σ | d = max_j abs(θ̂−θ*)/σ (at) | verdict |"
    )
    print("|---|---|---|---|---|---:|---:|---:|---:|---|")
    for r in rows:
        conv = "–" if r.converged is None else ("yes" if r.converged else "no")
        evals = "–" if r.evaluations is None else str(r.evaluations)
        where = f" ({r.at})" if r.at else ""
        print(
            f"| {r.problem} | {r.start} | {r.solver.upper()} | {r.status} | {conv} | {evals} | "
            f"{r.wall_s:.2f} | {_fmt(r.optimality, '.2g')} | {_fmt(r.d, '.3g')}{where} | "
            f"{r.verdict} |",
            flush=True,
        )


def part1(problems: list[Problem], quick: bool) -> list[Row]:
    rows: list[Row] = []
    print("### Part 1: start values\n")
    described = []
    refs = {}
    for problem in problems:
        problem.warm()
        ref = reference(problem)
        refs[problem.label] = ref
        for label, values, text in starts(problem, ref, quick):
            described.append((problem.label, label, text))
            for solver in (MNRES(), MNR()):
                rows.append(robustness_run(problem, ref, label, values, solver))
    print("| problem | start | what was changed |")
    print("|---|---|---|")
    for problem_label, label, text in described:
        print(f"| {problem_label} | {label} | {text} |")
    print()
    print_robustness(rows)
    wrong = [r for r in rows if r.verdict.startswith(("WRONG", "UNNAMED"))]
    lost = [r for r in rows if r.verdict.startswith("ERROR DURING")]
    print(f"\n{len(rows)} runs, {len(wrong)} failing the requirement, {len(lost)} lost to an error")
    for r in wrong + lost:
        print(f"  {r.problem}, {r.start}, {r.solver.upper()}: {r.verdict}")
    return rows


def part2(problems: list[Problem]) -> list[tuple]:
    print("\n### Part 2: default tolerances against the tight reference\n")
    print(
        "| problem | solver | status | evaluations (tight) | opt. σ | d = max_j abs(Δθ)/σ (at) | "
        "d, R̂ | ≤ 0.05 σ |"
    )
    print("|---|---|---|---:|---:|---:|---:|---|")
    out = []
    for problem in problems:
        problem.warm()
        ref = reference(problem)
        for solver in (MNRES(), MNR()):
            result = problem.run(problem.model, solver, Convergence())
            d, at = deviation(result, ref, ref.sigma)
            d_hat, _ = deviation(result, ref, ref.sigma_rhat)
            ok = result.converged and d <= TOLERANCE_SIGMA
            out.append((problem.label, solver.name, d, ok))
            print(
                f"| {problem.label} | {solver.name.upper()} | {result.status} | "
                f"{result.equivalent_evaluations} ({ref.estimate.equivalent_evaluations}) | "
                f"{_fmt(result.optimality_sigma, '.2g')} | {d:.3g} ({at}) | "
                f"{_fmt(d_hat, '.3g')} | {'yes' if ok else 'NO'} |",
                flush=True,
            )
    bad = [o for o in out if not o[3]]
    print(f"\n{len(out)} runs, {len(bad)} beyond {TOLERANCE_SIGMA} σ or not converged")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two cheap cases, starts a and c")
    parser.add_argument(
        "--only", nargs="*", default=None, help="problem labels (substring match) to run"
    )
    parser.add_argument("--part", choices=("1", "2", "both"), default="both")
    args = parser.parse_args()
    if not (DATA / "fvsysid").is_dir():
        raise SystemExit(f"real flight data not found at {DATA} (set FLIGHTID_DATA)")

    def keep(label: str) -> bool:
        return args.only is None or any(s in label for s in args.only)

    cases = QUICK_CASES if args.quick else STANDARD_CASES
    started = time.perf_counter()
    if args.part in ("1", "both"):
        problems = [case_problem(n) for n in cases if keep(n)]
        if not args.quick:
            problems += [example3_problem(c) for c in (2, 3) if keep(f"example 3 case {c}")]
        part1(problems, args.quick)
    if args.part in ("2", "both"):
        problems = [case_problem(n) for n in cases if keep(n)]
        problems += [p for p in examples12_problems() if keep(p.label)]
        if not args.quick:
            problems += [example3_problem(c) for c in (2, 3) if keep(f"example 3 case {c}")]
        problems += [p for p in unstab_problems() if keep(p.label)]
        part2(problems)
    print(f"\ntotal wall time {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
