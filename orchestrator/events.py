"""Event indicators, crossing detection over a step, and event location.

An indicator is a unit output whose zero crossing (in a given direction) is
an event, optionally with another output that is its exact time derivative
(the stator's ``gap_rate``).  With the derivative the master sees crossings
that happen and undo themselves inside a step (cubic Hermite interpolation).
A bracketed crossing is located by the engines' locator
(:mod:`rubcosim.components.root_finding`), the master re-running the step
onto each trial time.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from rubcosim.components.root_finding import (
    F_CUR,
    R_B,
    R_D,
    R_F,
    R_X,
    X_CUR,
    advance,
    advance_with_rates,
    bracket,
    bracket_with_rates,
    crossed_end,
)

from . import coupling_kernels as kernels


@dataclass(frozen=True)
class Indicator:
    """``unit.output`` crossing zero: ``direction`` -1 falling, +1 rising;
    ``rate`` names the output that is its time derivative, if any."""

    unit: str
    output: str
    direction: int
    kind: str
    rate: str | None = None


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
    found, lo, hi = kernels.crossing_bracket(ind.direction, ind.rate is not None, ga, gb, h, ra, rb)
    return (lo, hi) if found else None


def predicted_to_cross(
    ind: Indicator, g: float, rate: float, accel_bound: float, h: float, safety: float = 2.0
) -> bool:
    """Conservative test of whether the indicator could reach zero within ``h``,
    given its value, its rate and a bound on its second derivative."""
    return kernels.predicted_to_cross(ind.direction, g, rate, accel_bound, h, safety)


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
    its rate there.  The trial times come from the one locator
    (:mod:`rubcosim.components.root_finding`): cubic Hermite interpolation through
    values and rates when the indicator has a rate, the engines' three-point
    interpolation of values otherwise; always inside the bracket.  Returns the time
    on the far side of the crossing (the indicator has crossed, by at most the
    tolerance) and the number of probes.
    The system is left at the last probe, which the caller may need to redo.
    """
    sign = -1.0 if ind.direction < 0 else 1.0
    if ind.rate is not None and sign * gb >= 0.0 and rb != 0.0 and abs(gb / rb) <= t_tol:
        return tb, 0  # the end of the step is within the tolerance of the crossing
    # the locator's convention: positive before the event, <= 0 once it has happened
    trials = 0
    if ind.rate is not None:
        s = bracket_with_rates(ta, -sign * ga, -sign * ra, tb, -sign * gb, -sign * rb, t_tol)
        while trials < max_trials and not advance_with_rates(s):
            g, r = probe(float(s[R_X]))
            trials += 1
            s[R_F], s[R_D] = -sign * g, -sign * r
        return float(s[R_B]), trials
    s = bracket(ta, -sign * ga, tb, -sign * gb, t_tol)
    while trials < max_trials and not advance(s):
        g, _ = probe(float(s[X_CUR]))
        trials += 1
        s[F_CUR] = -sign * g
    return float(crossed_end(s)), trials
