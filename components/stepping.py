"""Step a unit across one communication step: one compiled DOP853 driver for every unit.

:func:`advance` integrates a unit's state from ``t0`` to ``t_end``:

* an ODE unit (the rotors, the casing stator; ``kind`` of :mod:`.unit_odes`)
  with its inputs as polynomials over the step, no events;
* a hybrid unit (``kind = HYBRID + i``, hybrid type ``i`` of
  :mod:`.hybrid_dispatch`): its vector field in its current mode, its event
  functions checked after every accepted step, a crossing located on the
  step's dense output by the one event locator (:mod:`.root_finding`) and the
  type's event map applied there, so every impact and change of mode happens
  at its own time, whatever the communication step.

The Runge-Kutta step, error norm, controller and dense output are those of
:mod:`.dop853`, shared with the reference engines.  The step size to start
the next communication step with is returned, and the unit keeps it in its
state: no fresh initial-step guess each time, and a restored snapshot
re-steps bit-identically.
"""

from __future__ import annotations

import math

import numpy as np

from . import dop853 as rk
from . import hybrid_dispatch
from .hybrid_dispatch import KIND_IMPACT, N_EVENTS
from .jit import USE_NUMBA, njit
from .kernels import all_finite
from .root_finding import F_CUR, MAX_TRIALS, X_CUR, bracket, crossed_end
from .root_finding import advance as brent_advance
from .unit_odes import unit_rhs

HYBRID = 1000  # unit kinds from here on are hybrid unit types (kind - HYBRID)
NO_INPUTS = np.zeros((0, 3))  # the input rows of a hybrid unit (its inputs live in p)

OK = 0
STEP_TOO_SMALL = 1
NOT_FINITE = 2
TOO_MANY_EVENTS = 3
MAX_EVENTS_PER_STEP = 100_000


# Called, not inlined: a unit's step evaluates the right-hand side and the event
# functions from half a dozen places, and inlined each place held a copy of every unit
# type's (the hybrid types' dispatch is inlined into these two); no reference counting:
# they allocate nothing
@njit(borrows=True)
def _rhs(kind, t, y, mode, p, u, t0, dy):
    if kind >= HYBRID:
        hybrid_dispatch.hybrid_rhs(kind - HYBRID, t, y, mode, p, dy)
    else:
        unit_rhs(kind, t, y, p, u, t0, dy)


@njit(borrows=True)
def _events(kind, t, y, mode, p, g, dirs, rates):
    """Event functions of ``mode`` (slots without an event: g = 1, direction 0)."""
    for k in range(N_EVENTS):
        g[k] = 1.0
        dirs[k] = 0
        rates[k] = -1
    if kind >= HYBRID:
        hybrid_dispatch.hybrid_events(kind - HYBRID, t, y, mode, p, g, dirs, rates)


@njit
def _rk_step(kind, t, y, f, h, mode, p, u, t0, K, y_new, f_new, ytmp, dy):
    n = y.shape[0]
    for i in range(n):
        K[0, i] = f[i]
    for s in range(1, rk.N_STAGES):
        rk.stage_point(K, s, y, h, ytmp)
        _rhs(kind, t + rk.C[s] * h, ytmp, mode, p, u, t0, dy)
        for i in range(n):
            K[s, i] = dy[i]
    rk.solution_point(K, y, h, y_new)
    _rhs(kind, t + h, y_new, mode, p, u, t0, f_new)
    for i in range(n):
        K[rk.N_STAGES, i] = f_new[i]


@njit
def _crossing(direction, ga, gb):
    """Sign ``s`` that makes ``s * g`` fall through zero for a crossing of the event's
    ``direction`` between step ends ``ga``, ``gb`` (scipy's rule, touching counts);
    0 when there is none. Breakpoints (direction 2) are integrated through: a kink of
    the vector field without a jump, which the step-size control absorbs."""
    if direction == -1 and ga >= 0.0 and gb <= 0.0:
        return 1.0
    if direction == 1 and ga <= 0.0 and gb >= 0.0:
        return -1.0
    return 0.0


