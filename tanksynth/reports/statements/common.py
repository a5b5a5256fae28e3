"""What the problem statements share: the template every statement is made from, and the
mathematics several families state alike (the LMI region condition, the time domain).

A statement is ``statement(diag) -> Tex``: one paragraph saying, in mathematics, the problem a
method solved, with the numbers its artefact's diagnostics record. `problem_statement` makes
one from the method's name and its text (fixed, or composed from the diagnostics), documented
alike for every method, so that a family's module spells out only what differs.
"""

from __future__ import annotations

from typing import Callable, Union

from tanksynth.reports.diagnostics.common import Diagnostics
from tanksynth.reports.latex import Tex, escape_latex

__all__ = ["Statement", "Compose", "problem_statement", "domain_phrase", "region_inequality",
           "region_lmi_problem"]

#: A problem statement: the artefact's diagnostics -> one paragraph of LaTeX (text mode).
Statement = Callable[[Diagnostics], Tex]

#: What a statement says: a fixed text, or a function composing it from the diagnostics.
Compose = Union[str, Callable[[Diagnostics], str]]

_DOC = """The problem ``{method}`` solves, in mathematics, from the artefact's diagnostics.

Parameters
----------
diag : mapping
    The artefact's diagnostics; an entry missing or edited to another type is left out of
    the text (`tanksynth.reports.diagnostics`).

Returns
-------
Tex
    One paragraph of LaTeX (text mode).
"""


def problem_statement(method: str, module: str, compose: Compose) -> Statement:
    """The statement ``<method>_statement`` of a method, as a documented function of ``module``.

    Parameters
    ----------
    method : str
        The method's name (a row of `tanksynth.methods.TABLE`).
    module : str
        The family's statements module that exports it (``__name__``): where the function
        says it lives (its docs, its pickled name).
    compose : str or callable
        The statement's text, or ``compose(diag) -> str`` making it from the diagnostics.

    Returns
    -------
    callable
        ``statement(diag) -> Tex``.
    """
    def statement(diag: Diagnostics) -> Tex:
        return Tex(compose if isinstance(compose, str) else compose(diag))

    statement.__name__ = statement.__qualname__ = f"{method}_statement"
    statement.__module__ = module
    statement.__doc__ = _DOC.format(method=method)
    return statement


def domain_phrase(domain: str | None) -> str:
    """`` (discrete time)``: the time domain a design worked in, or nothing when unknown.

    Parameters
    ----------
    domain : str or None
        ``"continuous"``, ``"discrete"`` or None.
    """
    return f" ({escape_latex(domain)} time)" if domain else ""


def region_inequality(pair: str) -> str:
    """The Chilali--Gahinet condition (math mode, no ``$``) that puts the eigenvalues of the
    pair's closed loop in the LMI region ``D = {z : L_D + M_D z + M_D' conj(z) < 0}``.

    Parameters
    ----------
    pair : str
        The LaTeX of the matrix in the condition (``AX - BY``; ``A^\\top X - C^\\top Y`` for
        the dual pair of an observer).
    """
    return rf"L_D \otimes X + M_D \otimes ({pair}) + M_D^\top \otimes ({pair})^\top \prec 0"


def region_lmi_problem(pair: str, gain: str, closed_loop: str, *, dual: str = "",
                       region: str = "D") -> str:
    """``Find X > 0 and Y with <region LMI>, <gain>: every eigenvalue of <closed loop> lies in
    the LMI region D``: the LMI region problem of a gain.

    Parameters
    ----------
    pair : str
        The matrix of the condition (`region_inequality`).
    gain : str
        How the gain follows from ``X`` and ``Y`` (``K = Y X^{-1}``).
    closed_loop : str
        The matrix whose eigenvalues are placed (``A - BK``).
    dual : str, optional
        Words after the condition (`` (dual pair)`` for an observer).
    region : str, optional
        How the region is written (``D``, or ``D`` with its definition).
    """
    return (rf"Find $X \succ 0$ and $Y$ with ${region_inequality(pair)}${dual}, ${gain}$: every "
            rf"eigenvalue of ${closed_loop}$ lies in the LMI region ${region}$")
