"""Exception hierarchy of tanksynth.

Every error raised on purpose by the toolbox derives from `TanksynthError` and
also from the built-in exception a caller would naturally catch, following
python-control's ``exception.py`` pattern.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pathlib import Path

__all__ = [
    "TanksynthError",
    "SpecError",
    "ParseError",
    "RegionError",
    "DataError",
    "ArtefactError",
    "SchedulerError",
    "DimensionError",
    "InfeasibleDesign",
    "DesignTooLarge",
    "UnobservableError",
    "UncontrollableError",
    "ReportError",
    "CovarianceError",
    "SimulationError",
    "TanksynthWarning",
    "DesignWarning",
]


class TanksynthError(Exception):
    """Base class of every error raised by tanksynth."""


class SpecError(TanksynthError, ValueError):
    """A spec (file, table, key or value) is malformed or out of range.

    Parameters
    ----------
    message : str
        What is wrong and what was expected.
    key : str, optional
        Dotted path of the offending key, e.g. ``plant.parameters.A``.
    source : str, optional
        File the spec came from, if any.

    Attributes
    ----------
    errors : tuple of SpecError
        When several ``[[design]]`` tables are invalid, each table's error (this
        error's message joins them); empty otherwise.
    """

    def __init__(self, message: str, key: str | None = None, source: str | None = None):
        self.key = key
        self.source = source
        self.detail = message
        self.errors: tuple[SpecError, ...] = ()
        where = []
        if source:
            where.append(str(source))
        if key:
            where.append(f"key '{key}'")
        prefix = (": ".join(where) + ": ") if where else ""
        super().__init__(prefix + message)


class ParseError(SpecError):
    """An equation string is outside the whitelisted grammar.

    Parameters
    ----------
    message : str
        What is wrong and what was expected.
    key : str, optional
        Dotted path of the offending key.
    source : str, optional
        File the spec came from, if any.
    """


class RegionError(SpecError):
    """An operating point lies outside the plant's operating region.

    Parameters
    ----------
    message : str
        What is wrong and what was expected.
    key : str, optional
        Dotted path of the offending key.
    source : str, optional
        File the spec came from, if any.
    """


class DataError(SpecError):
    """A measured-data file (or its ``[data]`` mapping) is unusable: exit code 2.

    One line naming the file, the column and the row where it applies
    (`tanksynth.measurements.read_experiments`): lengths that differ, time not
    strictly increasing, a column missing, all NaN or not numeric, a unit that
    cannot be right, a file that is not a regular file or is too large.

    Parameters
    ----------
    message : str
        What is wrong (with the column and row) and what was expected.
    key : str, optional
        Dotted spec key when the ``[data]`` table is at fault (``data.columns.h1``).
    source : str, optional
        The data file (or spec) concerned.
    """


class ArtefactError(TanksynthError, ValueError):
    """An artefact file is missing, malformed, or fails its provenance check."""


class SchedulerError(TanksynthError, ConnectionError):
    """A Dask scheduler address is malformed, unreachable, or does not answer in time."""


class DimensionError(TanksynthError, ValueError):
    """Matrix or vector arguments have incompatible shapes."""


class InfeasibleDesign(TanksynthError, RuntimeError):
    """A design problem has no solution (or its solution fails the re-check)."""


class DesignTooLarge(InfeasibleDesign):
    """A design refused before it runs: its estimated memory exceeds the budget.

    A design refusal (`InfeasibleDesign`, exit code 3) naming the design, its
    estimated size and what shrinks it (`tanksynth.spec.memory`).
    """


class UnobservableError(InfeasibleDesign, ValueError):
    """A design needs an observable (detectable) pair and the pair is not.

    A design refusal (`InfeasibleDesign`, exit code 3): the plant at this
    operating point admits no such gain. Also a `ValueError` for callers
    that catch it as bad input.
    """


class UncontrollableError(InfeasibleDesign, ValueError):
    """A design needs a controllable (stabilisable) pair and the pair is not.

    A design refusal (`InfeasibleDesign`, exit code 3), also a `ValueError`.
    """


class ReportError(TanksynthError, RuntimeError):
    """A report could not be built (LaTeX failed, or undefined references remain).

    Parameters
    ----------
    message : str
        What failed.
    log_path : str or Path, optional
        The LaTeX log kept for diagnosis (``DIR/report.log``).
    """

    def __init__(self, message: str, log_path: str | Path | None = None):
        self.log_path = log_path
        super().__init__(message)


class CovarianceError(TanksynthError, ArithmeticError):
    """A covariance stopped being positive definite (or a state became non-finite).

    Attributes
    ----------
    step : int
        1-based index of the estimator step that failed.
    run : int or None
        Index of the failing run in a batch (None for a single run).
    matrix : str
        Which quantity failed (``"predicted covariance P(k|k-1)"``, ...).
    value : float
        Smallest Cholesky pivot (or the offending value).
    message : str
        What failed.
    """

    def __init__(self, message: str, step: int, run: int | None, matrix: str, value: float):
        self.step = step
        self.run = run
        self.matrix = matrix
        self.value = value
        super().__init__(message)


class SimulationError(TanksynthError, RuntimeError):
    """A simulation produced a non-finite state or was given inconsistent inputs."""


class TanksynthWarning(Warning):
    """Base class of every warning issued by tanksynth."""


class DesignWarning(TanksynthWarning, UserWarning):
    """A design was produced but something about it (or its input) looks wrong.

    Issued with `warnings.warn` (e.g. an operating point that is not an
    equilibrium, an implausible plant parameter, poles that look written for
    the other time domain); ``tanksynth design`` prints each as one line and
    records it in the artefact's ``diagnostics["warnings"]``.
    """
