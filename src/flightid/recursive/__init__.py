"""Recursive (online) parameter estimation: the parameters as constant states of an
augmented model, estimated sample by sample (Jategaonkar, *Flight Vehicle System Identification*,
2nd ed., ch. 7; FVSysID's ``mainRPE``).

* ``AugmentedModel`` — x_a = (x, θ_free) of any ``StateSpaceModel``, RK4 propagation and
  central-difference Jacobians, batched over sigma points / perturbations;
* ``ExtendedKalmanFilter``, ``UnscentedKalmanFilter`` (additive noise),
  ``AugmentedUnscentedKalmanFilter`` (noise in the sigma-point state),
  ``ExtendedForgettingRLS`` (forgetting-factor RLS), ``FourierTransformRegression``
  (recursive DFT + least squares);
* ``InputDelayLine`` — the model's fixed input delays, u(t − τ) from the samples fed so far;
* ``RecursiveEstimator`` — feed one sample or a block, read the current estimates and σ;
* ``RecursiveResult`` — parameter histories, reported and last filtered values.

Case files with a ``[recursive]`` table run through ``flightid.cases.recursive_case``.
"""

from flightid.recursive.augmented import AugmentedModel
from flightid.recursive.base import RecursiveDivergenceError
from flightid.recursive.delay import InputDelayLine
from flightid.recursive.efrls import ExtendedForgettingRLS
from flightid.recursive.ekf import ExtendedKalmanFilter
from flightid.recursive.ftr import FourierTransformRegression, NoEstimateYetError
from flightid.recursive.result import RecursiveResult
from flightid.recursive.streaming import RecursiveEstimator, run_recursive
from flightid.recursive.ukf import AugmentedUnscentedKalmanFilter, UnscentedKalmanFilter

__all__ = [
    "AugmentedModel",
    "AugmentedUnscentedKalmanFilter",
    "ExtendedForgettingRLS",
    "InputDelayLine",
    "ExtendedKalmanFilter",
    "FourierTransformRegression",
    "NoEstimateYetError",
    "RecursiveDivergenceError",
    "RecursiveEstimator",
    "RecursiveResult",
    "UnscentedKalmanFilter",
    "run_recursive",
]
