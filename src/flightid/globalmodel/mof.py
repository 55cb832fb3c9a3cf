"""Model structure by multivariate orthogonal functions (MOF) and predicted squared error.

The method of E. A. Morelli, "Global nonlinear aerodynamic modeling using multivariate
orthogonal functions", Journal of Aircraft 32(2), 1995, and V. Klein & E. A. Morelli,
*Aircraft System Identification: Theory and Practice* (AIAA, 2006), the chapter on model
structure determination (orthogonal modelling functions, predicted squared error), written
from those published descriptions; the greedy variant is the orthogonal forward regression
of S. Chen, S. A. Billings & W. Luo, "Orthogonal least squares methods and their application
to non-linear system identification", Int. J. Control 50(5), 1989.

For a response z (N,) and candidate columns ξ_j (scaled variables, constant first):

1. Orthogonalise the candidates (``flightid.globalmodel.orthogonal``); each orthogonal
   function p_j lowers the cost J = ½‖z − ŷ‖² by ΔJ_j = ½ (p_jᵀz)² / p_jᵀp_j, independently
   of the others.
2. Rank the functions:

   - ``ranking="fixed_order"`` (the 1995 description): one orthogonalisation in candidate
     order, the non-forced functions ranked once by ΔJ_j (so the ranking depends on the
     order of the candidates);
   - ``ranking="greedy"`` (default, independent of the order): at step s the remaining
     candidates are orthogonalised against the function retained at step s − 1,
     w_j ← w_j − (p_sᵀw_j / p_sᵀp_s) p_s, and the one of largest ΔJ = ½ (w_jᵀz)² / w_jᵀw_j is
     retained; a candidate with ‖w_j‖² < tol ‖ξ_j‖² is dependent on those retained and skipped.

3. Along the ranked sequence, with n functions retained (forced ones included),

       MSFE(n) = (1/N) ‖z − ŷ_n‖² = (1/N) (zᵀz − Σ_{j≤n} (p_jᵀz)² / p_jᵀp_j)
       PSE(n)  = MSFE(n) + σ²_max · n / N

   and the model is the n of least PSE. σ²_max is an upper bound on the squared fit error
   that new data will see; Morelli takes σ²_max = (1/N) Σ (z_i − z̄)², the mean-square error
   of the constant-only model (``sigma2_max="response"``). That form (penalty σ²_max·n/N) is
   the one ``flightid.regression.least_squares`` reports as PSE; Barron's original predicted
   squared error, MSFE + 2σ²n/N, has the *noise* variance σ² with a factor 2 — Morelli's
   conservative σ²_max replaces 2σ². Also offered: ``"full"`` (s² of the fit on every
   candidate, a noise estimate: PSE then behaves like Mallows' C_p) or a number (z's unit²).
   The greedy path's PSE need not have a single minimum: it is followed to ``max_terms`` or
   until PSE has risen ``patience`` times in a row past its least value, and its least value
   taken.
4. The retained functions are expanded back into the candidates they came from: for the
   greedy ranking they span exactly the retained candidates (θ = Γ⁻¹a, the triangular Γ of
   the retained ones, ``retransform``); the caller refits those candidates by least squares,
   which gives the same fitted values and the statistics. For ``fixed_order`` a retained p_j
   also holds earlier, non-retained candidates; the model is then the retained candidates
   themselves, refitted (their span, not the orthogonal functions').
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from flightid.globalmodel.orthogonal import gram_schmidt, retransform
from flightid.globalmodel.variables import GlobalModelError

__all__ = ["MofPath", "select_terms", "predicted_squared_error", "RANKINGS"]

RANKINGS = ("greedy", "fixed_order")
# relative difference of ΔJ below which two candidates tie
_TIE = 1e-9


def predicted_squared_error(mse, n_terms, n_samples: int, sigma2_max: float):
    """PSE = MSFE + σ²_max · n / N (module docstring), z's unit squared."""
    # PSE(n) = MSFE(n) + σ²_max n / N
    return np.asarray(mse, dtype=float) + sigma2_max * np.asarray(n_terms) / n_samples


