"""One naming rule for the gains of every method (issue 16), checked on every example's designs.

The rule (docs/artefacts.md): continuous-time model ``F, B, C, Bw``; discrete-time ``Ad, Bd,
C, Bwd``; operating point ``x_op, u_op``; an estimator's initial estimate ``x_hat0``. No gain
is called ``A``, none ``x0`` or ``u0``; ``B`` appears only beside ``F`` and ``Bd`` beside
``Ad``; the names agree with the design's ``time_domain`` diagnostic, and the matrices behave
like their time domain (checked independently: eigenvalues, and ``Ad, Bd`` the exact ZOH of
``F, B`` computed here with ``scipy.linalg.expm``).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from tanksynth.analysis.statespace import GAIN_NAMES, undocumented_gains
from tanksynth.artefacts.export import implementation_data, mat_contents
from tanksynth.docgen import gain_names_markdown, generated_section
from tanksynth.errors import ArtefactError
from tanksynth.methods import METHODS, load_spec
from tanksynth.verify.common import artefact_gain, artefact_matrix

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted(ROOT.joinpath("examples").glob("*.toml"))
CONTINUOUS = ("F", "B", "Bw")
DISCRETE = ("Ad", "Bd", "Bwd")


@pytest.fixture(scope="module")
def designed() -> dict:
    """``(example, design name) -> (spec, DesignResult)`` for every design of every example."""
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")     # design warnings are other tests' business
        for path in EXAMPLES:
            spec = load_spec(path)
            for entry in spec.designs:
                out[(path.stem, entry.name)] = (spec, METHODS[entry.method].design(spec, entry))
    return out


@pytest.mark.slow
def test_every_method_has_an_example_design(designed):
    assert {r.method for _, r in designed.values()} == set(METHODS)


@pytest.mark.slow
def test_the_rule_holds_for_every_gain(designed):
    bad = []
    for (example, name), (_, r) in designed.items():
        g = set(r.gains)
        where = f"{example}/{name} ({r.method}): {sorted(g)}"
        if {"A", "x0", "u0"} & g:
            bad.append(f"{where}: a gain named A, x0 or u0")
        if "B" in g and "F" not in g:
            bad.append(f"{where}: B without F")
        if "Bw" in g and "F" not in g:
            bad.append(f"{where}: Bw without F")
        if ("Bd" in g or "Bwd" in g) and "Ad" not in g:
            bad.append(f"{where}: Bd/Bwd without Ad")
        if ("x_op" in g) != ("u_op" in g):
            bad.append(f"{where}: x_op and u_op come together")
    assert not bad, "\n".join(bad)


@pytest.mark.slow
def test_names_agree_with_the_time_domain(designed):
    bad = []
    checked = 0
    for (example, name), (_, r) in designed.items():
        g = set(r.gains)
        has_c, has_d = bool(g & set(CONTINUOUS)), bool(g & set(DISCRETE))
        domain = r.diagnostics.get("time_domain")
        where = f"{example}/{name} ({r.method}, time_domain {domain!r})"
        if r.method == "linearize":     # both models, by definition
            if not (g >= {"F", "B", "Ad", "Bd", "C", "x_op", "u_op"}):
                bad.append(f"{where}: {sorted(g)}")
            continue
        if (has_c or has_d) and domain not in ("continuous", "discrete"):
            bad.append(f"{where}: a model without a time_domain diagnostic")
        elif domain == "continuous" and has_d or domain == "discrete" and has_c:
            bad.append(f"{where}: {sorted(g)}")
        checked += has_c or has_d
    assert not bad, "\n".join(bad)
    assert checked >= 15        # pole/LMI placement, synthesis, robust, TS PDC, canonical, Kalman


@pytest.mark.slow
def test_matrices_behave_like_their_time_domain(designed):
    """Tank plants are open-loop stable: ``F`` has eigenvalues with real part <= 0 (1/s), its
    ZOH ``Ad = expm(F ts)`` eigenvalues in (0, 1]. A discrete matrix stored as ``F`` (or the
    reverse) fails one of the two."""
    bad = []
    for (example, name), (_, r) in designed.items():
        for key in ("F", "Ad"):
            M = np.asarray(r.gains.get(key, np.zeros((0, 0))), dtype=float)
            if M.ndim != 2 or M.size == 0:
                continue        # absent, or the Takagi-Sugeno vertex stack
            eig = np.linalg.eigvals(M)
            scale = max(1.0, float(np.max(np.abs(eig))))
            ok = (np.all(eig.real <= 1e-9 * scale) if key == "F"
                  else np.all(eig.real > 0) and np.all(np.abs(eig) <= 1 + 1e-9))
            if not ok:
                bad.append(f"{example}/{name} ({r.method}): {key} eigenvalues {np.round(eig, 6)}")
    assert not bad, "\n".join(bad)


@pytest.mark.slow
def test_linearize_Ad_Bd_are_the_zoh_of_F_B(designed):
    n_checked = 0
    for (example, name), (spec, r) in designed.items():
        if r.method != "linearize":
            continue
        F, B, Ad, Bd = (np.asarray(r.gains[k], dtype=float) for k in ("F", "B", "Ad", "Bd"))
        n, m = B.shape
        E = expm(np.block([[F, B], [np.zeros((m, n + m))]]) * float(spec.ts))
        np.testing.assert_allclose(Ad, E[:n, :n], rtol=1e-9, atol=1e-14, err_msg=example)
        np.testing.assert_allclose(Bd, E[:n, n:], rtol=1e-9, atol=1e-16, err_msg=example)
        np.testing.assert_allclose(r.gains["x_op"], spec.x0, rtol=0, atol=0, err_msg=example)
        n_checked += 1
    assert n_checked >= 5


@pytest.mark.slow
def test_initial_estimates_are_x_hat0(designed):
    """Every estimator shipping an initial estimate names it ``x_hat0``: the spec's ``x0`` option."""
    seen = 0
    for (example, name), (spec, r) in designed.items():
        if "x_hat0" not in r.gains:
            continue
        assert np.asarray(r.gains["x_hat0"]).shape == (spec.plant.n,), (example, name)
        seen += 1
    assert seen >= 8   # ekf, ukf (twice each), kalman, adaptive_kalman, luenberger, narx, ...


