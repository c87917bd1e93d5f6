"""Integrate a unit's ODE across one communication step.

Units hold their inputs constant over a step, so the step is an ordinary
initial-value problem; scipy's DOP853 solves it.  The last internal step size
is returned so that the unit can keep it in its state: the next step starts
from it (no fresh initial-step guess each time) and a restored snapshot
re-steps bit-identically.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

Rhs = Callable[[float, np.ndarray], np.ndarray]
EventFunction = Callable[[float, np.ndarray], float]


@dataclass
class Segment:
    """Result of :func:`integrate`: where it stopped and why."""

    t: float
    y: np.ndarray
    h_next: float
    event: int  # index of the terminal event that stopped it, -1 if it reached t_end


def integrate(
    rhs: Rhs,
    t0: float,
    t_end: float,
    y0: np.ndarray,
    rtol: float,
    atol: float,
    h_first: float = 0.0,
    events: Sequence[EventFunction] = (),
) -> Segment:
    """Integrate from ``t0`` to ``t_end`` or to the first terminal event.

    ``events`` are scipy-style event functions; each must carry ``terminal``
    and ``direction`` attributes.  ``h_first <= 0`` lets the solver choose.
    """
    if t_end <= t0:
        return Segment(t0, np.array(y0, dtype=float), h_first, -1)
    span = t_end - t0
    first = min(h_first, span) if h_first > 0.0 else None
    sol = solve_ivp(
        rhs,
        (t0, t_end),
        np.asarray(y0, dtype=float),
        method="DOP853",
        rtol=rtol,
        atol=atol,
        first_step=first,
        events=list(events) or None,
    )
    if sol.status < 0:
        raise RuntimeError(f"integration failed at t = {sol.t[-1]}: {sol.message}")
    h_next = float(sol.t[-1] - sol.t[-2]) if sol.t.size > 1 else h_first
    if sol.status == 1:
        for k, times in enumerate(sol.t_events):
            if times.size:
                return Segment(float(times[0]), sol.y_events[k][0].copy(), h_next, k)
    return Segment(float(sol.t[-1]), sol.y[:, -1].copy(), h_next, -1)


def event(function: EventFunction, direction: float = 0.0) -> EventFunction:
    """Mark ``function`` as a terminal event with the given crossing direction."""
    function.terminal = True  # type: ignore[attr-defined]
    function.direction = direction  # type: ignore[attr-defined]
    return function
