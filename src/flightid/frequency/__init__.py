"""Frequency-domain estimation (Morelli & Klein, *Aircraft System Identification*, 2nd ed.,
ch. 5, 7, 10): finite Fourier transforms on a band, frequency-domain equation error and
output error for linear models, frequency responses with coherence from data, and
low-order equivalent system fits.

Modules, one job each:

* ``fourier``: finite Fourier transform at arbitrary frequencies (direct sum or chirp z),
  quadrature rules, detrending, the per-maneuver transforms ``ManeuverSpectra``.
* ``linear_system``: a linear ``StateSpaceModel`` as matrices A, B, C, D (+ constants),
  with its input and output delays (factors e^{−jωτ}).
* ``arguments``: the argument checks of the public functions (``InputError`` naming them).
* ``equation_error``: complex least squares on jωX = AX + BU (+ boundary terms).
* ``output_error``: Y = (C(jωI − A)⁻¹B + D)U fitted with S estimated from the residuals,
  Cramér–Rao bounds and the coloured-residual correction.
* ``uncertainty``: the grid factor of frequencies closer than 1/T and the coloured-residual
  (sandwich) covariance the two estimators report.
* ``response``: Welch spectra, single/multiple-input responses, ordinary, partial and
  multiple coherence.
* ``loes``: low-order equivalent systems with time delay (MIL-STD-1797A cost).
* ``plots``: Bode and spectra figures (matplotlib, lazily).

``flightid.cases.frequency_case`` runs a case with a ``[frequency_domain]`` table.
"""

from flightid.frequency.equation_error import (
    ComplexRegression,
    EquationErrorFit,
    complex_least_squares,
    equation_error,
)
from flightid.frequency.fourier import (
    ManeuverSpectra,
    constant_transform,
    finite_fourier_transform,
    frequency_grid,
    maneuver_spectra,
    remove_trend,
)
from flightid.frequency.linear_system import LinearSystem, bias_like_parameters, linear_system
from flightid.frequency.loes import LoesFit, fit_loes, loes_response, short_period_loes
from flightid.frequency.output_error import OutputErrorFit, model_response, output_error
from flightid.frequency.response import FrequencyResponse, frequency_response, spectral_matrix

__all__ = [
    "ComplexRegression",
    "EquationErrorFit",
    "FrequencyResponse",
    "LinearSystem",
    "LoesFit",
    "ManeuverSpectra",
    "OutputErrorFit",
    "bias_like_parameters",
    "complex_least_squares",
    "constant_transform",
    "equation_error",
    "finite_fourier_transform",
    "fit_loes",
    "frequency_grid",
    "frequency_response",
    "linear_system",
    "loes_response",
    "maneuver_spectra",
    "model_response",
    "output_error",
    "remove_trend",
    "short_period_loes",
    "spectral_matrix",
]
