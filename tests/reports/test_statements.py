"""The problem statements (`tanksynth.reports.statements`): one module per method family, each
statement naming the problem's quantities and the numbers its artefact's diagnostics record.

The diagnostics below are written here by hand, shaped as the designs write them; the expected
fragments are the LaTeX a reader sees (named matrices, the relaxation, the bounds), and every
number is the one put in the diagnostics, printed by `format_number`.
"""

from __future__ import annotations

import copy

import pytest

from tanksynth.methods import FAMILIES, STATEMENTS, TABLE, home
from tanksynth.reports.latex import Tex

PLACEMENT = {"placement": {"kind": "state_feedback", "method": "place",
                           "requested": [[-0.02, 0.0], [-0.03, 0.01], [-0.03, -0.01]]}}
LMI = {"lmi": {"kind": "state_feedback", "region": {"description": "|z - 0.9| < 0.08"},
               "domain": "discrete", "margin": 1e-6}}
TS_OBSERVER = {"lmi": {"psi": 0.125, "Q_form": "Q = q I"}, "psi_source": "maximised",
               "ts_model": {"r": 4, "domain": {"description": "h1 in [0.05, 0.62]"}}}
PDC = {"relaxation": "tuan", "decay_rate": 0.0125,
       "region": {"c": 0.75, "binding": "pump u1", "states": ["h1", "h2"], "extents": [0.22, 0.15],
                  "semi_axes": [0.1, 0.3]},
       "setpoint": {"x_op2": [0.46, 0.26], "switch_level": 0.5, "dwell_time": 1851.0,
                    "region": {"c": 0.8}}}
OUTPUT_PDC = {**PDC, "relaxation": "all_pairs", "premises": "estimated", "observer": {"psi": 0.0625},
              "composite": {"beta": 2.5}}
ROBUST = {"uncertain": [["a1", 1.0e-5, 2.0e-5], ["a2", 3.0e-5, 4.0e-5]],
          "vertex_models": {"balanced": [True, False, True, True]},
          "robust": {"region": {"description": "|z - 0.9| < 0.08"}, "domain": "discrete", "margin": 1e-7,
                     "hinf": {"gamma": 3.5, "imposed": False, "lyapunov_scale": 1.5}},
          "hinf_channel": {"observer": False, "given": ["Cz"]},
          "offsets": {"max_abs_deviation": 0.0123},
          "saturation": {"ellipsoid_axes": {"lengths": [0.1, 0.25]}}}
SYNTHESIS = {"time_domain": "discrete", "route": "lmi",
             "synthesis": {"h2_bound": 1.5, "gamma": 2.25, "achieved_h2": [1.25], "achieved_hinf": [2.0],
                           "scaling": {"backoff": 0.05}, "region": {"description": "|z| < 0.97"},
                           "objective": "h2"}}

