"""Options of ``decentralized_kalman``: sparse Kalman gains over one window (seed 003)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

import numpy as np

from tanksynth.errors import SpecError
from tanksynth.spec.method_options.base import MethodOptions, OptionReader, option
from tanksynth.spec.options import (parse_choice, parse_covariance, parse_integer, parse_matrix,
                                    parse_number, parse_vector)

if TYPE_CHECKING:  # the plant's module loads sympy; only its type is needed here
    from tanksynth.plants.base import Plant

__all__ = ["DECENTRALIZED_ALGORITHMS", "DecentralizedKalmanOptions"]

#: Values of the ``algorithm`` option.
DECENTRALIZED_ALGORITHMS = ("casadi", "iterative", "one_step")


def _noise(value: Any, key: str, size: int, *, semidefinite: bool) -> float | np.ndarray:
    """A number (kept: times the identity) or a covariance matrix (list of rows, or diagonal),
    at most `NOISE_MAX` in size (beyond it the Riccati recursion overflows or loses every digit)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if semidefinite:
            return parse_number(value, key, at_least=0.0, at_most=NOISE_MAX)
        return parse_number(value, key, above=0.0, at_most=NOISE_MAX)
    cov = parse_covariance(value, key, size, semidefinite)
    if np.max(np.abs(cov)) > NOISE_MAX:
        raise SpecError(f"covariance entries must be at most {NOISE_MAX:g} in size, got "
                        f"{np.max(np.abs(cov)):.3g}", key=key)
    return cov


#: Largest covariance entry accepted (the plant's units squared, or squared per s): a
#: level known to 1e6 m (or cm) is no knowledge at all, and 1e12 keeps the recursion finite.
NOISE_MAX = 1e12


def _pattern(value: Any, key: str, shape: tuple[int, int]) -> str | np.ndarray:
    """``"own_tank"`` or an explicit 0/1 matrix with at least one free entry."""
    if isinstance(value, str):
        if value not in ("own_tank", "own tank"):
            raise SpecError(f"expected \"own_tank\" or an explicit {shape[0]} x {shape[1]} matrix of "
                            f"0/1, got {value!r}", key=key)
        return "own_tank"
    E = parse_matrix(value, key, shape)
    if not np.all((E == 0) | (E == 1)):
        raise SpecError("E entries must be 0 (gain entry fixed at 0) or 1 (free)", key=key)
    if not E.any():
        raise SpecError("E has no free entry: every gain would be 0", key=key)
    return E


