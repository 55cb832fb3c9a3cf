"""The Ljung–Box p-value of the residual-whiteness test, P(χ²_m > Q), in closed form
(``flightid.accuracy.whiteness.chi_square_survival``): the same values as scipy.special's
``chdtrc`` (the independent reference), without loading scipy.special in a run."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from scipy.special import chdtrc

from flightid.accuracy.whiteness import chi_square_survival

Q = np.concatenate([[0.0, 1e-12, 1e-3, 0.5], np.linspace(0.1, 200.0, 400), [1e3, 1e4, 3e4, np.inf]])


@pytest.mark.parametrize("m", [1, 2, 3, 4, 5, 19, 20, 21, 50, 99, 100])
def test_the_closed_form_is_scipys_chi_square_survival(m):
    expected = chdtrc(m, Q)
    got = chi_square_survival(m, Q)
    np.testing.assert_allclose(got, expected, rtol=1e-11, atol=1e-300)


def test_no_probability_for_a_negative_or_nan_statistic():
    got = chi_square_survival(20, np.array([np.nan, -1.0, 0.0]))
    assert np.isnan(got[0]) and np.isnan(got[1]) and got[2] == 1.0


def test_the_whiteness_test_does_not_load_scipy_special():
    script = (
        "import json, sys\n"
        "import numpy as np\n"
        "from flightid.accuracy.whiteness import residual_whiteness\n"
        "rng = np.random.default_rng(3)\n"
        "w = residual_whiteness(rng.normal(size=(400, 2)), ['a', 'b'], max_lag=40)\n"
        "print(json.dumps({'special': 'scipy.special' in sys.modules,\n"
        "                  'p': [float(v) for v in w.p_value], 'm': w.ljung_box_lags,\n"
        "                  'q': [float(v) for v in w.ljung_box]}))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True, timeout=120
    )
    found = json.loads(done.stdout.strip().splitlines()[-1])
    assert found["special"] is False
    np.testing.assert_allclose(found["p"], chdtrc(found["m"], np.array(found["q"])), rtol=1e-11)
