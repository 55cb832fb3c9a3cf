"""bench/kernel.py's hand-written 6-DOF kernel integrates the same equations as flightid.

The timings of bench/kernel.py compare flightid's kernel with a hand-written one; they mean
something only if both compute the same trajectory. Independent source of the check: the
hand-written kernel is written from the equations of RP-1153 [2.5–2.23] (as documented in
``flightid.aircraft.equations``), not from flightid's code paths.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"


@pytest.fixture(scope="module")
def kernel_module():
    sys.path.insert(0, str(BENCH))
    try:
        spec = importlib.util.spec_from_file_location("bench_kernel", BENCH / "kernel.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        yield module
    finally:
        sys.path.remove(str(BENCH))


@pytest.fixture(scope="module")
def setup(kernel_module):
    # 200 RK4 steps of the 20 s manoeuvre (0.1 s): long enough to excite every term
    return kernel_module.Setup(n_steps=200)


def test_hand_kernel_matches_flightid(kernel_module, setup):
    assert kernel_module.check(setup, tolerance=1e-10) <= 1e-10
    # away from the start values too: a perturbed θ moves both the same way
    theta = setup.theta * (1 + 0.2 * np.random.default_rng(3).uniform(-1, 1, setup.theta.size))
    y_lib = setup.flightid(theta[None, :])[0]
    y_hand = setup.hand(theta).copy()
    np.testing.assert_allclose(y_hand, y_lib, rtol=1e-10, atol=1e-12)
    # the outputs respond to the manoeuvre (a check on a constant trajectory proves little)
    assert np.ptp(y_lib[:, 2]) > 0.01 and np.ptp(y_lib[:, 5]) > 0.05


def test_check_detects_a_wrong_kernel(kernel_module, setup, monkeypatch):
    # swapping two derivatives in the hand kernel's parameter order must fail the check
    order = setup.order.copy()
    order[[13, 14]] = order[[14, 13]]  # Cl_phat ↔ Cl_rhat
    monkeypatch.setattr(setup, "order", order)
    with pytest.raises(AssertionError, match="disagrees"):
        kernel_module.check(setup, tolerance=1e-10)


def test_the_user_module_matches_the_hand_kernel(kernel_module, setup):
    """bench/navion_user_model.py (the same equations as a user model module) runs through
    its generated out forms and the call-then-copy adapter alike, and both agree with the
    hand-written kernel (the ratio bench/kernel.py prints compares the same trajectory)."""
    from flightid.model.outform_source import GENERATED_MARK

    generated, adapted = kernel_module.user_module_simulators(setup)
    assert getattr(generated.model.f_out, GENERATED_MARK, None) is generated.model.f
    assert getattr(adapted.model.f_out, GENERATED_MARK, None) is None
    theta = setup.theta[setup.order]
    y_hand = setup.hand(setup.theta)
    scale = np.maximum(np.max(np.abs(y_hand), axis=0), 1e-3)
    for simulator in (generated, adapted):
        y = simulator.run(theta[None, :]).outputs[0]
        assert np.max(np.abs(y - y_hand) / scale) <= 1e-10
