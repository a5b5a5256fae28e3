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
provenance hash is untouched); verify records its sha256 in the artefact's
``verification`` (``traces_sha256``, absent when it wrote no trace), and the
report draws each stored trace as a time-domain figure only when it matches
(`check_trace`). A verdict that simulates nothing leaves no trace (a stale one
is removed), and design removes the trace of an artefact it rewrites.

A trace file is input like every file of a result directory: it is read with a
size cap (`tanksynth.artefacts.io.read_limited`: a FIFO, a device or a huge
file is refused, never opened blocking), and its members are bounded before
anything is decompressed (`tanksynth.artefacts.npzfile.read_npz`): at most
`TRACE_MAX_MEMBERS` of them, each numeric array of at most `TRACE_MAX_VALUES`
values and 3 dimensions, the JSON header at most `TRACE_MAX_HEADER_BYTES`, all
together at most `TRACE_MAX_BYTES` uncompressed. `write_trace` refuses a trace
beyond these limits, so every trace tanksynth writes reads back.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
from pathlib import Path
from typing import Any, Mapping, cast

import numpy as np

from tanksynth.artefacts.atomic import atomic_write
from tanksynth.artefacts.io import read_limited
from tanksynth.artefacts.npzfile import MalformedNPZ, read_npz
from tanksynth.errors import ArtefactError


__all__ = ["TRACE_SUFFIX", "TRACE_MAX_SAMPLES", "TRACE_RUNS", "TRACE_EXTRAS", "TRACE_MAX_VALUES",
           "TRACE_MAX_HEADER_BYTES", "TRACE_MAX_MEMBERS", "TRACE_MAX_BYTES", "trace_path", "write_trace",
           "read_trace", "check_trace", "TraceLimitError"]


#: File name suffix of an artefact's verdict trace: ``DIR/<name>.traces.npz``.
TRACE_SUFFIX = ".traces.npz"



#: Samples kept in a trace at most (decimated by a constant stride).
TRACE_MAX_SAMPLES = 2000



#: Runs of the verdict simulation batch kept in a trace (the first ones).
TRACE_RUNS = 2


#: Further traces kept beside the main one at most: the first simulation of each other check
#: (a figure each in the report; a file stays small). Four: seed 002's inverse-dynamics verdict
#: draws its +-10 % mismatch, leak and clogging runs beside the servo test (the paper's Fig. 7-8).
TRACE_EXTRAS = 4


#: Values of one array of a trace at most: `TRACE_MAX_SAMPLES` samples of 2048 columns (runs kept
#: times states, inputs or signals: 2 runs of the largest built-in plant, 256 tanks, use 512).
TRACE_MAX_VALUES = TRACE_MAX_SAMPLES * 2048


#: Size of a trace's JSON header at most (bytes, as numpy stores it: 4 per character).
TRACE_MAX_HEADER_BYTES = 4 * 1024 ** 2


#: Members of a trace file at most: the header and, for the main trace and each extra, its arrays
#: (``t``, ``x``, ``t_u``, ``u``, ``x_hat``, ``reference``, ``signals`` and a few more).
TRACE_MAX_MEMBERS = 1 + (1 + TRACE_EXTRAS) * 12


#: Uncompressed size of a whole trace file at most (bytes): the header and eight arrays of
#: `TRACE_MAX_VALUES` float64 values; also the largest trace file read.
TRACE_MAX_BYTES = TRACE_MAX_HEADER_BYTES + 8 * TRACE_MAX_VALUES * 8


#: Room for an ``.npy`` member's header in its declared size (bytes).
_NPY_HEADER_ROOM = 4096


#: Header keys that describe the array ``signals`` (dropped with it when it does not fit).
_SIGNAL_KEYS = ("signal_names", "signal_units", "signal_styles", "signal_title", "events")


#: Prefix of an extra trace's array keys in the file: ``extra1.t``, ``extra1.x``, ...
_EXTRA = "extra{}."



class TraceLimitError(ValueError):
    """A trace beyond the limits every reader of trace files applies (`write_trace` refuses it)."""


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
    TraceLimitError
        The trace exceeds the limits every reader applies (`TRACE_MAX_VALUES` per array, at most 3 dimensions,
        `TRACE_MAX_MEMBERS`, `TRACE_MAX_HEADER_BYTES`, `TRACE_MAX_BYTES`); nothing is written then.
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
    members = {"header": text, **arrays}
    reasons = [f"{key}: {why}" for key, v in members.items() if (why := _beyond_limits(key, v.shape, v.dtype))]
    total = sum(v.nbytes for v in members.values())
    if reasons or len(members) > TRACE_MAX_MEMBERS or total > TRACE_MAX_BYTES:
        raise TraceLimitError(f"{path}: trace beyond the limits a reader accepts ({len(members)} members, "
                         f"{total} bytes{'; ' if reasons else ''}{'; '.join(reasons)})")
    buf = io.BytesIO()
    # Any: numpy's stub types allow_pickle as a keyword too, which no array name here can be
    entries = cast(dict[str, Any], arrays)
    np.savez_compressed(buf, header=text, **entries)
    return atomic_write(path, buf.getvalue())


