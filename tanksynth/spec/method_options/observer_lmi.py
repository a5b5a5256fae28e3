"""Options of ``ts_observer``: Takagi-Sugeno multiple model of the plant and the observer LMI."""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

import numpy as np
import sympy as sp

from tanksynth.errors import SpecError
from tanksynth.spec.method_options.base import MethodOptions, OptionReader, option
from tanksynth.spec.method_options.placement import LMI_SOLVERS
from tanksynth.spec.memory import ConicSize
from tanksynth.spec.options import (parse_bool, parse_box, parse_choice, parse_integer, parse_matrix,
                                    parse_names, parse_number, parse_vector)

if TYPE_CHECKING:  # the plant's module loads sympy; only its type is needed here
    from tanksynth.plants.base import Plant

__all__ = ["LMI_VARIANTS", "TsObserverOptions"]

#: Variants of the ``Q`` matrix of the observer LMI (seed 001 eq. 28).
LMI_VARIANTS = ("qI", "full")


def _weights(value: Any, key: str, n: int) -> Mapping[str, tuple[float, ...]]:
    """``{z1 = [w_1, ..., w_n], ...}``: premise weights, one per state, not all zero."""
    if not isinstance(value, Mapping):
        raise SpecError("expected a table {z1 = [...], ...} (one weight per state for each premise)",
                        key=key)
    out = {}
    for name, vec in value.items():
        k = f"{key}.{name}"
        if not (isinstance(name, str) and name.startswith("z") and name[1:].isdigit()
                and int(name[1:]) >= 1):
            raise SpecError(f"unknown premise {name!r}; expected z1, z2, ...", key=k)
        w = parse_vector(vec, k, n)
        if not np.any(w):
            raise SpecError(f"weights of {name} are all zero", key=k)
        out[name] = tuple(float(v) for v in w)
    return MappingProxyType(out)


def _blocks(value: Any, key: str, names: list[str]) -> tuple[tuple[str, ...], ...]:
    """A list of lists of state names (blocks of the Lyapunov matrix)."""
    if not isinstance(value, (list, tuple)) or not value:
        raise SpecError("expected a list of lists of state names", key=key)
    return tuple(parse_names(b, f"{key}[{i}]", names, what="state") for i, b in enumerate(value))


def _check_structure(r: OptionReader, blocks: tuple[tuple[str, ...], ...] | None,
                     pattern: np.ndarray | None, names: list[str]) -> None:
    """The LMI structure the design needs, checked with the other options (not at design time):
    ``blocks`` partition the states; ``pattern`` is 0/1, and restricts a gain only with
    ``blocks`` whose states share their row of the pattern (``L = P^-1 K`` mixes a block's rows)."""
    if blocks is not None:
        flat = [v for b in blocks for v in b]
        if sorted(flat) != sorted(names) or len(set(flat)) != len(flat):
            raise r.fail("blocks", f"blocks must partition the states {names} (each state in "
                                   f"exactly one block), got {[list(b) for b in blocks]}")
    if pattern is None:
        return
    if not np.all(np.isin(pattern, (0.0, 1.0))):
        raise r.fail("pattern", "expected a 0/1 matrix (1: the gain entry is free, 0: it is zero)")
    if pattern.all():
        return
    if blocks is None:
        raise r.fail("pattern", "a gain pattern needs blocks (a block-diagonal Lyapunov matrix): "
                                "with a dense P, L = P^-1 K is dense whatever the pattern of K")
    for b in blocks:
        rows = pattern[[names.index(v) for v in b]]
        if not np.all(rows == rows[0]):
            raise r.fail("pattern", f"pattern rows differ inside block {list(b)}: L = P^-1 K mixes "
                                    "the rows of a block, so its states must allow the same outputs")


