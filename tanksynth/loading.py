"""Load designed artefacts back into Python: gains, diagnostics, verdict and a linear system.

``tanksynth.load("out")`` reads every artefact of a result directory,
``tanksynth.load("out/ekf.json")`` one artefact. Each `Design` holds the gains
as numpy arrays, the diagnostics, the verdict recorded by ``tanksynth verify``
and `Design.to_statespace`: the closed loop of a controller, the estimation
error system of an observer or estimator, or the model of ``linearize``, as a
python-control ``StateSpace`` (discrete with ``dt = ts`` when the design is).

Every file is read with its integrity checks (`tanksynth.artefacts.io.read_artefact`):
an artefact edited after design is refused.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Mapping

import numpy as np

from tanksynth.artefacts.io import read_artefact, read_plant_record
from tanksynth.errors import ArtefactError

__all__ = ["Design", "Results", "load"]

#: Files of a result directory that are not design artefacts.
_NOT_ARTEFACTS = {"plant.json", "checks.json"}


@dataclass(frozen=True, eq=False)
class Design:
    """One designed artefact, as written by ``tanksynth design`` (and ``verify``).

    Attributes
    ----------
    name : str
        The design's name.
    method : str
        Its method (a row of `tanksynth.methods.TABLE`).
    path : Path
        The artefact JSON.
    gains : mapping of str to ndarray
        Every gain, in the plant's units (read-only arrays).
    diagnostics : mapping
        The design's evidence (solver status, eigenvalues, assumptions...).
    verification : mapping or None
        What ``tanksynth verify`` recorded (``passed``, ``checks``), None when not verified.
    plant_record : mapping or None
        ``plant.json`` of the directory (plant summary, operating point, ``ts``), if present.
    """

    name: str
    method: str
    path: Path
    gains: Mapping[str, np.ndarray]
    diagnostics: Mapping[str, Any]
    verification: Mapping[str, Any] | None
    plant_record: Mapping[str, Any] | None = field(default=None, repr=False)

    @property
    def verdict(self) -> bool | None:
        """True/False as recorded by ``tanksynth verify``; None when not verified."""
        return None if self.verification is None else bool(self.verification.get("passed"))

    @property
    def checks(self) -> list[dict[str, Any]]:
        """The verification checks (``check``, ``passed``, ``detail``, ``data``); empty if not verified."""
        return list((self.verification or {}).get("checks", []))

    @property
    def ts(self) -> float | None:
        """Sampling period (s) of the spec, None in continuous time."""
        record = self.plant_record or {}
        ts = record.get("ts", self.diagnostics.get("ts", self.diagnostics.get("sampling_period")))
        return None if ts is None else float(ts)

    def to_statespace(self) -> Any:
        """The design's linear system as a python-control ``StateSpace``.

        ========================  ===================================================
        controller (``K``)        closed loop ``x+ = (A - B K) x + B r``, ``y = C x``;
                                  with integral action the augmented loop
                                  ``(Aa - Ba K)`` driven by the references (``Br``),
                                  output the tracked outputs
        observer (``L``)          error ``e+ = (A - L C) e - L v`` (``v`` measurement
                                  noise), output ``e``
        ``ts_observer``           the linear part ``(A0 - L C)`` of the error dynamics
                                  (the nonlinear remainder, bounded by psi, is left out)
        ``luenberger``            error ``(Ad - L C)``, ``(I - L C) Ad`` or ``(F - L C)``
                                  by its form, input ``v``, output ``e``
        Kalman filters            steady state of the filter on the linearisation at the
                                  operating point: ``e+ = (I - K C) Ad e``, input
                                  ``v``; ``K`` by the discrete Riccati equation of
                                  the artefact's ``Q`` (``Q0``; ``G Q G'``) and ``R``
        ``linearize``             the ZOH model ``(Ad, Bd, C, 0)``
        ========================  ===================================================

        Discrete systems have ``dt = ts`` (s); continuous ones ``dt = 0``.

        Returns
        -------
        control.StateSpace

        Raises
        ------
        ArtefactError
            The method has no linear closed loop or error system (nonlinear
            laws, time-varying or decentralised gains, detectors, NARX).
        """
        import control

        A, B, C, D, dt = _linear_system(self)
        n = A.shape[0]
        names = _state_names(self, n)
        return control.ss(A, B, C, D, dt, states=names, name=self.name)


def _state_names(design: Design, n: int) -> list[str]:
    states = [s["name"] for s in ((design.plant_record or {}).get("plant") or {}).get("states", [])]
    integral = design.diagnostics.get("integral")
    if isinstance(integral, Mapping):
        states = states + [f"z_{t}" for t in integral.get("tracked", [])]
    return states if len(states) == n else [f"x{i}" for i in range(n)]


def _dt(design: Design, discrete: bool) -> float:
    if not discrete:
        return 0
    if design.ts is None:
        raise ArtefactError(f"{design.path}: a discrete design without a sampling period")
    return design.ts


def _linear_system(design: Design) -> tuple[np.ndarray, ...]:
    g, diag, method = design.gains, design.diagnostics, design.method
    discrete = diag.get("time_domain", "discrete") == "discrete"
    if method in ("pole_placement", "lmi_placement") and "K" in g:
        integral = diag.get("integral")
        if isinstance(integral, Mapping) and "augmented_A" in integral:
            Aa, C1 = np.array(integral["augmented_A"]), np.array(integral["C1"])
            if "augmented_B" in integral:
                Ba = np.array(integral["augmented_B"])
            else:  # the integrators take no input: Ba = [B; 0]
                B = _model(design)[1]
                Ba = np.vstack([B, np.zeros((Aa.shape[0] - B.shape[0], B.shape[1]))])
            Ca = np.hstack([C1, np.zeros((C1.shape[0], Aa.shape[0] - C1.shape[1]))])
            return Aa - Ba @ g["K"], np.asarray(g["Br"]), Ca, np.zeros((Ca.shape[0], g["Br"].shape[1])), \
                _dt(design, discrete)
        A, B, C = _model(design)
        return A - B @ g["K"], B, C, np.zeros((C.shape[0], B.shape[1])), _dt(design, discrete)
    if method in ("pole_placement", "lmi_placement", "canonical_observer") and "L" in g:
        A, _, C = _model(design)
        discrete = discrete and method != "canonical_observer"
        return _error_system(A - g["L"] @ C, g["L"], _dt(design, discrete))
    if method == "ts_observer":
        return _error_system(g["A0"] - g["L"] @ g["C"], g["L"], 0)
    if method == "integral_tracking":
        return _integral_tracking(design)
    if method == "linearize":
        return g["Ad"], g["Bd"], g["C"], np.zeros((g["C"].shape[0], g["Bd"].shape[1])), _dt(design, True)
    if method == "luenberger":
        lin = _linearisation(design)
        L, form = g["L"], diag.get("form")
        if form == "continuous":
            return _error_system(lin.F - L @ lin.C, L, 0)
        if form == "predictor":
            return _error_system(lin.Ad - L @ lin.C, L, _dt(design, True))
        return _error_system((np.eye(L.shape[0]) - L @ lin.C) @ lin.Ad, lin.Ad @ L, _dt(design, True))
    if method in ("kalman", "ekf", "ukf", "adaptive_kalman", "adaptive_scaling_kalman"):
        from scipy.linalg import solve_discrete_are

        if "Ad" in g and "C" in g:
            Ad, C = g["Ad"], g["C"]
        else:
            lin = _linearisation(design)
            Ad, C = lin.Ad, lin.C
        Q = g["Q0"] if "Q0" in g else g["Q"]
        if method == "adaptive_scaling_kalman" and "G" in g:
            Q = g["G"] @ Q @ g["G"].T
        P = solve_discrete_are(Ad.T, C.T, Q, g["R"])     # predicted covariance
        K = P @ C.T @ np.linalg.inv(C @ P @ C.T + g["R"])
        n = Ad.shape[0]
        return _error_system((np.eye(n) - K @ C) @ Ad, Ad @ K, _dt(design, True))
    raise ArtefactError(f"{design.path}: method {method!r} has no linear closed loop or error "
                        "system to give as a StateSpace (nonlinear law, time-varying or "
                        "decentralised gains, a detector or a neural estimator)")


def _error_system(Ae: np.ndarray, L: np.ndarray, dt: float) -> tuple[np.ndarray, ...]:
    n = Ae.shape[0]
    return Ae, -np.asarray(L), np.eye(n), np.zeros((n, L.shape[1])), dt


def _model(design: Design) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    g = design.gains
    if all(k in g for k in ("A", "B", "C")):
        return g["A"], g["B"], g["C"]
    lin = _linearisation(design)
    discrete = design.diagnostics.get("time_domain", "discrete") == "discrete"
    return (lin.Ad, lin.Bd, lin.C) if discrete else (lin.F, lin.B, lin.C)


def _integral_tracking(design: Design) -> tuple[np.ndarray, ...]:
    g = design.gains
    lin = _linearisation(design)
    C1, n, p = g["C1"], lin.Ad.shape[0], g["C1"].shape[0]
    ts = _dt(design, True)
    # x+ = Ad x + Bd u, z+ = z + ts (r - C1 x), u = -K1 x - K2 z (deviations, no saturation)
    Aa = np.block([[lin.Ad, np.zeros((n, p))], [-ts * C1, np.eye(p)]])
    Ba = np.vstack([lin.Bd, np.zeros((p, lin.Bd.shape[1]))])
    Br = np.vstack([np.zeros((n, p)), ts * np.eye(p)])
    Ca = np.hstack([C1, np.zeros((p, p))])
    return Aa - Ba @ g["K"], Br, Ca, np.zeros((p, p)), ts


def _linearisation(design: Design) -> Any:
    """The ZOH linearisation at the spec's operating point (from ``spec.toml`` beside the artefact)."""
    from tanksynth.analysis.linearize import equilibrium_input, linearize
    from tanksynth.spec import parse_spec_text

    path = design.path.parent / "spec.toml"
    if not path.is_file():
        raise ArtefactError(f"{design.path}: no spec.toml beside it, needed to linearise the plant")
    spec = parse_spec_text(path.read_bytes(), source=str(path))
    eq = equilibrium_input(spec.plant, spec.x0, spec.given_u0)
    return linearize(spec.plant, spec.x0, eq.u0, ts=spec.ts)


