"""The Sphinx documentation builds with no warning (``make docs``), and has the pages a user
expects: the quick start, one page per plant family and per method (a TOML and a Python example
each, option types in TOML words), the gain-name table, the exports with their C driver, the
Python API, the curated API reference of ``tanksynth.__all__`` (the modules in the developers'
section, not on the front page) and the notebooks, in pydata-sphinx-theme.

The test builds without executing the notebooks (``-D nb_execution_mode=off``, they run in
tests/test_notebooks.py); ``make docs`` executes them. Warnings are errors (``-W``), except
the known docstring problems of ``docs/known_warnings.txt`` that docs/conf.py lets through (a
list that may only shrink: an entry no warning matches fails here).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from html import unescape
from pathlib import Path

import pytest

import tanksynth
from tanksynth.analysis.statespace import GAIN_NAMES
from tanksynth.methods import TABLE
from tanksynth.plants import BUILTIN_PLANTS

ROOT = Path(__file__).resolve().parents[1]
KNOWN = ROOT / "docs" / "known_warnings.txt"

# sphinx and myst-nb are in the dev extra (`make test` installs them): missing is a failure
import myst_nb  # noqa: E402,F401
import sphinx  # noqa: E402,F401


pytestmark = pytest.mark.slow   # the Sphinx build with the notebooks executed


def _known() -> list[str]:
    return [line.strip() for line in KNOWN.read_text(encoding="utf-8").splitlines()
            if line.strip() and not line.startswith("#")]


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> tuple[Path, list[str]]:
    out = tmp_path_factory.mktemp("docs")
    log = out / "warnings.log"
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-b", "html", "-q", "-E",
                           "-D", "nb_execution_mode=off", "-w", str(log), str(ROOT / "docs"),
                           str(out / "html")], capture_output=True, text=True, env=env, timeout=900)
    warnings = log.read_text(encoding="utf-8") if log.is_file() else ""
    assert proc.returncode == 0, "Sphinx warnings are errors:\n" + warnings + proc.stderr[-3000:]
    assert not (out / "html" / "known_warnings_seen.txt").exists()  # not published with the site
    seen = (out / "known_warnings_seen.txt").read_text(encoding="utf-8").splitlines()
    return out / "html", seen


def test_docs_build_without_warnings(built):
    _, seen = built
    stale = [k for k in _known() if k not in seen]
    assert not stale, f"fixed: remove from {KNOWN.name}:\n" + "\n".join(stale)


def _text(path: Path) -> str:
    """The page's text without tags (code is split into spans by the highlighter)."""
    return unescape(" ".join(re.sub(r"<[^>]+>", " ", path.read_text(encoding="utf-8")).split()))


def test_docs_have_the_expected_pages(built):
    html, _ = built
    quick = _text(html / "quickstart.html")
    assert "make demo" in quick and "tanksynth methods" in quick
    for row in TABLE:
        page = (html / "_generated" / "methods" / f"{row.name}.html").read_text(encoding="utf-8")
        for name in row.options.option_names():
            assert name in page, (row.name, name)
    assert "(state units)^2" in _text(html / "_generated" / "methods" / "ekf.html")
    for name in [*BUILTIN_PLANTS, "custom"]:
        assert (html / "_generated" / "plants" / f"{name}.html").is_file()
    assert "parameter_set" in _text(html / "_generated" / "plants" / "tank_network.html")
    api_index = _text(html / "_generated" / "api" / "index.html")
    assert "tanksynth.loading" in api_index and "_lazy" not in api_index
    assert not (html / "_generated" / "api" / "tanksynth._lazy.html").exists()
    loading = _text(html / "_generated" / "api" / "tanksynth.loading.html")
    assert "to_statespace" in loading and "python-control" in loading
    notebooks = sorted(p.stem for p in (ROOT / "notebooks").glob("*.ipynb"))
    for nb in notebooks:
        assert (html / "_generated" / "notebooks" / f"{nb}.html").is_file(), nb


def test_docs_have_the_user_pages_of_the_readme(built):
    """Gain-name table, exports with the C driver, the Python API: in the HTML docs."""
    html, _ = built
    artefacts = _text(html / "artefacts.html")
    for names in GAIN_NAMES:
        for name in names:
            assert name in artefacts, name
    export = _text(html / "export.html")
    for needle in ("units.A", "x0", "--export law", "#include", "obs_pp_law.h", "-Werror",
                   "_sparsity_in"):
        assert needle in export, needle
    python_api = _text(html / "python_api.html")
    assert "tanksynth.load" in python_api and "to_statespace" in python_api


