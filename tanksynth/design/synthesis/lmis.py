"""LMI building blocks of H2 / H-infinity / region synthesis (collected in `tanksynth.design.synthesis.synthesize`).

Generalised plant (continuous time: ``x' = dx/dt``; discrete time: ``x' = x(k+1)``)::

    x' = A x + Bw w + B u          w: declared disturbances
    z  = Cz x + Dzu u              z: performance outputs (no direct term from w)

State feedback ``u = -K x`` gives ``Acl = A - B K``, ``Bw``, ``Ccl = Cz - Dzu K``.
The LMIs are written in ``X = X' > 0`` and ``Y = K X`` (``K = Y X^-1``); every
block builder below returns a matrix that must be NEGATIVE definite and works
on affine expressions (for solving: `tanksynth.design.conic`'s, written
straight in Clarabel's conic form, or cvxpy's on the SCS route) and on numpy
arrays (for re-checking):

`h2_lmis`
    continuous: ``He(AX - BY) + Bw Bw' < 0`` and ``[[W, CzX - DzuY], [., X]] > 0``;
    discrete: ``[[X - Bw Bw', AX - BY], [., X]] > 0`` and the same ``W`` block;
    ``||T_zw||_2^2 < trace W``.
`hinf_lmis`
    bounded-real lemma with ``X = P^-1``; continuous
    ``[[He(AX - BY), Bw, (CzX - DzuY)'], [Bw', -g I, 0], [CzX - DzuY, 0, -g I]] < 0``,
    discrete ``[[-X, AX - BY, Bw, 0], [., -X, 0, (CzX - DzuY)'], [Bw', 0, -g I, 0],
    [0, CzX - DzuY, 0, -g I]] < 0``; ``||T_zw||_inf < g``.
`region_lmi`
    Chilali-Gahinet ``L (x) X + M (x) (AX - BY) + M' (x) (AX - BY)' < 0`` for an
    `tanksynth.analysis.lmi_region.LMIRegion`: every eigenvalue of ``A - BK`` in it.

Solving (one ``X``, ``Y`` shared by every objective and model), scaling and the
independent re-check of the returned gain: `tanksynth.design.synthesis.synthesize`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from tanksynth.analysis.lmi_region import LMIRegion
from tanksynth.analysis.statespace import statespace_matrices
from tanksynth.design import conic
from tanksynth.design.matrices import symmetrized
from tanksynth.errors import DimensionError, SpecError

__all__ = ["DOMAINS", "GeneralizedPlant", "generalized_plant", "observer_plant",
           "h2_lmis", "hinf_lmis", "hinf_lmis_reduced", "region_lmi"]

#: Time domains.
DOMAINS = ("continuous", "discrete")


# =============================================================================== models
def _mat(value: Any, name: str, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise DimensionError(f"{name} must be a real matrix") from None
    if arr.ndim == 1 and rows is not None and cols is not None:
        arr = arr.reshape(rows, cols) if arr.size == rows * cols else arr
    arr = np.atleast_2d(arr)
    if arr.ndim != 2 or not np.all(np.isfinite(arr)):
        raise DimensionError(f"{name} must be a finite 2-D matrix")
    if (rows is not None and arr.shape[0] != rows) or (cols is not None and arr.shape[1] != cols):
        raise DimensionError(f"{name} has shape {arr.shape}, expected ({rows if rows is not None else '*'}, "
                             f"{cols if cols is not None else '*'})")
    return arr


@dataclass(frozen=True, eq=False)
class GeneralizedPlant:
    """``x' = A x + Bw w + B u``, ``z = Cz x + Dzu u`` (state-feedback synthesis data).

    Attributes
    ----------
    A : ndarray, shape (n, n)
        1/s (continuous) or dimensionless (discrete).
    B : ndarray, shape (n, m)
        Control input (state unit per input unit, per s in continuous time).
    Bw : ndarray, shape (n, nw)
        Disturbance input (state unit per disturbance unit, per s in continuous time).
    Cz : ndarray, shape (nz, n)
        Performance output (z unit per state unit).
    Dzu : ndarray, shape (nz, m)
        Performance output (z unit per input unit).
    domain : {"continuous", "discrete"}
    dt : float or None
        Sampling period (s) of a discrete-time model.
    """

    A: np.ndarray
    B: np.ndarray
    Bw: np.ndarray
    Cz: np.ndarray
    Dzu: np.ndarray
    domain: str = "continuous"
    dt: float | None = None

    def __post_init__(self) -> None:
        A = _mat(self.A, "A")
        n = A.shape[0]
        if A.shape != (n, n):
            raise DimensionError(f"A must be square, got shape {A.shape}")
        B = _mat(self.B, "B", n)
        Bw = _mat(self.Bw, "Bw", n)
        Cz = _mat(self.Cz, "Cz", None, n)
        Dzu = _mat(self.Dzu, "Dzu", Cz.shape[0], B.shape[1])
        if self.domain not in DOMAINS:
            raise SpecError(f"domain must be one of {DOMAINS}, got {self.domain!r}", key="domain")
        for name, value in (("A", A), ("B", B), ("Bw", Bw), ("Cz", Cz), ("Dzu", Dzu)):
            value.flags.writeable = False
            object.__setattr__(self, name, value)

    @property
    def n(self) -> int:
        """Number of states."""
        return int(self.A.shape[0])

    @property
    def m(self) -> int:
        """Number of control inputs."""
        return int(self.B.shape[1])

    def closed_loop(self, K: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(A - B K, Bw, Cz - Dzu K)`` of the gain ``K`` (m, n).

        Parameters
        ----------
        K : array_like, shape (m, n)
            State-feedback gain (input units per state unit).
        """
        K = _mat(K, "K", self.m, self.n)
        return self.A - self.B @ K, self.Bw, self.Cz - self.Dzu @ K


