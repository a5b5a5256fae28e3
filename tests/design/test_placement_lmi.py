"""Pole placement in LMI regions: gains, re-check, refusals."""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.analysis.lmi_region import disk, half_plane, sector
from tanksynth.design.placement_lmi import lmi_observer, lmi_state_feedback
from tanksynth.errors import DimensionError, InfeasibleDesign, SpecError, UncontrollableError, UnobservableError


def random_system(n=4, m=2, seed=0):
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n, n)), rng.standard_normal((n, m))


# -------------------------------------------------------------- LMI placement
def test_state_feedback_in_half_plane_and_sector():
    A, B = random_system()
    region = half_plane(0.5) & sector(np.radians(40))
    res = lmi_state_feedback(A, B, region)
    lam = np.linalg.eigvals(A - B @ res.gain)
    assert all(region.contains(z) for z in lam)
    assert all(c.passed for c in res.checks) and res.achieved_margin >= res.margin
    # P is a Lyapunov matrix of the closed loop
    Acl = A - B @ res.gain
    assert np.max(np.linalg.eigvalsh(Acl.T @ res.P + res.P @ Acl)) < 0


def test_observer_in_a_discrete_disk():
    A, B = random_system(seed=1)
    Ad = 0.5 * A / np.max(np.abs(np.linalg.eigvals(A)))
    C = B.T
    region = disk(0.2, 0.5)
    res = lmi_observer(Ad, C, region, domain="discrete")
    lam = np.linalg.eigvals(Ad - res.gain @ C)
    assert res.kind == "observer" and all(region.contains(z) for z in lam)
    assert res.as_dict()["scaling"]["formulation"] == "dual (A', C')"
    # P is a Lyapunov matrix of the discrete error dynamics
    Acl = Ad - res.gain @ C
    assert np.max(np.linalg.eigvalsh(Acl.T @ res.P @ Acl - res.P)) < 0


def test_infeasible_region_raises_with_the_achievable_margin():
    A, B = random_system()
    with pytest.raises(InfeasibleDesign, match=r"largest achievable margin t\* = "):
        lmi_state_feedback(A, B, disk(-100.0, 1e-3), kappa=1.5)


def test_region_outside_stability_domain_is_refused():
    A, B = random_system()
    with pytest.raises(SpecError, match="stability domain"):
        lmi_state_feedback(A, B, half_plane(-1.0))
    with pytest.raises(SpecError, match="stability domain"):
        lmi_state_feedback(A, B, half_plane(1.0), domain="discrete")


def test_uncontrollable_and_unobservable_are_named():
    A = np.diag([-1.0, -2.0, -3.0])
    B = np.array([[1.0], [1.0], [0.0]])
    with pytest.raises(UncontrollableError, match="x3"):
        lmi_state_feedback(A, B, half_plane(1.0), state_names=None)
    with pytest.raises(UnobservableError, match="h3"):
        lmi_observer(A, B.T, half_plane(1.0), state_names=["h1", "h2", "h3"])


def test_lmi_placement_bad_inputs():
    A, B = random_system()
    with pytest.raises(DimensionError):
        lmi_state_feedback(A, B[:3], half_plane(1.0))
    with pytest.raises(SpecError):
        lmi_state_feedback(A, B, half_plane(1.0), domain="hybrid")
    with pytest.raises(SpecError):
        lmi_state_feedback(A, B, half_plane(1.0), margin=2.0)
    with pytest.raises(SpecError):
        lmi_state_feedback(A, B, "disk")
