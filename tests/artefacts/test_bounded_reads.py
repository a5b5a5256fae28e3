"""Issue 31: every result file is read bounded, and the NPZ and the traces are the ones verified.

A FIFO in place of a trace file is refused instead of blocking the reader; a small trace or
gains file that decompresses to gigabytes (a zip bomb) is refused from its members' declared
sizes and ``.npy`` headers before anything is allocated; an NPZ whose gains are not the JSON's
is refused even with every hash recomputed; the trace is covered by a hash verify records
(``verification.traces_sha256``, kept current by `rehash`); a 400-digit gain is bad input naming
the file and the key; temporary files of a killed write are removed by the next run under the
lock, never a user's file.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import tanksynth
from tanksynth.artefacts import write_artefact
from tanksynth.artefacts.io import check_npz, content_digest, read_artefact, rehash
from tanksynth.artefacts.traces import read_trace, write_trace
from tanksynth.design.result import DesignResult
from tanksynth.errors import ArtefactError

#: The tree the tested tanksynth comes from (the child process imports the same one).
PACKAGE_ROOT = Path(tanksynth.__file__).resolve().parents[1]
SHA = "ab" * 32
GAINS = {"K": np.array([[1.5, -2.25e-5, 3.0], [0.1, 4.0, -7.0]]), "s": np.array(2.0)}


def _artefact(directory: Path) -> Path:
    result = DesignResult("akf", "linearize", "three_tank", GAINS, {"status": "optimal"}, {})
    return write_artefact(result, directory, SHA)


def _trace() -> dict:
    t = np.arange(7, dtype=float)
    rng = np.random.default_rng(0)
    return {"header": {"schema": "tanksynth.traces/1", "check": "regulation", "runs": 2},
            "arrays": {"t": t, "x": rng.normal(size=(2, 7, 3)), "t_u": t[:-1], "u": rng.normal(size=(2, 6, 2))}}


def _bomb(path: Path, members: dict[str, np.ndarray], key: str, values: int) -> Path:
    """An .npz of ``members`` plus ``key``: a float64 array of ``values`` zeros, deflated while
    streamed (the test never holds it in memory)."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, arr in members.items():
            with zf.open(f"{name}.npy", "w", force_zip64=True) as fh:
                np.lib.format.write_array(fh, np.asarray(arr), allow_pickle=False)
        with zf.open(f"{key}.npy", "w", force_zip64=True) as fh:
            np.lib.format.write_array_header_1_0(fh, {"descr": "<f8", "fortran_order": False,
                                                      "shape": (values,)})
            chunk = bytes(1 << 20)
            for _ in range(values * 8 // len(chunk)):
                fh.write(chunk)
    return path


def _record_npz(json_path: Path) -> None:
    """Recompute npz_sha256 and content_sha256 for whatever NPZ lies beside the JSON (what an
    editor of the NPZ would do), with the package's own digest functions."""
    doc = json.loads(json_path.read_text())
    doc["provenance"]["npz_sha256"] = hashlib.sha256(json_path.with_suffix(".npz").read_bytes()).hexdigest()
    doc["provenance"]["content_sha256"] = content_digest(doc)
    json_path.write_text(json.dumps(doc, indent=2))


# ---- item 1: a FIFO in place of a trace file -----------------------------------------------

def test_a_fifo_trace_is_refused_not_blocking(tmp_path):
    fifo = tmp_path / "akf.traces.npz"
    os.mkfifo(fifo)
    code = f"from tanksynth.artefacts.traces import read_trace; read_trace({str(fifo)!r})"
    try:   # a child process: a regression blocks in open() and fails here, not the suite
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                              env={**os.environ, "PYTHONPATH": str(PACKAGE_ROOT)})
    except subprocess.TimeoutExpired:
        pytest.fail("read_trace blocked on a FIFO")
    assert proc.returncode != 0
    last = proc.stderr.strip().splitlines()[-1]
    assert "ArtefactError" in last and str(fifo) in last and "not a regular file" in last, proc.stderr


# ---- item 3: trace members bounded before loading, traces hashed --------------------------

def test_a_trace_zip_bomb_is_refused_from_its_member_header(tmp_path):
    """256 MiB of zeros deflate to about 256 KiB; read_trace refuses the member from its header."""
    good = read_trace(write_trace(tmp_path / "ok.traces.npz", _trace()))
    header = np.array(json.dumps(_trace()["header"]))
    bomb = _bomb(tmp_path / "akf.traces.npz", {"header": header, "t": good["arrays"]["t"]}, "x", 32 * 1024 ** 2)
    assert bomb.stat().st_size < 2 * 1024 ** 2
    with pytest.raises(ArtefactError, match=r"akf\.traces\.npz: member 'x\.npy'"):
        read_trace(bomb)


