"""What a reviewer reads: the example reports' PDFs as text (pdftotext).

No Python/numpy text or ASCII operators in the body, every figure inside the
section it belongs to, the spec appendix copied out of the PDF is the spec
again (TOML), a user's own plant has no paper-vs-tool section, a refused
design is in the body with its reason.
"""

from __future__ import annotations

import re
import subprocess
import textwrap
import tomllib
from pathlib import Path

import pytest

from reports_helpers import needs_latex
from tanksynth.cli import main

pytestmark = [needs_latex, pytest.mark.slow]   # real pdflatex builds of several examples

#: Python/numpy reprs and ASCII operators that must not reach the body of a report.
FORBIDDEN = {
    "nested list": re.compile(r"\[\["),
    "list of str": re.compile(r"\['"),
    "complex repr": re.compile(r"\dj[,\]]"),
    "numpy repr": re.compile(r"array\("),
    "ASCII <=": re.compile(r"<="),
    "ASCII >=": re.compile(r">="),
    "lambda_max": re.compile(r"lambda_?max"),
    "|.|_inf": re.compile(r"\|_inf"),
    "caret power": re.compile(r"\w\s*[\^ˆ]\s*-?\d"),
    "fixed-point numpy": re.compile(r"\d\.\s+,"),
}


def pdf_text(pdf: Path, *args: str) -> str:
    return subprocess.run(["pdftotext", *args, str(pdf), "-"], check=True, capture_output=True,
                          text=True).stdout


def body(text: str) -> str:
    """The report without its spec appendix (which is the spec, verbatim)."""
    heads = list(re.finditer(r"^\f?A\s+Spec\s*$", text, flags=re.M))   # \f: the appendix may open a page
    assert heads, "no spec appendix heading"
    return text[:heads[-1].start()]


def test_no_python_text_in_the_body(example_pdfs):
    for name, d in example_pdfs.items():
        text = body(pdf_text(d / "report.pdf", "-layout"))
        for what, pattern in FORBIDDEN.items():
            hits = [text[max(0, m.start() - 40):m.end() + 40] for m in pattern.finditer(text)]
            assert not hits, f"{name}: {what} in the report body: {hits[:3]}"
        assert "Other diagnostics" not in text
        assert "no problem statement" not in text


def _squash(s: str) -> str:
    return re.sub(r"[\s_]+", "", s)


def test_figures_stay_in_their_sections(example_pdfs):
    """Each figure's caption names its design; the last heading before the caption (in reading
    order) must be that design's subsection, and it must come before the next section."""
    heading = re.compile(r"^\s{0,3}(\d+(?:\.\d+)?)\s{2,}(\S.*)$", re.M)   # "4.1     name (method)"
    caption = re.compile(r"Figure (\d+): .*?design (.+?) \(", re.S)
    seen = 0
    for name, d in example_pdfs.items():
        text = body(pdf_text(d / "report.pdf", "-layout"))
        text = text[re.search(r"^1\s{2,}Plant\s*$", text, flags=re.M).start():]   # after the contents
        heads = [(m.start(), m.group(1), m.group(2)) for m in heading.finditer(text)]
        for m in caption.finditer(text):
            design = _squash(m.group(2))
            before = [h for h in heads if h[0] < m.start()]
            assert before, f"{name}: figure {m.group(1)} before any heading"
            _, number, title = before[-1]
            assert "." in number and design in _squash(title), (
                f"{name}: figure {m.group(1)} of design {m.group(2)} is under heading "
                f"'{number} {title}', not under that design's subsection")
            seen += 1
    assert seen >= 6  # pole maps and time-domain figures of the three examples


def test_spec_appendix_copies_back_to_the_spec(example_pdfs):
    for name, d in example_pdfs.items():
        # the typewriter pitch, measured on a table header of the spec ("[plant]") in the PDF
        box = re.search(r'xMin="([\d.]+)"[^>]*xMax="([\d.]+)"[^>]*>(\[[a-z_.]+\])</word>',
                        pdf_text(d / "report.pdf", "-bbox"))
        pitch = (float(box.group(2)) - float(box.group(1))) / len(box.group(3))
        text = pdf_text(d / "report.pdf", "-layout", "-fixed", f"{pitch:.4f}")
        start = text.index("the TOML file again.")
        lines = text[start:].split("\n")[1:]
        kept = [ln for ln in lines if not re.fullmatch(r"\s*\d+\s*", ln.replace("\f", ""))]
        copied = textwrap.dedent("\n".join(ln.replace("\f", "") for ln in kept))
        spec = (d / "spec.toml").read_text(encoding="utf-8")
        assert tomllib.loads(copied) == tomllib.loads(spec), name
        # comments and quotes survive too (straight quotes, carets)
        assert '"' in copied and "''" not in copied


def test_custom_plant_has_no_paper_section(example_pdfs):
    text = pdf_text(example_pdfs["custom_two_tank"] / "report.pdf")
    assert "Paper vs tool" not in text and "paper vs tool" not in text
    seed = pdf_text(example_pdfs["seed000_pole_placement"] / "report.pdf")
    assert "Paper vs tool" in seed


def test_measured_states_are_a_vector_not_h1_equals_h1(example_pdfs):
    text = pdf_text(example_pdfs["seed000_pole_placement"] / "report.pdf")
    outputs = text[text.index("Outputs:"):text.index("Signals and parameters", text.index("Outputs:"))]
    assert "y =" in outputs
    assert not re.search(r"h\s*1\s*=\s*h\s*1", outputs)


