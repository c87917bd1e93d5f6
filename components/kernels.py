"""Small kernels shared by every unit and by the reference engines.

* :func:`planar_newton`: Newton's law for a point body in the plane.
* :func:`polynomial_at`: an input given over a step as its value and first two
  time derivatives at the step's start (FMI 2.0 input derivatives), evaluated
  inside the step.
* :func:`all_finite`: whether a state is finite, without allocating.
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
    dy[i + 2] = fx / m
    dy[i + 3] = fy / m


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
