"""Every shipped model module's f and h can be found again by their module's name.

numba rebuilds a kernel from its disk cache by importing the module of the compiled
functions' globals by name (``flightid.model.kernel_cache``); a model whose f and h live in a
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


def test_a_model_file_built_on_another_shares_its_module():
    # hfb320_upper.py imports hfb320.py with import_model_module: the module flightid loads
    # for a case naming hfb320.py itself is the very same object (one compilation, one
    # cache entry), and its f is the renamed model's f
    from flightid.cases.usermodel import import_model_module

    folder = MODELS[0].parent
    upper = load_user_model(folder / "hfb320_upper.py")
    base = load_user_model(folder / "hfb320.py")
    assert import_model_module(folder / "hfb320.py") is base.module
    assert upper.f is base.f and upper.h is base.h
    assert list(upper.parameters.values()) == list(base.parameters.values())
    assert list(upper.parameters)[:3] == ["CD0", "CDV", "CDAL"]


def test_import_model_module_names_a_missing_file(tmp_path):
    from flightid.cases.usermodel import UserModelError, import_model_module

    with pytest.raises(UserModelError, match="does not exist"):
        import_model_module(tmp_path / "no_such_model.py")
