"""Screenshots of the built HTML docs in a real (headless) browser, and the rendered DOM.

Usage::

    python scripts/docs_screenshots.py [HTML_DIR] [-o OUT_DIR]

``HTML_DIR`` is a built site (default ``docs/_build/html``, written by ``make docs``); the PNGs
and the rendered DOMs (``<page>.html``, after the page's JavaScript ran: the search page fills
its results in the browser) go to ``OUT_DIR`` (default ``docs/_build/screenshots``). Four pages:
the front page, a method page (``lmi_placement``), the curated API reference and the search
results for "observer". Look at the PNGs; tests/test_docs_browser.py checks the DOMs.

The browser is Chromium (``chromium``, ``chromium-browser``, ``google-chrome``; or the path in
``TANKSYNTH_BROWSER``); on Debian ``apt-get install chromium``. Without one the script prints
a line saying so and exits 0 (nothing checked); an HTML_DIR without ``index.html`` is exit 2.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path

__all__ = ["PAGES", "find_browser", "render", "shoot", "main"]

ROOT = Path(__file__).resolve().parents[1]

#: name -> (page relative to the site, query string): the pages a new user opens first.
PAGES: dict[str, tuple[str, str]] = {
    "index": ("index.html", ""),
    "method": ("_generated/methods/lmi_placement.html", ""),
    "api": ("_generated/api_reference.html", ""),
    "search": ("search.html", "?q=observer"),
}

_BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_browser() -> str | None:
    """The headless-capable browser to use, or None when there is none.

    Returns
    -------
    str or None
        ``TANKSYNTH_BROWSER`` when set, else the first of Chromium's usual names on ``PATH``.
    """
    named = os.environ.get("TANKSYNTH_BROWSER")
    if named:
        return named
    return next((path for path in map(shutil.which, _BROWSERS) if path), None)


def _command(browser: str, *args: str) -> list[str]:
    # --no-sandbox: Chromium refuses to run as root with its sandbox (containers, CI); the pages
    # are our own files. The virtual time budget lets the search page's script finish.
    return [browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
            "--window-size=1280,1600", "--virtual-time-budget=15000", *args]


def render(browser: str, url: str, timeout: float = 120.0) -> str:
    """The DOM of ``url`` after its scripts ran (``--dump-dom``).

    Parameters
    ----------
    browser : str
        The browser executable (`find_browser`).
    url : str
        A ``file://`` URL, query string included.
    timeout : float
        Seconds to wait for the browser (s).

    Returns
    -------
    str
        The serialised DOM.
    """
    proc = subprocess.run(_command(browser, "--dump-dom", url), capture_output=True, text=True,
                          timeout=timeout, check=True)
    return proc.stdout


def shoot(browser: str, url: str, png: Path, timeout: float = 120.0) -> None:
    """A 1280 x 1600 screenshot of ``url`` into ``png``.

    Parameters
    ----------
    browser : str
        The browser executable (`find_browser`).
    url : str
        A ``file://`` URL, query string included.
    png : Path
        The PNG written.
    timeout : float
        Seconds to wait for the browser (s).
    """
    subprocess.run(_command(browser, f"--screenshot={png}", url), capture_output=True, text=True,
                   timeout=timeout, check=True)


def main(argv: list[str] | None = None) -> int:
    """Screenshot and render `PAGES` of a built site.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        0 done (or no browser), 2 no built site.
    """
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("html", nargs="?", default=str(ROOT / "docs" / "_build" / "html"))
    parser.add_argument("-o", "--out", default=str(ROOT / "docs" / "_build" / "screenshots"))
    args = parser.parse_args(argv)
    html, out = Path(args.html).resolve(), Path(args.out)
    if not (html / "index.html").is_file():
        sys.stderr.write(f"{html}: no index.html: build the docs first (make docs)\n")
        return 2
    browser = find_browser()
    if browser is None:
        sys.stdout.write("no headless browser found (chromium, google-chrome; or set TANKSYNTH_BROWSER):"
                         " no screenshots taken (Debian: apt-get install chromium)\n")
        return 0
    out.mkdir(parents=True, exist_ok=True)
    for name, (page, query) in PAGES.items():
        url = (html / page).as_uri() + query
        shoot(browser, url, out / f"{name}.png")
        (out / f"{name}.html").write_text(render(browser, url), encoding="utf-8")
        sys.stdout.write(f"{name}: {out / (name + '.png')}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
