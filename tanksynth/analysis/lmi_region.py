"""LMI regions of the complex plane (Chilali-Gahinet): half-planes, disks, sectors, intersections."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np
import scipy.linalg as sla

from tanksynth.errors import SpecError
from tanksynth.spec.options import region_emptiness

__all__ = ["LMIRegion", "half_plane", "disk", "sector", "intersect", "region_from_parts", "variable_of",
           "check_region"]


@dataclass(frozen=True)
class LMIRegion:
    """An LMI region ``{z : L + M z + M' conj(z) < 0}`` (Chilali-Gahinet).

    Attributes
    ----------
    L : ndarray, shape (d, d)
        Real symmetric.
    M : ndarray, shape (d, d)
        Real.
    parts : tuple of tuple
        The elementary regions intersected, e.g. ``("disk", 0.0, 0.9)``,
        ``("half_plane", 0.5)``, ``("sector", theta)`` (units of the
        eigenvalues: 1/s in continuous time, none in discrete time).
    """

    L: np.ndarray
    M: np.ndarray
    parts: tuple[tuple, ...]

    @property
    def order(self) -> int:
        """Size ``d`` of the characteristic matrix."""
        return int(self.L.shape[0])

    def characteristic(self, z: complex) -> np.ndarray:
        """``f_D(z) = L + M z + M' conj(z)`` (Hermitian).

        Parameters
        ----------
        z : complex
            A point of the complex plane (1/s in continuous time, dimensionless in discrete time).
        """
        return self.L + self.M * z + self.M.T * np.conj(z)

    def margin(self, z: complex) -> float:
        """``-lambda_max(f_D(z))``: positive inside the region.

        Parameters
        ----------
        z : complex
            A point of the complex plane (1/s in continuous time, dimensionless in discrete time).
        """
        return float(-np.max(np.linalg.eigvalsh(self.characteristic(complex(z)))))

    def boundary_distance(self, z: complex) -> float:
        """Signed Euclidean distance from ``z`` to the region's boundary: positive inside (the
        distance to the nearest boundary point), negative outside (minus the distance to the
        nearest elementary region's boundary violated, a lower bound on the true distance).

        Unlike `margin` (``-lambda_max f_D(z)``, scaled by the region's matrices: twice the distance
        for a half-plane), this is in the units of ``z``.

        Parameters
        ----------
        z : complex
            A point of the complex plane (1/s in continuous time, dimensionless in discrete time).
        """
        z = complex(z)
        out = np.inf
        for part in self.parts:
            if part[0] == "half_plane":
                d = -float(part[1]) - z.real
            elif part[0] == "disk":
                d = float(part[2]) - abs(z - float(part[1]))
            else:   # sector |Im z| < tan(theta) (-Re z), apex 0, half-angle theta < pi/2
                s, c = np.sin(float(part[1])), np.cos(float(part[1]))
                d = min(-z.real * s - z.imag * c, -z.real * s + z.imag * c)
            out = min(out, float(d))
        return float(out)

    def contains(self, z: complex, margin: float = 0.0) -> bool:
        """True if ``z`` lies inside with ``-lambda_max(f_D(z)) > margin``.

        Parameters
        ----------
        z : complex
            A point of the complex plane (1/s in continuous time, dimensionless in discrete time).
        margin : float, optional
            Required margin (same unit as ``z``).
        """
        return self.margin(z) > margin

    def __and__(self, other: "LMIRegion") -> "LMIRegion":
        return intersect(self, other)

    def scaled(self, omega: float) -> "LMIRegion":
        """The region for eigenvalues divided by ``omega`` (time scaling).

        Parameters
        ----------
        omega : float
            Time scale (1/s), > 0.
        """
        return LMIRegion(self.L / omega, self.M, self.parts)

    def describe(self, variable: str = "z") -> str:
        """Human-readable description.

        Parameters
        ----------
        variable : str, optional
            The eigenvalue's letter: ``"s"`` for a continuous-time region (1/s),
            ``"z"`` (default) for a discrete-time one; `variable_of` gives it.
        """
        v = variable
        words = []
        for part in self.parts:
            if part[0] == "half_plane":
                words.append(f"Re {v} < {-part[1]:g}")
            elif part[0] == "disk":
                c = float(part[1])
                centre = f"|{v}|" if c == 0 else (f"|{v} - {c:g}|" if c > 0 else f"|{v} + {-c:g}|")
                words.append(f"{centre} < {part[2]:g}")
            else:
                words.append(f"|arg(-{v})| < {np.degrees(part[1]):g} deg")
        return " and ".join(words)

    def emptiness(self) -> str:
        """Why the region is empty (its parts do not intersect), ``""`` when it is not.

        Exact: see `tanksynth.spec.options.region_real_interval`.
        """
        return region_emptiness(self.parts)

    def stable_in(self, domain: str) -> bool:
        """True if the region lies in the stability domain.

        Continuous time: a half-plane with ``alpha >= 0``, a disk with
        ``centre + radius <= 0`` or a sector with half-angle < 90 degrees is
        part of the intersection. Discrete time: a disk with ``|centre| +
        radius <= 1`` is.

        Parameters
        ----------
        domain : {"continuous", "discrete"}
            Time domain.
        """
        for part in self.parts:
            if domain == "continuous":
                if part[0] == "half_plane" and part[1] >= 0:
                    return True
                if part[0] == "disk" and part[1] + part[2] <= 0:
                    return True
                if part[0] == "sector" and part[1] < np.pi / 2:
                    return True
            elif part[0] == "disk" and abs(part[1]) + part[2] <= 1:
                return True
        return False

    def as_dict(self) -> dict:
        """JSON-friendly form."""
        return {"description": self.describe(), "parts": [list(p) for p in self.parts],
                "L": self.L.tolist(), "M": self.M.tolist()}



def _finite(value: Any, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SpecError(f"{name} must be a number, got {value!r}", key=name)
    value = float(value)
    if not np.isfinite(value):
        raise SpecError(f"{name} must be finite, got {value}", key=name)
    return value



def half_plane(alpha: float) -> LMIRegion:
    """Half-plane ``Re z < -alpha`` (decay rate ``alpha``).

    Parameters
    ----------
    alpha : float
        Minimum decay rate (1/s in continuous time); ``alpha >= 0`` makes the
        region stable in continuous time.

    Returns
    -------
    LMIRegion
        ``L = [2 alpha]``, ``M = [1]``.
    """
    alpha = _finite(alpha, "alpha")
    return LMIRegion(np.array([[2.0 * alpha]]), np.array([[1.0]]), (("half_plane", alpha),))



def disk(center: float, radius: float) -> LMIRegion:
    """Open disk ``|z - center| < radius`` (real centre).

    In discrete time ``disk(0, r)`` with ``r < 1`` bounds the spectral radius.

    Parameters
    ----------
    center : float
        Real centre (1/s in continuous time, dimensionless in discrete time).
    radius : float
        Radius (> 0, same unit).

    Returns
    -------
    LMIRegion
        ``L = [[-r, -c], [-c, -r]]``, ``M = [[0, 1], [0, 0]]``.
    """
    c = _finite(center, "center")
    r = _finite(radius, "radius")
    if not r > 0:
        raise SpecError(f"radius must be > 0, got {r}", key="radius")
    return LMIRegion(np.array([[-r, -c], [-c, -r]]), np.array([[0.0, 1.0], [0.0, 0.0]]),
                     (("disk", c, r),))



def sector(theta: float) -> LMIRegion:
    """Conic sector ``|Im z| < tan(theta) (-Re z)`` (apex 0).

    Bounds the damping ratio from below by ``cos(theta)``.

    Parameters
    ----------
    theta : float
        Half-angle about the negative real axis, rad, in ``(0, pi/2)``.

    Returns
    -------
    LMIRegion
    """
    th = _finite(theta, "theta")
    if not 0 < th < np.pi / 2:
        raise SpecError(f"sector half-angle must be in (0, pi/2) rad, got {th}", key="theta")
    s, c = np.sin(th), np.cos(th)
    return LMIRegion(np.zeros((2, 2)), np.array([[s, c], [-c, s]]), (("sector", th),))



def intersect(*regions: LMIRegion) -> LMIRegion:
    """Intersection of LMI regions (block-diagonal ``L``, ``M``).

    Parameters
    ----------
    *regions : LMIRegion
        At least one.

    Returns
    -------
    LMIRegion
    """
    if not regions:
        raise SpecError("intersect needs at least one region", key="region")
    return LMIRegion(sla.block_diag(*[r.L for r in regions]), sla.block_diag(*[r.M for r in regions]),
                     tuple(p for r in regions for p in r.parts))


def region_from_parts(parts: Sequence[tuple]) -> LMIRegion:
    """The intersection of elementary regions given as ``("half_plane", alpha)``,
    ``("disk", center, radius)`` or ``("sector", theta_rad)`` (as `tanksynth.spec.options.parse_region`
    returns them).

    Parameters
    ----------
    parts : sequence of tuple
        Elementary regions (``alpha`` and ``center``, ``radius`` in 1/s in continuous time; ``theta_rad`` in
        rad).

    Raises
    ------
    SpecError
        An empty list or an invalid elementary region.
    """
    builders: dict[str, Callable[..., LMIRegion]] = {"half_plane": half_plane, "disk": disk,
                                                     "sector": sector}
    regions = []
    for part in parts:
        if not part or part[0] not in builders:
            raise SpecError(f"unknown region part {part!r}; expected one of {list(builders)}")
        regions.append(builders[part[0]](*part[1:]))
    if not regions:
        raise SpecError("an LMI region needs at least one part")
    return intersect(*regions)


def variable_of(domain: str) -> str:
    """The letter of an eigenvalue in ``domain``: ``"s"`` (continuous) or ``"z"`` (discrete).

    Parameters
    ----------
    domain : {"continuous", "discrete"}
    """
    return "s" if domain == "continuous" else "z"


def check_region(region: LMIRegion, domain: str) -> None:
    """Refuse an empty region, or one outside the stability domain, before any solve.

    Parameters
    ----------
    region : LMIRegion
    domain : {"continuous", "discrete"}
        Time domain of the design (names the eigenvalue ``s`` or ``z`` in the message).

    Raises
    ------
    SpecError
        The region is empty (its parts do not intersect: no plant's closed loop can meet
        it), or lies outside the ``domain``-time stability domain.
    """
    empty = region.emptiness()
    if empty:
        raise SpecError(f"the region {region.describe(variable_of(domain))} is empty: {empty}", key="region")
    if not region.stable_in(domain):
        raise SpecError(f"region {region.describe(variable_of(domain))} is not inside the {domain}-time "
                        "stability domain (continuous: add a half-plane alpha >= 0, a disk left of 0 or a "
                        "sector; discrete: add a disk with |centre| + radius <= 1)", key="region")
