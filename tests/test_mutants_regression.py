"""Stepwise regression and equation error against independent computations.

Written because hand-made mutants survived the suite (issue 10 §6): the removal test compared
with F-to-enter instead of F-to-remove, F-to-enter's degrees of freedom off by one, and C_X
adding thrust instead of removing it. The references here are plain numpy least squares
(residual sums of squares), scipy.stats.linregress, and an independent transcription of the
modified stepwise procedure of METHOD §5 (Klein, Batterson & Murphy, NASA TP-1916).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from flightid.regression import stepwise
from flightid.regression.equation_error import (
    Airframe,
    equation_error_signals,
    force_coefficients,
)

CANDIDATES = ("x1", "x2", "x3")


def _proxy_data(seed: int, n: int = 40):
    """z = x2 + x3 + ε, and a candidate x1 = x2 + x3 + noise (a proxy of the true pair).

    corr(z, x1) = 2/√((2 + σ_ε²)(2 + σ_1²)) exceeds corr(z, x2) = 1/√(2 + σ_ε²) when σ_1² < 2,
    so x1 enters first; once x2 and x3 are in, x1 explains nothing more and its partial F
    falls to an F(1, N − 4) draw: it leaves unless f_remove is below that draw.
    """
    rng = np.random.default_rng(seed)
    x2 = rng.normal(size=n)
    x3 = rng.normal(size=n)
    x1 = x2 + x3 + 0.5 * rng.normal(size=n)
    z = x2 + x3 + 0.3 * rng.normal(size=n)
    return z, {"x1": x1, "x2": x2, "x3": x3}


def _rss(z, signals, terms):
    """Residual sum of squares of z on a constant and the named signals (numpy lstsq)."""
    x = np.column_stack([np.ones_like(z)] + [signals[t] for t in terms])
    beta, *_ = np.linalg.lstsq(x, z, rcond=None)
    return float(np.sum((z - x @ beta) ** 2))


def _partial_f(z, signals, small, large):
    """Partial F of the one term in ``large`` but not ``small``:
    F = (RSS_small − RSS_large) / (RSS_large / (N − p_large)), p counting the constant."""
    n = z.size
    rss_large = _rss(z, signals, large)
    return (_rss(z, signals, small) - rss_large) / (rss_large / (n - len(large) - 1))


def _reference_stepwise(z, signals, f_enter, f_remove):
    """METHOD §5 transcribed independently: enter the candidate of largest partial F (the
    largest partial correlation) if F ≥ f_enter, then remove the weakest term (not the one
    just entered) while its partial F < f_remove; a model already visited is not re-entered.
    Returns the list of (action, term, F) and the final term set."""
    model: list[str] = []
    visited = {frozenset()}
    history = []
    while True:
        entered = None
        outside = [c for c in CANDIDATES if c not in model]
        if outside:
            f_in = {c: _partial_f(z, signals, model, model + [c]) for c in outside}
            best = max(f_in, key=f_in.get)
            trial = frozenset(model + [best])
            if f_in[best] >= f_enter and trial not in visited:
                model = [c for c in CANDIDATES if c in trial]
                visited.add(trial)
                entered = best
                history.append(("enter", best, f_in[best]))
        removed = False
        while True:
            f_out = {
                t: _partial_f(z, signals, [c for c in model if c != t], model)
                for t in model
                if t != entered
            }
            if not f_out:
                break
            weakest = min(f_out, key=f_out.get)
            trial = frozenset(c for c in model if c != weakest)
            if f_out[weakest] >= f_remove or trial in visited:
                break
            model = [c for c in CANDIDATES if c in trial]
            visited.add(trial)
            removed = True
            history.append(("remove", weakest, f_out[weakest]))
        if entered is None and not removed:
            return history, set(model)


@pytest.mark.parametrize(
    ("seed", "f_enter", "f_remove", "x1_leaves"),
    [
        # x1's final partial F is 0.53: it leaves whichever threshold is used
        (0, 4.0, 1.5, True),
        # x1's final partial F is 2.37, between the thresholds: f_remove = 1.5 keeps it (a
        # comparison with f_enter = 4 would remove it) ...
        (6, 4.0, 1.5, False),
        # ... and f_remove = 3 > f_enter = 2 removes it (a comparison with f_enter would not)
        (6, 2.0, 3.0, True),
    ],
)
def test_term_enters_then_leaves_by_the_f_to_remove_threshold(seed, f_enter, f_remove, x1_leaves):
    z, s = _proxy_data(seed)
    result = stepwise(
        z, list(CANDIDATES), s, f_enter=f_enter, f_remove=f_remove, select="final", response="z"
    )
    actions = [(step.action, step.term) for step in result.steps]
    # the proxy enters first, the true terms follow
    assert actions[:2] == [("start", None), ("enter", "x1")]
    assert {("enter", "x2"), ("enter", "x3")} <= set(actions)
    # x1's partial F in the final model {1, x1, x2, x3}, independently, lies where the
    # parametrisation says: below both thresholds, or between them
    final_f = _partial_f(z, s, ["x2", "x3"], ["x1", "x2", "x3"])
    if x1_leaves:
        assert final_f < f_remove
        assert ("remove", "x1") in actions
        assert set(result.selected) == {"1", "x2", "x3"}
    else:
        assert f_remove <= final_f < f_enter
        assert ("remove", "x1") not in actions
        assert set(result.selected) == {"1", "x1", "x2", "x3"}
    # the whole path agrees with the independent transcription, partial F included
    history, final = _reference_stepwise(z, s, f_enter, f_remove)
    assert [(a, t) for a, t, _ in history] == actions[1:]
    assert final | {"1"} == set(result.selected)
    for (_, _, f_ref), step in zip(history, result.steps[1:], strict=True):
        assert step.partial_f == pytest.approx(f_ref, rel=1e-9)


def test_f_to_enter_degrees_of_freedom_against_scipy_and_rss():
    """F to enter = (RSS_before − RSS_after) / (RSS_after / (N − n_p − 1)), n_p the terms
    before entry (constant included). N = 40 is small on purpose: one degree of freedom
    more or less moves F by ≈ 3 %."""
    z, s = _proxy_data(6)
    result = stepwise(z, list(CANDIDATES), s, f_enter=4.0, f_remove=1.5, select="final")
    first = result.steps[1]
    assert (first.action, first.term) == ("enter", "x1")
    # scipy: for the first entry the model is {1, x1}, F = t² of the slope, t on N − 2 dof
    fit = stats.linregress(s["x1"], z)
    assert first.partial_f == pytest.approx((fit.slope / fit.stderr) ** 2, rel=1e-9)
    # closed form through the partial correlation r: F = r² (N − n_p − 1)/(1 − r²)
    assert first.partial_f == pytest.approx(
        fit.rvalue**2 * (z.size - 2) / (1 - fit.rvalue**2), rel=1e-9
    )
    # later entries: RSS differences with numpy least squares
    model: list[str] = []
    for step in result.steps[1:]:
        if step.action == "enter":
            expected = _partial_f(z, s, model, model + [step.term])
            assert step.partial_f == pytest.approx(expected, rel=1e-9), step.term
            model.append(step.term)
        else:
            model.remove(step.term)
    assert len(model) == 3


def test_f_to_remove_values_are_partial_f_of_the_model_before_removal():
    z, s = _proxy_data(0)
    result = stepwise(z, list(CANDIDATES), s, f_enter=4.0, f_remove=4.0, select="final")
    (removal,) = [step for step in result.steps if step.action == "remove"]
    assert removal.term == "x1"
    expected = _partial_f(z, s, ["x2", "x3"], ["x1", "x2", "x3"])
    assert removal.partial_f == pytest.approx(expected, rel=1e-9)
    # and the model left behind is the true one, with least-squares estimates near (1, 1)
    est = dict(zip(result.fit.names, result.fit.estimates, strict=True))
    assert est["x2"] == pytest.approx(1.0, abs=0.1) and est["x3"] == pytest.approx(1.0, abs=0.1)


# ---------------------------------------------------------------- equation error with thrust

AIRFRAME = Airframe(mass=1200.0, S=16.0, g=9.80665)


def test_thrust_is_removed_from_the_measured_force_coefficients():
    """Accelerometers sense aerodynamic force plus thrust: a = (q̄ S C_aero + T)/(m g). With
    the thrust components given, the equation-error C_X and C_Z are the aerodynamic ones."""
    rng = np.random.default_rng(4)
    n = 50
    qbar = rng.uniform(1500.0, 3000.0, n)  # Pa
    cx_aero = rng.uniform(-0.1, 0.0, n)
    cz_aero = rng.uniform(-0.8, -0.2, n)
    thrust_x = rng.uniform(1000.0, 3000.0, n)  # N, forward
    thrust_z = rng.uniform(-300.0, -100.0, n)  # N, thrust line tilted up: −z
    mg = AIRFRAME.mass * AIRFRAME.g
    a_x = (qbar * AIRFRAME.S * cx_aero + thrust_x) / mg
    a_z = (qbar * AIRFRAME.S * cz_aero + thrust_z) / mg
    out = force_coefficients(a_x, None, a_z, qbar, AIRFRAME, thrust_x=thrust_x, thrust_z=thrust_z)
    np.testing.assert_allclose(out["CX"], cx_aero, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(out["CZ"], cz_aero, rtol=1e-12, atol=1e-15)
    # the same through the channel-level entry point
    signals = equation_error_signals(
        {"ax": a_x, "az": a_z, "qbar": qbar}, AIRFRAME, thrust_x=thrust_x, thrust_z=thrust_z
    )
    np.testing.assert_allclose(signals["CX"], cx_aero, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(signals["CZ"], cz_aero, rtol=1e-12, atol=1e-15)
    # without the thrust given, it stays folded into the coefficients (RP-1153's convention)
    folded = force_coefficients(a_x, None, a_z, qbar, AIRFRAME)
    np.testing.assert_allclose(folded["CX"], cx_aero + thrust_x / (qbar * AIRFRAME.S))
