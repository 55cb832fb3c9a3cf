"""Unstable-aircraft short-period model (``unstab_sp.py``, the basic model) with the
reference code's parameter names (those FVSysID's scripts and result files use):

    zw zq zeta mw mq meta    (= Zw, Zq, Zδe, Mw, Mq, Mδe)

f and h are those of ``unstab_sp.py`` (same θ order, same start values).
"""

from pathlib import Path

from flightid.cases.usermodel import import_model_module

# the module flightid imports for a case naming that file (registered in sys.modules, so
# numba reloads the compiled f and h from its disk cache)
_base = import_model_module(Path(__file__).with_name("unstab_sp.py"))

STATES = _base.STATES
INPUTS = _base.INPUTS
OUTPUTS = _base.OUTPUTS
_NAMES = ("zw", "zq", "zeta", "mw", "mq", "meta")
PARAMETERS = dict(zip(_NAMES, _base.PARAMETERS.values(), strict=True))
f = _base.f
h = _base.h
