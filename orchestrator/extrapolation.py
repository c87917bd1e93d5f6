"""Input polynomials over a communication step, from the coupling values at past points.

A connected input is handed to its unit as a polynomial over the step
``[t, t + h]``: its value and first two derivatives at ``t``.  The polynomial
goes through the last ``order + 1`` accepted coupling values (extrapolation)
or, when the source has already been stepped (Gauss-Seidel) or the step is
being iterated, through the last ``order`` values and the end value
(interpolation).
"""

from __future__ import annotations

from collections.abc import Sequence

from rubcosim.components.kernels import polynomial_at

Point = tuple[float, float]  # (time, value)


def polynomial(points: Sequence[Point], t: float) -> tuple[float, float, float]:
    """Value, first and second derivative at ``t`` of the polynomial through 1 to 3 points."""
    n = len(points)
    if n == 0:
        raise ValueError("no coupling value to build an input polynomial from")
    if n == 1:
        return points[0][1], 0.0, 0.0
    (t0, u0), (t1, u1) = points[0], points[1]
    f01 = (u1 - u0) / (t1 - t0)
    if n == 2:
        return u0 + f01 * (t - t0), f01, 0.0
    t2, u2 = points[2]
    f12 = (u2 - u1) / (t2 - t1)
    f012 = (f12 - f01) / (t2 - t0)
    value = u0 + (t - t0) * (f01 + f012 * (t - t1))
    return value, f01 + f012 * (2.0 * t - t0 - t1), 2.0 * f012


def evaluate(value: float, d1: float, d2: float, s: float) -> float:
    """The polynomial given by its value and derivatives at the step start, ``s`` later."""
    return polynomial_at(value, d1, d2, s)
