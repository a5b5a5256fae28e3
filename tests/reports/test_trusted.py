"""The math grammar of LaTeX read from a result directory (issue 31 item 9).

What the tool writes parses; edits that break it (a brace dropped, a trailing backslash) or
inject (``\\input``, ``\\write18``, ``\\catcode``, ``^^``) are refused, naming the file and key,
before a report is built; what parses compiles with pdflatex.
"""

from __future__ import annotations

import functools
import json
import random
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from reports_helpers import copy_dir, edit_json, needs_latex
from tanksynth.cli import main
from tanksynth.design.linear_gains import matrix_latex
from tanksynth.errors import ArtefactError
from tanksynth.methods import load_spec, write_report
from tanksynth.plants.parser import parse_expression
from tanksynth.reports.inputs import read_report_inputs
from tanksynth.reports.trusted import is_trusted_math, latex_problem

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
NO_CLOCK = settings(deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                          HealthCheck.function_scoped_fixture])


@functools.cache
def example_equations() -> tuple[str, ...]:
    """The LaTeX of every example's model (plant.json ``equations``), as the tool writes it."""
    out = []
    for spec in sorted(EXAMPLES.glob("*.toml")):
        for lines in load_spec(spec).plant.latex_equations().values():
            out.extend(lines)
    return tuple(out)


def gain_fragments() -> tuple[str, ...]:
    """Gains printed as artefacts print them: numbers of every size, up to 30 columns."""
    rng = np.random.default_rng(3)
    out = []
    for rows, cols in ((1, 1), (3, 1), (1, 4), (3, 3), (5, 12), (2, 30)):
        M = rng.normal(size=(rows, cols)) * 10.0 ** rng.integers(-9, 9, size=(rows, cols))
        M[0, 0] = 0.0
        out.append(matrix_latex(M))
    return tuple(out)


# ------------------------------------------------------------------ what the tool writes
def test_every_example_model_and_gain_parses():
    for fragment in example_equations() + gain_fragments():
        assert latex_problem(fragment) is None, (latex_problem(fragment), fragment[:300])


def test_the_demo_directory_parses(demo_dir):
    inputs = read_report_inputs(demo_dir)         # would raise naming the file and key
    fragments = [v for a in inputs.artefacts for v in (a.get("latex") or {}).values()]
    assert fragments and all(is_trusted_math(v) for v in fragments)


_NAMES = st.from_regex(r"[A-Za-z][A-Za-z0-9_]{0,8}", fullmatch=True).filter(
    lambda n: not n.endswith("_") and "__" not in n
    and not re.search(r"(scr|bm)$", n, re.I))       # sympy's \mathscr, \bm need packages
_ATOMS = st.sampled_from(["h1", "h2", "mu13", "Phi", "A", "q_in", "2", "0.5", "1e-5", "g"])


@st.composite
def expressions(draw, depth: int = 3) -> str:
    """Equation text in the custom-plant grammar (sqrt abs sign exp log min max)."""
    if depth == 0 or draw(st.booleans()):
        return draw(_ATOMS)
    op = draw(st.sampled_from(["+", "-", "*", "/", "**", "sqrt", "abs", "sign", "exp", "log",
                               "min", "max"]))
    a, b = draw(expressions(depth - 1)), draw(expressions(depth - 1))
    if op in ("min", "max"):
        return f"{op}({a}, {b})"
    if op in ("sqrt", "abs", "sign", "exp", "log"):
        return f"{op}({a})"
    if op == "**":
        return f"({a})**{draw(st.integers(2, 4))}"
    return f"({a}) {op} ({b})"


@settings(NO_CLOCK, max_examples=60)
@given(expressions(), _NAMES)
def test_sympy_latex_of_custom_models_parses(text, name):
    try:
        expr = parse_expression(text, {s: sp.Symbol(s, positive=True) for s in
                                       ("h1", "h2", "mu13", "Phi", "A", "q_in", "g")})
    except Exception:  # noqa: BLE001 - text the parser refuses never reaches a report
        return
    fragment = rf"\dot{{{sp.latex(sp.Symbol(name))}}} = {sp.latex(expr)}"
    assert latex_problem(fragment) is None, (latex_problem(fragment), fragment)


def test_a_custom_model_with_script_suffixed_names_parses(tmp_path):
    """A state or parameter named ``...scr`` (sympy: \\mathscr, a package the reports do not
    load) is typeset in a face the reports have, so a valid spec still gets its report."""
    text = (EXAMPLES / "custom_two_tank.toml").read_text()
    text = re.sub(r"\bh1\b", "hscr", text).replace("a1", "ascr")
    spec = tmp_path / "scr.toml"
    spec.write_text(text)
    fragments = [f for lines in load_spec(spec).plant.latex_equations().values() for f in lines]
    assert any(r"\mathcal{h}" in f for f in fragments) and any(r"\mathcal{a}" in f for f in fragments)
    for fragment in fragments:
        assert latex_problem(fragment) is None, (latex_problem(fragment), fragment)


