"""Issue 12 items 1, 4, 5 at the spec level: pole plane, repeated poles, fragile gains."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.linalg as sla

from tanksynth.errors import DesignWarning, InfeasibleDesign, SpecError
from tanksynth.methods import METHODS, parse_spec_text

TANK = """
title = "plane"
[plant]
model = "three_tank"
outputs = "all"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0
[[design]]
name = "pp"
method = "pole_placement"
target = "state_feedback"
"""


def _run(text):
    spec = parse_spec_text(text)
    entry = spec.designs[0]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", DesignWarning)
        res = METHODS[entry.method].design(spec, entry)
    return spec, res, [str(w.message) for w in caught if issubclass(w.category, DesignWarning)]


def test_s_plane_poles_in_a_discrete_spec_warn():
    """Issue 12 item 5: [-0.05, -0.06, -0.07] with ts = 1 were placed at z = -0.05.. silently."""
    _, res, lines = _run(TANK + "poles = [-0.05, -0.06, -0.07]\n")
    assert any("look like s-plane poles" in s and 'domain = "s"' in s for s in lines)
    assert any("domain" in s for s in res.diagnostics["warnings"])


def test_domain_s_converts_with_exp_p_ts():
    spec, res, lines = _run(TANK + 'poles = {values = [-0.05, -0.06, -0.07], domain = "s"}\n')
    assert not any("s-plane" in s for s in lines)
    A, B, K = (np.asarray(res.gains[k]) for k in ("Ad", "Bd", "K"))
    # independent: z = exp(p ts) with ts = 1 s
    want = np.sort(np.exp(np.array([-0.05, -0.06, -0.07]) * 1.0))
    assert np.allclose(np.sort(np.linalg.eigvals(A - B @ K).real), want, atol=1e-9)
    assert res.diagnostics["poles_converted"]["domain"] == "s"


def test_domain_z_is_accepted_and_silences_the_warning():
    _, _, lines = _run(TANK + 'poles = {values = [-0.05, -0.06, -0.07], domain = "z"}\n')
    assert not any("s-plane" in s for s in lines)


def test_domain_table_is_validated():
    with pytest.raises(SpecError, match="domain"):
        parse_spec_text(TANK + 'poles = {values = [0.9, 0.8, 0.7], domain = "w"}\n')
    with pytest.raises(SpecError, match="discrete"):
        parse_spec_text(TANK + 'time_domain = "continuous"\n'
                        'poles = {values = [0.9, 0.8, 0.7], domain = "z"}\n')


HF = """
title = "repeated"
[plant]
model = "hydraulic_fault"
[operating_point]
x = {x1 = 4.0, x2 = 1.3333333333333333, x3 = 4.0}
[[design]]
name = "d"
"""


@pytest.mark.parametrize("body", [
    'method = "pole_placement"\ntarget = "state_feedback"\npoles = [-2, -2, -2]\n',
    'method = "pole_placement"\ntarget = "observer"\npoles = [-2, -2, -2]\n',
    'method = "canonical_observer"\npoles = [-2, -2, -2]\n',
])
def test_triple_pole_designs_are_written(body):
    """Issue 12 item 1 at the spec level (used to exit 3 'pole placement inaccurate')."""
    _, res, _ = _run(HF + body)
    A = np.asarray(res.gains["F"])      # no sampling period: continuous time
    if "L" in res.gains:
        M = A - np.asarray(res.gains["L"]) @ np.asarray(res.gains["C"])
    else:
        M = A - np.asarray(res.gains["B"]) @ np.asarray(res.gains["K"])
    assert np.allclose(np.poly(M), [1, 6, 12, 8], rtol=1e-10)        # (s + 2)^3
    d = res.diagnostics
    acc = d["placement"]["accuracy"] if "placement" in d else d["accuracy"]
    assert "characteristic polynomial" in acc["measure"]
    assert not d["robustness"]["fragile"]


def test_fragile_spec_is_refused_unless_allowed():
    """Issue 12 item 4: a huge observer gain (A = 154 m^2, one level measured) is refused."""
    text = TANK.replace('outputs = "all"', 'outputs = "h1"\n[plant.parameters]\nA = 154.0')
    body = 'target = "observer"\npoles = {values = [-0.05, -0.06, -0.07], domain = "s"}\n'
    with pytest.raises(InfeasibleDesign, match="allow_fragile"):
        _run(text.replace('target = "state_feedback"\n', "") + body)
    _, res, lines = _run(text.replace('target = "state_feedback"\n', "") + body
                         + "allow_fragile = true\n")
    rob = res.diagnostics["robustness"]
    assert rob["fragile"] and rob["accepted_because"] == "allow_fragile = true"
    # independent: the relative stability radius bounds a destabilising change of A
    A, L, C = (np.asarray(res.gains[k]) for k in ("Ad", "L", "C"))
    M = A - L @ C
    theta = np.linspace(0, np.pi, 2001)
    smin = min(np.linalg.svd(np.exp(1j * t) * np.eye(3) - M, compute_uv=False)[-1] for t in theta)
    assert smin / np.linalg.norm(A, 2) < 1e-6
    assert any("fragile" in s for s in lines)
    assert sla.norm(L) > 1e6


def test_matrix_latex_is_sympys_text():
    """Issue 15: the ts_observer LaTeX of a gain is assembled per distinct value; the text is
    exactly sympy's ``latex(Matrix(M))`` (``matrix`` up to 10 columns, ``array`` beyond)."""
    import sympy as sp

    from tanksynth.design.linear_gains import matrix_latex
    rng = np.random.default_rng(2)
    for M in (np.round(rng.normal(size=(3, 3)), 6), np.round(np.kron(np.eye(8), rng.normal(size=(2, 2))), 6),
              np.zeros((2, 2)), np.round(rng.normal(size=(12, 3)) * 1e-7, 8), np.ones((1, 11)),
              np.array([[1e20, -0.0], [3.0, 0.5]]), np.array([[1.0]])):
        assert matrix_latex(M) == sp.latex(sp.Matrix(M))


@pytest.mark.slow
def test_uncovered_psi_warns_that_nothing_is_certified():
    """Seed 001's safe variant maximises psi on a region without orderings, where the remainder's
    Lipschitz constant is unbounded (sqrt of a head difference at equal heads): the LMI holds,
    but the design must say it certifies nothing; a psi that covers the constant says nothing."""
    from pathlib import Path

    from tanksynth.methods import load_spec

    spec = load_spec(Path(__file__).parents[2] / "examples" / "seed001_ts_observer.toml")
    by_name = {d.name: d for d in spec.designs}
    for name, expect in (("ts_observer_paper_safe", True), ("ts_observer_certified", False)):
        entry = by_name[name]
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", DesignWarning)
            res = METHODS[entry.method].design(spec, entry)
        said = [str(w.message) for w in caught if "certifies no convergence" in str(w.message)]
        assert bool(said) is expect, (name, said)
        if expect:
            assert "unbounded" in said[0]
            assert not np.isfinite(res.diagnostics["lipschitz"]["value"])
