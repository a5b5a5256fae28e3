"""Property-based adversarial runs through the CLI entry point (issue 19, done-when).

Generated specs (examples mutated key by key, and raw text mutations) go through
``tanksynth check --spec-only``; edited result directories go through ``tanksynth verify``.
Attacked result files (issue 31: FIFOs, symlinks, zip-bombed NPZ and trace members, NPZ and JSON
gains that disagree with every hash recomputed by ``rehash``) go through ``verify`` and ``report``,
which must never exit 0 while the NPZ is not the JSON's gains.
Every case must keep the exit-code contract (`fuzz_helpers.assert_contract`): exit 0/1/2/3,
one stderr line, never a traceback, bounded time and memory. ``make test`` runs 2,000 cases,
``make fuzz`` (TANKSYNTH_FUZZ_SCALE=10) 20,000.
"""

from __future__ import annotations

import copy
import json
import os
import shutil
import tomllib

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzz_helpers import EXAMPLES, SCALE, assert_contract, run, toml_document

BASES = {p.name: tomllib.loads(p.read_text(encoding="utf-8")) for p in sorted(EXAMPLES.glob("*.toml"))}
BASE_TEXTS = {p.name: p.read_text(encoding="utf-8") for p in sorted(EXAMPLES.glob("*.toml"))}

SETTINGS = dict(deadline=None, database=None, derandomize=SCALE == 1, print_blob=True,
                suppress_health_check=list(HealthCheck))

_words = st.sampled_from([
    "inv-dyn", "it--2", "jac", "plant", "checks", "lin.traces", "x_law", "", " ", "é", "a" * 200,
    "sqrt(q)", "h1 > A", "h1 > q", "((h1+h2+1)**64+1)**64 > h2", "exp(exp(exp(exp(exp(exp(exp(h1)))))))",
    "h1 > h2", "h1 >= h2", "1/0", "log(0)", "custom", "three_tank", "quadruple_tank", "hydraulic_fault",
    "pole_placment", "ekf", "ukf", "narx", "ts_observer", "lmi_placement", "decentralized_kalman",
    "inverse_dynamics", "feedback_linearization", "disk", "half_plane", "sector", "all", "h1h2",
    "\\input{/etc/passwd}", "../../etc/passwd", "null", "nan", "inf", "{", "[[", "\x00"])
