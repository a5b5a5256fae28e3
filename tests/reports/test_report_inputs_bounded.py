"""Break31: `report` reads every file of a result directory bounded, like `verify`.

A FIFO (or ``/dev/zero``) named as any ``*.json`` of the directory, ``spec.toml``,
``refused.json`` or ``campaign.csv`` blocked `read_report_inputs` in ``open()`` (or read
without end); each is refused naming the file, exit 2, as `verify` does.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import tanksynth
from reports_helpers import design_dir

PACKAGE_ROOT = Path(tanksynth.__file__).resolve().parents[1]
SPEC = """
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {h1 = 0.40, h2 = 0.20, h3 = 0.30}
[sampling]
ts = 1.0
[[design]]
name = "pp"
method = "pole_placement"
target = "state_feedback"
poles = [0.92, 0.97, 0.90]
"""


@pytest.mark.parametrize("name", ["pp.json", "notes.json", "spec.toml", "refused.json", "campaign.csv"])
@pytest.mark.parametrize("kind", ["fifo", "dev_zero"])
def test_report_refuses_a_fifo_or_device_named_as_its_input(tmp_path, name, kind):
    directory = design_dir(tmp_path, SPEC)
    (directory / "spec.toml").write_text(SPEC)
    target = directory / name
    target.unlink(missing_ok=True)
    if kind == "fifo":
        os.mkfifo(target)
    else:
        target.symlink_to("/dev/zero")
    code = ("from tanksynth.reports.inputs import read_report_inputs\n"
            "from tanksynth.errors import ArtefactError\n"
            f"try:\n    read_report_inputs({str(directory)!r})\n"
            "except ArtefactError as exc:\n    print(exc)\n")
    env = dict(os.environ, PYTHONPATH=str(PACKAGE_ROOT))
    try:   # a hang guard, not a timing assertion
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             timeout=120, env=env)
    except subprocess.TimeoutExpired:
        pytest.fail(f"read_report_inputs blocked on a {kind} named {name}")
    assert out.returncode == 0, out.stderr
    assert f"{name}: not a regular file" in out.stdout