@dataclass(frozen=True, eq=False)
class MofPath:
    """The ranked path of a MOF selection.

    Attributes:
        labels: candidate labels in ranked order (forced first); the first ``n_terms`` are
            the selected model.
        indices: their column indices among the candidates.
        cost_reduction: ΔJ of each ranked function (z's unit² · samples / 2).
        mse: MSFE(n) after the first n functions, n = 1 … len(labels).
        pse: PSE(n) along the path.
        n_terms: n*, the number of functions selected (least PSE).
        sigma2_max: σ²_max used in PSE, z's unit².
        ranking: ``"greedy"`` or ``"fixed_order"``.
        theta_scaled: the selected model's parameters in scaled candidates (θ = Γ⁻¹a),
            in the order of ``labels[:n_terms]``.
        n_candidates: how many candidates were offered.
    """

    labels: tuple[str, ...]
    indices: np.ndarray
    cost_reduction: np.ndarray
    mse: np.ndarray
    pse: np.ndarray
    n_terms: int
    sigma2_max: float
    ranking: str
    theta_scaled: np.ndarray
    n_candidates: int

    @property
    def selected(self) -> tuple[str, ...]:
        """Labels of the selected candidates, in the order they were retained."""
        return self.labels[: self.n_terms]

    def cost_share(self, z_spread: float) -> np.ndarray:
        """ΔJ of each ranked function as a share of ½ Σ (z − z̄)² (``z_spread`` = Σ (z − z̄)²);
        NaN for the constant term and when z does not vary."""
        if not z_spread > 0:
            return np.full(self.cost_reduction.shape, np.nan)
        share = self.cost_reduction / (0.5 * z_spread)
        return np.where([label == "1" for label in self.labels], np.nan, share)

    def to_dict(self) -> list[dict]:
        """The path: one entry per ranked function (n_terms, term, mse, pse)."""
        return [
            {"n_terms": n + 1, "term": label, "mse": float(m), "pse": float(p)}
            for n, (label, m, p) in enumerate(zip(self.labels, self.mse, self.pse, strict=True))
        ]


def _sigma2_max(option, z: np.ndarray, columns: np.ndarray, tol: float) -> float:
    """σ²_max for PSE: "response", "full" or a non-negative number (module docstring)."""
    if isinstance(option, str):
        if option == "response":
            # σ²_max = (1/N) Σ (z − z̄)²
            return float(np.mean((z - z.mean()) ** 2))
        if option == "full":
            P, _, kept = gram_schmidt(columns, tol)
            dof = z.size - kept.size
            if dof <= 0:
                raise GlobalModelError(
                    f"sigma2_max: 'full' needs more samples ({z.size}) than independent "
                    f"candidates ({kept.size})"
                )
            # s² = (zᵀz − Σ (p_jᵀz)²/p_jᵀp_j) / (N − M)
            rss = float(z @ z) - float(np.sum((P.T @ z) ** 2 / np.einsum("ij,ij->j", P, P)))
            return max(rss, 0.0) / dof
        raise GlobalModelError(
            f"sigma2_max: expected 'response', 'full' or a number, got {option!r}"
        )
    value = float(option)
    if not (np.isfinite(value) and value >= 0):
        raise GlobalModelError(f"sigma2_max: expected a non-negative number, got {option!r}")
    return value


def _greedy(
    z: np.ndarray,
    columns: np.ndarray,
    forced: list[int],
    max_terms: int,
    tol: float,
    patience: int,
    sigma2_max: float,
):
    """Greedy orthogonal forward selection: (order, ΔJ, P (N, n), Γ (n, n)) over the path."""
    n, n_columns = columns.shape
    work = columns.copy()
    norms2 = np.einsum("ij,ij->j", columns, columns)
    available = np.ones(n_columns, dtype=bool)
    order: list[int] = []
    reductions: list[float] = []
    retained: list[np.ndarray] = []
    gamma_rows: list[np.ndarray] = []
    zz = float(z @ z)
    best_pse, rises = np.inf, 0
    while len(order) < max_terms:
        ww = np.einsum("ij,ij->j", work, work)
        wz = work.T @ z
        usable = available & (ww > tol * norms2) & (ww > 0)
        if len(order) < len(forced):
            j = forced[len(order)]
            if not usable[j]:
                raise GlobalModelError(
                    f"forced: candidate column {j} is dependent on the other forced terms"
                )
        elif not usable.any():
            break
        else:
            # ΔJ_j = ½ (w_jᵀz)² / w_jᵀw_j over the usable candidates
            gain = np.where(usable, wz**2 / np.where(usable, ww, 1.0), -np.inf)
            # ties (to round-off) go to the earlier, lower-order candidate: with a variable
            # that does not vary, α and α·M are the same function and α is kept
            j = int(np.flatnonzero(gain >= np.max(gain) * (1.0 - _TIE))[0])
        p = work[:, j].copy()
        pp = float(ww[j])
        reductions.append(0.5 * float(wz[j]) ** 2 / pp)
        order.append(j)
        retained.append(p)
        available[j] = False
        # γ_sk = p_sᵀ w_k / p_sᵀ p_s;  w_k ← w_k − γ_sk p_s
        coefficients = (p @ work) / pp
        coefficients[j] = 0.0
        work -= np.outer(p, coefficients)
        gamma_rows.append(coefficients)
        if len(order) <= len(forced):
            continue
        # PSE(n) = (zᵀz − 2 Σ ΔJ)/N + σ²_max n / N: stop after `patience` rises in a row
        pse = (zz - 2.0 * sum(reductions)) / n + sigma2_max * len(order) / n
        if pse < best_pse:
            best_pse, rises = pse, 0
        else:
            rises += 1
            if rises >= patience:
                break
    gamma = np.eye(len(order))
    for s, row in enumerate(gamma_rows):
        gamma[s, s + 1 :] = row[order[s + 1 :]]
    P = np.column_stack(retained) if retained else np.zeros((n, 0))
    return order, np.array(reductions), P, gamma


