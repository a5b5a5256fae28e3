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
is design work: `tanksynth.design.estimators.narx_training`. Caches: `tanksynth.runtime.cache`.
"""

from __future__ import annotations

from tanksynth._lazy import lazy_exports as _lazy_exports

#: Re-exported name -> its module, imported on first use (PEP 562): importing the package
#: loads none of its modules' dependencies (issue 15).
_EXPORTS = {
    **dict.fromkeys(["AdaptiveKalmanFilter", "AdaptiveKalmanTuning",
                     "AdaptiveScalingKalmanFilter", "AdaptiveScalingTuning", "linear_model_for"],
                    "tanksynth.runtime.estimators.adaptive"),
    **dict.fromkeys(["BACKENDS", "ArrayEstimator", "CovarianceError", "CovarianceKernelEstimator",
                     "DiscreteModel",
                     "Estimator", "KernelEstimator", "discrete_model", "joseph_update",
                     "regularized_jacobian"],
                    "tanksynth.runtime.estimators.base"),
    **dict.fromkeys(["ConsensusFilter", "ConsensusTuning"],
                    "tanksynth.runtime.estimators.consensus"),
    **dict.fromkeys(["ExtendedKalmanFilter", "KalmanFilter", "KalmanTuning", "model_from_tuning",
                     "steady_state_gain"],
                    "tanksynth.runtime.estimators.kalman"),
    **dict.fromkeys(["OBSERVER_FORMS", "LuenbergerObserver", "LuenbergerTuning",
                     "TSMultiObserver"],
                    "tanksynth.runtime.estimators.luenberger"),
    **dict.fromkeys(["NARXEstimator", "NARXTuning"], "tanksynth.runtime.estimators.narx"),
    **dict.fromkeys(["UKFTuning", "UnscentedKalmanFilter", "ukf_weights"],
                    "tanksynth.runtime.estimators.ukf"),
}

__getattr__, __dir__ = _lazy_exports(__name__, _EXPORTS)

__all__ = [
    "BACKENDS", "ArrayEstimator", "CovarianceError", "DiscreteModel", "Estimator",
    "KernelEstimator", "CovarianceKernelEstimator", "discrete_model", "joseph_update", "regularized_jacobian",
    "KalmanTuning", "KalmanFilter", "ExtendedKalmanFilter", "model_from_tuning",
    "steady_state_gain",
    "UKFTuning", "UnscentedKalmanFilter", "ukf_weights",
    "AdaptiveKalmanTuning", "AdaptiveKalmanFilter", "AdaptiveScalingTuning",
    "AdaptiveScalingKalmanFilter", "linear_model_for",
    "ConsensusTuning", "ConsensusFilter",
    "NARXTuning", "NARXEstimator",
    "LuenbergerTuning", "LuenbergerObserver", "TSMultiObserver", "OBSERVER_FORMS",
]
