"""The ``fit`` family's problem statement: grey-box estimation of free plant parameters and
initial states from logged data (output error, multiple shooting, IPOPT)."""

from __future__ import annotations

from typing import Any, Mapping

from tanksynth.reports.latex import Tex, escape_latex, format_number, symbol_latex

__all__ = ["fit_statement"]


def _covariance_text(diag: Mapping[str, Any]) -> str:
    """Which covariance the standard errors come from (LaTeX): the Fisher information when the
    residuals are white, the Newey-West sandwich when they are not (``diagnostics.uncertainty``)."""
    unc = diag.get("uncertainty") or {}
    if unc.get("used") == "hac":
        lags = ", ".join(str(int(v)) for v in (unc.get("hac") or {}).get("lags") or [])
        return (r"Residuals not white (Ljung-Box, 20 lags, 95\,\%): standard errors from the "
                r"autocorrelation-consistent Newey-West covariance $B^{-1} S B^{-1}$, $B = J^\top J$, "
                r"$S$ the Bartlett-weighted long-run covariance of the scores (lags "
                + escape_latex(lags) + r"); they cover coloured noise, not model error")
    return (r"Standard errors from the Fisher information, $\mathrm{cov}\,\hat\theta = \hat\sigma^2 "
            r"(J^\top J)^{-1}$ (residuals white: Ljung-Box, 20 lags, 95\,\%)")


def _parameters(diag: Mapping[str, Any]) -> str:
    """``mu13 \\in [0.2, 0.9]`` for each free parameter (its search box), tolerating edits."""
    params = diag.get("parameters")
    if not isinstance(params, Mapping):
        return r"\theta"
    items = []
    for name, p in params.items():
        if isinstance(p, Mapping) and isinstance(p.get("lower"), (int, float)) \
                and isinstance(p.get("upper"), (int, float)):
            items.append(rf"{symbol_latex(name)} \in [{format_number(p['lower'])}, "
                         rf"{format_number(p['upper'])}]")
    return ", ".join(items) if items else r"\theta"


def _table(diag: Mapping[str, Any]) -> str:
    """The fitted values, standard errors and intervals, and the correlation matrix (LaTeX
    tabulars; empty when the diagnostics do not hold them)."""
    params = diag.get("parameters")
    if not isinstance(params, Mapping) or not params:
        return ""
    level = diag.get("level", 0.95)
    pct = format_number(100 * float(level), 3) if isinstance(level, (int, float)) else "95"
    rows = []
    names = []
    for name, p in params.items():
        if not isinstance(p, Mapping):
            continue
        given = p.get("ci95")
        ci = given if isinstance(given, list) and len(given) == 2 else [None, None]
        cells = [format_number(v) if isinstance(v, (int, float)) else "--"
                 for v in (p.get("value"), p.get("stderr"), ci[0], ci[1], p.get("start"))]
        unit = escape_latex(p.get("unit", "")) if p.get("unit") not in (None, "", "1", "-") else "--"
        bound = r" (at a bound)" if p.get("at_bound") is True else ""
        rows.append(rf"${symbol_latex(name)}$ & ${cells[0]}$ & ${cells[1]}$ & "
                    rf"$[{cells[2]}, {cells[3]}]$ & ${cells[4]}$ & {unit}{bound} \\")
        names.append(str(name))
    text = (r"\par\medskip\noindent\begin{tabular}{lrrrrl}\hline parameter & value & std.\ error & "
            rf"{pct}\,\% interval & start & unit \\ \hline " + " ".join(rows) + r" \hline\end{tabular}")
    corr = diag.get("correlation")
    if isinstance(corr, list) and len(corr) == len(names) and len(names) > 1 and all(
            isinstance(r, list) and len(r) == len(names) for r in corr):
        head = " & ".join(f"${symbol_latex(n)}$" for n in names)
        body = " ".join(
            f"${symbol_latex(n)}$ & " + " & ".join(
                f"${format_number(v, 3)}$" if isinstance(v, (int, float)) else "--" for v in r) + r" \\"
            for n, r in zip(names, corr))
        # beside the parameter table while both fit the line; below it for more parameters
        gap = r"\quad" if len(names) <= 3 else r"\par\medskip\noindent"
        text += (gap + r"\begin{tabular}{l" + "r" * len(names) + r"}\hline correlation & " + head
                 + r" \\ \hline " + body + r" \hline\end{tabular}")
    return text + _scores(diag) + r"\par\medskip"


