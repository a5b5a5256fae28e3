"""The JSON text of artefacts: ``json.dumps(doc, indent=2, allow_nan=False)``, byte for byte,
without the standard library's one-Python-call-per-number cost on big matrices."""

from __future__ import annotations

import json
import math
from typing import Any

__all__ = ["dumps"]


class _NotPlain(Exception):
    """A value `dumps` leaves to `json.dumps` (the whole document then goes there)."""



_FLOAT_REPR = float.__repr__



def dumps(doc: Any) -> str:
    """``json.dumps(doc, indent=2, allow_nan=False)``, the same text, faster on big matrices.

    With ``indent``, the standard library encodes in pure Python, one call per
    number (seconds for the artefact of a 256-state design); here each list of
    numbers is encoded by the C encoder in one call and only re-joined with the
    indentation. Anything unusual (non-string keys, other types) is left to
    `json.dumps` itself.

    Parameters
    ----------
    doc : object
        A JSON-able document (dicts with string keys, lists, str, finite float,
        int, bool, None).

    Returns
    -------
    str
        Its JSON text, two-space indented.

    Raises
    ------
    ValueError
        A non-finite float (as ``json.dumps(..., allow_nan=False)``).
    """
    try:
        return _encode(doc, "")
    except _NotPlain:
        return json.dumps(doc, indent=2, allow_nan=False)



def _encode(value: Any, indent: str) -> str:
    inner = indent + "  "
    if isinstance(value, dict):
        if not value:
            return "{}"
        parts = []
        for k, v in value.items():
            if not isinstance(k, str):
                raise _NotPlain
            parts.append(f"{inner}{json.encoder.encode_basestring_ascii(k)}: {_encode(v, inner)}")
        return "{\n" + ",\n".join(parts) + "\n" + indent + "}"
    if isinstance(value, list):
        if not value:
            return "[]"
        if all(type(v) is float or type(v) is int for v in value):
            for v in value:
                if type(v) is float and not math.isfinite(v):
                    raise ValueError(f"Out of range float values are not JSON compliant: {v!r}")
            flat = json.dumps(value)[1:-1].split(", ")
            return "[\n" + inner + (",\n" + inner).join(flat) + "\n" + indent + "]"
        return "[\n" + ",\n".join(inner + _encode(v, inner) for v in value) + "\n" + indent + "]"
    if isinstance(value, str):
        return json.encoder.encode_basestring_ascii(value)
    if value is None or value is True or value is False or type(value) in (int, float):
        return json.dumps(value, allow_nan=False)
    raise _NotPlain
