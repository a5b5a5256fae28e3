"""``tanksynth fit`` end to end on logged data simulated from known parameters (`fit_data`):
the artefact, the data copies, ``fitted.toml``, the verdict, bad inputs, and a robust design over
the fitted box (``uncertain = "fit"``)."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fit_data import TRUE, spec_text, write_log  # noqa: E402

from tanksynth.cli import main  # noqa: E402

FIT_DESIGN = """
[[design]]
name = "fit"
method = "fit"
data = ["est.csv"]
validate = ["val.csv"]
starts = 1
"""

ROBUST = """
[[design]]
name = "rsf"
method = "robust_state_feedback"
uncertain = "fit"
{fit}
region = [{{type = "disk", center = 0.0, radius = 0.99}}]
"""


def _run(*args, capsys=None):
    code = main([str(a) for a in args])
    out = capsys.readouterr() if capsys is not None else None
    return code, out


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """One fit of mu13, mu32, mu20 on 200 simulated samples (shared: a fit takes seconds)."""
    root = tmp_path_factory.mktemp("fit")
    write_log(root / "est.csv", seed=1, samples=200)
    write_log(root / "val.csv", seed=2, samples=200)
    (root / "spec.toml").write_text(spec_text(FIT_DESIGN + ROBUST.format(fit="")))
    code = main(["fit", str(root / "spec.toml"), "-o", str(root / "out")])
    return root, code


@pytest.mark.slow
def test_fit_writes_artefact_data_and_fitted_spec(fitted):
    root, code = fitted
    out = root / "out"
    assert code == 0
    doc = json.loads((out / "fit.json").read_text())
    assert set(doc["gains"]) == {"theta", "covariance", "x_init"}
    diag = doc["diagnostics"]
    for name in TRUE:
        p = diag["parameters"][name]
        assert set(p) >= {"value", "stderr", "ci95", "unit", "start", "lower", "upper", "at_bound"}
        assert abs(p["value"] - TRUE[name]) < 0.02, (name, p["value"])
    assert set(diag["estimation"]["rmse"]) == {"h1", "h2"} == set(diag["validation"]["rmse"])
    assert diag["converged"] is True
    # the data copies, byte for byte, with the recorded sha256
    import hashlib
    for rec in diag["estimation"]["experiments"] + diag["validation"]["experiments"]:
        copy = out / rec["file"]
        assert copy.read_bytes() == (root / Path(rec["file"]).name).read_bytes()
        assert hashlib.sha256(copy.read_bytes()).hexdigest() == rec["sha256"]
    # fitted.toml: the fitted values as plain numbers, the fit design gone, the robust design
    # pointed at fit.json; it loads as a spec
    import tomllib

    from tanksynth.methods import load_spec

    table = tomllib.loads((out / "fitted.toml").read_text())
    assert {k: table["plant"]["parameters"][k] for k in TRUE} == {
        k: diag["parameters"][k]["value"] for k in TRUE}
    assert [d["method"] for d in table["design"]] == ["robust_state_feedback"]
    assert table["design"][0]["fit"] == "fit.json"
    spec = load_spec(out / "fitted.toml")
    assert spec.free_parameters == ()
    assert spec.designs[0].config.uncertain == tuple(
        (k, *diag["parameters"][k]["ci95"]) for k in diag["parameters"])


@pytest.mark.slow
def test_fitted_spec_runs(fitted, tmp_path, capsys):
    root, _ = fitted
    code, out = _run("run", root / "out" / "fitted.toml", "-o", tmp_path / "r", capsys=capsys)
    assert code == 0, out.err
    doc = json.loads((tmp_path / "r" / "rsf.json").read_text())
    source = doc["diagnostics"]["uncertain_source"]
    fit_json = root / "out" / "fit.json"
    import hashlib
    assert source["sha256"] == hashlib.sha256(fit_json.read_bytes()).hexdigest()
    assert source["level"] == 0.95
    box = json.loads(fit_json.read_text())["diagnostics"]["parameters"]
    assert doc["diagnostics"]["uncertain"] == [[k, *v["ci95"]] for k, v in box.items()]


@pytest.mark.slow
def test_verdict_reproduces_and_fails_on_edits(fitted, tmp_path):
    from tanksynth.methods import load_directory, verify_directory
    from tanksynth.verify.fit.verdicts import fit_verdict

    root, _ = fitted
    work = tmp_path / "copy"
    shutil.copytree(root / "out", work)
    spec, docs = load_directory(work)
    (doc,) = [d for _, d in docs]
    checks = {c.name: c for c in fit_verdict(doc, spec)}
    assert checks["rmse_reproduced"].passed and checks["data_files"].passed
    assert checks["converged"].passed and checks["parameters_inside_bounds"].passed
    # the verdict recomputes the fit's own whiteness statistic and bound (Ljung-Box, 95 %)
    from scipy.stats import chi2
    recorded = doc["diagnostics"]["estimation"]["whiteness"]
    for nm, w in checks["residual_whiteness"].data["whiteness"].items():
        assert w["statistic"] == pytest.approx(recorded[nm]["statistic"], rel=1e-6)
        assert w["bound"] == pytest.approx(recorded[nm]["bound"]) == pytest.approx(chi2.ppf(0.95, 20))
    # a changed value: the re-simulated RMSE no longer equals the recorded one
    edited = dict(doc, gains={**doc["gains"], "theta": doc["gains"]["theta"] * np.array([1.01, 1, 1])})
    assert {c.name: c for c in fit_verdict(edited, spec)}["rmse_reproduced"].passed is False
    # an edited data copy: refused on its hash
    csv = work / "data" / "est.csv"
    csv.write_text(csv.read_text().replace("\n1,", "\n1.0,", 1))
    (verdict,) = verify_directory(work)
    failed = [c for c in verdict.checks if c.passed is False]
    assert [c.name for c in failed] == ["data_files"] and "sha256" in failed[0].detail


@pytest.mark.slow
def test_edited_fit_json_is_refused(fitted, tmp_path, capsys):
    root, _ = fitted
    work = tmp_path / "copy"
    shutil.copytree(root / "out", work)
    doc = json.loads((work / "fit.json").read_text())
    doc["diagnostics"]["estimation"]["rmse"]["h1"] *= 2
    (work / "fit.json").write_text(json.dumps(doc))
    code, out = _run("verify", work, capsys=capsys)
    assert code == 2 and len(out.err.strip().splitlines()) == 1


def test_no_free_parameter_exit_2(tmp_path, capsys):
    write_log(tmp_path / "est.csv", seed=1, samples=20)
    (tmp_path / "s.toml").write_text(spec_text(free=False))
    code, out = _run("fit", tmp_path / "s.toml", "--data", tmp_path / "est.csv", "-o", tmp_path / "o",
                     capsys=capsys)
    assert code == 2
    (line,) = out.err.strip().splitlines()
    assert "fit = true" in line and "plant.parameters" in line
    assert not (tmp_path / "o" / "fit.json").exists()


def test_fit_design_without_free_parameter_refused_at_load(tmp_path, capsys):
    (tmp_path / "s.toml").write_text(spec_text(FIT_DESIGN, free=False))
    code, out = _run("check", tmp_path / "s.toml", "--spec-only", capsys=capsys)
    assert code == 2 and "fit = true" in out.err and len(out.err.strip().splitlines()) == 1


def test_missing_data_file_exit_2(tmp_path, capsys):
    (tmp_path / "s.toml").write_text(spec_text(FIT_DESIGN))
    code, out = _run("fit", tmp_path / "s.toml", "-o", tmp_path / "o", capsys=capsys)
    assert code == 2
    (line,) = out.err.strip().splitlines()
    assert "est.csv" in line and "design[0].data[0]" in line
    code, out = _run("fit", tmp_path / "s.toml", "--data", tmp_path / "nope.csv", "-o", tmp_path / "o",
                     capsys=capsys)
    assert code == 2 and "nope.csv" in out.err


def test_robust_fit_without_path_refused_at_design(tmp_path, capsys):
    (tmp_path / "s.toml").write_text(spec_text(ROBUST.format(fit="")))
    code, out = _run("design", tmp_path / "s.toml", "-o", tmp_path / "o", capsys=capsys)
    assert code == 2 and "fit = \"PATH\"" in out.err


def test_robust_fit_bad_file_exit_2(tmp_path, capsys):
    (tmp_path / "f.json").write_text('{"schema": "tanksynth.artefact/1", "method": "lqr"}')
    (tmp_path / "s.toml").write_text(spec_text(ROBUST.format(fit='fit = "f.json"')))
    code, out = _run("check", tmp_path / "s.toml", "--spec-only", capsys=capsys)
    assert code == 2 and "f.json" in out.err and "not a fit result" in out.err


@pytest.mark.slow
def test_non_converging_fit_exit_3(tmp_path, capsys):
    write_log(tmp_path / "est.csv", seed=1, samples=60)
    (tmp_path / "s.toml").write_text(spec_text(FIT_DESIGN.replace('validate = ["val.csv"]\n', "")
                                               + "max_iter = 1\n"))
    code, out = _run("fit", tmp_path / "s.toml", "-o", tmp_path / "o", capsys=capsys)
    assert code == 3, out.err
    assert "refused" in out.err and len(out.err.strip().splitlines()) == 1
    assert "did not converge (IPOPT status 'Maximum_Iterations_Exceeded'" in out.out
    assert not (tmp_path / "o" / "fit.json").exists()


@pytest.mark.slow
def test_robust_box_from_fit_directory_equals_intervals(fitted, tmp_path):
    from tanksynth.methods import load_spec

    root, _ = fitted
    spec_path = root / "robust.toml"
    spec_path.write_text(spec_text(ROBUST.format(fit='fit = "out"')))
    box = load_spec(spec_path).designs[0].config.uncertain
    params = json.loads((root / "out" / "fit.json").read_text())["diagnostics"]["parameters"]
    assert box == tuple((k, *v["ci95"]) for k, v in params.items())


def test_campaign_draws_follow_the_covariance():
    """Draws of `FitRun` have the fit's mean and covariance (sample estimates, 4000 draws)."""
    from tanksynth.verify.fit.campaign import FitRun

    cov = np.array([[4e-6, -1e-6], [-1e-6, 1e-6]])
    run = FitRun(("a", "b"), np.array([0.5, 0.6]), cov, np.array([0.0, 0.0]), np.array([1.0, 1.0]),
                 np.zeros(3), np.zeros(2), "")
    d = run.draws(range(4000))
    np.testing.assert_allclose(d.mean(axis=0), [0.5, 0.6], atol=1e-4)
    np.testing.assert_allclose(np.cov(d.T), cov, rtol=0.1, atol=1e-7)
    # clipped to the box
    tight = FitRun(("a", "b"), np.array([0.5, 0.6]), cov * 1e4, np.array([0.49, 0.59]),
                   np.array([0.51, 0.61]), np.zeros(3), np.zeros(2), "")
    d = tight.draws(range(100))
    assert d.min(axis=0).tolist() == [0.49, 0.59] and d.max(axis=0).tolist() == [0.51, 0.61]
    # a parameter the data do not determine (its covariance entries zero) is drawn uniformly in
    # its box, not held at its arbitrary fitted value: mean 0.5, variance 1/12 of the box squared
    flat = FitRun(("a", "b"), np.array([0.5, 0.9]), np.diag([1e-6, 0.0]), np.array([0.0, 0.0]),
                  np.array([1.0, 1.0]), np.zeros(3), np.zeros(2), "", np.array([False, True]))
    d = flat.draws(range(4000))
    assert d[:, 1].mean() == pytest.approx(0.5, abs=0.02) and d[:, 1].var() == pytest.approx(1 / 12, rel=0.1)
    np.testing.assert_allclose(d[:, 0].std(), 1e-3, rtol=0.1)


