"""Pole maps (tanksynth.reports.figures): region shading, content and layout on the page."""

from __future__ import annotations

import io
import shutil
import subprocess

import numpy as np
import pytest

from tanksynth.reports.diagnostics.common import lmi_region_of
from tanksynth.reports.figures import _pole_figure, _region_margin, eigenvalue_sets, pole_map


def _pdf_draw(fig):
    """Draw with the PDF backend's renderer (72 dpi) into memory; return it."""
    from matplotlib.backends.backend_pdf import PdfFile, RendererPdf

    fig.set_dpi(72)
    w, h = fig.get_size_inches()
    pdf = PdfFile(io.BytesIO())
    pdf.newPage(w, h)
    r = RendererPdf(pdf, 72, h, w)
    fig.draw(r)
    return r


@pytest.mark.parametrize("n", [1, 2, 3])
def test_region_margin_is_minus_the_largest_eigenvalue(n):
    rng = np.random.default_rng(n)
    X, Y = np.meshgrid(np.linspace(-3.0, 1.0, 60), np.linspace(-2.0, 2.0, 50))
    Z = X + 1j * Y
    for _ in range(4):
        L = rng.standard_normal((n, n))
        L = L + L.T
        M = rng.standard_normal((n, n))
        ref = np.empty(Z.shape)
        for idx, z in np.ndenumerate(Z):        # by hand, point by point
            F = L + M * z + M.T * np.conj(z)
            ref[idx] = -np.linalg.eigvalsh(0.5 * (F + F.conj().T))[-1]
        np.testing.assert_allclose(_region_margin(L, M, Z), ref, rtol=0, atol=1e-12)


def _artefact():
    # a disk region |z + 2| < 1.5 in the s-plane: L = [[-r, q], [q, -r]], M = [[0, 1], [0, 0]]
    r, q = 1.5, -2.0
    return {"name": "demo", "method": "pole_placement",
            "diagnostics": {"time_domain": "continuous",
                            "placement": {"requested": [[-2.0, 0.5], [-2.0, -0.5], [-1.0, 0.0]],
                                          "achieved": [[-2.0, 0.5], [-2.0, -0.5], [-1.0, 0.0]]},
                            "model": {"Ad_eigenvalues": [0.9, [0.8, 0.1], [0.8, -0.1]]},
                            "region": {"L": [[-r, q], [q, -r]], "M": [[0.0, 1.0], [0.0, 0.0]],
                                       "description": "disk |s + 2| < 1.5"}}}


def test_pole_map_keeps_everything_on_the_page():
    art = _artefact()
    sets = eigenvalue_sets(art)
    region = lmi_region_of(art["diagnostics"])
    assert region is not None and region.description == "disk |s + 2| < 1.5" and region.domain == "continuous"
    np.testing.assert_array_equal(region.L, [[-1.5, -2.0], [-2.0, -1.5]])
    fig = _pole_figure(art, sets, region)
    r = _pdf_draw(fig)
    page = fig.bbox
    axes = fig.axes
    assert len(axes) == 2                                    # s-plane and z-plane
    for ax in axes:
        box = ax.get_window_extent(r)
        assert box.width == pytest.approx(box.height, rel=1e-6)
        leg = ax.get_legend().get_window_extent(r)
        assert leg.y1 <= box.y0 and page.y0 - 0.5 <= leg.y0 and page.x0 - 0.5 <= leg.x0 and leg.x1 <= page.x1 + 0.5
        for t in ax.texts + [ax.title]:
            e = t.get_window_extent(r)
            assert page.x0 - 0.5 <= e.x0 and e.x1 <= page.x1 + 0.5 and page.y0 - 0.5 <= e.y0 \
                and e.y1 <= page.y1 + 0.5, t.get_text()
    labels = [t.get_text() for t in axes[0].get_legend().get_texts()]
    # requested and achieved are equal here (exact placement): one marker, both names
    assert labels == ["requested region: disk |s + 2| < 1.5", "requested = achieved"]
    assert [t.get_text() for t in axes[1].get_legend().get_texts()] == [
        "plant (open loop): eigenvalues of Ad"]
    # the axis labels and tick labels are drawn (as texts of the axes)
    words = {t.get_text() for t in axes[0].texts}
    assert {"real part [1/s]", "imaginary part [1/s]"} <= words and len(words) >= 8