def _fixed_order(z: np.ndarray, columns: np.ndarray, forced: list[int], tol: float):
    """One orthogonalisation in candidate order (forced first), ranked once by ΔJ."""
    rest = [j for j in range(columns.shape[1]) if j not in forced]
    sequence = forced + rest
    P, Gamma, kept = gram_schmidt(columns[:, sequence], tol)
    kept_columns = [sequence[k] for k in kept]
    missing = [j for j in forced if j not in kept_columns]
    if missing:
        raise GlobalModelError(f"forced: candidate columns {missing} are dependent")
    # ΔJ_j = ½ (p_jᵀz)² / p_jᵀp_j
    reductions = 0.5 * (P.T @ z) ** 2 / np.einsum("ij,ij->j", P, P)
    n_forced = len(forced)
    ranked = n_forced + np.argsort(-reductions[n_forced:], kind="stable")
    positions = np.concatenate([np.arange(n_forced), ranked]).astype(int)
    return [kept_columns[k] for k in positions], reductions[positions], P, Gamma, positions


def select_terms(
    z: np.ndarray,
    columns: np.ndarray,
    labels: Sequence[str],
    *,
    forced: Sequence[str] = ("1",),
    sigma2_max: float | str = "response",
    ranking: str = "greedy",
    max_terms: int | None = None,
    patience: int = 10,
    tol: float = 1e-10,
) -> MofPath:
    """Rank the candidates by orthogonal functions and select by least PSE (module docstring).

    Args:
        z: response (N,).
        columns: candidate columns in scaled variables (N, M), one per label.
        labels: candidate labels (term text).
        forced: labels always in the model, retained first (default the constant).
        sigma2_max: "response", "full" or a number (z's unit²).
        ranking: "greedy" or "fixed_order".
        max_terms: longest path followed (default: every candidate).
        patience: the greedy path stops after PSE rose this many times in a row.
        tol: relative squared norm under which a column is dependent.
    """
    z = np.asarray(z, dtype=float)
    columns = np.asarray(columns, dtype=float)
    labels = list(labels)
    if ranking not in RANKINGS:
        raise GlobalModelError(f"ranking: expected one of {list(RANKINGS)}, got {ranking!r}")
    unknown = [f for f in forced if f not in labels]
    if unknown:
        raise GlobalModelError(f"forced: expected candidate terms, got {unknown}")
    forced_index = [labels.index(f) for f in forced]
    n, m = columns.shape
    # the path holds at least the forced terms
    max_terms = m if max_terms is None else min(max(int(max_terms), len(forced_index), 1), m)
    s2max = _sigma2_max(sigma2_max, z, columns, tol)
    if ranking == "greedy":
        order, reductions, P, Gamma = _greedy(
            z, columns, forced_index, max_terms, tol, patience, s2max
        )
        positions = np.arange(len(order))
    else:
        order, reductions, P, Gamma, positions = _fixed_order(z, columns, forced_index, tol)
        order, reductions = order[:max_terms], reductions[:max_terms]
    # MSFE(n) = (zᵀz − 2 Σ_{j≤n} ΔJ_j) / N
    mse = np.maximum((float(z @ z) - 2.0 * np.cumsum(reductions)) / n, 0.0)
    counts = np.arange(1, len(order) + 1)
    pse = predicted_squared_error(mse, counts, n, s2max)
    # n* = argmin PSE(n) over n ≥ the number of forced terms (at least one term)
    first = max(len(forced_index), 1)
    n_terms = first + int(np.argmin(pse[first - 1 :]))
    theta = _retained_theta(z, P, Gamma, positions[:n_terms])
    return MofPath(
        labels=tuple(labels[j] for j in order),
        indices=np.array(order, dtype=int),
        cost_reduction=np.asarray(reductions, dtype=float),
        mse=mse,
        pse=pse,
        n_terms=int(n_terms),
        sigma2_max=s2max,
        ranking=ranking,
        theta_scaled=theta,
        n_candidates=m,
    )


def _retained_theta(z: np.ndarray, P: np.ndarray, Gamma: np.ndarray, positions) -> np.ndarray:
    """θ = Γ⁻¹ a with a_j = p_jᵀz / p_jᵀp_j for the retained functions and 0 for the others,
    read at the retained candidates. On the greedy path the retained functions are the first
    ones, so this is the exact expansion Γ_SS⁻¹ a_S of the orthogonal model."""
    a = np.zeros(P.shape[1])
    chosen = np.asarray(positions, dtype=int)
    # a_j = p_jᵀ z / p_jᵀ p_j
    a[chosen] = (P[:, chosen].T @ z) / np.einsum("ij,ij->j", P[:, chosen], P[:, chosen])
    return retransform(Gamma, a)[chosen]
