"""Unstable-aircraft short-period model (``unstab_sp.py``, CASES.md §3 basic model) with the
reference code's parameter names (CASES.md §3: "code and reference-CSV names"):

    zw zq zeta mw mq meta    (= Zw, Zq, Zδe, Mw, Mq, Mδe)

f and h are those of ``unstab_sp.py`` (same θ order, same start values).
"""

import importlib.util
import sys
from pathlib import Path

_spec = importlib.util.spec_from_file_location(
    "flightid_example_unstab_sp", Path(__file__).with_name("unstab_sp.py")
)
_base = importlib.util.module_from_spec(_spec)
# registered: numba finds the module of f's and h's globals by name when it loads their
# compiled kernels from its disk cache
sys.modules[_spec.name] = _base
_spec.loader.exec_module(_base)

STATES = _base.STATES
INPUTS = _base.INPUTS
OUTPUTS = _base.OUTPUTS
_NAMES = ("zw", "zq", "zeta", "mw", "mq", "meta")
PARAMETERS = dict(zip(_NAMES, _base.PARAMETERS.values(), strict=True))
f = _base.f
h = _base.h
