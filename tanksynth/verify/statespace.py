"""The closed loops and observers of an artefact as python-control ``StateSpace`` objects.

So that a python-control user can ``step``, ``bode`` or ``margin`` a tanksynth
design in one line::

    import control, json
    doc = json.load(open("out/hinf_controller.json"))
    control.bode(artefact_statespace(doc))

Built from the artefact's gains alone (the model ``A``, ``B``, ``C`` stored with
every linear gain, and ``Bw``, ``Cz``, ``Dzu`` / ``Dv`` where the design has
them), in deviation variables about the operating point:

state feedback ``K`` (``u = -K x``)
    ``"performance"``: ``(A - B K, Bw, Cz - Dzu K, 0)`` from ``w`` to ``z``;
    ``"reference"``: ``(A - B K, B, C, 0)`` from an input offset to the outputs;
    ``"loop"``: the loop transfer ``(A, B, K, 0)`` broken at the plant input
    (``margin`` of ``L(s) = K (sI - A)^-1 B``).
observer ``L``
    ``"performance"``: the error system ``(A - L C, [Bw, -L Dv], Cz, 0)``;
    ``"observer"``: the observer itself ``(A - L C, [B, L], I, 0)`` from
    ``(u, y)`` to the estimate.

Discrete-time designs (``time_domain = "discrete"`` in the diagnostics) get
``dt = ts``.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from tanksynth.errors import ArtefactError

__all__ = ["artefact_statespace", "SYSTEMS"]

#: The systems `artefact_statespace` builds.
SYSTEMS = ("performance", "reference", "loop", "observer")


def _gain(doc: Mapping[str, Any], name: str) -> np.ndarray | None:
    value = (doc.get("gains") or {}).get(name)
    return None if value is None else np.atleast_2d(np.asarray(value, dtype=float))


def _dt(doc: Mapping[str, Any]) -> float:
    diag = doc.get("diagnostics") or {}
    if diag.get("time_domain") == "discrete":
        ts = diag.get("ts")
        if not isinstance(ts, (int, float)) or ts <= 0:
            raise ArtefactError(f"artefact '{doc.get('name', '')}': discrete design without ts")
        return float(ts)
    return 0.0


def artefact_statespace(doc: Mapping[str, Any], system: str = "performance",
                        spec: Any = None) -> Any:
    """A closed loop or observer of an artefact as a `control.StateSpace`.

    Parameters
    ----------
    doc : mapping
        The artefact (as read from its JSON file).
    system : {"performance", "reference", "loop", "observer"}
        See the module docstring.
    spec : Spec, optional
        Names the states, inputs and outputs after the plant's.

    Returns
    -------
    control.StateSpace

    Raises
    ------
    ArtefactError
        The artefact lacks the gains this system needs.
    """
    import control

    if system not in SYSTEMS:
        raise ArtefactError(f"system must be one of {SYSTEMS}, got {system!r}")
    A, B, C = _gain(doc, "A"), _gain(doc, "B"), _gain(doc, "C")
    K, L = _gain(doc, "K"), _gain(doc, "L")
    name = str(doc.get("name", "artefact"))
    if A is None or (K is None and L is None):
        raise ArtefactError(f"artefact '{name}' ({doc.get('method', '')}) stores no linear model A "
                            "with a gain K or L")
    n = A.shape[0]
    dt = _dt(doc)
    plant = getattr(spec, "plant", None)
    states = [s.name for s in plant.states] if plant is not None else None
    kw: dict[str, Any] = {"name": f"{name}_{system}".replace(".", "_")}
    if K is not None:
        if K.shape[1] != n:
            raise ArtefactError(f"artefact '{name}': K has {K.shape[1]} columns, the model {n} states "
                                "(integral action: use the augmented model)")
        if system == "performance":
            Bw, Cz, Dzu = _gain(doc, "Bw"), _gain(doc, "Cz"), _gain(doc, "Dzu")
            if Bw is None or Cz is None or Dzu is None:
                raise ArtefactError(f"artefact '{name}' declares no Bw, Cz, Dzu (not an H2/Hinf design)")
            return control.ss(A - B @ K, Bw, Cz - Dzu @ K, np.zeros((Cz.shape[0], Bw.shape[1])), dt,
                              **kw, **({"states": states} if states else {}))
        if system == "reference":
            extra = {"states": states} if states else {}
            if plant is not None:
                extra.update(inputs=[s.name for s in plant.inputs],
                             outputs=[s.name for s in plant.outputs])
            return control.ss(A - B @ K, B, C, np.zeros((C.shape[0], B.shape[1])), dt, **kw, **extra)
        if system == "loop":
            return control.ss(A, B, K, np.zeros((K.shape[0], B.shape[1])), dt, **kw)
        raise ArtefactError(f"artefact '{name}' is a state feedback: system 'observer' does not apply")
    if system == "performance":
        Bw, Dv, Cz = _gain(doc, "Bw"), _gain(doc, "Dv"), _gain(doc, "Cz")
        if Bw is None or Dv is None or Cz is None:
            raise ArtefactError(f"artefact '{name}' declares no Bw, Dv, Cz (not an H2/Hinf design)")
        Bcl = np.hstack([Bw, -L @ Dv])
        return control.ss(A - L @ C, Bcl, Cz, np.zeros((Cz.shape[0], Bcl.shape[1])), dt, **kw)
    if system == "observer":
        Bo = np.hstack([B, L]) if B is not None else L
        return control.ss(A - L @ C, Bo, np.eye(n), np.zeros((n, Bo.shape[1])), dt, **kw,
                          **({"states": states, "outputs": [f"{s}_hat" for s in states]}
                             if states else {}))
    raise ArtefactError(f"artefact '{name}' is an observer: use system 'performance' or 'observer'")
