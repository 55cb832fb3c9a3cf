"""Simulation kernels: flightid's against a hand-written serial numba kernel of the same model.

    python -P bench/kernel.py [--steps 1000] [--repeats 100] [--batch 21] [--quick]

The model is the one of ``bench/peers.py`` (base variant): the Navion 6-DOF model of
``flightid.aircraft.six_dof_model`` with Nelson's 22 derivatives, 8 outputs, 1000 RK4 steps
(1001 samples) with linear input interpolation. ``hand_simulate`` below writes the same
equations (``flightid.aircraft.equations``: [2.5–2.16], [2.19–2.23]) as straight-line numba
code — scalars, no arrays but the state, stage and output buffers allocated once per
trajectory, nothing allocated per step — and is checked against ``Simulator.run`` (``check``:
outputs agree to 1e-10 relative to their scale, asserted before any timing).

Tables, best (min) over ``--repeats`` rounds after a warm-up call (flightid
and the hand-written kernel take turns within a round; the batch is timed apart):

1. µs per trajectory: ``Simulator.run`` on one θ against the hand-written kernel; ratio
   (target ≤ 1.1).
2. a batch of ``--batch`` trajectories (different θ): ``Simulator.run`` on the batch against
   ``--batch`` × its single-trajectory time (speed-up; target ≥ 1.7 on 2 cores), with
   ``--batch`` × the hand-written kernel for reference, and a hand-written parallel batch
   (``hand_simulate_batch``: the hand kernel in a ``prange``, outputs asserted identical),
   timed in turns with flightid's batch: where the machine gives a process's threads less
   than two CPUs, both batches are slow alike.
3. the same model written as a user model module (``bench/navion_user_model.py``: ``f`` and
   ``h`` return new arrays, as documented): ``Simulator.run`` on one θ against the
   hand-written kernel (target ≤ 1.1, printed as a PASS/FAIL line), beside the same module
   run through the call-then-copy adapter (``flightid.model.forms.copy_out_form``, the path
   of functions whose out form cannot be generated) for reference.
4. sensitivity equations: ``Simulator.run_with_sensitivities`` (the kernel of
   ``MNR(sensitivities="equations")``) for the 22 free parameters against ``Simulator.run`` on
   the 23-trajectory forward-difference batch (θ and θ + δ_j e_j) — the two ways to get the
   outputs and G.

flightid is measured through its public API only (``Simulator``), whatever its kernels' inner
form. Set ``NUMBA_NUM_THREADS`` to fix the number of threads; the machine's core count is
printed.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

from flightid.aircraft import navion  # noqa: E402
from flightid.simulation import Simulator  # noqa: E402
from peers import OUTPUTS8, benchmark  # noqa: E402

# the hand-written kernel's parameter order (θ below); mapped from the model's by name
HAND_PARAMETERS = (
    "CD_0", "CD_alpha",
    "CL_0", "CL_alpha", "CL_qhat", "CL_de",
    "Cm_0", "Cm_alpha", "Cm_qhat", "Cm_de",
    "CY_beta", "CY_dr",
    "Cl_beta", "Cl_phat", "Cl_rhat", "Cl_da", "Cl_dr",
    "Cn_beta", "Cn_phat", "Cn_rhat", "Cn_da", "Cn_dr",
)  # fmt: skip
HAND_INPUTS = ("de", "dr", "da", "thrust")


def airplane_constants() -> np.ndarray:
    """(m, I_x, I_y, I_z, I_xz, S, b, c̄, ρ, g, α_T, l_T) of the Navion (SI units)."""
    a = navion()
    if a.engine_momentum != 0.0 or a.engine_momentum_input or a.propeller_torque_input:
        raise ValueError("the hand-written kernel has no engine momentum or shaft torque terms")
    return np.array(
        [a.mass, a.Ix, a.Iy, a.Iz, a.Ixz, a.S, a.b, a.cbar, a.rho, a.g,
         a.thrust_inclination, a.thrust_moment_arm],
    )  # fmt: skip


# Not cached (cache=True): this file runs as a script and is loaded by path in the tests, and
# a numba cache written under one of those module names cannot be loaded under the other.
@numba.njit(fastmath=False)
def _rates(x, de, dr, da, thrust, th, c, out):
    """dx/dt of x = (u, v, w, p, q, r, l_xz, l_yz, l_zz) into ``out`` [2.5–2.16]."""
    m, Ix, Iy, Iz, Ixz, S, b, cbar, rho, g = (
        c[0],
        c[1],
        c[2],
        c[3],
        c[4],
        c[5],
        c[6],
        c[7],
        c[8],
        c[9],
    )
    u, v, w, p, q, r = x[0], x[1], x[2], x[3], x[4], x[5]
    lxz, lyz, lzz = x[6], x[7], x[8]
    V = math.sqrt(u * u + v * v + w * w)
    alpha = math.atan2(w, u)
    beta = math.asin(v / V)
    # p̂ = p b/2V, q̂ = q c̄/2V, r̂ = r b/2V
    phat = p * b / (2.0 * V)
    qhat = q * cbar / (2.0 * V)
    rhat = r * b / (2.0 * V)
    CD = th[0] + th[1] * alpha
    CL = th[2] + th[3] * alpha + th[4] * qhat + th[5] * de
    Cm = th[6] + th[7] * alpha + th[8] * qhat + th[9] * de
    CY = th[10] * beta + th[11] * dr
    Cl = th[12] * beta + th[13] * phat + th[14] * rhat + th[15] * da + th[16] * dr
    Cn = th[17] * beta + th[18] * phat + th[19] * rhat + th[20] * da + th[21] * dr
    # q̄ = ½ρV²; forces and moments [2.14–2.15], thrust moment M_T = l_T T
    qS = 0.5 * rho * V * V * S
    sa = math.sin(alpha)
    ca = math.cos(alpha)
    X = qS * (CL * sa - CD * ca) + thrust * math.cos(c[10])
    Y = qS * CY
    Z = qS * (-CL * ca - CD * sa) - thrust * math.sin(c[10])
    L = qS * b * Cl
    M = qS * cbar * Cm + c[11] * thrust
    N = qS * b * Cn
    # [2.5–2.7]
    out[0] = -q * w + r * v + g * lxz + X / m
    out[1] = -r * u + p * w + g * lyz + Y / m
    out[2] = -p * v + q * u + g * lzz + Z / m
    # [2.8–2.10]
    gamma = Ix * Iz - Ixz * Ixz
    F1 = (Iy - Iz) * q * r + Ixz * p * q + L
    F2 = (Ix - Iy) * p * q - Ixz * q * r + N
    out[3] = (Iz * F1 + Ixz * F2) / gamma
    out[4] = ((Iz - Ix) * p * r + Ixz * (r * r - p * p) + M) / Iy
    out[5] = (Ixz * F1 + Ix * F2) / gamma
    # [2.11–2.13]
    out[6] = r * lyz - q * lzz
    out[7] = -r * lxz + p * lzz
    out[8] = q * lxz - p * lyz


@numba.njit(fastmath=False)
def _outputs(x, y):
    """(V, α, β, Θ, Φ, p, q, r) into ``y`` [2.19–2.23]."""
    u, v, w = x[0], x[1], x[2]
    V = math.sqrt(u * u + v * v + w * w)
    y[0] = V
    y[1] = math.atan2(w, u)
    y[2] = math.asin(v / V)
    y[3] = math.asin(max(-1.0, min(1.0, -x[6])))
    y[4] = math.atan2(x[7], x[8])
    y[5] = x[3]
    y[6] = x[4]
    y[7] = x[5]


@numba.njit(fastmath=False)
def hand_simulate(theta, x0, t, u, c, y):
    """RK4 (linear input interpolation) of one trajectory; outputs into y (N × 8)."""
    n_x = 9
    x = x0.copy()
    k1 = np.empty(n_x)
    k2 = np.empty(n_x)
    k3 = np.empty(n_x)
    k4 = np.empty(n_x)
    xs = np.empty(n_x)
    n = t.shape[0]
    for k in range(n):
        _outputs(x, y[k])
        if k == n - 1:
            break
        dt = t[k + 1] - t[k]
        half = 0.5 * dt
        # u_k+½ = (u_k + u_{k+1})/2
        de_m = 0.5 * (u[k, 0] + u[k + 1, 0])
        dr_m = 0.5 * (u[k, 1] + u[k + 1, 1])
        da_m = 0.5 * (u[k, 2] + u[k + 1, 2])
        th_m = 0.5 * (u[k, 3] + u[k + 1, 3])
        _rates(x, u[k, 0], u[k, 1], u[k, 2], u[k, 3], theta, c, k1)
        for i in range(n_x):
            xs[i] = x[i] + half * k1[i]
        _rates(xs, de_m, dr_m, da_m, th_m, theta, c, k2)
        for i in range(n_x):
            xs[i] = x[i] + half * k2[i]
        _rates(xs, de_m, dr_m, da_m, th_m, theta, c, k3)
        for i in range(n_x):
            xs[i] = x[i] + dt * k3[i]
        _rates(xs, u[k + 1, 0], u[k + 1, 1], u[k + 1, 2], u[k + 1, 3], theta, c, k4)
        sixth = dt / 6.0
        for i in range(n_x):
            # x_{k+1} = x_k + Δt/6 (k1 + 2k2 + 2k3 + k4)
            x[i] = x[i] + sixth * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@numba.njit(parallel=True)
def hand_simulate_batch(thetas, x0, t, u, c, y):
    """``hand_simulate`` over a batch, one trajectory per ``prange`` iteration, outputs into
    y (B × N × 8): the hand-written reference for the parallel batch."""
    for b in numba.prange(thetas.shape[0]):
        hand_simulate(thetas[b], x0, t, u, c, y[b])


USER_MODULE = Path(__file__).resolve().with_name("navion_user_model.py")
# the user-module kernel's target: µs per trajectory ≤ 1.1 × the hand-written kernel's
USER_TARGET = 1.1


def user_module_simulators(setup: Setup) -> tuple[Simulator, Simulator]:
    """Simulators of ``USER_MODULE`` on the benchmark data at the benchmark's parameter
    values and initial state: as flightid builds it (generated out forms) and through the
    call-then-copy adapter (a copy of f and h marked with ``copy_out_form``)."""
    import types

    from flightid.cases.usermodel import load_user_model
    from flightid.model import Parameters, StateSpaceModel
    from flightid.model.forms import copy_out_form, with_out_form

    user = load_user_model(USER_MODULE)
    values = dict(zip(setup.model.parameters.names, setup.theta, strict=True))
    parameters = Parameters({name: float(values[name]) for name in user.parameters})

    def model(f, h):
        return StateSpaceModel(user.states, user.inputs, user.outputs, f, h, parameters,
                               x0=tuple(setup.x0), name="navion_user_module")  # fmt: skip

    def adapted(fn):
        # a copy of the user's function (the module's own is left as it is), with the adapter
        copy = types.FunctionType(fn.__code__, fn.__globals__, fn.__name__)
        return with_out_form(copy, copy_out_form(copy))

    return (
        Simulator(model(user.f, user.h), setup.data),
        Simulator(model(adapted(user.f), adapted(user.h)), setup.data),
    )


def user_module_table(setup: Setup, repeats: int) -> float:
    """Table 3 (module docstring); returns the ratio user module / hand-written."""
    generated, adapted = user_module_simulators(setup)
    theta = setup.theta[setup.order]  # the module's order is HAND_PARAMETERS
    y_hand = setup.hand(setup.theta).copy()
    scale = np.maximum(np.max(np.abs(y_hand), axis=0), 1e-3)
    for simulator in (generated, adapted):
        y = simulator.run(theta[None, :]).outputs[0]
        error = float(np.max(np.abs(y - y_hand) / scale))
        assert error <= 1e-10, (
            f"the user module disagrees with the hand-written kernel: {error:.3g}"
        )
    t_gen, t_hand, t_adapted = best_times(
        [
            lambda: generated.run(theta[None, :]),
            lambda: setup.hand(setup.theta),
            lambda: adapted.run(theta[None, :]),
        ],
        repeats,
    )
    print()
    print("<!-- numbers: kernel-user-module -->")
    print("| user model module (bench/navion_user_model.py) | µs per trajectory | "
          "÷ hand-written |")  # fmt: skip
    print("|---|---:|---:|")
    print(f"| hand-written serial numba | {t_hand * 1e6:.0f} | 1.00 |")
    print(f"| flightid, generated out forms | {t_gen * 1e6:.0f} | {t_gen / t_hand:.2f} |")
    print(f"| flightid, call-then-copy adapter | {t_adapted * 1e6:.0f} | "
          f"{t_adapted / t_hand:.2f} |")  # fmt: skip
    print("<!-- /numbers -->")
    ratio = t_gen / t_hand
    verdict = "PASS" if ratio <= USER_TARGET else "FAIL"
    print(f"\n{verdict}: user-module kernel / hand-written kernel = {ratio:.2f} "
          f"(target ≤ {USER_TARGET})")  # fmt: skip
    return ratio


class Setup:
    """The benchmark model and data, flightid's simulator, and the hand kernel's arguments."""

    def __init__(self, n_steps: int = 1000, seed: int = 0) -> None:
        model, data, _, _ = benchmark(seed, n_steps)
        if tuple(model.inputs) != HAND_INPUTS or tuple(model.outputs) != OUTPUTS8:
            raise ValueError(f"unexpected model layout {model.inputs}, {model.outputs}")
        self.model = model
        self.data = data
        self.simulator = Simulator(model, data)
        names = list(model.parameters.names)
        self.order = np.array([names.index(n) for n in HAND_PARAMETERS])
        if len(names) != len(HAND_PARAMETERS):
            raise ValueError(f"the hand kernel has 22 parameters, the model {len(names)}")
        self.theta = model.parameters.values.copy()
        self.x0 = np.asarray(model.initial_state(self.theta), dtype=float)
        self.t = np.ascontiguousarray(data.time, dtype=float)
        self.u = np.ascontiguousarray(np.column_stack([data.channel(n) for n in HAND_INPUTS]))
        self.c = airplane_constants()
        self.y = np.empty((self.t.shape[0], len(OUTPUTS8)))

    def hand(self, theta: np.ndarray) -> np.ndarray:
        hand_simulate(theta[self.order], self.x0, self.t, self.u, self.c, self.y)
        return self.y

    def hand_batch(self, thetas: np.ndarray) -> np.ndarray:
        y = np.empty((thetas.shape[0], *self.y.shape))
        hand_simulate_batch(np.ascontiguousarray(thetas[:, self.order]), self.x0, self.t,
                            self.u, self.c, y)  # fmt: skip
        return y

    def flightid(self, thetas: np.ndarray) -> np.ndarray:
        return self.simulator.run(thetas).outputs


def check(setup: Setup, tolerance: float = 1e-10) -> float:
    """Largest |hand − flightid| over the outputs' scales (max |y| per output, ≥ 1e-3);
    raises AssertionError above ``tolerance``."""
    y_lib = setup.flightid(setup.theta[None, :])[0]
    y_hand = setup.hand(setup.theta)
    scale = np.maximum(np.max(np.abs(y_lib), axis=0), 1e-3)
    error = float(np.max(np.abs(y_hand - y_lib) / scale))
    assert np.all(np.isfinite(y_lib)) and error <= tolerance, (
        f"hand-written kernel disagrees with flightid: {error:.3g} > {tolerance:.1g}"
    )
    return error


def best_times(functions, repeats: int) -> list[float]:
    """Smallest wall time (s) of each function over ``repeats`` rounds (after one warm-up call
    each). The functions take turns within a round, so a passing disturbance of the machine
    falls on all of them alike, not on whichever was being timed."""
    for function in functions:
        function()
    best = [math.inf] * len(functions)
    for _ in range(repeats):
        for i, function in enumerate(functions):
            start = time.perf_counter()
            function()
            best[i] = min(best[i], time.perf_counter() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1000, help="RK4 steps (samples − 1)")
    parser.add_argument("--repeats", type=int, default=100, help="rounds of timings (min taken)")
    parser.add_argument("--batch", type=int, default=21, help="trajectories in the batch")
    parser.add_argument("--quick", action="store_true", help="10 rounds (well under a minute)")
    args = parser.parse_args()
    if args.quick:
        args.repeats = min(args.repeats, 10)
    started = time.perf_counter()
    print("<!-- guide: docs/benchmarks.md -->")
    setup = Setup(args.steps)
    error = check(setup)
    n = setup.t.shape[0]
    print(
        f"Navion 6-DOF (bench/peers.py base), {n} samples, 9 states, 8 outputs, 22 parameters; "
        f"{os.cpu_count()} CPUs, numba {numba.__version__}, {numba.get_num_threads()} threads; "
        f"hand-written vs flightid outputs: max relative difference {error:.2g}"
    )
    rng = np.random.default_rng(0)
    theta = setup.theta
    batch = theta * (1 + 0.01 * rng.uniform(-1, 1, (args.batch, theta.size)))

    t_lib, t_hand = best_times(
        [lambda: setup.flightid(theta[None, :]), lambda: setup.hand(theta)], args.repeats
    )
    # the batch apart: after a parallel call numba's worker thread stays awake for a while
    # and slowed the next serial calls (measured 1.14-1.28× instead of 1.04×)
    y_lib, y_hand = setup.flightid(batch), setup.hand_batch(batch)
    assert np.array_equal(y_lib, y_hand), "hand-written parallel batch disagrees with flightid"
    # flightid's batch and the hand-written parallel batch in turns (both parallel): a
    # process whose threads share one effective CPU slows both alike
    t_batch, t_hand_batch = best_times(
        [lambda: setup.flightid(batch), lambda: setup.hand_batch(batch)], args.repeats
    )
    print()
    print("| kernel | µs per trajectory | ratio to hand-written |")
    print("|---|---:|---:|")
    print(f"| hand-written serial numba | {t_hand * 1e6:.0f} | 1.00 |")
    print(f"| flightid Simulator.run, 1 θ | {t_lib * 1e6:.0f} | {t_lib / t_hand:.2f} |")

    print()
    print(f"| batch of {args.batch} | ms | speed-up over {args.batch} × flightid serial |")
    print("|---|---:|---:|")
    print(
        f"| {args.batch} × flightid serial (1 θ per call) | {args.batch * t_lib * 1e3:.2f} | 1.00 |"
    )
    print(f"| {args.batch} × hand-written serial | {args.batch * t_hand * 1e3:.2f} | "
          f"{t_lib / t_hand:.2f} |")  # fmt: skip
    print(f"| flightid Simulator.run, batch | {t_batch * 1e3:.2f} | "
          f"{args.batch * t_lib / t_batch:.2f} |")  # fmt: skip
    print(f"| hand-written parallel batch (prange) | {t_hand_batch * 1e3:.2f} | "
          f"{args.batch * t_lib / t_hand_batch:.2f} |")  # fmt: skip
    print(f"\nflightid batch / hand-written parallel batch: {t_batch / t_hand_batch:.2f}")

    user_module_table(setup, args.repeats)

    free = np.arange(theta.size, dtype=np.int64)
    steps = 1e-6 * np.maximum(np.abs(theta), 0.05)
    fd_batch = np.vstack([theta, theta + np.diag(steps)])
    t_sens, t_fd = best_times(
        [
            lambda: setup.simulator.run_with_sensitivities(theta, free, steps),
            lambda: setup.flightid(fd_batch),
        ],
        max(3, args.repeats // 4),
    )
    print()
    print(f"| outputs and G, {theta.size} free parameters | ms | per trajectory-equivalent, µs |")
    print("|---|---:|---:|")
    print(
        f"| sensitivity equations (Simulator.run_with_sensitivities) | {t_sens * 1e3:.2f} | "
        f"{t_sens / (theta.size + 1) * 1e6:.0f} |"
    )
    print(
        f"| forward differences ({theta.size + 1} trajectories, Simulator.run) | "
        f"{t_fd * 1e3:.2f} | {t_fd / (theta.size + 1) * 1e6:.0f} |"
    )
    print(
        f"| {theta.size + 1} × hand-written serial | {(theta.size + 1) * t_hand * 1e3:.2f} | "
        f"{t_hand * 1e6:.0f} |"
    )
    print()
    print(f"(run time {time.perf_counter() - started:.0f} s)")


if __name__ == "__main__":
    main()
