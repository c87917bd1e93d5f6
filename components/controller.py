"""Delayed-feedback controller: Pyragas and extended (ETDAS) feedback, fixed or variable delay.

``u(t) = K [(1 - R) sum_{k>=1} R^(k-1) z(t - k tau) - z(t)]`` on both axes,
where z is the disc displacement (``feedback = "position"``, K in N/m) or
velocity (``"velocity"``, K in N s/m) and R = ``memory`` in [0, 1) (R = 0 is
plain Pyragas feedback ``K [z(t - tau) - z(t)]``).  The sum is computed
recursively: the filter ``S(t) = (1 - R) z(t - tau) + R S(t - tau)`` runs
from the start of the run (the initial function is the constant initial
state, so S = z there) and ``u = K [S(t) - z(t)]``; only the force is gated by
``t_on``.  With a variable delay the recursion nests: ``t_1 = t - tau(t)``,
``S(t) = (1 - R) z(t_1) + R S(t_1)``.

The delay is ``tau(t) = tau0 + eps f(nu t)`` with a zero-mean modulation f,
|f| <= 1 (``modulation_shape``): ``sine`` sin(nu t); ``sawtooth`` a ramp from
-1 to 1 over each period 2 pi/nu, then a jump back; ``telegraph`` a random
sign held over each interval of length pi/nu (a random binary, or telegraph,
signal with seed ``modulation_seed``).  ``eps = 0`` or ``nu = 0`` gives the
fixed delay ``tau0 = delay`` if given (> 0), else ``delay_periods`` forcing
periods 2 pi/w.  On an orbit of period tau the force is zero: the controller
only acts while the motion departs from it.
"""

from __future__ import annotations

import math

from .jit import njit
from .parameters import Param, ParameterError, choice, nonnegative, real

MODULATION_SHAPES = ("sine", "sawtooth", "telegraph")
SHAPE_SINE, SHAPE_SAWTOOTH, SHAPE_TELEGRAPH = 0, 1, 2  # indices in MODULATION_SHAPES

CONTROLLER_PARAMS = (
    real("gain", None, "N/m", "feedback gain K (N s/m for velocity feedback)", example=1e5),
    nonnegative("delay", 0.0, "s", "delay tau0; 0 means delay_periods forcing periods"),
    Param("delay_periods", 1, "1", "delay in forcing periods when delay = 0", "int", 1.0, 1e6),
    real(
        "memory",
        0.0,
        "1",
        "ETDAS memory R: weight of older periods (0 = plain Pyragas feedback)",
        0.0,
        1.0,
        high_open=True,
    ),
    nonnegative("t_on", 0.0, "s", "time at which the control force is switched on"),
    choice("feedback", "position", "fed-back signal", ("position", "velocity")),
    nonnegative("modulation_amplitude", 0.0, "s", "delay modulation eps (variable delay)"),
    nonnegative("modulation_frequency", 0.0, "rad/s", "delay modulation frequency nu"),
    choice("modulation_shape", "sine", "zero-mean delay modulation f", MODULATION_SHAPES),
    Param("modulation_seed", 0, "1", "seed of the telegraph modulation's signs", "int", 0.0, 2e9),
)

_MASK31 = 2147483647
# A piecewise modulation's k-th piece starts at (k - PIECE_TOL) * width: a time
# computed as k * width (a breakpoint the engines step onto) is in piece k
# whatever its rounding.
PIECE_TOL = 1e-9


@njit
def telegraph_sign(k: int, seed: int) -> float:
    """The telegraph modulation's sign on its k-th interval: +1 or -1, each with
    probability 1/2, a fixed function of (seed, k) (a few rounds of a 31-bit
    multiplicative hash; every product fits in 63 bits)."""
    x = (k * 40503 + seed * 69069 + 12345) & _MASK31
    for _ in range(3):
        x = (x * 1103515245 + 12345) & _MASK31
        x ^= x >> 13
    return 1.0 if (x >> 17) & 1 else -1.0


@njit
def modulation(t: float, nu: float, shape: int, seed: int) -> float:
    """The zero-mean modulation f(nu t), |f| <= 1 (0 when nu = 0)."""
    if nu == 0.0:
        return 0.0
    if shape == SHAPE_SINE:
        return math.sin(nu * t)
    width = switch_interval(nu, shape)
    k = piece_index(t, width)
    if shape == SHAPE_SAWTOOTH:
        return 2.0 * (t / width - k) - 1.0
    return telegraph_sign(int(k), seed)


@njit
def switch_interval(nu: float, shape: int) -> float:
    """Time between the modulation's possible jumps, s (inf: a smooth modulation)."""
    if nu == 0.0 or shape == SHAPE_SINE:
        return math.inf
    if shape == SHAPE_SAWTOOTH:
        return 2.0 * math.pi / nu
    return math.pi / nu


