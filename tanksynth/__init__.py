"""tanksynth: observer and controller synthesis for multi-tank hydraulic plants.

The pipeline runs one way: spec (TOML) -> plant (sympy) -> design -> artefacts
-> verify -> report. The most used names are re-exported here; the
subpackages `tanksynth.plants`, `tanksynth.design`, `tanksynth.verify` hold
the rest.
"""

from __future__ import annotations

from importlib import metadata as _metadata

from tanksynth.artefacts.io import read_artefact, write_artefact
from tanksynth.analysis import (discretize_zoh, equilibrium_input, lie_derivative, linearize,
                                relative_degree)
from tanksynth.design.result import DesignResult
from tanksynth.errors import (ArtefactError, DimensionError, InfeasibleDesign, ParseError, RegionError,
                     SpecError, TanksynthError, UncontrollableError, UnobservableError)
from tanksynth.plants import (Plant, builtin_plant, custom_plant, hybrid_three_tank, hydraulic_fault,
                     tank_network, three_tank)
from tanksynth.methods import load_spec, parse_spec, parse_spec_text
from tanksynth.spec import Spec
from tanksynth.analysis.rank import (controllability_rank, nonlinear_observability, observability_rank,
                          pbh_test, symbolic_observability)

try:
    __version__ = _metadata.version("tanksynth")
except _metadata.PackageNotFoundError:  # pragma: no cover - source tree without install
    __version__ = "0+unknown"

__all__ = [
    "__version__",
    "read_artefact", "write_artefact",
    "DesignResult", "discretize_zoh", "equilibrium_input", "lie_derivative", "linearize",
    "relative_degree",
    "ArtefactError", "DimensionError", "InfeasibleDesign", "ParseError", "RegionError", "SpecError",
    "TanksynthError", "UncontrollableError", "UnobservableError",
    "Plant", "builtin_plant", "custom_plant", "hybrid_three_tank", "hydraulic_fault", "tank_network",
    "three_tank",
    "Spec", "load_spec", "parse_spec", "parse_spec_text",
    "controllability_rank", "nonlinear_observability", "observability_rank", "pbh_test",
    "symbolic_observability",
]
