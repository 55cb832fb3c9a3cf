"""HFB-320 longitudinal model (``hfb320.py``) with the parameter names of CASES.md §2 (the
reference's filter-error case): CD0 CDV CDAL CL0 CLV CLAL CM0 CMV CMAL CMQ CMDE.

Same f, h, states, inputs, outputs and start values as ``hfb320.py``; only the names differ
(CDAL = C_Dα, CMQ = C_mq, ...).
"""

import importlib.util
import sys
from pathlib import Path

_spec = importlib.util.spec_from_file_location(
    "flightid_example_hfb320", Path(__file__).with_name("hfb320.py")
)
_base = importlib.util.module_from_spec(_spec)
# registered, as importlib's recipe does: numba finds the module of f's and h's globals by
# name when it loads their compiled kernels from its disk cache (unregistered, every run
# compiled them again)
sys.modules[_spec.name] = _base
_spec.loader.exec_module(_base)

STATES = _base.STATES
INPUTS = _base.INPUTS
OUTPUTS = _base.OUTPUTS
_NAMES = ("CD0", "CDV", "CDAL", "CL0", "CLV", "CLAL", "CM0", "CMV", "CMAL", "CMQ", "CMDE")
# same order as hfb320.PARAMETERS, which f and h index
PARAMETERS = dict(zip(_NAMES, _base.PARAMETERS.values(), strict=True))
f = _base.f
h = _base.h
