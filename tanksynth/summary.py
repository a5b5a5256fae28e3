"""One line per verified artefact: its key figure and verdict (the end of ``tanksynth run``).

The key figure is read from the artefact's recorded verification (never
recomputed here): the achieved poles when the verdict matched them, the
observer LMI's ``psi``, the decay of an observer's or estimator's error on the
nonlinear plant, or the spectral radius / largest real part of the checked
closed loop.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

from tanksynth.artefacts.model import Artefact, Verification, VerificationCheck

__all__ = ["SummaryRow", "key_figure", "summary_row"]


@dataclass(frozen=True)
class SummaryRow:
    """What the run summary shows of one artefact.

    Attributes
    ----------
    name, method : str
    figure : str
        The key figure, in words with units.
    passed : bool
        The artefact's verdict.
    """

    name: str
    method: str
    figure: str
    passed: bool


@dataclass(frozen=True)
class _Read:
    """What the summary reads of an artefact (an `Artefact`, or a document as read from its JSON)."""

    name: str
    method: str
    diagnostics: Mapping[str, Any]
    verification: Verification | None


def _read(doc: Artefact | Mapping[str, Any]) -> _Read:
    if isinstance(doc, Artefact):
        return _Read(doc.name, doc.method, doc.diagnostics, doc.verification)
    diagnostics = doc.get("diagnostics")
    return _Read(str(doc.get("name", "")), str(doc.get("method", "")),
                 diagnostics if isinstance(diagnostics, Mapping) else {},
                 Verification.from_document(doc.get("verification")))


def _checks(read: _Read) -> dict[str, VerificationCheck]:
    """The recorded checks by name (the last of a name)."""
    return {} if read.verification is None else {c.check: c for c in read.verification.checks}


def _complex(v: Any) -> complex:
    return complex(v[0], v[1]) if isinstance(v, (list, tuple)) and len(v) == 2 else complex(v)


def _poles(values: Any) -> str:
    parts = []
    for z in sorted((_complex(v) for v in values), key=lambda z: (z.real, z.imag)):
        if abs(z.imag) < 1e-12:
            parts.append(f"{z.real:.4g}")
        elif z.imag > 0:
            parts.append(f"{z.real:.4g} ± {z.imag:.3g}j")
    return ", ".join(parts)


def _common_unit(units: Sequence[str] | None) -> str:
    """The unit shared by every state (``m`` for tank levels); empty when unknown or mixed."""
    if units and all(str(u) == str(units[0]) for u in units) and str(units[0]) not in ("", "1"):
        return str(units[0])
    return ""


def key_figure(doc: Artefact | Mapping[str, Any], state_units: Sequence[str] | None = None) -> str:
    """The key figure of one verified artefact, or ``"-"``.

    ``state_units`` (the plant record's state units) give the error figures their unit.
    Recorded data that cannot be read (an edited artefact: a string, None or an
    empty list where a number or list was recorded) gives
    ``"- (unreadable verification data)"``, never an exception.

    Parameters
    ----------
    doc : Artefact or mapping
        A verified artefact (`tanksynth.artefacts.io.load_artefact`), or its
        document as read from its JSON.
    state_units : sequence of str, optional
        Units of the plant's states (e.g. ``m``); None: figures without a unit.
    """
    try:
        return _key_figure(_read(doc), state_units)
    except (TypeError, ValueError, KeyError, IndexError, AttributeError, OverflowError):
        return "- (unreadable verification data)"


def _key_figure(doc: _Read, state_units: Sequence[str] | None) -> str:
    checks = _checks(doc)
    data: dict[str, Mapping[str, Any]] = {name: c.data for name, c in checks.items()}
    if "achieved" in data.get("poles", {}):
        return "poles " + _poles(data["poles"]["achieved"])
    if "psi" in data.get("lmi_recheck", {}):
        text = f"psi = {float(data['lmi_recheck']['psi']):.4g} 1/s"
        conv = data.get("observer_convergence", {})
        if "e0" in conv and "tail_max" in conv:
            unit = _common_unit(state_units)
            text += (f"; |e| {float(conv['e0']):.2g} {unit} -> {float(conv['tail_max']):.2g} "
                     f"{unit}").replace("  ", " ").rstrip()
        return text
    norms = (("hinf_norm", "||T_zw||inf"), ("h2_norm", "||T_zw||2"))
    if doc.method.startswith("h2_") or data.get("h2_optimality"):
        norms = norms[::-1]  # an H2 design is judged by its H2 norm
    for name, label in norms:
        if "value" in data.get(name, {}):
            return f"{label} = {float(data[name]['value']):.4g} (recomputed)"
    if "margins" in data.get("vertex_region", {}):
        margins = data["vertex_region"]["margins"]
        text = (f"region margin -lambda_max(f_D) {min(float(m) for m in margins):.3g} at the worst of "
                f"{len(margins)} models")
        hinf = data.get("vertex_hinf", {})
        if hinf.get("norms") and "gamma" in hinf:  # the H-infinity channel, recomputed per model
            bound = ((doc.diagnostics.get("robust") or {}).get("hinf") or {})
            worst, gamma = max(float(v) for v in hinf["norms"]), float(hinf["gamma"])
            text += (f"; ||T_zw||inf {worst:.4g} {'<=' if worst <= gamma else '> (EXCEEDS)'} gamma "
                     f"{gamma:.4g}"
                     + (" (not binding)" if bound.get("imposed") is False else ""))
        return text
    if "inner_radius" in data.get("region_recheck", {}):
        unit = _common_unit(state_units)
        text = (f"certified region: ball of radius {float(data['region_recheck']['inner_radius']):.3g} "
                f"{unit} around x_op")
        allowed = ((doc.diagnostics.get("composite") or {}).get("initial_error") or {})
        if "error_ball_at_x_op" in allowed and "plant_ball_estimate_at_x_op" in allowed:
            # an observer runs: the region holds for an exact initial estimate only
            text += (f" with the estimate starting exact; from x_op an initial estimation error up to "
                     f"{float(allowed['error_ball_at_x_op']):.3g} {unit}; estimate started at x_op: "
                     f"plant within {float(allowed['plant_ball_estimate_at_x_op']):.3g} {unit} of x_op")
        return text.replace("  ", " ")
    for name in ("estimator_convergence", "observer_convergence"):
        conv = data.get(name, {})
        if "e0" in conv and "tail_max" in conv:
            unit = _common_unit(state_units)
            return (f"|e|inf {float(conv['e0']):.2g} {unit} -> {float(conv['tail_max']):.2g} {unit} "
                    f"in {float(conv.get('horizon_s', 0.0)):.0f} s (nonlinear plant)").replace("  ", " ")
    fault = data.get("fault_detected", {})
    if fault.get("t_detect") and "t_fault" in fault:   # the residual detector on the nonlinear plant
        times = list(fault["t_detect"])
        no_false_alarm = checks.get("no_false_alarm")
        alarm = None if no_false_alarm is None else no_false_alarm.passed
        missed = sum(t is None for t in times)   # a run whose fault was never detected
        text = (f"fault NOT detected in {missed} of {len(times)} runs" if missed else
                f"fault detected {max(float(t) for t in times) - float(fault['t_fault']):.3g} s after "
                f"it occurs (worst of {len(times)} runs)")
        return text + ("; no false alarm" if alarm is True else "; FALSE ALARM" if alarm is False else "")
    stab = data.get("stability", {})
    if "value" in stab:
        what = "spectral radius" if stab.get("domain") == "discrete" else "max Re(pole)"
        return f"{what} {float(stab['value']):.4g}" + ("" if stab.get("domain") == "discrete" else " 1/s")
    if "validation" in data.get("validation_fit", {}) or "rmse" in data.get("rmse_reproduced", {}):
        fits = [float(r["fit_percent"]) for r in data.get("validation_fit", {}).get("validation", {}).values()
                if isinstance(r, Mapping) and isinstance(r.get("fit_percent"), (int, float))]
        params = doc.diagnostics.get("parameters") or {}
        text = ", ".join(f"{nm} {float(p['value']):.4g}" for nm, p in params.items()
                         if isinstance(p, Mapping) and isinstance(p.get("value"), (int, float)))
        return (text + (f"; validation fit >= {min(fits):.1f} %" if fits else "")) or "-"
    if data.get("first_order_agreement", {}).get("relative_errors"):   # a linearisation
        return (f"first-order agreement with the nonlinear plant: relative error "
                f"{max(float(e) for e in data['first_order_agreement']['relative_errors']):.2g}")
    return "-"


def summary_row(doc: Artefact | Mapping[str, Any], state_units: Sequence[str] | None = None) -> SummaryRow:
    """`SummaryRow` of one verified artefact (``state_units``: see `key_figure`).

    Parameters
    ----------
    doc : Artefact or mapping
        A verified artefact (`tanksynth.artefacts.io.load_artefact`), or its
        document as read from its JSON.
    state_units : sequence of str, optional
        Units of the plant's states (e.g. ``m``); None: figures without a unit.
    """
    read = _read(doc)
    return SummaryRow(read.name, read.method, key_figure(doc, state_units),
                      read.verification is not None and read.verification.passed)