def test_a_trace_member_declaring_more_than_the_limits_is_refused(tmp_path):
    """A member's header with a shape far beyond the trace limits (and a file of a few bytes)."""
    path = tmp_path / "akf.traces.npz"
    with zipfile.ZipFile(path, "w") as zf:
        with zf.open("header.npy", "w") as fh:
            np.lib.format.write_array(fh, np.array(json.dumps({"check": "a"})))
        with zf.open("x.npy", "w") as fh:  # 8 GiB announced, 8 bytes given
            np.lib.format.write_array_header_1_0(fh, {"descr": "<f8", "fortran_order": False,
                                                      "shape": (1024 ** 3,)})
            fh.write(bytes(8))
    with pytest.raises(ArtefactError, match=r"member 'x\.npy': 1073741824 values of float64"):
        read_trace(path)


def test_verify_records_the_trace_hash_and_the_report_check_refuses_an_edit(tmp_path):
    from tanksynth.artefacts.traces import check_trace

    path = _artefact(tmp_path)
    doc = json.loads(path.read_text())
    trace = write_trace(tmp_path / "akf.traces.npz", _trace())
    # not covered by any hash: an unverified artefact (or one verified before traces were hashed)
    with pytest.raises(ArtefactError, match=r"akf\.traces\.npz: no traces_sha256"):
        check_trace(path, doc)
    doc["verification"] = {"passed": True, "checks": []}
    path.write_text(json.dumps(doc, indent=2))
    rehash(path)                                   # rehash records the trace beside it
    doc = read_artefact(path)
    assert doc["verification"]["traces_sha256"] == hashlib.sha256(trace.read_bytes()).hexdigest()
    assert check_trace(path, doc) == trace
    write_trace(trace, {**_trace(), "header": {**_trace()["header"], "check": "edited"}})
    with pytest.raises(ArtefactError, match=r"akf\.traces\.npz: does not match the traces_sha256"):
        check_trace(path, doc)
    trace.unlink()
    assert check_trace(path, doc) is None          # a missing trace: no figure, as before


def test_design_removes_the_trace_of_the_artefact_it_replaces(tmp_path):
    _artefact(tmp_path)
    write_trace(tmp_path / "akf.traces.npz", _trace())
    _artefact(tmp_path)
    assert not (tmp_path / "akf.traces.npz").exists()


# ---- item 5: the NPZ holds exactly the JSON's gains ----------------------------------------

def test_an_npz_with_other_gains_is_refused_with_every_hash_recomputed(tmp_path):
    path = _artefact(tmp_path)
    np.savez(path.with_suffix(".npz"), K=100 * GAINS["K"], s=GAINS["s"])
    _record_npz(path)
    doc = read_artefact(path)                      # the JSON itself is consistent
    with pytest.raises(ArtefactError, match=r"akf\.npz: gain K differs"):
        check_npz(path, doc)


@pytest.mark.parametrize("edit", ["missing", "extra", "float32", "shape"])
def test_an_npz_of_another_form_is_refused(tmp_path, edit):
    path = _artefact(tmp_path)
    gains = {"K": GAINS["K"], "s": GAINS["s"]}
    if edit == "missing":
        del gains["s"]
    elif edit == "extra":
        gains["L"] = np.zeros(2)
    elif edit == "float32":
        gains["K"] = GAINS["K"].astype(np.float32)
    else:
        gains["K"] = GAINS["K"].T
    np.savez(path.with_suffix(".npz"), **gains)
    _record_npz(path)
    with pytest.raises(ArtefactError, match=r"akf\.npz"):
        check_npz(path, read_artefact(path))


@pytest.mark.parametrize("values, refusal", [
    (1024 ** 2, r"akf\.npz: member 'K\.npy' declares 8388\d+ bytes uncompressed"),   # 8 MiB in 8 KiB
    (16 * 1024 ** 2, r"akf\.npz: \d+ bytes, more than the \d+ a result file may have")])  # 128 MiB in 128 KiB
def test_an_npz_zip_bomb_is_refused_before_decompression(tmp_path, values, refusal):
    """The size the JSON's six gain values imply bounds the file and each member's declared size."""
    path = _artefact(tmp_path)
    _bomb(path.with_suffix(".npz"), {"s": GAINS["s"]}, "K", values)
    _record_npz(path)
    with pytest.raises(ArtefactError, match=refusal):
        check_npz(path, read_artefact(path))


