"""N-tank network generalising the quadruple-tank process (seed 003).

``N`` tanks (``N`` even): lower tanks ``1..N/2`` and upper tanks
``N/2+1..N``; upper tank ``N/2+i`` drains into lower tank ``i``. Pump ``i``
(input ``u_i``, V) splits its flow ``k_i u_i`` by a three-way valve: the
fraction ``gamma_i`` goes to lower tank ``i``, the rest to an upper tank of
the *next* pair (cyclically), which is what couples the network::

    A_i dh_i/dt = -a_i sqrt(2 g h_i) + a_{N/2+i} sqrt(2 g h_{N/2+i})
                  + gamma_i k_i u_i                            i = 1..N/2
    A_{N/2+1} dh_{N/2+1}/dt = -a_{N/2+1} sqrt(2 g h_{N/2+1})
                  + (1 - gamma_{N/2}) k_{N/2} u_{N/2}
    A_i dh_i/dt = -a_i sqrt(2 g h_i)
                  + (1 - gamma_j) k_j u_j,  j = i - N/2 - 1     i = N/2+2..N

For ``N = 4`` this is Johansson's quadruple-tank process (IEEE TCST 8(3),
2000): pump 1 feeds tanks 1 and 4, pump 2 feeds tanks 2 and 3. Units: cm,
cm^2, cm^3/(V s), cm/s^2 (``g = 981``), V.

Parameter sets
--------------
``"decenter"``
    The DECENTER N-tank example: ``A_i`` 28/32 cm^2 (odd/even ``i``), lower
    outlets ``a_i`` 0.071/0.057 cm^2, upper outlets 0.040 cm^2, ``gamma_i``
    0.7/0.6, ``k_i = 3.33`` cm^3/(V s). Every tank measures its own level,
    ``y_i = h_i`` (cm).
``"johansson_min_phase"``, ``"johansson_nonmin_phase"``
    Johansson's P- and P+ parameters (``N = 4`` only), ``y = (kc h1, kc
    h2)`` in V with ``kc = 0.5`` V/cm.
"""

from __future__ import annotations

from typing import Any

import sympy as sp

from tanksynth.errors import SpecError
from tanksynth.plants.base import Assumption, Parameter, Plant, Quantity, Region

__all__ = ["tank_network", "PARAMETER_SETS", "JOHANSSON_OPERATING_POINTS"]

#: Parameter sets accepted by `tank_network`.
PARAMETER_SETS = ("decenter", "johansson_min_phase", "johansson_nonmin_phase")

#: Johansson (2000) operating points P- and P+ (levels in cm, pump voltages
#: in V), notes/plants.md section 3. State order ``(h1, h2, h3, h4)``.
JOHANSSON_OPERATING_POINTS: dict[str, dict[str, list[float]]] = {
    "johansson_min_phase": {"x": [12.4, 12.7, 1.8, 1.4], "u": [3.00, 3.00]},
    "johansson_nonmin_phase": {"x": [12.6, 13.0, 4.8, 4.9], "u": [3.15, 3.15]},
}

_USAT = 10.0        # V, pump command range [0, usat]
_G = 981.0          # cm/s^2
_KC = 0.5           # V/cm
_JOHANSSON = {
    # (k1, k2) cm^3/(V s), (gamma1, gamma2)
    "johansson_min_phase": {"k": (3.33, 3.35), "gamma": (0.70, 0.60)},
    "johansson_nonmin_phase": {"k": (3.14, 3.29), "gamma": (0.43, 0.34)},
}
_SOURCE = {
    "decenter": "seed 003 (DECENTER N-tank network example, Pedroso et al. 2021); parameter "
                "values of DECENTER's getConstantsNTankNetwork",
    "johansson_min_phase": "Johansson, IEEE TCST 8(3):456-465, 2000, P- (Tables 1-2)",
    "johansson_nonmin_phase": "Johansson, IEEE TCST 8(3):456-465, 2000, P+ (Tables 1-2)",
}


def _check_options(N: Any, parameter_set: Any) -> int:
    if parameter_set not in PARAMETER_SETS:
        raise SpecError(f"unknown parameter_set {parameter_set!r}; expected one of: "
                        + ", ".join(PARAMETER_SETS), key="plant.parameter_set")
    if isinstance(N, bool) or not isinstance(N, int):
        raise SpecError(f"N must be an even integer in [4, 256], got {type(N).__name__} {N!r}",
                        key="plant.N")
    if N % 2 or not 4 <= N <= 256:
        raise SpecError(f"N must be an even integer in [4, 256], got {N}", key="plant.N")
    if parameter_set != "decenter" and N != 4:
        raise SpecError(f"parameter_set {parameter_set!r} is the quadruple tank: N must be 4, "
                        f"got {N}", key="plant.N")
    return N


