"""Memory of a design before it runs: the budget, and the size of an LMI design's conic problem.

The budget of one design is `MEMORY_BUDGET` (2 GiB), or the environment
variable ``TANKSYNTH_MEMORY_BUDGET_MB`` (MiB); `memory_budget` refuses a value
that is not a number of MiB in ``[MIN_BUDGET_MB, MAX_BUDGET_MB]`` (exit 2
naming the variable and its value) instead of ignoring it.

The LMI families (``lmi_placement``, ``ts_observer``, ``ts_state_feedback``,
``ts_output_feedback``, ``robust_*``, the LMI routes of ``synthesis``) solve
``min c'x s.t. A x + s = b, s in K`` with Clarabel, ``K`` holding one
positive semidefinite cone per LMI block. Their peak memory grows as the
fourth power of the state dimension and is reached inside the solver's
allocator, which aborts the process (SIGABRT) rather than raising
`MemoryError`: so each family's Options describe its conic problem from the
plant's sizes and the options alone (`ConicSize`, the family's
``conic_size``), `conic_bytes` estimates its peak, and `conic_refusal`
refuses the design (exit 3, `DesignTooLarge`) before anything is built.

What `conic_bytes` counts (8-byte floats), for ``V`` scalar variables and
PSD blocks of orders ``k_i`` (``s_i = k_i (k_i + 1) / 2`` rows each):

* Clarabel: each PSD cone's scaling is a dense ``s_i x s_i`` block of the KKT
  matrix; the KKT's upper triangle (value and row index), its LDL factor
  (the same pattern, filled in) and the cone's own dense copy make about
  `CLARABEL_BYTES_PER_ENTRY` bytes per entry of ``s_i^2``;
* the modelling (`tanksynth.design.conic`): every expression is dense, one
  coefficient per variable, so a block of order ``k`` holds ``k^2 (V + 1)``
  floats, with the temporaries of its products and its transpose, for each
  problem alive at once (phase 1 and phase 2);
* the constraint matrix, first dense (``S x (V + 1)``, ``S = sum s_i``),
  then its column selection and sparse copy.

Calibration (``benchmarks/conic_memory.py``, ``tests/spec/test_memory.py``):
``multiobjective`` (H-infinity + disk, discrete) on ``tank_network`` with N =
8, 12, 16, 20, 24 tanks measured 13, 32, 86, 231 and 412 MiB of peak RSS above
the interpreter's (VmHWM); `conic_bytes` gives 24, 53, 132, 297 and 596 MiB:
an upper bound within a factor 1.3 to 1.9 (the fixed `FIXED_BYTES` weighs most
on the small ones). N = 64 is estimated at 28 GiB (it aborted past 7.2 GB).

The ``fit`` method (`tanksynth.design.fit`) grows with the logged samples: its CasADi graphs
(the multiple-shooting NLP, the single-shooting chain of the statistics: RK4 sub-steps of the
plant per sample), the derivative blocks and the residual Jacobian all hold a few kB per sample
and state. `fit_bytes` = `FIT_FIXED_BYTES` + `FIT_BYTES_PER_SAMPLE_STATE` x samples x states;
`refuse_oversized_fit` refuses a fit above the budget before its NLP is built (exit 3, naming
the samples and what shrinks them). Calibration (peak RSS above the interpreter's with the fit
loaded, ``examples/three_tank_fit.toml`` on one log of N samples, 3 states, 4 starts; the
design alone, ``resource.getrusage`` before and after): N = 2000, 10000, 40000 measured 57,
141, 351 MiB (fit 37, 95, 158 s on one core); `fit_bytes` gives 93, 211, 650 MiB (an upper
bound: 2.4 kB per sample and state measured between 10000 and 40000, 5 kB counted, which also
covers the 13 GB reported for a 900 000-sample log: 12.9 GiB). That log is refused at the
default budget (up to about 136 000 samples of a three-state plant fit in 2 GiB).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

from tanksynth.errors import DesignTooLarge, SpecError

if TYPE_CHECKING:
    from tanksynth.plants.base import Plant
    from tanksynth.spec import DesignSpec

__all__ = ["BUDGET_VARIABLE", "MEMORY_BUDGET", "MIN_BUDGET_MB", "MAX_BUDGET_MB", "memory_budget",
           "ConicSize", "conic_bytes", "conic_refusal", "refuse_oversized_conic", "region_order",
           "nonlinear_atoms",
           "CLARABEL_BYTES_PER_ENTRY", "FIXED_BYTES", "FIT_FIXED_BYTES",
           "FIT_BYTES_PER_SAMPLE_STATE", "fit_bytes", "refuse_oversized_fit"]

#: The environment variable that sets the memory budget of one design (MiB).
BUDGET_VARIABLE = "TANKSYNTH_MEMORY_BUDGET_MB"

#: Default memory budget of one design (bytes): 2 GiB.
MEMORY_BUDGET = 2 * 1024 ** 3

#: The smallest and largest budget accepted (MiB): below 1 MiB nothing runs, above 1e9 MiB
#: (about 1 PiB) the number is a typo.
MIN_BUDGET_MB, MAX_BUDGET_MB = 1.0, 1e9

#: Bytes per entry of a PSD cone's dense ``s x s`` KKT block inside Clarabel (KKT triangle with
#: row indices, its LDL factor, the cone's scaling matrix): calibrated, see the module docstring.
CLARABEL_BYTES_PER_ENTRY = 32.0

#: Fixed memory of one conic solve (bytes): the solver's workspaces, the model's bookkeeping.
FIXED_BYTES = 16.0 * 1024 ** 2

#: Fixed memory of a fit above the interpreter's (bytes): calibrated, see the module docstring.
FIT_FIXED_BYTES = 64.0 * 1024 ** 2

#: Memory of a fit per logged sample and plant state (bytes): calibrated, see the module
#: docstring.
FIT_BYTES_PER_SAMPLE_STATE = 5120.0

#: Order of each elementary LMI region (rows of its ``L`` and ``M`` matrices).
_REGION_ORDER = {"half_plane": 1, "disk": 2, "sector": 2}


def memory_budget() -> int:
    """The memory budget of one design (bytes).

    `MEMORY_BUDGET`, or ``TANKSYNTH_MEMORY_BUDGET_MB`` (a number of MiB)
    when it is set and not empty.

    Returns
    -------
    int
        Bytes.

    Raises
    ------
    SpecError
        The variable is set to something that is not a finite number of MiB
        in ``[MIN_BUDGET_MB, MAX_BUDGET_MB]`` (``abc``, ``-5``, ``nan``,
        ``inf``, ``1e-300``, ``0``): one line naming the variable and the value.
    """
    raw = os.environ.get(BUDGET_VARIABLE)
    if raw is None or not raw.strip():
        return MEMORY_BUDGET
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not (MIN_BUDGET_MB <= value <= MAX_BUDGET_MB):  # False for nan
        shown = raw if len(raw) <= 40 else raw[:40] + "..."
        raise SpecError(f"environment variable {BUDGET_VARIABLE}={shown!r}: expected the memory "
                        f"budget of one design in MiB, a number from {MIN_BUDGET_MB:g} to "
                        f"{MAX_BUDGET_MB:g} (unset: {MEMORY_BUDGET // 1024 ** 2})")
    return int(value * 1024 ** 2)


def region_order(region: tuple[tuple, ...]) -> int:
    """The order of an LMI region (the sum of its parts' orders: half-plane 1, disk 2, sector 2).

    Parameters
    ----------
    region : tuple of tuple
        The parts of `tanksynth.spec.options.parse_region`.

    Returns
    -------
    int
        The region LMI of an ``n``-state design is ``order * n`` rows.
    """
    return sum(_REGION_ORDER.get(str(part[0]), 2) for part in region) or 1


def nonlinear_atoms(plant: Plant) -> int:
    """The distinct nonlinear atoms of the plant's dynamics: an upper bound of its TS premises.

    Counts the distinct outermost subexpressions of ``f`` that depend on a
    state and are not polynomial in it (a root, a negative or fractional power,
    a function such as ``sign`` or ``abs``). The quasi-LPV split of
    `tanksynth.analysis.quasi_lpv` makes one premise per such atom at most
    (``sign(h1 - h3) sqrt(|h1 - h3|)`` counts 2 here, one premise there).

    Parameters
    ----------
    plant : Plant

    Returns
    -------
    int
    """
    import sympy as sp  # the plant holds sympy expressions already

    states = set(plant.x)
    found: set[object] = set()
    todo: list[sp.Basic] = list(plant.f_numeric)   # sympy expressions (a Matrix's entries)
    while todo:
        expr = todo.pop()
        if not expr.free_symbols & states:
            continue
        if isinstance(expr, sp.Function) or (isinstance(expr, sp.Pow) and not (
                expr.exp.is_Integer and expr.exp >= 0)):
            found.add(expr)
        else:
            todo.extend(expr.args)
    return len(found)


@dataclass(frozen=True)
class ConicSize:
    """The size of an LMI design's conic problem, from its structure.

    Attributes
    ----------
    variables : int
        Scalar decision variables (a symmetric ``n x n`` matrix counts
        ``n (n + 1) / 2``).
    psd_orders : tuple of float
        The order ``k`` of each LMI block (``k x k``); floats so that a
        count of blocks that overflows an int stays a number.
    linear_rows : int
        Rows of the nonnegative and second-order cones.
    problems : int
        Problems whose expressions are alive at once (phase 1 and phase 2: 2).
    advice : str
        What shrinks it (options, plant size, another method), for the message.
    """

    variables: float
    psd_orders: tuple[float, ...]
    linear_rows: float = 0
    problems: int = 2
    advice: str = ""

    @property
    def svec_rows(self) -> float:
        """Rows of the PSD cones: ``sum k (k + 1) / 2``."""
        return float(sum(k * (k + 1) / 2 for k in self.psd_orders))


#: Factor of each retry of an LMI design whose conditioning bound ``kappa`` was active
#: (`tanksynth.design.lmi_checks.KAPPA_STEP`; spec may not import design, a test ties the two).
KAPPA_RETRY_STEP = 100.0


def kappa_tries(kappa: float, kappa_max: float) -> int:
    """How many solves the ``kappa`` relaxation may make: ``kappa``, x100, ... up to ``kappa_max``.

    Parameters
    ----------
    kappa, kappa_max : float
        The first conditioning bound and its ceiling (dimensionless).

    Returns
    -------
    int
        At least 1. Each try builds its problems anew, and their memory is counted as alive
        together (measured: ``lmi_placement`` on ``tank_network`` N = 36 peaked at 635 MiB
        above the idle process where two problems were estimated at 490 MiB).
    """
    tries, level = 1, float(kappa)
    while level < kappa_max and tries < 64:
        level *= KAPPA_RETRY_STEP
        tries += 1
    return tries


def conic_bytes(size: ConicSize) -> float:
    """Estimated peak memory of building and solving a conic problem (bytes, an upper bound).

    Parameters
    ----------
    size : ConicSize

    Returns
    -------
    float
        Bytes (see the module docstring for what is counted and the calibration).
    """
    columns = float(size.variables) + 1.0
    rows = size.svec_rows + float(size.linear_rows)
    kkt = CLARABEL_BYTES_PER_ENTRY * sum((k * (k + 1) / 2) ** 2 for k in size.psd_orders)
    modelling = 8.0 * size.problems * columns * sum(float(k) ** 2 for k in size.psd_orders)
    constraints = 16.0 * rows * columns
    return FIXED_BYTES + kkt + modelling + constraints


def conic_refusal(entry: DesignSpec, plant: Plant, ts: float | None) -> str | None:
    """Why ``entry``'s conic problem is refused for its memory (None: it fits the budget).

    Parameters
    ----------
    entry : DesignSpec
        A validated ``[[design]]`` entry (its ``config`` the method's Options).
    plant : Plant
        The spec's plant.
    ts : float or None
        Sampling period (s).

    Returns
    -------
    str or None
        One line naming the design, the estimated size and what shrinks it.
    """
    config = entry.config
    size = None if config is None else config.conic_size(plant, ts)
    if size is None:
        return None
    need, budget = conic_bytes(size), memory_budget()
    if need <= budget:
        return None
    kmax = int(max(size.psd_orders, default=0))
    gib = f"{need / 1024 ** 3:.3g}" if need < 1e18 else f"{need / 1024 ** 3:.3e}"
    return (f"design '{entry.name}' ({entry.method}): its LMI problem ({size.variables:.0f} "
            f"variables, {len(size.psd_orders):.0f} LMI block(s) up to {kmax} x {kmax}) would need "
            f"about {gib} GiB of memory, over the budget of {budget / 1024 ** 3:.3g} GiB "
            f"({BUDGET_VARIABLE}); shrink it: {size.advice or 'a smaller plant'}")


def refuse_oversized_conic(entry: DesignSpec, plant: Plant, ts: float | None) -> None:
    """Raise `DesignTooLarge` (exit 3) when `conic_refusal` refuses ``entry``.

    Parameters
    ----------
    entry : DesignSpec
    plant : Plant
    ts : float or None
        Sampling period (s).

    Raises
    ------
    DesignTooLarge
        Before anything of the design is built.
    """
    why = conic_refusal(entry, plant, ts)
    if why is not None:
        raise DesignTooLarge(why)


def fit_bytes(samples: int, states: int) -> float:
    """Estimated peak memory of a ``fit`` (bytes above the interpreter's; see the module docstring).

    Parameters
    ----------
    samples : int
        Logged samples of every data file the fit reads (estimation and validation).
    states : int
        The plant's states.

    Returns
    -------
    float
        Bytes.
    """
    return FIT_FIXED_BYTES + FIT_BYTES_PER_SAMPLE_STATE * float(samples) * float(states)


def refuse_oversized_fit(name: str, samples: int, states: int) -> None:
    """Raise `DesignTooLarge` (exit 3) when `fit_bytes` exceeds `memory_budget`.

    Parameters
    ----------
    name : str
        The design's name.
    samples : int
        Logged samples of every data file the fit reads.
    states : int
        The plant's states.

    Raises
    ------
    DesignTooLarge
        Before the fit's NLP is built: one line naming the design, the samples, the estimate
        against the budget and what shrinks it.
    """
    need, budget = fit_bytes(samples, states), memory_budget()
    if need <= budget:
        return
    most = max(int((budget - FIT_FIXED_BYTES) / (FIT_BYTES_PER_SAMPLE_STATE * max(states, 1))), 0)
    raise DesignTooLarge(
        f"design '{name}' (fit): {samples} logged samples x {states} states would need about "
        f"{need / 1024 ** 3:.3g} GiB of memory, over the budget of {budget / 1024 ** 3:.3g} GiB "
        f"({BUDGET_VARIABLE}); shrink it: decimate the logs or fit fewer or shorter files (at "
        f"most about {most} samples in all), or raise {BUDGET_VARIABLE}")