@pytest.mark.slow
def test_mat_files_follow_the_rule(designed):
    for (example, name), (_, r) in designed.items():
        mat = mat_contents(r.gains, implementation_data(r.diagnostics, None))
        # x0/u0 are MATLAB's names of the operating point (issue 30 item 5), never an estimate;
        # A, B, C, D (continuous) come only from the plant record's linearisation (none here)
        assert {"x_op", "u_op", "x0", "u0"} <= set(mat) and "A" not in mat, (example, name)
        np.testing.assert_array_equal(mat["x0"], mat["x_op"])
        np.testing.assert_array_equal(mat["u0"], mat["u_op"])
        if "x_op" in r.gains:        # the design's own operating point, as a column
            np.testing.assert_array_equal(mat["x_op"][:, 0], np.ravel(r.gains["x_op"]))


def test_an_artefact_with_the_old_names_is_named():
    doc = {"name": "old", "method": "pole_placement",
           "gains": {"A": [[1.0]], "B": [[1.0]], "C": [[1.0]], "x0": [0.1]}}
    with pytest.raises(ArtefactError, match=r"no gain 'Ad' but 'A'.*design again"):
        artefact_matrix(doc, "A", (1, 1), "discrete")
    with pytest.raises(ArtefactError, match=r"no gain 'x_hat0' but 'x0'"):
        artefact_gain(doc, "x_hat0")
    with pytest.raises(ArtefactError, match=r"no gain 'Lambda_op' but 'Lambda_x0'"):
        artefact_matrix({**doc, "gains": {"Lambda_x0": [[1.0]]}}, "Lambda_op", (1, 1))
    with pytest.raises(ArtefactError, match=r"no gain 'K'$"):
        artefact_gain(doc, "K")
    np.testing.assert_array_equal(artefact_matrix({**doc, "gains": {"F": [[2.0]]}}, "A", (1, 1),
                                                  "continuous"), [[2.0]])


@pytest.mark.slow
def test_every_gain_name_is_in_the_table(designed):
    """The docs' table (`GAIN_NAMES`) lists every gain every example's designs store."""
    bad = [f"{example}/{name} ({r.method}): {undocumented_gains(list(r.gains))}"
           for (example, name), (_, r) in designed.items() if undocumented_gains(list(r.gains))]
    assert not bad, "undocumented gain names (add them to GAIN_NAMES):\n" + "\n".join(bad)


def test_the_table_check_fails_on_a_new_name():
    names = ["K", "K_0", "K_39", "R1", "C12", "sp_K", "sp_x_op", "sp_switch_level",
             "Lambda_x0", "K_x", "sp_new", "new_gain", "x0", "A", "sp_"]
    assert undocumented_gains(names) == ["Lambda_x0", "K_x", "sp_new", "new_gain", "x0", "A", "sp_"]


def test_the_docs_table_is_generated_from_the_dict():
    table = generated_section((ROOT / "docs" / "artefacts.md").read_text(encoding="utf-8"), "gain_names")
    assert table == gain_names_markdown()
    rows = [line for line in table.splitlines() if line.startswith("| `")]
    assert len(rows) == len(GAIN_NAMES)
    for (names, _), row in zip(GAIN_NAMES.items(), rows):
        assert row.split(" | ")[0] == "| " + ", ".join(f"`{n}`" for n in names)


@pytest.mark.slow
def test_placement_designs_store_their_operating_point(designed):
    """Placement and H2 / H-infinity / multi-objective gains hold ``x_op`` (the spec's point) and
    ``u_op`` (the equilibrium input the .mat also carries, from the diagnostics)."""
    seen = 0
    for (example, name), (spec, r) in designed.items():
        if r.method not in ("pole_placement", "lmi_placement", "h2_state_feedback", "h2_observer",
                            "hinf_state_feedback", "hinf_observer", "multiobjective"):
            continue
        np.testing.assert_array_equal(r.gains["x_op"], spec.x0, err_msg=f"{example}/{name}")
        data = implementation_data(r.diagnostics, None)
        np.testing.assert_allclose(r.gains["u_op"], data["u_op"], rtol=0, atol=0,
                                   err_msg=f"{example}/{name}")
        assert r.gains["u_op"].shape == (spec.plant.m,)
        seen += 1
    assert seen >= 7     # placement and synthesis designs in examples/
