"""Multivariate orthogonal functions: candidates, Gram–Schmidt, PSE selection and the front
door's checks, against independent references (brute-force enumeration, numpy.linalg.qr and
lstsq, least squares on each prefix of the path, stepwise regression)."""

from __future__ import annotations

from itertools import product

import numpy as np
import pytest

from flightid.globalmodel import GlobalModelError, GlobalModelSettings, fit_global_model
from flightid.globalmodel.candidates import (
    candidate_columns,
    generate_candidates,
    monomial_exponents,
    term_scale,
)
from flightid.globalmodel.mof import select_terms
from flightid.globalmodel.orthogonal import (
    cost_reductions,
    gram_schmidt,
    orthogonal_coefficients,
    retransform,
)
from flightid.globalmodel.variables import Normalisation
from flightid.model.terms import evaluate_terms, parse_term
from flightid.regression.least_squares import least_squares
from flightid.regression.stepwise import stepwise

VARIABLES = ["alpha", "beta", "Mach", "qhat", "de"]
ORDERS = {"alpha": 4, "beta": 2, "Mach": 2, "qhat": 1, "de": 2}


def _brute_force_count(orders: dict[str, int], max_order: int) -> int:
    """Exponent vectors in the box 0 ≤ e_k ≤ o_k with Σ e_k ≤ T, counted one by one."""
    count = 0
    for e in product(*[range(o + 1) for o in orders.values()]):
        if sum(e) <= max_order:
            count += 1
    return count


@pytest.mark.parametrize(
    ("orders", "max_order"),
    [(ORDERS, 3), (ORDERS, 4), ({"alpha": 5, "Mach": 3}, 5), ({"alpha": 2, "de": 2}, 2)],
)
def test_candidate_count_equals_brute_force_enumeration(orders, max_order):
    exponents = monomial_exponents(orders, max_order)
    assert len(exponents) == _brute_force_count(orders, max_order)
    assert len(set(exponents)) == len(exponents)
    assert exponents[0] == (0,) * len(orders)
    # total order never decreases along the list
    totals = [sum(e) for e in exponents]
    assert totals == sorted(totals)


def test_the_five_variable_counts_of_the_plan():
    # enumeration by hand of the plan's example: 47 candidates at T = 3, 87 at T = 4
    assert len(generate_candidates(VARIABLES, ORDERS, 3)) == 47
    assert len(generate_candidates(VARIABLES, ORDERS, 4)) == 87


def test_candidate_labels_parse_back_to_the_same_terms():
    terms = generate_candidates(
        VARIABLES, ORDERS, 3, knots={"alpha": [0.25, -0.05]}, cross_with=["qhat"]
    )
    for term in terms:
        assert parse_term(term.label) == term
    labels = [t.label for t in terms]
    assert labels[0] == "1"
    assert "spline1(alpha,0.25)" in labels and "qhat*spline1(alpha,-0.05)" in labels
    assert len(set(labels)) == len(labels)


def test_too_many_candidates_is_a_named_error_with_the_count():
    with pytest.raises(GlobalModelError, match=r"max_candidates = 40 .* got 47"):
        generate_candidates(VARIABLES, ORDERS, 3, max_candidates=40)


def _random_matrix(seed=0, n=60, m=6):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, n)
    # polynomial columns: strongly correlated, as real candidates are
    return np.column_stack([x**k + 0.1 * rng.normal(size=n) * (k > 0) for k in range(m)])


def test_gram_schmidt_matches_numpy_qr():
    Xi = _random_matrix()
    P, Gamma, kept = gram_schmidt(Xi)
    assert list(kept) == list(range(Xi.shape[1]))
    Q, _ = np.linalg.qr(Xi)
    unit = P / np.linalg.norm(P, axis=0)
    signs = np.sign(np.sum(unit * Q, axis=0))
    np.testing.assert_allclose(unit, Q * signs, atol=1e-10)
    gram = P.T @ P
    off = gram - np.diag(np.diag(gram))
    assert np.max(np.abs(off)) < 1e-12 * np.max(np.diag(gram))
    np.testing.assert_allclose(np.diag(Gamma), 1.0)
    np.testing.assert_array_equal(np.tril(Gamma, -1), 0.0)
    np.testing.assert_allclose(P @ Gamma, Xi, atol=1e-12)


