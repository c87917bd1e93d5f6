"""Jeffcott rotor: a single disc, or a journal + disc two-mass rotor.

Coordinates: disc centre (x, y) in m, spin speed ``w`` in rad/s in the x->y
sense, gravity (if any) along -y.  Equations of the single disc::

    m x'' + c x' + k x = m e w^2 cos(w t) + Fx
    m y'' + c y' + k y = m e w^2 sin(w t) - m g + Fy

The two-mass rotor has a journal (mass ``journal_mass``) that sits in the
bearing and a disc (mass ``mass``) that carries the unbalance and rubs; the
shaft (``stiffness``, ``shaft_damping``) connects them.
"""

from __future__ import annotations

import math

import numpy as np

from . import trig
from .jit import njit
from .parameters import nonnegative, planar_initial_state, positive

_STATE = planar_initial_state("", "disc")

JEFFCOTT_PARAMS = (
    positive("mass", None, "kg", "disc mass m", example=10.0),
    nonnegative("damping", 0.0, "N s/m", "viscous damping c of the disc to ground"),
    positive("stiffness", None, "N/m", "shaft stiffness k", example=1e6),
    nonnegative("eccentricity", 0.0, "m", "unbalance eccentricity e"),
    nonnegative("speed", None, "rad/s", "spin speed w (x->y sense)", example=379.473319),
    nonnegative("gravity", 0.0, "m/s^2", "gravitational acceleration g along -y"),
    nonnegative(
        "disc_radius", 0.0, "m", "radius Rd of the rubbing surface (slip speed v.t + Rd w)"
    ),
    *_STATE,
)

TWO_MASS_PARAMS = (
    *JEFFCOTT_PARAMS,
    positive("journal_mass", None, "kg", "journal mass in the bearing", example=2.0),
    nonnegative("journal_damping", 0.0, "N s/m", "viscous damping of the journal to ground"),
    nonnegative("shaft_damping", 0.0, "N s/m", "damping of the shaft between journal and disc"),
    *planar_initial_state("journal_", "journal"),
)


@njit(inline="always")
def unbalance_force(t: float, m: float, e: float, w: float) -> tuple[float, float]:
    """Rotating unbalance force on the disc, N: m e w^2 (cos wt, sin wt)."""
    a = m * e * w * w
    c, s = trig.cos_sin(w * t)
    return a * c, a * s


@njit(inline="always")
def jeffcott_force(
    t: float,
    x: float,
    y: float,
    vx: float,
    vy: float,
    m: float,
    c: float,
    k: float,
    e: float,
    w: float,
    g: float,
) -> tuple[float, float]:
    """All forces on a Jeffcott disc except contact and control, N."""
    ux, uy = unbalance_force(t, m, e, w)
    fy = uy - c * vy - k * y
    if g != 0.0:  # x - 0.0 is x: without gravity, one subtraction less on the stages' chain
        fy -= m * g
    return ux - c * vx - k * x, fy


@njit
def shaft_force(y: np.ndarray, i: int, j: int, k: float, cs: float) -> tuple[float, float]:
    """Force of the shaft on the disc, N (the journal feels the opposite); the disc's
    state (x, y, vx, vy) in ``y[i:i + 4]``, the journal's in ``y[j:j + 4]``."""
    return (
        -k * (y[i] - y[j]) - cs * (y[i + 2] - y[j + 2]),
        -k * (y[i + 1] - y[j + 1]) - cs * (y[i + 3] - y[j + 3]),
    )


@njit
def two_mass_disc_force(
    t: float, y: np.ndarray, i: int, j: int, m: float, c: float, k: float, cs: float,
    e: float, w: float, g: float,
) -> tuple[float, float]:  # fmt: skip
    """All forces on the disc of a two-mass rotor except contact and control, N:
    unbalance, damping to ground, gravity and the shaft to the journal (states as in
    :func:`shaft_force`)."""
    fx, fy = jeffcott_force(t, y[i], y[i + 1], y[i + 2], y[i + 3], m, c, 0.0, e, w, g)
    sx, sy = shaft_force(y, i, j, k, cs)
    return fx + sx, fy + sy


@njit
def journal_force(
    y: np.ndarray, i: int, j: int, k: float, cs: float, mj: float, cj: float, g: float
) -> tuple[float, float]:
    """All forces on the journal except the bearing's, N: the shaft (reaction of
    :func:`shaft_force`, states as there), damping to ground and gravity."""
    sx, sy = shaft_force(y, i, j, k, cs)
    return -sx - cj * y[j + 2], -sy - cj * y[j + 3] - mj * g


def free_whirl(mass: float, damping: float, stiffness: float, eccentricity: float, speed: float):
    """Steady unbalance whirl of a free Jeffcott disc: x = A cos(w t - phase).

    Returns ``(A, phase)`` with A in m and phase in rad (0 <= phase <= pi);
    A is infinite at undamped resonance.
    """
    wn = math.sqrt(stiffness / mass)
    s = speed / wn
    z = damping / (2.0 * mass * wn)
    den = math.hypot(1.0 - s * s, 2.0 * z * s)
    if den == 0.0:
        return math.inf, 0.5 * math.pi
    return eccentricity * s * s / den, math.atan2(2.0 * z * s, 1.0 - s * s)
