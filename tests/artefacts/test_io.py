"""Artefacts: JSON + npz (+ .mat, C header), provenance, tamper detection, atomic writes."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess

import numpy as np
import pytest

import tanksynth.artefacts.atomic as atomic_mod
import tanksynth.artefacts.io as artefact_mod
from tanksynth.artefacts import SCHEMA, c_header, gains_digest, read_artefact, write_artefact
from tanksynth.design.result import DesignResult
from tanksynth.errors import ArtefactError, SpecError

SHA = "ab" * 32


def make_result(name: str = "akf", **gains) -> DesignResult:
    if not gains:
        gains = {
            "K": np.array([[1.5, -2.25e-5, 3.0], [0.1, 1e300, -7.0]]),
            "x_hat0": np.array([0.4, 0.2, 0.3]),
            "s": np.array(2.0),
        }
    diagnostics = {"status": "optimal", "eigenvalues": np.array([-1.0 + 0.5j, -1.0 - 0.5j]),
                   "margin": np.float64(1e-3), "rank": np.int64(3), "full": np.bool_(True),
                   "bad": float("inf")}
    return DesignResult(name, "linearize", "three_tank", gains, diagnostics, {"F": r"\begin{bmatrix}\end{bmatrix}"})


def listing(directory):
    return sorted(p.name for p in directory.iterdir())


def test_writes_json_and_npz(tmp_path):
    res = make_result()
    path = write_artefact(res, tmp_path / "out", SHA, solver="none")
    assert path == tmp_path / "out" / "akf.json"
    assert listing(tmp_path / "out") == ["akf.json", "akf.npz"]
    doc = json.loads(path.read_text(encoding="utf-8"))
    assert doc["schema"] == SCHEMA == "tanksynth.artefact/1"
    assert {"schema", "name", "method", "plant", "gains", "diagnostics", "verification",
            "provenance"} <= set(doc)
    assert (doc["name"], doc["method"], doc["plant"]) == ("akf", "linearize", "three_tank")
    assert doc["verification"] is None
    prov = doc["provenance"]
    assert prov["spec_sha256"] == SHA
    assert prov["solver"] == "none"
    assert prov["tanksynth_version"] and prov["tanksynth_version"] != "unknown"
    assert {"numpy", "scipy", "sympy", "casadi", "python"} <= set(prov["packages"])
    assert prov["gains_sha256"] == gains_digest(res.gains)
    assert prov["npz_sha256"] == artefact_mod.file_sha256(tmp_path / "out" / "akf.npz")
    assert prov["plant_record_sha256"] is None
    assert prov["content_sha256"] == artefact_mod.content_digest(doc)
    # gains as nested lists of floats, equal to the npz
    assert doc["gains"]["K"] == res.gains["K"].tolist()
    assert doc["gains"]["x_hat0"] == [0.4, 0.2, 0.3]
    with np.load(tmp_path / "out" / "akf.npz") as npz:
        assert set(npz.files) == set(res.gains)
        for k in res.gains:
            np.testing.assert_array_equal(npz[k], res.gains[k])
            np.testing.assert_array_equal(np.asarray(doc["gains"][k]), npz[k])
    # diagnostics are strict JSON (no NaN/Infinity tokens), complex -> [re, im]
    text = path.read_text()
    assert "Infinity" not in text and "NaN" not in text
    assert doc["diagnostics"]["bad"] == "inf"
    assert doc["diagnostics"]["eigenvalues"] == [[-1.0, 0.5], [-1.0, -0.5]]
    assert doc["diagnostics"]["rank"] == 3 and doc["diagnostics"]["full"] is True


def test_read_round_trip(tmp_path):
    res = make_result()
    path = write_artefact(res, tmp_path, SHA)
    doc = read_artefact(path)
    assert set(doc["gains"]) == set(res.gains)
    for k, v in res.gains.items():
        np.testing.assert_array_equal(doc["gains"][k], v)
        assert doc["gains"][k].shape == np.shape(v)
    assert doc["name"] == "akf"


def test_tampered_gain_refused(tmp_path):
    path = write_artefact(make_result(), tmp_path, SHA)
    doc = json.loads(path.read_text())
    doc["gains"]["K"][0][0] = 1.5000000001
    path.write_text(json.dumps(doc))
    with pytest.raises(ArtefactError, match="provenance hash"):
        read_artefact(path)
    # explicitly unchecked read still works
    assert read_artefact(path, check_gains=False)["gains"]["K"][0, 0] == 1.5000000001


def test_tampered_shape_refused(tmp_path):
    path = write_artefact(make_result(), tmp_path, SHA)
    doc = json.loads(path.read_text())
    doc["gains"]["x_hat0"] = [[0.4], [0.2], [0.3]]       # same numbers, other shape
    path.write_text(json.dumps(doc))
    with pytest.raises(ArtefactError):
        read_artefact(path)


@pytest.mark.parametrize("content,match", [
    ("not json", "not a JSON artefact"),
    ('{"schema": "other/1"}', "schema"),
    ('[1, 2]', "schema"),
    ('{"schema": "tanksynth.artefact/1", "name": "a"}', "missing key"),
    ('{"schema": "tanksynth.artefact/1", "name": "a", "method": "m", "plant": "p", '
     '"gains": {"K": "abc"}, "provenance": {}}', "nested lists"),
])
def test_malformed_artefacts_refused(tmp_path, content, match):
    path = tmp_path / "x.json"
    path.write_text(content)
    with pytest.raises(ArtefactError, match=match):
        read_artefact(path)


def test_missing_artefact(tmp_path):
    with pytest.raises(ArtefactError, match="cannot read"):
        read_artefact(tmp_path / "none.json")


def test_failing_write_leaves_nothing(tmp_path, monkeypatch):
    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(artefact_mod.np, "savez", boom)
    out = tmp_path / "out"
    with pytest.raises(OSError, match="disk full"):
        write_artefact(make_result(), out, SHA, export=("mat", "h"))
    assert listing(out) == []


def test_failing_rename_leaves_no_partial_artefact(tmp_path, monkeypatch):
    """If a later rename fails, what was renamed before is removed again."""
    real_replace = os.replace
    calls = []

    def flaky(src, dst):
        calls.append(dst)
        if len(calls) == 2:
            raise OSError("rename failed")
        return real_replace(src, dst)

    monkeypatch.setattr(atomic_mod.os, "replace", flaky)
    with pytest.raises(OSError, match="rename failed"):
        write_artefact(make_result(), tmp_path, SHA, export=("h",))
    assert listing(tmp_path) == []


def test_failing_write_keeps_previous_json(tmp_path, monkeypatch):
    first = write_artefact(make_result(), tmp_path, SHA)
    before = first.read_bytes()
    monkeypatch.setattr(artefact_mod.np, "savez", lambda *a, **k: (_ for _ in ()).throw(OSError("x")))
    with pytest.raises(OSError):
        write_artefact(make_result(K=np.eye(2)), tmp_path, SHA)
    assert first.read_bytes() == before
    assert not [n for n in listing(tmp_path) if n.endswith(".tmp")]


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_gains_refused(tmp_path, bad):
    res = make_result(K=np.array([[1.0, bad]]))
    with pytest.raises(ArtefactError, match="non-finite"):
        write_artefact(res, tmp_path / "o", SHA, export=("mat", "h"))
    assert not (tmp_path / "o").exists() or listing(tmp_path / "o") == []


def test_unknown_export_format(tmp_path):
    with pytest.raises(SpecError, match="export"):
        write_artefact(make_result(), tmp_path, SHA, export=("xlsx",))
    assert listing(tmp_path) == []


def test_mat_export(tmp_path):
    from scipy.io import loadmat

    res = make_result()
    write_artefact(res, tmp_path, SHA, export=("mat",))
    assert listing(tmp_path) == ["akf.json", "akf.mat", "akf.npz"]
    mat = loadmat(tmp_path / "akf.mat")
    np.testing.assert_array_equal(mat["K"], res.gains["K"])
    np.testing.assert_array_equal(mat["x_hat0"].ravel(), res.gains["x_hat0"])


def _parse_header(text: str) -> dict[str, np.ndarray]:
    out = {}
    dims = dict(re.findall(r"#define (\w+) (\d+)", text))
    for name, body in re.findall(r"static const double (\w+)\[\d+\] = \{([^}]*)\};", text):
        vals = np.array([float(v) for v in body.split(",")])
        rows, cols = int(dims[name.upper() + "_ROWS"]), int(dims[name.upper() + "_COLS"])
        out[name] = vals.reshape(rows, cols)
    return out


def test_c_header_values_round_trip_textually():
    res = make_result()
    parsed = _parse_header(c_header("akf", res.gains))
    np.testing.assert_array_equal(parsed["akf_K"], res.gains["K"])
    np.testing.assert_array_equal(parsed["akf_x_hat0"], res.gains["x_hat0"].reshape(-1, 1))
    np.testing.assert_array_equal(parsed["akf_s"], [[2.0]])


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed")
@pytest.mark.parametrize("name", ["akf", "2tank-v1.0"])
def test_c_header_compiles_and_values_round_trip(tmp_path, name):
    res = make_result(name)
    write_artefact(res, tmp_path, SHA, export=("h",))
    header = tmp_path / f"{name}.h"
    text = header.read_text()
    ident = re.search(r"static const double (\w+)_K\[", text).group(1)
    src = tmp_path / "main.c"
    src.write_text(
        f'#include <stdio.h>\n#include "{header.name}"\n#include "{header.name}"  /* guard */\n'
        "int main(void) {\n"
        f"  for (int i = 0; i < {ident.upper()}_K_ROWS * {ident.upper()}_K_COLS; i++)"
        f' printf("%.17g\\n", {ident}_K[i]);\n'
        f'  for (int i = 0; i < 3; i++) printf("%.17g\\n", {ident}_x_hat0[i]);\n'
        f'  printf("%.17g\\n", {ident}_s[0]);\n'
        "  return 0;\n}\n")
    subprocess.run(["gcc", "-std=c99", "-Wall", "-Werror", "-Wno-unused-const-variable",
                    "-fsyntax-only", str(src)], check=True, cwd=tmp_path)
    exe = tmp_path / "main"
    subprocess.run(["gcc", "-std=c99", "-o", str(exe), str(src)], check=True, cwd=tmp_path)
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split()
    values = np.array([float(v) for v in out])
    expected = np.concatenate([res.gains["K"].ravel(), res.gains["x_hat0"], [2.0]])
    np.testing.assert_array_equal(values, expected)     # bit-exact through the C compiler


def test_c_header_three_dimensional_gain(tmp_path):
    if shutil.which("gcc") is None:
        pytest.skip("gcc not available")
    K = np.arange(24, dtype=float).reshape(2, 3, 4) / 7.0
    header = c_header("seq", {"K": K})
    assert "#define SEQ_K_NDIM 3" in header
    assert "#define SEQ_K_DIM2 4" in header
    (tmp_path / "seq.h").write_text(header)
    (tmp_path / "main.c").write_text(
        '#include <stdio.h>\n#include "seq.h"\nint main(void){int i;'
        'for(i=0;i<SEQ_K_DIM0*SEQ_K_DIM1*SEQ_K_DIM2;i++) printf("%.17g\\n", seq_K[i]);return 0;}\n')
    subprocess.run(["gcc", "-o", str(tmp_path / "main"), str(tmp_path / "main.c")], check=True)
    out = subprocess.run([str(tmp_path / "main")], capture_output=True, text=True, check=True).stdout
    np.testing.assert_array_equal(np.array(out.split(), dtype=float), K.ravel())


def test_written_files_are_world_readable(tmp_path):
    write_artefact(make_result(), tmp_path, SHA, export=["h"])
    for path in tmp_path.iterdir():
        assert path.stat().st_mode & 0o044 == 0o044, path.name


def test_law_export_needs_a_law(tmp_path):
    with pytest.raises(SpecError, match="no control law"):
        write_artefact(make_result(), tmp_path, SHA, export=["law"])
    assert list(tmp_path.iterdir()) == []


def test_law_export_writes_casadi_and_c(tmp_path):
    import casadi as ca

    from tanksynth.runtime.laws import law_document, law_from_document

    x = ca.SX.sym("x", 2)
    law = ca.Function("demo", [x], [2 * x + 1], ["x"], ["u"])
    result = DesignResult("ctl", "demo", "custom", {"K": np.eye(2)}, {"law": law_document(law)})
    write_artefact(result, tmp_path, "0" * 64, export=["law"])
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["ctl.json", "ctl.npz", "ctl_law.c", "ctl_law.casadi", "ctl_law.h"]
    loaded = ca.Function.load(str(tmp_path / "ctl_law.casadi"))
    np.testing.assert_array_equal(np.asarray(loaded([1.0, 2.0])).ravel(), [3.0, 5.0])
    doc = read_artefact(tmp_path / "ctl.json")
    assert law_from_document(doc["diagnostics"]["law"]).name() == "demo"


def test_atomic_write_payloads_and_failure(tmp_path):
    """bytes, text and writer callables; a failing writer leaves the old file and no temp file."""
    target = tmp_path / "x.bin"
    assert atomic_mod.atomic_write(target, b"\x00\x01").read_bytes() == b"\x00\x01"
    atomic_mod.atomic_write(target, "h\u00e9")
    assert target.read_bytes() == "h\u00e9".encode("utf-8")
    assert (target.stat().st_mode & 0o777) == 0o644

    def broken(fh):
        fh.write(b"partial")
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        atomic_mod.atomic_write(target, broken)
    assert target.read_bytes() == "h\u00e9".encode("utf-8")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.bin"]


def test_nan_gain_and_foreign_name_are_refused(tmp_path):
    """A NaN gain (even with a re-computed hash) and a name that is not the file's are bad input."""
    import json

    path = write_artefact(make_result(), tmp_path, SHA)
    doc = json.loads(path.read_text())
    doc["gains"]["K"][0][0] = float("nan")
    doc["provenance"]["gains_sha256"] = gains_digest({k: np.asarray(v, dtype=float)
                                                      for k, v in doc["gains"].items()})
    path.write_text(json.dumps(doc))
    with pytest.raises(ArtefactError, match="NaN"):
        read_artefact(path)
    good = write_artefact(make_result(), tmp_path / "b", SHA)
    other = good.with_name("someone_else.json")
    good.rename(other)
    with pytest.raises(ArtefactError, match="does not match its file name"):
        read_artefact(other)


