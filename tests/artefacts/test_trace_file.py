"""The verdict trace file: main trace plus extra traces, and files written before extras existed."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tanksynth.artefacts.traces import TRACE_EXTRAS, read_trace, write_trace


def _trace(seed: int, check: str, n: int = 3, m: int = 2, k: int = 7) -> dict:
    rng = np.random.default_rng(seed)
    t = np.arange(k, dtype=float)
    arrays = {"t": t, "x": rng.normal(size=(2, k, n)), "t_u": t[:-1], "u": rng.normal(size=(2, k - 1, m))}
    header = {"schema": "tanksynth.traces/1", "scenario": f"scenario {seed}", "check": check, "runs": 2,
              "stride": 1, "state_names": ["h1", "h2", "h3"], "input_names": ["q1", "q2"]}
    return {"header": header, "arrays": arrays}


def _same(a: dict, b: dict) -> None:
    assert a["header"] == b["header"]
    assert set(a["arrays"]) == set(b["arrays"])
    for key, value in a["arrays"].items():
        np.testing.assert_array_equal(value, b["arrays"][key])


def test_round_trip_with_extras(tmp_path):
    main, one, two = _trace(0, "regulation"), _trace(1, "disturbance_step", m=5), _trace(2, "other")
    one["arrays"]["x_hat"] = one["arrays"]["x"] + 1.0
    path = write_trace(tmp_path / "a.traces.npz", {**main, "more": [one, two]})
    back = read_trace(path)
    _same(back, main)
    assert len(back["more"]) == 2
    _same(back["more"][0], one)
    _same(back["more"][1], two)


def test_more_than_the_limit_is_not_written(tmp_path):
    more = [_trace(k, f"c{k}") for k in range(1, TRACE_EXTRAS + 3)]
    back = read_trace(write_trace(tmp_path / "a.traces.npz", {**_trace(0, "c0"), "more": more}))
    assert [m["header"]["check"] for m in back["more"]] == [f"c{k}" for k in range(1, TRACE_EXTRAS + 1)]


def test_an_old_file_reads_with_no_extras(tmp_path):
    """A file as written before extras existed (header + main arrays, nothing else)."""
    main = _trace(0, "regulation")
    path = tmp_path / "old.traces.npz"
    with open(path, "wb") as fh:
        np.savez_compressed(fh, header=np.array(json.dumps(main["header"], sort_keys=True)), **main["arrays"])
    back = read_trace(path)
    _same(back, main)
    assert back["more"] == []


def test_a_new_file_reads_with_the_old_reader(tmp_path):
    """The pre-extras reader (header + every array by name) finds the main trace unchanged: schema
    /1, same arrays under the same keys; the extras are keys and a header list it does not use."""
    main = _trace(0, "regulation")
    path = write_trace(tmp_path / "a.traces.npz", {**main, "more": [_trace(1, "disturbance_step")]})
    with np.load(path, allow_pickle=False) as data:
        header = json.loads(str(data["header"][()]))
        arrays = {k: np.asarray(data[k]) for k in data.files if k != "header"}
    assert header["schema"] == "tanksynth.traces/1" and header["check"] == "regulation"
    for key, value in main["arrays"].items():
        np.testing.assert_array_equal(arrays[key], value)
    assert header["extras"][0]["check"] == "disturbance_step"


def test_a_file_without_extras_has_only_the_main_keys(tmp_path):
    main = _trace(0, "regulation")
    for trace in (main, {**main, "more": []}):
        path = write_trace(tmp_path / "a.traces.npz", trace)
        with np.load(path, allow_pickle=False) as data:
            assert set(data.files) == {"header", *main["arrays"]}
            assert "extras" not in json.loads(str(data["header"][()]))


def test_an_unreadable_extra_is_left_out(tmp_path):
    path = write_trace(tmp_path / "a.traces.npz", {**_trace(0, "a"), "more": [_trace(1, "b"), _trace(2, "c")]})
    with np.load(path, allow_pickle=False) as data:
        kept = {k: data[k] for k in data.files if k != "extra1.x"}     # extra 1 lost its states
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **kept)
    back = read_trace(path)
    assert [m["header"]["check"] for m in back["more"]] == ["c"] and back["header"]["check"] == "a"


def test_a_header_holding_extras_is_refused(tmp_path):
    bad = _trace(0, "a")
    bad["header"]["extras"] = []
    with pytest.raises(ValueError, match="extras"):
        write_trace(tmp_path / "a.traces.npz", bad)


# ----------------------------------------------------------------------------- named signals
def _with_signals(trace: dict, k: int = 2) -> dict:
    runs, samples = trace["arrays"]["x"].shape[:2]
    sig = np.random.default_rng(5).uniform(size=(runs, samples, k))
    head = {**trace["header"], "signal_names": [f"s{j}" for j in range(k)], "signal_units": ["m"] * k,
            "signal_styles": ["-"] * k, "signal_title": "signals", "events": [[2.0, "onset"]]}
    return {"header": head, "arrays": {**trace["arrays"], "signals": sig}}


def test_round_trip_with_signals_in_the_main_and_an_extra_trace(tmp_path):
    main, extra = _with_signals(_trace(0, "fault_detected")), _with_signals(_trace(1, "other"), k=3)
    back = read_trace(write_trace(tmp_path / "a.traces.npz", {**main, "more": [extra, _trace(2, "plain")]}))
    _same(back, main)
    _same(back["more"][0], extra)
    _same(back["more"][1], _trace(2, "plain"))
    assert "signals" not in back["more"][1]["arrays"] and "signal_names" not in back["more"][1]["header"]


def test_a_file_without_signals_is_byte_identical_to_the_old_writer(tmp_path):
    """Written the pre-signals way (header JSON sorted + the arrays, compressed) by hand."""
    main = _trace(0, "regulation")
    new = write_trace(tmp_path / "new.traces.npz", main)
    old = tmp_path / "old.traces.npz"
    with open(old, "wb") as fh:
        np.savez_compressed(fh, header=np.array(json.dumps(main["header"], allow_nan=False, sort_keys=True)),
                            **main["arrays"])
    assert new.read_bytes() == old.read_bytes()
    back = read_trace(old)
    assert "signals" not in back["arrays"] and not any(k.startswith("signal") for k in back["header"])


@pytest.mark.parametrize("spoil", ["shape", "names", "units"])
def test_signals_that_do_not_fit_are_dropped_and_the_rest_reads(tmp_path, spoil):
    bad = _with_signals(_trace(0, "fault_detected"))
    if spoil == "shape":
        bad["arrays"]["signals"] = bad["arrays"]["signals"][:, :-1]          # one sample short
    elif spoil == "names":
        bad["header"]["signal_names"] = ["only one"]
    else:
        bad["header"]["signal_units"] = "m"
    back = read_trace(write_trace(tmp_path / "a.traces.npz", bad))
    _same(back, _trace(0, "fault_detected"))


def test_a_non_numeric_array_is_unreadable_not_a_crash(tmp_path):
    """An edited file whose array holds strings: that extra is left out, such a main trace is None
    (the report's figure code converted it with float() and the report died)."""
    path = write_trace(tmp_path / "a.traces.npz", {**_trace(0, "a"), "more": [_trace(1, "b"), _trace(2, "c")]})
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **{**arrays, "extra1.x": np.array("garbage")})
    assert [m["header"]["check"] for m in read_trace(path)["more"]] == ["c"]
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **{**arrays, "x": np.array(["a", "b"])})
    assert read_trace(path) is None