def _beyond_limits(key: str, shape: tuple[int, ...], dtype: np.dtype) -> str | None:
    """Why a trace member of this header may not be read (None: it may)."""
    count = 1
    for n in shape:
        count *= int(n)
    if key == "header":
        if dtype.kind != "U" or shape != ():
            return f"the header is a {dtype} array of shape {shape}, not one JSON string"
        return None if dtype.itemsize <= TRACE_MAX_HEADER_BYTES else \
            f"a header of {dtype.itemsize} bytes, more than the {TRACE_MAX_HEADER_BYTES} accepted"
    if len(shape) > 3:
        return f"{len(shape)} dimensions, more than the 3 of a trace's arrays"
    if count > TRACE_MAX_VALUES or count * dtype.itemsize > TRACE_MAX_VALUES * 8:
        return (f"{count} values of {dtype} (shape {shape}), more than the {TRACE_MAX_VALUES} "
                f"values ({TRACE_MAX_VALUES * 8} bytes) a trace's array may hold")
    return None


def _numeric(arrays: dict) -> bool:
    """Every array holds numbers (an edited file's string array is unreadable, not a crash)."""
    return all(np.issubdtype(v.dtype, np.number) or v.dtype == np.bool_ for v in arrays.values())


def _members(path: Path, sha256: str | None) -> dict[str, np.ndarray] | None:
    """The arrays of a trace file, every read bounded; None when it is missing (not when it is
    a dangling symlink, a FIFO or a device: refused)."""
    if not os.path.lexists(path):
        return None
    data = read_limited(path, TRACE_MAX_BYTES)
    if sha256 is not None and hashlib.sha256(data).hexdigest() != sha256:
        raise ArtefactError(f"{path}: does not match the traces_sha256 verify recorded (edited, "
                            "replaced or swapped after verification)")

    def room(key: str) -> int:
        return (TRACE_MAX_HEADER_BYTES if key == "header" else TRACE_MAX_VALUES * 8) + _NPY_HEADER_ROOM

    try:
        return read_npz(data, path, max_members=TRACE_MAX_MEMBERS, max_total=TRACE_MAX_BYTES,
                        member_limit=room, check=_beyond_limits)
    except MalformedNPZ:
        return {}     # garbage within the bounds: unreadable, no figure (as before bounds existed)


def read_trace(path: str | Path, sha256: str | None = None) -> dict | None:
    """Read a trace file; None when it is missing or unreadable (no time-domain figure then).

    Files written before extra traces existed read the same way (``more`` empty). The
    file is read with a cap and each member's header is checked against the trace limits
    before its data are decompressed (see the module docstring).

    Parameters
    ----------
    path : str or Path
        A ``.traces.npz`` file.
    sha256 : str, optional
        The sha256 (hex) its bytes must have (the artefact's ``verification.traces_sha256``,
        `check_trace`); not checked when omitted.

    Returns
    -------
    dict or None
        ``{"header": dict, "arrays": dict of ndarray, "more": list}``: the main trace and
        the extra traces (each ``{"header", "arrays"}``, in the order recorded; an
        unreadable extra is left out). Signals that do not fit their trace (array
        ``signals`` not (runs, samples, k) for k names) are left out with their header keys.
        None when the file is missing or not a readable trace.

    Raises
    ------
    ArtefactError
        One line naming the file: not a regular file (a FIFO, a device, a dangling
        symlink), larger than `TRACE_MAX_BYTES`, a member beyond the trace limits (a zip
        bomb), or bytes other than ``sha256``.
    """
    path = Path(path)
    arrays = _members(path, sha256)
    if not arrays or "header" not in arrays:
        return None
    try:
        header = json.loads(str(arrays.pop("header")[()]))
    except (ValueError, RecursionError):
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


def check_trace(artefact_path: str | Path, doc: Mapping[str, Any]) -> Path | None:
    """Refuse a verdict trace beside an artefact that is not the one verify wrote; read it bounded.

    ``verify`` records the sha256 of the ``<name>.traces.npz`` it writes as the artefact's
    ``verification.traces_sha256`` (no key when it wrote none). Strict: a trace file
    beside an artefact that records no such hash (not verified, verified by a tanksynth
    that did not record trace hashes, or a verdict that simulated nothing) is refused; run
    ``tanksynth verify DIR`` again then. A missing trace is no figure, as it always was.

    Parameters
    ----------
    artefact_path : str or Path
        The artefact ``DIR/<name>.json``.
    doc : mapping
        Its document (`tanksynth.artefacts.io.read_artefact`).

    Returns
    -------
    Path or None
        The checked trace file; None when there is none.

    Raises
    ------
    ArtefactError
        Naming the trace file: see `read_trace` (FIFO, size, bomb, sha256), or not covered
        by a ``traces_sha256``.
    """
    target = trace_path(artefact_path, str(doc.get("name", Path(artefact_path).stem)))
    ver = doc.get("verification")
    stored = ver.get("traces_sha256") if isinstance(ver, Mapping) else None
    present = os.path.lexists(target)
    if stored is None:
        if present:
            raise ArtefactError(f"{target}: no traces_sha256 in the verification of "
                                f"{Path(artefact_path).name} covers it (not verified, or verified "
                                "by an older tanksynth); run `tanksynth verify` on the directory again")
        return None
    if not isinstance(stored, str):
        raise ArtefactError(f"{artefact_path}: verification.traces_sha256 must be a string, got "
                            f"{type(stored).__name__}")
    if not present:
        return None
    read_trace(target, stored)
    return target


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
