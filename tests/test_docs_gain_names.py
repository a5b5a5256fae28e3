"""Issue 30 items 6 and 12: the table of gain names is in the documentation source (the artefacts
page and the gain-name page),
generated from the same table (`tanksynth.analysis.statespace.GAIN_NAMES`) and kept current."""

from __future__ import annotations

from pathlib import Path

from tanksynth import docgen

ROOT = Path(__file__).resolve().parents[1]


def test_the_docs_gain_name_page_is_current_and_is_the_artefacts_pages_table():
    page = ROOT / "docs" / "gain_names.md"
    assert "docs/gain_names.md" in docgen.DOC_PAGES
    assert docgen.update_readme(page, check=True, sections=docgen.DOC_PAGES["docs/gain_names.md"]) == []
    text = page.read_text(encoding="utf-8")
    artefacts = (ROOT / "docs" / "artefacts.md").read_text(encoding="utf-8")
    table = docgen.generated_section(text, "gain_names")
    assert table == docgen.generated_section(artefacts, "gain_names")
    for row in ("| `K` |", "| `L` |", "| `x_op`, `u_op` |", "| `F`, `B`, `C`, `Bw` |"):
        assert row in table


def test_docgen_rewrites_a_stale_page(tmp_path):
    page = tmp_path / "gain_names.md"
    text = (ROOT / "docs" / "gain_names.md").read_text(encoding="utf-8")
    page.write_text(text.replace("| `K` |", "| `gain` |"), encoding="utf-8")
    assert docgen.update_readme(page, sections=("gain_names",)) == ["gain_names"]
    assert page.read_text(encoding="utf-8") == text