def test_fitted_text_keeps_the_rest_and_parses():
    import tomllib

    from tanksynth.spec.fitted import FittedValue, fitted_spec_text

    text = spec_text(FIT_DESIGN).replace(
        "mu20 = {value = 0.6, min = 0.3, max = 0.9, fit = true}\n",
        "\n[plant.parameters.mu20]   # a table of its own\nvalue = 0.6\nmin = 0.3\nmax = 0.9\nfit = true\n")
    values = {k: FittedValue(v, v - 0.01, v + 0.01, 0.95, "1") for k, v in TRUE.items()}
    out = fitted_spec_text(text, values, "fit.json")
    table = tomllib.loads(out)
    assert {k: table["plant"]["parameters"][k] for k in TRUE} == TRUE
    assert "design" not in table and table["operating_point"]["trim"] == "states"
    assert "# the levels these flows hold" in out  # comments kept
    assert "mu13 = 0.55  # fitted: 95 % interval [0.54, 0.56]" in out


def test_bad_data_exit_2_names_file_and_column(tmp_path, capsys):
    write_log(tmp_path / "est.csv", seed=1, samples=20)
    text = (tmp_path / "est.csv").read_text().replace("t,q1,q2,h1,h2", "t,q1,qq2,h1,h2", 1)
    (tmp_path / "bad.csv").write_text(text)
    (tmp_path / "s.toml").write_text(spec_text())
    code, out = _run("fit", tmp_path / "s.toml", "--data", tmp_path / "bad.csv", "-o", tmp_path / "o",
                     capsys=capsys)
    assert code == 2
    (line,) = out.err.strip().splitlines()
    assert "bad.csv" in line and "q2" in line
    assert not (tmp_path / "o" / "fit.json").exists()