def test_actuator_range_with_its_units(example_pdfs):
    text = pdf_text(example_pdfs["seed000_pole_placement"] / "report.pdf")
    flat = " ".join(text.split())
    # qmax = 1.2e-4 m^3/s: the range is [0, 0.00012], not [[0. , 0.0001]]
    assert re.search(r"q\s*1 in \[0, 0\.00012\] m\s*3\s*/s", flat), flat[flat.find("actuator"):][:300]


def test_refused_design_is_in_the_body(tmp_path):
    spec = tmp_path / "refused.toml"
    spec.write_text(textwrap.dedent("""
        title = "one design refused"
        [plant]
        model = "three_tank"
        [operating_point]
        x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
        [sampling]
        ts = 1.0
        [[design]]
        name = "disk"
        method = "lmi_placement"
        target = "state_feedback"
        region = [{type = "disk", center = 0.0, radius = 0.97}]
        [[design]]
        name = "impossible"
        method = "lmi_placement"
        target = "state_feedback"
        region = [{type = "disk", center = 0.0, radius = 0.999}, {type = "disk", center = -0.5, radius = 0.01}]
        """), encoding="utf-8")
    d = tmp_path / "out"
    assert main(["run", str(spec), "-o", str(d), "--pdf"]) == 3      # infeasible: exit 3
    assert (d / "refused.json").is_file() and not (d / "impossible.json").exists()
    text = " ".join(pdf_text(d / "report.pdf").split())
    assert "impossible (lmi placement): refused" in text.replace("_", " ")
    assert "Refused as infeasible" in text
    # the reason and its certificate (the optimal margin) are in the body, not only in the spec
    body_text = body(pdf_text(d / "report.pdf"))
    assert "largest achievable margin" in " ".join(body_text.split())
    assert "1 refused as infeasible" in text


#: A4 text area of the report (geometry margin 2.2 cm = 62.36 pt): the body lies between these (pt).
_TEXT_TOP, _TEXT_BOTTOM = 62.36, 841.89 - 62.36
_WORD = re.compile(r'<word xMin="[\d.]+" yMin="([\d.]+)" xMax="[\d.]+" yMax="([\d.]+)">([^<]*)</word>')


def _page_fill(pdf: Path, page: int) -> float:
    """Fraction of the text height used on ``page``: lowest word of the body (not the page
    number below it) measured from the top of the text area, over the text height."""
    words = [(float(y0), float(y1)) for y0, y1, _ in
             _WORD.findall(pdf_text(pdf, "-bbox", "-f", str(page), "-l", str(page)))]
    body_words = [y1 for y0, y1 in words if y0 < _TEXT_BOTTOM]
    if not body_words:
        return 0.0
    return (max(body_words) - _TEXT_TOP) / (_TEXT_BOTTOM - _TEXT_TOP)


def _section_pages(pdf: Path, number: str, next_number: str) -> tuple[int, int]:
    """First page of section ``number`` and the page where section ``next_number`` opens."""
    first = last = None
    pages = pdf_text(pdf, "-layout").split("\f")
    for i, text in enumerate(pages, start=1):
        if i > 2 and first is None and re.search(rf"^{number}\s{{2,}}\S", text, flags=re.M):
            first = i   # (page 1-2 hold the contents, which list the headings too)
        if first is not None and re.search(rf"^{next_number}\s{{2,}}\S", text, flags=re.M):
            last = i
            break
    assert first is not None and last is not None, f"no section {number} / {next_number} in {pdf}"
    return first, last


def test_seed004_verification_has_no_half_empty_page(tmp_path):
    """Issue 30.10: with each time-domain figure held at its place ([H]) a figure that did not fit
    after its check table went to the next page and left the page blank below the table (seed
    004: pages filled to 0.52, 0.22 and 0.23 of the text height). The figures float within
    their subsection now (placed before the check table where they fit, set by a float barrier
    at the next subsection otherwise): every page of the verification section but its last is
    filled to more than 0.45 of the text height (0.56 at least: a short table with a figure too
    tall for the rest of its page still ends its page early), and each figure still sits in its
    design's subsection."""
    from tanksynth.cli import main as cli

    d = tmp_path / "s4"
    assert cli(["run", str(Path(__file__).resolve().parents[2] / "examples"
                           / "seed004_fault_detection.toml"), "-o", str(d), "--pdf"]) == 0
    pdf = d / "report.pdf"
    first, after = _section_pages(pdf, "5", "6")
    assert after - first >= 4   # six designs with their check tables and figures
    fills = {p: _page_fill(pdf, p) for p in range(first, after)}
    # the verification's last page may be short; the page where section 6 opens is not its own
    short = {p: round(f, 2) for p, f in fills.items() if p < after - 1 and f < 0.45}
    assert not short, f"verification pages filled to less than 0.45 of the text height: {short}"
    # every figure of the verification after its own subsection heading, before the next one
    text = "\f".join(pdf_text(pdf, "-layout").split("\f")[first - 1:after])
    text = text[:re.search(r"^\f?6\s{2,}\S", text, flags=re.M).start()]
    heads = [(m.start(), _squash(m.group(1))) for m in
             re.finditer(r"^\f?\s{0,3}5\.\d+\s{2,}(\S.*)$", text, flags=re.M)]
    captions = list(re.finditer(r"Figure (\d+): .*?design (.+?) \(", text, flags=re.S))
    assert len(heads) == 6 and len(captions) >= 6
    for m in captions:
        before = [h for h in heads if h[0] < m.start()]
        assert before and _squash(m.group(2)) in before[-1][1], (
            f"figure {m.group(1)} of {m.group(2)} is not under its subsection")
