"""Status messages are one sentence: what happened last and why, no message quoted inside
another (flightid.estimation.confirm)."""

from flightid.estimation.confirm import confirmed_message, continued_message, solver_stop


def test_continued_message_is_one_sentence():
    assert continued_message(5, 0.0123, 0.8134, "converged") == (
        "converged: 5 further Gauss–Newton passes on central differences reached the optimum "
        "(next step 0.012 σ) after its own tests stopped the solver 0.813 σ short of it"
    )
    assert continued_message(1, 0.5, 3.0, "stalled") == (
        "converged: 1 further Gauss–Newton pass on central differences reached the optimum "
        "(next step 0.5 σ) after the solver stalled 3 σ short of it"
    )


def test_confirmed_message_names_the_solver_stop_without_quoting_it():
    assert confirmed_message(0.04, "max_iterations") == (
        "converged: central differences confirm the optimum within 0.04 σ where the solver "
        "reached its pass limit"
    )
    assert solver_stop("max_evaluations") == "the solver spent its evaluation budget"
    assert solver_stop("odd") == "the solver stopped (odd)"
    for status in ("converged", "stalled", "max_iterations", "max_evaluations"):
        message = continued_message(2, 0.1, 1.0, status)
        assert message.count("converged") == 1 and "(the solver" not in message


def test_second_opinion_message_is_one_sentence():
    from types import SimpleNamespace

    from flightid.estimation.driver import second_opinion_message

    converged = SimpleNamespace(
        status="converged", converged=True, message="converged: cost changes below tolerance"
    )
    assert second_opinion_message(converged, "MNR", "ln det R", (-36.1, -43.8), 25.0) == (
        "converged: MNR's result is reported, the higher likelihood of two runs "
        "(ln det R = -36.1 for MNRES, -43.8 for MNR), after MNRES stopped 25 σ from an "
        "optimum (its surface misled it) and MNR ran from the start values too"
    )
    stalled = SimpleNamespace(
        status="stalled", converged=False, message="not converged: no step lowers the cost"
    )
    message = second_opinion_message(stalled, "MNRES", "J", (10.0, 12.0), 11.0)
    assert message.startswith("stalled: MNRES's result is reported")
    assert message.endswith("from the start values too; no step lowers the cost")
