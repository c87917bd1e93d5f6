"""Integrate a unit's ODE across one communication step.

Two integrators, both DOP853:

* :func:`advance`, compiled: the ODE of a unit kind from :mod:`.unit_odes`
  with its inputs as polynomials over the step; no events.  This is what
  the rotors and the casing stator use (through :func:`step_ode`, which hands
  the same right-hand side to scipy where numba is not in use);
* :func:`integrate`, scipy's ``solve_ivp``: any Python right-hand side with
  terminal events (the single-DOF oscillator locates its impacts inside a
  step with it).

Both return the step size to start the next communication step with, which
the unit keeps in its state: no fresh initial-step guess each time, and a
restored snapshot re-steps bit-identically.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from .dop853 import N_STAGES, C, error_norm, next_step, solution_point, stage_point
from .jit import USE_NUMBA, njit
from .unit_odes import unit_rhs

Rhs = Callable[[float, np.ndarray], np.ndarray]
EventFunction = Callable[[float, np.ndarray], float]

OK = 0
STEP_TOO_SMALL = 1
NOT_FINITE = 2


@njit
def _rk_step(kind, t, y, f, h, p, u, t0, K, y_new, f_new, ytmp, dy):
    n = y.shape[0]
    for i in range(n):
        K[0, i] = f[i]
    for s in range(1, N_STAGES):
        stage_point(K, s, y, h, ytmp)
        unit_rhs(kind, t + C[s] * h, ytmp, p, u, t0, dy)
        for i in range(n):
            K[s, i] = dy[i]
    solution_point(K, y, h, y_new)
    unit_rhs(kind, t + h, y_new, p, u, t0, f_new)
    for i in range(n):
        K[N_STAGES, i] = f_new[i]


@njit
def advance(kind, t0, t_end, y, h, p, u, rtol, atol):
    """Integrate unit ``kind`` from ``t0`` to ``t_end`` (s), updating ``y`` in place.

    ``h`` is the step to try first (<= 0: the whole span), ``p`` the kind's
    parameter array, ``u`` the input rows (value, d1, d2) at ``t0``.  Returns
    ``(h_next, status)``: the step to try next, and :data:`OK`,
    :data:`STEP_TOO_SMALL` or :data:`NOT_FINITE` (``y`` is then partly advanced;
    the caller restores it).
    """
    n = y.shape[0]
    K = np.empty((N_STAGES + 1, n))
    f = np.empty(n)
    f_new = np.empty(n)
    y_new = np.empty(n)
    ytmp = np.empty(n)
    dy = np.empty(n)
    tol = np.full(n, atol)
    unit_rhs(kind, t0, y, p, u, t0, f)
    t = t0
    if h <= 0.0:
        h = t_end - t0
    rejected = False
    while t < t_end:
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        if h < min_step:
            return h, STEP_TOO_SMALL
        t_new = t + h
        clipped = t_new >= t_end
        if clipped:
            t_new = t_end
        hs = t_new - t
        _rk_step(kind, t, y, f, hs, p, u, t0, K, y_new, f_new, ytmp, dy)
        accepted, h_proposed = next_step(error_norm(K, hs, y, y_new, rtol, tol), hs, rejected)
        if not accepted:
            h = h_proposed
            rejected = True
            continue
        for i in range(n):
            y[i] = y_new[i]
            f[i] = f_new[i]
        t = t_new
        rejected = False
        # a step cut short by the end of the span says nothing against the one proposed
        h = max(h_proposed, h) if clipped else h_proposed
    for i in range(n):
        if not np.isfinite(y[i]):
            return h, NOT_FINITE
    return h, OK


def step_ode(
    kind: int,
    t0: float,
    t_end: float,
    y: np.ndarray,
    h: float,
    p: np.ndarray,
    u: np.ndarray,
    rtol: float,
    atol: float,
) -> tuple[np.ndarray, float]:
    """:func:`advance` on a copy of ``y``; returns ``(y at t_end, h_next)`` and raises
    ``RuntimeError`` naming the time when the integration fails.

    Without numba (inside an FMU by default) the same right-hand side goes to scipy's
    DOP853 instead: the element-wise loops of :func:`advance` are fast only compiled.
    """
    if not USE_NUMBA:
        dy = np.empty(len(y))

        def rhs(t: float, state: np.ndarray) -> np.ndarray:
            unit_rhs(kind, t, state, p, u, t0, dy)
            return dy.copy()

        seg = integrate(rhs, t0, t_end, y, rtol, atol, h)
        return seg.y, seg.h_next
    y_new = np.array(y, dtype=float)
    h_next, status = advance(kind, t0, t_end, y_new, h, p, u, rtol, atol)
    if status == STEP_TOO_SMALL:
        raise RuntimeError(f"step size below round-off between t = {t0} and {t_end}")
    if status == NOT_FINITE:
        raise RuntimeError(f"state not finite between t = {t0} and {t_end}")
    return y_new, float(h_next)


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