def test_retransformation_equals_lstsq_and_cost_identity():
    Xi = _random_matrix(1)
    z = np.random.default_rng(2).normal(size=Xi.shape[0])
    P, Gamma, _ = gram_schmidt(Xi)
    a = orthogonal_coefficients(P, z)
    theta = retransform(Gamma, a)
    reference, *_ = np.linalg.lstsq(Xi, z, rcond=None)
    np.testing.assert_allclose(theta, reference, rtol=1e-10, atol=1e-10)
    # Σ ΔJ_j = ½ (zᵀz − ‖z − Ξθ‖²)
    residual = z - Xi @ reference
    assert np.sum(cost_reductions(P, z)) == pytest.approx(
        0.5 * (z @ z - residual @ residual), rel=1e-12
    )


def test_a_dependent_column_is_dropped():
    Xi = _random_matrix(3, m=3)
    Xi = np.column_stack([Xi, Xi[:, 1] + 2.0 * Xi[:, 2], Xi[:, 1] ** 3])
    _, _, kept = gram_schmidt(Xi)
    assert list(kept) == [0, 1, 2, 4]


def _known_polynomial(seed=1, n=4000):
    rng = np.random.default_rng(seed)
    alpha = rng.uniform(-0.2, 0.6, n)
    mach = rng.uniform(0.3, 0.9, n)
    de = rng.uniform(-0.3, 0.3, n)
    true = {"1": 0.2, "alpha": 4.5, "alpha^2": -3.0, "alpha*Mach": 0.8, "alpha^2*de": -1.2}
    signals = {"alpha": alpha, "Mach": mach, "de": de}
    z = sum(v * parse_term(t).evaluate(signals, n) for t, v in true.items())
    signals["CL"] = z + rng.normal(0.0, 0.01, n)
    return signals, true


SETTINGS = GlobalModelSettings(orders={"alpha": 4, "Mach": 2, "de": 2}, max_order=4)


def test_the_known_polynomial_is_recovered_exactly():
    signals, true = _known_polynomial()
    model = fit_global_model(signals, ["CL"], ["alpha", "Mach", "de"], settings=SETTINGS)
    cl = model["CL"]
    assert set(cl.terms) == set(true)
    for j, term in enumerate(cl.terms):
        assert abs(cl.estimates[j] - true[term]) < 3.0 * cl.std[j], term
    # the path's PSE at the selected model is least_squares' PSE of the same terms
    fit = least_squares(
        evaluate_terms([parse_term(t) for t in cl.terms], signals),
        signals["CL"],
        sigma2_max=cl.sigma2_max,
    )
    assert cl.path.pse[cl.path.n_terms - 1] == pytest.approx(fit.pse, rel=1e-12)
    assert cl.pse == pytest.approx(fit.pse, rel=1e-12)
    # σ²_max "response": the variance of z about its mean
    assert cl.sigma2_max == pytest.approx(np.var(signals["CL"]), rel=1e-12)


def test_the_path_is_least_squares_on_each_prefix():
    signals, _ = _known_polynomial(seed=4, n=800)
    names = ["alpha", "Mach", "de"]
    terms = generate_candidates(names, SETTINGS.orders, 4)
    normalisation = Normalisation.from_data(signals, names)
    columns = candidate_columns(terms, signals, normalisation)
    z = signals["CL"]
    path = select_terms(z, columns, [t.label for t in terms], max_terms=12, patience=100)
    n = z.size
    for count in range(1, len(path.labels) + 1):
        X = evaluate_terms([parse_term(t) for t in path.labels[:count]], signals)
        theta, *_ = np.linalg.lstsq(X, z, rcond=None)
        rss = float(np.sum((z - X @ theta) ** 2))
        assert path.mse[count - 1] == pytest.approx(rss / n, rel=1e-8, abs=1e-14)
        # PSE = MSFE + σ²_max n / N
        assert path.pse[count - 1] == pytest.approx(rss / n + path.sigma2_max * count / n, rel=1e-8)
    assert path.n_terms == int(np.argmin(path.pse)) + 1
    # θ of the scaled candidates, retransformed to raw units, is the raw least-squares fit
    selected = [parse_term(t) for t in path.selected]
    raw, *_ = np.linalg.lstsq(evaluate_terms(selected, signals), z, rcond=None)
    scales = np.array([term_scale(t, normalisation) for t in selected])
    np.testing.assert_allclose(path.theta_scaled / scales, raw, rtol=1e-8, atol=1e-10)


def test_greedy_selects_the_same_set_as_stepwise():
    signals, _ = _known_polynomial()
    names = ["alpha", "Mach", "de"]
    terms = generate_candidates(names, SETTINGS.orders, 4)
    model = fit_global_model(signals, ["CL"], names, settings=SETTINGS)
    result = stepwise(
        signals["CL"],
        [t.label for t in terms[1:]],
        signals,
        sigma2_max="response",
    )
    assert set(result.selected) == set(model["CL"].terms)