#: method -> (diagnostics, fragments its statement must contain).
CASES = {
    "linearize": ({}, [r"$F = \partial f/\partial x$", r"$A_d = e^{F t_s}$"]),
    "pole_placement": ({**PLACEMENT, "integral": {"tracked": ["h1", "h3"]}},
                       [r"$A - BK$", r"at $-0.02,\allowbreak\; -0.03 \pm 0.01\,\mathrm{j}$",
                        r"\texttt{place}", "Integral action", r"$K = [K_1\;K_2]$"]),
    "lmi_placement": (LMI, [r"(AX - BY)", r"$K = Y X^{-1}$", "Chilali--Gahinet", "(discrete time)",
                            r"margin $10^{-6}$"]),
    "canonical_observer": ({}, [r"$L = \Delta\Psi_o$"]),
    "ts_observer": (TS_OBSERVER, [r"L = P^{-1}K", r"$\psi = 0.125$", "(maximised)", "4 vertices"]),
    "ts_state_feedback": (PDC, ["Tuan et al.", "Relaxation used: tuan", "$0.0125$ 1/s",
                                r"\le 0.75\}", "bound by pump $u_{1}$", "$h1$: 0.22 m", "semi-axes 0.1, 0.3 m",
                                r"$x_0' = (0.46,\; 0.26)$", "$c_2 = 0.8$", r"$\gamma = 0.5$",
                                r"= 1851$ s"]),
    "ts_output_feedback": (OUTPUT_PDC, ["for every $(i, j)$", "Estimated premises", r"$\psi = 0.0625$ 1/s",
                                       r"$\beta = 2.5$", "the observer kept"]),
    "feedback_linearization": ({}, [r"$D(x) = [L_g L_f^{r_i-1} h_i]$"]),
    "integral_tracking": ({}, ["anti-windup"]),
    "inverse_dynamics": ({}, [r"$C_i \ge 0$"]),
    "decentralized_kalman": ({}, ["sparsity pattern $E$"]),
    "kalman": ({}, ["minimum-variance", "Joseph form"]),
    "ekf": ({}, ["Extended Kalman filter", "Joseph form"]),
    "ukf": ({}, ["$2n+1$ sigma points", "Joseph form"]),
    "adaptive_kalman": ({}, ["sliding window", "Joseph form"]),
    "adaptive_scaling_kalman": ({}, [r"$\varphi_k$", "Joseph form"]),
    "consensus_filter": ({}, ["redundant sensors", "Joseph form"]),
    "luenberger": ({}, ["Luenberger observer"]),
    "narx": ({}, ["Levenberg-Marquardt"]),
    "fault_detection": ({}, [r"$J_{th}(t)$"]),
    "robust_state_feedback": (ROBUST, [r"(A_i X - B_i Y)", r"$2^{2}$ corners",
                                       r"a_{1} \in [10^{-5}, 2 \times 10^{-5}]",
                                       "at 1 of the 4 corner models", r"< 3.5$", "with the given $C_z$",
                                       r"$D_{zu} = 0$", r"times $1.5$", "not imposed",
                                       r"margin $10^{-7}$", "settles up to $0.0123$",
                                       "semi-axes $0.1, 0.25$"]),
    "robust_observer": ({**ROBUST, "hinf_channel": {"observer": True, "given": []}},
                        [r"(A_i^\top X - C_i^\top Y)", "(dual pairs)", r"$A_i - L C_i$",
                         r"$B_w = s I$", "keeps a bias"]),
    "h2_state_feedback": (SYNTHESIS, [r"$x(k+1) = A x + B_w w + B u$", r"\operatorname{tr} W",
                                      r"$\|T_{zw}\|_2 \le 1.5$", r"recomputed $\|T_{zw}\|_2 = 1.25$",
                                      "LQR", "in the units of $z$ per unit of $w$",
                                      r"$R$ in 1/input unit$^2$"]),
    "h2_observer": ({**SYNTHESIS, "route": "riccati"}, ["steady Kalman filter", "noise covariances",
                                                        "$w$ and $v$ are normalised", r"$C_z = Q^{1/2}$"]),
    "hinf_state_feedback": (SYNTHESIS, ["bounded-real-lemma", r"$\gamma \le (1 + 0.05)\gamma^\star$",
                                       r"$\|T_{zw}\|_\infty \le 2.25$"]),
    "hinf_observer": ({**SYNTHESIS, "route": "riccati"}, ["game algebraic Riccati", "dual pair",
                                                          r"$\gamma = (1 + 0.05)\gamma^\star$"]),
    "multiobjective": ({**SYNTHESIS, "target": "observer"},
                       [r"minimise $\operatorname{tr} W$", "ONE Lyapunov matrix", r"region $D$: \textbar{}z",
                        "observer error", "Conservatism"]),
    "fit": ({"mode": "simulation", "substeps": 4, "level": 0.95,
             "estimation": {"experiments": [{}, {}], "rmse": {"h1": 0.0018}, "fit_percent": {"h1": 98.4}},
             "validation": {"rmse": {"h1": 0.0016}, "fit_percent": {"h1": 98.3}},
             "output_units": {"h1": "m"},
             "parameters": {"mu13": {"value": 0.46, "stderr": 1e-3, "ci95": [0.458, 0.462], "unit": "1",
                                     "start": 0.5, "lower": 0.2, "upper": 0.9},
                            "mu32": {"value": 0.52, "stderr": 2e-3, "ci95": [0.516, 0.524], "unit": "1",
                                     "start": 0.5, "lower": 0.2, "upper": 0.9, "at_bound": True}},
             "correlation": [[1.0, -0.4], [-0.4, 1.0]]},
            [r"\mu_{13} \in [0.2, 0.9]", "$E = 2$ logged experiments", r"$\mu_{32}$ & $0.52$", r"validation & $h_{1}$ & $0.0016$ & m & $98.3$", "4 clipped RK4 steps",
             r"$[0.458, 0.462]$", "(at a bound)", "$-0.4$", r"(J^\top J)^{-1}"]),
}


def test_every_method_has_a_case():
    assert set(CASES) == {row.name for row in TABLE}


@pytest.mark.parametrize("method", sorted(CASES))
def test_statement_names_its_quantities_and_numbers(method):
    diag, fragments = CASES[method]
    text = STATEMENTS[method](diag)
    assert isinstance(text, Tex)
    for fragment in fragments:
        assert fragment in text, (method, fragment, text)


@pytest.mark.parametrize("row", TABLE, ids=lambda row: row.name)
def test_each_statement_lives_in_its_familys_module(row):
    statement = row.statement
    assert statement.__module__ == home("statement", row.family)
    assert statement.__name__ == f"{row.name}_statement"
    assert f"``{row.name}``" in statement.__doc__ and "diag : mapping" in statement.__doc__


