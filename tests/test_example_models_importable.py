"""Every shipped model module's f and h can be found again by their module's name.

numba rebuilds a kernel from its disk cache by importing the module of the compiled
functions' globals by name (``flightid.simulate.cache``); a model whose f and h live in a
module missing from ``sys.modules`` is compiled again by every process. examples/models/
hfb320_upper.py loaded hfb320.py without registering it, and the shipped
hfb320_longitudinal_filter_error case compiled 16 functions (29.7 s) in every run
(bench/startup.py, 2026-11-26).
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from flightid.cases.usermodel import load_user_model

MODELS = sorted((Path(__file__).resolve().parents[1] / "examples" / "models").glob("*.py"))


@pytest.mark.parametrize("path", MODELS, ids=[p.stem for p in MODELS])
def test_model_functions_live_in_a_registered_module(path):
    model = load_user_model(path)
    for function in (model.f, model.h):
        if function is None:  # a model without states has no f
            continue
        function = getattr(function, "py_func", function)
        module = sys.modules.get(function.__module__)
        assert module is not None, (path.name, function.__module__)
        assert module.__dict__ is function.__globals__, (path.name, function.__module__)
