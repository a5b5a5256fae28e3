"""Issue 30 item 11: ``tanksynth plants`` is text for a terminal, and the tank_network page (the
docs/plant_families.md and the Sphinx page, both from `tanksynth.docgen.plant_markdown`) lists
parameter values, those of each parameter set included."""

from __future__ import annotations

import re

from click.testing import CliRunner

from tanksynth.cli import cli
from tanksynth.docgen import plant_families, plant_markdown

#: reStructuredText/Markdown markup a terminal shows as it is.
MARKUP = {"RST role": re.compile(r":[a-z]+:`"), "literal": re.compile(r"``"),
          "backticks": re.compile(r"`[^`\n]+`"), "directive": re.compile(r"^\s*\.\. ", re.M),
          "code fence": re.compile(r"^```", re.M), "heading": re.compile(r"^#+ ", re.M)}


def test_plants_prints_no_markup():
    out = CliRunner().invoke(cli, ["plants"], terminal_width=200)
    assert out.exit_code == 0, out.output
    for what, pattern in MARKUP.items():
        hits = pattern.findall(out.output)
        assert not hits, f"{what} in `tanksynth plants`: {hits[:3]}"
    assert "module docstring" not in out.output
    # the Johansson sets' values, which differ from the defaults, are printed (lines wrap)
    flat = " ".join(out.output.split())
    assert re.search(r"johansson_min_phase\W+: .*k2 = 3\.35 cm\^3/\(V s\)", flat)
    assert re.search(r"johansson_nonmin_phase\W+: .*gamma1 = 0\.43.*k1 = 3\.14", flat)


def test_plain_text_removes_roles_literals_and_fences():
    from tanksynth.docgen import plain_text   # new in issue 30

    text = ".. note::\n\n:math:`x_0` and ``N/2`` pumps, `model`\n```toml\na = 1\n```"
    assert plain_text(text) == "\nx_0 and N/2 pumps, model\n    a = 1"


def test_tank_network_page_lists_parameter_values():
    family = next(f for f in plant_families() if f["name"] == "tank_network")
    page = plant_markdown(family)
    assert "module docstring" not in page
    rows = dict(re.findall(r"^\| `(\w+)` \| ([-\d.e]+) \|", page, re.M))
    # Johansson (2000) / DECENTER defaults written independently of the plant module
    expected = {"A1": 28.0, "A2": 32.0, "a1": 0.071, "a2": 0.057, "a3": 0.040, "gamma1": 0.7,
                "gamma2": 0.6, "k1": 3.33, "g": 981.0, "kc": 0.5}
    for name, value in expected.items():
        assert name in rows and abs(float(rows[name]) - value) <= 1e-9 * value, (name, rows.get(name))
    # each parameter set's own values (Johansson 2000, P- and P+)
    assert re.search(r'`parameter_set = "johansson_min_phase"`: .*`k2` = 3\.35', page)
    assert re.search(r'`parameter_set = "johansson_nonmin_phase"`: .*`gamma1` = 0\.43.*`gamma2` = 0\.34'
                     r'.*`k1` = 3\.14.*`k2` = 3\.29', page)
