"""Identified models as files other tools load: state-space JSON / NPZ and MATLAB .mat of a
linear model with the covariance of its entries, and a stand-alone Python module of the
estimated model, a JSBSim aircraft of a built-in airplane model (``flightid export``), and
the flying qualities of its modes (docs/fly.md, docs/flying_qualities.md).

The names are loaded on first use (PEP 562 module ``__getattr__``): the modal analysis every
run makes (``flightid.export.modal``) does not import the file writers.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from flightid.lazy_exports import lazy_exports

# public name -> module that defines it
_LAZY_EXPORTS = {
    "ExportError": "flightid.export.files",
    "ExportOverwriteError": "flightid.export.files",
    "PythonExportError": "flightid.export.python_module",
    "python_source": "flightid.export.python_module",
    "write_python": "flightid.export.python_module",
    "read_statespace": "flightid.export.statespace",
    "write_mat": "flightid.export.statespace",
    "write_statespace": "flightid.export.statespace",
}

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

if TYPE_CHECKING:  # static tools see the eager imports
    from flightid.export.files import ExportError, ExportOverwriteError
    from flightid.export.python_module import PythonExportError, python_source, write_python
    from flightid.export.statespace import read_statespace, write_mat, write_statespace


__getattr__, __dir__ = lazy_exports(__name__, _LAZY_EXPORTS)
