"""The ``fault`` family's diagnostics (``fault_detection``): the detection times it recorded for
its initial states, and the fault size.

A detection is read under any of the names the seed 004 runs use (``x0``, ``initial_state`` ...
for the initial state; ``t_detect``, ``detection_time`` ... for the time), from a list of
records or from columns.
"""

from __future__ import annotations

import math
from typing import Any, Mapping, Sequence

import numpy as np

from tanksynth.reports.diagnostics.common import Diagnostics, entry, is_number, section

__all__ = ["Detection", "detection_time", "detections_of", "initial_states_of", "fault_size_of"]

#: One detection: the initial state (state units) and the detection time (s; None: not detected).
Detection = tuple[np.ndarray, float | None]

_X0_KEYS = ("x0", "initial_state", "initial_states", "starts", "start")
_T_KEYS = ("t_detect", "t_d", "detection_time", "detection_times", "time", "times")


def detection_time(value: Any) -> float | None:
    """A stored detection time (s); None when it says "not detected" (None, negative, not finite)
    or is no number.

    Parameters
    ----------
    value : object
        The stored time (s).
    """
    if not is_number(value):
        return None
    time = float(value)
    return time if math.isfinite(time) and time >= 0 else None


def _first(node: Mapping[str, Any], keys: Sequence[str]) -> Any:
    """The value of the first of ``keys`` that ``node`` has."""
    return next((node[k] for k in keys if k in node), None)


def _detections(node: Any) -> list[Detection]:
    """The detections of a list of records or of a table of columns."""
    out: list[Detection] = []
    if isinstance(node, list):
        for record in node:
            if isinstance(record, Mapping):
                x0, t = _first(record, _X0_KEYS), _first(record, _T_KEYS)
                try:
                    out.append((np.asarray(x0, dtype=float).reshape(-1), detection_time(t)))
                except (TypeError, ValueError):
                    continue
        return out
    if isinstance(node, Mapping):
        for key in ("records", "runs", "results"):
            if isinstance(node.get(key), list):
                return _detections(node[key])
        x0s, ts = _first(node, _X0_KEYS), _first(node, _T_KEYS)
        if isinstance(x0s, list) and isinstance(ts, list) and len(x0s) == len(ts):
            try:
                return [(np.asarray(x, dtype=float).reshape(-1), detection_time(t)) for x, t in zip(x0s, ts)]
            except (TypeError, ValueError):
                return []
    return out


def detections_of(diag: Diagnostics) -> list[Detection]:
    """The detections ``diagnostics["detection"]`` (or ``["detections"]``) records, first found.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.

    Returns
    -------
    list of (ndarray, float or None)
        Initial state (state units) and detection time (s; None: not detected); empty when the
        artefact records none.
    """
    for key in ("detection", "detections"):
        found = _detections(diag.get(key)) if isinstance(diag, Mapping) else []
        if found:
            return found
    return []


def initial_states_of(diag: Diagnostics) -> list[Any] | None:
    """The initial states the detection runs started from (``initial_states`` or ``starts``),
    each a list of levels (state units), when the artefact lists them beside its detection times.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    starts = _first(diag, ("initial_states", "starts")) if isinstance(diag, Mapping) else None
    return starts if isinstance(starts, list) else None


def fault_size_of(diag: Diagnostics) -> float | None:
    """The fault size ``delta_bar`` the design was given (dimensionless factor on the fault
    matrix), at the top of the diagnostics or in its detection section.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    for node in (diag, section(diag, "detection")):
        size = entry(node, "delta_bar", is_number)
        if size is not None:
            return float(size)
    return None