@dataclass(frozen=True, eq=False)
class TsObserverOptions(MethodOptions):
    """Options of ``ts_observer``: TS multiple model (sector nonlinearity on the premises) and
    the observer LMI (28) of seed 001, continuous time.

    Attributes
    ----------
    weights : mapping of str to tuple of float, or None
        Premise weightings ``{z1 = [w_1 .. w_n], ...}`` (one dimensionless
        weight per state, not all zero); default None: each premise weighs
        the states it depends on by 1.
    psi : float or None
        Lipschitz constant of the nonlinear remainder (1/s, >= 0), used when
        ``psi_source = "given"``; default None.
    psi_source : str
        ``"given"`` (``psi``), ``"lipschitz"`` (bound of the remainder on the
        domain) or ``"maximise"`` (largest feasible psi); default ``"given"``
        with ``psi``, else ``"maximise"``.
    variant : str
        ``Q`` of the LMI: ``"qI"`` (default, ``Q = q I``) or ``"full"``.
    lipschitz : str
        Form of the Lipschitz bound: ``"jacobian"`` (default) or ``"eq27"``.
    lipschitz_method : str
        How the Jacobian bound is taken: ``"interval"`` (default, interval
        arithmetic) or ``"sampling"``.
    domain : mapping of str to (float, float), or None
        Box ``{state = [min, max]}`` (state units) replacing the plant's
        region bounds of those states; default None (the plant's region).
    orderings : bool
        Keep the region's flow-direction orderings in the domain; default true.
    ordering_gap : float
        Minimum separation kept in each ordering (state units, >= 0); default 0.
    premise_bounds : str
        Bounds of the premises: ``"interval"`` (default) or ``"sampling"``.
    premise_margin : float
        Relative widening of the premise bounds (>= 0); default 0.01.
    samples : int
        Points sampled on the domain for the checks (>= 100); default 5000.
    seed : int
        Seed of the sampling (>= 0); default 0.
    search : bool
        Search the weightings (every direction of ``search_values``); default
        false.
    search_values : tuple of float
        Weight values tried by the search (dimensionless); default (-1, 0, 1).
    search_criterion : str
        Pick the weighting with the largest psi (``"psi_max"``, default) or the
        best certified one (``"certified"``).
    blocks : tuple of tuple of str, or None
        Block-diagonal structure of the Lyapunov matrix, as groups of state
        names; default None (full).
    pattern : ndarray or None
        n x q 0/1 sparsity pattern of the gain ``L``; default None (full).
        Dimensionless.
    reference_L : ndarray or None
        An n x q gain to compare with the derived one (1/s), e.g. a published
        one; default None.
    margin : float
        Strictness margin of the LMIs, in (0, 1); default 1e-6.
    kappa : float
        Bound ``I <= P <= kappa I`` (> 1); default 1e4.
    kappa_max : float
        Ceiling of the automatic relaxation of ``kappa``: when the bound is
        active at the optimum of a refused LMI, it is retried with ``kappa``
        multiplied by 100 up to ``kappa_max`` (>= kappa; equal to ``kappa``
        disables the retry); default 1e8.
    solver : str
        Conic solver, ``"CLARABEL"`` (default) or ``"SCS"``.
    allow_fragile : bool
        Accept an observer error matrix ``A0 - L C`` that a relative change of
        ``A0`` smaller than 1e-6 destabilises (stability radius); default false
        (refused, exit 3).
    x_start : ndarray or None
        Declared initial state of the plant for an extra verdict run (state units,
        >= 0); given with ``x_hat_start``; default None (no extra run).
    x_hat_start : ndarray or None
        Declared initial estimate of that run (state units, >= 0); default None.
    """

    method_name: ClassVar[str] = "ts_observer"

    weights: Mapping[str, tuple[float, ...]] | None = option(None, unit="-")
    psi: float | None = option(None, unit="1/s",
                               default_text="unset: needed only with psi_source = \"given\"")
    psi_source: str | None = option(None, unit="-", choices=("given", "lipschitz", "maximise"))
    variant: str = option("qI", unit="-", choices=LMI_VARIANTS)
    lipschitz: str = option("jacobian", unit="-", choices=("jacobian", "eq27"))
    lipschitz_method: str = option("interval", unit="-", choices=("interval", "sampling"))
    domain: Mapping[str, tuple[float, float]] | None = option(None, unit="state units")
    orderings: bool = option(True, unit="-")
    ordering_gap: float = option(0.0, unit="state units")
    premise_bounds: str = option("interval", unit="-", choices=("interval", "sampling"))
    premise_margin: float = option(0.01, unit="-")
    samples: int = option(5000, unit="-")
    seed: int = option(0, unit="-")
    search: bool = option(False, unit="-")
    search_values: tuple[float, ...] = option((-1.0, 0.0, 1.0), unit="-")
    search_criterion: str = option("psi_max", unit="-", choices=("psi_max", "certified"))
    blocks: tuple[tuple[str, ...], ...] | None = option(None, unit="-")
    pattern: np.ndarray | None = option(None, unit="-")
    reference_L: np.ndarray | None = option(None, unit="1/s", default_text="unset: no comparison")
    margin: float = option(1e-6, unit="-")
    kappa: float = option(1e4, unit="-")
    solver: str = option("CLARABEL", unit="-", choices=LMI_SOLVERS)
    kappa_max: float = option(1e8, unit="-")
    allow_fragile: bool = option(False, unit="-")
    x_start: np.ndarray | None = option(None, unit="state units", default_text="unset: no extra run")
    x_hat_start: np.ndarray | None = option(None, unit="state units",
                                            default_text="unset: no extra run")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "TsObserverOptions":
        """See `MethodOptions.from_table`."""
        r = OptionReader(cls, options, key, ts)
        names = [s.name for s in plant.states]
        n, q = plant.n, plant.q
        states = set(plant.x)
        if not any(sp.diff(e, v).free_symbols & states for e in plant.f for v in e.free_symbols & states):
            raise SpecError(f"method 'ts_observer' needs a plant with nonlinear dynamics (its premise "
                            f"variables); plant '{plant.name}' is linear in its states: use "
                            "luenberger or pole_placement", key=f"{key}.method")
        psi = r.read("psi", parse_number, at_least=0.0)
        psi_source = r.read("psi_source", parse_choice, ("given", "lipschitz", "maximise"))
        if psi_source is None:
            psi_source = "given" if psi is not None else "maximise"
        if psi_source == "given" and psi is None:
            raise r.fail("psi", "psi_source = 'given' needs psi (1/s)")
        domain = r.read("domain", parse_box, names)
        values = r.read("search_values", parse_vector)
        kappa = r.read("kappa", parse_number, above=1.0)
        kappa_max = r.read("kappa_max", parse_number, above=1.0)
        if kappa_max < kappa:
            raise r.fail("kappa_max", f"kappa_max = {kappa_max:g} is below kappa = {kappa:g}")
        blocks = r.read("blocks", _blocks, names)
        pattern = r.read("pattern", parse_matrix, (n, q))
        _check_structure(r, blocks, pattern, names)
        x_start = r.read("x_start", parse_vector, names=names, at_least=0.0)
        x_hat_start = r.read("x_hat_start", parse_vector, names=names, at_least=0.0)
        if (x_start is None) != (x_hat_start is None):
            raise r.fail("x_start" if x_start is None else "x_hat_start",
                         "x_start and x_hat_start are given together (state units)")
        return cls(
            weights=r.read("weights", _weights, n), psi=psi, psi_source=psi_source,
            variant=r.read("variant", parse_choice, LMI_VARIANTS),
            lipschitz=r.read("lipschitz", parse_choice, ("jacobian", "eq27")),
            lipschitz_method=r.read("lipschitz_method", parse_choice, ("interval", "sampling")),
            domain=None if domain is None else MappingProxyType(domain),
            orderings=r.read("orderings", parse_bool),
            ordering_gap=r.read("ordering_gap", parse_number, at_least=0.0),
            premise_bounds=r.read("premise_bounds", parse_choice, ("interval", "sampling")),
            premise_margin=r.read("premise_margin", parse_number, at_least=0.0),
            samples=r.read("samples", parse_integer, at_least=100, at_most=10_000_000),
            seed=r.read("seed", parse_integer, at_least=0),
            search=r.read("search", parse_bool),
            search_values=tuple(float(v) for v in values),
            search_criterion=r.read("search_criterion", parse_choice, ("psi_max", "certified")),
            blocks=blocks, pattern=pattern,
            reference_L=r.read("reference_L", parse_matrix, (n, q)),
            margin=r.read("margin", parse_number, above=0.0, below=1.0),
            kappa=kappa, kappa_max=kappa_max,
            solver=r.read("solver", parse_choice, LMI_SOLVERS),
            allow_fragile=r.read("allow_fragile", parse_bool),
            x_start=x_start, x_hat_start=x_hat_start)

    def conic_size(self, plant: Plant, ts: float | None) -> ConicSize:
        """The observer LMI (`tanksynth.design.observer_lmi.conic_form`), from its structure.

        ``P`` (n x n, symmetric), ``L`` (n x q) and ``psi``; the Lipschitz LMI
        (counted ``2n + 1``, its widest variant) and ``I <= P <= kappa I``. The
        weighting search solves it again, one problem at a time.
        """
        n = plant.n
        return ConicSize(variables=n * (n + 1) / 2 + n * plant.q + 2,
                         psd_orders=(2.0 * n + 1, float(n), float(n)), linear_rows=8,
                         advice="a plant with fewer states, or blocks = [...] (a decentralised "
                                "observer of smaller blocks)")

    def memory_estimate(self, plant: Plant, ts: float | None) -> tuple[float, str]:
        """Peak memory of the sampled steps (bytes).

        ``samples`` points of the domain plus up to 4,096 box corners, each with
        its states, premises, inputs and model values (exactness test); the
        Jacobians of the Lipschitz estimate are evaluated in chunks of 2^20
        values (their non-constant entries only), so they add a fixed amount,
        except in the weighting search (every point's n x n Jacobian at once).
        """
        n, points = plant.n, max(self.samples, 2000) + 4096
        need = 6 * points * (2 * n + 8) + 8 * 2 ** 20 + 16 * n * n
        if self.search:
            need += points * n * n
        return 8.0 * need, "samples"