def test_the_statements_package_re_exports_every_statement():
    import tanksynth.reports.statements as statements

    assert {row.family for row in TABLE} == set(FAMILIES)
    for row in TABLE:
        assert getattr(statements, f"{row.name}_statement") is row.statement


def test_the_observer_and_the_controller_say_which_matrix_they_place():
    observer = STATEMENTS["pole_placement"]({"placement": {"kind": "observer"}})
    assert "$A - LC$" in observer and "at $" not in observer
    lmi_observer = STATEMENTS["lmi_placement"]({"lmi": {"kind": "observer"}})
    assert "(dual pair)" in lmi_observer and r"$L = (Y X^{-1})^\top$" in lmi_observer


def test_what_is_not_recorded_is_not_stated():
    """Without diagnostics a statement states the problem only: no number, no empty phrase."""
    for method, (diag, _) in CASES.items():
        text = STATEMENTS[method]({})
        assert "$$" not in text and "()" not in text and "None" not in text, method
    assert "nominal model (no uncertain parameter)" in STATEMENTS["robust_state_feedback"]({})
    assert "basic vertex conditions" in STATEMENTS["ts_state_feedback"]({})
    assert r"$\dot x = A x" in STATEMENTS["hinf_state_feedback"]({})


def _paths(node, prefix=()):
    if isinstance(node, dict):
        for key, value in node.items():
            yield prefix + (key,)
            yield from _paths(value, prefix + (key,))


def _edited(diag, path, value):
    out = copy.deepcopy(diag)
    node = out
    for key in path[:-1]:
        node = node[key]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return out


_DELETE = object()
#: What a hand edit may leave: nothing, null, a string, numbers, a bool, lists and mappings.
_EDITS = (_DELETE, None, "", "observer", "tuan", 0, -1.5, True, False, [], [1.0, "x"], [[0.1], [0.2, 0.3, 4]],
          {}, {"description": 5}, ["k", 0.1, 0.2])


@pytest.mark.parametrize("method", sorted(CASES))
def test_an_edited_artefact_gives_a_statement_not_a_traceback(method):
    """Every entry replaced by a value of another type (or deleted): the statement still renders;
    the edited quantity is left out, the others stay."""
    diag, _ = CASES[method]
    statement = STATEMENTS[method]
    for path in _paths(diag):
        for value in _EDITS:
            assert isinstance(statement(_edited(diag, path, value)), Tex), (method, path, value)
    mistyped = {key: "garbage" for key in ("placement", "lmi", "region", "setpoint", "robust", "synthesis",
                                           "composite", "observer", "uncertain", "hinf_channel", "saturation",
                                           "offsets", "ts_model", "vertex_models", "integral")}
    assert isinstance(statement(mistyped), Tex)


def test_an_edited_number_is_left_out_and_the_rest_stays():
    edited = copy.deepcopy(ROBUST)
    edited["robust"]["hinf"]["gamma"] = "large"
    text = STATEMENTS["robust_state_feedback"](edited)
    assert "bounded real lemma" not in text
    assert r"margin $10^{-7}$" in text and "settles up to $0.0123$" in text


def test_a_decay_rate_at_the_bisections_end_is_stated_as_at_most_with_the_certified_margin():
    """Issue 30.3: the TS PDC decay rate is the bisection's end point, where the LMIs hold with
    equality: the statement says "at most" there and gives the rate certified strictly, with
    its margin."""
    diag = copy.deepcopy(PDC)
    diag["lmi"] = {"decay_rate_bracket": {"at_least": 0.0124, "margin": 3.5e-7}}
    text = str(STATEMENTS["ts_state_feedback"](diag))
    assert r"certified decay rate $\alpha \ge 0.0124$ 1/s" in text
    assert r"margin $3.5 \times 10^{-7}$" in text
    assert r"at most $\alpha = 0.0125$ 1/s" in text and "with equality" in text
    plain = str(STATEMENTS["ts_state_feedback"](PDC))
    assert "decay rate at most $0.0125$ 1/s" in plain


def test_an_lmi_region_gain_gets_its_distance_to_the_region_boundary(tmp_path):
    """Issue 30.3: an LMI-region gain 5.9e-4 inside its half-plane got no margin figure."""
    from tanksynth.reports.designs import design_view

    art = {"name": "k", "method": "lmi_placement", "gains": {},
           "diagnostics": {"lmi": {**LMI["lmi"], "min_boundary_distance": 5.9e-4}}}
    view = design_view(art, None, STATEMENTS, None)
    rows = {str(k): str(v) for k, v in view.margins}
    label = next(k for k in rows if "distance of the closed-loop eigenvalues to the region" in k)
    assert rows[label] == "$0.00059$"