@pytest.mark.slow
def test_parameter_at_a_bound_warns_and_fails_the_verdict(tmp_path, capsys):
    write_log(tmp_path / "est.csv", seed=1, samples=120)
    text = spec_text(FIT_DESIGN.replace('validate = ["val.csv"]\n', "")).replace(
        "mu20 = {value = 0.6, min = 0.3, max = 0.9, fit = true}",
        "mu20 = {value = 0.6, min = 0.3, max = 0.65, fit = true}")   # the data's 0.70 is outside
    (tmp_path / "s.toml").write_text(text)
    code, out = _run("fit", tmp_path / "s.toml", "-o", tmp_path / "o", capsys=capsys)
    assert code == 1, out.err
    assert "warning: fit: fitted mu20 = 0.65 lies at a bound" in out.err
    doc = json.loads((tmp_path / "o" / "fit.json").read_text())
    assert doc["diagnostics"]["parameters"]["mu20"]["at_bound"] is True
    assert any("mu20" in w for w in doc["diagnostics"]["warnings"])
    checks = {c["check"]: c for c in doc["verification"]["checks"]}
    assert checks["parameters_inside_bounds"]["passed"] is False


# ------------------------------------------------------------- a model that is not finite, quiet CasADi
_EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def _leak_spec(tmp_path: Path, edit) -> Path:
    """The leak example with its data beside it, edited by ``edit(text) -> text``."""
    (tmp_path / "data").mkdir()
    for name in ("three_tank_estimation.csv", "three_tank_validation.csv"):
        shutil.copy(_EXAMPLES / "data" / name, tmp_path / "data" / name)
    spec = tmp_path / "spec.toml"
    spec.write_text(edit((_EXAMPLES / "three_tank_fit_leak.toml").read_text()))
    return spec


