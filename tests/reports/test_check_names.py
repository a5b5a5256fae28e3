"""Check keys and gain keys are typeset, never printed raw (issue 30, point 9)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import tanksynth
from tanksynth.analysis.statespace import GAIN_NAMES
from tanksynth.reports.check_names import check_title
from tanksynth.reports.latex import gain_symbol

ROOT = Path(tanksynth.__file__).parent


def _check_keys() -> set[str]:
    keys: set[str] = set()
    for path in ROOT.rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        keys.update(re.findall(r'Check\(\s*"([a-z0-9_]+)"', text))
        keys.update(re.findall(r'"check": "([a-z0-9_]+)"', text))
    return keys


@pytest.mark.parametrize("key, words", [
    ("rmse_reproduced", "RMSE reproduced"), ("zoh_consistency", "ZOH consistency"),
    ("jacobian_recheck", "Jacobian re-check"), ("first_order_agreement", "First order agreement"),
    ("nis_mean", "NIS mean"), ("lmi_recheck", "LMI re-check"), ("vertex_hinf", "Vertex H-infinity"),
    ("pbh_controllability", "PBH controllability"), ("given_u0_balances", "Spec's input balances the model"),
])
def test_check_keys_in_words(key, words):
    assert check_title(key) == words


def test_every_check_key_of_the_package_reads_as_words():
    keys = _check_keys()
    assert len(keys) > 50 and "rmse_reproduced" in keys
    for key in keys:
        title = check_title(key)
        assert "_" not in title and title[0].isupper(), (key, title)


def test_gain_keys_are_symbols_or_words_never_raw_keys():
    """`x_init` printed as "x init", `Gamma_d` as "Gamma_d", `threshold_coefficients` with its
    underscore (the fit and fault-detection reports)."""
    assert gain_symbol("x_init") == r"x_{\mathrm{init}}"
    assert gain_symbol("Gamma_d") == r"\Gamma_{d}"
    assert gain_symbol("theta") == r"\theta"
    assert gain_symbol("threshold_coefficients") == r"\text{threshold coefficients}"
    for names in GAIN_NAMES:
        for name in names:
            if "<" in name:
                continue
            tex = gain_symbol(name)
            assert r"\_" not in tex and not re.search(r"[A-Za-z]{2,}_[A-Za-z]{2,}", tex), (name, tex)