# ------------------------------------------------------------------ edits are refused
INJECTIONS = [r"\input{/etc/passwd}", r"\write18{ls}", r"\immediate\write18{ls}", r"\catcode`\^=7",
              "^^5cinput{x}", "^^", r"\csname input\endcsname", r"\def\x{y}", r"\openin1=x",
              r"\read16 to \x", r"\begin{verbatim}", "%", "#1", "~"]


@st.composite
def mutations(draw) -> tuple[str, str]:
    fragment = draw(st.sampled_from(example_equations() + gain_fragments()))
    kind = draw(st.sampled_from(["drop_brace", "trailing_backslash", "insert"]))
    if kind == "trailing_backslash":
        return fragment + "\\", kind
    if kind == "drop_brace":
        braces = [i for i, c in enumerate(fragment) if c in "{}" and fragment[i - 1] != "\\"]
        i = draw(st.sampled_from(braces))
        return fragment[:i] + fragment[i + 1:], kind
    # anywhere but right after a backslash (which would make it another control sequence)
    spots = [i for i in range(len(fragment) + 1) if i == 0 or fragment[i - 1] != "\\"]
    i = draw(st.sampled_from(spots))
    return fragment[:i] + draw(st.sampled_from(INJECTIONS)) + fragment[i:], kind


@settings(NO_CLOCK, max_examples=250)
@given(mutations())
def test_broken_or_injected_latex_is_refused(mutated):
    fragment, kind = mutated
    assert latex_problem(fragment) is not None, (kind, fragment)


_SOUP = ["x", "2", "+", "=", "(", ")", " ", "{", "}", "^", "_", "'", "[", "]", "&", "$", "\\",
         "\\\\", "\\frac", "\\sqrt", "\\left(", "\\right)", "\\left.", "\\right|", "\\alpha",
         "\\cdot", "\\,", "\\{", "\\}", "\\max", "\\dot", "\\mathrm", "\\operatorname",
         "\\begin{matrix}", "\\end{matrix}", "\\begin{cases}", "\\end{cases}", "\\text{", "\\left",
         "\\input", "^^", "%", "\\catcode", "\\end{document}", "\\begin{tabular}{l|r}",
         "\\end{tabular}", "\\hline", "a-b"]


@settings(NO_CLOCK, max_examples=800)
@given(st.lists(st.sampled_from(_SOUP), max_size=16).map("".join))
def test_what_parses_is_balanced_and_closed(fragment):
    """Independent of the parser: an accepted fragment has balanced braces (escapes aside),
    paired \\left/\\right and $, no trailing backslash and nothing of the injection list."""
    if not is_trusted_math(fragment):
        return
    plain = re.sub(r"\\[^A-Za-z]", "", fragment)        # escapes, spacing, \\ rows
    depth = 0
    for ch in plain:
        depth += (ch == "{") - (ch == "}")
        assert depth >= 0, fragment
    assert depth == 0, fragment
    assert not plain.endswith("\\"), fragment
    assert len(re.findall(r"\\left(?![a-z])", plain)) == len(re.findall(r"\\right(?![a-z])", plain))
    assert plain.count("$") % 2 == 0, fragment
    assert not re.search(r"\\input|\\catcode|\^\^|%|\\end\{document\}", plain), fragment


def test_limits_of_length_and_nesting(tmp_path):
    from tanksynth.reports.trusted import check_result_latex

    assert latex_problem("{" * 150 + "x" + "}" * 150) is not None
    assert latex_problem("{" * 50 + "x" + "}" * 50) is None
    assert latex_problem("x" * 2_000_000) is not None
    # four styles per \text, \boldsymbol, \sqrt[n]: pdflatex's work grows 4x per level
    assert latex_problem(r"\text{$" * 4 + "x" + "$}" * 4) is None
    assert latex_problem(r"\boldsymbol{" * 5 + "x" + "}" * 5) is not None
    assert latex_problem(r"\sqrt[3]{" * 4 + "x+y " * 500 + "}" * 4) is not None
    many = [{"_file": f"a{i}.json", "latex": {"F": "x+y " * 4000}} for i in range(20)]
    with pytest.raises(ArtefactError, match=r"a12\.json: key 'latex\.F': .*characters of LaTeX"):
        check_result_latex(tmp_path, {}, many, None)