def generalized_plant(sys: Any, ncon: int) -> GeneralizedPlant:
    """A `GeneralizedPlant` from a `control.StateSpace` partitioned as for ``control.hinfsyn``.

    Inputs ``[w; u]`` (the last ``ncon`` are the controls), outputs ``z`` (all
    of them: state feedback measures the state).

    Parameters
    ----------
    sys : control.StateSpace
        ``D`` must be ``[0, Dzu]`` (no direct term from ``w`` to ``z``).
    ncon : int
        Number of control inputs (>= 1).

    Returns
    -------
    GeneralizedPlant
    """
    A, B, C, D, dt = statespace_matrices(sys)
    if not 1 <= int(ncon) < B.shape[1]:
        raise DimensionError(f"ncon = {ncon} must be in [1, {B.shape[1] - 1}] (inputs are [w; u])")
    k = B.shape[1] - int(ncon)
    if np.any(D[:, :k] != 0):
        raise DimensionError("the direct term from w to z must be zero (Dzw = 0)")
    return GeneralizedPlant(A, B[:, k:], B[:, :k], C, D[:, k:],
                            "continuous" if dt is None else "discrete", dt)


def observer_plant(A: Any, C: Any, Bw: Any, Dv: Any, Cz: Any, domain: str = "continuous",
                   dt: float | None = None) -> GeneralizedPlant:
    """The state-feedback dual of the observer error ``e' = (A - L C) e + Bw w - L Dv v``, ``z = Cz e``.

    ``A' - C' L'`` with disturbance ``Cz'`` and performance ``[Bw'; -Dv' L']``:
    a `GeneralizedPlant` ``(A', C', Cz', [Bw'; 0], [0; Dv'])`` whose gain is
    ``L'``; its H2 and H-infinity norms equal those of the error system
    (transposition), its eigenvalues those of ``A - L C``.

    Parameters
    ----------
    A : array_like, shape (n, n)
    C : array_like, shape (q, n)
        Measured outputs (output unit per state unit).
    Bw : array_like, shape (n, nw)
        Process disturbance input.
    Dv : array_like, shape (q, q)
        Measurement noise input (output units per noise unit), invertible.
    Cz : array_like, shape (nz, n)
        Weight of the estimation error.
    domain : {"continuous", "discrete"}
    dt : float, optional
        Sampling period (s) of a discrete-time model.

    Returns
    -------
    GeneralizedPlant
    """
    A = _mat(A, "A")
    n = A.shape[0]
    C = _mat(C, "C", None, n)
    q = C.shape[0]
    Bw = _mat(Bw, "Bw", n)
    Dv = _mat(Dv, "Dv", q, q)
    Cz = _mat(Cz, "Cz", None, n)
    nw = Bw.shape[1]
    return GeneralizedPlant(A.T, C.T, Cz.T, np.vstack([Bw.T, np.zeros((q, n))]),
                            np.vstack([np.zeros((nw, q)), Dv.T]), domain, dt)


# ========================================================================= LMI blocks
def _library(values: Sequence[Any]) -> Any:
    """The module whose ``bmat``/``kron`` handle ``values``: design.conic, cvxpy or None (numpy)."""
    lib: Any = None
    for v in values:
        if isinstance(v, conic.Expression):
            return conic
        if type(v).__module__.startswith("cvxpy."):
            # only the SCS route builds cvxpy expressions (cvxpy is loaded then; here, not at
            # the top, so that the Clarabel route never pays its import)
            import cvxpy
            lib = cvxpy
    return lib


def _bmat(rows: list[list[Any]]) -> Any:
    lib = _library([b for row in rows for b in row])
    if lib is not None:
        return lib.bmat(rows)
    return np.block([[np.asarray(b, dtype=float) for b in row] for row in rows])


def _eye_times(g: Any, k: int) -> Any:
    return g * np.eye(k)


