"""Key figures of the run summary for the convex-synthesis, robust and TS-control methods."""

from tanksynth.summary import key_figure


def _doc(*checks):
    return {"verification": {"checks": [{"check": name, "data": data} for name, data in checks]}}


def test_hinf_key_figure_is_the_recomputed_norm():
    doc = _doc(("h2_norm", {"value": 0.5}), ("hinf_norm", {"value": 0.123456}))
    assert key_figure(doc) == "||T_zw||inf = 0.1235 (recomputed)"
    assert key_figure(_doc(("h2_norm", {"value": 0.5}))) == "||T_zw||2 = 0.5 (recomputed)"
    h2_design = dict(doc, method="h2_state_feedback")
    assert key_figure(h2_design) == "||T_zw||2 = 0.5 (recomputed)"


def test_robust_key_figure_is_the_worst_vertex_margin():
    doc = _doc(("vertex_region", {"margins": [0.3, 0.0027, 0.1]}))
    assert key_figure(doc) == "region margin -lambda_max(f_D) 0.0027 at the worst of 3 models"


def test_robust_key_figure_shows_the_hinf_norm_against_gamma():
    """With an H-infinity channel: the largest recomputed vertex norm against gamma, and whether
    the bound was imposed (a loose gamma is met by the design without it)."""
    doc = _doc(("vertex_region", {"margins": [0.3, 0.0027]}),
               ("vertex_hinf", {"norms": [0.0123, 0.0495, 0.02], "gamma": 10.0}))
    assert key_figure(doc).endswith("; ||T_zw||inf 0.0495 <= gamma 10")
    loose = dict(doc, diagnostics={"robust": {"hinf": {"gamma": 10.0, "imposed": False}}})
    assert key_figure(loose).endswith("; ||T_zw||inf 0.0495 <= gamma 10 (not binding)")


def test_ts_control_key_figure_is_the_certified_radius_with_its_unit():
    doc = _doc(("region_recheck", {"inner_radius": 0.0412, "c": 1.0}))
    assert key_figure(doc, ["m", "m", "m"]) == "certified region: ball of radius 0.0412 m around x_op"


def test_fault_detector_and_linearisation_key_figures():
    doc = _doc(("no_false_alarm", {"healthy_margin": 1e-9}),
               ("fault_detected", {"t_detect": [2.0170, 2.0152, 2.0127], "t_fault": 2.0}))
    doc["verification"]["checks"][0]["passed"] = True
    assert key_figure(doc) == "fault detected 0.017 s after it occurs (worst of 3 runs); no false alarm"
    lin = _doc(("first_order_agreement", {"relative_errors": [8.1e-14, 1.75e-13, 4.5e-13]}))
    assert key_figure(lin) == "first-order agreement with the nonlinear plant: relative error 4.5e-13"


def test_a_norm_above_gamma_is_not_printed_as_within_it():
    doc = _doc(("vertex_region", {"margins": [0.3]}), ("vertex_hinf", {"norms": [0.2, 12.5], "gamma": 10.0}))
    assert key_figure(doc).endswith("; ||T_zw||inf 12.5 > (EXCEEDS) gamma 10")


def test_a_fault_missed_in_a_run_is_said_so():
    """The verdict records None for a run whose fault was never detected (float(None) crashed the summary)."""
    doc = _doc(("no_false_alarm", {}), ("fault_detected", {"t_detect": [2.017, None, 2.0127], "t_fault": 2.0}))
    doc["verification"]["checks"][0]["passed"] = True
    assert key_figure(doc) == "fault NOT detected in 1 of 3 runs; no false alarm"


def test_edited_verification_data_gives_no_key_figure_not_an_exception():
    bad = [("poles", {"achieved": None}), ("poles", {"achieved": ["x"]}), ("poles", "achieved"),
           ("first_order_agreement", {"relative_errors": [None]}), ("hinf_norm", {"value": "x"}),
           ("fault_detected", {"t_detect": ["x"], "t_fault": 2.0}), ("vertex_region", {"margins": []})]
    for name, data in bad:
        figure = key_figure(_doc((name, data)))
        assert figure in ("- (unreadable verification data)", "-"), (name, data, figure)
    for ver in ("x", [1], {"checks": "x"}, {"checks": [1, None]}):
        assert key_figure({"verification": ver}) == "-"
    from tanksynth.summary import summary_row
    assert summary_row({"name": "a", "verification": "x"}).passed is False
    assert summary_row({"name": "a", "verification": {"passed": "false"}}).passed is False


def test_output_feedback_key_figure_states_the_initial_estimation_error_allowed():
    """Issue 30.17: the certified ball holds for an exact initial estimate only."""
    doc = dict(_doc(("region_recheck", {"inner_radius": 0.0212, "c": 1.0})),
               diagnostics={"composite": {"initial_error": {"error_ball_at_x_op": 0.0011,
                                                            "plant_ball_estimate_at_x_op": 0.00109}}})
    text = key_figure(doc, ["m", "m", "m"])
    assert text.startswith("certified region: ball of radius 0.0212 m around x_op with the estimate starting exact")
    assert "initial estimation error up to 0.0011 m" in text and "0.00109 m of x_op" in text