@pytest.mark.parametrize("where", ["plant", "artefact", "checks"])
@pytest.mark.parametrize("bad", [r"\frac{1}{", "x + 1\\", r"\left( x", r"\input{/etc/passwd}"])
def test_a_directory_with_broken_latex_is_refused_naming_file_and_key(demo_dir, tmp_path, capsys,
                                                                       where, bad):
    from tanksynth.artefacts.io import rehash

    d = copy_dir(demo_dir, tmp_path / "edited")
    if where == "plant":
        plant = json.loads((d / "plant.json").read_text(encoding="utf-8"))
        plant["equations"]["smooth"][1] = bad
        (d / "plant.json").write_text(json.dumps(plant), encoding="utf-8")
        for art in d.glob("*.json"):              # the plant record's digest, consistently
            if art.name not in ("plant.json", "checks.json"):
                rehash(art)
        file, key = "plant.json", "equations.smooth[1]"
    elif where == "artefact":
        art = json.loads((d / "linear_model.json").read_text(encoding="utf-8"))
        edit_json(d / "linear_model.json", latex={**art["latex"], "F": bad})
        file, key = "linear_model.json", "latex.F"
    else:
        checks = json.loads((d / "checks.json").read_text(encoding="utf-8"))
        checks[0].setdefault("data", {})["determinant_latex"] = bad
        (d / "checks.json").write_text(json.dumps(checks), encoding="utf-8")
        file, key = "checks.json", "[0].data.determinant_latex"
    before = sorted(p.name for p in d.iterdir())
    with pytest.raises(ArtefactError, match=re.escape(f"{d / file}: key '{key}': LaTeX refused")):
        write_report(d, pdf=False)
    assert main(["report", str(d)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and str(d / file) in err and f"key '{key}'" in err, err
    assert sorted(p.name for p in d.iterdir()) == before      # nothing written


# ------------------------------------------------------------------ what parses compiles
PREAMBLE = r"""\documentclass{article}
\usepackage{amsmath,amssymb}
\setcounter{MaxMatrixCols}{24}
\newsavebox{\tsbox}
\newcommand{\tsfit}[1]{\sbox{\tsbox}{$\displaystyle #1$}\usebox{\tsbox}}
\newcommand{\tsdisplay}[1]{\par\noindent\tsfit{#1}\par}
\begin{document}
"""


def soup_samples(count: int, seed: int = 0) -> list[str]:
    """Random token soups the grammar accepts (a few in a hundred are)."""
    rng = random.Random(seed)
    found: list[str] = []
    for _ in range(400_000):
        fragment = "".join(rng.choice(_SOUP) for _ in range(rng.randint(3, 14)))
        if fragment.strip() and fragment not in found and is_trusted_math(fragment):
            found.append(fragment)
            if len(found) == count:
                break
    return found


def compile_fragments(fragments: list[str], directory: Path) -> tuple[int, str]:
    body = "".join(rf"\tsdisplay{{F = {f}}}" "\n" rf"\tsdisplay{{\begin{{aligned}}F &= {f}\end{{aligned}}}}"
                   "\n" for f in fragments)
    (directory / "t.tex").write_text(PREAMBLE + body + "\\end{document}\n", encoding="utf-8")
    proc = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error",
                           "-no-shell-escape", "t.tex"], cwd=directory, capture_output=True,
                          timeout=300)
    log = (directory / "t.log").read_text(encoding="latin-1") if (directory / "t.log").exists() else ""
    return proc.returncode, log


#: Examples whose designs write LaTeX of every kind: matrices, Lie derivatives, cost tables.
DESIGNED = ("seed003_tank_network", "seed000_feedback_linearization", "hybrid_three_tank")


@pytest.mark.slow
@needs_latex
def test_what_parses_compiles(tmp_path):
    """Every fragment designs of `DESIGNED` write parses; they, a sample of the examples'
    equations, gains and random accepted token soups compile."""
    written = []
    for name in DESIGNED:
        out = tmp_path / name
        assert main(["design", str(EXAMPLES / f"{name}.toml"), "-o", str(out)]) == 0
        for path in sorted(out.glob("*.json")):
            doc = json.loads(path.read_text(encoding="utf-8"))
            written += [v for v in (doc.get("latex") or {}).values()] if isinstance(doc, dict) else []
    assert any("tabular" in f for f in written)
    for fragment in written:
        assert latex_problem(fragment) is None, (latex_problem(fragment), fragment[:300])
    samples = (written[::3] + list(example_equations()[::9]) + list(gain_fragments())
               + soup_samples(40))
    code, log = compile_fragments(samples, tmp_path)
    if code != 0 or re.search(r"^! ", log, re.M):
        culprits = [f for f in samples if compile_fragments([f], tmp_path)[0] != 0]
        pytest.fail(f"accepted but does not compile: {culprits[:5]}")
