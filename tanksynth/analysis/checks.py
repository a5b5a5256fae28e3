"""Rank verdicts of a spec's plant at its operating point and over its region."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

import sympy as sp

from tanksynth.analysis.budget import TooComplexError, run_within_budget
from tanksynth.analysis.symbolic import jacobian
from tanksynth.analysis.linearize import equilibrium_input, linearize
from tanksynth.analysis.rank_structured import (coupled_blocks, frozen_at, mode_cells,
                                                numeric_observability_rank)
from tanksynth.plants.base import HybridModes, Plant
from tanksynth.analysis.rank import (controllability_rank, nonlinear_observability,
                                     observability_determinant_zeros, observability_rank, pbh_test,
                                     symbolic_observability)

__all__ = ["Check", "rank_conditions", "equilibrium_checks", "symbolic_observability_check"]

#: Largest state dimension for which the symbolic determinant is attempted.
SYMBOLIC_MAX_STATES = 4


@dataclass(frozen=True)
class Check:
    """One verdict: a named condition, whether it holds, and why.

    Parameters
    ----------
    name : str
        The condition's name (``"observability_rank"``, ``"equilibrium"``...).
    passed : bool or None
        Whether it holds; None when it could not be decided (e.g. a symbolic
        test beyond its budget).
    detail : str
        One line saying why, with the numbers in the plant's units.
    data : dict, optional
        JSON-friendly numbers behind the verdict (ranks, singular values,
        residuals in the plant's units); default empty.
    """

    name: str
    passed: bool | None
    detail: str
    data: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict:
        """JSON-friendly form."""
        return {"check": self.name, "passed": self.passed, "detail": self.detail, "data": self.data}


def _kalman(name: str, result) -> Check:
    s = result.singular_values
    k = result.n if result.blocks is None else result.blocks
    if k >= result.n:
        what = "of the full Kalman matrix"
    elif k == 1:
        what = (f"of {'B' if result.kind == 'controllability' else 'C'} alone (its first block: rank n "
                "there, the later blocks cannot lower it; singular values of that block)")
    else:   # the leading blocks already span the states: later ones cannot lower the rank
        last = {1: "", 2: ", A"}.get(k, f", ..., A^{k - 1}")
        blocks = (f"[B{last.replace('A', 'AB') if k == 2 else (last + ' B' if last else '')}]"
                  if result.kind == "controllability"
                  else f"[C{'; CA' if k == 2 else ('; ...; C A^' + str(k - 1) if k > 2 else '')}]")
        what = (f"of the leading {k} Kalman block(s) {blocks} (rank n there: the later blocks "
                "cannot lower it; singular values of those blocks)")
    detail = (f"rank {result.rank}/{result.n} {what}, smallest of first n singular values "
              f"{(s[result.n - 1] if s.size >= result.n else 0.0):.3g}, condition number "
              f"{result.condition_number:.3g}")
    return Check(name, result.full, detail, result.as_dict())


_NONSMOOTH = (sp.Abs, sp.sign, sp.Max, sp.Min, sp.Heaviside, sp.DiracDelta, sp.Piecewise)


def _analytic_jacobians(plant: Plant) -> tuple[sp.Matrix, sp.Matrix] | None:
    """Symbolic ``df/dx``, ``dh/dx`` of the region's smooth form, or None if one keeps a non-smooth term.

    The entries of `tanksynth.analysis.linearize.symbolic_jacobians` (``dh/dx`` first, then ``df/dx`` row
    by row), stopping at the first row with a non-smooth term: on a hybrid
    model the verdict (not attempted) is then known without differentiating
    the rest (sympy's product rule through ``Piecewise``/``Max`` took ~1 s of
    the hybrid three-tank's 1.4 s check); ``df/du`` is not needed.
    """
    rows = []
    for exprs in (plant.h, plant.f_smooth):
        block = []
        for e in exprs:
            row = jacobian(sp.Matrix([e]), plant.x)
            if row.has(*_NONSMOOTH):
                return None
            block.append(row)
        rows.append(sp.Matrix.vstack(*block) if block else sp.zeros(0, plant.n))
    C_sym, F_sym = rows
    return F_sym, C_sym


def equilibrium_checks(plant: Plant, eq) -> list[Check]:
    """``equilibrium`` (residual against its tolerance, the unbalanced equation) and
    ``equilibrium_input_bounds`` (u0 within the actuator range).

    Parameters
    ----------
    plant : Plant
    eq : tanksynth.analysis.linearize.Equilibrium
    """
    res = np.abs(eq.residual)
    i = int(np.argmax(res))
    st = plant.states[i]
    detail = (f"max |f(x_op, u_op)| = {res[i]:.3g} {st.unit}/s (tolerance {eq.tolerance:.3g}) with "
              f"least-squares u_op = {np.array2string(eq.u0, precision=4)}")
    if not eq.is_equilibrium:
        bad = [plant.states[j].name for j in np.flatnonzero(res > eq.tolerance)]
        detail += (f"; unbalanced: d{st.name}/dt = {eq.residual[i]:.3g} {st.unit}/s (equation(s) of "
                   f"{', '.join(bad)}): no input holds the plant at x_op")
        from tanksynth.analysis.trim import balancing_hint, trim_hint

        for hint in (trim_hint(plant, eq.x0, eq.u0 if eq.given_u0 is None else eq.given_u0,
                               u_given=eq.given_u0 is not None),
                     balancing_hint(plant, eq.x0, eq.tolerance)):
            if hint:
                detail += f"; {hint}"
    out = [Check("equilibrium", eq.is_equilibrium, detail, eq.as_dict())]
    lim = plant.input_limits
    def unit(q: Any) -> str:
        return "" if str(q.unit) in ("", "1", "-") else f" {q.unit}"

    parts = [(f"{q.name} = {v:.4g}{unit(q)} in [{lo:g}, {hi:g}]" if np.isfinite(lo) or np.isfinite(hi)
              else f"{q.name} = {v:.4g}{unit(q)} (no actuator range given)")
             + ("" if lo - 1e-12 <= v <= hi + 1e-12 else " VIOLATED")
             for q, v, (lo, hi) in zip(plant.inputs, eq.u0, lim)]
    out.append(Check("equilibrium_input_bounds", eq.within_bounds,
                     "equilibrium input within the actuator range: " + "; ".join(parts)
                     if parts else "no inputs", {"u0": eq.u0.tolist(), "limits": lim.tolist()}))
    return out


def rank_conditions(plant: Plant, x0: npt.ArrayLike, ts: float | None = None,
                    given_u0: npt.ArrayLike | None = None, samples: int = 200,
                    seed: int = 0) -> list[Check]:
    """Every rank verdict for a plant at an operating point.

    Linearisation at ``x0`` (with the equilibrium input): Kalman
    controllability and observability (continuous, and discrete when ``ts``
    is given), PBH tests naming failing modes; nonlinear local observability
    over ``samples`` points of the region; the symbolic observability
    determinant of the linearisation in the model's parameters and states
    (for ``n <= 4``).

    Parameters
    ----------
    plant : Plant
    x0 : array_like, shape (n,)
        Operating levels (state units, e.g. m).
    ts : float, optional
        Sampling period (s).
    given_u0 : array_like, shape (m,), optional
        Input written in the spec (its balance is reported).
    samples, seed : int
        Region sampling for the nonlinear check.

    Returns
    -------
    list of Check
    """
    names = [s.name for s in plant.states]
    eq = equilibrium_input(plant, x0, given_u0)
    checks = equilibrium_checks(plant, eq)
    if eq.given_residual is not None:   # given_u0 was given
        bal = float(np.max(np.abs(eq.given_residual)))
        verdict = "balances the model" if bal <= eq.tolerance else "does NOT balance the model"
        # Informative (None): a printed input that does not balance is an
        # erratum to report, not a failed rank condition.
        checks.append(Check("given_u0_balances", None,
                            f"the input u written in the spec's operating point {verdict}: max |f(x_op, u)| = {bal:.3g} "
                            "(state units/s)",
                            {"residual": eq.given_residual.tolist()}))
    lin = linearize(plant, x0, eq.u0, ts=ts)
    checks.append(_kalman("controllability", controllability_rank(lin.F, lin.B)))
    checks.append(_kalman("observability", observability_rank(lin.F, lin.C)))
    for kind, pbh in (("controllability", pbh_test(lin.F, B=lin.B, state_names=names)),
                      ("observability", pbh_test(lin.F, C=lin.C, state_names=names))):
        detail = "every mode passes" if pbh.passed else "; ".join(
            f"mode {m.eigenvalue:.4g} fails, lives in {', '.join(m.states)}" for m in pbh.modes)
        checks.append(Check(f"pbh_{kind}", pbh.passed, detail, pbh.as_dict()))
    if lin.Ad is not None and lin.Bd is not None:   # discretised: ts was given
        checks.append(_kalman("controllability_discrete", controllability_rank(lin.Ad, lin.Bd)))
        checks.append(_kalman("observability_discrete", observability_rank(lin.Ad, lin.C)))
    nl = nonlinear_observability(plant, count=samples, seed=seed)
    data = nl.as_dict()
    if nl.full:
        detail = (f"rank {plant.n} at {len(nl.ranks)} sampled points of the region (every one) with "
                  f"d(L_f^k h), k < {nl.orders}")
        zeros = observability_determinant_zeros(plant, nl)
        data["determinant_zeros"] = zeros.as_dict()
        if not zeros.searched:
            detail += f"; between the points not searched ({zeros.reason})"
        elif zeros.meets_region:
            detail += (f"; but its determinant changes sign between them: it vanishes inside the "
                       f"region, e.g. at {np.round(zeros.zeros[0], 4).tolist()} (rank < {plant.n} on "
                       f"a surface the samples miss; {len(zeros.zeros)} zero(s) found along "
                       f"{zeros.segments} segments)")
        else:
            detail += (f"; no zero of its determinant found along {zeros.segments} segments "
                       "between them (sign changes searched)")
        ok = nl.full and not zeros.meets_region
    else:
        detail = (f"rank {int(nl.ranks.min())}/{plant.n} (minimum over {len(nl.ranks)} sampled "
                  f"points) with d(L_f^k h), k < {nl.orders}; drops at {len(nl.drop_points)} of "
                  f"them, e.g. {np.round(nl.drop_points[0], 4).tolist()}; unobservable direction "
                  f"there in {', '.join(nl.unobservable_states())}")
        ok = False
    if nl.undefined_points:
        detail += (f"; {nl.undefined_points} sampled point(s) left out: a Lie derivative is not "
                   "finite there (a kink of sqrt/abs/max in the model)")
    checks.append(Check("nonlinear_observability", ok, detail, data))
    checks.append(_symbolic_check(plant, np.asarray(x0, dtype=float), eq.u0, tuple(names), samples, seed))
    return checks


def _symbolic_check(plant: Plant, x0: np.ndarray, u0: np.ndarray, names: tuple[str, ...],
                    samples: int, seed: int) -> Check:
    """The ``symbolic_observability`` verdict: whole, per hybrid mode, or per coupled block."""
    if plant.hybrid is not None:
        return _per_mode(plant, plant.hybrid, x0, u0, names, samples, seed)
    jacobians = _analytic_jacobians(plant)
    if jacobians is None:
        return Check("symbolic_observability", None,
                     "not attempted: the Jacobian keeps non-smooth terms on the region "
                     "(undetermined flow directions)")
    F_sym, C_sym = jacobians
    point = {**dict(zip(plant.x, x0)), **dict(zip(plant.u, u0)), **plant.parameter_values}
    return _smooth_system(F_sym, C_sym, tuple(plant.x), names, point)


def _smooth_system(F_sym: sp.Matrix, C_sym: sp.Matrix, x: tuple[sp.Symbol, ...], names: tuple[str, ...],
                   point: dict, extra: tuple[sp.Symbol, ...] = (), search: bool = True) -> Check:
    """One smooth system: one determinant if ``n <= SYMBOLIC_MAX_STATES``, else one per coupled block.

    ``extra``: symbols that vary with the states (square roots named as symbols); ``search``:
    solve for the degenerate parameter sets.
    """
    n = len(x)
    if n <= SYMBOLIC_MAX_STATES:
        try:
            return run_within_budget(symbolic_observability_check, F_sym, C_sym, x + extra, names,
                                     search, what="the symbolic observability determinant")
        except TooComplexError as exc:
            return Check("symbolic_observability", None, f"not attempted: {exc.detail}")
    blocks = coupled_blocks(F_sym, C_sym)
    big = max(len(b) for b in blocks)
    if big > SYMBOLIC_MAX_STATES:
        return Check("symbolic_observability", None,
                     f"not attempted: n = {n} > {SYMBOLIC_MAX_STATES} states and df/dx, dh/dx couple "
                     f"{big} states in one block ({len(blocks)} block(s))")
    parts, rank, zero, factors = [], 0, [], []
    forms: dict[str, tuple[Check, tuple[str, ...]]] = {}
    for b in blocks:
        rows = [r for r in range(C_sym.shape[0]) if any(C_sym[r, j] != 0 for j in b)]
        Fb = F_sym.extract(b, b)
        Cb = C_sym.extract(rows, b) if rows else sp.zeros(0, len(b))
        bn = tuple(names[j] for j in b)
        r = numeric_observability_rank(np.array(Fb.xreplace(point), dtype=float),
                                       np.array(Cb.xreplace(point), dtype=float)) if rows else 0
        rank += r
        same_as = None
        if not rows:
            check = Check("symbolic_observability", None, "no output sees this block", {})
        else:
            key = _block_form(Fb, Cb, tuple(x[j] for j in b))
            if key in forms:       # a block of the same form: its determinant up to renaming
                check, same_as = forms[key]
            else:
                check = _smooth_system(Fb, Cb, tuple(x[j] for j in b), bn, point,
                                       tuple(e for e in extra if Fb.has(e) or Cb.has(e)), search)
                forms[key] = (check, bn)
        data = dict(check.data)
        parts.append({"states": list(bn), "outputs": rows, "rank": r, "detail": check.detail, **data,
                      **({"same_form_as": list(same_as)} if same_as is not None else {})})
        if data.get("identically_zero") or not rows:
            zero.append(bn)
        if same_as is None:
            factors += [(bn, f) for f in data.get("factors", [])]
    sizes = sorted({len(b) for b in blocks})
    detail = (f"per coupled block: df/dx and dh/dx couple the {n} states only inside {len(blocks)} "
              f"block(s) of {'/'.join(map(str, sizes))} state(s) (the observability matrix is block "
              f"diagonal, its rank the sum of the blocks'): rank {rank}/{n} at the operating point; "
              f"{len(forms)} distinct block form(s) (blocks equal up to renaming their symbols share "
              "one determinant; factors shown for the first block of each form); ")
    if zero:
        detail += "det O identically zero in block(s) " + ", ".join("{" + ", ".join(z) + "}" for z in zero[:4])
    else:
        detail += "no block's det O is identically zero"
    if factors:
        shown = "; ".join(f"{{{', '.join(bn)}}}: {f} = 0" for bn, f in factors[:4])
        detail += f"; det O vanishes where {shown}" + (f" (and {len(factors) - 4} more)" if len(factors) > 4 else "")
    else:
        detail += "; no block's det O depends on the states"
    return Check("symbolic_observability", None, detail, {"blocks": parts, "rank": rank, "n": n})


def _block_form(F: sp.Matrix, C: sp.Matrix, states: tuple[sp.Symbol, ...]) -> str:
    """``F``, ``C`` with the block's states renamed by position and every other symbol by its
    order among the block's symbols (sorted by name): equal strings, equal determinants up to
    that renaming. A renaming that orders two such blocks differently only misses the cache."""
    own = {s: sp.Symbol(f"_state{k}", **s.assumptions0) for k, s in enumerate(states)}
    others = sorted((F.free_symbols | C.free_symbols) - set(states), key=str)
    own.update({s: sp.Symbol(f"_other{k}", **s.assumptions0) for k, s in enumerate(others)})
    return sp.srepr((F.xreplace(own), C.xreplace(own)))


class _Root(sp.Symbol):
    """A positive symbol standing for ``sqrt(name_arg)`` (its name prints as that root)."""

    name_arg: sp.Expr


def _roots_as_symbols(F: sp.Matrix, C: sp.Matrix) -> tuple[sp.Matrix, sp.Matrix, tuple[sp.Symbol, ...]]:
    """Every ``sqrt(e)`` (and ``1/sqrt(e)``) of ``F``, ``C`` replaced by a positive symbol.

    A Torricelli flow's derivative is ``g / sqrt(2 g dh)``: with its root as a symbol the
    determinant is a rational function that sympy factors in milliseconds (with the roots in
    it, a three-tank mode took over 20 s and its factors did not split).
    """
    roots: dict[sp.Expr, sp.Symbol] = {}
    for M in (F, C):
        for p in M.atoms(sp.Pow):
            if p.exp in (sp.Rational(1, 2), sp.Rational(-1, 2)) and p.base.free_symbols:
                base = sp.factor(p.base)
                if base not in roots:
                    r = _Root(f"sqrt({base})", positive=True)
                    r.name_arg = base
                    roots[base] = r

    def sub(e: sp.Basic) -> sp.Basic:
        if (isinstance(e, sp.Pow) and e.exp in (sp.Rational(1, 2), sp.Rational(-1, 2))
                and e.base.free_symbols):
            r = roots[sp.factor(e.base)]
            return r if e.exp > 0 else 1 / r
        return e

    return (F.replace(lambda e: isinstance(e, sp.Pow), sub),
            C.replace(lambda e: isinstance(e, sp.Pow), sub), tuple(roots.values()))


def _per_mode(plant: Plant, hybrid: HybridModes, x0: np.ndarray, u0: np.ndarray, names: tuple[str, ...], samples: int,
              seed: int) -> Check:
    """Per hybrid mode: each mode's field, frozen at a point of that mode, as a smooth system."""
    params = plant.parameter_values
    points = plant.region.sample(max(samples, 400), plant.x, seed=seed)
    cells = mode_cells(hybrid.switching, plant.x, params, points, prefer=x0)
    # Parameters whose value is 0 (closed valves, outlets at the tank bottom) are put in: their
    # terms vanish or simplify, which keeps each mode's determinant small.
    zeros = {sym: sp.Integer(0) for sym, v in params.items() if v == 0}
    modes, lines = [], []
    for bits, pt in cells:
        point = {**dict(zip(plant.x, pt)), **dict(zip(plant.u, u0)), **params}
        label = "(" + ", ".join(f"{nm}={b}" for nm, b in zip(hybrid.names, bits)) + ")"
        f_m = frozen_at(plant.f, point).xreplace(zeros)
        h_m = frozen_at(plant.h, point).xreplace(zeros)
        F_m, C_m = jacobian(f_m, plant.x), jacobian(h_m, plant.x)
        if F_m.has(*_NONSMOOTH) or C_m.has(*_NONSMOOTH):
            check = Check("symbolic_observability", None, "not attempted: non-smooth terms remain")
            r = -1
        else:
            num = {k: v for k, v in point.items()}
            r = numeric_observability_rank(np.array(F_m.xreplace(num), dtype=float),
                                           np.array(C_m.xreplace(num), dtype=float))
            F_r, C_r, roots = _roots_as_symbols(F_m, C_m)
            check = _smooth_system(F_r, C_r, tuple(plant.x), names,
                                   {**point, **{r: sp.sqrt(r.name_arg.xreplace(point)) for r in roots}},
                                   roots, search=False)
        modes.append({"mode": list(bits), "point": pt.tolist(), "rank": r, "detail": check.detail,
                      **dict(check.data)})
        lines.append(f"mode {label} at {np.round(pt, 3).tolist()}: rank {r}/{plant.n}; {check.detail}")
    full = [m for m in modes if m["rank"] == plant.n]
    detail = (f"per hybrid mode ({len(modes)} mode(s) reached by the region's points; each mode's "
              f"field, its branches frozen at a point of the mode, as its own smooth system): "
              f"rank {plant.n} in {len(full)}/{len(modes)} modes"
              + (f" (parameters of value 0 put in: {', '.join(sorted(str(k) for k in zeros))})" if zeros else "")
              + ". " + " | ".join(lines))
    return Check("symbolic_observability", None, detail, {"hybrid_modes": modes})


def symbolic_observability_check(F_sym: sp.Matrix, C_sym: sp.Matrix, variables: tuple[sp.Symbol, ...],
                                 state_names: tuple[str, ...], search_degenerate: bool = True) -> Check:
    """The ``symbolic_observability`` verdict (informative) of the Jacobians ``F``, ``C``.

    The whole symbolic step (the factored determinant, its identically-zero test, the
    degenerate parameter sets): `rank_conditions` runs it under the symbolic budget
    (`tanksynth.analysis.budget.run_within_budget`).

    Parameters
    ----------
    F_sym : sympy.Matrix, shape (n, n)
        Symbolic ``df/dx`` of the smooth form.
    C_sym : sympy.Matrix, shape (q, n)
        Symbolic ``dh/dx``.
    variables : tuple of sympy.Symbol
        The states (treated as varying).
    state_names : tuple of str
        Their names.
    search_degenerate : bool, optional
        Also solve for the parameter sets that make ``O`` singular everywhere (default True;
        the per-mode checks of a hybrid plant skip it: each mode's factors name them).
    """
    sym = symbolic_observability(F_sym, C_sym, variables=variables, state_names=state_names,
                                 search_degenerate=search_degenerate)
    if sym.identically_zero:
        detail = ("det O is identically zero: the linearisation is unobservable for every "
                  "parameter value and operating point"
                  + (f"; unobservable direction in {', '.join(sym.null_direction)}"
                     if sym.null_direction else ""))
    elif not search_degenerate:
        detail = "not identically zero"
    elif sym.degenerate_parameters:
        detail = "rank < n for every state when " + " or ".join(
            "(" + ", ".join(f"{k} = {v}" for k, v in d.items()) + ")" for d in sym.degenerate_parameters)
    else:
        detail = "no parameter values make the linearisation unobservable everywhere"
    if sym.factors:
        detail += "; det O vanishes where " + " or ".join(f"{f} = 0" for f in sym.factors)
    return Check("symbolic_observability", None, detail, sym.as_dict())
