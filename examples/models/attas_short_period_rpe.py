"""ATTAS short-period model (``attas_short_period.py``) with the parameter names of the
recursive-estimation reference (CASES.md §8.2, "Parameter names in the reference"):

    z0 zalfa zq zdele m0 malfa mq mdele    (= Z0, Zα, Zq, Zδe, M0, Mα, Mq, Mδe)

f and h are those of ``attas_short_period.py`` (same θ order, same start values).
"""

import importlib.util
import sys
from pathlib import Path

_spec = importlib.util.spec_from_file_location(
    "flightid_example_attas_short_period", Path(__file__).with_name("attas_short_period.py")
)
_base = importlib.util.module_from_spec(_spec)
# registered: numba finds the module of f's and h's globals by name when it loads their
# compiled kernels from its disk cache
sys.modules[_spec.name] = _base
_spec.loader.exec_module(_base)

STATES = _base.STATES
INPUTS = _base.INPUTS
OUTPUTS = _base.OUTPUTS
_NAMES = ("z0", "zalfa", "zq", "zdele", "m0", "malfa", "mq", "mdele")
PARAMETERS = dict(zip(_NAMES, _base.PARAMETERS.values(), strict=True))
f = _base.f
h = _base.h