@njit
def _left_side(kind, k, sgn, t, h, y, F, mode, p, ybuf, g, dirs, rates):
    """``(t_s, sgn * g_k(t_s))`` for the latest of the points ``t + h / 2**i``
    (i = 52..1) with ``sgn * g_k > 0`` before the first one with ``sgn * g_k < 0``:
    the left end of the bracket of a rebound's return; ``(t, 0)`` if g does not
    leave the surface."""
    ts, fs = t, 0.0
    for i in range(52, 0, -1):
        tm = t + math.ldexp(h, -i)
        if tm <= ts:
            continue
        rk.dense_eval(t, h, y, F, tm, ybuf, ybuf.shape[0])
        _events(kind, tm, ybuf, mode, p, g, dirs, rates)
        if sgn * g[k] < 0.0:
            break
        if sgn * g[k] > 0.0:  # zero: within round-off of the surface, undecided
            ts, fs = tm, sgn * g[k]
    return ts, fs


@njit
def _first_event(kind, t, h, y, F, mode, p, g_a, dirs, g_b, ybuf, g, dirs_s, rates_s):
    """The earliest located event in the accepted step ``[t, t + h]``: ``(slot, time)``,
    slot -1 when no event function crossed."""
    slot, t_event = -1, t + h
    tol = 4.0 * np.finfo(np.float64).eps * max(abs(t), abs(t + h), 1.0)
    for k in range(N_EVENTS):
        sgn = _crossing(dirs[k], g_a[k], g_b[k])
        if sgn == 0.0:
            continue
        ta, fa = t, sgn * g_a[k]
        if fa == 0.0:
            # the step starts on the surface (just after an impact map): the crossing is
            # the return of a rebound shorter than the step, or, if it does not leave,
            # the start itself
            ta, fa = _left_side(kind, k, sgn, t, h, y, F, mode, p, ybuf, g, dirs_s, rates_s)
        if fa <= 0.0:
            te = ta
        else:
            s = bracket(ta, fa, t + h, sgn * g_b[k], tol)
            for _ in range(MAX_TRIALS):
                if brent_advance(s):
                    break
                rk.dense_eval(t, h, y, F, s[X_CUR], ybuf, ybuf.shape[0])
                _events(kind, s[X_CUR], ybuf, mode, p, g, dirs_s, rates_s)
                s[F_CUR] = sgn * g[k]
            te = crossed_end(s)
        if te < t_event or slot < 0:
            slot, t_event = k, te
    return slot, t_event


@njit
def advance(kind, t0, t_end, y, mode, h, p, u, rtol, atol):
    """Integrate unit ``kind`` from ``t0`` to ``t_end`` (s), updating ``y`` in place.

    ``mode`` is a hybrid unit's discrete mode (0 for an ODE unit), ``h`` the step to
    try first (<= 0: the whole span), ``p`` the kind's parameter array, ``u`` the
    input rows (value, d1, d2) at ``t0`` of an ODE unit.  Returns ``(h_next, mode,
    impacts, status)``: the step to try next, the mode at ``t_end``, the impacts
    applied, and :data:`OK`, :data:`STEP_TOO_SMALL`, :data:`NOT_FINITE` or
    :data:`TOO_MANY_EVENTS` (``y`` is then partly advanced; the caller restores it).
    """
    n = y.shape[0]
    K, F, f, f_new, y_new, ytmp, dy = rk.workspace(n)
    tol = np.full(n, atol)
    g_a, g_b, g = np.empty(N_EVENTS), np.empty(N_EVENTS), np.empty(N_EVENTS)
    dirs, dirs_b = np.empty(N_EVENTS, np.int64), np.empty(N_EVENTS, np.int64)
    rates = np.empty(N_EVENTS, np.int64)
    _rhs(kind, t0, y, mode, p, u, t0, f)
    _events(kind, t0, y, mode, p, g_a, dirs, rates)
    t = t0
    if h <= 0.0:
        h = t_end - t0
    rejected = False
    impacts = 0
    n_events = 0
    while t < t_end:
        if rk.below_min_step(h, t):
            return h, mode, impacts, STEP_TOO_SMALL
        t_new = t + h
        clipped = t_new >= t_end
        if clipped:
            t_new = t_end
        hs = t_new - t
        _rk_step(kind, t, y, f, hs, mode, p, u, t0, K, y_new, f_new, ytmp, dy)
        accepted, h_proposed = rk.next_step(rk.error_norm(K, hs, y, y_new, rtol, tol), hs, rejected)
        if not accepted:
            h = h_proposed
            rejected = True
            continue
        rejected = False
        if kind >= HYBRID:
            _events(kind, t_new, y_new, mode, p, g_b, dirs_b, rates)
            slot, t_event = -1, t_new
            for k in range(N_EVENTS):
                if _crossing(dirs[k], g_a[k], g_b[k]) != 0.0:
                    for s in range(rk.N_STAGES + 1, rk.N_EXT):
                        rk.stage_point(K, s, y, hs, ytmp)
                        _rhs(kind, t + rk.C[s] * hs, ytmp, mode, p, u, t0, dy)
                        for i in range(n):
                            K[s, i] = dy[i]
                    rk.dense_from_stages(hs, y, y_new, f_new, K, F)
                    slot, t_event = _first_event(
                        kind, t, hs, y, F, mode, p, g_a, dirs, g_b, ytmp, g, dirs_b, rates
                    )
                    break
            if slot >= 0:
                n_events += 1
                if n_events > MAX_EVENTS_PER_STEP:
                    return h_proposed, mode, impacts, TOO_MANY_EVENTS
                rk.dense_eval(t, hs, y, F, t_event, ytmp, n)
                for i in range(n):
                    y[i] = ytmp[i]
                t = t_event
                mode, event_kind = hybrid_dispatch.hybrid_apply(kind - HYBRID, slot, t, y, mode, p)
                if event_kind == KIND_IMPACT:
                    impacts += 1
                _rhs(kind, t, y, mode, p, u, t0, f)
                _events(kind, t, y, mode, p, g_a, dirs, rates)
                h = h_proposed
                continue
            for k in range(N_EVENTS):
                g_a[k] = g_b[k]
                dirs[k] = dirs_b[k]
        for i in range(n):
            y[i] = y_new[i]
            f[i] = f_new[i]
        t = t_new
        # a step cut short by the end of the span says nothing against the one proposed
        h = max(h_proposed, h) if clipped else h_proposed
    if not all_finite(y, n):
        return h, mode, impacts, NOT_FINITE
    return h, mode, impacts, OK