def test_pole_map_pdf_text(tmp_path):
    if not shutil.which("pdftotext"):
        pytest.skip("pdftotext not installed")
    fig = pole_map(_artefact(), tmp_path, "poles-00-demo")
    assert fig is not None and "shaded" in fig.caption
    text = subprocess.run(["pdftotext", "-raw", str(fig.path), "-"], capture_output=True, text=True,
                          check=True).stdout
    text = " ".join(text.split())
    for words in ("s-plane (continuous time)", "z-plane (discrete time)", "requested region: disk",
                  "plant (open loop): eigenvalues of Ad", "real part [1/s]", "real part"):
        assert words in text, words


def test_only_equal_eigenvalue_sets_share_a_marker():
    from tanksynth.reports.figures import _same_sets_merged

    art = _artefact()
    art["diagnostics"]["placement"]["achieved"] = [[-2.0, 0.5], [-2.0, -0.5], [-1.001, 0.0]]
    labels = [label for _, label in _same_sets_merged([s for s in eigenvalue_sets(art) if not s.discrete])]
    assert labels == ["requested", "achieved"]
    art["diagnostics"]["placement"]["achieved"] = [[-1.0, 1e-13], [-2.0, -0.5], [-2.0, 0.5 + 1e-12]]
    labels = [label for _, label in _same_sets_merged([s for s in eigenvalue_sets(art) if not s.discrete])]
    assert labels == ["requested = achieved"]


def test_per_model_eigenvalue_lists_are_one_set_of_every_model():
    """The synthesis designs store one eigenvalue list per model of their polytope: one set
    (their pole maps were missing: the nested lists were not read)."""
    art = {"diagnostics": {"time_domain": "discrete", "synthesis": {"closed_loop_eigenvalues": [
        [[0.96, 0.0], [0.97, 0.1], [0.97, -0.1]], [[0.95, 0.0], [0.5, 0.0], [0.6, 0.0]]]}}}
    (s,) = eigenvalue_sets(art)
    assert s.discrete and s.values == (0.96, 0.97 + 0.1j, 0.97 - 0.1j, 0.95, 0.5, 0.6)
    bad = {"diagnostics": {"synthesis": {"closed_loop_eigenvalues": [[[0.9, 0.0]], [["x"]]]}}}
    assert eigenvalue_sets(bad) == ()


def test_an_observers_closed_loop_is_its_error_dynamics():
    """The synthesis observers store their A - L C eigenvalues as ``closed_loop_eigenvalues``:
    labelled as the error dynamics for an observer artefact (gain L, no K)."""
    diag = {"time_domain": "discrete", "synthesis": {"closed_loop_eigenvalues": [[[0.7, 0.0]]]}}
    (obs,) = eigenvalue_sets({"gains": {"L": [[1.0]], "X": [[1.0]]}, "diagnostics": diag})
    (ctl,) = eigenvalue_sets({"gains": {"K": [[1.0]], "X": [[1.0]]}, "diagnostics": diag})
    assert obs.label == "achieved: error dynamics" and ctl.label == "achieved: closed loop"


def test_a_printed_gain_and_a_printed_closed_loop_matrix_are_told_apart():
    from tanksynth.reports.figures import eigen_label

    assert eigen_label("reference_gain.reference_closed_loop_eigenvalues") == "with the gain printed in the paper"
    assert eigen_label("reference_closed_loop.reference_eigenvalues") == \
        "of the closed-loop matrix printed in the paper"


def test_matplotlib_font_fallbacks_stay_off_stderr(capfd):
    """A stale matplotlib font cache makes it log 'findfont: ... not found' warnings through
    logging's last-resort handler (stderr): the CLI's stderr carries one line at most (a signal
    test saw these lines in a fresh clone), so the report package lets only matplotlib's errors
    through."""
    import logging

    import tanksynth.reports  # noqa: F401  (sets the level)

    logging.getLogger("matplotlib.font_manager").warning("findfont: Font family ['STIXGeneral'] not found.")
    assert "findfont" not in capfd.readouterr().err
    assert logging.getLogger("matplotlib").getEffectiveLevel() == logging.ERROR
