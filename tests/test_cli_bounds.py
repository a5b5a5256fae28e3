"""Size bounds of today's synthesis options and the routing of warnings (breaker findings)."""

import warnings

import pytest

from tanksynth.cli import main

SPEC = """
[plant]
model = "three_tank"
outputs = "h1h2"
[operating_point]
x = {{h1 = 0.40, h2 = 0.20, h3 = 0.30}}
[sampling]
ts = 1.0
[[design]]
name = "d"
method = "{method}"
{extra}
"""


@pytest.mark.parametrize("method, extra, key", [
    ("h2_state_feedback", "disturbance_std = 1e300", "design[0].disturbance_std"),
    ("hinf_observer", "measurement_std = [1e300, 1.0]", "design[0].measurement_std"),
    ("hinf_observer", "backoff = 1e308", "design[0].backoff"),
    ("multiobjective", 'target = "state_feedback"\nregion = [{type = "disk", center = 0.9, radius = 0.08}]\nhinf_bound = 1e300',
     "design[0].hinf_bound"),
    ("robust_state_feedback", 'region = [{type = "disk", center = 0.9, radius = 0.08}]\ngamma = 1e308',
     "design[0].gamma"),
])
def test_absurd_sizes_are_bad_input_naming_the_key(tmp_path, capsys, method, extra, key):
    spec = tmp_path / "s.toml"
    spec.write_text(SPEC.format(method=method, extra=extra))
    assert main(["design", str(spec), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and key in err[0] and "s.toml" in err[0]
    assert not (tmp_path / "out").exists() or not list((tmp_path / "out").glob("d.*"))


def test_unknown_method_name_suggests_the_close_one(capsys):
    assert main(["methods", "hinf_statefeedback"]) == 2
    err = capsys.readouterr().err
    assert "did you mean 'hinf_state_feedback'" in err and "linearize" not in err


def test_library_warnings_are_one_note_on_stdout_and_ours_a_line_on_stderr(monkeypatch, capsys):
    from tanksynth import cli
    from tanksynth.errors import TanksynthWarning

    def noisy(argv):
        warnings.warn("overflow encountered in exp", RuntimeWarning)
        warnings.warn("overflow encountered in exp", RuntimeWarning)
        warnings.warn("premises undefined at 3 points", TanksynthWarning)
        return 0

    monkeypatch.setattr(cli, "_main", noisy)
    assert cli.main(["check", "x.toml"]) == 0
    out, err = capsys.readouterr()
    assert err.strip() == "warning: premises undefined at 3 points"
    assert "note: 2 library warning(s) (RuntimeWarning) were handled" in out
    assert "overflow" not in err


def test_our_warning_stays_off_stderr_when_the_exit_is_bad_input(monkeypatch, capsys):
    from tanksynth import cli
    from tanksynth.errors import TanksynthWarning

    def failing(argv):
        warnings.warn("premises undefined at 3 points", TanksynthWarning)
        cli.click.echo("error: x.toml: key 'plant': bad", err=True)
        return 2

    monkeypatch.setattr(cli, "_main", failing)
    assert cli.main(["check", "x.toml"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == ["error: x.toml: key 'plant': bad"]


def test_an_echoed_huge_value_is_cut_in_the_one_error_line(tmp_path, capsys):
    """Found by make fuzz: plant.N = a nested list of 301-digit integers echoed whole (2,550 chars)."""
    big = str(10 ** 300)
    row = "[" + ", ".join([big] * 3) + "]"
    spec = tmp_path / "s.toml"
    spec.write_text(f'[plant]\nmodel = "tank_network"\nN = [[0, 0, 0], {row}, {row}]\n'
                    '[operating_point]\nx = {h1 = 0.1}\n')
    assert main(["check", str(spec), "--spec-only"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "plant.N" in lines[0] and "<301 digits>" in lines[0]
    assert len(lines[0]) <= 600


def test_a_region_written_as_a_list_gets_the_toml_form_in_the_error(tmp_path, capsys):
    """New-user finding: `tanksynth methods` showed the parsed tuple form, the error no example."""
    spec = tmp_path / "s.toml"
    spec.write_text(SPEC.format(method="lmi_placement", extra='target = "observer"\nregion = [["disk", 0.9, 0.08]]'))
    assert main(["check", str(spec), "--spec-only"]) == 2
    err = capsys.readouterr().err
    assert "design[0].region[0]" in err and '{type = "disk", center = 0.9, radius = 0.08}' in err
    assert main(["methods", "lmi_placement", "--json"]) == 0
    assert '{type = \\"disk\\", center = c, radius = r}' in capsys.readouterr().out