def test_a_model_that_evaluates_non_finite_is_refused_with_exit_3(tmp_path, capsys):
    # y3 reads sqrt(h2 - h3): NaN wherever h3 > h2, i.e. on every logged sample (the operating
    # point, h2 > h3, passes the spec's checks)
    def edit(text: str) -> str:
        text = text.replace('y3 = {expr = "h3"', 'y3 = {expr = "h3 + 0.001*sqrt(h2 - h3)"')
        text = text.replace('trim = "states"', "").replace('orderings = ["h1 > h3", "h3 > h2"]', "")
        text = text.replace("x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}", "x = {h1 = 0.40, h2 = 0.30, h3 = 0.20}")
        return text.replace("starts = 4", "starts = 1")

    code, out = _run("fit", _leak_spec(tmp_path, edit), "-o", tmp_path / "out", capsys=capsys)
    assert code == 3
    said = out.out + out.err
    assert "non-finite" in said and "output(s) y3" in said
    assert "internal error" not in said and "LinAlgError" not in said
    assert "CasADi" not in out.out + out.err


def test_an_offset_output_counts_as_measuring_its_state():
    # y2 = h2 + b2 measures h2: the initial guess reads h2 = y2 - b2
    from tanksynth.design.fit.model import direct_states, fit_model
    from tanksynth.methods import load_spec

    spec = load_spec(_EXAMPLES / "three_tank_fit_leak.toml")
    model = fit_model(spec.plant, spec.free_parameters)
    assert model.names[-1] == "b2"
    theta = np.array([0.5, 0.5, 0.675, 0.05, 0.004])
    assert direct_states(model, theta) == {0: (0, 1.0, 0.0), 1: (1, 1.0, pytest.approx(0.004)),
                                           2: (2, 1.0, 0.0)}


