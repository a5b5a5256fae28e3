"""The eigenvalue lists of an artefact's diagnostics, found by their key names (pole maps, tables).

Every list under a key naming eigenvalues or poles (`is_pole_key`) is one
`EigenvalueSet`, as complex numbers (``[re, im]`` pairs or reals; a list of
such lists, one per model of a polytope, is one set of every model's
eigenvalues), with its plane from the key or the nearest ``time_domain``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Iterator, Mapping

__all__ = ["EigenvalueSet", "eigenvalue_sets", "eigen_label", "is_pole_key"]


#: Keys whose eigenvalues are not poles of a dynamic system (LMI blocks, matrices P, Q, X ...).
_NOT_POLES = ("lmi", "residual", "covariance", "_P", "_Q", "_X", "hessian")



@dataclass(frozen=True)
class EigenvalueSet:
    """Eigenvalues found in an artefact.

    Attributes
    ----------
    path : str
        Dotted key path in the diagnostics (``lmi.closed_loop_eigenvalues``).
    values : tuple of complex
    discrete : bool
        z-plane (True) or s-plane (False).
    observer : bool
        The artefact is an observer (gain ``L``, no ``K``): its "closed loop" is the
        estimation-error dynamics.
    """

    path: str
    values: tuple[complex, ...]
    discrete: bool
    observer: bool = False

    @property
    def label(self) -> str:
        """The set in words (`eigen_label`)."""
        return eigen_label(self.path, self.observer)



def _as_complex(values: Any) -> tuple[complex, ...] | None:
    if not isinstance(values, list) or not values:
        return None
    if all(isinstance(v, list) and v and isinstance(v[0], (list, tuple)) for v in values):
        # one list per model (the synthesis designs' polytope): every model's eigenvalues
        sets = [_as_complex(v) for v in values]
        every = [s for s in sets if s is not None]
        return tuple(z for s in every for z in s) if len(every) == len(sets) else None
    out = []
    for v in values:
        if isinstance(v, (list, tuple)) and len(v) == 2 and all(isinstance(x, (int, float)) for x in v):
            out.append(complex(float(v[0]), float(v[1])))
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            out.append(complex(float(v), 0.0))
        else:
            return None
    return tuple(out)



def is_pole_key(key: str) -> bool:
    """True for diagnostics keys that name eigenvalues or poles of a dynamic system.

    ``*eigenvalue*``, ``poles``, ``*_poles``, ``achieved``, ``requested``;
    not LMI-block or matrix eigenvalues (``lmi_eigenvalues`` ...).

    Parameters
    ----------
    key : str
        A diagnostics key.
    """
    k = str(key)
    if any(bad in k for bad in _NOT_POLES):
        return False
    return "eigenvalue" in k or k in ("poles", "achieved", "requested") or k.endswith("_poles")



def _walk(node: Any, path: str, discrete: bool | None) -> Iterator[EigenvalueSet]:
    if not isinstance(node, Mapping):
        return
    dom = node.get("time_domain", node.get("domain"))
    if isinstance(dom, str) and dom in ("discrete", "continuous"):
        discrete = dom == "discrete"
    for key, value in node.items():
        sub = f"{path}.{key}" if path else str(key)
        k = str(key)
        if is_pole_key(k):
            vals = _as_complex(value)
            if vals:
                if "Ad" in k or "discrete" in k:
                    disc = True
                elif k.endswith("_F") or "continuous" in k:
                    disc = False
                else:
                    disc = bool(discrete)
                yield EigenvalueSet(sub, vals, disc)
        elif isinstance(value, Mapping):
            yield from _walk(value, sub, discrete)



def eigen_label(path: str, observer: bool = False) -> str:
    """An eigenvalue set's key path in words, for legends and tables.

    ``placement.requested`` -> ``requested``; ``lmi.closed_loop_eigenvalues`` ->
    ``achieved: closed loop`` (``achieved: error dynamics`` for an observer); a set
    computed with a reference (printed) gain -> ``with the gain printed in the paper``;
    ``eigenvalues_Ad`` -> ``eigenvalues of Ad``.

    Parameters
    ----------
    path : str
        Dotted key path of the eigenvalue set in the diagnostics.
    observer : bool
        The artefact is an observer: a "closed loop" is its error dynamics.
    """
    parts = [p for p in str(path).split(".") if p]
    last = parts[-1] if parts else str(path)
    if "reference_closed_loop" in parts[:-1]:   # the printed matrix itself, not a printed gain's loop
        return "of the closed-loop matrix printed in the paper"
    if any("reference" in p for p in parts):
        return "with the gain printed in the paper"
    if last in ("requested", "achieved"):
        return last
    if last in ("achieved_poles", "achieved_eigenvalues"):
        return "achieved"
    if last.startswith("eigenvalues_"):
        return "eigenvalues of " + last[len("eigenvalues_"):]
    if last.endswith("_eigenvalues") and "model" in parts[:-1]:   # the plant's own matrix
        return "plant (open loop): eigenvalues of " + last[:-len("_eigenvalues")]
    core = last.replace("eigenvalues", "").replace("poles", "").replace("_", " ").strip()
    if observer and core == "closed loop":
        core = "error dynamics"
    return ("achieved: " + core) if core else "achieved"



def eigenvalue_sets(artefact: Mapping[str, Any]) -> tuple[EigenvalueSet, ...]:
    """Every eigenvalue list in an artefact's diagnostics (see module docstring).

    Parameters
    ----------
    artefact : mapping
        A loaded artefact.
    """
    diag = artefact.get("diagnostics") or {}
    gains = artefact.get("gains")
    gains = gains if isinstance(gains, Mapping) else {}
    observer = "L" in gains and "K" not in gains
    return tuple(dataclasses.replace(e, observer=observer) if observer else e for e in _walk(diag, "", None))
