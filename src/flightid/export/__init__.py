"""Identified models as files other tools load: state-space JSON / NPZ and MATLAB .mat of a
linear model with the covariance of its entries, and a stand-alone Python module of the
estimated model, a JSBSim aircraft of a built-in airplane model (``flightid export``), and
the flying qualities of its modes (docs/fly.md, docs/flying_qualities.md)."""

from flightid.export.files import ExportError, ExportOverwriteError
from flightid.export.python_module import PythonExportError, python_source, write_python
from flightid.export.statespace import read_statespace, write_mat, write_statespace

__all__ = [
    "ExportError",
    "ExportOverwriteError",
    "PythonExportError",
    "python_source",
    "read_statespace",
    "write_mat",
    "write_python",
    "write_statespace",
]
