"""Small kernels shared by every unit and by the reference engines.

* :func:`planar_newton`: Newton's law for a point body in the plane.
* :func:`polynomial_at`: an input given over a step as its value and first two
  time derivatives at the step's start (FMI 2.0 input derivatives), evaluated
  inside the step.
* :func:`all_finite`: whether a state is finite, without allocating.
* :func:`hypot`: ``sqrt(x^2 + y^2)`` without overflow, within an ulp, compiled
  inline.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import USE_NUMBA, njit


@njit
def planar_newton(y: np.ndarray, i: int, fx: float, fy: float, m: float, dy: np.ndarray) -> None:
    """Write ``d/dt (x, y, vx, vy) = (vx, vy, fx/m, fy/m)`` for the body whose state
    (m, m/s) starts at index ``i`` of ``y`` into the same slots of ``dy``.

    ``fx, fy`` (N) is the total force on the body, ``m`` (kg) its mass.
    """
    dy[i] = y[i + 2]
    dy[i + 1] = y[i + 3]
    # Times the inverse, not divided: the acceleration is on the chain from one
    # Runge-Kutta stage to the next, where a division waits ~13 cycles and a product 4;
    # 1 / m does not depend on the state, so a compiled step loop computes it once.
    # (It rounds differently from fx / m, within an ulp.)
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


# hypot's scalings (glibc's e_hypot.c): inputs beyond these are scaled by SCALE first
_HYPOT_LARGE = 2.0**511
_HYPOT_TINY = 2.0**-511
_HYPOT_SCALE = 2.0**-600
_HYPOT_EPS = 2.0**-54


@njit(inline="always")
def _hypot_kernel(ax: float, ay: float) -> float:
    """``sqrt(ax^2 + ay^2)`` for ``ax >= ay > 0`` in range, with one correction step."""
    h = math.sqrt(ax * ax + ay * ay)
    if h <= 2.0 * ay:
        delta = h - ay
        t1 = ax * (2.0 * delta - ax)
        t2 = (delta - 2.0 * (ax - ay)) * delta
    else:
        delta = h - ax
        t1 = 2.0 * delta * (ax - 2.0 * ay)
        t2 = (4.0 * delta - ay) * ay + delta * delta
    return h - (t1 + t2) / (2.0 * h)


@njit(inline="always")
def _hypot_written_out(x: float, y: float) -> float:
    """``sqrt(x^2 + y^2)`` without overflow or underflow: glibc's algorithm (2.35,
    e_hypot.c, the build without fused multiply-add), the same result bit for bit as
    the ``math.hypot`` numba calls there.  Written out so that it compiles inline: the
    contact geometry evaluates it at every step and a dozen times per impact, where a
    libm call cost a rotor run 8 % of its time.  A bare ``sqrt(x*x + y*y)`` is cheaper
    still but differs in the last bit, and a co-simulation's communication points move
    with that bit.  Without numba (inside an FMU) :data:`hypot` is the interpreter's
    ``math.hypot`` instead: these lines interpreted cost 1.5 us a call against its
    60 ns (it may differ in the last bit, as it did before they were written out)."""
    if math.isinf(x) or math.isinf(y):
        return math.inf
    if math.isnan(x) or math.isnan(y):
        return x + y
    x = abs(x)
    y = abs(y)
    ax = y if x < y else x
    ay = x if x < y else y
    if ax > _HYPOT_LARGE:
        if ay <= ax * _HYPOT_EPS:
            return ax + ay
        return _hypot_kernel(ax * _HYPOT_SCALE, ay * _HYPOT_SCALE) / _HYPOT_SCALE
    if ay < _HYPOT_TINY:
        if ax >= ay / _HYPOT_EPS:
            return ax + ay
        return _hypot_kernel(ax / _HYPOT_SCALE, ay / _HYPOT_SCALE) * _HYPOT_SCALE
    if ay <= ax * _HYPOT_EPS:
        return ax + ay
    return _hypot_kernel(ax, ay)


hypot = _hypot_written_out if USE_NUMBA else math.hypot