@njit
def piece_index(t: float, width: float) -> float:
    """Index of the piece of a piecewise modulation (pieces ``width`` long) at ``t``."""
    return float(math.floor(t / width + PIECE_TOL))


@njit
def delay_at(t: float, tau0: float, eps: float, nu: float, shape: int, seed: int) -> float:
    """Delay tau(t) = tau0 + eps f(nu t), s."""
    if eps == 0.0:
        return tau0
    return tau0 + eps * modulation(t, nu, shape, seed)


@njit
def delayed_arrivals(
    tj: float, tau0: float, eps: float, nu: float, shape: int, seed: int, out
) -> int:
    """The times s at which ``s - tau(s) = tj`` (a jump of the signal at ``tj``
    reaches the delayed term), in increasing order, into ``out``; returns their
    number.  A sine modulation has one (``s - tau(s)`` increases); a sawtooth or
    telegraph one may have one per piece between its jumps (a telegraph switch
    that lengthens the delay sends the delayed time back: a jump arrives twice,
    or, when the delayed time jumps over ``tj``, at the switch itself, which is
    a breakpoint anyway).  ``out`` holds at least 4 (the parameter checks
    bound eps nu)."""
    s = tj + tau0
    if eps == 0.0 or nu == 0.0:
        out[0] = s
        return 1
    if shape == SHAPE_SINE:
        for _ in range(60):  # Newton on a function with derivative 1 - eps nu cos(nu s) > 0
            step = (s - delay_at(s, tau0, eps, nu, shape, seed) - tj) / (
                1.0 - eps * nu * math.cos(nu * s)
            )
            s -= step
            if abs(step) <= 1e-15 * max(1.0, abs(s)):
                break
        out[0] = s
        return 1
    width = switch_interval(nu, shape)
    lo, hi = tj + tau0 - eps, tj + tau0 + eps
    n = 0
    m = piece_index(lo, width)
    while (m - PIECE_TOL) * width <= hi and n < out.shape[0]:
        start, stop = (m - PIECE_TOL) * width, (m + 1.0 - PIECE_TOL) * width
        if shape == SHAPE_SAWTOOTH:
            # tau = tau0 + eps ((nu s - 2 pi m) / pi - 1) on the piece: linear in s
            root = (tj + tau0 - eps * (2.0 * m + 1.0)) / (1.0 - eps * nu / math.pi)
        else:
            root = tj + tau0 + eps * telegraph_sign(int(m), seed)
        if start <= root < stop:
            out[n] = root
            n += 1
        m += 1.0
    return n


@njit
def feedback_force(gain: float, now: float, delayed: float) -> float:
    """Delayed-feedback force on one axis: K (z_delayed - z), where z_delayed is
    z(t - tau) (Pyragas) or the ETDAS filter's (1 - R) z(t - tau) + R S(t - tau)."""
    return gain * (delayed - now)


@njit
def etdas_blend(memory: float, delayed: float, filtered: float) -> float:
    """The ETDAS filter's value from its delayed input and its own delayed value:
    ``(1 - R) z(t - tau) + R S(t - tau)``; exactly ``z(t - tau)`` when R = 0."""
    if memory == 0.0:
        return delayed
    return (1.0 - memory) * delayed + memory * filtered


def base_delay(
    params: dict, speed: float, unit: str = "controller", speed_name: str = "rotor.speed"
) -> float:
    """The delay tau0, s, from the controller's parameters and the rotor speed (rad/s).

    Also checks what no single parameter's range can: the modulation keeps the
    delay positive and the delayed time moving forward within each smooth
    piece of the modulation.
    """
    if speed <= 0.0 and params["delay"] <= 0.0:
        raise ParameterError(f"{unit}.delay_periods needs {speed_name} > 0 (or give {unit}.delay)")
    tau0 = params["delay"]
    if tau0 <= 0.0:  # 0: the delay is given in forcing periods
        tau0 = params["delay_periods"] * 2.0 * math.pi / speed
    eps, nu = params["modulation_amplitude"], params["modulation_frequency"]
    if eps >= tau0:
        raise ParameterError(f"{unit}.modulation_amplitude must be smaller than the delay")
    # the slope of eps f(nu t): eps nu (sine), eps nu / pi (sawtooth); the telegraph
    # signal is flat, but its switches must be farther apart than eps (at most a few
    # arrivals of one jump)
    bound = 1.0 if params.get("modulation_shape", "sine") == "sine" else math.pi
    if eps * nu >= bound:
        limit = "1" if bound == 1.0 else "pi"
        raise ParameterError(
            f"{unit}.modulation_amplitude * {unit}.modulation_frequency must be < {limit} "
            "(the delayed time must keep moving forward)"
        )
    return tau0
