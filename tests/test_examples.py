"""Every example spec loads, passes its rank checks and designs its artefacts."""

from pathlib import Path

import numpy as np
import pytest

from tanksynth.artefacts import read_artefact, write_artefact
from tanksynth.methods import METHODS
from tanksynth.methods import load_spec
from tanksynth.analysis.checks import rank_conditions

EXAMPLES = sorted(Path(__file__).resolve().parents[1].joinpath("examples").glob("*.toml"))


def test_there_is_an_example_per_builtin_plant():
    from tanksynth.plants import BUILTIN_PLANTS

    models = {load_spec(path).plant.name for path in EXAMPLES}
    assert set(BUILTIN_PLANTS) <= models | {"three_tank"}
    assert any(load_spec(path).raw["plant"]["model"] == "custom" for path in EXAMPLES)


@pytest.mark.slow
@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_example_checks_and_designs(path, tmp_path):
    spec = load_spec(path)
    checks = rank_conditions(spec.plant, spec.x0, spec.ts, spec.given_u0, samples=50)
    failed = [c.name for c in checks if c.passed is False]
    assert failed == [], f"{path.name}: failing checks {failed}"
    # The operating point of every example is an equilibrium of its model.
    assert next(c for c in checks if c.name == "equilibrium").passed
    for design in spec.designs:
        result = METHODS[design.method].design(spec, design)
        json_path = write_artefact(result, tmp_path, spec.sha256)
        doc = read_artefact(json_path)
        assert doc["name"] == design.name
        for name, gain in result.gains.items():
            np.testing.assert_array_equal(doc["gains"][name], np.asarray(gain, dtype=float))
