"""Memory of an LMI design before it runs (issue 31 items 2 and 8b).

A large valid plant's LMI synthesis used to grow until Clarabel's allocator
aborted the process (SIGABRT, no message, the lock left, the finished designs
lost); a bad ``TANKSYNTH_MEMORY_BUDGET_MB`` was ignored or refused everything.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import pytest

from tanksynth.cli import main
from tanksynth.errors import SpecError

#: One pump pair's equilibrium at 4 V (examples/tank_network_n8.toml), repeated for N = 4k tanks.
_LOWER, _UPPER = [21.70591608, 22.54471524], [9.04293578, 5.08665138]
_MULTIOBJECTIVE = ('[[design]]\nname = "{name}"\nmethod = "multiobjective"\ntarget = "state_feedback"\n'
                   'region = [{{type = "disk", center = 0.9, radius = 0.08}}]\n')


def network_spec(N: int, designs: str) -> str:
    """A tank_network spec with N tanks at 4 V on every pump, then ``designs``."""
    x = _LOWER * (N // 4) + _UPPER * (N // 4)
    return (f'[plant]\nmodel = "tank_network"\nN = {N}\n[operating_point]\nx = {x}\n'
            f'u = {[4.0] * (N // 2)}\n[sampling]\nts = 1.0\n' + designs)


def _linearize(name: str) -> str:
    return f'[[design]]\nname = "{name}"\nmethod = "linearize"\n'


@pytest.fixture
def no_conic_build(monkeypatch):
    """Fail loudly if a synthesis LMI problem starts being built (the refusal must come first)."""
    import tanksynth.design.synthesis.synthesize as synthesize

    def forbidden(solver):
        raise AssertionError("the LMI problem was built: not refused before solving")

    monkeypatch.setattr(synthesize, "modelling", forbidden)


def test_a_huge_lmi_design_after_small_ones_is_refused_before_solving_and_theirs_are_written(
        tmp_path, capsys, no_conic_build):
    spec = tmp_path / "big.toml"
    spec.write_text(network_spec(64, _linearize("lin_a") + _linearize("lin_b")
                                 + _MULTIOBJECTIVE.format(name="mo")))
    out = tmp_path / "out"
    assert main(["design", str(spec), "-o", str(out)]) == 3
    captured = capsys.readouterr()
    line = [ln for ln in captured.out.splitlines() if ln.startswith("refused mo")]
    assert len(line) == 1 and "GiB" in line[0] and "fewer" in line[0]
    assert "mo" in captured.err and "Traceback" not in captured.err
    for name in ("lin_a", "lin_b"):
        assert (out / f"{name}.json").is_file() and (out / f"{name}.npz").is_file()
    assert not list(out.glob("mo.*"))
    assert not list(out.glob("*.lock")) and not list(out.glob(".*lock*"))
    refused = json.loads((out / "refused.json").read_text())
    assert "mo" in json.dumps(refused)


def test_check_spec_only_reports_the_design_over_the_budget(tmp_path, capsys):
    spec = tmp_path / "big.toml"
    spec.write_text(network_spec(64, _linearize("lin") + _MULTIOBJECTIVE.format(name="mo")))
    assert main(["check", "--spec-only", str(spec)]) == 3
    out = capsys.readouterr().out
    assert "refused design 'mo'" in out and "GiB" in out


def test_a_low_budget_refuses_a_mid_size_design_before_solving(tmp_path, capsys, monkeypatch,
                                                               no_conic_build):
    monkeypatch.setenv("TANKSYNTH_MEMORY_BUDGET_MB", "64")
    spec = tmp_path / "mid.toml"
    spec.write_text(network_spec(16, _MULTIOBJECTIVE.format(name="mid")))
    assert main(["design", str(spec), "-o", str(tmp_path / "out")]) == 3
    out = capsys.readouterr().out
    assert "refused mid" in out and "0.0625 GiB" in out
    assert not list((tmp_path / "out").glob("mid.*"))


def test_each_artefact_is_written_before_the_next_design_starts(tmp_path, monkeypatch):
    import tanksynth.design.synthesis.synthesize as synthesize

    out = tmp_path / "out"
    seen = []

    def crash(solver):  # the second design dies mid-way (as the solver's abort did)
        seen.append((out / "first.json").is_file())
        raise RuntimeError("simulated crash")

    monkeypatch.setattr(synthesize, "modelling", crash)
    spec = tmp_path / "s.toml"
    spec.write_text(network_spec(8, _linearize("first") + _MULTIOBJECTIVE.format(name="second")))
    assert main(["design", str(spec), "-o", str(out)]) == 4
    assert seen == [True]
    assert (out / "first.json").is_file() and not list(out.glob("second.*"))


BAD_BUDGETS = ["abc", "-5", "nan", "inf", "1e-300", "0", "-inf", "1e400"]


@pytest.fixture(scope="module")
def linear_run(tmp_path_factory):
    """A result directory (two linearisations of the 8-tank network) for `verify`."""
    root = tmp_path_factory.mktemp("budget")
    spec = root / "s.toml"
    spec.write_text(network_spec(8, _linearize("lin") + _linearize("lin2")))
    assert main(["design", str(spec), "-o", str(root / "run")]) == 0
    return spec, root / "run"


@pytest.mark.parametrize("value", BAD_BUDGETS)
def test_a_bad_memory_budget_is_bad_input_naming_the_variable(tmp_path, capsys, monkeypatch, value,
                                                             linear_run):
    spec, run = linear_run
    capsys.readouterr()
    monkeypatch.setenv("TANKSYNTH_MEMORY_BUDGET_MB", value)
    for argv in (["check", "--spec-only", str(spec)], ["design", str(spec), "-o", str(tmp_path / "o")],
                 ["verify", str(run)]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and repr(value) in err[0], (argv, err)
        assert err[0].count("TANKSYNTH_MEMORY_BUDGET_MB") == 1  # once, not once per design
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("value, mib", [("64", 64), ("1", 1), (" 2048 ", 2048), ("", 2048)])
def test_a_good_memory_budget_is_read_in_mib(monkeypatch, value, mib):
    from tanksynth.spec.memory import memory_budget

    monkeypatch.setenv("TANKSYNTH_MEMORY_BUDGET_MB", value)
    assert memory_budget() == mib * 1024 ** 2


@pytest.mark.parametrize("value", BAD_BUDGETS)
def test_memory_budget_refuses_a_bad_value(monkeypatch, value):
    from tanksynth.spec.memory import memory_budget

    monkeypatch.setenv("TANKSYNTH_MEMORY_BUDGET_MB", value)
    with pytest.raises(SpecError, match="TANKSYNTH_MEMORY_BUDGET_MB"):
        memory_budget()


def test_the_conic_size_of_multiobjective_is_its_lmi_structure():
    """Counted by hand from `tanksynth.design.synthesis.synthesize` (discrete, H-infinity, disk):
    X (n x n), Y (m x n), gamma, t; blocks X > 0, X < cap I, the reduced bounded real lemma
    (2n + nz, nz = n + m) and the disk (2n)."""
    from tanksynth.methods import parse_spec_text

    spec = parse_spec_text(network_spec(8, _MULTIOBJECTIVE.format(name="mo")))
    size = spec.designs[0].config.conic_size(spec.plant, spec.ts)
    n, m = 8, 4
    assert size.variables == n * (n + 1) // 2 + m * n + 2
    assert sorted(size.psd_orders) == sorted([n, n, 2 * n + n + m, 2 * n])


_MEASURE = textwrap.dedent("""
    import json, sys, warnings
    warnings.simplefilter("ignore")
    from tanksynth.methods import METHODS, parse_spec_text
    import tanksynth.design.synthesis.synthesize, clarabel, scipy.sparse  # imports before the baseline
    def status(key):
        for line in open("/proc/self/status"):
            if line.startswith(key + ":"):
                return int(line.split()[1]) * 1024
    spec = parse_spec_text(sys.stdin.read())
    base = status("VmRSS")
    METHODS[spec.designs[0].method].design(spec, spec.designs[0])
    print(json.dumps(status("VmHWM") - base))