class Results(Mapping[str, Design]):
    """The artefacts of a result directory, by design name (a read-only mapping).

    Parameters
    ----------
    directory : Path
        The result directory.
    designs : mapping of str to Design
        Its artefacts by design name.
    checks : list of dict
        The rank verdicts of ``checks.json``.
    plant_record : mapping or None
        ``plant.json``.

    Attributes
    ----------
    directory : Path
        The directory.
    checks : list of dict
        The rank verdicts of ``checks.json`` (empty when absent).
    plant_record : mapping or None
        ``plant.json`` (None when absent).
    """

    def __init__(self, directory: Path, designs: Mapping[str, Design], checks: list[dict[str, Any]],
                 plant_record: Mapping[str, Any] | None):
        self.directory = directory
        self._designs = dict(designs)
        self.checks = checks
        self.plant_record = plant_record

    def __getitem__(self, name: str) -> Design:
        if name not in self._designs:
            raise KeyError(f"no design {name!r} in {self.directory}; designs: {', '.join(self._designs)}")
        return self._designs[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._designs)

    def __len__(self) -> int:
        return len(self._designs)

    @property
    def verdict(self) -> bool | None:
        """True if every design was verified and passed, False if one failed, None if one is unverified."""
        verdicts = [d.verdict for d in self._designs.values()]
        if any(v is False for v in verdicts):
            return False
        return None if any(v is None for v in verdicts) or not verdicts else True

    def __repr__(self) -> str:
        return f"Results({str(self.directory)!r}, designs={list(self._designs)})"