def test_the_npz_design_wrote_and_a_rehashed_one_read_back(tmp_path):
    path = _artefact(tmp_path)
    assert check_npz(path, read_artefact(path)) == path.with_suffix(".npz")
    rehash(path)
    assert check_npz(path, read_artefact(path)) == path.with_suffix(".npz")


# ---- item 7b: a 400-digit integer among the gains ------------------------------------------

def test_a_400_digit_gain_is_bad_input_naming_the_file_and_key(tmp_path):
    path = _artefact(tmp_path)
    text = path.read_text()
    path.write_text(text.replace("1.5", "1" + "0" * 400, 1))
    with pytest.raises(ArtefactError, match=r"akf\.json.*gains\.K.*float64 range"):
        read_artefact(path)


# ---- item 8a: what a killed write left -----------------------------------------------------

def test_an_interrupted_write_is_cleaned_and_nothing_else(tmp_path):
    """A kill between the NPZ and the JSON rename: the staged JSON and the NPZ it records go;
    user files (even named like ours but of another form), symlinks and a foreign NPZ stay."""
    from tanksynth.artefacts.io import remove_interrupted_writes

    path = _artefact(tmp_path)
    staged = tmp_path / ".akf.json.tanksynth-abcd1234.tmp"
    path.rename(staged)                            # as if the JSON rename never happened
    (tmp_path / ".akf.npz.tanksynth-zz9_q0w1.tmp").write_bytes(b"partial")
    build = tmp_path / ".law-build-k2j4h5g6.tmp"
    build.mkdir()
    (build / ".tanksynth-build").touch()           # the tool's own build directory (its marker)
    (build / "x.c").write_text("int x;")
    keep = ["notes.tmp", ".notes.tmp", ".akf.json.tmp", ".a.json.TOOLONG12.tmp", ".notes.abcdefgh.tmp",
            ".law-build-x.tmp", "other.npz",
            ".notes.json.abcdefgh.tmp", ".thesis.tex.abcd1234.tmp"]   # a user's, named like mkstemp's
    for name in keep:
        (tmp_path / name).write_text("mine")
    (tmp_path / ".link.json.tanksynth-abcdefgh.tmp").symlink_to(tmp_path / "notes.tmp")
    removed = remove_interrupted_writes(tmp_path)
    assert sorted(p.name for p in removed) == sorted([staged.name, ".akf.npz.tanksynth-zz9_q0w1.tmp", build.name, "akf.npz"])
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted(keep + [".link.json.tanksynth-abcdefgh.tmp"])


def test_what_stage_leaves_is_what_the_cleanup_takes(tmp_path):
    """The name `stage` gives a file is the one `stale_temporaries` recognises (and no other)."""
    from tanksynth.artefacts.atomic import stage, stale_temporaries

    staged = [stage(tmp_path / name, b"x") for name in ("a.json", "a.npz", "report.pdf", "f.png")]
    assert sorted(stale_temporaries(tmp_path)) == sorted(staged)


def test_an_orphan_npz_without_evidence_is_left_for_the_readers(tmp_path):
    from tanksynth.artefacts.io import remove_interrupted_writes

    path = _artefact(tmp_path)
    path.unlink()
    (tmp_path / ".akf.json.tanksynth-abcd1234.tmp").write_text("{\"truncated")
    remove_interrupted_writes(tmp_path)
    assert [p.name for p in tmp_path.iterdir()] == ["akf.npz"]


# ---- the archive itself: a directory of millions of entries, a negative shape --------------

def test_a_trace_whose_zip_directory_lists_thousands_of_entries_is_refused_before_parsing(tmp_path):
    """zipfile builds one object per central-directory entry before anything else is read."""
    path = tmp_path / "akf.traces.npz"
    with zipfile.ZipFile(path, "w") as zf:
        for i in range(20000):
            zf.writestr(f"a{i}.npy", b"")
    with pytest.raises(ArtefactError, match=r"akf\.traces\.npz: a zip directory of \d+ bytes"):
        read_trace(path)


def test_a_negative_shape_in_a_member_header_is_unreadable_not_a_read_of_everything(tmp_path):
    path = _artefact(tmp_path)
    npz = path.with_suffix(".npz")
    with zipfile.ZipFile(npz, "w") as zf:
        with zf.open("K.npy", "w") as fh:
            np.lib.format.write_array_header_1_0(fh, {"descr": "<f8", "fortran_order": False, "shape": (-2, 3)})
            fh.write(bytes(48))
        with zf.open("s.npy", "w") as fh:
            np.lib.format.write_array(fh, GAINS["s"])
    _record_npz(path)
    with pytest.raises(ArtefactError, match=r"akf\.npz: member 'K\.npy'"):
        check_npz(path, read_artefact(path))