def _values(N: int, parameter_set: str) -> tuple[list[float], list[float], list[float], list[float]]:
    """Tank sections, outlet sections, valve fractions and pump gains."""
    half = N // 2
    A = [28.0 if i % 2 else 32.0 for i in range(1, N + 1)]
    if parameter_set == "decenter":
        a = [0.071 if i % 2 else 0.057 for i in range(1, half + 1)] + [0.040] * half
        gamma = [0.7 if i % 2 else 0.6 for i in range(1, half + 1)]
        k = [3.33] * half
    else:
        a = [0.071, 0.057, 0.071, 0.057]
        gamma = list(_JOHANSSON[parameter_set]["gamma"])
        k = list(_JOHANSSON[parameter_set]["k"])
    return A, a, gamma, k


def tank_network(N: int = 4, parameter_set: str = "decenter") -> Plant:
    """Build the N-tank network (quadruple tank for ``N = 4``).

    Parameters
    ----------
    N : int
        Number of tanks, even, ``4 <= N <= 256``; ``N/2`` pumps.
    parameter_set : {"decenter", "johansson_min_phase", "johansson_nonmin_phase"}
        Parameter values and output map. "decenter": tank sections A 28/32
        cm^2 (odd/even tank), outlets a 0.071/0.057 cm^2 (lower tanks) and
        0.040 cm^2 (upper tanks), valve fractions gamma 0.7/0.6, pump gains
        k 3.33 cm^3/(V s), every level measured (y = h, cm).
        "johansson_min_phase" (P-): A 28/32 cm^2, a 0.071/0.057 cm^2,
        gamma 0.70/0.60, k 3.33/3.35 cm^3/(V s); "johansson_nonmin_phase"
        (P+): gamma 0.43/0.34, k 3.14/3.29 cm^3/(V s); both measure
        y = kc (h1, h2) in V with kc = 0.5 V/cm and need N = 4.

    Returns
    -------
    Plant
        States ``h1..hN`` (cm), inputs ``u1..u{N/2}`` (V, range ``[0,
        usat]``), outputs ``y1..yN = h`` (cm, ``"decenter"``) or ``y1, y2 =
        kc (h1, h2)`` (V, Johansson sets). Parameters ``A1..AN``, ``a1..aN``
        (cm^2), ``gamma1..``, ``k1..`` (per pump), ``g``, ``kc``, ``usat``.

    Raises
    ------
    SpecError
        ``N`` not an even integer in [4, 256] (key ``plant.N``), a Johansson
        set with ``N != 4`` (key ``plant.N``) or an unknown parameter set
        (key ``plant.parameter_set``).
    """
    N = _check_options(N, parameter_set)
    half = N // 2
    A_v, a_v, gamma_v, k_v = _values(N, parameter_set)
    johansson = parameter_set != "decenter"

    params: list[Parameter] = []
    for i in range(1, N + 1):
        params.append(Parameter(f"A{i}", A_v[i - 1], "cm^2", f"cross-section of tank {i}",
                                lower=0, plausible=(1.0, 1e4)))
    for i in range(1, N + 1):
        where = "lower" if i <= half else "upper"
        params.append(Parameter(f"a{i}", a_v[i - 1], "cm^2",
                                f"outlet hole section of tank {i} ({where})", lower=0,
                                plausible=(1e-4, 10.0)))
    for j in range(1, half + 1):
        params.append(Parameter(f"gamma{j}", gamma_v[j - 1], "1",
                                f"fraction of pump {j} flow to lower tank {j}", lower=0, upper=1))
    for j in range(1, half + 1):
        params.append(Parameter(f"k{j}", k_v[j - 1], "cm^3/(V s)", f"gain of pump {j}", lower=0,
                                plausible=(0.01, 100.0)))
    params += [
        Parameter("g", _G, "cm/s^2", "gravity", lower=0, plausible=(970.0, 990.0)),
        Parameter("kc", _KC, "V/cm", "level sensor gain", lower=0),
        Parameter("usat", _USAT, "V", "pump command saturation", lower=0),
    ]
    p = {prm.name: prm.symbol for prm in params}
    h = [sp.Symbol(f"h{i}", real=True) for i in range(1, N + 1)]
    u = [sp.Symbol(f"u{j}", real=True) for j in range(1, half + 1)]
    g = p["g"]

    def outflow(i: int) -> sp.Expr:
        """Torricelli outflow of tank i (1-based), cm^3/s."""
        return p[f"a{i}"] * sp.sqrt(2 * g * h[i - 1])

    def pump(j: int, lower: bool) -> sp.Expr:
        frac = p[f"gamma{j}"] if lower else 1 - p[f"gamma{j}"]
        return frac * p[f"k{j}"] * u[j - 1]

    rows = []
    for i in range(1, half + 1):                      # lower tanks
        rows.append((-outflow(i) + outflow(half + i) + pump(i, True)) / p[f"A{i}"])
    rows.append((-outflow(half + 1) + pump(half, False)) / p[f"A{half + 1}"])
    for i in range(half + 2, N + 1):                  # remaining upper tanks
        rows.append((-outflow(i) + pump(i - half - 1, False)) / p[f"A{i}"])
    f = sp.Matrix(rows)

    outputs: tuple[Quantity, ...]
    if johansson:
        hmap = sp.Matrix([p["kc"] * h[0], p["kc"] * h[1]])
        outputs = (Quantity("y1", "V", "level sensor of tank 1, kc h1"),
                   Quantity("y2", "V", "level sensor of tank 2, kc h2"))
        hmax = 20.0
    else:
        hmap = sp.Matrix(h)
        outputs = tuple(Quantity(f"y{i}", "cm", f"measured level of tank {i}")
                        for i in range(1, N + 1))
        hmax = 40.0

    assumptions = [
        Assumption("Torricelli outflow with constant outlet sections; incompressible water; the "
                   "three-way valve fractions gamma_i are constant",
                   kind="modelling", source="seed 003 model equations"),
        Assumption(f"pump commands saturate to [0, usat] with usat = {_USAT:g} V: seed 003 names "
                   "u_sat but gives no value (DECENTER's N-tank control example uses 12 V); the "
                   "input bounds are fixed at build time and do not follow a usat override",
                   kind="omitted", source="seed 003"),
    ]
    if johansson:
        assumptions += [
            Assumption("operating region [0, 20] cm per tank: the quadruple-tank tanks are about "
                       "20 cm high", kind="modelling", source="Johansson 2000, Sec. 2 (laboratory process)"),
            Assumption("y = (kc h1, kc h2), kc = 0.5 V/cm: only the lower tanks are measured",
                       kind="modelling", source="Johansson 2000, Table 1"),
        ]
        if parameter_set == "johansson_nonmin_phase":
            assumptions.append(Assumption(
                "k2 = 3.29 cm^3/(V s) for P+; several public scripts print 3.19, a typo: with "
                "3.19 tanks 2 and 3 do not balance at the published P+ operating point",
                kind="modelling", source="Johansson 2000, Tables 1-2"))
    else:
        assumptions += [
            Assumption("parameter values are not printed in seed 003; taken from the DECENTER "
                       "example code (getConstantsNTankNetwork): A 28/32 cm^2, lower outlets "
                       "0.071/0.057 cm^2, upper outlets 0.040 cm^2, gamma 0.7/0.6, k = 3.33",
                       kind="omitted", source="DECENTER Examples/NTanksNetworkEstimationOSFH"),
            Assumption("each tank measures its own level, y_i = h_i in cm (C = I, R = I); "
                       "DECENTER's code scales the measurement by kc = 0.5 V/cm (C = kc I), which "
                       "only rescales R", kind="modelling", source="seed 003"),
            Assumption("operating region [0, 40] cm per tank: the DECENTER examples start at "
                       "20 cm and track lower-tank references up to 40 cm (30 +/- 10 cm), above "
                       "the 20 cm of Johansson's physical rig", kind="modelling",
                       source="DECENTER N-tank examples"),
        ]
    return Plant(
        name="tank_network",
        description=(f"{N}-tank network, {half} pumps, parameter set {parameter_set} (seed 003)"
                     if not johansson else
                     f"quadruple-tank process, {parameter_set.replace('_', ' ')} (seed 003, N = 4)"),
        states=tuple(Quantity(f"h{i}", "cm",
                              f"level of {'lower' if i <= half else 'upper'} tank {i}")
                     for i in range(1, N + 1)),
        inputs=tuple(Quantity(f"u{j}", "V", f"command of pump {j}") for j in range(1, half + 1)),
        outputs=outputs,
        parameters=tuple(params),
        f=f,
        h=hmap,
        region=Region(bounds=((0.0, hmax),) * N),
        input_bounds=((0.0, "usat"),) * half,
        assumptions=tuple(assumptions),
        source=_SOURCE[parameter_set],
        options=(("N", N), ("parameter_set", parameter_set)),
    )
