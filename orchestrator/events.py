"""Event indicators, crossing detection over a step, and event location.

An indicator is a unit output whose zero crossing (in a given direction) is
an event, optionally with another output that is its exact time derivative
(the stator's ``gap_rate``).  With the derivative the master sees crossings
that happen and undo themselves inside a step (cubic Hermite interpolation)
and locates them by Newton steps; without it, by inverse quadratic
interpolation through three points.  Every trial is safeguarded by the
bracket, and bisection takes over when a trial does not shrink it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Indicator:
    """``unit.output`` crossing zero: ``direction`` -1 falling, +1 rising;
    ``rate`` names the output that is its time derivative, if any."""

    unit: str
    output: str
    direction: int
    kind: str
    rate: str | None = None


def _hermite_cubic(ga: float, ra: float, gb: float, rb: float, h: float):
    """Coefficients (a, b, c, d) in theta = s/h of the cubic Hermite interpolant."""
    return (
        2.0 * (ga - gb) + h * (ra + rb),
        3.0 * (gb - ga) - h * (2.0 * ra + rb),
        h * ra,
        ga,
    )


def hermite_extremum(ga: float, ra: float, gb: float, rb: float, h: float, direction: int):
    """Time offset and value of the interior extremum of the Hermite cubic that comes
    closest to crossing in ``direction`` (minimum for -1, maximum for +1), or None."""
    a, b, c, d = _hermite_cubic(ga, ra, gb, rb, h)
    roots: list[float] = []
    if abs(a) > 1e-300:
        disc = b * b - 3.0 * a * c
        if disc >= 0.0:
            sq = math.sqrt(disc)
            roots = [(-b - sq) / (3.0 * a), (-b + sq) / (3.0 * a)]
    elif abs(b) > 1e-300:
        roots = [-c / (2.0 * b)]
    best = None
    for th in roots:
        if 0.0 < th < 1.0:
            value = ((a * th + b) * th + c) * th + d
            if best is None or direction * value > direction * best[1]:
                best = (th * h, value)
    return best


def crossing(
    ind: Indicator, ga: float, gb: float, h: float, ra: float = 0.0, rb: float = 0.0
) -> tuple[float, float] | None:
    """A bracket ``(lo, hi)`` of offsets within a step of length ``h`` around the first
    crossing of the indicator in its direction, or None.

    ``(0, h)`` for a sign change over the step.  With a rate, the Hermite
    interpolant also finds a crossing undone inside the step (``hi`` is then the
    interior extremum), and one that follows a start on the crossed side, as just
    after an impact (``lo`` is then the extremum on the other side).  An interior
    end of the bracket is a prediction the caller must confirm.
    """
    sign = -1.0 if ind.direction < 0 else 1.0
    before_a = sign * ga < 0.0
    if before_a and sign * gb >= 0.0:
        return 0.0, h
    if ind.rate is None:
        return None
    if before_a:
        ext = hermite_extremum(ga, ra, gb, rb, h, ind.direction)
        if ext is not None and sign * ext[1] >= 0.0:
            return 0.0, ext[0]
        return None
    if sign * ra < 0.0 and sign * gb >= 0.0:
        # starts on (or at) the crossed side moving back: back across and over again?
        ext = hermite_extremum(ga, ra, gb, rb, h, -ind.direction)
        if ext is not None and sign * ext[1] < 0.0:
            return ext[0], h
    return None


def predicted_to_cross(
    ind: Indicator, g: float, rate: float, accel_bound: float, h: float, safety: float = 2.0
) -> bool:
    """Conservative test of whether the indicator could reach zero within ``h``,
    given its value, its rate and a bound on its second derivative."""
    sign = -1.0 if ind.direction < 0 else 1.0
    if sign * g >= 0.0:
        return False
    reach = sign * rate * h * safety + 0.5 * accel_bound * (h * safety) ** 2
    return reach >= abs(g)


Probe = Callable[[float], tuple[float, float]]


def locate(
    probe: Probe,
    ind: Indicator,
    ta: float,
    ga: float,
    ra: float,
    tb: float,
    gb: float,
    rb: float,
    t_tol: float,
    max_trials: int = 60,
) -> tuple[float, int]:
    """Locate the crossing between ``ta`` (before) and ``tb`` (beyond) to ``t_tol``.

    ``probe(t)`` runs the coupled system onto ``t`` and returns the indicator and
    its rate there.  Returns the time on the far side of the crossing (the
    indicator has crossed, by at most the tolerance) and the number of probes.
    The system is left at the last probe, which the caller may need to redo.
    """
    sign = -1.0 if ind.direction < 0 else 1.0
    lo, g_lo, r_lo = ta, ga, ra
    hi, g_hi, r_hi = tb, gb, rb
    has_rate = ind.rate is not None
    pts = [(ta, ga), (tb, gb)]
    if has_rate and sign * g_hi >= 0.0 and r_hi != 0.0 and abs(g_hi / r_hi) <= t_tol:
        return hi, 0
    trials = stalls = 0
    guess = _first_guess(lo, g_lo, r_lo, hi, g_hi, r_hi, has_rate)
    while trials < max_trials and hi - lo > t_tol:
        width = hi - lo
        margin = 0.01 * width
        t = min(max(guess, lo + margin), hi - margin)
        g, r = probe(t)
        trials += 1
        pts.append((t, g))
        if sign * g >= 0.0:
            hi, g_hi, r_hi = t, g, r
        else:
            lo, g_lo, r_lo = t, g, r
        if has_rate and r != 0.0 and abs(g / r) <= t_tol and sign * g >= 0.0:
            break
        stalls = stalls + 1 if hi - lo > 0.5 * width else 0
        if stalls >= 2:
            guess, stalls = 0.5 * (lo + hi), 0
        else:
            guess = _next_guess(t, g, r, pts, has_rate, lo, hi, t_tol)
    return hi, trials


def _first_guess(lo, g_lo, r_lo, hi, g_hi, r_hi, has_rate) -> float:
    if has_rate:
        a, b, c, d = _hermite_cubic(g_lo, r_lo, g_hi, r_hi, hi - lo)
        # Newton on the cubic from the secant root
        th = g_lo / (g_lo - g_hi) if g_lo != g_hi else 0.5
        for _ in range(8):
            dp = (3.0 * a * th + 2.0 * b) * th + c
            if dp == 0.0:
                break
            th -= (((a * th + b) * th + c) * th + d) / dp
        if 0.0 < th < 1.0:
            return lo + th * (hi - lo)
    return lo + g_lo / (g_lo - g_hi) * (hi - lo) if g_lo != g_hi else 0.5 * (lo + hi)


def _next_guess(t, g, r, pts, has_rate, lo, hi, t_tol) -> float:
    if has_rate and r != 0.0:
        # Newton, aimed a little past the root (the crossed side is later in time) so
        # that the next probe closes the bracket
        guess = t - g / r + 0.5 * t_tol
        if lo < guess < hi:
            return guess
    (t0, g0), (t1, g1), (t2, g2) = pts[-3:]
    if g0 != g1 and g1 != g2 and g0 != g2:
        # inverse quadratic interpolation through the last three points
        guess = (
            t0 * g1 * g2 / ((g0 - g1) * (g0 - g2))
            + t1 * g0 * g2 / ((g1 - g0) * (g1 - g2))
            + t2 * g0 * g1 / ((g2 - g0) * (g2 - g1))
        )
        if lo < guess < hi:
            return guess
    return 0.5 * (lo + hi)
