"""ATTAS lateral p, r model (``attas_lateral_pr.py``) with the parameter names of the
recursive-estimation reference (the FVSysID recursive examples of the book's chapter 7):

    Lp Lr Ldla Ldlr Lbeta L0 Np Nr Ndla Ndlr Nbeta N0    (Ldla = L_δa, Ldlr = L_δr, …)

f and h are those of ``attas_lateral_pr.py`` (same θ order, same start values); only the
names differ, so that the recursive cases report under the reference's names.
"""

from pathlib import Path

from flightid.cases.usermodel import import_model_module

# the module flightid imports for a case naming that file (registered in sys.modules, so
# numba reloads the compiled f and h from its disk cache)
_base = import_model_module(Path(__file__).with_name("attas_lateral_pr.py"))

STATES = _base.STATES
INPUTS = _base.INPUTS
OUTPUTS = _base.OUTPUTS
_NAMES = ("Lp", "Lr", "Ldla", "Ldlr", "Lbeta", "L0", "Np", "Nr", "Ndla", "Ndlr", "Nbeta", "N0")
PARAMETERS = dict(zip(_NAMES, _base.PARAMETERS.values(), strict=True))
f = _base.f
h = _base.h
