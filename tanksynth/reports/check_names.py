"""A check's key (``rmse_reproduced``) as the words a report prints (``RMSE reproduced``).

The keys of `tanksynth.analysis.checks.Check` are identifiers for the JSON files and the
tests; tables and figure captions print these words instead: underscores become spaces,
abbreviations are capitalised as engineers write them (RMSE, ZOH, LMI, PBH, NIS, NEES, H2,
H-infinity...), a few words are spelt out, and the phrase starts with a capital.
"""

from __future__ import annotations

import re
from typing import Any

__all__ = ["check_title"]

#: Words of the keys written as the report writes them.
_WORDS = {
    "rmse": "RMSE", "zoh": "ZOH", "lmi": "LMI", "pbh": "PBH", "nis": "NIS", "nees": "NEES",
    "h2": "H2", "hinf": "H-infinity", "ts": "Takagi-Sugeno",
    "jacobian": "Jacobian", "recheck": "re-check", "setpoint": "set-point", "u0": "u0",
    "mean": "mean", "vs": "vs.", "monte": "Monte", "carlo": "Carlo", "riccati": "Riccati",
    "lyapunov": "Lyapunov", "acf": "ACF", "pdc": "PDC", "nonlinear": "nonlinear",
}

#: Whole keys with a better phrase than their words.
_PHRASES = {
    "given_u0_balances": "Spec's input balances the model",
    "ts_model_rebuilt": "Takagi-Sugeno model rebuilt",
    "filter_vs_open_loop": "Filter vs. open-loop prediction",
    "one_step_fit": "One-step prediction fit",
    "data_files": "Data files",
}


def check_title(key: Any) -> str:
    """The words of a check's key, for tables and captions (plain text, no LaTeX).

    Parameters
    ----------
    key : str
        The check's key (``"zoh_consistency"``); any other text is returned with its
        underscores as spaces.

    Returns
    -------
    str
        ``"ZOH consistency"``, ``"RMSE reproduced"``, ``"Jacobian re-check"``.
    """
    text = str(key).strip()
    if text in _PHRASES:
        return _PHRASES[text]
    if not re.fullmatch(r"[a-z0-9_]+", text):
        return text.replace("_", " ")
    words = [_WORDS.get(w, w) for w in text.split("_") if w]
    if not words:
        return ""
    first = words[0]
    if first[:1].isalpha() and first.replace("-", "").isalpha() and first.islower():
        words[0] = first[0].upper() + first[1:]
    return " ".join(words)
