"""The reference tool's schedule of the filter error method (FVSysID's ``ml_fem2``; Jategaonkar,
*Flight Vehicle System Identification*, 2nd ed., ch. 5).

One Gauss–Newton step per iteration, forward differences δθ_j = 1e-4·θ_j (1e-4 if θ_j = 0),
each perturbed θ with its own gain (same linearisation point, same weighting R) and its own
filter pass:

    H_k = ∂ỹ_k/∂θ,  M = Σ H_kᵀR⁻¹H_k,  g = −Σ H_kᵀR⁻¹e_k,  Δθ = −M⁻¹g

Constraint diag(KC) ≤ 1, linearised: s = diag(KC) + G_KC Δθ − 1 with G_KC = ∂diag(KC)/∂θ
(forward differences from the perturbed gains); for the violated rows (s_i > 0, stacked as
M_c, s_a):  Δθ ← Δθ − M⁻¹M_cᵀ(M_c M⁻¹ M_cᵀ)⁻¹ s_a.

Cost J = det R̂, R̂ = diag((1/N) Σ e_k e_kᵀ) of the filter pass. Relaxation: the weighting
stays R₀ (the K = 0 pass) up to and including the 3rd step; after the 3rd and every later
step: (1) gain with the old R, filter pass; (2) |ΔJ|/J < 1e-4: converged; (3) J increased:
halve the step (at most 10 times); (4) else compensate the free F elements for the new R,

    F_jj ← F_jj · [Σ_i C_ij² r_i,old⁻¹ (r_i,new/r_i,old)^½] / [Σ_i C_ij² r_i,old⁻¹];

(5) R ← R_new, new gain and cost; (6) if that cost is higher than before the compensation,
F goes halfway back (at most twice), the third time F and R are restored. At most 15
iterations. Standard deviations √diag(M⁻¹) of the last Gauss–Newton step.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["ReferenceRun", "reference_relaxation"]

ITER_F_UP_R = 3  # iterFupR: R held at R₀ up to and including this step
TOL_R = 1e-4  # relative change of det R
NITER_MAX = 15
RELATIVE_STEP = 1e-4
MAX_HALVINGS = 10


@dataclass
class ReferenceRun:
    """Outcome of the reference schedule."""

    theta: np.ndarray
    outputs: np.ndarray
    r_diag: np.ndarray
    sensitivities: np.ndarray
    information: np.ndarray
    converged: bool
    message: str
    cost_history: list
    evaluation_history: list
    iterations: int
    r_updates: int


def _pass(problem, theta: np.ndarray, r_diag: np.ndarray):
    """Filter pass at θ with weighting R: (outputs, det R̂, R̂) or (None, inf, None)."""
    problem.gain_r = np.array(r_diag, dtype=float)
    batch = problem.run(theta[None, :], check_kc=False)
    if batch.diverged[0]:
        return None, np.inf, None
    r_hat = np.mean(problem.residuals(batch.outputs[0]) ** 2, axis=0)
    return batch.outputs[0], float(np.prod(r_hat)), r_hat


def _kc(problem, theta: np.ndarray, r_diag: np.ndarray) -> np.ndarray:
    return problem.filter_point(problem.full_theta(theta), r_diag).kc


def reference_relaxation(
    problem, r_start: np.ndarray, progress: Callable[[int, int, float], None] | None = None
) -> ReferenceRun:
    """Run the reference schedule on a ``FilterErrorProblem`` from its start values."""
    theta = problem.theta_start
    r_diag = np.array(r_start, dtype=float)
    n_f = problem.n_free
    noise_free = np.array(
        [
            problem.free_index.tolist().index(p) if p in problem.free_index else -1
            for p in problem.noise_parameters
        ]
    )
    outputs, cost, r_hat = _pass(problem, theta, r_diag)
    costs, evaluations = [cost], [problem.evaluations]
    converged, message, r_updates = False, "", 0
    g = np.zeros((problem.n_samples, problem.n_outputs, n_f))
    m = np.eye(n_f)
    iteration = 0
    for iteration in range(1, NITER_MAX + 1):
        # forward differences, gain recomputed per perturbed θ (same R)
        problem.gain_r = r_diag.copy()
        steps = RELATIVE_STEP * np.where(theta == 0.0, 1.0, np.abs(theta))
        steps = np.where(theta < 0, -steps, steps)
        perturbed = problem.run(theta + np.diag(steps), check_kc=False)
        g = np.moveaxis((perturbed.outputs - outputs[None]) / steps[:, None, None], 0, -1)
        e = problem.residuals(outputs)
        weighted = g / r_diag[None, :, None]
        # M = Σ HᵀR⁻¹H, g = −Σ HᵀR⁻¹e, Δθ = −M⁻¹g
        m = np.einsum("kif,kig->fg", weighted, g)
        gradient = -np.einsum("kif,ki->f", weighted, e)
        chol = np.linalg.cholesky(m)
        m_inv = np.linalg.inv(chol.T) @ np.linalg.inv(chol)
        step = -m_inv @ gradient
        # linearised constraint diag(KC) ≤ 1
        kc = _kc(problem, theta, r_diag)
        kc_perturbed = np.array(
            [_kc(problem, theta + steps[j] * np.eye(n_f)[j], r_diag) for j in range(n_f)]
        )
        g_kc = ((kc_perturbed - kc[None, :]) / steps[:, None]).T  # (n_x, n_f)
        s = kc + g_kc @ step - 1.0
        active = s > 0
        if active.any():
            mc, sa = g_kc[active], s[active]
            # Δθ ← Δθ − M⁻¹M_cᵀ(M_c M⁻¹ M_cᵀ)⁻¹ s_a
            step = step - m_inv @ mc.T @ np.linalg.solve(mc @ m_inv @ mc.T, sa)
        # the new point, with step halving while the cost (under the old R) increases
        previous_cost = cost
        for _ in range(MAX_HALVINGS + 1):
            trial = theta + step
            new_outputs, new_cost, new_r_hat = _pass(problem, trial, r_diag)
            if new_cost <= previous_cost:
                break
            step = step / 2.0
        theta, outputs, cost, r_hat = trial, new_outputs, new_cost, new_r_hat
        if outputs is None:
            message = "the filter pass failed after 10 halvings"
            break
        costs.append(cost)
        evaluations.append(problem.evaluations)
        if progress is not None:
            progress(iteration, problem.evaluations, cost)
        if abs(cost - previous_cost) / cost < TOL_R:
            converged = True
            message = (
                f"converged (reference schedule): |ΔJ|/J < {TOL_R:g} after {iteration} iterations"
            )
            break
        if iteration < ITER_F_UP_R:
            continue
        # F compensation for the new innovation covariance, then R ← R_new
        point = problem.filter_point(problem.full_theta(theta), r_diag)
        c2 = point.c**2
        r_new = r_hat
        saved = theta.copy()
        compensated = theta.copy()
        for state, free in zip(problem.noise_states, noise_free, strict=True):
            if free < 0:
                continue
            denominator = np.sum(c2[:, state] / r_diag)
            if denominator <= 0:
                continue
            # F_jj ← F_jj Σ_i C_ij² r_i⁻¹ (r_i,new / r_i)^½ / Σ_i C_ij² r_i⁻¹
            factor = np.sum(c2[:, state] / r_diag * np.sqrt(r_new / r_diag)) / denominator
            compensated[free] = theta[free] * factor
        before = cost
        candidate = compensated
        accepted = False
        for _ in range(3):
            new_outputs, new_cost, new_r_hat = _pass(problem, candidate, r_new)
            if new_cost <= before:
                accepted = True
                break
            candidate = 0.5 * (candidate + saved)
        if accepted:
            theta, outputs, cost, r_hat = candidate, new_outputs, new_cost, new_r_hat
            r_diag = r_new.copy()
            r_updates += 1
        else:
            # restore F and R
            outputs, cost, r_hat = _pass(problem, saved, r_diag)
            theta = saved
    else:
        message = f"not converged (reference schedule): {NITER_MAX} iterations"
    problem.gain_r = r_diag.copy()
    return ReferenceRun(
        theta,
        outputs,
        r_diag,
        g,
        m,
        converged,
        message,
        costs,
        evaluations,
        iteration,
        r_updates,
    )