@pytest.mark.parametrize("key, value", [
    ("method", "kalman"), ("plant", "quadruple_tank"), ("latex", {"F": r"\input{/etc/passwd}"}),
    ("diagnostics", {"status": "edited"}),
])
def test_content_edited_after_design_is_refused(tmp_path, key, value):
    """Anything design wrote (not only the gains) is covered by content_sha256."""
    path = write_artefact(make_result(), tmp_path, SHA)
    doc = json.loads(path.read_text())
    doc[key] = value
    path.write_text(json.dumps(doc))
    with pytest.raises(ArtefactError, match=r"akf\.json: .*content edited after design"):
        read_artefact(path)
    read_artefact(path, check_gains=False)                  # the explicit opt-out still reads
    artefact_mod.rehash(path)                               # consistently re-written: accepted
    assert read_artefact(path)[key] == value


def test_verification_field_is_not_covered(tmp_path):
    path = write_artefact(make_result(), tmp_path, SHA)
    doc = json.loads(path.read_text())
    doc["verification"] = {"passed": True, "checks": []}
    path.write_text(json.dumps(doc))
    assert read_artefact(path)["verification"]["passed"] is True


def test_missing_content_hash_and_nan_diagnostics_are_refused(tmp_path):
    path = write_artefact(make_result(), tmp_path, SHA)
    doc = json.loads(path.read_text())
    del doc["provenance"]["content_sha256"]
    path.write_text(json.dumps(doc))
    with pytest.raises(ArtefactError, match="no content_sha256"):
        read_artefact(path)
    doc["diagnostics"]["margin"] = float("nan")               # JSON with a NaN token
    doc["provenance"]["content_sha256"] = "0" * 64
    path.write_text(json.dumps(doc))
    with pytest.raises(ArtefactError, match="canonical JSON"):
        read_artefact(path)


