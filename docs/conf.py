"""Sphinx configuration of the tanksynth documentation (``make docs``).

The method and plant pages are generated from the method table and the plant
builders (`tanksynth.docgen.write_pages`) into ``_generated/``, and the
notebooks are copied there, at every build: nothing generated is committed.
Notebooks are executed at build (``nb_execution_mode = "force"``); the test
suite builds with ``-D nb_execution_mode=off`` to stay fast.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

from tanksynth import __version__  # noqa: E402
from tanksynth.docgen import write_pages  # noqa: E402

GENERATED = HERE / "_generated"
write_pages(GENERATED)
(GENERATED / "notebooks").mkdir(parents=True, exist_ok=True)
for nb in sorted((ROOT / "notebooks").glob("*.ipynb")):
    target = GENERATED / "notebooks" / nb.name
    if not target.is_file() or target.read_bytes() != nb.read_bytes():
        shutil.copyfile(nb, target)

project = "tanksynth"
author = "tanksynth contributors"
release = version = __version__
extensions = ["myst_nb", "sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.mathjax"]
source_suffix = {".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "**.ipynb_checkpoints"]
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3
# "more than one target found": words of a numpydoc type ("shape (n, n)") become
# cross-references, and many classes have an attribute ``n``: not an error of the docs.
suppress_warnings = ["myst.header", "ref.python"]

# straight quotes: the option types and defaults are TOML ("auto"), to be copied as they are
smartquotes = False

napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_use_ivar = True
autodoc_typehints = "none"
autodoc_member_order = "bysource"
# Each object is documented once, in the module that defines it (a package's re-exports are
# not repeated): members by definition, not by ``__all__``.
autodoc_default_options = {"members": True, "ignore-module-all": True}

nb_execution_mode = "force"
nb_execution_timeout = 900
nb_execution_raise_on_error = True
nb_execution_in_temp = True

# pydata-sphinx-theme (the docs extra): navigation bar of the top-level pages, a sidebar of the
# section, an "on this page" outline; no icon links or version switcher (nothing to fetch).
html_theme = "pydata_sphinx_theme"
html_title = f"tanksynth {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    # one row of links beside the search button at 1280 px (eight wrapped to two rows)
    "header_links_before_dropdown": 4,
    # the method and plant pages have two or three headings: their option tables (five columns)
    # get the outline's width instead (with it the "meaning" column was cut off at 1280 px)
    # (the patterns do not overlap: "*" does not cross a "/", and the theme warns on two matches)
    "secondary_sidebar_items": {"*": ["page-toc"], "_generated/*": ["page-toc"],
                                "_generated/api/*": ["page-toc"], "_generated/notebooks/*": ["page-toc"],
                                "_generated/methods/*": [], "_generated/plants/*": []},
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
# no empty "Section Navigation" column beside the pages that have no sub-pages
html_sidebars = {page: [] for page in ("index", "quickstart", "artefacts", "export", "python_api",
                                       "notebooks", "developers", "_generated/api_reference")}
html_static_path = ["_static"]
# the user's pages rank above the developers' module reference in the search results
html_search_scorer = str(HERE / "search_scorer.js")
html_css_files = ["tanksynth.css"]


def _api_pages() -> None:
    """The developers' module reference: one page per module of the package (autodoc), and
    its index. Users read the curated page of ``tanksynth.__all__`` (``api_reference.md``,
    written by `tanksynth.docgen.write_pages`)."""
    import pkgutil

    import tanksynth

    # private modules (a ``_``-prefixed part: tanksynth._lazy, __main__) are not API
    names = sorted(m.name for m in pkgutil.walk_packages(tanksynth.__path__, "tanksynth.")
                   if not any(part.startswith("_") for part in m.name.split(".")))
    api = GENERATED / "api"
    api.mkdir(parents=True, exist_ok=True)
    for stale in api.glob("*.md"):  # a page of a module gone (or now private) from an older build
        if stale.stem not in ("index", "tanksynth", *names):
            stale.unlink()
    # a module that is also a public name (the package; tanksynth.design, callable) is described
    # on the API page: its module page must not index the same object twice
    api_names = {"tanksynth", *(f"tanksynth.{n}" for n in tanksynth.__all__)}
    for name in ["tanksynth", *names]:
        text = (f"# `{name}`\n\n```{{eval-rst}}\n.. automodule:: {name}\n"
                + ("   :no-index:\n" if name in api_names else "") + "```\n")
        page = api / f"{name}.md"
        if not page.is_file() or page.read_text(encoding="utf-8") != text:
            page.write_text(text, encoding="utf-8")
    index = ("# Module reference (developers)\n\nEvery module of the package, internals included, "
             "from its numpydoc docstrings: for work on tanksynth itself. The public interface is "
             "the {doc}`API reference </_generated/api_reference>` (`tanksynth.__all__`: "
             "`tanksynth.load`, `tanksynth.load_spec`, ...).\n\n```{toctree}\n:maxdepth: 1\n\n"
             + "\n".join(["tanksynth", *names]) + "\n```\n")
    if not (api / "index.md").is_file() or (api / "index.md").read_text(encoding="utf-8") != index:
        (api / "index.md").write_text(index, encoding="utf-8")


_api_pages()


# -- known warnings -------------------------------------------------------------------------------
KNOWN_WARNINGS = [line.strip() for line in (HERE / "known_warnings.txt").read_text(encoding="utf-8")
                  .splitlines() if line.strip() and not line.startswith("#")]
_seen_known: set[str] = set()


class _KnownWarnings:
    """A logging filter dropping the warnings of ``known_warnings.txt`` (and noting them)."""

    def filter(self, record) -> bool:
        import re

        text = record.getMessage()
        location = getattr(record, "location", None)
        if location is not None and not isinstance(location, str):
            from sphinx.util.logging import get_node_location

            location = get_node_location(location)
        full = f"{location or ''}: {text}"
        for known in KNOWN_WARNINGS:
            parts = re.split(r": (?:ERROR|WARNING|CRITICAL): ", known, maxsplit=1)
            where, message = parts if len(parts) == 2 else ("", known)
            if message in text and where in full:
                _seen_known.add(known)
                return False
        return True


def _write_seen(app, exception) -> None:
    """Note the known warnings met next to the html directory (not inside the published site)."""
    (Path(app.outdir) / "known_warnings_seen.txt").unlink(missing_ok=True)  # left by older builds
    (Path(app.outdir).parent / "known_warnings_seen.txt").write_text(
        "".join(f"{k}\n" for k in sorted(_seen_known)), encoding="utf-8")


def setup(app):
    import logging

    for handler in logging.getLogger("sphinx").handlers:
        handler.filters.insert(0, _KnownWarnings())
    app.connect("build-finished", _write_seen)
