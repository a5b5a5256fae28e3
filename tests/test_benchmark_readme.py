"""benchmarks/README.md's figures are rendered from benchmarks/results/*.json, never typed.

`benchmarks/report.py` renders the blocks between ``<!-- report:NAME -->`` markers from
``results/NAME.json``; the README committed must be exactly what the committed records
render, and the figures in it must be the records' own numbers (recomputed here from the
JSON without the renderer).
"""

from __future__ import annotations

import json
import re
import statistics
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import report  # noqa: E402

#: Blocks issue 29 requires (benchmarks against compiled code, and those it rewrote).
REQUIRED = ("closed_loop", "campaign", "estimators", "simulate", "lmi_handwritten",
            "decentralized_numpy")


def test_readme_equals_what_the_committed_results_render():
    text = report.README.read_text()
    assert report.update(text) == text, "run: python benchmarks/report.py --write"


def test_issue_29_blocks_are_present_and_have_records():
    names = report.blocks(report.README.read_text())
    for name in REQUIRED:
        assert name in names, f"README has no <!-- report:{name} --> block"
        assert (report.RESULTS / f"{name}.json").exists(), f"results/{name}.json missing"


def test_every_block_names_an_existing_record():
    for name in report.blocks(report.README.read_text()):
        assert (report.RESULTS / f"{name}.json").exists(), name


def test_no_figure_outside_the_blocks_reads_like_a_measurement():
    """Outside the generated blocks, no 'measured ... ms'-style figure (the old hand tables)."""
    text = re.sub(r"<!-- report:(\S+) -->.*?<!-- /report:\1 -->", "", report.README.read_text(),
                  flags=re.S)
    assert "Measured (" not in text and "Last full run" not in text
    # no hand-typed markdown table of timings: every table row with 'ms' lives in a block
    for line in text.splitlines():
        if line.startswith("|") and re.search(r"\d\s*ms\b", line):
            pytest.fail(f"hand-typed timing outside a generated block: {line[:100]}")


def _block(name: str) -> str:
    text = report.README.read_text()
    m = re.search(rf"<!-- report:{re.escape(name)} -->\n(.*?)<!-- /report:{re.escape(name)} -->",
                  text, re.S)
    assert m is not None
    return m.group(1)


def test_closed_loop_figures_are_the_records_numbers():
    """Every tanksynth row of the closed-loop block: min / median ms from the JSON times."""
    rec = json.loads((report.RESULTS / "closed_loop.json").read_text())
    block = _block("closed_loop")
    for row in rec["rows"]:
        t = row["times"]["tanksynth"]
        lo, med = min(t) * 1e3, statistics.median(t) * 1e3
        line = next(ln for ln in block.splitlines()
                    if ln.startswith(f"| {row['plant']} | {row['M']} | tanksynth"))
        cell = line.split("|")[4].strip()
        a, b = (float(v.replace(",", "")) for v in cell.split(" / "))
        assert a == pytest.approx(lo, rel=5e-3) and b == pytest.approx(med, rel=5e-3)
    # the load average of the record is the one quoted
    assert f"load average {report.num(rec['machine']['loadavg'][0], 2)} before" in block


def test_number_format_by_hand():
    assert report.num(1234.7) == "1,235"
    assert report.num(0.012345) == "0.0123"
    assert report.num(12.345) == "12.3"
    assert report.num(2.5e-5) == "2.50e-05"
    assert report.num(float("inf")) == "inf"
    assert report.num(None) == "-"
    assert report.min_med([0.003, 0.001, 0.002], 1e3) == "1.00 / 2.00"


def test_update_replaces_only_the_inside_of_blocks(tmp_path):
    (tmp_path / "x.json").write_text(json.dumps({
        "machine": {"time": "T", "commit": "abc", "loadavg": [1.5, 1, 1], "cpus": 2},
        "loadavg_after": [2.25, 1, 1],
        "floors": [{"what": "w", "median_ratio": 0.5, "floor": 1.0, "ok": False,
                    "strict_only": True}]}))
    text = "head 12 ms\n<!-- report:x -->\nstale 99\n<!-- /report:x -->\ntail\n"
    out = report.update(text, tmp_path)
    assert out.startswith("head 12 ms\n<!-- report:x -->\n") and out.endswith("<!-- /report:x -->\ntail\n")
    assert "stale" not in out
    assert "| w | 0.500 (median) | 1.00 | **miss** (exit 1 with --strict) |" in out
    assert "commit abc" in out and "load average 1.5 before, 2.2 after" in out
