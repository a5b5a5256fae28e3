"""Reading logged experiments: formats agree, bad data is one exit-2 line naming file/column/row."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from tanksynth.errors import DataError, SpecError
from tanksynth.measurements import (DataTable, Experiment, file_sha256, parse_data_table,
                                    read_experiments)
from tanksynth.measurements.read import LIMIT_RTOL, censor
from tanksynth.plants import custom_plant, three_tank

PLANT = three_tank()
COLUMNS = ("t", "q1", "q2", "h1", "h2", "h3")


def table_values(n: int = 6) -> dict[str, np.ndarray]:
    """Hand-made samples: t in s, flows in m^3/s, levels in m, one missing h2 sample."""
    t = 2.0 * np.arange(n)
    q1 = np.full(n, 2.5e-5)
    q2 = np.linspace(0.0, 3e-5, n)
    h1 = np.linspace(0.30, 0.35, n)
    h2 = np.linspace(0.10, 0.12, n)
    h2[2] = np.nan
    h3 = np.linspace(0.20, 0.22, n)
    return dict(zip(COLUMNS, (t, q1, q2, h1, h2, h3)))


def write_csv(path: Path, cols: dict[str, np.ndarray], *, header: list[str] | None = None) -> Path:
    names = header or list(cols)
    rows = [",".join(names)]
    n = len(next(iter(cols.values())))
    for k in range(n):
        rows.append(",".join("" if np.isnan(cols[c][k]) else repr(float(cols[c][k])) for c in cols))
    path.write_text("\n".join(rows) + "\n")
    return path


def write_raw(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def assert_same(a: Experiment, b: Experiment) -> None:
    assert a.name == b.name
    for field in ("t", "u", "y", "censored_low", "censored_high"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    assert a.input_names == b.input_names and a.output_names == b.output_names
    assert a.limits == b.limits


def test_csv_npz_mat_give_identical_experiments(tmp_path):
    cols = table_values()
    (tmp_path / "csv").mkdir(), (tmp_path / "npz").mkdir(), (tmp_path / "mat").mkdir()
    csv = write_csv(tmp_path / "csv" / "run.csv", cols)
    npz = tmp_path / "npz" / "run.npz"
    np.savez(npz, **cols)
    mat = tmp_path / "mat" / "run.mat"
    scipy.io.savemat(mat, {k: v.reshape(-1, 1) for k, v in cols.items()})  # column vectors
    table = {"limits": {"h1": [0.0, 0.34]}}
    exps = [read_experiments([p], PLANT, table)[0] for p in (csv, npz, mat)]
    for e in exps[1:]:
        assert_same(exps[0], e)
    e = exps[0]
    # independent reference: the hand-made columns (h1 clipped at its limit 0.34 where above)
    np.testing.assert_array_equal(e.t, cols["t"])
    np.testing.assert_array_equal(e.u, np.column_stack([cols["q1"], cols["q2"]]))
    at_limit = cols["h1"] >= 0.34 - LIMIT_RTOL * 0.34   # linspace's 0.33999999999999997 counts
    assert at_limit.tolist() == [False, False, False, False, True, True]
    expected_y = np.column_stack([np.where(at_limit, 0.34, cols["h1"]), cols["h2"], cols["h3"]])
    np.testing.assert_array_equal(e.y, expected_y)
    np.testing.assert_array_equal(e.censored_high[:, 0], at_limit)
    assert not e.censored_high[:, 1:].any() and not e.censored_low.any()
    assert e.output_names == ("h1", "h2", "h3") and e.input_names == ("q1", "q2")
    assert e.name == "run" and e.uniform_period == 2.0
    assert e.observed.sum() == 18 - 1 - 2
    assert e.x_ref is None


def test_mat_row_vectors_and_npz_2d_columns(tmp_path):
    cols = table_values()
    mat = tmp_path / "a.mat"
    scipy.io.savemat(mat, cols)  # savemat writes 1-D arrays as row vectors (1, N)
    npz = tmp_path / "b.npz"
    np.savez(npz, **{k: v.reshape(-1, 1) for k, v in cols.items()})
    a, b = read_experiments([mat, npz], PLANT)
    np.testing.assert_array_equal(a.y, b.y)
    np.testing.assert_array_equal(a.u, b.u)


def test_scale_columns_ts_and_states(tmp_path):
    cols = table_values()
    data = {"pump1": cols["q1"] * 6e4, "q2": cols["q2"] * 6e4,   # l/min
            "level1": cols["h1"] * 100, "h2": cols["h2"] * 100, "h3": cols["h3"] * 100,  # cm
            "h2_ref": cols["h2"] * 100}
    path = write_csv(tmp_path / "scaled.csv", data)
    raw = {"ts": 0.5, "columns": {"q1": "pump1", "h1": "level1"},
           "scale": {"q1": 1 / 6e4, "q2": 1 / 6e4, "h1": 0.01, "h2": 0.01, "h3": 0.01},
           "states": {"h2": "h2_ref"}}
    (e,) = read_experiments([path], PLANT, raw)
    np.testing.assert_allclose(e.t, 0.5 * np.arange(6), rtol=0, atol=0)
    np.testing.assert_allclose(e.u, np.column_stack([cols["q1"], cols["q2"]]), rtol=1e-14)
    np.testing.assert_allclose(e.y, np.column_stack([cols["h1"], cols["h2"], cols["h3"]]),
                               rtol=1e-14)
    assert e.x_ref is not None and e.x_ref.shape == (6, 3)
    assert np.isnan(e.x_ref[:, [0, 2]]).all()
    np.testing.assert_allclose(e.x_ref[:, 1], cols["h2"], rtol=1e-14)
    # the same through a parsed DataTable
    (f,) = read_experiments([path], PLANT, parse_data_table(raw, PLANT))
    assert_same(e, f)


def test_only_some_outputs_logged(tmp_path):
    cols = table_values()
    del cols["h3"], cols["h2"]
    (e,) = read_experiments([write_csv(tmp_path / "h1only.csv", cols)], PLANT)
    assert e.output_names == ("h1",) and e.y.shape == (6, 1)


def test_censoring_matches_hand_computation():
    y = np.array([[0.0, 0.1], [0.05, 0.6], [0.5500004, 0.61], [np.nan, 0.59999], [0.549, -0.01]])
    limits = [(0.0, 0.55), (-np.inf, 0.6)]
    out, low, high = censor(y, limits)
    tol0 = LIMIT_RTOL * 0.55          # both limits finite: relative to the span
    tol1 = LIMIT_RTOL * 1.0           # one infinite: relative to max(1, |limit|)
    assert tol0 == pytest.approx(5.5e-7)
    # by hand: column 0 low at 0.0 (row 0); high at 0.5500004 (beyond 0.55) -> row 2; 0.549 is
    # inside by 1 mm >> tol0; NaN never censored. Column 1: 0.6 and 0.61 high; 0.59999 is
    # 1e-5 below 0.6, more than tol1 = 1e-6: not censored; no lower limit.
    np.testing.assert_array_equal(low, [[1, 0], [0, 0], [0, 0], [0, 0], [0, 0]])
    np.testing.assert_array_equal(high, [[0, 0], [0, 1], [1, 1], [0, 0], [0, 0]])
    assert out[2, 0] == 0.55 and out[2, 1] == 0.6 and out[0, 0] == 0.0
    assert out[4, 1] == -0.01 and np.isnan(out[3, 0]) and out[3, 1] == 0.59999
    assert tol1 == 1e-6


def test_censoring_tolerance_edge():
    lim = [(0.0, 1.0)]
    y = np.array([[1.0 - 0.9e-6], [1.0 - 1.1e-6], [0.9e-6], [1.1e-6]])
    _, low, high = censor(y, lim)
    assert high[:, 0].tolist() == [True, False, False, False]
    assert low[:, 0].tolist() == [False, False, True, False]


CUSTOM = {
    "model": "custom", "name": "gain_tank",
    "states": {"h": {"unit": "m", "min": 0.0, "max": 1.0}},
    "inputs": {"q": {"unit": "m^3/s", "min": 0.0, "max": 1e-4}},
    "parameters": {"A": {"value": 0.0154, "unit": "m^2", "min": 0.0},
                   "a": {"value": 5e-5, "unit": "m^2", "min": 0.0, "max": 1e-3, "fit": True},
                   "kc": {"value": 10.0, "unit": "V/m"}, "g": 9.81},
    "equations": {"h": "(q - a*sqrt(2*g*h))/A"},
    "outputs": {"y": {"expr": "kc*h", "unit": "V", "min": 0.0, "max": 8.0}},
}


def test_custom_plant_sensor_range_and_gain(tmp_path):
    plant = custom_plant(CUSTOM)
    assert plant.outputs[0].limits == (0.0, 8.0)
    assert plant.summary()["outputs"][0]["limits"] == [0.0, 8.0]
    path = write_raw(tmp_path / "g.csv", "t,q,y\n0,1e-5,2.5\n1,1e-5,8.0\n2,1e-5,8.3\n3,1e-5,0\n")
    (e,) = read_experiments([path], plant)
    assert e.limits == ((0.0, 8.0),)
    assert e.censored_high[:, 0].tolist() == [False, True, True, False]
    assert e.censored_low[:, 0].tolist() == [False, False, False, True]
    np.testing.assert_array_equal(e.y[:, 0], [2.5, 8.0, 8.0, 0.0])
    # the [data] table overrides the plant's range
    (f,) = read_experiments([path], plant, {"limits": {"y": [0.0, 9.0]}})
    assert f.censored_high.sum() == 0 and f.y[2, 0] == 8.3
    # a gain of 10 V/m: 95 V is 10 V/m * 9.5 m, beyond 10x the 10 V range -> a unit error
    bad = write_raw(tmp_path / "v.csv", "t,q,y\n0,1e-5,2.5\n1,1e-5,101\n")
    with pytest.raises(DataError, match=r"v\.csv.*column 'y'.*row 2.*expects V"):
        read_experiments([bad], plant)


# --------------------------------------------------------------------------- bad data
GOOD = "t,q1,q2,h1,h2,h3\n0,1e-5,2e-5,0.3,0.1,0.2\n1,1e-5,2e-5,0.31,0.1,0.2\n2,1e-5,2e-5,0.32,0.1,0.2\n"

BAD_CASES = {
    # name: (file text, regex the one-line message must match)
    "cells_differ": ("t,q1,q2,h1,h2,h3\n0,1e-5,2e-5,0.3,0.1,0.2\n1,1e-5,2e-5,0.31,0.1\n",
                     r"row 2 \(line 3\) has 5 cells, the header has 6"),
    "time_not_increasing": ("t,q1,q2,h1\n0,1e-5,2e-5,0.3\n1,1e-5,2e-5,0.3\n1,1e-5,2e-5,0.3\n",
                            r"time column 't' is not strictly increasing at row 3 \(line 4\)"),
    "time_missing_cell": ("t,q1,q2,h1\n0,1e-5,2e-5,0.3\n,1e-5,2e-5,0.3\n",
                          r"time column 't', row 2 \(line 3\): missing"),
    "input_missing": ("t,q_1,q2,h1\n0,1e-5,2e-5,0.3\n1,1e-5,2e-5,0.3\n",
                      r"missing column 'q1' \(plant input q1, m\^3/s.*did you mean 'q_1'\?"),
    "time_column_missing": ("time,q1,q2,h1\n0,1e-5,2e-5,0.3\n1,1e-5,2e-5,0.3\n",
                            r"missing column 't' \(time, s\); did you mean 'time'\?.*\[data\] ts"),
    "no_output": ("t,q1,q2,level\n0,1e-5,2e-5,0.3\n1,1e-5,2e-5,0.3\n",
                  r"no output column: none of 'h1', 'h2', 'h3'"),
    "all_nan": ("t,q1,q2,h1,h2\n0,1e-5,2e-5,0.3,\n1,1e-5,2e-5,0.3,NaN\n",
                r"column 'h2' \(output h2\) is empty"),
    "non_numeric": ("t,q1,q2,h1\n0,1e-5,2e-5,0.3\n1,1e-5,2e-5,0.3m\n",
                    r"column 'h1', row 2 \(line 3\): '0.3m' is not a number"),
    "infinite": ("t,q1,q2,h1\n0,1e-5,2e-5,0.3\n1,1e-5,2e-5,inf\n",
                 r"column 'h1', row 2 \(line 3\): inf is not a finite number"),
    "input_nan": ("t,q1,q2,h1\n0,1e-5,2e-5,0.3\n1,,2e-5,0.3\n",
                  r"column 'q1' \(input q1\), row 2 \(line 3\): missing sample"),
    "level_in_cm": ("t,q1,q2,h1\n0,1e-5,2e-5,30\n1,1e-5,2e-5,31\n",
                    r"column 'h1' \(output h1\): \|value\| 31 at row 2 \(line 3\).*10x.*expects m"),
    "flow_in_ml_per_s": ("t,q1,q2,h1\n0,10,2e-5,0.3\n1,12,2e-5,0.3\n",
                         r"column 'q1' \(input q1\): \|value\| 12 at row 2.*10x.*expects m\^3/s"),
    "one_sample": ("t,q1,q2,h1\n0,1e-5,2e-5,0.3\n", r"1 sample\(s\); an experiment needs at least 2"),
    "header_only": ("t,q1,q2,h1\n", r"0 sample\(s\)"),
    "empty": ("", r"empty file; expected a header row"),
    "duplicate_header": ("t,q1,q2,h1,h1\n0,1e-5,2e-5,0.3,0.3\n", r"column 'h1' appears twice"),
    "semicolons": ("t;q1;q2;h1\n0;1e-5;2e-5;0.3\n", r"separator must be ','"),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_csv_is_one_line_naming_file_column_row(tmp_path, case):
    text, pattern = BAD_CASES[case]
    path = write_raw(tmp_path / f"{case}.csv", text)
    with pytest.raises(DataError) as info:
        read_experiments([path], PLANT)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(f"{path}: "), msg
    assert __import__("re").search(pattern, msg), msg
    assert isinstance(info.value, SpecError)   # exit code 2


def test_good_csv_reads(tmp_path):
    (e,) = read_experiments([write_raw(tmp_path / "ok.csv", GOOD)], PLANT)
    assert e.samples == 3


def test_npz_and_mat_errors_name_file_column(tmp_path):
    cols = table_values()
    short = dict(cols, h1=cols["h1"][:-1])
    np.savez(tmp_path / "short.npz", **short)
    with pytest.raises(DataError, match=r"short\.npz: column 'h1' has 5 rows, column 't' has 6"):
        read_experiments([tmp_path / "short.npz"], PLANT)
    np.savez(tmp_path / "text.npz", **dict(cols, h1=np.array(["a"] * 6)))
    with pytest.raises(DataError, match=r"text\.npz: column 'h1' is not numeric"):
        read_experiments([tmp_path / "text.npz"], PLANT)
    np.savez(tmp_path / "matrix.npz", **dict(cols, h1=np.ones((6, 2))))
    with pytest.raises(DataError, match=r"matrix\.npz: column 'h1' has shape \(6, 2\)"):
        read_experiments([tmp_path / "matrix.npz"], PLANT)
    np.savez(tmp_path / "obj.npz", **dict(cols, h1=np.array([None] * 6, dtype=object)))
    with pytest.raises(DataError, match=r"obj\.npz: column 'h1' cannot be read"):
        read_experiments([tmp_path / "obj.npz"], PLANT)
    t = cols["t"].copy()
    t[3] = t[2]
    scipy.io.savemat(tmp_path / "t.mat", dict(cols, t=t))
    with pytest.raises(DataError, match=r"t\.mat: time column 't' is not strictly increasing at row 4 "
                                        r"\(t = 4 s after 4 s\)"):
        read_experiments([tmp_path / "t.mat"], PLANT)
    (tmp_path / "junk.mat").write_bytes(b"not a mat file at all" * 20)
    with pytest.raises(DataError, match=r"junk\.mat: not a readable \.mat file"):
        read_experiments([tmp_path / "junk.mat"], PLANT)
    (tmp_path / "junk.npz").write_bytes(b"PK not a zip")
    with pytest.raises(DataError, match=r"junk\.npz: not a readable \.npz archive"):
        read_experiments([tmp_path / "junk.npz"], PLANT)


def test_file_level_errors(tmp_path):
    ok = write_raw(tmp_path / "run.csv", GOOD)
    (tmp_path / "b").mkdir()
    other = write_raw(tmp_path / "b" / "run.csv", GOOD)
    with pytest.raises(DataError, match=r"experiment name 'run' .* is also the name of"):
        read_experiments([ok, other], PLANT)
    with pytest.raises(DataError, match=r"unknown data file type '\.xlsx'; expected \.csv, \.npz, \.mat"):
        read_experiments([tmp_path / "run.xlsx"], PLANT)
    with pytest.raises(DataError, match=r"nothere\.csv: cannot read data file: No such file"):
        read_experiments([tmp_path / "nothere.csv"], PLANT)
    (tmp_path / "dir.csv").mkdir()
    with pytest.raises(DataError, match=r"dir\.csv: not a regular file \(a directory\)"):
        read_experiments([tmp_path / "dir.csv"], PLANT)
    with pytest.raises(DataError, match="no data files given"):
        read_experiments([], PLANT)
    big = tmp_path / "big.csv"
    with open(big, "wb") as fh:
        fh.truncate(65 * 1024 ** 2)   # sparse: 65 MiB, above the cap
    with pytest.raises(DataError, match=r"big\.csv: \d+ bytes, more than the \d+ a data file may have"):
        read_experiments([big], PLANT)


def test_fifo_does_not_hang(tmp_path):
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    errors: list[BaseException] = []

    def read() -> None:
        try:
            read_experiments([fifo], PLANT)
        except BaseException as exc:  # noqa: BLE001 - collected for the assertion
            errors.append(exc)

    worker = threading.Thread(target=read, daemon=True)
    worker.start()
    worker.join(timeout=10)
    assert not worker.is_alive(), "reading a FIFO hung"
    assert len(errors) == 1 and isinstance(errors[0], DataError)
    assert "not a regular file (a FIFO)" in str(errors[0])
    with pytest.raises(DataError, match="a FIFO"):
        file_sha256(fifo)


def test_file_sha256_matches_hashlib(tmp_path):
    import hashlib

    path = write_raw(tmp_path / "x.csv", GOOD)
    assert file_sha256(path) == hashlib.sha256(GOOD.encode()).hexdigest()


def test_text_column_not_used_is_ignored(tmp_path):
    path = write_raw(tmp_path / "c.csv", "t,note,q1,q2,h1\n0,start,1e-5,2e-5,0.3\n1,,1e-5,2e-5,0.3\n")
    (e,) = read_experiments([path], PLANT)
    assert e.samples == 2 and e.output_names == ("h1",)


def test_mapped_output_missing_is_an_error(tmp_path):
    path = write_raw(tmp_path / "m.csv", GOOD)
    with pytest.raises(DataError, match=r"m\.csv: missing column 'lvl3' \(plant output h3, m, "
                                        r"\[data\] columns\.h3\)"):
        read_experiments([path], PLANT, {"columns": {"h3": "lvl3"}})


def test_data_table_defaults():
    t = DataTable()
    assert t.time == "t" and t.ts is None and t.column("h1") == "h1" and t.factor("h1") == 1.0



def test_row_and_column_caps(tmp_path, monkeypatch):
    from tanksynth.measurements import formats

    path = write_raw(tmp_path / "long.csv", GOOD)
    monkeypatch.setattr(formats, "MAX_ROWS", 2)
    with pytest.raises(DataError, match=r"long\.csv: more than the 2 rows a data file may have"):
        read_experiments([path], PLANT)
    np.savez(tmp_path / "long.npz", **table_values())
    with pytest.raises(DataError, match=r"long\.npz: column '.*' has 6 rows, more than the 2"):
        read_experiments([tmp_path / "long.npz"], PLANT)
    monkeypatch.setattr(formats, "MAX_ROWS", 1000)
    monkeypatch.setattr(formats, "MAX_COLUMNS", 5)
    with pytest.raises(DataError, match=r"long\.csv: 6 columns, more than the 5 a data file may have"):
        read_experiments([path], PLANT)