_numbers = st.one_of(
    st.integers(min_value=-10, max_value=10),
    st.sampled_from([0, -1, 1, 2, 10 ** 9, 10 ** 400, -(10 ** 400), 2 ** 63, 2 ** 64, 10 ** 7]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([1e308, -1e308, 1e-300, 5e-324, 0.0, -0.0, 0.5, 1e-6, 1e6, 0.97, -5.0]))
_leaf = st.one_of(_numbers, st.booleans(), _words, st.text(max_size=12))
_values = st.recursive(_leaf, lambda inner: st.one_of(
    st.lists(inner, max_size=5), st.dictionaries(st.one_of(_words, st.text(max_size=6)), inner,
                                                 max_size=4)), max_leaves=12)


pytestmark = pytest.mark.slow   # 2,000 generated cases through the CLI (about a minute)


def _paths(node, prefix=()):
    """Every (path, value) in a TOML document (dict keys and list indices)."""
    out = [(prefix, node)]
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _paths(v, prefix + (i,))
    return out


def _mutate(doc: dict, data) -> dict:
    doc = copy.deepcopy(doc)
    for _ in range(data.draw(st.integers(1, 3), label="mutations")):
        paths = [p for p, _ in _paths(doc) if p]
        if not paths:
            break
        path = data.draw(st.sampled_from(paths), label="path")
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        last = path[-1]
        op = data.draw(st.sampled_from(["set", "set", "set", "delete", "add_key", "duplicate",
                                        "wrap"]), label="op")
        if op == "set":
            parent[last] = data.draw(_values, label="value")
        elif op == "delete":
            del parent[last]
        elif op == "add_key" and isinstance(parent, dict):
            parent[data.draw(st.one_of(_words, st.text(min_size=1, max_size=8)), label="key")] = \
                data.draw(_values, label="value")
        elif op == "duplicate" and isinstance(parent, list):
            parent.append(copy.deepcopy(parent[last]))
        elif op == "wrap":
            parent[last] = [parent[last]]
    return doc


def _text_mutation(text: str, data) -> str:
    op = data.draw(st.sampled_from(["truncate", "insert", "brackets", "replace_line"]), label="text op")
    pos = data.draw(st.integers(0, len(text)), label="pos")
    if op == "truncate":
        return text[:pos]
    if op == "insert":
        return text[:pos] + data.draw(st.text(max_size=8), label="insert") + text[pos:]
    if op == "brackets":
        depth = data.draw(st.integers(1, 3000), label="depth")
        return text + "\nzz = " + "[" * depth + "]" * depth + "\n"
    lines = text.splitlines()
    i = data.draw(st.integers(0, max(0, len(lines) - 1)), label="line")
    if lines:
        key = lines[i].split("=")[0].strip() or "x"
        value = data.draw(st.sampled_from(["inf", "1e400", "[[1], [2, 3]]", '"abc"', "-1",
                                           "10000000000000000000000"]), label="v")
        lines[i] = f"{key} = {value}"
    return "\n".join(lines) + "\n"


@settings(max_examples=1600 * SCALE, **SETTINGS)
@given(data=st.data())
def test_generated_specs_keep_the_exit_code_contract(data, tmp_path_factory):
    """A mutated example spec: exit 0 (valid), 2 (one line naming the file) or 3 (a design over
    the memory budget), never a crash."""
    name = data.draw(st.sampled_from(sorted(BASES)), label="example")
    if data.draw(st.integers(0, 9), label="raw?") == 0:
        text = _text_mutation(BASE_TEXTS[name], data)
    else:
        try:
            text = toml_document(_mutate(BASES[name], data))
        except (TypeError, ValueError, RecursionError):  # a value TOML cannot hold
            return
    path = tmp_path_factory.getbasetemp() / f"fuzz-{os.getpid()}.toml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    code, _, err, seconds = run(["check", "--spec-only", path])
    assert_contract(code, err, seconds, what=name)
    # 3: a valid spec whose LMI design is over the memory budget (refused, named on stdout)
    assert code in (0, 2) or (code == 3 and "memory budget" in err), err
    if code == 2:
        assert str(path) in err, err  # the message names the spec file


_DIR_OPS = ["delete", "truncate", "flip", "json_set", "json_delete", "swap", "orphan", "lock",
            "directory", "garbage_json", "symlink", "spec", "fifo"]


def _clear_special(path) -> None:
    """Remove ``path`` if an earlier edit made it a symlink, FIFO or directory (the test never
    writes through one)."""
    if path.is_symlink() or (path.exists() and not path.is_file()):
        path.rmdir() if path.is_dir() and not path.is_symlink() else path.unlink()


def _edit_directory(d, data) -> str:
    # Regular files only: an edit never writes through a symlink an earlier edit made.
    files = sorted(p for p in d.iterdir() if p.is_file() and not p.is_symlink())
    if not files:
        return "nothing left to edit"
    op = data.draw(st.sampled_from(_DIR_OPS), label="dir op")
    target = data.draw(st.sampled_from(files), label="file")
    if op == "delete":
        target.unlink()
    elif op == "truncate":
        raw = target.read_bytes()
        target.write_bytes(raw[:data.draw(st.integers(0, len(raw)), label="len")])
    elif op == "flip":
        raw = bytearray(target.read_bytes())
        if raw:
            i = data.draw(st.integers(0, len(raw) - 1), label="byte")
            raw[i] = (raw[i] + data.draw(st.integers(1, 255), label="delta")) % 256
            target.write_bytes(bytes(raw))
    elif op in ("json_set", "json_delete"):
        jsons = [p for p in files if p.suffix == ".json"]
        if not jsons:
            return "no json left"
        target = data.draw(st.sampled_from(jsons), label="json")
        try:
            doc = json.loads(target.read_text(encoding="utf-8"))
        except ValueError:
            return "json already broken"
        paths = [p for p, _ in _paths(doc) if p]
        if not paths:
            return "empty json"
        path = data.draw(st.sampled_from(paths), label="path")
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        if op == "json_delete":
            del parent[path[-1]]
        else:
            value = data.draw(_values, label="value")
            parent[path[-1]] = value
        target.write_text(json.dumps(doc, allow_nan=True), encoding="utf-8")
    elif op == "swap":
        other = data.draw(st.sampled_from(files), label="other")
        if other != target:
            shutil.copyfile(other, target)
    elif op == "orphan":
        orphan = d / data.draw(st.sampled_from(["x.npz", "x.json", "plant.npz", "x.traces.npz"]),
                               label="orphan")
        if orphan != target:
            _clear_special(orphan)
            shutil.copyfile(target, orphan)
    elif op == "lock":
        info = data.draw(st.one_of(_values, st.fixed_dictionaries(
            {"pid": st.sampled_from([os.getpid(), 1, 2 ** 22 + 12345, -1]),
             "host": st.sampled_from([os.uname().nodename, "elsewhere"])})), label="lock")
        lock = d / ".tanksynth.lock"
        _clear_special(lock)
        lock.write_text(json.dumps(info), encoding="utf-8")
    elif op == "directory":
        target.unlink()
        target.mkdir()
    elif op == "garbage_json":
        garbage = d / "zz.json"
        if garbage.exists() or garbage.is_symlink():
            return "zz.json exists"
        garbage.write_text(json.dumps(data.draw(_values, label="garbage")), encoding="utf-8")
    elif op == "symlink":
        target.unlink()
        target.symlink_to(data.draw(st.sampled_from(["/etc/passwd", "/nonexistent", "/dev/zero"]),
                                    label="link"))
    elif op == "fifo":
        target.unlink()
        os.mkfifo(target)
    elif op == "spec":
        spec = d / "spec.toml"
        _clear_special(spec)
        spec.write_text(data.draw(st.text(max_size=40), label="spec"), encoding="utf-8",
                                     errors="surrogatepass")
    return f"{op} {target.name}"


@settings(max_examples=400 * SCALE, **SETTINGS)
@given(data=st.data())
def test_edited_result_directories_keep_the_exit_code_contract(data, result_dir, tmp_path_factory):
    """A verified directory with one to three edits: verify exits 0/1/2, never a crash."""
    d = tmp_path_factory.getbasetemp() / f"fuzz-dir-{os.getpid()}"
    shutil.rmtree(d, ignore_errors=True)
    shutil.copytree(result_dir, d, symlinks=True)
    done = [_edit_directory(d, data) for _ in range(data.draw(st.integers(1, 3), label="edits"))]
    code, _, err, seconds = run(["verify", d, "--json"])
    assert_contract(code, err, seconds, what="; ".join(done))


# ---- issue 31: result files that hang, bomb or disagree -------------------------------------

_FILE_ATTACKS = ["fifo", "symlink", "bomb", "scaled_npz", "json_gain_npz_kept", "reshaped_npz",
                 "huge_integer", "rehashed_json_gain"]


def _zip_bomb(path, members: dict, key: str, values: int) -> None:
    """An .npz of ``members`` plus ``key``: ``values`` float64 zeros deflated as they are streamed."""
    import zipfile

    import numpy as np

    path.unlink(missing_ok=True)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, arr in members.items():
            with zf.open(f"{name}.npy", "w", force_zip64=True) as fh:
                np.lib.format.write_array(fh, np.asarray(arr), allow_pickle=False)
        with zf.open(f"{key}.npy", "w", force_zip64=True) as fh:
            np.lib.format.write_array_header_1_0(fh, {"descr": "<f8", "fortran_order": False,
                                                      "shape": (values,)})
            chunk = bytes(1 << 20)
            for _ in range(max(1, values * 8 // len(chunk))):
                fh.write(chunk)


def _attack(d, data) -> tuple[str, bool]:
    """One attack on the artefact of ``d``; returns what it did and whether the NPZ then holds
    gains other than the JSON's (so that no command may exit 0)."""
    import numpy as np

    from tanksynth.artefacts.io import rehash

    art = next(p for p in sorted(d.glob("*.json")) if p.name != "plant.json")
    npz, trace = art.with_suffix(".npz"), art.with_name(art.stem + ".traces.npz")
    op = data.draw(st.sampled_from(_FILE_ATTACKS), label="attack")
    which = data.draw(st.sampled_from(["npz", "trace"]), label="which")
    target = npz if which == "npz" else trace
    with np.load(npz) as z:
        gains = {k: z[k] for k in z.files}
    name = data.draw(st.sampled_from(sorted(gains)), label="gain")
    if op == "fifo":
        target.unlink()
        os.mkfifo(target)
    elif op == "symlink":
        target.unlink()
        target.symlink_to(data.draw(st.sampled_from(["/dev/zero", "/etc/passwd", "/nonexistent"]), label="to"))
    elif op == "bomb":
        values = data.draw(st.sampled_from([2 ** 20, 2 ** 23, 2 ** 25]), label="values")
        if which == "npz":
            _zip_bomb(npz, {k: v for k, v in gains.items() if k != name}, name, values)
            rehash(art, keep_npz=True)                 # every hash recomputed: only the content differs
            return f"bomb npz {name} {values}", True
        with np.load(trace) as z:
            members = {k: z[k] for k in z.files if k != "x"}
        _zip_bomb(trace, members, "x", values)
        rehash(art)
    elif op in ("scaled_npz", "reshaped_npz"):
        factor = data.draw(st.sampled_from([100.0, -1.0, 1.0 + 2.0 ** -52, 0.0]), label="factor")
        value = gains[name] * factor if op == "scaled_npz" else gains[name].reshape(-1)[::-1].copy()
        if value.shape == gains[name].shape and value.tobytes() == gains[name].tobytes():
            return "no change", False
        np.savez(npz, **{**gains, name: value})
        rehash(art, keep_npz=True)
        return f"{op} {name}", True
    elif op == "json_gain_npz_kept":
        doc = json.loads(art.read_text(encoding="utf-8"))
        doc["gains"][name] = (np.asarray(doc["gains"][name], dtype=float) * 100 + 1).tolist()
        art.write_text(json.dumps(doc), encoding="utf-8")
        rehash(art, keep_npz=True)
        return f"json gain {name} edited, npz kept", True
    elif op == "huge_integer":
        doc = json.loads(art.read_text(encoding="utf-8"))
        value = doc["gains"][name]
        doc["gains"][name] = [10 ** 400] if isinstance(value, list) else 10 ** 400
        art.write_text(json.dumps(doc), encoding="utf-8")
        return f"huge integer {name}", True
    else:                                              # a consistent (possibly wrong) design
        doc = json.loads(art.read_text(encoding="utf-8"))
        doc["gains"][name] = (np.asarray(doc["gains"][name], dtype=float) * -3).tolist()
        art.write_text(json.dumps(doc), encoding="utf-8")
        rehash(art)
        return f"rehashed json gain {name}", False
    return f"{op} {which}", False


@settings(max_examples=5 * SCALE, **SETTINGS)
@given(data=st.data())
def test_attacked_result_files_never_hang_crash_or_pass_an_unverified_gain(data, result_dir, tmp_path_factory):
    """FIFOs, symlinks, zip-bombed NPZ/trace members and rehashed edits (issue 31): verify and
    report end within the time bound (a hang is killed by the watchdog), with one line and a
    documented code, never a traceback, and never exit 0 when the NPZ is not the JSON's gains."""
    d = tmp_path_factory.getbasetemp() / f"fuzz-attack-{os.getpid()}"
    shutil.rmtree(d, ignore_errors=True)
    shutil.copytree(result_dir, d, symlinks=True)
    what, edited = _attack(d, data)
    command = data.draw(st.sampled_from(["verify", "report"]), label="command")
    code, _, err, seconds = run([command, d] + (["--json"] if command == "verify" else []))
    assert_contract(code, err, seconds, what=f"{command}: {what}")
    if edited:
        assert code != 0, f"{command} exit 0 with {what}"
