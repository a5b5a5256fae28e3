"""Plain-text check details typeset as LaTeX (`tanksynth.reports.prose`)."""

from __future__ import annotations

import re

from tanksynth.reports.prose import prose_latex
from tanksynth.verify.common import fmt, fmt_signals


def test_python_reprs_become_mathematics():
    tex = prose_latex("eigenvalues [0.954947-0.0108947j, 0.954947+0.0108947j, 0.959641] of "
                      "['h1', 'h2'] within [[0.0, 0.00012], [0.0, 0.00012]]")
    assert r"\pm" in tex and "j," not in tex.replace(r"\mathrm{j}", "J")
    assert "$h_{1}$, $h_{2}$" in tex and "'" not in tex
    assert r"\begin{smallmatrix}0 & 0.00012 \\ 0 & 0.00012\end{smallmatrix}" in tex


def test_ascii_operators_and_names():
    tex = prose_latex("margin -lambda_max(f_D(z)) <= 0.1, X = P^-1, |e|_inf >= 2, L_f^k h, "
                      "x_hat - x, M' (x) X, 4.34e-19, psi^2")
    for expected in (r"$-\lambda_{\max}$", r"$\leq$", r"$P^{-1}$", r"$\|e\|_{\infty}$", r"$\geq$",
                     r"$L_{f}^{k}$", r"$\hat{x}$", r"$M^{\top}$", r"$\otimes$",
                     r"4.34 \times 10^{-19}", r"$\psi^{2}$"):
        assert expected in tex, expected
    assert "<=" not in tex and "lambda_max" not in tex


def test_plain_words_and_names_stay_text():
    tex = prose_latex("the spec's design ts_observer_paper, rank 3/3 (seed 000 eq. 4)")
    assert "spec's" in tex and "ts\\_" in tex and "$" not in tex


def test_fmt_uses_significant_digits():
    # np.array2string(precision=4) printed qmax = 1.2e-4 as 0.0001
    assert fmt([[0.0, 1.2e-4], [0.0, 1.2e-4]]) == "[[0, 0.00012], [0, 0.00012]]"
    assert fmt([3.5884e-05, 1.0]) == "[3.588e-05, 1]"

    class Sig:
        def __init__(self, name, unit):
            self.name, self.unit = name, unit

    text = fmt_signals([[0.0, 1.2e-4], [0.0, 1.2e-4]], [Sig("q1", "m^3/s"), Sig("q2", "m^3/s")])
    assert text == "q1 in [0, 0.00012] m^3/s, q2 in [0, 0.00012] m^3/s"
    assert fmt_signals([3.5e-5], [Sig("q1", "m^3/s")]) == "q1 = 3.5e-05 m^3/s"
    assert re.fullmatch(r"[^\[]*", fmt_signals([1.0], [Sig("x", "1")]))


def test_user_names_given_as_literals_stay_verbatim():
    """A design called ``my_pp`` is a name, not ``my`` with subscript ``pp`` (new-user report);
    the rest of the sentence is still typeset (``lambda_max`` as Greek with a subscript)."""
    text = "Verdict simulation of design my_pp (pole_placement): lambda_max = 0.9, pp_my_pp kept"
    assert "_{pp}" in prose_latex(text)                       # what the literal protects against
    tex = prose_latex(text, literal=("my_pp",)).replace("\\allowbreak{}", "")
    assert "my\\_pp (" in tex and "_{pp}" not in tex.replace("pp\\_my\\_pp", "")
    assert "\\lambda_{\\max}" in tex
    assert "pp\\_my\\_pp" in tex or "pp_my_pp" not in tex     # a longer word is not split
    assert prose_latex("a_b", literal=("",)) == prose_latex("a_b")


def test_quoted_phrase_is_quoted_not_a_transpose():
    """A quoted phrase ending in a bracket (a robust verdict's detail) is not read as the
    transpose of a bracket; a real transpose still is."""
    tex = str(prose_latex("1 run(s) fail 'every state settled (to the run's own equilibrium)' on [H, 1.2 H]"))
    assert r"^{\top}" not in tex and "`every state settled" in tex and "equilibrium)' on" in tex
    assert str(prose_latex("with (A - L C)' P and K' P")).count(r"^{\top}") == 2


def test_an_inverse_before_a_closing_bracket_keeps_the_bracket():
    assert str(prose_latex("at every model (X = P^-1)")) == "at every model (X = $P^{-1}$)"
    assert "$X^{-1}$" in str(prose_latex("X^(-1) here"))
