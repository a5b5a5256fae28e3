"""What `design` looks at after (and before) designing: warnings a control engineer should see.

A design can be computed and still be suspicious. `designed` runs a design
method and collects one line per problem as a `DesignWarning`:

* the operating point is not an equilibrium (which equation is unbalanced,
  by how much, against which tolerance);
* the equilibrium input lies outside the actuator range;
* the sampling period is longer than the plant's slowest time constant (named, with
  the fastest);
* a plant parameter lies outside the plausible range its plant declares
  (a unit slip: cm^2 written as m^2);
* the design's own closed loop (``A - B K``, ``A - L C`` from its gains, or
  the error dynamics it reports) is not stable;
* warnings the design method issued itself (poles that look written for the
  other time domain, a relaxed conditioning bound, an accepted fragile gain).

The lines are recorded in the result's ``diagnostics["warnings"]`` and
issued again with `warnings.warn` (category `DesignWarning`), so the CLI
prints each as one line and Python callers can filter them.
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from typing import Callable

import numpy as np

from tanksynth.analysis.sampling import sampling_warning
from tanksynth.analysis.statespace import model_names
from tanksynth.analysis.trim import balancing_hint, trim_hint
from tanksynth.design.operating_point import as_levels, equilibrium_at, linearized_at
from tanksynth.design.result import DesignResult
from tanksynth.errors import DesignWarning, TanksynthWarning
from tanksynth.spec import DesignSpec, Spec
from tanksynth.spec.memory import refuse_oversized_conic

__all__ = ["spec_warnings", "result_warnings", "designed"]


def spec_warnings(spec: Spec) -> list[str]:
    """Warnings about the spec's plant and operating point (one line each).

    Parameters
    ----------
    spec : Spec
        The validated spec (its plant and operating point).

    Returns
    -------
    list of str
    """
    plant = spec.plant
    out = list(plant.implausible_parameters())
    eq = equilibrium_at(plant, spec.x0, spec.given_u0)
    if not eq.is_equilibrium:
        res = np.abs(eq.residual)
        i = int(np.argmax(res))
        st = plant.states[i]
        out.append(f"the operating point is not an equilibrium: max |f(x_op, u_op)| = {res[i]:.3g} "
                   f"{st.unit}/s in the equation of d{st.name}/dt (tolerance {eq.tolerance:.3g}) with "
                   f"the least-squares input u_op = {np.array2string(eq.u0, precision=4)}; the design "
                   "linearises about a point the plant does not stay at")
        for hint in (trim_hint(plant, as_levels(spec.x0), eq.u0 if eq.given_u0 is None else eq.given_u0,
                               u_given=eq.given_u0 is not None),
                     balancing_hint(plant, as_levels(spec.x0), eq.tolerance)):
            if hint:
                out[-1] += f"; {hint}"
    if not eq.within_bounds:
        bad = [f"{q.name} = {v:.4g} {q.unit} not in [{lo:g}, {hi:g}]"
               for q, v, (lo, hi) in zip(plant.inputs, eq.u0, plant.input_limits)
               if not lo - 1e-12 <= v <= hi + 1e-12]
        out.append("the equilibrium input lies outside the actuator range: " + "; ".join(bad))
    if spec.ts is not None:
        slow = sampling_warning(linearized_at(plant, spec.x0, eq.u0).F, spec.ts)
        if slow:
            out.append(slow)
    return out


def _unstable(eigs: np.ndarray, domain: str) -> bool:
    eigs = np.asarray(eigs, dtype=complex)
    return bool(np.any(np.abs(eigs) >= 1.0) if domain == "discrete" else np.any(eigs.real >= 0.0))


def result_warnings(result: DesignResult) -> list[str]:
    """Warnings about a design's own result: an unstable closed loop or error dynamics.

    Looks for the state matrix ``A`` (gain ``F`` in continuous time, ``Ad``
    in discrete time: `model_names`) with the input matrix and ``K``
    (``A - B K``, the augmented matrix of an integral design when stored) or
    ``C`` and ``L`` (``A - L C``) in the gains, in the time domain of
    ``diagnostics["time_domain"]``, and for the ``error_dynamics_eigenvalues``
    an estimator reports.

    Parameters
    ----------
    result : DesignResult
        The design's result (gains, diagnostics).
    """
    g, d = result.gains, result.diagnostics
    domain = d.get("time_domain", "continuous")
    out = []
    loops = []
    try:
        names = model_names(domain)
        kA, kB = names["A"], names["B"]
        if kA in g and "L" in g and "C" in g:
            loops.append(("A - L C", np.asarray(g[kA]) - np.asarray(g["L"]) @ np.asarray(g["C"])))
        if kA in g and "K" in g and kB in g:
            A, B, K = (np.atleast_2d(np.asarray(g[k], dtype=float)) for k in (kA, kB, "K"))
            if K.shape[1] == A.shape[0]:
                loops.append(("A - B K", A - B @ K))
            elif isinstance(d.get("integral"), dict) and "augmented_A" in d["integral"]:
                Aa = np.asarray(d["integral"]["augmented_A"], dtype=float)
                Ba = np.vstack([B, np.zeros((Aa.shape[0] - B.shape[0], B.shape[1]))])
                loops.append(("the augmented Aa - Ba K", Aa - Ba @ K))
    except (ValueError, TypeError):  # shapes that are not a loop: nothing to say
        loops = []
    for what, M in loops:
        eigs = np.linalg.eigvals(M)
        if _unstable(eigs, domain):
            worst = np.max(np.abs(eigs)) if domain == "discrete" else np.max(eigs.real)
            out.append(f"the designed {what} is not stable ({domain} time): "
                       + (f"spectral radius {worst:.4g} >= 1" if domain == "discrete" else
                          f"largest real part {worst:.4g} 1/s >= 0"))
    err = d.get("error_dynamics_eigenvalues")
    if err:
        eigs = np.array([complex(re, im) for re, im in err])
        dom = "continuous" if d.get("form") == "continuous" else "discrete"
        if _unstable(eigs, dom):
            out.append(f"the designed error dynamics are not stable ({dom} time): eigenvalues "
                       + ", ".join(f"{z:.4g}" for z in eigs))
    return out


def designed(run: Callable[[Spec, DesignSpec], DesignResult], spec: Spec,
             entry: DesignSpec) -> DesignResult:
    """Run ``run(spec, entry)`` and record every warning in ``diagnostics["warnings"]``.

    Spec warnings (`spec_warnings`) are issued before designing (so a refused
    design still shows them), then the design runs with its own warnings collected
    (every `TanksynthWarning`, e.g. undefined Takagi-Sugeno premises, not only the
    `DesignWarning` s), then `result_warnings` of what it produced.
    Every line is issued as a `DesignWarning` and listed, once, in the
    result's diagnostics.

    Parameters
    ----------
    run : callable
        ``run(spec, entry) -> DesignResult`` (a method's design function).
    spec : Spec
        The validated spec.
    entry : DesignSpec
        One of its ``[[design]]`` entries.

    Returns
    -------
    DesignResult
        With ``diagnostics["warnings"]`` (a list of str, empty when nothing
        looks wrong).

    Raises
    ------
    DesignTooLarge
        The design's conic (LMI) problem would exceed the memory budget
        (`tanksynth.spec.memory`): refused before anything is built.
    """
    refuse_oversized_conic(entry, spec.plant, spec.ts)
    lines = spec_warnings(spec)
    for line in lines:
        warnings.warn(line, DesignWarning, stacklevel=2)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = run(spec, entry)
    own = []
    for w in caught:
        # every tanksynth warning the design issued is this design's (one path: issued again as a
        # DesignWarning below, so the CLI prints it with the design's name, and listed here)
        if issubclass(w.category, TanksynthWarning):
            own.append(str(w.message))
        else:  # a library's: pass it on unchanged
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    after = result_warnings(result)
    for line in own + after:
        warnings.warn(line, DesignWarning, stacklevel=2)
    listed = list(dict.fromkeys(lines + own + after))
    diagnostics = dict(result.diagnostics)
    diagnostics["warnings"] = listed
    return replace(result, diagnostics=diagnostics)
