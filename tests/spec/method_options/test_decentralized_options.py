"""Options of ``decentralized_kalman`` (spec/method_options/decentralized.py): covariances are
bounded in size, and a too-large one is a spec error on its own key (it used to reach the
design as a non-finite ``Q_seq`` keyed by the whole design table)."""

from __future__ import annotations

import pytest

from tanksynth.errors import SpecError
from tanksynth.methods import parse_spec_text

_SPEC = """
[plant]
model = "tank_network"
N = 4
[operating_point]
x = [21.70591608, 22.54471524, 9.04293578, 5.08665138]
u = [4.0, 4.0]
[sampling]
ts = 1.0
[[design]]
name = "dk"
method = "decentralized_kalman"
window = 5
"""
_NOISE = {"process_noise": "0.01", "measurement_noise": "4.0", "initial_covariance": "10.0"}


def _spec(**override: str) -> str:
    values = {**_NOISE, **override}
    return _SPEC + "".join(f"{k} = {v}\n" for k, v in values.items())


@pytest.mark.parametrize("key", sorted(_NOISE))
@pytest.mark.parametrize("value", ["1e300", "[1e13, 1.0, 1.0, 1.0]"])
def test_huge_covariance_is_refused_on_its_key(key, value):
    with pytest.raises(SpecError) as info:
        parse_spec_text(_spec(**{key: value}))
    assert info.value.key == f"design[0].{key}"
    assert "1e+12" in str(info.value) or "at most 1e12" in str(info.value)


def test_large_but_sane_covariance_is_accepted():
    spec = parse_spec_text(_spec(initial_covariance="1e6"))
    assert spec.designs[0].config.initial_covariance == 1e6


@pytest.mark.parametrize("key, value", [("run_steps", "-1"), ("input_after", "[4.0]"),
                                        ("input_switch", "-5.0"), ("run_x0", "[1.0, 2.0]"),
                                        ("run_seed", "-3")])
def test_long_run_options_refused_on_their_key(key, value):
    with pytest.raises(SpecError) as info:
        parse_spec_text(_spec(**{key: value}))
    assert info.value.key == f"design[0].{key}"


def test_long_run_options_read():
    spec = parse_spec_text(_spec(run_steps="30", input_after="[3.0, 3.5]", input_switch="10.0",
                                 run_x0="[20.0, 20.0, 20.0, 20.0]", run_seed="2"))
    o = spec.designs[0].options
    assert (o["run_steps"], o["input_switch"], o["run_seed"]) == (30, 10.0, 2)
    assert list(o["input_after"]) == [3.0, 3.5] and list(o["run_x0"]) == [20.0] * 4