def test_fixed_order_equals_greedy_on_orthogonal_columns():
    rng = np.random.default_rng(5)
    n = 500
    Q, _ = np.linalg.qr(rng.normal(size=(n, 7)))
    columns = np.column_stack([np.ones(n), Q[:, 1:] - Q[:, 1:].mean(axis=0)])
    columns[:, 1:] -= np.outer(np.ones(n), columns[:, 1:].mean(axis=0))
    Pz, _, _ = gram_schmidt(columns)
    z = Pz @ np.array([1.0, 3.0, 0.0, 2.0, 0.01, 0.5, 0.0]) + 0.05 * rng.normal(size=n)
    labels = [f"c{j}" if j else "1" for j in range(7)]
    greedy = select_terms(z, Pz, labels, ranking="greedy", patience=100)
    fixed = select_terms(z, Pz, labels, ranking="fixed_order")
    assert greedy.labels == fixed.labels
    assert greedy.n_terms == fixed.n_terms
    np.testing.assert_allclose(greedy.pse, fixed.pse, rtol=1e-12)
    assert set(greedy.selected) == {"1", "c1", "c3", "c5"}


def test_sigma2_max_full_is_the_all_candidate_fit_s2():
    signals, _ = _known_polynomial(seed=6, n=600)
    names = ["alpha", "Mach", "de"]
    terms = generate_candidates(names, SETTINGS.orders, 4)
    normalisation = Normalisation.from_data(signals, names)
    columns = candidate_columns(terms, signals, normalisation)
    path = select_terms(signals["CL"], columns, [t.label for t in terms], sigma2_max="full")
    X = evaluate_terms(terms, signals)
    theta, *_ = np.linalg.lstsq(X, signals["CL"], rcond=None)
    rss = np.sum((signals["CL"] - X @ theta) ** 2)
    assert path.sigma2_max == pytest.approx(rss / (X.shape[0] - X.shape[1]), rel=1e-6)
    fixed = select_terms(signals["CL"], columns, [t.label for t in terms], sigma2_max=0.5)
    assert fixed.sigma2_max == 0.5


def test_decimation_keeps_every_kth_sample_per_maneuver():
    signals, _ = _known_polynomial(seed=7, n=1000)
    index = np.repeat([0, 1, 2], [300, 333, 367])
    settings = GlobalModelSettings(orders={"alpha": 2, "Mach": 1, "de": 1}, max_order=2)
    model = fit_global_model(
        signals,
        {"CL": "CL"},
        ["alpha", "Mach", "de"],
        settings=GlobalModelSettings(**{**settings.to_dict(), "decimate": 4}),
        maneuver_index=index,
    )
    # ceil(300/4) + ceil(333/4) + ceil(367/4)
    assert model["CL"].n_samples == 75 + 84 + 92
    assert [s.n_samples for s in model.sources] == [300, 333, 367]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda s: s.pop("Mach"), r"signals: expected channels \['Mach'\]"),
        (lambda s: s.__setitem__("de", s["de"][:-1]), r"signals\['de'\]: expected 1000 samples"),
        (lambda s: s["alpha"].__setitem__(17, np.nan), r"signals\['alpha'\].*sample 17"),
    ],
)
def test_front_door_errors_name_the_key(change, message):
    signals, _ = _known_polynomial(seed=8, n=1000)
    signals = {k: v.copy() for k, v in signals.items()}
    change(signals)
    with pytest.raises(GlobalModelError, match=message):
        fit_global_model(signals, ["CL"], ["alpha", "Mach", "de"], settings=SETTINGS)


def test_too_few_samples_and_too_many_candidates_are_named_errors():
    signals, _ = _known_polynomial(seed=9, n=30)
    with pytest.raises(GlobalModelError, match=r"signals\['CL'\]: expected more samples than"):
        fit_global_model(signals, ["CL"], ["alpha", "Mach", "de"], settings=SETTINGS)
    few = GlobalModelSettings(max_order=4, max_candidates=10)
    with pytest.raises(GlobalModelError, match=r"max_candidates = 10 .*got 35"):
        fit_global_model(signals, ["CL"], ["alpha", "Mach", "de"], settings=few)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"method": "spline"}, r"method: expected one of \['mof', 'table'\], got 'spline'"),
        ({"ranking": "best"}, "ranking: expected one of"),
        ({"sigma2_max": "noise"}, "sigma2_max: expected 'response', 'full' or a number"),
        ({"decimate": 0}, "decimate: expected an integer ≥ 1"),
        ({"orders": {"alpha": -1}}, r"orders\['alpha'\]: expected an integer ≥ 0"),
        ({"residual_variance": "both"}, "residual_variance: expected one of"),
        ({"level": 1.5}, "level"),
    ],
)
def test_settings_are_checked(options, message):
    with pytest.raises(GlobalModelError, match=message):
        GlobalModelSettings(**options)