""")


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs /proc (Linux)")
@pytest.mark.parametrize("N", [8, 12])
def test_the_estimate_bounds_the_measured_peak_within_a_small_factor(N):
    """Calibration (more sizes: benchmarks/conic_memory.py): the estimate is above the peak RSS
    a real solve adds, and within a factor 2.5 of it."""
    from tanksynth.methods import parse_spec_text
    from tanksynth.spec.memory import conic_bytes

    text = network_spec(N, _MULTIOBJECTIVE.format(name="mo"))
    spec = parse_spec_text(text)
    estimate = conic_bytes(spec.designs[0].config.conic_size(spec.plant, spec.ts))
    done = subprocess.run([sys.executable, "-c", _MEASURE], input=text, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    measured = json.loads(done.stdout.strip().splitlines()[-1])
    assert measured <= estimate <= 2.5 * measured


EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.mark.slow
@pytest.mark.parametrize("example, name", [
    ("seed000_pole_placement", "integral_lmi_disk"),        # lmi_placement, integral action
    ("three_tank_robust", "robust_integral"),               # robust_state_feedback
    ("three_tank_robust", "robust_saturation"),
    ("three_tank_robust", "robust_observer"),
    ("three_tank_ts_control", "pdc"),                       # ts_state_feedback
    ("three_tank_ts_control", "pdc_output"),                # ts_output_feedback
    ("seed001_ts_observer", "ts_observer_paper_safe"),      # ts_observer
    ("three_tank_hinf", "multiobjective_disk"),             # synthesis, LMI route
])
def test_every_lmi_familys_estimate_covers_the_problem_it_really_builds(monkeypatch, example, name):
    """The reference is the conic problem the design hands Clarabel (cones and columns read
    at `Problem._data`): the structure each family's ``conic_size`` counts must not be smaller."""
    from tanksynth.methods import load_spec

    spec = load_spec(EXAMPLES / f"{example}.toml")
    _assert_estimate_covers_the_built_problem(monkeypatch, spec, name)


