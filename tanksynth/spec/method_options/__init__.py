"""The Options dataclass of every design method: its options, their defaults (written once)
and units, and ``from_table`` validating a ``[[design]]`` table before any design runs.

The design adapters read these validated options; the verdicts read the same
values (this package is below both). `tanksynth.methods.TABLE` ties each
class to its method.
"""

from __future__ import annotations

from tanksynth.spec.method_options.base import MethodOptions, OptionReader
from tanksynth.spec.method_options.control import (FeedbackLinearizationOptions, IntegralTrackingOptions,
                                                   InverseDynamicsOptions)
from tanksynth.spec.method_options.decentralized import DecentralizedKalmanOptions
from tanksynth.spec.method_options.estimators import (AdaptiveKalmanOptions, AdaptiveScalingKalmanOptions,
                                                      ConsensusFilterOptions, EkfOptions, KalmanOptions,
                                                      LuenbergerOptions, NarxOptions, UkfOptions)
from tanksynth.spec.method_options.fault import FaultDetectionOptions
from tanksynth.spec.method_options.placement import (CanonicalObserverOptions, LinearizeOptions,
                                                     LmiPlacementOptions, PolePlacementOptions)
from tanksynth.spec.method_options.ts_observer import TsObserverOptions
from tanksynth.spec.method_options.robust import RobustObserverOptions, RobustStateFeedbackOptions
from tanksynth.spec.method_options.ts_control import TsOutputFeedbackOptions, TsStateFeedbackOptions
from tanksynth.spec.method_options.synthesis import (H2ObserverOptions, H2StateFeedbackOptions,
                                                     HinfObserverOptions, HinfStateFeedbackOptions,
                                                     MultiobjectiveOptions)

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