def test_method_pages_have_examples_and_toml_types(built):
    html, _ = built
    for row in TABLE:
        page = _text(html / "_generated" / "methods" / f"{row.name}.html")
        assert "TOML example" in page and "[[design]]" in page and f'method = "{row.name}"' in page
        assert "Python example" in page and "import tanksynth" in page
        assert re.search(r"tanksynth \. design \(|load_spec", page), row.name   # the public API, or the spec file
        assert "tuple of" not in page and "ndarray" not in page, row.name
    assert "array of tables" in _text(html / "_generated" / "methods" / "lmi_placement.html")


def test_api_reference_is_the_public_names(built):
    """The curated page documents exactly ``tanksynth.__all__``; the ~180 modules are in the
    developers' section, not listed on the front page."""
    html, _ = built
    page = (html / "_generated" / "api_reference.html").read_text(encoding="utf-8")
    documented = set(re.findall(r'<dt class="[^"]*" id="tanksynth\.(\w+)">', page))
    assert documented == {n for n in tanksynth.__all__ if n != "__version__"}
    front = (html / "index.html").read_text(encoding="utf-8")
    assert "_generated/api_reference.html" in front and "developers.html" in front
    assert not re.search(r'href="_generated/api/tanksynth\.', front)


def test_docs_use_the_pydata_theme(built):
    html, _ = built
    front = (html / "index.html").read_text(encoding="utf-8")
    assert "pydata-sphinx-theme" in front and "alabaster" not in front


# -- the rendered pages, in a real browser (scripts/docs_screenshots.py) ---------------------------

def _screenshots_module():
    import importlib.util

    spec = importlib.util.spec_from_file_location("docs_screenshots", ROOT / "scripts" / "docs_screenshots.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def rendered(built, tmp_path_factory) -> dict[str, str]:
    """The DOM of each page of `PAGES` after its scripts ran, and the screenshots beside them."""
    shots = _screenshots_module()
    if shots.find_browser() is None:
        pytest.skip("no headless browser (chromium): the rendered pages are not checked "
                    "(Debian: apt-get install chromium)")
    html, _ = built
    out = tmp_path_factory.mktemp("screenshots")
    proc = subprocess.run([sys.executable, str(ROOT / "scripts" / "docs_screenshots.py"), str(html),
                           "-o", str(out)], capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    for name in shots.PAGES:
        png = (out / f"{name}.png").read_bytes()
        assert png.startswith(b"\x89PNG") and len(png) > 20_000, name   # a page, not a blank
    return {name: (out / f"{name}.html").read_text(encoding="utf-8") for name in shots.PAGES}


def _visible_text(dom: str) -> str:
    dom = re.sub(r"<(script|style)\b.*?</\1>", " ", dom, flags=re.S)
    return unescape(" ".join(re.sub(r"<[^>]+>", " ", dom).split()))


#: MyST or reST markup that did not render (a role, a directive fence, a link target).
RAW_MARKUP = re.compile(r"\{(doc|py:\w+|ref|eval-rst|toctree)\}|```|:py:obj:|\]\([\w/]+\.md\)")


def test_rendered_pages_have_navigation_and_no_raw_markup(rendered):
    for name, dom in rendered.items():
        assert 'class="bd-header' in dom and "bd-search" in dom, name            # top bar, search
        assert not RAW_MARKUP.search(_visible_text(dom)), (name, RAW_MARKUP.search(_visible_text(dom)))
    # the front page links every user page from its navigation bar
    header = rendered["index"].split('class="bd-header', 1)[1].split("</header>", 1)[0]
    for page in ("quickstart.html", "_generated/methods/index.html", "_generated/plants/index.html",
                 "python_api.html", "_generated/api_reference.html"):
        assert page in header, page
    # a method page: the sidebar lists every method, the option table has its five columns
    method = rendered["method"]
    sidebar = method.split('class="bd-sidebar-primary', 1)[1].split("</div>\n  </div>", 1)[0]
    for row in TABLE:   # the page itself is linked as "#"
        assert f'href="{row.name}.html"' in sidebar or row.name == "lmi_placement", row.name
    assert "lmi_placement" in sidebar
    assert all(f">{column}</p></th>" in method or f">{column}</th>" in method
               for column in ("option", "type", "default", "unit", "meaning"))
    assert 'id="tanksynth.load"' in rendered["api"] and 'id="tanksynth.design"' in rendered["api"]


def test_rendered_search_finds_the_user_pages_first(rendered):
    """The search page fills its results in the browser: "observer" finds pages, the method
    pages rank before the ~200 module pages of the developers' reference."""
    results = rendered["search"].split('id="search-results"', 1)[1]
    links = re.findall(r'<li[^>]*>\s*<a[^>]*href="([^"]+)"', results)
    assert len(links) >= 10, links
    first = [link.split("?")[0].split("#")[0] for link in links[:10]]
    assert not any(link.startswith("_generated/api/") for link in first), first
    assert "_generated/methods/ts_observer.html" in first, first