def _scores(diag: Mapping[str, Any]) -> str:
    """RMSE (the output's unit) and fit % per output on the estimation and validation data (a
    LaTeX tabular; empty when the diagnostics hold none)."""
    found = diag.get("output_units")
    units: Mapping[str, Any] = found if isinstance(found, Mapping) else {}
    rows = []
    for part in ("estimation", "validation"):
        block = diag.get(part)
        if not isinstance(block, Mapping) or not isinstance(block.get("rmse"), Mapping):
            continue
        given = block.get("fit_percent")
        fits: Mapping[str, Any] = given if isinstance(given, Mapping) else {}
        for name, value in block["rmse"].items():
            fit = fits.get(name)
            unit = units.get(name)
            rows.append(rf"{part} & ${symbol_latex(name)}$ & "
                        + (f"${format_number(value)}$" if isinstance(value, (int, float)) else "--")
                        + " & " + (escape_latex(str(unit)) if unit not in (None, "", "1", "-") else "--")
                        + " & " + (f"${format_number(fit, 3)}$" if isinstance(fit, (int, float)) else "--")
                        + r" \\")
    if not rows:
        return ""
    return (r"\par\medskip\noindent\begin{tabular}{llrlr}\hline data & output & RMSE & unit & fit \% \\ "
            r"\hline " + " ".join(rows) + r" \hline\end{tabular}")


def fit_statement(diag: Mapping[str, Any]) -> Tex:
    """The problem ``fit`` solves, in mathematics, from the artefact's diagnostics.

    Parameters
    ----------
    diag : mapping
        The artefact's diagnostics.
    """
    mode = diag.get("mode", "simulation")
    experiments = (diag.get("estimation") or {}).get("experiments") if isinstance(
        diag.get("estimation"), Mapping) else None
    count = len(experiments) if isinstance(experiments, list) else None
    substeps = diag.get("substeps")
    level = diag.get("level", 0.95)
    pct = format_number(100 * float(level), 3) if isinstance(level, (int, float)) else "95"
    e_text = rf"$E = {count}$ logged experiment{'s' if count != 1 else ''}" if count else "the logged experiments"
    step = (rf"{int(substeps)} clipped RK4 steps per sample" if isinstance(substeps, int)
            else "the simulator's clipped RK4 steps")
    if mode == "prediction":
        cost = (r"the one-step-ahead prediction errors $y_k^{(e)} - \hat y_{k|k-1}^{(e)}(\theta)$ "
                r"of an extended Kalman filter on the model")
    else:
        cost = (r"the output (simulation) error $\sum_{e=1}^{E}\sum_{k} \big\| W \big(y_k^{(e)} - "
                r"h(x_k^{(e)}, \theta)\big)\big\|^2$ over the samples that count (present, not at a "
                r"sensor limit, or at a limit the model crosses)")
    return Tex(
        rf"Grey-box estimation of the free parameters $\theta$ (${_parameters(diag)}$) and of each "
        rf"experiment's initial state $x_0^{{(e)}}$ from {e_text}: minimise {cost}, subject to the "
        rf"sampled model $x_{{k+1}}^{{(e)}} = F_{{t_k}}(x_k^{{(e)}}, u_k^{{(e)}}, \theta)$ "
        rf"(the toolbox's simulator: {escape_latex(step)}, inputs held and saturated, levels "
        r"clipped), by multiple shooting with CasADi and IPOPT from several starts inside the box. "
        + _covariance_text(diag)
        + rf"; {pct}\,\% intervals (profile likelihood where the cost is not "
        r"quadratic in $\theta$). Fit \% $= 100\,(1 - \|y - \hat y\| / \|y - \bar y\|)$; validation "
        r"files are simulated from an initial state estimated on their first samples only."
        + _table(diag))
