"""The master's numerics as compiled kernels, shared by the Python and compiled masters.

Input polynomials through past coupling values (:mod:`.extrapolation`), the PI
step-size controller (:mod:`.step_control`), the Hermite crossing test and the
crossing prediction (:mod:`.events`): each written once here, called from the
Python master through those modules and inlined into the compiled master
(:mod:`.flat_master`), so both take the same decisions on the same numbers.
"""

from __future__ import annotations

import math

from rubcosim.components.jit import njit
from rubcosim.components.root_finding import hermite_critical_points, hermite_cubic

PI_SAFETY = 0.9
PI_MIN_FACTOR = 0.2
PI_MAX_FACTOR = 5.0
PI_ERR_START = 1e-4  # the controller's error memory after a (re)start


@njit
def polynomial3(n: int, t0: float, u0: float, t1: float, u1: float, t2: float, u2: float,
                t: float) -> tuple[float, float, float]:  # fmt: skip
    """Value, first and second derivative at ``t`` of the polynomial through the first
    ``n`` (1 to 3) of the points ``(t0, u0), (t1, u1), (t2, u2)``, oldest first."""
    if n == 1:
        return u0, 0.0, 0.0
    f01 = (u1 - u0) / (t1 - t0)
    if n == 2:
        return u0 + f01 * (t - t0), f01, 0.0
    f12 = (u2 - u1) / (t2 - t1)
    f012 = (f12 - f01) / (t2 - t0)
    value = u0 + (t - t0) * (f01 + f012 * (t - t1))
    return value, f01 + f012 * (2.0 * t - t0 - t1), 2.0 * f012


@njit
def pi_accept(h: float, err: float, err_prev: float, order: int) -> tuple[float, float]:
    """PI control after an accepted step (Gustafsson; Hairer & Wanner IV.2): the next
    step ``h * safety * err^-a * err_prev^b`` (a = 0.7 / order, b = 0.4 / order), the
    change bounded to [0.2, 5]; returns it with the error to remember."""
    err = max(err, 1e-10)
    a, b = 0.7 / order, 0.4 / order
    factor = PI_SAFETY * err**-a * err_prev**b
    return h * min(PI_MAX_FACTOR, max(PI_MIN_FACTOR, factor)), err


@njit
def pi_reject(h: float, err: float, order: int) -> float:
    """A smaller step after a rejected one (no integral memory)."""
    factor = PI_SAFETY * err ** (-1.0 / order) if math.isfinite(err) else 0.0
    return h * min(0.9, max(PI_MIN_FACTOR, factor))


@njit
def hermite_extremum(ga: float, ra: float, gb: float, rb: float, h: float,
                     direction: int) -> tuple[bool, float, float]:  # fmt: skip
    """``(found, offset, value)`` of the interior extremum of the cubic Hermite
    interpolant (values ``ga, gb``, rates ``ra, rb`` over a step ``h``) that comes
    closest to crossing in ``direction`` (minimum for -1, maximum for +1)."""
    a, b, c = hermite_cubic(ga, ra, gb, rb, h)
    d = ga
    n, r0, r1 = hermite_critical_points(a, b, c)
    found, best_s, best_v = False, 0.0, 0.0
    for k in range(n):
        th = r0 if k == 0 else r1
        if 0.0 < th < 1.0:
            value = ((a * th + b) * th + c) * th + d
            if not found or direction * value > direction * best_v:
                found, best_s, best_v = True, th * h, value
    return found, best_s, best_v


@njit
def crossing_bracket(direction: int, has_rate: bool, ga: float, gb: float, h: float,
                     ra: float, rb: float) -> tuple[bool, float, float]:  # fmt: skip
    """``(found, lo, hi)``: offsets within a step of length ``h`` bracketing the first
    crossing of an indicator in ``direction`` (see :func:`.events.crossing`)."""
    sign = -1.0 if direction < 0 else 1.0
    before_a = sign * ga < 0.0
    if before_a and sign * gb >= 0.0:
        return True, 0.0, h
    if not has_rate:
        return False, 0.0, 0.0
    if before_a:
        found, s, v = hermite_extremum(ga, ra, gb, rb, h, direction)
        if found and sign * v >= 0.0:
            return True, 0.0, s
        return False, 0.0, 0.0
    if sign * ra < 0.0 and sign * gb >= 0.0:
        # starts on (or at) the crossed side moving back: back across and over again?
        found, s, v = hermite_extremum(ga, ra, gb, rb, h, -direction)
        if found and sign * v < 0.0:
            return True, s, h
    return False, 0.0, 0.0


@njit
def secant_offset(ga: float, gb: float, h: float) -> float:
    """Offset within a step of length ``h`` where the secant through ``ga`` at 0 and
    ``gb`` at ``h`` crosses zero (``h`` when they are equal): which crossing of a step
    comes first."""
    return h * ga / (ga - gb) if ga != gb else h


@njit
def predicted_to_cross(direction: int, g: float, rate: float, accel_bound: float, h: float,
                       safety: float = 2.0) -> bool:  # fmt: skip
    """Conservative test of whether an indicator could reach zero within ``h``, given
    its value, its rate and a bound on its second derivative."""
    sign = -1.0 if direction < 0 else 1.0
    if sign * g >= 0.0:
        return False
    reach = sign * rate * h * safety + 0.5 * accel_bound * (h * safety) ** 2
    return reach >= abs(g)
