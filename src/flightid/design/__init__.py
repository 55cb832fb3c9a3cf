"""Input design: test-input generators and model-based design from predicted information.

``signals``      doublet, 2-1-1, 3-2-1-1 timed to a natural frequency; relative peak factor
``multisine``    orthogonal, phase-optimised multisines for several inputs at once
``information``  predicted Cramér–Rao bounds and correlations of a candidate input
``optimize``     amplitudes / band / timing chosen for a D-, A- or named-parameter criterion
``result``       the design result: summary, JSON, CSV, figures

The ``[design]`` table of a case file (``flightid design CASE.toml``) is read by
``flightid.cases.design_case``.
"""