def test_npz_and_plant_record_checks(tmp_path):
    path = write_artefact(make_result(), tmp_path, SHA, plant_record_sha256="cd" * 32)
    doc = read_artefact(path)
    assert artefact_mod.check_npz(path, doc) == tmp_path / "akf.npz"
    (tmp_path / "plant.json").write_text("{}")
    with pytest.raises(ArtefactError, match=r"plant\.json: does not match plant_record_sha256"):
        artefact_mod.check_plant_record(tmp_path, [(path, doc)])
    np.savez(tmp_path / "akf.npz", K=np.zeros((2, 3)))
    with pytest.raises(ArtefactError, match=r"akf\.npz: does not match npz_sha256"):
        artefact_mod.check_npz(path, doc)
    np.savez(tmp_path / "other.npz", K=np.zeros(1))
    with pytest.raises(ArtefactError, match=r"other\.npz: gains file with no artefact"):
        artefact_mod.check_orphan_npz(tmp_path, ["akf"])
    (tmp_path / "other.npz").rename(tmp_path / "other.traces.npz")
    artefact_mod.check_orphan_npz(tmp_path, ["akf"])        # a verdict trace is not a gains file


def test_fast_indented_json_is_the_standard_text():
    """Issue 15: the artefact JSON is encoded list by list with the C encoder; the text is
    exactly ``json.dumps(doc, indent=2, allow_nan=False)``, NaN is still refused, and
    unusual content (tuples, numpy scalars, non-string keys) is left to json itself."""
    from tanksynth.artefacts.jsontext import dumps

    rng = np.random.default_rng(0)
    doc = {"gains": {"L": rng.normal(size=(5, 3)).tolist(), "e": []},
           "d": {"n": [1, 2.5, -0.0, 1e300, 5e-324], "mixed": [True, None, "x\u00e9\"\n", 3],
                 "nested": [[], [[1.0]], {}], "t": "caf\u00e9"}, "k": 7, "f": 0.1, "b": False}
    for value in (doc, {}, [], [[{"a": 1}]], 3.5, "s", None, {"t": (1, 2)}, {1: 2},
                  {"n": np.float64(1.5)}, [1.0, True]):
        assert dumps(value) == json.dumps(value, indent=2, allow_nan=False)
    for bad in ({"a": [float("nan")]}, {"a": float("inf")}, [1.0, float("-inf")]):
        with pytest.raises(ValueError):
            dumps(bad)
    assert artefact_mod.to_jsonable({"a": np.array([[1.0, 2.0]]), "b": np.array([1.0, np.inf]),
                                     "c": np.arange(2)}) == {"a": [[1.0, 2.0]], "b": [1.0, "inf"],
                                                             "c": [0, 1]}
