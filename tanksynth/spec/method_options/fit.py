"""Options of ``fit``: grey-box fit of the plant's free parameters (``{value, min, max, fit =
true}`` in ``[plant.parameters]``) and of each experiment's initial state to logged data
(CasADi + IPOPT, multiple shooting; `tanksynth.design.fit`).

The data files are named relative to the spec file (`tanksynth.spec.context`); ``tanksynth fit
SPEC --data FILE...`` gives them on the command line instead.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

from tanksynth.errors import SpecError
from tanksynth.spec.context import free_parameters_in_scope, parse_paths
from tanksynth.spec.method_options.base import MethodOptions, OptionReader, option
from tanksynth.spec.options import parse_choice, parse_integer, parse_number

if TYPE_CHECKING:  # the plant's module loads sympy; only its type is needed here
    from tanksynth.plants.base import Plant

__all__ = ["FitOptions", "FIT_MODES"]

#: The fit's cost: output (simulation) error. (A one-step-ahead prediction-error mode, for
#: drifting or unstable data, is not built: the catalogue lists only what runs.)
FIT_MODES = ("simulation",)
#: Most starts of the multi-start search.
MAX_STARTS = 1000


@dataclass(frozen=True, eq=False)
class FitOptions(MethodOptions):
    """Options of ``fit``: the plant's free parameters (``{value = start, min = lower, max =
    upper, fit = true}`` in ``[plant.parameters]``) and each experiment's initial state fitted
    to logged data by CasADi + IPOPT with multiple shooting, multi-start inside the bounds.

    Attributes
    ----------
    data : tuple of str
        Estimation data files (``.csv`` with a header, ``.npz``, ``.mat``), relative to the spec
        file; their columns map onto the plant by the spec's ``[data]`` table. Required unless
        given on the command line (``tanksynth fit SPEC --data FILE...``); default none.
    validate : tuple of str
        Validation data files (same forms), simulated at the fitted values from an initial state
        estimated on their first ``init_samples`` samples only; default none.
    starts : int
        Starts of the multi-start search (the spec's start value first, then points drawn in
        the bounds), 1 to 1000; default 8.
    mode : str
        ``"simulation"``: the output error of the simulated model (the only mode; a
        one-step-ahead prediction-error mode is not available).
    shooting : int
        Samples per multiple-shooting interval (1 to 100000); default 20.
    seed : int
        Seed of the multi-start draws; default 0.
    level : float
        Confidence level of the reported intervals, in (0, 1) (dimensionless); default 0.95.
    init_samples : int
        Samples of a validation file on which its initial state is estimated (at least 2);
        default 10.
    max_iter : int
        IPOPT's iteration limit per start (1 to 100000); default 500. A fit that stops there
        has not converged and is refused.
    max_time : float
        Wall-clock time the fit's solves may take in all (s; every start and the profile
        solves of the intervals), 1 to 1e6; default 600. A fit that runs out is refused (exit
        3, saying so).
    """

    method_name: ClassVar[str] = "fit"

    data: tuple[str, ...] = option((), unit="-", default_text="unset: the files of tanksynth fit --data")
    validate: tuple[str, ...] = option((), unit="-")
    starts: int = option(8, unit="-")
    mode: str = option("simulation", unit="-", choices=FIT_MODES)
    shooting: int = option(20, unit="samples")
    seed: int = option(0, unit="-")
    level: float = option(0.95, unit="-")
    init_samples: int = option(10, unit="samples")
    max_iter: int = option(500, unit="-")
    max_time: float = option(600.0, unit="s")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "FitOptions":
        """See `MethodOptions.from_table`; the data files must exist (paths relative to the spec
        file, checked when a spec file is read)."""
        r = OptionReader(cls, options, key, ts)
        if free_parameters_in_scope() == ():
            names = [p.name for p in getattr(plant, "parameters", ())]
            example = names[0] if names else "p"
            raise SpecError("method 'fit' needs a free parameter: mark one in [plant.parameters] as "
                            f"{example} = {{value = <start>, min = <lower>, max = <upper>, fit = true}}",
                            key="plant.parameters")
        return cls(data=r.read("data", parse_paths, what="data file"),
                   validate=r.read("validate", parse_paths, what="validation data file"),
                   starts=r.read("starts", parse_integer, at_least=1, at_most=MAX_STARTS),
                   mode=r.read("mode", parse_choice, FIT_MODES),
                   shooting=r.read("shooting", parse_integer, at_least=1, at_most=100_000),
                   seed=r.read("seed", parse_integer, at_least=0),
                   level=r.read("level", parse_number, above=0.0, below=1.0),
                   init_samples=r.read("init_samples", parse_integer, at_least=2, at_most=1_000_000),
                   max_iter=r.read("max_iter", parse_integer, at_least=1, at_most=100_000),
                   max_time=r.read("max_time", parse_number, at_least=1.0, at_most=1e6))
