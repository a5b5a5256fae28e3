"""Plant library: each built-in family builds a symbolic `Plant`.

========================  ==============================================
``three_tank``            DTS200 three-tank (seeds 000, 001)
``hybrid_three_tank``     hybrid three-tank with threshold pipes (seed 002)
``tank_network``          N-tank network / quadruple tank (seed 003)
``hydraulic_fault``       linear three-state hydraulic model (seed 004)
``custom``                a plant written in the spec as equations
========================  ==============================================
"""

from __future__ import annotations

from typing import Any, Callable

from tanksynth.plants.base import Assumption, HybridModes, Parameter, Plant, Quantity, Region, exact
from tanksynth.plants.custom import custom_plant
from tanksynth.plants.hybrid_three_tank import hybrid_three_tank
from tanksynth.plants.hydraulic_fault import hydraulic_fault
from tanksynth.plants.tank_network import tank_network
from tanksynth.plants.three_tank import three_tank

__all__ = [
    "Assumption", "HybridModes", "Parameter", "Plant", "Quantity", "Region", "exact",
    "three_tank", "hybrid_three_tank", "tank_network", "hydraulic_fault", "custom_plant",
    "BUILTIN_PLANTS", "builtin_plant",
]

#: Built-in plant families by spec name.
BUILTIN_PLANTS: dict[str, Callable[..., Plant]] = {
    "three_tank": three_tank,
    "hybrid_three_tank": hybrid_three_tank,
    "tank_network": tank_network,
    "hydraulic_fault": hydraulic_fault,
}


def builtin_plant(name: str, **options: Any) -> Plant:
    """Build a built-in plant family by its spec name.

    Parameters
    ----------
    name : str
        One of `BUILTIN_PLANTS`.
    **options
        Family options (e.g. ``N`` and ``parameter_set`` for ``tank_network``).
    """
    from tanksynth.errors import SpecError

    if name not in BUILTIN_PLANTS:
        raise SpecError(f"unknown plant model {name!r}; expected one of: "
                        + ", ".join([*BUILTIN_PLANTS, "custom"]), key="plant.model")
    return BUILTIN_PLANTS[name](**options)
