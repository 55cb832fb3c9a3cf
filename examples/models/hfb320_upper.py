"""HFB-320 longitudinal model (``hfb320.py``) with the parameter names of the reference's
HFB-320 filter-error case: CD0 CDV CDAL CL0 CLV CLAL CM0 CMV CMAL CMQ CMDE.

Same f, h, states, inputs, outputs and start values as ``hfb320.py``; only the names differ
(CDAL = C_Dα, CMQ = C_mq, ...).
"""

from pathlib import Path

from flightid.cases.usermodel import import_model_module

# the module flightid imports for a case naming that file (registered in sys.modules, so
# numba reloads the compiled f and h from its disk cache)
_base = import_model_module(Path(__file__).with_name("hfb320.py"))

STATES = _base.STATES
INPUTS = _base.INPUTS
OUTPUTS = _base.OUTPUTS
_NAMES = ("CD0", "CDV", "CDAL", "CL0", "CLV", "CLAL", "CM0", "CMV", "CMAL", "CMQ", "CMDE")
# same order as hfb320.PARAMETERS, which f and h index
PARAMETERS = dict(zip(_NAMES, _base.PARAMETERS.values(), strict=True))
f = _base.f
h = _base.h
