"""The design section's view of one artefact (`tanksynth.reports.designs`)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tanksynth.methods import STATEMENTS
from tanksynth.reports.designs import design_view

ROOT = Path(__file__).resolve().parents[2]


def _pole_placement_artefact() -> dict:
    # the diagnostics a pole placement records: the placement's own numbers, copied again by
    # its accuracy check and its robustness analysis (same keys, same values)
    err, cond, norm = 7.589e-12, 129.17227877763986, 0.0024707195603124793
    return {"name": "pp", "method": "pole_placement", "gains": {}, "diagnostics": {
        "placement": {"max_pole_error": err, "eigenvector_condition": cond, "gain_norm": norm,
                      "accuracy": {"max_pole_error": err, "passed": True}},
        "robustness": {"eigenvector_condition": cond, "gain_norm": norm,
                       "stability_radius": 0.0027}}}


def test_margins_show_each_quantity_once_with_the_plain_label():
    view = design_view(_pole_placement_artefact(), None, STATEMENTS)
    labels = [str(k) for k, _ in view.margins]
    assert labels == ["largest error of the placed poles", "norm of the gain",
                      "condition number of the closed-loop eigenvectors"]
    assert not any("robustness" in k or "accuracy" in k for k in labels)


def test_margins_keep_different_values_of_one_key():
    art = _pole_placement_artefact()
    art["diagnostics"]["robustness"]["gain_norm"] = 0.5  # a different gain: a different quantity
    labels = [str(k) for k, _ in design_view(art, None, STATEMENTS).margins]
    assert labels.count("norm of the gain") == 1 and "gain norm (robustness)" in labels
    assert len(labels) == 4


def test_lmi_gain_norm_duplicate_is_dropped():
    art = {"name": "lmi", "method": "lmi_placement", "gains": {}, "diagnostics": {
        "lmi": {"margin": 1e-6, "achieved_margin": 0.0131, "gain_norm": 0.00138},
        "robustness": {"gain_norm": 0.00138, "eigenvector_condition": 456.5}}}
    labels = [str(k) for k, _ in design_view(art, None, STATEMENTS).margins]
    assert sum("gain" in k for k in labels) == 1 and len(labels) == 4
    assert "norm of the gain" in labels      # the plain label, not "gain norm (robustness)"
    # the same diagnostics with the robustness record first: the same rows
    art["diagnostics"] = {"robustness": art["diagnostics"]["robustness"], "lmi": art["diagnostics"]["lmi"]}
    again = [str(k) for k, _ in design_view(art, None, STATEMENTS).margins]
    assert sorted(again) == sorted(labels)


def _sign(relation: str) -> str:
    return {"<=": r"\le", "<": "<", ">=": r"\ge", ">": ">"}[relation]


@pytest.mark.slow
def test_saturation_recheck_rows_state_their_test_and_tolerance(tmp_path):
    """Issue 30.2: a re-check row whose value lies above its limit (1.0000000074 against 1) and
    passes on a tolerance prints the test made (direction, limit, tolerance) and enough digits to
    show the value is past the limit; every recorded row's verdict is its own test, recomputed."""
    from tanksynth.artefacts import read_artefact
    from tanksynth.cli import main

    assert main(["design", str(ROOT / "examples" / "three_tank_robust.toml"), "-o", str(tmp_path)]) == 0
    art = read_artefact(tmp_path / "robust_saturation.json")
    records = art["diagnostics"]["robust"]["checks"]
    assert records and all(r["relation"] in ("<=", "<", ">=", ">") for r in records)
    for r in records:    # the verdict is the recorded test, recomputed here
        v, lim, tol = r["value"], r["limit"], r["tolerance"]
        expected = {"<=": v <= lim + tol, "<": v < lim + tol, ">=": v >= lim - tol, ">": v > lim - tol}
        assert r["passed"] is expected[r["relation"]], r
    view = design_view(art, None, STATEMENTS)
    past = [(r, row) for r, row in zip(records, view.checks) if r["value"] > r["limit"] and r["relation"] == "<="]
    assert past, "the example has rows passing on the tolerance alone"
    for r, row in past:
        assert str(row["limit"]).startswith("$" + _sign("<=")) and "(tolerance)" in str(row["limit"])
        assert "10^{-6}" in str(row["limit"])
        shown = float(str(row["value"]).strip("$"))
        assert shown > r["limit"]      # not rounded back to the limit


def test_optimal_inaccurate_status_is_explained():
    art = {"name": "x", "method": "lmi_placement", "gains": {}, "diagnostics": {
        "lmi": {"status": "optimal_inaccurate", "solver": "CLARABEL"}}}
    note = str(design_view(art, None, STATEMENTS).status_note).replace(r"\allowbreak{}", "")
    assert "optimal" in note and "re-check" in note and "not" in note and "proven" in note
    art["diagnostics"]["lmi"]["status"] = "optimal"
    assert str(design_view(art, None, STATEMENTS).status_note) == ""


def test_a_value_just_under_its_limit_never_prints_above_it():
    """New-user pass: 0.039736887 <= 0.0397369 printed as '0.03974 <= 0.0397369' read as false.
    The value gets the digits that make the printed numbers compare as the true ones do."""
    def shown(tex: object) -> float:
        text = str(tex).strip("$")
        if r"\times" in text:          # m \times 10^{e}
            m, e = text.split(r"\times")
            return float(m) * 10.0 ** float(e.strip().removeprefix("10^{").removesuffix("}"))
        return float(text)

    for value, limit in ((0.039736887, 0.0397369), (0.999999, 1.0), (1.0, 1.0), (0.5, 1.0)):
        art = {"name": "x", "method": "robust_state_feedback", "gains": {}, "diagnostics": {
            "robust": {"checks": [{"name": "H2 norm", "value": value, "limit": limit,
                                   "relation": "<=", "tolerance": 4e-8, "passed": True}]}}}
        row = design_view(art, None, STATEMENTS).checks[0]
        limit_shown = shown(str(row["limit"]).split(r"\le")[1].split("+")[0])
        assert (shown(row["value"]) <= limit_shown) == (value <= limit), (row["value"], row["limit"])
        assert (shown(row["value"]) == limit_shown) == (value == limit), (row["value"], row["limit"])
