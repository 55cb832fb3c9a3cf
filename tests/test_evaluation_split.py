"""Evaluations to the optimum, on the confirmation and on the bounds, reported apart.

``Estimate.evaluations_to_optimum`` counts the integrations until the first point on the path
whose cost excess over the final cost — predicted by the quadratic model at θ̂ under the
final R — is within the cost tolerance; ``confirmation_evaluations`` the optimizer's
integrations after it; ``accuracy_evaluations`` those of the sensitivities at θ̂.
"""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from flightid.estimation.convergence import Convergence
from flightid.estimation.driver import evaluations_to_optimum
from flightid.paper.examples12 import comparison_table, run_example1, run_example2


@pytest.fixture(scope="module")
def example2():
    return {r.solver: r for r in run_example2(1).results}


@pytest.fixture(scope="module")
def example1():
    return {r.solver: r for r in run_example1(("mnr", "mnres")).results}


def _first_within_recorded_cost(result, convergence: Convergence) -> int:
    """Independent reference under a fixed R: the evaluations at the first recorded cost
    within cost_rtol·J + cost_atol of the final cost (the costs as the objective recorded
    them, not the quadratic model)."""
    tolerance = convergence.cost_rtol * result.cost + convergence.cost_atol
    for cost, spent in zip(result.cost_history, result.evaluation_history, strict=True):
        if cost - result.cost <= tolerance:
            return spent
    raise AssertionError("no recorded point within the tolerance")


@pytest.mark.parametrize("solver", ["mnr", "mnres"])
def test_example2_split_adds_up_and_agrees_with_the_recorded_costs(example2, solver):
    result = example2[solver]
    assert result.converged, result.message
    assert (
        result.evaluations_to_optimum + result.confirmation_evaluations
        == result.equivalent_evaluations
    )
    assert result.evaluations_to_optimum == _first_within_recorded_cost(
        result, Convergence(max_iterations=200)
    )
    assert result.total_evaluations == result.equivalent_evaluations + result.accuracy_evaluations


@pytest.mark.parametrize("solver", ["mnr", "mnres"])
def test_example1_split_agrees_with_the_recorded_costs(example1, solver):
    # noise-free: the absolute floor cost_atol = 1e-8 of example 1 is the tolerance
    result = example1[solver]
    reference = _first_within_recorded_cost(result, Convergence(cost_atol=1e-8))
    assert result.evaluations_to_optimum == reference


def test_the_counts_of_the_paper_examples(example1, example2):
    # regression values (measured on this code): MNR reaches the optimum after three passes
    # of n + 1 = 7 (1 + 3·7 = 22), MNRES after one sweep and six one-simulation passes
    # (1 + 6 + 6 = 13); after it, MNR's last sweep (6) and on example 2 one confirming
    # step (1), then the central differences at θ̂ (12, or the backward half 6)
    counts = {
        (k, s): (r.evaluations_to_optimum, r.confirmation_evaluations, r.accuracy_evaluations)
        for k, runs in (("1", example1), ("2", example2))
        for s, r in runs.items()
    }
    assert counts == {
        ("1", "mnr"): (22, 6, 6),
        ("1", "mnres"): (13, 0, 12),
        ("2", "mnr"): (22, 7, 12),
        ("2", "mnres"): (13, 7, 12),
    }


def test_json_summary_and_the_paper_table_show_the_split(example2):
    result = example2["mnres"]
    document = json.loads(result.to_json())
    assert document["evaluations_to_optimum"] == 13
    assert document["confirmation_evaluations"] == 7
    assert document["accuracy_evaluations"] == 12
    assert "32: 13 to the optimum, 7 confirming it, 12 for the information matrix" in (
        result.summary()
    )
    table = comparison_table(run_example2(1))
    assert "to the optimum" in table and "confirming it" in table


def test_to_the_optimum_by_the_quadratic_model_with_an_offset():
    # closed form: M = diag(4, 1), θ̂ = 0, J(θ̂) = 100, cost_rtol = 1e-3 → tolerance 0.1;
    # excesses 4·1² = 4, 4·0.1² + 0.2² = 0.08 (within), 0 → the second point, at 9
    objective = SimpleNamespace(
        convergence=Convergence(),
        theta_history=[np.array([1.0, 0.0]), np.array([0.1, 0.2]), np.zeros(2)],
        evaluation_history=[1, 9, 12],
        evaluations=20,
    )
    m = np.diag([4.0, 1.0])
    assert evaluations_to_optimum(objective, np.zeros(2), 100.0, m) == 9
    assert evaluations_to_optimum(objective, np.zeros(2), 100.0, m, offset=30) == 39
    # a tolerance too tight for the second point: the end point itself (excess 0)
    assert evaluations_to_optimum(objective, np.zeros(2), 1.0, m) == 12
