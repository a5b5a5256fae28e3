"""State estimators with one interface: ``step(y, u) -> x_hat``, single or batch runs.

==============================  =====================================================
`KalmanFilter`                  CKF on a linear model (seed 000 eq. 29-34)
`ExtendedKalmanFilter`          EKF, mode-aware on hybrid plants (seed 002 eq. 13-22)
`UnscentedKalmanFilter`         UKF (seed 002 eq. 23-40)
`AdaptiveKalmanFilter`          innovation-window adaptive Q (seed 000 eq. 35-37)
`AdaptiveScalingKalmanFilter`   scaled process noise (seed 004 eq. 30-41)
`ConsensusFilter`               information-form consensus filter (seed 004 eq. 42-51)
`NARXEstimator`                 NARX neural correction (seed 002 section 3.3, Table 3)
`LuenbergerObserver`            discrete or continuous Luenberger observer
`TSMultiObserver`               Takagi-Sugeno multi-observer (seed 001 eq. 20)
==============================  =====================================================

Training the NARX network (data through the simulator, Levenberg-Marquardt)
is design work: `tanksynth.design.narx`. Caches: `tanksynth.runtime.cache`.
"""

from __future__ import annotations

from tanksynth.runtime.estimators.adaptive import (AdaptiveKalmanFilter, AdaptiveKalmanTuning, AdaptiveScalingKalmanFilter,
                       AdaptiveScalingTuning, linear_model_for)
from tanksynth.runtime.estimators.base import (BACKENDS, ArrayEstimator, CovarianceError, DiscreteModel, Estimator,
                   KernelEstimator, discrete_model, joseph_update, regularized_jacobian)
from tanksynth.runtime.estimators.consensus import ConsensusFilter, ConsensusTuning
from tanksynth.runtime.estimators.kalman import (ExtendedKalmanFilter, KalmanFilter, KalmanTuning, model_from_tuning,
                     steady_state_gain)
from tanksynth.runtime.estimators.luenberger import OBSERVER_FORMS, LuenbergerObserver, LuenbergerTuning, TSMultiObserver
from tanksynth.runtime.estimators.narx import NARXEstimator, NARXTuning
from tanksynth.runtime.estimators.ukf import UKFTuning, UnscentedKalmanFilter, ukf_weights

__all__ = [
    "BACKENDS", "ArrayEstimator", "CovarianceError", "DiscreteModel", "Estimator",
    "KernelEstimator", "discrete_model", "joseph_update", "regularized_jacobian",
    "KalmanTuning", "KalmanFilter", "ExtendedKalmanFilter", "model_from_tuning",
    "steady_state_gain",
    "UKFTuning", "UnscentedKalmanFilter", "ukf_weights",
    "AdaptiveKalmanTuning", "AdaptiveKalmanFilter", "AdaptiveScalingTuning",
    "AdaptiveScalingKalmanFilter", "linear_model_for",
    "ConsensusTuning", "ConsensusFilter",
    "NARXTuning", "NARXEstimator",
    "LuenbergerTuning", "LuenbergerObserver", "TSMultiObserver", "OBSERVER_FORMS",
]