@pytest.mark.slow
def test_verdict_checks_the_parameter_table_against_the_gains(fitted, tmp_path):
    """An edited parameter table (the artefact rehashed: the verdict is what stands between it
    and a user) fails `parameters_consistent`: a value that is not theta's, a stderr that is not
    the covariance's, a covariance that is not positive semidefinite, a box that is not the
    spec's, an interval that does not hold the value (breaker finding F)."""
    import copy

    from tanksynth.methods import load_directory
    from tanksynth.verify.fit.verdicts import consistency_check

    root, _ = fitted
    spec, docs = load_directory(root / "out")
    (doc,) = [d for _, d in docs]
    assert consistency_check(doc, spec).passed

    def edited(change):
        d = copy.deepcopy(doc)
        change(d["diagnostics"]["parameters"]["mu13"], d)
        return consistency_check(d, spec)

    assert not edited(lambda p, d: p.update(value=0.8)).passed
    assert not edited(lambda p, d: p.update(stderr=p["stderr"] / 10)).passed
    assert not edited(lambda p, d: p.update(ci95=[-5.0, -4.0])).passed
    assert not edited(lambda p, d: p.update(lower=0.1)).passed
    cov = np.array(doc["gains"]["covariance"], dtype=float)
    bad = cov.copy()
    bad[0, 0] = -abs(bad[0, 0])
    res = edited(lambda p, d: d.update(gains={**d["gains"], "covariance": bad}))
    assert not res.passed and "positive semidefinite" in res.detail


def test_fitted_spec_keeps_the_start_of_an_undetermined_parameter():
    """A parameter the data do not determine keeps its start value in fitted.toml (the optimum
    moves it freely along a flat cost), and the comment says so."""
    import tomllib

    from tanksynth.spec.fitted import FittedValue, fitted_spec_text

    text = ('[plant]\nmodel = "three_tank"\n[plant.parameters]\n'
            'mu13 = {value = 0.5, min = 0.2, max = 0.9, fit = true}\n'
            'hmax = {value = 0.62, min = 0.6, max = 0.9, fit = true}\n')
    out = fitted_spec_text(text, {"mu13": FittedValue(0.46, 0.45, 0.47, 0.95),
                                  "hmax": FittedValue(0.62, 0.6, 0.9, 0.95, "m", determined=False)},
                           "fit.json")
    params = tomllib.loads(out)["plant"]["parameters"]
    assert params == {"mu13": 0.46, "hmax": 0.62}
    assert "not determined by the data: start value kept" in out


def test_a_fit_directory_names_its_fit_artefact_whatever_the_design_is_called(tmp_path):
    """`fit = "DIR"` finds the fit artefact of DIR: fit.json, else the one JSON whose method is
    "fit" (a design named myfit writes myfit.json; new-user finding: only fit.json was found)."""
    from tanksynth.errors import SpecError
    from tanksynth.spec.fit_box import fit_file

    (tmp_path / "plant.json").write_text('{"schema": "tanksynth.plant/1"}')
    with pytest.raises(SpecError, match="no fit artefact"):
        fit_file(tmp_path)
    (tmp_path / "myfit.json").write_text('{"method": "fit"}')
    (tmp_path / "ekf.json").write_text('{"method": "ekf"}')
    assert fit_file(tmp_path) == tmp_path / "myfit.json"
    (tmp_path / "other.json").write_text('{"method": "fit"}')
    with pytest.raises(SpecError, match="2 fit artefacts"):
        fit_file(tmp_path)
    (tmp_path / "fit.json").write_text('{"method": "fit"}')
    assert fit_file(tmp_path) == tmp_path / "fit.json"


