"""Issue 12 items 6-7: `design` looks at its input and its result and warns (DesignWarning)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tanksynth.errors import DesignWarning
from tanksynth.methods import METHODS, parse_spec_text
from tanksynth.plants import three_tank

HEAD = """
title = "audit"
[plant]
model = "three_tank"
outputs = "all"
{params}
[operating_point]
x = {{h1 = {h1}, h2 = {h2}, h3 = {h3}}}
[sampling]
ts = 1.0
[[design]]
name = "lin"
method = "linearize"
"""


def _design(text):
    spec = parse_spec_text(text)
    entry = spec.designs[0]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", DesignWarning)
        res = METHODS[entry.method].design(spec, entry)
    lines = [str(w.message) for w in caught if issubclass(w.category, DesignWarning)]
    return res, lines


def test_clean_spec_has_no_warning():
    res, lines = _design(HEAD.format(params="", h1=0.40, h2=0.20, h3=0.30))
    assert lines == [] and res.diagnostics["warnings"] == []


def test_non_equilibrium_operating_point_warns_naming_the_equation():
    # tank 3 is balanced only when q13 = q32, i.e. h1 - h3 = h3 - h2; (0.40, 0.20, 0.25) is not
    res, lines = _design(HEAD.format(params="", h1=0.40, h2=0.20, h3=0.25))
    # independent: the h3 equation at this point, no input enters it
    p = three_tank()
    g, A, Phi, mu = 9.81, 0.0154, 5e-5, 0.5
    dh3 = (mu * Phi * np.sqrt(2 * g * 0.15) - mu * Phi * np.sqrt(2 * g * 0.05)) / A
    assert dh3 > 1e-4 and p.n == 3
    line = next(s for s in lines if "not an equilibrium" in s)
    assert "dh3/dt" in line and "tolerance" in line and f"{dh3:.3g}" in line
    assert line in res.diagnostics["warnings"]


def test_equilibrium_input_outside_actuator_range_warns():
    # at equilibrium q1 = q13 (Torricelli, computed here independently): 1.1e-5 m^3/s, more than
    # a pump limited to qmax = 1e-5 m^3/s delivers
    h1, h2, h3 = 0.60, 0.58, 0.59
    g, Phi = 9.81, 5e-5
    q13 = 0.5 * Phi * np.sqrt(2 * g * (h1 - h3))
    assert q13 > 1e-5
    text = HEAD.format(params="[plant.parameters]\nqmax = 1e-5", h1=h1, h2=h2, h3=h3)
    _, lines = _design(text)
    line = next(s for s in lines if "actuator range" in s)
    assert "q1" in line and "[0, 1e-05]" in line


def test_implausible_parameter_warns_with_unit_and_range():
    text = HEAD.format(params="[plant.parameters]\nA = 154.0", h1=0.40, h2=0.20, h3=0.30)
    res, lines = _design(text)
    line = next(s for s in lines if "plausible" in s)
    assert "A = 154 m^2" in line and "[0.0001, 1] m^2" in line
    assert three_tank().parameter("A").plausible == (1e-4, 1.0)


def test_unstable_designed_observer_warns():
    """A Luenberger gain given by hand (no pole check at parse time) that destabilises A - L C."""
    text = HEAD.format(params="", h1=0.40, h2=0.20, h3=0.30).split("[[design]]")[0] + """
