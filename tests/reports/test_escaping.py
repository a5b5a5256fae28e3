"""User strings are escaped: unit tests, a property test, and a real build with hostile text."""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from reports_helpers import copy_dir, edit_json, needs_latex
from tanksynth.methods import write_report
from tanksynth.reports.latex import escape_latex, format_number, format_unit

HOSTILE = r"Ti_tle 100% & #1 $x$ {a} ~b ^c \input{/etc/passwd} \\ -- <|> `q` \"µ—é☃"


@pytest.mark.parametrize("raw,expected", [
    ("a_b", r"a\_b"), ("50%", r"50\%"), ("a&b", r"a\&b"), ("#", r"\#"), ("$", r"\$"),
    ("{}", r"\{\}"), ("~", r"\textasciitilde{}"), ("^", r"\textasciicircum{}"),
    ("\\", r"\textbackslash{}"), ("a\nb", "a b"), ("--", "-{}-"), ("é", r"\'{e}"),
])
def test_escape_table(raw, expected):
    assert escape_latex(raw) == expected


def test_unknown_unicode_is_named_not_fatal():
    assert escape_latex("☃") == r"\texttt{[U+2603]}"
    assert escape_latex("\x00\x07") == ""


@pytest.mark.slow
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])  # no clock
@given(st.text(max_size=60))
def test_escaped_text_has_no_active_characters(text):
    out = escape_latex(text, breakable=True)
    # every special character is a command argument or follows a backslash
    stripped = re.sub(r"\\[A-Za-z]+\{\}|\\[A-Za-z]+|\\[^A-Za-z]", "", out)
    assert not re.search(r"[%#&$_^~\\]", stripped), out
    depth = 0
    for ch in re.sub(r"\\[{}]", "", out):
        depth += ch == "{"
        depth -= ch == "}"
        assert depth >= 0
    assert depth == 0


def test_numbers_and_units():
    assert format_number(0.0) == "0"
    assert format_number(-0.011369432659021511) == "-0.011369"
    assert format_number(3.501785258978626e-05) == r"3.5018 \times 10^{-5}"
    assert format_number(1e-6) == "10^{-6}"
    assert format_number("inf") == r"\infty"
    assert format_unit("m^3/s") == r"$\mathrm{m}^{3}/\mathrm{s}$"
    assert format_unit("1") == "--"
    assert format_unit("50% & co") == r"50\% \& co"


@pytest.mark.slow
@needs_latex
def test_hostile_strings_compile(demo_dir, tmp_path):
    d = copy_dir(demo_dir, tmp_path / "hostile")
    plant = json.loads((d / "plant.json").read_text(encoding="utf-8"))
    plant["title"] = HOSTILE
    plant["spec_source"] = HOSTILE
    plant["plant"]["description"] = HOSTILE
    plant["plant"]["assumptions"].append({"kind": "odd_kind", "text": HOSTILE, "source": HOSTILE})
    plant["plant"]["parameters"][0]["description"] = HOSTILE
    plant["plant"]["parameters"][0]["unit"] = "m^2 % $"
    (d / "plant.json").write_text(json.dumps(plant), encoding="utf-8")
    art = json.loads((d / "linear_model.json").read_text(encoding="utf-8"))
    art["diagnostics"]["note"] = HOSTILE
    art["diagnostics"][HOSTILE] = HOSTILE
    edit_json(d / "linear_model.json", name="lin_%&#$", diagnostics=art["diagnostics"])
    for ext in (".json", ".npz"):          # an artefact's file is named after it
        (d / f"linear_model{ext}").rename(d / f"lin_%&#${ext}")
    (d / "spec.toml").write_text("title = '" + HOSTILE + "'\n\\end{document}\n", encoding="utf-8")
    res = write_report(d, pdf=True)
    assert res.pdf is not None and res.pdf.exists()
    log = res.log.read_text(encoding="latin-1")
    assert not re.search(r"^! ", log, re.M)
    assert not re.search(r"undefined references|Reference `[^']*' on page \d+ undefined", log)
    text = subprocess.run(["pdftotext", str(res.pdf), "-"], capture_output=True, text=True,
                          check=True).stdout
    for fragment in ("100%", "& #1", "{a}", "input{/etc/passwd}", "[U+2603]"):
        assert fragment in text, fragment


INJECT = r"\input{/etc/passwd}"


def test_trusted_math_allow_list():
    from tanksynth.reports.trusted import is_trusted_math

    assert is_trusted_math(r"\left[\begin{matrix}- \frac{\mu_{13} \Phi}{A} & 0\\0 & \sqrt{h_{2}}\end{matrix}\right]")
    for bad in (INJECT, r"\read16 to \x", r"\catcode`\^=7", "^^5cinput{x}", r"a % comment",
                r"\begin{verbatim}x\end{verbatim}", r"\immediate\write18{ls}", r"\csname input\endcsname"):
        assert not is_trusted_math(bad), bad


@pytest.mark.slow
@needs_latex
def test_no_file_leaks_through_a_report(demo_dir, tmp_path, monkeypatch):
    """LaTeX planted in plant.json's equations and in an artefact's `latex` field is refused,
    naming the file and key, before LaTeX runs; let through anyway, pdflatex cannot read
    absolute paths (openin_any = p): /etc/passwd never reaches the PDF or the log."""
    import tanksynth.reports.trusted as trusted
    from tanksynth.errors import ArtefactError, ReportError

    d = copy_dir(demo_dir, tmp_path / "inject")
    plant = json.loads((d / "plant.json").read_text(encoding="utf-8"))
    plant["equations"]["general"] = [INJECT] + list(plant["equations"]["general"])
    (d / "plant.json").write_text(json.dumps(plant), encoding="utf-8")
    art = json.loads((d / "linear_model.json").read_text(encoding="utf-8"))
    edit_json(d / "linear_model.json", latex={**art["latex"], "F": INJECT})
    tex = (d / "report.tex").read_bytes()
    with pytest.raises(ArtefactError, match=r"plant\.json: key 'equations\.general\[0\]'.*input"):
        write_report(d, pdf=True)
    assert (d / "report.tex").read_bytes() == tex and not (d / "report.pdf").exists()
    monkeypatch.setattr(trusted, "latex_problem", lambda fragment: None)   # the grammar bypassed
    with pytest.raises(ReportError):
        write_report(d, pdf=True)
    secret = Path("/etc/passwd").read_text(encoding="utf-8").splitlines()[0]
    assert secret and not (d / "report.pdf").exists()
    assert secret not in (d / "report.log").read_text(encoding="latin-1")
