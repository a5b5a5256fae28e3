"""The Options dataclass of every design method: its options, their defaults (written once)
and units, and ``from_table`` validating a ``[[design]]`` table before any design runs.

The design adapters read these validated options; the verdicts read the same
values (this package is below both). `tanksynth.methods.TABLE` ties each
class to its method.
"""

from __future__ import annotations

from tanksynth._lazy import lazy_exports as _lazy_exports

#: Re-exported name -> its module, imported on first use (PEP 562): importing the package
#: loads none of its modules' dependencies (issue 15).
_EXPORTS = {
    **dict.fromkeys(["MethodOptions", "OptionReader"], "tanksynth.spec.method_options.base"),
    **dict.fromkeys(["FeedbackLinearizationOptions", "IntegralTrackingOptions",
                     "InverseDynamicsOptions"],
                    "tanksynth.spec.method_options.laws"),
    "DecentralizedKalmanOptions": "tanksynth.spec.method_options.decentralized",
    **dict.fromkeys(["AdaptiveKalmanOptions", "AdaptiveScalingKalmanOptions",
                     "ConsensusFilterOptions", "EkfOptions", "KalmanOptions",
                     "LuenbergerOptions", "NarxOptions", "UkfOptions"],
                    "tanksynth.spec.method_options.estimators"),
    "FaultDetectionOptions": "tanksynth.spec.method_options.fault",
    "LinearizeOptions": "tanksynth.spec.method_options.model",
    **dict.fromkeys(["CanonicalObserverOptions", "LmiPlacementOptions", "PolePlacementOptions"],
                    "tanksynth.spec.method_options.placement"),
    "TsObserverOptions": "tanksynth.spec.method_options.observer_lmi",
    **dict.fromkeys(["RobustObserverOptions", "RobustStateFeedbackOptions"],
                    "tanksynth.spec.method_options.robust"),
    **dict.fromkeys(["TsOutputFeedbackOptions", "TsStateFeedbackOptions"],
                    "tanksynth.spec.method_options.takagi_sugeno"),
    **dict.fromkeys(["H2ObserverOptions", "H2StateFeedbackOptions", "HinfObserverOptions",
                     "HinfStateFeedbackOptions", "MultiobjectiveOptions"],
                    "tanksynth.spec.method_options.synthesis"),
}

__getattr__, __dir__ = _lazy_exports(__name__, _EXPORTS)

__all__ = [
    "MethodOptions", "OptionReader",
    "LinearizeOptions", "PolePlacementOptions", "LmiPlacementOptions", "CanonicalObserverOptions",
    "TsObserverOptions",
    "FeedbackLinearizationOptions", "IntegralTrackingOptions", "InverseDynamicsOptions",
    "DecentralizedKalmanOptions",
    "KalmanOptions", "EkfOptions", "UkfOptions", "AdaptiveKalmanOptions",
    "AdaptiveScalingKalmanOptions", "ConsensusFilterOptions", "LuenbergerOptions", "NarxOptions",
    "FaultDetectionOptions",
    "RobustStateFeedbackOptions", "RobustObserverOptions",
    "TsStateFeedbackOptions", "TsOutputFeedbackOptions",
    "H2StateFeedbackOptions", "H2ObserverOptions", "HinfStateFeedbackOptions", "HinfObserverOptions",
    "MultiobjectiveOptions",
]
