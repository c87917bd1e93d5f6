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

from .coupling_kernels import polynomial3

Point = tuple[float, float]  # (time, value)


def polynomial(points: Sequence[Point], t: float) -> tuple[float, float, float]:
    """Value, first and second derivative at ``t`` of the polynomial through 1 to 3 points."""
    n = len(points)
    if n == 0:
        raise ValueError("no coupling value to build an input polynomial from")
    (t0, u0) = points[0]
    (t1, u1) = points[1] if n > 1 else (0.0, 0.0)
    (t2, u2) = points[2] if n > 2 else (0.0, 0.0)
    v, d1, d2 = polynomial3(n, t0, u0, t1, u1, t2, u2, t)
    return float(v), float(d1), float(d2)


def evaluate(value: float, d1: float, d2: float, s: float) -> float:
    """The polynomial given by its value and derivatives at the step start, ``s`` later."""
    return polynomial_at(value, d1, d2, s)