def _design(path: Path, record: Mapping[str, Any] | None) -> Design:
    doc = read_artefact(path)
    gains = {}
    for k, v in doc["gains"].items():
        arr = np.array(v, dtype=float)
        arr.flags.writeable = False
        gains[k] = arr
    return Design(doc["name"], doc["method"], path, gains, doc.get("diagnostics") or {},
                  doc.get("verification"), record)


def load(path: str | Path) -> Design | Results:
    """Load an artefact (``<name>.json``) or every artefact of a result directory.

    Parameters
    ----------
    path : str or Path
        A result directory (``tanksynth design/run -o DIR``) or one artefact JSON in it.

    Returns
    -------
    Design or Results
        One `Design` for a file; for a directory a `Results` mapping of design
        name to `Design`, with the rank verdicts (``checks``) and the plant record.

    Raises
    ------
    ArtefactError
        Missing path, not an artefact, or a file edited after design.
    """
    path = Path(path)
    if path.is_dir():
        record = read_plant_record(path) if (path / "plant.json").is_file() else None
        designs = {}
        for file in sorted(path.glob("*.json")):
            if file.name in _NOT_ARTEFACTS or file.name.endswith(".traces.json"):
                continue
            d = _design(file, record)
            designs[d.name] = d
        if not designs:
            raise ArtefactError(f"{path}: no design artefact (<name>.json) in it")
        checks_path = path / "checks.json"
        checks = json.loads(checks_path.read_text(encoding="utf-8")) if checks_path.is_file() else []
        return Results(path, designs, checks, record)
    if not path.is_file():
        raise ArtefactError(f"{path}: no such artefact or result directory")
    parent = path.parent
    record = read_plant_record(parent) if (parent / "plant.json").is_file() else None
    return _design(path, record)
