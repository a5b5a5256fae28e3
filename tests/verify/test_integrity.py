"""Every file of an artefact is covered by its integrity check (issue 19, item 2).

Each tampering of a designed directory -- gains changed only in the NPZ, two NPZs swapped,
an NPZ deleted, a JSON deleted with its NPZ kept, ``method`` set to another valid method,
edited diagnostics or LaTeX, an edited ``plant.json`` -- makes ``tanksynth verify DIR`` exit 2
with one line naming the file; an untouched directory still verifies.
"""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tanksynth.artefacts.io import rehash
from tanksynth.cli import main

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
A, B = "integral_pole_placement", "integral_lmi_disk"


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    out = tmp_path_factory.mktemp("integrity") / "pp"
    assert main(["design", str(EXAMPLES / "seed000_pole_placement.toml"), "-o", str(out)]) == 0
    return out


@pytest.fixture
def d(designed, tmp_path):
    return Path(shutil.copytree(designed, tmp_path / "pp"))


def _refused(d, capsys, filename, *words):
    assert main(["verify", str(d)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    assert filename in err, err
    for word in words:
        assert word in err, err
    for name in (A, B):                      # nothing written
        assert json.loads((d / f"{name}.json").read_text())["verification"] is None


def _edit(path, mutate):
    doc = json.loads(path.read_text())
    mutate(doc)
    path.write_text(json.dumps(doc, indent=2))


def test_untouched_directory_verifies(d, capsys):
    assert main(["verify", str(d)]) == 0
    assert main(["verify", str(d)]) == 0      # the verification field is not covered: re-verifiable


def test_gain_changed_only_in_npz(d, capsys):
    with np.load(d / f"{A}.npz") as z:
        gains = {k: z[k] for k in z.files}
    first = sorted(gains)[0]
    gains[first] = gains[first] * 1.01
    np.savez(d / f"{A}.npz", **gains)
    _refused(d, capsys, f"{A}.npz", "npz_sha256")


def test_npz_files_swapped(d, capsys):
    (d / f"{A}.npz").rename(d / "tmp.bin")
    (d / f"{B}.npz").rename(d / f"{A}.npz")
    (d / "tmp.bin").rename(d / f"{B}.npz")
    _refused(d, capsys, ".npz", "npz_sha256")


def test_npz_deleted(d, capsys):
    (d / f"{B}.npz").unlink()
    _refused(d, capsys, f"{B}.npz", "missing")


def test_json_deleted_npz_kept(d, capsys):
    (d / f"{B}.json").unlink()
    assert main(["verify", str(d)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"{B}.npz" in err and "no artefact" in err, err


def test_trace_files_are_not_orphans(d, capsys):
    assert main(["verify", str(d)]) == 0
    assert (d / f"{A}.traces.npz").exists()           # written by the first verify
    assert main(["verify", str(d)]) == 0


@pytest.mark.parametrize("mutate", [
    pytest.param(lambda doc: doc.update(method="lmi_placement"), id="method-other-valid"),
    pytest.param(lambda doc: doc.update(method="evil"), id="method-evil"),
    pytest.param(lambda doc: doc.update(plant="custom"), id="plant"),
    pytest.param(lambda doc: doc["diagnostics"].update(note="edited"), id="diagnostics"),
    pytest.param(lambda doc: doc.update(latex={"K": r"\input{/etc/passwd}"}), id="latex"),
    pytest.param(lambda doc: doc["provenance"].update(solver="other"), id="provenance"),
    pytest.param(lambda doc: doc["provenance"].pop("content_sha256"), id="no-content-hash"),
])
def test_json_content_edited(d, capsys, mutate):
    _edit(d / f"{A}.json", mutate)
    _refused(d, capsys, f"{A}.json", "content_sha256")


def test_plant_record_edited(d, capsys):
    _edit(d / "plant.json", lambda doc: doc["operating_point"].update(x=[0.5, 0.2, 0.3]))
    _refused(d, capsys, "plant.json", "plant_record_sha256")


def test_plant_record_deleted(d, capsys):
    (d / "plant.json").unlink()
    _refused(d, capsys, "plant.json", "missing")


def test_rehash_makes_a_consistent_design(d, capsys):
    """`rehash` recomputes every digest: an edited JSON then reads as a (wrong) design, NPZ included."""
    def scale(doc):
        doc["gains"]["K"] = (np.asarray(doc["gains"]["K"]) * 3.0).tolist()
    _edit(d / f"{A}.json", scale)
    rehash(d / f"{A}.json")
    with np.load(d / f"{A}.npz") as z:
        np.testing.assert_array_equal(z["K"], np.asarray(json.loads((d / f"{A}.json").read_text())
                                                         ["gains"]["K"]))
    assert main(["verify", str(d)]) in (0, 1)          # judged, not refused
