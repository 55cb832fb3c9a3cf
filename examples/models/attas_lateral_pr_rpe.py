"""ATTAS lateral p, r model (``attas_lateral_pr.py``) with the parameter names of the
recursive-estimation reference (CASES.md §8.2, "Parameter names in the reference"):

    Lp Lr Ldla Ldlr Lbeta L0 Np Nr Ndla Ndlr Nbeta N0    (Ldla = L_δa, Ldlr = L_δr, …)

f and h are those of ``attas_lateral_pr.py`` (same θ order, same start values); only the
names differ, so that the recursive cases report under the reference's names.
"""

import importlib.util
import sys
from pathlib import Path

_spec = importlib.util.spec_from_file_location(
    "flightid_example_attas_lateral_pr", Path(__file__).with_name("attas_lateral_pr.py")
)
_base = importlib.util.module_from_spec(_spec)
# registered: numba finds the module of f's and h's globals by name when it loads their
# compiled kernels from its disk cache
sys.modules[_spec.name] = _base
_spec.loader.exec_module(_base)

STATES = _base.STATES
INPUTS = _base.INPUTS
OUTPUTS = _base.OUTPUTS
_NAMES = ("Lp", "Lr", "Ldla", "Ldlr", "Lbeta", "L0", "Np", "Nr", "Ndla", "Ndlr", "Nbeta", "N0")
PARAMETERS = dict(zip(_NAMES, _base.PARAMETERS.values(), strict=True))
f = _base.f
h = _base.h