def test_orders_of_an_unknown_variable_is_a_named_error():
    signals, _ = _known_polynomial(seed=10, n=300)
    settings = GlobalModelSettings(orders={"beta": 2})
    with pytest.raises(GlobalModelError, match=r"orders: expected variables from .* \['beta'\]"):
        fit_global_model(signals, ["CL"], ["alpha", "Mach", "de"], settings=settings)


def test_the_facade_exports_the_front_door():
    import flightid
    import flightid.globalmodel.fit as fit_module
    import flightid.globalmodel.model as model_module

    assert flightid.fit_global_model is fit_module.fit_global_model
    assert flightid.GlobalModel is model_module.GlobalModel


def test_aero_model_carries_the_selected_terms_and_names():
    signals, true = _known_polynomial(seed=12, n=2000)
    model = fit_global_model(signals, {"CL": "CL"}, ["alpha", "Mach", "de"], settings=SETTINGS)
    aero = model.aero_model()
    cl = model["CL"]
    assert aero.coefficients == ("CL",)
    assert [t.label for t in aero.terms("CL")] == list(cl.terms)
    assert aero.parameter_names == list(cl.parameters)
    # NASA names: coefficient, underscore, the term's signals with powers
    assert set(cl.parameters) == {"CL_0", "CL_alpha", "CL_alpha2", "CL_alpha_Mach", "CL_alpha2_de"}
    values = model.parameter_values()
    assert values["CL_alpha"] == pytest.approx(4.5, abs=0.01)
    other = fit_global_model(signals, {"lift": "CL"}, ["alpha", "Mach", "de"], settings=SETTINGS)
    with pytest.raises(GlobalModelError, match=r"aero_model: expected coefficients .* \['lift'\]"):
        other.aero_model()


def test_summary_and_frame_list_the_selected_terms():
    pytest.importorskip("pandas")
    signals, _ = _known_polynomial(seed=13, n=1000)
    model = fit_global_model(signals, ["CL"], ["alpha", "Mach", "de"], settings=SETTINGS)
    text = model.summary()
    for term in model["CL"].terms:
        assert term in text
    frame = model.to_frame()
    assert list(frame.index) == list(model["CL"].parameters)
    np.testing.assert_array_equal(frame["value"].to_numpy(), model["CL"].estimates)
    prediction = model.predict({"alpha": [0.0, 0.2], "Mach": 0.5, "de": 0.0})["CL"]
    assert list(prediction.to_frame()["value"]) == list(prediction.value)


def test_a_variable_that_does_not_vary_leaves_the_lower_order_term():
    rng = np.random.default_rng(14)
    n = 1500
    alpha = rng.uniform(-0.1, 0.4, n)
    signals = {"alpha": alpha, "Mach": np.full(n, 0.6)}
    signals["CL"] = 0.1 + 5 * alpha - 2 * alpha**2 + rng.normal(0, 0.01, n)
    model = fit_global_model(
        signals, ["CL"], ["alpha", "Mach"], settings=GlobalModelSettings(max_order=3)
    )
    # α·M and α·M² are α times a constant: the same function as α, which is kept
    assert set(model["CL"].terms) == {"1", "alpha", "alpha^2"}
    assert model.predict({"alpha": 0.1, "Mach": 0.7})["CL"].outside[0]


def test_a_spline_term_past_a_knot_is_selected_and_recovered():
    rng = np.random.default_rng(15)
    n = 3000
    alpha, qhat = rng.uniform(-0.1, 0.6, n), rng.uniform(-0.02, 0.02, n)
    true = {"1": 0.1, "alpha": 4.0, "spline1(alpha,0.3)": -6.0, "qhat*spline1(alpha,0.3)": 40.0}
    signals = {"alpha": alpha, "qhat": qhat}
    z = sum(v * parse_term(t).evaluate(signals, n) for t, v in true.items())
    signals["CL"] = z + rng.normal(0, 0.005, n)
    settings = GlobalModelSettings(
        orders={"alpha": 3, "qhat": 1}, max_order=3, knots={"alpha": [0.3]}, cross_with=["qhat"]
    )
    model = fit_global_model(signals, ["CL"], ["alpha", "qhat"], settings=settings)
    cl = model["CL"]
    assert set(cl.terms) == set(true)
    for j, term in enumerate(cl.terms):
        assert abs(cl.estimates[j] - true[term]) < 3.0 * cl.std[j], term
