

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


def test_design_runs_on_one_blas_thread(monkeypatch):
    """The reference costs and the finite-horizon iteration run with the BLAS limited to one
    thread (issue 15: OpenBLAS's threads made each 128 x 128 Cholesky ~60 ms of waiting on the
    loaded 2-core machine); the limit is lifted again after the design."""
    from threadpoolctl import threadpool_info

    import tanksynth.design.decentralized.adapters as dm
    from tanksynth.methods import METHODS
    from tanksynth.spec import parse_spec_text

    def blas_threads():
        return [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]

    seen = {}
    for name in ("one_step_gains", "centralized_gain", "finite_horizon_gains"):
        def spy(*args, _fn=getattr(dm, name), _name=name, **kwargs):
            seen.setdefault(_name, blas_threads())
            return _fn(*args, **kwargs)
        monkeypatch.setattr(dm, name, spy)
    spec = parse_spec_text(
        '[plant]\nmodel = "tank_network"\nN = 4\n\n'
        '[operating_point]\nx = [21.70591608, 22.54471524, 9.04293578, 5.08665138]\n'
        'u = [4.0, 4.0]\n\n[sampling]\nts = 1.0\n\n'
        '[[design]]\nname = "dk"\nmethod = "decentralized_kalman"\nwindow = 5\n'
        'process_noise = 0.01\nmeasurement_noise = 4.0\ninitial_covariance = 10.0\n')
    before = blas_threads()
    METHODS["decentralized_kalman"].design(spec, spec.designs[0])
    assert before, "no BLAS library found by threadpoolctl"
    assert set(seen) == {"one_step_gains", "centralized_gain", "finite_horizon_gains"}
    assert all(threads == [1] * len(before) for threads in seen.values()), seen
    assert blas_threads() == before