_THREE_TANK_HEAD = (EXAMPLES / "three_tank_hinf.toml").read_text().split("[[design]]")[0]
_DISK = 'region = [{type = "disk", center = 0.9, radius = 0.08}]\n'


@pytest.mark.slow
@pytest.mark.parametrize("options", [
    'method = "multiobjective"\ntarget = "observer"\n' + _DISK,
    'method = "multiobjective"\ntarget = "state_feedback"\nobjective = "h2"\nhinf_bound = 1e3\n' + _DISK,
    'method = "multiobjective"\ntarget = "state_feedback"\ntime_domain = "continuous"\n'
    'region = [{type = "half_plane", alpha = 0.001}, {type = "sector", angle_deg = 60}]\n',
    'method = "h2_observer"\nroute = "lmi"\n',
    'method = "hinf_state_feedback"\nroute = "lmi"\ntime_domain = "continuous"\n',
])
def test_the_synthesis_estimate_covers_every_lmi_variant(monkeypatch, options):
    from tanksynth.methods import parse_spec_text

    spec = parse_spec_text(_THREE_TANK_HEAD + '[[design]]\nname = "d"\n' + options)
    _assert_estimate_covers_the_built_problem(monkeypatch, spec, "d")


def _assert_estimate_covers_the_built_problem(monkeypatch, spec, name):
    from tanksynth.design import conic
    from tanksynth.methods import METHODS
    from tanksynth.spec.memory import ConicSize, conic_bytes

    built: list[ConicSize] = []
    real_data = conic.Problem._data

    def spy(self):
        out = real_data(self)
        A, cones = out[2], out[4]
        psd = [type(c).__name__.startswith("PSD") for c in cones]
        built.append(ConicSize(variables=A.shape[1],
                               psd_orders=tuple(float(c.dim) for c, p in zip(cones, psd) if p),
                               linear_rows=sum(c.dim for c, p in zip(cones, psd) if not p)))
        return out

    monkeypatch.setattr(conic.Problem, "_data", spy)
    entry = next(d for d in spec.designs if d.name == name)
    size = entry.config.conic_size(spec.plant, spec.ts)
    assert size is not None and size.advice
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            METHODS[entry.method].design(spec, entry)
    except Exception:  # a refusal after solving is fine: the problems were built
        pass
    assert built, "the design built no conic problem"
    for real in built:
        assert size.variables >= real.variables
        assert size.svec_rows >= real.svec_rows
        assert size.linear_rows >= real.linear_rows
        assert conic_bytes(size) >= conic_bytes(real)


@pytest.mark.parametrize("name, options", [("three_tank", {}), ("hybrid_three_tank", {}),
                                           ("tank_network", {"N": 8}), ("hydraulic_fault", {})])
def test_nonlinear_atoms_bound_the_premises_of_the_quasi_lpv_split(name, options):
    from tanksynth.analysis.quasi_lpv import quasi_lpv
    from tanksynth.plants import builtin_plant
    from tanksynth.spec.memory import nonlinear_atoms

    plant = builtin_plant(name, **options)
    assert quasi_lpv(plant).p <= nonlinear_atoms(plant) <= 2 * max(quasi_lpv(plant).p, 1)


def test_lmi_placement_counts_every_kappa_retry():
    """The kappa relaxation may solve at kappa, 100 kappa, ... up to kappa_max: each try's
    problems are counted (breaker: N = 36 peaked 1.3x over the two-problem estimate)."""
    from tanksynth.design.lmi_checks import KAPPA_STEP
    from tanksynth.spec.memory import KAPPA_RETRY_STEP, kappa_tries

    assert KAPPA_RETRY_STEP == KAPPA_STEP
    assert kappa_tries(1e4, 1e4) == 1
    assert kappa_tries(1e4, 1e8) == 3              # 1e4, 1e6, 1e8
    assert kappa_tries(1e4, 1.5e6) == 3            # 1e4, 1e6, then the ceiling
    assert kappa_tries(2.0, 1e300) <= 64


@pytest.mark.parametrize("samples, measured_mib", [(2000, 57), (10000, 141), (40000, 351)])
def test_fit_bytes_bounds_the_measured_peak(samples, measured_mib):
    """The fit's estimate is an upper bound of the peak RSS measured on the three-tank (3 states;
    see the module docstring), without overstating it more than about 2x."""
    from tanksynth.spec.memory import fit_bytes

    need = fit_bytes(samples, 3) / 1024 ** 2
    assert measured_mib <= need <= 2.0 * measured_mib
