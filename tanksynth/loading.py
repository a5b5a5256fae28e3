"""Load designed artefacts back into Python: gains, diagnostics, verdict and a linear system.

``tanksynth.load("out")`` reads every artefact of a result directory,
``tanksynth.load("out/ekf.json")`` one artefact. Each `Design` holds the gains
as numpy arrays, the diagnostics, the verdict recorded by ``tanksynth verify``
and `Design.to_statespace`: the closed loop of a controller, the estimation
error system of an observer or estimator, or the model of ``linearize``, as a
python-control ``StateSpace`` (discrete with ``dt = ts`` when the design is).

Every file is read with the integrity checks of ``tanksynth verify`` (one code
path, `tanksynth.verify.runner.read_directory`): an artefact, its ``.npz``,
``plant.json`` or ``spec.toml`` edited, swapped or deleted after design, an
``.npz`` left without its artefact, or a malformed ``checks.json`` is refused
with an `ArtefactError` naming the file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Mapping

import numpy as np

from tanksynth.artefacts.io import read_plant_record
from tanksynth.artefacts.model import Artefact
from tanksynth.errors import ArtefactError
from tanksynth.verify.runner import Verdict, read_checks, read_directory

__all__ = ["Design", "Results", "load", "as_complex"]

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

    @classmethod
    def from_artefact(cls, artefact: Artefact, path: Path,
                      plant_record: Mapping[str, Any] | None = None) -> "Design":
        """The `Design` of an artefact read from ``path``.

        Parameters
        ----------
        artefact : Artefact
            As read (`tanksynth.artefacts.model.Artefact.from_document`).
        path : Path
            Its JSON file.
        plant_record : mapping, optional
            ``plant.json`` of its directory.
        """
        verification = None if artefact.verification is None else artefact.verification.to_document()
        return cls(artefact.name, artefact.method, path, artefact.gains, artefact.diagnostics,
                   verification, plant_record)

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

    def verify(self, scheduler: str | None = None) -> Verdict:
        """Verify this design as ``tanksynth verify`` does: simulate it on the nonlinear plant.

        Runs the verdict of every artefact of its directory
        (`tanksynth.methods.verify_directory`, which records each in its JSON, so
        ``tanksynth.load`` shows them afterwards) and returns this design's.

        Parameters
        ----------
        scheduler : str, optional
            Dask scheduler address (``tcp://host:port``); default this machine.

        Returns
        -------
        tanksynth.verify.runner.Verdict
            ``passed`` (bool) and the ``checks`` (each with ``check``, ``passed``, ``detail``).

        Raises
        ------
        ArtefactError
            A file of the directory was edited, swapped or deleted after design.
        """
        from tanksynth.methods import verify_directory

        verdicts = verify_directory(self.path.parent, scheduler=scheduler)
        return next(v for v in verdicts if v.name == self.name)

    def to_statespace(self, system: str | None = None, *, vertex: int | None = None) -> Any:
        """The design's linear system as a python-control ``StateSpace``.

        One entry point for every method with a linear closed loop or error
        system; it delegates to `tanksynth.verify.statespace.artefact_statespace`
        (see there for every system and its matrices):

        ==========================  ==================================================
        H2 / H-infinity /           ``"performance"`` (default): the closed loop from
        ``multiobjective``          the disturbances ``w`` to the performance outputs
                                    ``z``; the systems below on request
        controllers (``K``)         ``"closed_loop"`` (default): ``(A - B K, B, C, 0)``;
                                    with integral action (``pole_placement``,
                                    ``lmi_placement``, ``robust_state_feedback``,
                                    ``integral_tracking``) the augmented loop from
                                    the references to the tracked outputs, the
                                    integrator states named ``z_<output>``;
                                    ``"loop"``: the
                                    loop transfer ``(A, B, K, 0)`` for ``margin``
        observers (``L``)           ``"error"`` (default): ``e+ = (A - L C) e - L v``;
                                    ``"performance"``: ``(A - L C, [Bw, -L Dv], Cz)``
                                    (the default of H2 / H-infinity observers);
                                    ``"observer"``: ``(u, y) -> x_hat``
        Kalman filters              steady state on the linearisation at the
                                    operating point: ``e+ = (I - K C) Ad e``
        robust designs              the nominal model; ``vertex=i`` the i-th stored
                                    vertex model
        ``ts_state_feedback``,      NOT LTI: the linearisation of the nonlinear
        ``ts_output_feedback``      closed loop at ``x0``, ``sum_i mu_i(x0) A_i - B
                                    sum_j mu_j(x0) K_j`` (output feedback: states
                                    ``(x, e)``), with a `TanksynthWarning`
        ``linearize``               the ZOH model ``(Ad, Bd, C, 0)``
        ==========================  ==================================================

        Discrete systems have ``dt = ts`` (s); continuous ones ``dt = 0``. States,
        inputs and outputs carry the plant's names.

        Parameters
        ----------
        system : {"closed_loop", "reference", "performance", "loop", "error", "observer", "model"}, optional
            Which system (default: ``w -> z`` of an H2 / H-infinity /
            multi-objective design, the closed loop of another controller,
            the error system of another observer or an estimator).
        vertex : int, optional
            Robust designs: the stored vertex model ``vertex`` (0-based) instead
            of the nominal one.

        Returns
        -------
        control.StateSpace

        Raises
        ------
        ArtefactError
            The method has no linear closed loop or error system (nonlinear
            laws, time-varying or decentralised gains, detectors, NARX), or
            the system asked for does not apply to it.

        Warns
        -----
        TanksynthWarning
            Takagi-Sugeno PDC designs (a local linearisation).
        """
        from tanksynth.verify.statespace import artefact_statespace

        doc = {"name": self.name, "method": self.method, "gains": dict(self.gains),
               "diagnostics": self.diagnostics}
        return artefact_statespace(doc, system, plant_record=self.plant_record, source=self.path,
                                   vertex=vertex)


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


def _design(path: Path, doc: Mapping[str, Any], record: Mapping[str, Any] | None) -> Design:
    """The `Design` of a document `read_directory` checked (hashes included)."""
    return Design.from_artefact(Artefact.from_document(doc, path), path, record)


def _plant_record(directory: Path) -> Mapping[str, Any] | None:
    """``plant.json`` (its bytes already checked against the artefacts), None when absent."""
    return read_plant_record(directory) if (directory / "plant.json").is_file() else None


def load(path: str | Path) -> Design | Results:
    """Load an artefact (``<name>.json``) or every artefact of a result directory.

    The files are checked exactly as ``tanksynth verify`` checks them
    (`tanksynth.verify.runner.read_directory`): every artefact's content
    hash, its ``<name>.npz``, ``plant.json`` and ``spec.toml`` against the
    hashes recorded at design; for a directory also no orphan ``.npz`` and a
    well-formed ``checks.json``. One file is checked with its own ``.npz``,
    the plant record and the spec of its directory.

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
        Missing path, not an artefact, or a file edited, swapped or deleted
        after design (the message names the file).
    """
    path = Path(path)
    if path.is_dir():
        _, docs = read_directory(path)
        record = _plant_record(path)
        designs = {doc["name"]: _design(file, doc, record) for file, doc in docs}  # name == file stem
        return Results(path, designs, read_checks(path) or [], record)
    if not path.is_file():
        raise ArtefactError(f"{path}: no such artefact or result directory")
    _, docs = read_directory(path.parent, path)
    return _design(path, docs[0][1], _plant_record(path.parent))


def as_complex(value: Any) -> Any:
    """Eigenvalues or poles as the artefact's JSON writes them, as a numpy complex array.

    JSON has no complex numbers: ``diagnostics`` writes each eigenvalue as an ``[re, im]`` pair,
    a list of them sorted as `numpy.sort_complex` sorts (real part, then imaginary part), a
    real eigenvalue also as a plain number in older keys; a polytopic design writes one such
    list per vertex model. ``[[-0.2, -0.1], [-0.2, 0.1], -0.5]`` is ``-0.2 - 0.1j, -0.2 + 0.1j,
    -0.5``.

    Parameters
    ----------
    value : list
        A list of ``[re, im]`` pairs or numbers (1/s in continuous time, dimensionless in the
        z-plane), or a list of such lists (one per model).

    Returns
    -------
    ndarray of complex
        Shape (n,), or (models, n) for a list of lists of equal length.

    Raises
    ------
    ValueError
        ``value`` is not such a list.
    """
    import numpy as np

    def one(v: Any) -> complex:
        if isinstance(v, (list, tuple)) and len(v) == 2 and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
            return complex(float(v[0]), float(v[1]))
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            return complex(float(v), 0.0)
        raise ValueError(f"not an eigenvalue ([re, im] pair or number): {v!r}")

    if not isinstance(value, (list, tuple)):
        raise ValueError(f"not a list of eigenvalues: {value!r}")
    if value and all(isinstance(v, (list, tuple)) and v and isinstance(v[0], (list, tuple)) for v in value):
        rows = [[one(z) for z in v] for v in value]
        if len({len(r) for r in rows}) != 1:
            raise ValueError("the models' eigenvalue lists differ in length")
        return np.array(rows, dtype=complex)
    return np.array([one(v) for v in value], dtype=complex)
