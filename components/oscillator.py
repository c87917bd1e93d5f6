"""Single-DOF impact oscillators (per unit mass, nondimensional as in the literature).

``x'' + b x' + a x + c3 x^3 = f cos(w t) + F_stop``.

Stops (``stop``):

* ``rigid_one_sided``: barrier at ``x = D``; Newton's law ``v+ = -R v-``.
* ``rigid_two_sided``: barriers at ``x = +D`` and ``x = -D`` (D > 0).
* ``elastic_one_sided`` / ``elastic_two_sided``: piecewise-linear stops,
  ``F_stop = -k_s (x - D)`` beyond ``+D`` (and ``-k_s (x + D)`` beyond ``-D``).
* ``none``: the free (Duffing) oscillator.

At a rigid stop the mass may stick (the paper's free flight -> sticking and
impact -> sticking switches): it stays on the barrier while the free
acceleration pushes it into the barrier.
"""

from __future__ import annotations

from . import trig
from .jit import njit
from .parameters import ParameterError, choice, nonnegative, positive, real

STOP_KINDS = (
    "none",
    "rigid_one_sided",
    "rigid_two_sided",
    "elastic_one_sided",
    "elastic_two_sided",
)

OSCILLATOR_PARAMS = (
    real("linear_stiffness", None, "1/s^2", "linear stiffness a (per unit mass)", example=1.0),
    nonnegative("damping", 0.0, "1/s", "viscous damping b (per unit mass)"),
    real("cubic_stiffness", 0.0, "1/(m^2 s^2)", "cubic stiffness (Duffing term)"),
    nonnegative("forcing_amplitude", 0.0, "m/s^2", "forcing amplitude f"),
    positive("forcing_frequency", None, "rad/s", "forcing frequency w", example=2.0),
    real("barrier", 1.0, "m", "barrier position D"),
    real("restitution", 0.8, "1", "Newton restitution R at a rigid stop", 0.0, 1.0),
    choice("stop", "rigid_one_sided", "kind of stop", STOP_KINDS),
    nonnegative("stop_stiffness", 0.0, "1/s^2", "stiffness of an elastic stop (per unit mass)"),
    real("x0", 0.0, "m", "initial displacement"),
    real("v0", 0.0, "m/s", "initial velocity"),
)

STOP_NONE = 0
STOP_RIGID_ONE = 1
STOP_RIGID_TWO = 2
STOP_ELASTIC_ONE = 3
STOP_ELASTIC_TWO = 4


@njit(inline="always")
def free_acceleration(
    t: float, x: float, v: float, a: float, b: float, c3: float, f: float, w: float
) -> float:
    """Acceleration without stop forces, m/s^2."""
    return f * trig.cos(w * t) - b * v - a * x - c3 * x * x * x


@njit(inline="always")
def elastic_stop_force(x: float, kind: int, barrier: float, ks: float) -> float:
    """Restoring force of a piecewise-linear stop, per unit mass."""
    if kind == STOP_ELASTIC_ONE or kind == STOP_ELASTIC_TWO:
        if x > barrier:
            return -ks * (x - barrier)
        if kind == STOP_ELASTIC_TWO and x < -barrier:
            return -ks * (x + barrier)
    return 0.0


@njit
def impact_velocity(v: float, restitution: float) -> float:
    """Newton's law at a rigid stop: v+ = -R v-."""
    return -restitution * v


@njit(inline="always")
def barrier_gap(x: float, barrier: float, side: int) -> float:
    """Distance (m) of the mass at x from the barrier on ``side`` (+1: the barrier at
    +D, -1: at -D), positive while clear: ``D - x`` or ``x + D``."""
    if side > 0:
        return barrier - x
    return x + barrier


@njit(inline="always")
def pressing(side: int, acc_at_rest: float) -> float:
    """How hard the mass resting on the barrier on ``side`` is pushed into it: its free
    acceleration there (m/s^2, with zero velocity) along the outward side.  The
    mass stays stuck while this is > 0 and is released when it falls through 0."""
    return side * acc_at_rest


@njit
def stop_impact(
    v: float, restitution: float, v_chat: float, side: int, acc_at_rest: float
) -> tuple[float, bool]:
    """Impact of the mass on the rigid barrier on ``side`` arriving at speed v (m/s).

    Newton's law ``v+ = -R v-``; a rebound slower than ``v_chat`` (m/s) ends a
    chattering sequence: the mass comes to rest on the barrier and sticks if
    it is pushed into it (:func:`pressing` of ``acc_at_rest``, the free
    acceleration at rest on the barrier now, m/s^2).  Returns ``(v+, stuck)``.
    """
    v_plus = impact_velocity(v, restitution)
    if abs(v_plus) >= v_chat:
        return v_plus, False
    return 0.0, pressing(side, acc_at_rest) > 0.0


def check_oscillator(params: dict, unit: str = "oscillator") -> None:
    """Checks across parameters: a two-sided stop needs D > 0, an elastic stop a
    stiffness, and the mass must not start beyond a rigid barrier."""
    stop, barrier = params["stop"], params["barrier"]
    two_sided = stop.endswith("two_sided")
    if two_sided and barrier <= 0.0:
        raise ParameterError(f"{unit}.barrier = {barrier!r} must be > 0 for a two-sided stop")
    if stop.startswith("elastic") and params["stop_stiffness"] <= 0.0:
        raise ParameterError(f"{unit}.stop_stiffness must be > 0 for an elastic stop")
    x0 = params["x0"]
    if stop.startswith("rigid") and (x0 > barrier or (two_sided and x0 < -barrier)):
        raise ParameterError(f"{unit}.x0 = {x0!r} starts beyond the rigid barrier")
