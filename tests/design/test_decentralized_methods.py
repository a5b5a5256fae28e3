

def test_not_converged_is_a_design_warning_on_the_command_line(tmp_path):
    """An unconverged finite-horizon iteration is about the design: the CLI says so on a
    `warning: <design>:` line (it was a library RuntimeWarning cut in a note)."""
    from click.testing import CliRunner

    from tanksynth.cli import cli

    spec = tmp_path / "dk.toml"
    spec.write_text(
        '[plant]\nmodel = "tank_network"\nN = 4\n\n'
        '[operating_point]\nx = [21.70591608, 22.54471524, 9.04293578, 5.08665138]\n'
        'u = [4.0, 4.0]\n\n[sampling]\nts = 1.0\n\n'
        '[[design]]\nname = "dk"\nmethod = "decentralized_kalman"\nwindow = 10\n'
        'algorithm = "iterative"\nmax_iter = 1\ntolerance = 1e-15\nprocess_noise = 0.01\n'
        'measurement_noise = 4.0\ninitial_covariance = 10.0\n')
    res = CliRunner().invoke(cli, ["design", str(spec), "-o", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert "warning: dk: finite-horizon gains (iterative) did not converge" in res.output
