"""Logged measurements of a plant: experiments read from data files, checked against the plant.

An experiment is one logged run of the rig (pump inputs and sensor readings over time) in the
plant's own signal names and units (`Experiment`). The fit (`tanksynth.design.fit`) estimates
plant parameters from experiments; the replay (`tanksynth.verify.replay`) runs estimators and
detectors on them. This package sits beside `tanksynth.analysis` (it needs only the plant), so
that both stages read data the same way.
"""

from __future__ import annotations

from tanksynth.measurements.experiment import Experiment
from tanksynth.measurements.files import file_sha256
from tanksynth.measurements.read import read_experiments
from tanksynth.spec.data_table import DataTable, parse_data_table

__all__ = ["Experiment", "read_experiments", "file_sha256", "DataTable", "parse_data_table"]
