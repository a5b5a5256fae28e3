"""The fit report's residual autocorrelation figure (issue 30: MATLAB's ``resid`` was missing)."""

from __future__ import annotations

import numpy as np

from tanksynth.reports.fit_figures import residual_acf, residual_acf_figure


def _artefact(acf, band, samples):
    return {"name": "fit", "method": "fit", "diagnostics": {"estimation": {"whiteness": {
        "h1": {"autocorrelation": list(acf), "band": band, "statistic": 40.0, "bound": 31.41,
               "samples": samples, "passed": False}}}}}


def test_figure_draws_the_recorded_autocorrelation_and_the_white_noise_band(tmp_path):
    rng = np.random.default_rng(0)
    e = rng.standard_normal(400)
    e = e - e.mean()
    acf = np.array([e[k:] @ e[:-k] for k in range(1, 11)]) / (e @ e)   # the textbook estimate
    band = 1.96 / np.sqrt(e.size)
    art = _artefact(acf, band, e.size)
    [(name, values, got_band, _)] = residual_acf(art)
    assert name == "h1" and np.array_equal(values, acf) and got_band == band
    fig = residual_acf_figure(art, tmp_path, "acf-00-fit")
    assert fig is not None and fig.path.is_file() and fig.path.stat().st_size > 1000
    assert "lags 1 to 10" in fig.caption and "N = 400" in fig.caption


def test_no_figure_for_other_methods_or_without_the_record(tmp_path):
    assert residual_acf_figure({"name": "k", "method": "lqr", "diagnostics": {}}, tmp_path, "x") is None
    assert residual_acf_figure({"name": "f", "method": "fit", "diagnostics": {}}, tmp_path, "x") is None
    assert not list(tmp_path.iterdir())
