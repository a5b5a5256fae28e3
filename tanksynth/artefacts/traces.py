"""Verdict traces beside the artefacts: ``DIR/<name>.traces.npz``.

`tanksynth verify` stores beside each artefact a compact trace of the verdict's main
simulation (the first one the verdict runs that calls `tanksynth.verify.traces.TraceRecorder.record`):
``DIR/<name>.traces.npz`` with ``t``, ``x`` (plant), ``x_hat`` (estimators
and observers), ``t_u``/``u`` (inputs), ``reference`` (if any) for the first
`TRACE_RUNS` runs, decimated to at most `TRACE_MAX_SAMPLES` samples, and a
JSON header (scenario, check and its verdict, state/input names and units).

The file also holds up to `TRACE_EXTRAS` further traces: the first simulation
of each other check the verdict records (e.g. the H2/H-infinity
``disturbance_step`` after the ``regulation`` run). Their arrays are stored
under the prefixed keys ``extraK.t``, ``extraK.x``, ... (K = 1, 2) and their
headers as the list ``extras`` in the main header, so the main trace reads
exactly as in a file without extras (schema ``tanksynth.traces/1``; a reader
that knows nothing of extras ignores them), and a file without extras is
byte for byte the file written before extras existed.

A trace may also hold further named signals of its runs (e.g. the fault
detector's residual and threshold): the array ``signals`` (runs, samples, k) on
the times ``t``, and in its header ``signal_names``, ``signal_units``,
``signal_styles`` (matplotlib line styles), ``signal_title`` and ``events``
(``[[t, label], ...]``, instants to mark, s). A trace without signals has none
of these keys (its file is the one written before signals existed); signals
that do not fit their trace (shape or names) are dropped on reading, the rest
of the trace reads as usual.

It is written atomically and is not part of the artefact JSON (the
provenance hash is untouched); the report draws each stored trace as a
time-domain figure. A verdict that simulates nothing leaves no trace (a
stale one is removed).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, Mapping, cast

import numpy as np

from tanksynth.artefacts.atomic import atomic_write


__all__ = ["TRACE_SUFFIX", "TRACE_MAX_SAMPLES", "TRACE_RUNS", "TRACE_EXTRAS", "trace_path", "write_trace",
           "read_trace"]


#: File name suffix of an artefact's verdict trace: ``DIR/<name>.traces.npz``.
TRACE_SUFFIX = ".traces.npz"



#: Samples kept in a trace at most (decimated by a constant stride).
TRACE_MAX_SAMPLES = 2000



#: Runs of the verdict simulation batch kept in a trace (the first ones).
TRACE_RUNS = 2


#: Further traces kept beside the main one at most: the first simulation of each other check
#: (a figure each in the report; a file stays small).
TRACE_EXTRAS = 2


#: Header keys that describe the array ``signals`` (dropped with it when it does not fit).
_SIGNAL_KEYS = ("signal_names", "signal_units", "signal_styles", "signal_title", "events")


#: Prefix of an extra trace's array keys in the file: ``extra1.t``, ``extra1.x``, ...
_EXTRA = "extra{}."



def trace_path(artefact_path: str | Path, name: str) -> Path:
    """``DIR/<name>.traces.npz`` beside the artefact ``DIR/<name>.json``.

    Parameters
    ----------
    artefact_path : str or Path
        The artefact ``DIR/<name>.json``.
    name : str
        The design's name.
    """
    return Path(artefact_path).with_name(f"{name}{TRACE_SUFFIX}")



def write_trace(path: str | Path, trace: Mapping[str, Any]) -> Path:
    """Write a trace (`verdict_with_trace`) as ``.npz``, atomically (temp file + os.replace).

    The header is stored as a JSON string (``header``); no pickled object. The
    extra traces (``trace["more"]``, at most `TRACE_EXTRAS` are written) go under
    the array keys ``extraK.<key>`` with their headers as the main header's list
    ``extras``; without extras the file is the one-trace file.

    Parameters
    ----------
    path : str or Path
        Target ``.traces.npz``.
    trace : mapping
        ``header`` (a JSON-friendly mapping) and ``arrays`` (time in s, signals in the
        plant's units); optionally ``more``, a sequence of such mappings.

    Raises
    ------
    ValueError
        A header already holds the key ``extras``.
    """
    path = Path(path)
    arrays = {k: np.asarray(v, dtype=float) for k, v in trace["arrays"].items()}
    header = dict(trace["header"])
    more = list(trace.get("more") or [])[:TRACE_EXTRAS]
    if "extras" in header or any("extras" in m["header"] for m in more):
        raise ValueError(f"{path}: a trace header may not hold the key 'extras' (the extra traces' list)")
    if more:
        header["extras"] = [dict(m["header"]) for m in more]
        for k, m in enumerate(more, start=1):
            arrays.update({_EXTRA.format(k) + key: np.asarray(v, dtype=float) for key, v in m["arrays"].items()})
    text = np.array(json.dumps(header, allow_nan=False, sort_keys=True))
    # Any: numpy's stub types allow_pickle as a keyword too, which no array name here can be
    entries = cast(dict[str, Any], arrays)
    return atomic_write(path, lambda fh: np.savez_compressed(fh, header=text, **entries))



def _numeric(arrays: dict) -> bool:
    """Every array holds numbers (an edited file's string array is unreadable, not a crash)."""
    return all(np.issubdtype(v.dtype, np.number) or v.dtype == np.bool_ for v in arrays.values())


def read_trace(path: str | Path) -> dict | None:
    """Read a trace file; None when it is missing or unreadable (no time-domain figure then).

    Files written before extra traces existed read the same way (``more`` empty).

    Parameters
    ----------
    path : str or Path
        A ``.traces.npz`` file.

    Returns
    -------
    dict or None
        ``{"header": dict, "arrays": dict of ndarray, "more": list}``: the main trace and
        the extra traces (each ``{"header", "arrays"}``, in the order recorded; an
        unreadable extra is left out). Signals that do not fit their trace (array
        ``signals`` not (runs, samples, k) for k names) are left out with their header keys.
    """
    try:
        with np.load(Path(path), allow_pickle=False) as data:
            header = json.loads(str(data["header"][()]))
            arrays = {k: np.asarray(data[k]) for k in data.files if k != "header"}
    except (OSError, ValueError, KeyError, json.JSONDecodeError, EOFError):
        return None
    if not isinstance(header, dict):
        return None
    extras = header.pop("extras", None)
    main = {k: v for k, v in arrays.items() if not re.match(r"extra\d+\.", k)}
    if "t" not in main or "x" not in main or not _numeric(main):
        return None
    more = []
    for k, head in enumerate(extras if isinstance(extras, list) else [], start=1):
        prefix = _EXTRA.format(k)
        arr = {key[len(prefix):]: v for key, v in arrays.items() if key.startswith(prefix)}
        if isinstance(head, dict) and "t" in arr and "x" in arr and _numeric(arr):
            more.append(_signals_checked({"header": head, "arrays": arr}))
    return {**_signals_checked({"header": header, "arrays": main}), "more": more}


def _signals_checked(trace: dict) -> dict:
    """The trace, without its signals (array and header keys) when they do not fit it."""
    head, arr = trace["header"], trace["arrays"]
    if "signals" not in arr and not any(k in head for k in _SIGNAL_KEYS):
        return trace
    sig, x, t = arr.get("signals"), arr["x"], arr["t"]
    names, units = head.get("signal_names"), head.get("signal_units")
    ok = (sig is not None and sig.ndim == 3 and x.ndim == 3 and sig.shape[:2] == (x.shape[0], t.size)
          and isinstance(names, list) and len(names) == sig.shape[2]
          and (units is None or (isinstance(units, list) and len(units) == sig.shape[2])))
    if ok:
        return trace
    return {"header": {k: v for k, v in head.items() if k not in _SIGNAL_KEYS},
            "arrays": {k: v for k, v in arr.items() if k != "signals"}}
