"""Issue 30 item 7: ``lqr``, ``dlqr``, ``lqe``, ``dlqe`` are aliases a control engineer types.

A spec with ``method = "lqr"`` runs the method the alias names (with the options it fixes), the
artefact records that method and the alias, and ``tanksynth methods lqr`` says what it runs.
References: python-control's ``lqr``, ``dlqr``, ``lqe``, ``dlqe`` on the linearisation at the
operating point (`tanksynth.analysis.linearize`, exact ZOH), with the weights the options hold.
"""

from __future__ import annotations

import json

import control
import numpy as np
import pytest

from tanksynth.analysis import equilibrium_input, linearize
from tanksynth.cli import main
from tanksynth.errors import SpecError
from tanksynth.methods import ALIASES, METHODS, parse_spec_text

HEAD = """
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0
"""


def _design(body: str):
    spec = parse_spec_text(HEAD + '[[design]]\nname = "d"\n' + body)
    entry = spec.designs[0]
    return spec, entry, METHODS[entry.method].design(spec, entry)


def _model(spec):
    eq = equilibrium_input(spec.plant, spec.x0)
    return linearize(spec.plant, spec.x0, eq.u0, ts=spec.ts)


def _close(a, b):
    np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-9 * np.abs(b).max())


@pytest.mark.parametrize("alias, domain", [("lqr", "continuous"), ("dlqr", "discrete")])
def test_lqr_and_dlqr_are_python_controls(alias, domain):
    spec, entry, res = _design(f'method = "{alias}"\n')
    assert (entry.method, entry.alias, entry.config.time_domain) == ("h2_state_feedback", alias, domain)
    assert res.method == "h2_state_feedback" and res.diagnostics["method_alias"] == alias
    lin, Q, R = _model(spec), np.asarray(entry.config.Q), np.asarray(entry.config.R)
    K_ref, _, _ = (control.lqr(lin.F, lin.B, Q, R) if domain == "continuous"
                   else control.dlqr(lin.Ad, lin.Bd, Q, R))
    _close(res.gains["K"], K_ref)
    # the same gain as the method it names, with the option it fixes written out
    _, _, plain = _design(f'method = "h2_state_feedback"\ntime_domain = "{domain}"\n')
    _close(res.gains["K"], plain.gains["K"])


@pytest.mark.parametrize("alias, domain", [("lqe", "continuous"), ("dlqe", "discrete")])
def test_lqe_and_dlqe_are_python_controls(alias, domain):
    spec, entry, res = _design(f'method = "{alias}"\n')
    assert (entry.method, entry.alias, entry.config.time_domain) == ("h2_observer", alias, domain)
    cfg, lin = entry.config, _model(spec)
    QN = np.diag(np.asarray(cfg.disturbance_std) ** 2)
    RN = np.diag(np.asarray(cfg.measurement_std) ** 2)
    Bw = np.asarray(cfg.Bw)
    if domain == "continuous":
        L_ref, _, _ = control.lqe(lin.F, Bw, lin.C, QN, RN)
    else:  # the disturbance held over a period, as the inputs (ZOH of [F Bw])
        n = lin.F.shape[0]
        M = np.zeros((n + Bw.shape[1],) * 2)
        M[:n, :n], M[:n, n:] = lin.F * spec.ts, Bw * spec.ts
        from scipy.linalg import expm

        Bwd = expm(M)[:n, n:]
        L_ref, _, _ = control.dlqe(lin.Ad, Bwd, lin.C, QN, RN)
    _close(res.gains["L"], L_ref)


def test_an_alias_refuses_an_option_it_fixes_otherwise():
    with pytest.raises(SpecError) as info:
        parse_spec_text(HEAD + '[[design]]\nname = "d"\nmethod = "lqr"\ntime_domain = "discrete"\n')
    assert info.value.key == "design[0].time_domain"
    assert "h2_state_feedback" in str(info.value)


def test_a_misspelt_alias_gets_a_did_you_mean():
    with pytest.raises(SpecError, match="did you mean 'dlqr'"):
        parse_spec_text(HEAD + '[[design]]\nname = "d"\nmethod = "dlqrr"\n')


def test_aliases_name_methods_of_the_table_and_shadow_none():
    assert set(ALIASES) == {"lqr", "dlqr", "lqe", "dlqe"}
    assert all(a.method in METHODS and a.name not in METHODS for a in ALIASES.values())


def test_methods_command_says_what_an_alias_runs(capsys):
    assert main(["methods", "lqr"]) == 0
    assert "lqr: alias of h2_state_feedback" in capsys.readouterr().out
    assert main(["methods", "dlqe", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["alias_of"] == "h2_observer" and doc["alias_options"] == {"time_domain": "discrete"}


@pytest.mark.slow
def test_an_alias_design_is_recorded_and_verified(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(HEAD + '[[design]]\nname = "k"\nmethod = "lqr"\n')
    assert main(["design", str(spec), "-o", str(tmp_path / "out")]) == 0
    doc = json.loads((tmp_path / "out" / "k.json").read_text())
    assert doc["method"] == "h2_state_feedback" and doc["diagnostics"]["method_alias"] == "lqr"
    assert main(["verify", str(tmp_path / "out")]) == 0


def test_a_spec_read_without_the_table_finds_the_alias_entry_of_an_artefact():
    """Campaign workers parse the spec without the method table: the entry keeps ``lqr``, the
    artefact says ``h2_state_feedback`` and records the alias; its options are still found."""
    from tanksynth.spec import parse_spec_text as parse_without_table
    from tanksynth.verify.common import design_options

    spec = parse_without_table(HEAD + '[[design]]\nname = "k"\nmethod = "lqr"\nQ = [[1.0, 0.0, 0.0], '
                               '[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n')
    doc = {"name": "k", "method": "h2_state_feedback", "diagnostics": {"method_alias": "lqr"}}
    assert "Q" in design_options(doc, spec)
    assert design_options({**doc, "diagnostics": {}}, spec) == {}
