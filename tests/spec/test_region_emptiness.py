"""Issue 30 item 16: an LMI region whose parts do not intersect is refused at spec validation
(exit 2: no plant can meet it), naming the parts; the emptiness test is exact.

Reference: membership written from each part's definition (``Re z < -alpha``, ``|z - c| < r``,
``|Im z| < tan(theta) (-Re z)``), tested on a dense grid of the complex plane.
"""

from __future__ import annotations

import numpy as np
import pytest

from tanksynth.errors import SpecError
from tanksynth.methods import parse_spec_text
from tanksynth.spec.options import region_emptiness, region_real_interval


def _inside(part: tuple, z: np.ndarray) -> np.ndarray:
    if part[0] == "half_plane":
        return z.real < -part[1]
    if part[0] == "disk":
        return np.abs(z - part[1]) < part[2]
    return np.abs(z.imag) < np.tan(part[1]) * (-z.real)


def _random_parts(rng: np.random.Generator) -> tuple[tuple, ...]:
    parts = []
    for _ in range(rng.integers(2, 4)):
        kind = rng.choice(["half_plane", "disk", "sector"])
        if kind == "half_plane":
            parts.append(("half_plane", float(rng.uniform(-2, 2))))
        elif kind == "disk":
            parts.append(("disk", float(rng.uniform(-2, 2)), float(rng.uniform(0.1, 1.5))))
        else:
            parts.append(("sector", float(rng.uniform(0.1, 1.4))))
    return tuple(parts)


def test_emptiness_agrees_with_membership_on_a_grid():
    re, im = np.meshgrid(np.linspace(-5, 5, 801), np.linspace(-5, 5, 801))
    grid = re + 1j * im
    rng = np.random.default_rng(30)
    empties = 0
    for _ in range(300):
        parts = _random_parts(rng)
        member = np.ones(grid.shape, dtype=bool)
        for part in parts:
            member &= _inside(part, grid)
        lo, hi = region_real_interval(parts)
        if region_emptiness(parts):
            empties += 1
            assert not member.any(), parts
        else:  # a witness: the interval's real point lies in every part
            witness = complex(hi - 1e-9 if lo == -np.inf else 0.5 * (lo + hi), 0.0)
            assert all(_inside(p, np.array([witness]))[0] for p in parts), parts
    assert 20 < empties < 280  # both cases exercised


SPEC = """
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {{h1 = 0.40, h2 = 0.20, h3 = 0.30}}
[[design]]
name = "d"
method = "{method}"
{extra}
region = [{{type = "half_plane", alpha = 0.5}}, {{type = "disk", center = 0.3, radius = 0.1}}]
"""


@pytest.mark.parametrize("method, extra", [("lmi_placement", 'target = "state_feedback"'),
                                           ("multiobjective", 'target = "state_feedback"\ntime_domain = "continuous"'),
                                           ("robust_state_feedback", "")])
def test_empty_region_is_refused_at_spec_validation_naming_its_parts(method, extra):
    with pytest.raises(SpecError, match="the region is empty") as info:
        parse_spec_text(SPEC.format(method=method, extra=extra))
    assert info.value.key == "design[0].region"
    text = str(info.value)
    assert "below -0.5" in text and "(0.2, 0.4)" in text
