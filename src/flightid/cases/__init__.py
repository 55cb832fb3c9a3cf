"""Case files: a TOML description of an estimation from flight data, checked and run.

from flightid.cases import load_case, run_case
run = run_case(load_case("examples/cases/hfb320_longitudinal.toml"))
print(run.estimate.summary())

A case with ``[[stages]]`` (stepwise regression → output error → prediction, docs/cases.md):

from flightid.cases import load_case, run_stages
run = run_stages(load_case("examples/cases/twin_otter_stepwise.toml"))
print(run.summary())

A result folder of ``flightid run --out`` read back (nothing estimated again):

from flightid.cases import load_run
run = load_run("out/hfb320")
print(run.linearize().summary())

The names are loaded on first use (PEP 562 module ``__getattr__``): ``from flightid.cases
import load_case`` does not import the estimators, the regression stages or the accuracy
methods a case may never use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from flightid.lazy_exports import lazy_exports

# public name -> module that defines it
_LAZY_EXPORTS: dict[str, str] = {
    "Case": "flightid.cases.spec",
    "CaseChangedError": "flightid.cases.load_run",
    "CaseError": "flightid.cases.spec",
    "CaseRun": "flightid.cases.run",
    "LoadedRun": "flightid.cases.load_run",
    "Prediction": "flightid.cases.run",
    "RunFolderError": "flightid.cases.load_run",
    "StageSpec": "flightid.cases.spec",
    "StagesRun": "flightid.cases.stages",
    "UserModelError": "flightid.cases.usermodel",
    "load_case": "flightid.cases.spec",
    "load_run": "flightid.cases.load_run",
    "load_user_model": "flightid.cases.usermodel",
    "parse_case": "flightid.cases.spec",
    "prepare_case": "flightid.cases.run",
    "resolve_data_dir": "flightid.cases.build",
    "run_case": "flightid.cases.run",
    "run_stages": "flightid.cases.stages",
}

__all__ = [
    "Case",
    "CaseChangedError",
    "CaseError",
    "CaseRun",
    "LoadedRun",
    "Prediction",
    "RunFolderError",
    "StageSpec",
    "StagesRun",
    "UserModelError",
    "load_case",
    "load_run",
    "load_user_model",
    "parse_case",
    "prepare_case",
    "resolve_data_dir",
    "run_case",
    "run_stages",
]

if TYPE_CHECKING:  # static tools see the eager imports
    from flightid.cases.build import resolve_data_dir
    from flightid.cases.load_run import CaseChangedError, LoadedRun, RunFolderError, load_run
    from flightid.cases.run import CaseRun, Prediction, prepare_case, run_case
    from flightid.cases.spec import Case, CaseError, StageSpec, load_case, parse_case
    from flightid.cases.stages import StagesRun, run_stages
    from flightid.cases.usermodel import UserModelError, load_user_model


__getattr__, __dir__ = lazy_exports(__name__, _LAZY_EXPORTS)
