"""The C driver of the docs' export page (docs/export.md, "Using an exported law") compiles
(gcc -std=c99 -Wall -Werror) against laws exported from an example's plant and prints what the
``.casadi`` Function computes.

The designs: the example seed000_pole_placement's integral state feedback (inputs x, z, y_r) and
a pole-placement observer on the same plant (predictor form, inputs x_hat, u, y). The observer's
expected step is also rebuilt here from the artefact's gain and a numpy ZOH of the linearisation
(absolute values in, absolute values out).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tanksynth.cli import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "seed000_pole_placement.toml"

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")

OBSERVER = """
[[design]]
name = "obs_pp"
method = "pole_placement"
target = "observer"
poles = [0.5, 0.6, 0.7]
"""


def _readme_driver() -> tuple[str, str]:
    """The C driver and the gcc command of the export page's section."""
    text = (ROOT / "docs" / "export.md").read_text(encoding="utf-8")
    section = text.split("## Using an exported law", 1)[1].split("\n## ", 1)[0]
    driver = re.search(r"```c\n(.*?)```", section, re.S).group(1)
    command = re.search(r"```\n(gcc .*?)\n", section, re.S).group(1)
    return driver, command


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> Path:
    work = tmp_path_factory.mktemp("cdriver")
    text = EXAMPLE.read_text(encoding="utf-8")
    text = text.split("# Same structure, eigenvalues anywhere", 1)[0] + OBSERVER  # first design only
    spec = work / "spec.toml"
    spec.write_text(text, encoding="utf-8")
    assert main(["design", str(spec), "-o", str(work / "out"), "--export", "law"]) == 0
    return work / "out"


def _build(directory: Path, name: str, tmp: Path) -> Path:
    driver, command = _readme_driver()
    assert command.split()[:5] == ["gcc", "-std=c99", "-Wall", "-Werror", "-O2"]
    (tmp / "main.c").write_text(driver.replace("obs_pp", name), encoding="utf-8")
    exe = tmp / name
    args = [a for a in command.replace("obs_pp", name).replace("DIR", str(directory)).split()]
    args[args.index("-o") + 1] = str(exe)
    subprocess.run(args, cwd=tmp, check=True, capture_output=True, text=True, timeout=120)
    return exe


def _run(exe: Path, inputs: list[np.ndarray]) -> dict[str, np.ndarray]:
    stdin = " ".join(f"{v:.17g}" for arr in inputs for v in np.ravel(arr, order="F"))
    proc = subprocess.run([str(exe)], input=stdin, capture_output=True, text=True, timeout=60,
                          check=True)
    out = {}
    for line in proc.stdout.strip().splitlines():
        name, *values = line.split()
        out[name] = np.array([float(v) for v in values])
    return out


@pytest.mark.parametrize("name", ["integral_pole_placement", "obs_pp"])
def test_readme_driver_prints_what_the_casadi_function_computes(exported, tmp_path, name):
    import casadi as ca

    law = ca.Function.load(str(exported / f"{name}_law.casadi"))
    exe = _build(exported, name, tmp_path)
    rng = np.random.default_rng(7)
    x_op = np.array([0.40, 0.20, 0.30])
    for _ in range(3):
        inputs = []
        for i in range(law.n_in()):
            size = law.size1_in(i)
            base = x_op if size == 3 else np.full(size, 3.3e-5 if law.name_in(i) == "u" else 0.25)
            inputs.append(base + 0.01 * base * rng.standard_normal(size))
        got = _run(exe, inputs)
        want = law(*inputs)
        want = want if isinstance(want, (list, tuple)) else [want]
        assert list(got) == [law.name_out(j) for j in range(law.n_out())]
        for j, value in enumerate(want):
            np.testing.assert_allclose(got[law.name_out(j)], np.asarray(value).ravel(),
                                       rtol=1e-12, atol=1e-15)


def test_observer_law_is_the_predictor_step_in_absolute_values(exported, tmp_path):
    """x_hat(k+1) = x_op + Ad dx + Bd du + L (dy - C dx), rebuilt with numpy/scipy."""
    from scipy.linalg import expm

    from tanksynth.analysis import equilibrium_input, linearize
    from tanksynth.plants import three_tank

    assert (exported / "obs_pp.json").is_file()
    L = np.load(exported / "obs_pp.npz")["L"]
    plant = three_tank(outputs="all")
    x_op = np.array([0.40, 0.20, 0.30])
    u_op = equilibrium_input(plant, x_op).u0
    lin = linearize(plant, x_op, u_op, ts=None)
    n, m = lin.F.shape[0], lin.B.shape[1]
    big = np.zeros((n + m, n + m))
    big[:n, :n], big[:n, n:] = lin.F, lin.B
    E = expm(big * 1.0)
    Ad, Bd = E[:n, :n], E[:n, n:]
    np.testing.assert_allclose(np.sort(np.linalg.eigvals(Ad - L @ lin.C).real), [0.5, 0.6, 0.7],
                               atol=1e-9)
    x_hat, u, y = np.array([0.41, 0.19, 0.31]), u_op * 1.05, np.array([0.40, 0.21, 0.29])
    want = x_op + Ad @ (x_hat - x_op) + Bd @ (u - u_op) + L @ ((y - x_op) - lin.C @ (x_hat - x_op))
    got = _run(_build(exported, "obs_pp", tmp_path), [x_hat, u, y])["x_hat_next"]
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