[[design]]
name = "bad_observer"
method = "luenberger"
form = "predictor"
L = [[-2.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
"""
    res, lines = _design(text)
    eig = np.array([complex(a, b) for a, b in res.diagnostics["error_dynamics_eigenvalues"]])
    assert np.max(np.abs(eig)) > 1                      # independent of the warning text
    assert any("error dynamics are not stable" in s for s in lines)


def test_pole_placement_refuses_an_unstable_request_at_parse_time():
    """A pole at 1.5 in a discrete spec: refused with the key (exit 2), never placed silently."""
    from tanksynth.errors import SpecError

    text = HEAD.format(params="", h1=0.40, h2=0.20, h3=0.30).split("[[design]]")[0] + """
[[design]]
name = "pp"
method = "pole_placement"
target = "state_feedback"
poles = [1.5, 0.9, 0.8]
"""
    with pytest.raises(SpecError, match="unit circle"):
        parse_spec_text(text)


def _three_tank_time_constants(h1, h2, h3):
    """Time constants (s) of the three-tank linearised by hand: d/dd (k sqrt(d)) = k / (2 sqrt(d))."""
    g, A, Phi, mu13, mu32, mu20 = 9.81, 0.0154, 5e-5, 0.5, 0.5, 0.675
    c13, c32, c20 = (mu * Phi * np.sqrt(2 * g) / (2 * np.sqrt(d)) / A
                     for mu, d in ((mu13, h1 - h3), (mu32, h3 - h2), (mu20, h2)))
    F = np.array([[-c13, 0.0, c13],
                  [0.0, -c32 - c20, c32],
                  [c13, c32, -c13 - c32]])
    return np.sort(-1.0 / np.linalg.eigvals(F).real)


def test_sampling_period_longer_than_the_slowest_time_constant_warns_naming_them():
    """Issue 30 item 15: ts = 1000 s on the three-tank is 2.2x its slowest time constant."""
    taus = _three_tank_time_constants(0.40, 0.20, 0.30)
    assert 1000.0 / taus[-1] == pytest.approx(2.2, abs=0.05)
    text = HEAD.format(params="", h1=0.40, h2=0.20, h3=0.30).replace("ts = 1.0", "ts = 1000.0")
    res, lines = _design(text)
    line = next(s for s in lines if "slowest time constant" in s)
    assert f"{taus[-1]:.3g} s" in line and f"fastest {taus[0]:.3g} s" in line, line
    assert f"{1000.0 / taus[0]:.2g}x" in line and "ts = 1000 s" in line
    assert line in res.diagnostics["warnings"]
    # the ZOH factor of the fastest mode is below machine epsilon: said so
    assert np.exp(-1000.0 / taus[0]) < np.finfo(float).eps and "machine epsilon" in line


def test_sampling_period_shorter_than_the_slowest_time_constant_is_quiet():
    taus = _three_tank_time_constants(0.40, 0.20, 0.30)
    ts = float(0.9 * taus[-1])
    text = HEAD.format(params="", h1=0.40, h2=0.20, h3=0.30).replace("ts = 1.0", f"ts = {ts!r}")
    _, lines = _design(text)
    assert not [s for s in lines if "time constant" in s]


def test_every_tanksynth_warning_of_a_design_is_recorded_and_printed_per_design():
    """Issue 30.18: one path: a tanksynth warning issued while designing (not only a DesignWarning,
    e.g. undefined Takagi-Sugeno premises) is listed in the design's diagnostics["warnings"] and
    issued again as a DesignWarning (the CLI prints those per design, naming it)."""
    from tanksynth.design.audit import designed
    from tanksynth.errors import TanksynthWarning

    spec = parse_spec_text(HEAD.format(params="[plant.parameters]\nA = 154.0", h1=0.40, h2=0.20, h3=0.30))
    entry = spec.designs[0]
    method = METHODS[entry.method]

    def run(s, e):
        warnings.warn(TanksynthWarning("premises undefined at 1 point"), stacklevel=2)
        return method.adapter.run(s, e)

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = designed(run, spec, entry)
    printed = [str(w.message) for w in caught if issubclass(w.category, DesignWarning)]
    assert "premises undefined at 1 point" in printed
    assert any("A = 154 m^2" in line for line in printed)
    assert set(printed) == set(res.diagnostics["warnings"])


def test_cli_warning_lines_are_the_designs_recorded_warnings(tmp_path, capsys):
    """Issue 30.18: every 'warning: <designs>: <text>' line of the CLI is in each named design's
    diagnostics["warnings"] (the implausible tank area of a unit slip)."""
    import json

    from tanksynth.cli import main

    spec = tmp_path / "spec.toml"
    spec.write_text(HEAD.format(params="[plant.parameters]\nA = 154.0", h1=0.40, h2=0.20, h3=0.30)
                    + '[[design]]\nname = "lin2"\nmethod = "linearize"\n', encoding="utf-8")
    assert main(["design", str(spec), "-o", str(tmp_path / "out")]) == 0
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("warning: ")]
    assert lines and any("plausible" in ln for ln in lines)
    for ln in lines:
        names, text = ln.removeprefix("warning: ").split(": ", 1)
        for name in names.split(", "):
            doc = json.loads((tmp_path / "out" / f"{name}.json").read_text(encoding="utf-8"))
            assert text in doc["diagnostics"]["warnings"], (name, text)
