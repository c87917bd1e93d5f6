"""Delayed-feedback (Pyragas) controller.

``u(t) = K [z(t - tau(t)) - z(t)]`` on both axes, where z is the disc
displacement (``feedback = "position"``, K in N/m) or velocity
(``"velocity"``, K in N s/m).  The delay is ``tau(t) = tau0 + eps sin(nu t)``
(zero-mean modulation; ``eps = 0`` gives the fixed Pyragas delay), with
``tau0 = delay`` if given, else ``delay_periods`` forcing periods 2 pi/w.
The control is off before ``t_on``.  On an orbit of period tau the force is
zero: the controller only acts while the motion departs from it.
"""

from __future__ import annotations

import math

from .jit import njit
from .parameters import Param, ParameterError, choice, nonnegative, real

CONTROLLER_PARAMS = (
    real("gain", None, "N/m", "feedback gain K (N s/m for velocity feedback)", example=1e5),
    real("delay", -1.0, "s", "delay tau0; negative means delay_periods forcing periods", -1.0),
    Param("delay_periods", 1, "1", "delay in forcing periods when delay < 0", "int", 1.0, 1e6),
    nonnegative("t_on", 0.0, "s", "time at which the control is switched on"),
    choice("feedback", "position", "fed-back signal", ("position", "velocity")),
    nonnegative("modulation_amplitude", 0.0, "s", "delay modulation eps (variable delay)"),
    nonnegative("modulation_frequency", 0.0, "rad/s", "delay modulation frequency nu"),
)


@njit
def delay_at(t: float, tau0: float, eps: float, nu: float) -> float:
    """Delay tau(t) = tau0 + eps sin(nu t), s."""
    return tau0 + eps * math.sin(nu * t)


@njit
def feedback_force(gain: float, now: float, delayed: float) -> float:
    """Pyragas force on one axis: K (z(t - tau) - z(t))."""
    return gain * (delayed - now)


def base_delay(
    params: dict, speed: float, unit: str = "controller", speed_name: str = "rotor.speed"
) -> float:
    """The delay tau0, s, from the controller's parameters and the rotor speed (rad/s).

    Also checks what no single parameter's range can: the delay is positive,
    the modulation keeps it positive and keeps the delayed time moving forward.
    """
    if speed <= 0.0 and params["delay"] < 0.0:
        raise ParameterError(f"{unit}.delay_periods needs {speed_name} > 0 (or give {unit}.delay)")
    tau0 = (
        params["delay"]
        if params["delay"] >= 0.0
        else params["delay_periods"] * 2.0 * math.pi / speed
    )
    if tau0 <= 0.0:
        raise ParameterError(f"{unit}.delay must be > 0")
    eps, nu = params["modulation_amplitude"], params["modulation_frequency"]
    if eps >= tau0:
        raise ParameterError(f"{unit}.modulation_amplitude must be smaller than the delay")
    if eps * nu >= 1.0:
        raise ParameterError(
            f"{unit}.modulation_amplitude * {unit}.modulation_frequency must be < 1 "
            "(the delayed time must keep moving forward)"
        )
    return tau0
