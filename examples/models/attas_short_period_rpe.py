"""ATTAS short-period model (``attas_short_period.py``) with the parameter names of the
recursive-estimation reference (the FVSysID recursive examples of the book's chapter 7):

    z0 zalfa zq zdele m0 malfa mq mdele    (= Z0, Zα, Zq, Zδe, M0, Mα, Mq, Mδe)

f and h are those of ``attas_short_period.py`` (same θ order, same start values).
"""

from pathlib import Path

from flightid.cases.usermodel import import_model_module

# the module flightid imports for a case naming that file (registered in sys.modules, so
# numba reloads the compiled f and h from its disk cache)
_base = import_model_module(Path(__file__).with_name("attas_short_period.py"))

STATES = _base.STATES
INPUTS = _base.INPUTS
OUTPUTS = _base.OUTPUTS
_NAMES = ("z0", "zalfa", "zq", "zdele", "m0", "malfa", "mq", "mdele")
PARAMETERS = dict(zip(_NAMES, _base.PARAMETERS.values(), strict=True))
f = _base.f
h = _base.h
