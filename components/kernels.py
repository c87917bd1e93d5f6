"""Small kernels shared by every unit and by the reference engines.

* :func:`planar_newton`: Newton's law for a point body in the plane.
* :func:`polynomial_at`: an input given over a step as its value and first two
  time derivatives at the step's start (FMI 2.0 input derivatives), evaluated
  inside the step.
* :func:`all_finite`: whether a state is finite, without allocating.
* :func:`hypot`: ``sqrt(x^2 + y^2)`` without overflow, within 2 ulps, the same bits
  compiled and interpreted.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import njit


@njit
def planar_newton(y: np.ndarray, i: int, fx: float, fy: float, m: float, dy: np.ndarray) -> None:
    """Write ``d/dt (x, y, vx, vy) = (vx, vy, fx/m, fy/m)`` for the body whose state
    (m, m/s) starts at index ``i`` of ``y`` into the same slots of ``dy``.

    ``fx, fy`` (N) is the total force on the body, ``m`` (kg) its mass.
    """
    dy[i] = y[i + 2]
    dy[i + 1] = y[i + 3]
    # Times the inverse, not divided: 1 / m does not depend on the state, so a compiled
    # step loop computes it once (measured: a right-hand side 15.3-15.5 ns against
    # 15.6-16.0, a rotor run 2-3 % shorter).  It rounds differently from fx / m, within
    # an ulp.
    inv_m = 1.0 / m
    dy[i + 2] = fx * inv_m
    dy[i + 3] = fy * inv_m


@njit
def polynomial_at(value: float, d1: float, d2: float, s: float) -> float:
    """``value + s d1 + s^2 d2 / 2``: the polynomial with value and first and second
    derivatives ``value, d1, d2`` at the step's start, ``s`` seconds later."""
    return value + s * (d1 + 0.5 * s * d2)


@njit(inline="always")
def all_finite(y: np.ndarray, n: int) -> bool:
    """Whether the first ``n`` components of ``y`` are finite (a loop: ``np.isfinite``
    would allocate an array on every step)."""
    for i in range(n):  # noqa: SIM110 - numba compiles no generator in all()
        if not math.isfinite(y[i]):
            return False
    return True


# hypot's range: for a larger magnitude between these its square neither overflows nor
# underflows (what the smaller one's square loses to underflow lies far below the sum's
# last bit); outside it the inputs are scaled by a power of two
_HYPOT_LARGE = 2.0**500
_HYPOT_SMALL = 2.0**-500
_HYPOT_SCALE = 2.0**600


@njit(inline="always")
def hypot(x: float, y: float) -> float:
    """``sqrt(x^2 + y^2)`` without overflow or underflow, within 2 ulps of the exact value.

    One definition for both ways the kernels run: compiled (the reference engines, the
    units in a compiled co-simulation) and interpreted (inside an FMU).  Each is a
    product, a sum and a square root of IEEE doubles, each rounded once (numba does not
    fuse the multiply-add), so the two give the same result bit for bit on any
    platform, and a co-simulation's communication points, which move with the last
    bit of a contact distance, do not depend on which one ran.  (Before, the compiled
    form was glibc's ``hypot`` written out and the interpreted one CPython's own
    ``math.hypot``: they differed in the last bit for about 0.2 % of arguments.)

    It is also the cheap form, inlined into every evaluation of the contact geometry
    (29 in a period of the engine benchmark's rotor: at the steps' ends, the restarts,
    the locator's trials, the first-return scans): in alternated pairs of that benchmark,
    `fast`'s distance to its floor read 1.80-1.90x with it against 1.92-1.96x with the
    written-out libm algorithm (its correction step and scalings cost about 27 cycles).
    """
    ax = abs(x)
    ay = abs(y)
    m = ax if ax > ay else ay
    if _HYPOT_SMALL < m < _HYPOT_LARGE:  # the common case; false for NaN and inf
        return math.sqrt(x * x + y * y)
    if m == 0.0:
        return 0.0
    if math.isinf(x) or math.isinf(y):
        return math.inf  # even with a NaN in the other (C99)
    if m != m:
        return x + y  # NaN
    if m >= _HYPOT_LARGE:
        xs, ys = x / _HYPOT_SCALE, y / _HYPOT_SCALE
        return math.sqrt(xs * xs + ys * ys) * _HYPOT_SCALE
    xs, ys = x * _HYPOT_SCALE, y * _HYPOT_SCALE  # exact: a power of two
    return math.sqrt(xs * xs + ys * ys) / _HYPOT_SCALE
