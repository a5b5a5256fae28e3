"""Every notebook in notebooks/ runs top to bottom in a kernel of this environment.

Each notebook reproduces one seed paper (or is the tutorial) and ends with a
cell asserting its key reproduced numbers; a failing assertion is a cell
error. The stored notebooks must be clean: no outputs, no execution counts.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("ipykernel")

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("*.ipynb"))
CELL_TIMEOUT = 300  # s


def _read(path: Path):
    return nbformat.read(path, as_version=4)


def test_notebooks_exist():
    names = {p.stem for p in NOTEBOOKS}
    assert {"00_tutorial", "01_seed000_three_tank", "02_seed001_ts_observer", "03_seed002_hybrid",
            "04_seed003_decentralized", "05_seed004_fault_detection", "06_fit_three_tank"} <= names


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_stored_without_outputs(path):
    nb = _read(path)
    nbformat.validate(nb)
    for i, cell in enumerate(nb.cells):
        if cell.cell_type == "code":
            assert cell.outputs == [], f"cell {i} of {path.name} has stored outputs"
            assert cell.execution_count is None, f"cell {i} of {path.name} has an execution count"
    assert nb.metadata.get("kernelspec", {}).get("name") == "python3"
    # the last code cell asserts the notebook's reproduced numbers
    last = [c for c in nb.cells if c.cell_type == "code"][-1]
    assert "assert" in last.source


def _no_private_imports(source: str) -> list[str]:
    bad = []
    for line in source.splitlines():
        s = line.strip()
        if s.startswith(("from tanksynth", "import tanksynth")):
            names = s.split(" import ", 1)[-1] if " import " in s else s
            module = s.split()[1]
            if any(part.startswith("_") for part in module.split(".")) or any(
                    n.strip(" ()").startswith("_") for n in names.split(",")):
                bad.append(s)
    return bad


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_public_api_only(path):
    nb = _read(path)
    bad = [b for c in nb.cells if c.cell_type == "code" for b in _no_private_imports(c.source)]
    assert not bad, f"private imports in {path.name}: {bad}"


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(path, tmp_path, monkeypatch):
    # figures are drawn off screen (the kernel inherits the environment)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = _read(path)
    probe = nbformat.v4.new_code_cell("import sys; print(sys.executable)")
    nb.cells.insert(0, probe)
    client = nbclient.NotebookClient(nb, kernel_name="python3", timeout=CELL_TIMEOUT,
                                     resources={"metadata": {"path": str(tmp_path)}})
    start = time.perf_counter()
    try:
        client.execute()
    except nbclient.exceptions.CellExecutionError as exc:
        pytest.fail(f"{path.name}: a cell failed:\n{exc}")
    elapsed = time.perf_counter() - start
    # the kernel is this environment's interpreter
    text = "".join(o.get("text", "") for o in nb.cells[0].outputs if o.output_type == "stream")
    assert Path(text.strip()).resolve() == Path(sys.executable).resolve()
    for i, cell in enumerate(nb.cells):
        if cell.cell_type == "code":
            errors = [o for o in cell.outputs if o.output_type == "error"]
            assert not errors, f"cell {i} of {path.name} raised {errors[0].ename}"
    print(f"{path.name}: {elapsed:.1f} s")
