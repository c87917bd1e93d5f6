"""Journal bearings: the Capone short-bearing oil film and a linear spring-damper.

Capone's model works in nondimensional variables: journal displacement over
the radial clearance ``cr`` and derivatives over ``tau = w t``.  The
dimensional force is ``sigma * f`` with
``sigma = mu_oil w R L (R/cr)^2 (L/(2R))^2`` (N).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from .jit import njit
from .parameters import nonnegative, positive

OILFILM_PARAMS = (
    positive("viscosity", None, "Pa s", "dynamic viscosity of the oil", example=0.02),
    positive("radius", None, "m", "journal radius R", example=0.03),
    positive("length", None, "m", "bearing length L", example=0.03),
    positive("clearance", None, "m", "radial clearance cr of the bearing", example=1.5e-4),
)

LINEAR_PARAMS = (
    positive("stiffness", None, "N/m", "bearing stiffness (isotropic)", example=1e7),
    nonnegative("damping", 0.0, "N s/m", "bearing damping (isotropic)"),
)


def oilfilm_sigma(viscosity: float, speed: float, radius: float, length: float, clearance: float):
    """Capone's force scale sigma = mu w R L (R/c)^2 (L/(2R))^2, N."""
    return (
        viscosity
        * speed
        * radius
        * length
        * (radius / clearance) ** 2
        * (length / (2.0 * radius)) ** 2
    )


@njit
def capone_force(x: float, y: float, xp: float, yp: float) -> tuple[float, float]:
    """Nondimensional Capone short-bearing force on the journal.

    ``x, y`` are displacements over the clearance, ``xp, yp`` their
    derivatives over ``tau = w t``.  Only defined inside the bearing
    (``x^2 + y^2 < 1``); at or beyond the wall NaN is returned so the caller
    reports the journal touching the bearing instead of going on silently.
    """
    q = 1.0 - x * x - y * y
    if q <= 0.0:
        return math.nan, math.nan
    a = x - 2.0 * yp
    b = y + 2.0 * xp
    rab = math.hypot(a, b)
    if rab == 0.0:
        # Pure half-speed whirl: no squeeze, no wedge, no pressure.
        return 0.0, 0.0
    alpha = math.atan2(-b, -a)
    ca, sa = math.cos(alpha), math.sin(alpha)
    sq = math.sqrt(q)
    u = y * ca - x * sa
    g = (2.0 / sq) * (0.5 * math.pi + math.atan(u / sq))
    v = (2.0 + u * g) / q
    w = x * ca + y * sa
    s = w / (1.0 - w * w)
    scale = rab / q
    return (
        -scale * (3.0 * x * v - sa * g - 2.0 * ca * s),
        -scale * (3.0 * y * v + ca * g - 2.0 * sa * s),
    )


@njit
def oilfilm_force(
    x: float,
    y: float,
    vx: float,
    vy: float,
    w: float,
    clearance: float,
    sigma: float,
) -> tuple[float, float]:
    """Dimensional oil-film force on the journal, N, from its state in SI units."""
    fx, fy = capone_force(x / clearance, y / clearance, vx / (w * clearance), vy / (w * clearance))
    return sigma * fx, sigma * fy


@njit
def linear_bearing_force(
    x: float, y: float, vx: float, vy: float, k: float, c: float
) -> tuple[float, float]:
    """Isotropic spring-damper bearing force on the journal, N."""
    return -k * x - c * vx, -k * y - c * vy


def film_scale(q: Mapping[str, Any]) -> float:
    """Capone's force scale sigma (N) of an oil-film bearing with parameters ``q`` (its
    ``speed`` the journal's spin, rad/s)."""
    return oilfilm_sigma(q["viscosity"], q["speed"], q["radius"], q["length"], q["clearance"])