def test_pump_flows_logged_in_litres_per_second_are_refused(tmp_path):
    """Inputs 200-600x the pump capacity (l/s where the plant takes m^3/s) are a unit error
    (exit 2 naming the column), not a fit that fails to converge (new-user finding)."""
    from tanksynth.errors import DataError
    from tanksynth.measurements import read_experiments
    from tanksynth.plants import builtin_plant

    plant = builtin_plant("three_tank")
    (tmp_path / "log.csv").write_text("t,q1,q2,h1,h2,h3\n0,0.025,0.03,0.3,0.1,0.2\n2,0.025,0.03,0.3,0.1,0.2\n")
    with pytest.raises(DataError, match=r"column 'q1' \(input q1\).*10x.*expects m\^3/s"):
        read_experiments([tmp_path / "log.csv"], plant)


@pytest.mark.slow
def test_report_labels_start_values_of_free_parameters(fitted):
    """Issue 30 (new-user finding): section 1.2 listed mu13's start value 0.5 as the plant's
    value, unlabelled, beside a fitted 0.46 in section 4."""
    root, code = fitted
    tex = (root / "out" / "report.tex").read_text(encoding="utf-8")
    table = tex.split(r"\subsection{Signals and parameters}")[1].split(r"\subsection{Operating region}")[0]
    diag = json.loads((root / "out" / "fit.json").read_text())["diagnostics"]
    for name, row in diag["parameters"].items():
        line = next(l for l in table.splitlines() if l.startswith("$" + {"mu13": r"\mu_{13}", "mu32": r"\mu_{32}",
                                                                          "mu20": r"\mu_{20}"}[name]))
        assert "(start; fitted" in line, line
    assert "``start''" in table and "free parameter" in table


@pytest.mark.slow
def test_report_has_the_residual_autocorrelation_figure(fitted):
    """Issue 30 (new-user finding): no residual ACF plot (MATLAB resid) in the fit report."""
    root, code = fitted
    tex = (root / "out" / "report.tex").read_text(encoding="utf-8")
    assert "report-figures/acf-00-fit.pdf" in tex
    assert (root / "out" / "report-figures" / "acf-00-fit.pdf").is_file()
    assert "Residual autocorrelation of design" in tex
    # the residual figure's check is information, as its table row says (not "undecided")
    assert "Check Residual whiteness: info;" in tex and "undecided" not in tex


@pytest.mark.slow
def test_a_refused_fit_leaves_the_directory_as_it_was(tmp_path, capsys):
    """Issue 30 (new-user finding): a refused fit left plant.json, spec.toml and refused.json,
    so the fixed spec was refused as "another spec's run" until --force."""
    write_log(tmp_path / "est.csv", seed=1, samples=120)
    write_log(tmp_path / "val.csv", seed=2, samples=120)
    bad = FIT_DESIGN.replace("starts = 1", "starts = 1\nmax_iter = 1")
    (tmp_path / "bad.toml").write_text(spec_text(bad))
    (tmp_path / "good.toml").write_text(spec_text(FIT_DESIGN))
    out = tmp_path / "out"
    code, said = _run("fit", tmp_path / "bad.toml", "-o", out, capsys=capsys)
    assert code == 3, said.err
    assert not out.exists() or not any(out.iterdir())
    code, said = _run("fit", tmp_path / "good.toml", "-o", out, capsys=capsys)
    assert code == 0, said.err
    assert "--force" not in said.out + said.err


@pytest.mark.slow
def test_report_states_the_validation_floor_in_symbols(fitted):
    """Issue 30 item 9 (raw keys in typeset text): the validation check printed
    'rmse_est / s_val' and 'file.h1' keys."""
    root, code = fitted
    tex = (root / "out" / "report.tex").read_text(encoding="utf-8")
    row = next(l for l in tex.splitlines() if "validation fit" in l and "floor" in l)
    assert r"$e_{est}$" in row and r"$s_{val}$" in row
    assert "rmse" not in row and r"val.h1" not in row
