"""What the adapters of linear gains report about a gain: robustness, a reference, its LaTeX.

Shared by the design adapters that return a state-feedback or observer gain of a linear loop
(``pole_placement``, ``lmi_placement``, ``canonical_observer``, ``ts_observer``):

===========================  =================================================================
`checked_robustness`         the loop's robustness figures; a fragile loop refused unless the
                             spec accepts it (``allow_fragile = true``, then a warning)
`reference_comparison`       a printed (reference) gain beside the derived one, and the
                             eigenvalues the reference gives on the derived model
`matrix_latex`               a gain as sympy prints a matrix, fast for large gains
===========================  =================================================================
"""

from __future__ import annotations

import warnings
from typing import Any, Callable

import numpy as np
import sympy as sp

from tanksynth.design.matrices import complex_pairs
from tanksynth.design.placement.exact import refuse_fragile, robustness_report
from tanksynth.errors import DesignWarning

__all__ = ["checked_robustness", "reference_comparison", "matrix_latex"]


def checked_robustness(A: np.ndarray, closed: np.ndarray, gain: np.ndarray, domain: str,
                       allow_fragile: bool, what: str) -> dict:
    """Robustness figures of a loop; a fragile one refused unless ``allow_fragile``.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        The open-loop matrix a model error would perturb (1/s in continuous time,
        dimensionless in discrete time).
    closed : ndarray, shape (n, n)
        ``A - B K`` or ``A - L C`` (units of ``A``).
    gain : ndarray
        ``K`` or ``L`` (input units per state unit, or state units per output unit).
    domain : {"continuous", "discrete"}
        Time domain of ``A``.
    allow_fragile : bool
        The spec's ``allow_fragile``: accept a fragile loop (with a `DesignWarning`).
    what : str
        The loop, for the messages (``"the closed loop A - B K"``).

    Returns
    -------
    dict
        `tanksynth.design.placement.exact.robustness_report`; with ``accepted_because`` when a
        fragile loop was accepted.

    Raises
    ------
    InfeasibleDesign
        A fragile loop and ``allow_fragile`` false (naming the option).
    """
    rob = robustness_report(A, closed, gain, domain)
    if rob["fragile"]:
        if not allow_fragile:
            refuse_fragile(rob, what)
        rob["accepted_because"] = "allow_fragile = true"
        warnings.warn(f"fragile design accepted (allow_fragile = true): a relative change of A of "
                      f"{rob['relative_stability_radius']:.3g} destabilises {what}", DesignWarning,
                      stacklevel=3)
    return rob


def reference_comparison(reference: np.ndarray, derived: np.ndarray,
                         closed_loop_of: Callable[[np.ndarray], np.ndarray] | None) -> dict:
    """A reference (printed) gain beside the derived one, for the diagnostics.

    Parameters
    ----------
    reference : ndarray
        The reference gain (units of the gain).
    derived : ndarray
        The derived gain, same shape (units of the gain).
    closed_loop_of : callable, optional
        ``closed_loop_of(G)``: the closed-loop matrix a gain gives on the derived model; with it
        the eigenvalues the reference gain gives are listed.

    Returns
    -------
    dict
        ``reference``, ``derived``, ``difference``, ``max_abs_difference``,
        ``relative_difference`` (Frobenius, relative to the reference) and
        ``reference_closed_loop_eigenvalues`` (sorted ``[re, im]`` pairs) with ``closed_loop_of``.
    """
    diff = derived - reference
    out = {"reference": reference.tolist(), "derived": derived.tolist(),
           "difference": diff.tolist(), "max_abs_difference": float(np.max(np.abs(diff))),
           "relative_difference": float(np.linalg.norm(diff)
                                        / max(float(np.linalg.norm(reference)), 1e-300))}
    if closed_loop_of is not None:
        eig = np.linalg.eigvals(closed_loop_of(reference))
        out["reference_closed_loop_eigenvalues"] = complex_pairs(eig)
    return out


def matrix_latex(M: Any) -> str:
    """``sympy.latex(sympy.Matrix(M))``, each distinct value converted and printed once.

    The same text as sympy's matrix printer (``\\left[\\begin{matrix}..`` up to
    10 columns, ``array`` with a column spec beyond), assembled here: a 256 x 256
    gain has 65,536 entries but a few distinct values, and printing every entry
    through sympy took seconds.

    Parameters
    ----------
    M : array_like, shape (r, c) or (r,)
        Numbers (a vector is printed as a column); any units.

    Returns
    -------
    str
        LaTeX of the matrix.
    """
    M = np.asarray(M)
    if M.ndim == 1:
        M = M.reshape(-1, 1)
    if M.ndim != 2 or not M.size:
        return sp.latex(sp.Matrix(M))
    kind = M.dtype.kind
    # a number, never text: the entries are floats or integers (anything else goes through Matrix)
    as_sympy = (lambda v: sp.Float(float(v))) if kind == "f" else \
        (lambda v: sp.Integer(int(v))) if kind in "iub" else (lambda v: sp.Matrix([[v]])[0, 0])
    text: dict = {}
    rows = []
    for row in M:
        cells = []
        for v in row:
            key = v.tobytes()
            if key not in text:
                text[key] = sp.latex(as_sympy(v))
            cells.append(text[key])
        rows.append(" & ".join(cells))
    env = "matrix" if M.shape[1] <= 10 else "array"
    spec = "" if env == "matrix" else "{" + "c" * M.shape[1] + "}"
    return rf"\left[\begin{{{env}}}{spec}" + r"\\".join(rows) + rf"\end{{{env}}}\right]"