def h2_lmis(plant: GeneralizedPlant, X: Any, Y: Any, W: Any) -> list[Any]:
    """H2 LMIs of state feedback (each returned matrix must be negative definite).

    With ``K = Y X^-1`` stabilising, ``||T_zw||_2^2 < trace W`` (continuous:
    ``X`` bounds the controllability Gramian; discrete: likewise for the
    Stein equation).

    Parameters
    ----------
    plant : GeneralizedPlant
    X : cvxpy expression or ndarray, shape (n, n)
        Symmetric.
    Y : cvxpy expression or ndarray, shape (m, n)
    W : cvxpy expression or ndarray, shape (nz, nz)
        Symmetric.

    Returns
    -------
    list
        Two symmetric matrices (cvxpy expressions or ndarrays).
    """
    A, B, Bw, Cz, Dzu = plant.A, plant.B, plant.Bw, plant.Cz, plant.Dzu
    AX = A @ X - B @ Y
    CX = Cz @ X - Dzu @ Y
    gram = Bw @ Bw.T
    if plant.domain == "continuous":
        first = AX + AX.T + gram
    else:
        first = -_bmat([[X - gram, AX], [AX.T, X]])
    second = -_bmat([[W, CX], [CX.T, X]])
    return [symmetrized(first), symmetrized(second)]


def hinf_lmis(plant: GeneralizedPlant, X: Any, Y: Any, gamma: Any) -> list[Any]:
    """Bounded-real-lemma LMI of state feedback (the returned matrix must be negative definite).

    With ``X > 0``: ``A - B Y X^-1`` stable and ``||T_zw||_inf < gamma``.

    Parameters
    ----------
    plant : GeneralizedPlant
    X, Y : cvxpy expressions or ndarrays
    gamma : cvxpy scalar expression or float
        Bound on the L2 gain from ``w`` to ``z`` (z unit per w unit).

    Returns
    -------
    list
        One symmetric matrix.
    """
    A, B, Bw, Cz, Dzu = plant.A, plant.B, plant.Bw, plant.Cz, plant.Dzu
    n, nw, nz = plant.n, Bw.shape[1], Cz.shape[0]
    AX = A @ X - B @ Y
    CX = Cz @ X - Dzu @ Y
    Zwz, Zzw = np.zeros((nw, nz)), np.zeros((nz, nw))
    if plant.domain == "continuous":
        M = _bmat([[AX + AX.T, Bw, CX.T],
                   [Bw.T, -_eye_times(gamma, nw), Zwz],
                   [CX, Zzw, -_eye_times(gamma, nz)]])
    else:
        Znw, Znz = np.zeros((n, nw)), np.zeros((n, nz))
        M = _bmat([[-X, AX, Bw, Znz],
                   [AX.T, -X, Znw, CX.T],
                   [Bw.T, Znw.T, -_eye_times(gamma, nw), Zwz],
                   [Znz.T, CX, Zzw, -_eye_times(gamma, nz)]])
    return [symmetrized(M)]


def hinf_lmis_reduced(plant: GeneralizedPlant, X: Any, Y: Any, mu: Any) -> list[Any]:
    """Bounded real lemma with the disturbance block eliminated (must be negative definite).

    Scaling ``X`` by ``gamma`` and taking the Schur complement of the ``w``
    block gives an LMI in ``(X, Y, mu = gamma^2)`` smaller by ``nw`` rows:
    continuous ``[[He(AX - BY) + Bw Bw', (CzX - DzuY)'], [., -mu I]] < 0``;
    discrete ``[[-X + Bw Bw', AX - BY, 0], [., -X, (CzX - DzuY)'], [0, ., -mu I]] < 0``.
    ``||T_zw||_inf < sqrt(mu)``. Not homogeneous like `hinf_lmis` in the same
    ``X``: combine it with region LMIs only (not with `h2_lmis`).

    Parameters
    ----------
    plant : GeneralizedPlant
    X, Y : cvxpy expressions or ndarrays
    mu : cvxpy scalar expression or float
        ``gamma^2``.

    Returns
    -------
    list
        One symmetric matrix.
    """
    A, B, Bw, Cz, Dzu = plant.A, plant.B, plant.Bw, plant.Cz, plant.Dzu
    n, nz = plant.n, Cz.shape[0]
    AX = A @ X - B @ Y
    CX = Cz @ X - Dzu @ Y
    gram = Bw @ Bw.T
    if plant.domain == "continuous":
        M = _bmat([[AX + AX.T + gram, CX.T], [CX, -_eye_times(mu, nz)]])
    else:
        Znz = np.zeros((n, nz))
        M = _bmat([[-X + gram, AX, Znz], [AX.T, -X, CX.T], [Znz.T, CX, -_eye_times(mu, nz)]])
    return [symmetrized(M)]


def region_lmi(region: LMIRegion, plant: GeneralizedPlant, X: Any, Y: Any) -> Any:
    """Chilali-Gahinet region LMI ``L (x) X + M (x) (AX - BY) + M' (x) (AX - BY)'`` (must be < 0).

    Parameters
    ----------
    region : LMIRegion
        In the units of the eigenvalues of ``plant.A``.
    plant : GeneralizedPlant
    X, Y : affine expressions (design.conic or cvxpy) or ndarrays

    Returns
    -------
    expression or ndarray
        Symmetric, size ``region.order * n``.
    """
    AX = plant.A @ X - plant.B @ Y
    lib = _library([X, Y])
    kron = np.kron if lib is None else lib.kron
    M = kron(region.L, X) + kron(region.M, AX) + kron(region.M.T, AX.T)
    return symmetrized(M)


