"""Verdict traces beside the artefacts: ``DIR/<name>.traces.npz``.

`tanksynth verify` stores beside each artefact a compact trace of the verdict's main
simulation (the first one the verdict runs that calls `tanksynth.verify.traces.TraceRecorder.record`):
``DIR/<name>.traces.npz`` with ``t``, ``x`` (plant), ``x_hat`` (estimators
and observers), ``t_u``/``u`` (inputs), ``reference`` (if any) for the first
`TRACE_RUNS` runs, decimated to at most `TRACE_MAX_SAMPLES` samples, and a
JSON header (scenario, check and its verdict, state/input names and units).
It is written atomically and is not part of the artefact JSON (the
provenance hash is untouched); the report draws it as a time-domain figure.
A verdict that simulates nothing leaves no trace (a stale one is removed).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from tanksynth.artefacts.atomic import atomic_write


__all__ = ["TRACE_SUFFIX", "TRACE_MAX_SAMPLES", "TRACE_RUNS", "trace_path", "write_trace", "read_trace"]


#: File name suffix of an artefact's verdict trace: ``DIR/<name>.traces.npz``.
TRACE_SUFFIX = ".traces.npz"



#: Samples kept in a trace at most (decimated by a constant stride).
TRACE_MAX_SAMPLES = 2000



#: Runs of the verdict simulation batch kept in a trace (the first ones).
TRACE_RUNS = 2



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

    The header is stored as a JSON string (``header``); no pickled object.

    Parameters
    ----------
    path : str or Path
        Target ``.traces.npz``.
    trace : mapping
        ``header`` (a JSON-friendly mapping) and ``arrays`` (time in s, signals in the
        plant's units).
    """
    path = Path(path)
    arrays = {k: np.asarray(v, dtype=float) for k, v in trace["arrays"].items()}
    header = np.array(json.dumps(trace["header"], allow_nan=False, sort_keys=True))
    return atomic_write(path, lambda fh: np.savez_compressed(fh, header=header, **arrays))



def read_trace(path: str | Path) -> dict | None:
    """Read a trace file; None when it is missing or unreadable (no time-domain figure then).

    Parameters
    ----------
    path : str or Path
        A ``.traces.npz`` file.

    Returns
    -------
    dict or None
        ``{"header": dict, "arrays": dict of ndarray}``.
    """
    try:
        with np.load(Path(path), allow_pickle=False) as data:
            header = json.loads(str(data["header"][()]))
            arrays = {k: np.asarray(data[k]) for k in data.files if k != "header"}
    except (OSError, ValueError, KeyError, json.JSONDecodeError, EOFError):
        return None
    if not isinstance(header, dict) or "t" not in arrays or "x" not in arrays:
        return None
    return {"header": header, "arrays": arrays}