@dataclass(frozen=True, eq=False)
class DecentralizedKalmanOptions(MethodOptions):
    """Options of ``decentralized_kalman``: the decentralised Kalman gains ``K(1) .. K(T)`` of
    one window from the operating point, under a sparsity pattern ``E`` (seed 003, DECENTER).

    Attributes
    ----------
    process_noise : float or ndarray
        Required. Process-noise intensity ``Qc`` (squared state unit per s): a
        number ``q`` (>= 0; ``Qc = q ((1 - rho) I + rho 1 1')``) or an n x n
        positive semidefinite matrix; discretised exactly (Van Loan).
    algorithm : str
        ``"iterative"`` (default: finite horizon, Pedroso and Batista's
        sweeps), ``"casadi"`` (the same window problem by IPOPT: the same
        cost, 18-20x slower at N = 64) or ``"one_step"`` (step-by-step
        optimal gains).
    window : int
        Steps ``T`` of the window (>= 1); default 40.
    E : str or ndarray
        Sparsity pattern: ``"own_tank"`` (default: each state uses the outputs
        measuring it alone) or an explicit n x q matrix of 0 (fixed at 0) and
        1 (free).
    tolerance : float
        Relative tolerance of the finite-horizon iteration (> 0); default 1e-6.
        Dimensionless.
    max_iter : int
        Iteration limit (>= 1); default 100.
    process_noise_correlation : float
        ``rho`` in [0, 1) for a number ``process_noise``; default 0.
    measurement_noise : float or ndarray
        ``R`` (squared output unit): a number (> 0, times I) or a q x q positive
        definite matrix; default 1.
    initial_covariance : float or ndarray
        ``P(0|0)`` (squared state unit): a number (> 0, times I) or an n x n
        positive definite matrix; default 10.
    input : ndarray or None
        Input held over the window (m values, input units); default None: the
        equilibrium input of the operating point.
    relinearize_every : int
        Steps between linearisations along the predicted trajectory (>= 1);
        default 10.
    run_steps : int
        Samples of the verdict's long run (>= 0; default 0: none): the nonlinear plant
        from the operating point under ``input`` (then ``input_after``), measured with
        ``measurement_noise``, filtered by the centralised, the one-step and the finite-horizon
        decentralised filters relinearised at their estimates every ``relinearize_every``
        samples (the last with gains per ``window`` samples, to ``tolerance``, at most
        ``max_iter`` sweeps).
    input_after : ndarray or None
        Input of the long run from ``input_switch`` on (m values, input units); default
        None: ``input`` throughout.
    input_switch : float
        Time of the long run's input change (s, >= 0); default 0.
    run_seed : int
        Seed of the long run's noise and initial estimate (>= 0); default 7.
    run_x0 : ndarray or None
        Initial state of the long run (n values, state units); default None: the operating
        point. The estimates start at ``run_x0 + N(0, initial_covariance)``.
    """

    method_name: ClassVar[str] = "decentralized_kalman"
    needs_sampling: ClassVar[bool] = True

    process_noise: float | np.ndarray = option(unit="(state units)^2/s")
    algorithm: str = option("iterative", unit="-", choices=DECENTRALIZED_ALGORITHMS)
    window: int = option(40, unit="samples")
    E: str | np.ndarray = option("own_tank", unit="-")
    tolerance: float = option(1e-6, unit="-")
    max_iter: int = option(100, unit="-")
    process_noise_correlation: float = option(0.0, unit="-")
    measurement_noise: float | np.ndarray = option(1.0, unit="(output units)^2")
    initial_covariance: float | np.ndarray = option(10.0, unit="(state units)^2")
    input: np.ndarray | None = option(None, unit="input units")
    relinearize_every: int = option(10, unit="samples")
    run_steps: int = option(0, unit="samples")
    input_after: np.ndarray | None = option(None, unit="input units",
                                              default_text="unset: input throughout")
    input_switch: float = option(0.0, unit="s")
    run_seed: int = option(7, unit="-")
    run_x0: np.ndarray | None = option(None, unit="state units",
                                         default_text="unset: the operating point")

    @classmethod
    def from_table(cls, options: Mapping[str, Any], key: str, plant: Plant,
                   ts: float | None) -> "DecentralizedKalmanOptions":
        """See `MethodOptions.from_table`; the correlation applies to a number ``process_noise``."""
        r = OptionReader(cls, options, key, ts)
        n, q = plant.n, plant.q
        Qc = r.read("process_noise", _noise, n, semidefinite=True)
        rho = r.read("process_noise_correlation", parse_number, at_least=0.0, below=1.0)
        if isinstance(Qc, np.ndarray) and r.given("process_noise_correlation"):
            raise r.fail("process_noise_correlation",
                         "process_noise_correlation only applies to a scalar process_noise")
        return cls(
            process_noise=Qc, algorithm=r.read("algorithm", parse_choice, DECENTRALIZED_ALGORITHMS),
            window=r.read("window", parse_integer, at_least=1, at_most=100_000),
            E=r.read("E", _pattern, (n, q)),
            tolerance=r.read("tolerance", parse_number, above=0.0),
            max_iter=r.read("max_iter", parse_integer, at_least=1, at_most=100_000),
            process_noise_correlation=rho,
            measurement_noise=r.read("measurement_noise", _noise, q, semidefinite=False),
            initial_covariance=r.read("initial_covariance", _noise, n, semidefinite=False),
            input=r.read("input", parse_vector, names=[s.name for s in plant.inputs]),
            relinearize_every=r.read("relinearize_every", parse_integer, at_least=1),
            run_steps=r.read("run_steps", parse_integer, at_least=0, at_most=100_000),
            input_after=r.read("input_after", parse_vector, names=[s.name for s in plant.inputs]),
            input_switch=r.read("input_switch", parse_number, at_least=0.0),
            run_seed=r.read("run_seed", parse_integer, at_least=0, at_most=2 ** 32 - 1),
            run_x0=r.read("run_x0", parse_vector, names=[s.name for s in plant.states]))

    def memory_estimate(self, plant: Plant, ts: float | None) -> tuple[float, str]:
        """``window`` steps of n x n models, covariances and gains; CasADi's graph of the window
        problem holds some 50 matrices per step (bytes)."""
        per_step = plant.n ** 2 * 10 + plant.n * plant.q * 4 + plant.q ** 2 * 4
        return 8.0 * (50 if self.algorithm == "casadi" else 1) * self.window * per_step, "window"