def _raise_on(status: int, t0: float, t_end: float) -> None:
    if status == STEP_TOO_SMALL:
        raise RuntimeError(f"step size below round-off between t = {t0} and {t_end}")
    if status == NOT_FINITE:
        raise RuntimeError(f"state not finite between t = {t0} and {t_end}")
    if status == TOO_MANY_EVENTS:
        raise RuntimeError(f"more than {MAX_EVENTS_PER_STEP} events between t = {t0} and {t_end}")


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
    """:func:`advance` of an ODE unit on a copy of ``y``; returns ``(y at t_end, h_next)``
    and raises ``RuntimeError`` naming the time when the integration fails.

    Without numba (inside an FMU by default) the same right-hand side goes to scipy's
    DOP853 instead: the element-wise loops of :func:`advance` are fast only compiled,
    and an ODE unit has no event to locate.
    """
    if not USE_NUMBA:
        return _scipy_step(kind, t0, t_end, y, h, p, u, rtol, atol)
    y_new = np.array(y, dtype=float)
    h_next, _, _, status = advance(kind, t0, t_end, y_new, 0, h, p, u, rtol, atol)
    _raise_on(status, t0, t_end)
    return y_new, float(h_next)


def step_hybrid(
    index: int,
    t0: float,
    t_end: float,
    y: np.ndarray,
    mode: int,
    h: float,
    p: np.ndarray,
    rtol: float,
    atol: float,
) -> tuple[np.ndarray, int, int, float]:
    """:func:`advance` of hybrid unit type ``index`` on a copy of ``y``; returns
    ``(y at t_end, mode, impacts applied, h_next)``, raising ``RuntimeError`` naming
    the time when the integration fails."""
    y_new = np.array(y, dtype=float)
    h_next, mode, impacts, status = advance(
        HYBRID + index, t0, t_end, y_new, mode, h, p, NO_INPUTS, rtol, atol
    )
    _raise_on(status, t0, t_end)
    return y_new, int(mode), int(impacts), float(h_next)


def _scipy_step(kind, t0, t_end, y, h, p, u, rtol, atol):
    from scipy.integrate import solve_ivp

    if t_end <= t0:
        return np.array(y, dtype=float), h
    dy = np.empty(len(y))

    def rhs(t: float, state: np.ndarray) -> np.ndarray:
        unit_rhs(kind, t, state, p, u, t0, dy)
        return dy.copy()

    first = min(h, t_end - t0) if h > 0.0 else None
    sol = solve_ivp(rhs, (t0, t_end), np.asarray(y, float), "DOP853", rtol=rtol, atol=atol,
                    first_step=first)  # fmt: skip
    if sol.status < 0:
        raise RuntimeError(f"integration failed at t = {sol.t[-1]}: {sol.message}")
    h_next = float(sol.t[-1] - sol.t[-2]) if sol.t.size > 1 else h
    return sol.y[:, -1].copy(), h_next
