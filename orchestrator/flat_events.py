"""Events in the compiled master: indicators, crossings, location and the protocols.

The compiled counterpart of :mod:`.event_steps` and :mod:`.protocols`: which
indicators the protocols watch, whether a step may cross one, which crossing
comes first, its location by re-running the step onto trial times (the one
locator, :mod:`rubcosim.components.root_finding`), and what an event does (a
rigid stator's protocol program, :mod:`rubcosim.components.rigid_protocol`, which
the Python master runs too; a penalty stator's onset and release are recorded).
An indicator is a row ``(unit, output, direction, kind, rate output or -1,
protocol)``.
"""

from __future__ import annotations

import math

import numpy as np

from rubcosim.components.contact_law import penalty_state
from rubcosim.components.jit import njit
from rubcosim.components.rigid_protocol import (
    ACT_DONE,
    ACT_SET_MODE,
    ST_MODE,
    next_action,
    start,
)
from rubcosim.components.rigid_protocol import overdue as rigid_overdue
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

from .coupling_kernels import PI_ERR_START, crossing_bracket, predicted_to_cross, secant_offset
from .flat_layout import (
    EVENTS_OFF,
    F_PERIOD,
    F_T_TOL,
    FAIL_EVENTS,
    I_CONTROLLERS,
    I_EVENTS,
    I_MAX_EVENTS,
    MS_ERR_PREV,
    MS_N_EVENTS,
    MS_RECENT,
    MS_TIME,
    N_EV0,
    N_EVENTS,
    N_PROBES,
    PENALTY_GAP,
    PF_MIN_FLIGHT,
    PF_V_CHAT,
    PR_RIGID,
    RESET_COUNTER_INPUT,
    RESET_VX_INPUT,
    RESET_VY_INPUT,
    RIGID_GAP,
    RIGID_GAP_RATE,
    RIGID_HOLD_FORCE,
    RIGID_HOLD_MARGIN,
    RIGID_MODE_INPUT,
    RIGID_NORMAL,
    RIGID_SLIP,
    RIGID_VX_PLUS,
    RIGID_VY_PLUS,
    WATCH,
)
from .flat_round import fail, set_input, settle, step, unit_step

MAX_INDICATORS = 8
LOCATE_TRIALS = 60


@njit(inline="always")  # called with literal ints: each call would be its own compile
def _add(inds, n, unit, output, direction, kind, rate, proto):
    inds[n, 0], inds[n, 1], inds[n, 2] = unit, output, direction
    inds[n, 3], inds[n, 4], inds[n, 5] = kind, rate, proto
    return n + 1


@njit(inline="always")
def indicators(G, S, inds):
    """Fill ``inds`` with the indicators the protocols watch now (the table
    ``WATCH``, from :data:`rubcosim.components.contact_law.WATCHED`); returns how many."""
    n = 0
    if G.iset[I_EVENTS] == EVENTS_OFF:
        return 0
    for p in range(G.pr_kind.shape[0]):
        s, kind = G.pr_stator[p], G.pr_kind[p]
        if kind == PR_RIGID:
            state = int(S.prs[p, ST_MODE])
        else:
            state = penalty_state(S.out[s, PENALTY_GAP])
        for j in range(WATCH.shape[2]):
            w = WATCH[kind, state, j]
            if w[0] < 0:
                break
            n = _add(inds, n, s, w[0], w[1], w[2], w[3], p)
    return n


@njit(inline="always")
def value(S, ind):
    g = S.out[ind[0], ind[1]]
    r = S.out[ind[0], ind[4]] if ind[4] >= 0 else 0.0
    return g, r


@njit(inline="always")
def may_cross(S, inds, n, h):
    for i in range(n):
        if inds[i, 4] < 0:
            return True  # no rate to predict from: always be ready to roll back
        g, r = value(S, inds[i])
        a = S.acc[inds[i, 0], inds[i, 1]]
        if math.isnan(a) or predicted_to_cross(inds[i, 2], g, r, a, h):
            return True
    return False


@njit(inline="always")
def learn_rates(S, inds, n, bef, h):
    """Running bound on the second derivative of every indicator that has a rate."""
    for i in range(n):
        if inds[i, 4] < 0:
            continue
        r1 = S.out[inds[i, 0], inds[i, 4]]
        a = S.acc[inds[i, 0], inds[i, 1]]
        S.acc[inds[i, 0], inds[i, 1]] = max(0.0 if math.isnan(a) else a, abs(r1 - bef[i, 1]) / h)


@njit(inline="always")
def first_crossing(S, inds, n, bef, h):
    """``(index, lo, hi)`` of the indicator whose crossing in the step comes first
    (index -1: none)."""
    best, best_est, best_lo, best_hi = -1, 0.0, 0.0, 0.0
    for i in range(n):
        ga, ra = bef[i, 0], bef[i, 1]
        gb, rb = value(S, inds[i])
        found, lo, hi = crossing_bracket(inds[i, 2], inds[i, 4] >= 0, ga, gb, h, ra, rb)
        if not found:
            continue
        est = lo if lo > 0.0 else secant_offset(ga, gb, hi)
        if best < 0 or est < best_est:
            best, best_est, best_lo, best_hi = i, est, lo, hi
    return best, best_lo, best_hi


@njit
def _probe(G, S, ind, t, tq, last):
    S.ust[:] = S.snap
    status, _ = step(G, S, t, tq - t)
    last[0] = tq
    S.cnt[N_PROBES] += 1
    g, r = value(S, ind)
    return status, g, r


@njit
def locate(G, S, ind, bef_i, t, h, lo, hi):
    """Cut the step at the first crossing (``_locate``): ``(status, confirmed, new h)``
    with the units at ``t + new h``; not confirmed when a predicted interior crossing
    is not there after all."""
    last = np.array([np.nan])
    sign = -1.0 if ind[2] < 0 else 1.0
    ga, ra = bef_i[0], bef_i[1]
    gb, rb = value(S, ind)
    if lo > 0.0:
        status, ga, ra = _probe(G, S, ind, t, t + lo, last)
        if status:
            return status, False, h
        if sign * ga >= 0.0:
            return 0, False, h
    if hi < h:
        status, gb, rb = _probe(G, S, ind, t, t + hi, last)
        if status:
            return status, False, h
        if sign * gb < 0.0:
            return 0, False, h
    ta, tb = t + lo, t + hi
    t_tol = G.fset[F_T_TOL]
    if ind[4] >= 0 and sign * gb >= 0.0 and rb != 0.0 and abs(gb / rb) <= t_tol:
        t_ev = tb  # the end of the step is within the tolerance of the crossing
    elif ind[4] >= 0:  # with its rate: Hermite interpolation (events.locate)
        s = bracket_with_rates(ta, -sign * ga, -sign * ra, tb, -sign * gb, -sign * rb, t_tol)
        trials = 0
        while trials < LOCATE_TRIALS and not advance_with_rates(s):
            status, g, r = _probe(G, S, ind, t, s[R_X], last)
            if status:
                return status, False, h
            trials += 1
            s[R_F] = -sign * g
            s[R_D] = -sign * r
        t_ev = s[R_B]
    else:
        s = bracket(ta, -sign * ga, tb, -sign * gb, t_tol)
        trials = 0
        while trials < LOCATE_TRIALS and not advance(s):
            status, g, _ = _probe(G, S, ind, t, s[X_CUR], last)
            if status:
                return status, False, h
            trials += 1
            s[F_CUR] = -sign * g
        t_ev = crossed_end(s)
    if last[0] != t_ev:
        status, _, _ = _probe(G, S, ind, t, t_ev, last)
        if status:
            return status, False, h
    return 0, True, t_ev - t


@njit
def _rigid_event(G, S, p, kind):
    """A rigid stator's event: run its protocol's program
    (:mod:`rubcosim.components.rigid_protocol`, as ``RigidContact.handle``), performing
    each action on the units; 1 on a failure."""
    s, r, st = G.pr_stator[p], G.pr_rotor[p], S.prs[p]
    start(st, kind)
    while True:
        action, arg = next_action(
            st, S.ms[MS_TIME], S.out[s, RIGID_GAP_RATE], S.out[s, RIGID_SLIP],
            S.out[s, RIGID_HOLD_MARGIN], S.out[s, RIGID_HOLD_FORCE], S.out[s, RIGID_NORMAL],
            G.pr_f[p, PF_V_CHAT], G.pr_f[p, PF_MIN_FLIGHT],
        )  # fmt: skip
        if action == ACT_DONE:
            return 0
        if action == ACT_SET_MODE:
            set_input(S, s, RIGID_MODE_INPUT, arg)
        else:
            set_input(S, r, RESET_VX_INPUT, S.out[s, RIGID_VX_PLUS])
            set_input(S, r, RESET_VY_INPUT, S.out[s, RIGID_VY_PLUS])
            set_input(S, r, RESET_COUNTER_INPUT, arg)
            if unit_step(G, S, r, S.ms[MS_TIME], 0.0):
                return 1
        if settle(G, S, False, S.scratch):
            return 1


@njit(inline="always")
def overdue(G, S, p):
    """A rigid impact the locator could not resolve (the disc inside the stator, still
    approaching), to be applied now: True (``RigidContact.overdue``)."""
    if G.pr_kind[p] != PR_RIGID:
        return False
    s = G.pr_stator[p]
    return rigid_overdue(S.prs[p], S.out[s, RIGID_GAP], S.out[s, RIGID_GAP_RATE])


@njit
def _left_limits(G, S):
    """Each controller records the left limit of its inputs (a zero-length step on the
    pre-event inputs): the jump the event makes stays a jump in its history.  Apart, so
    that a graph without controllers does not carry it."""
    for k in range(G.kind.shape[0]):
        if G.ctl[k] >= 0 and unit_step(G, S, k, S.ms[MS_TIME], 0.0):
            return 1
    return 0


@njit
def event(G, S, kind, p):
    """Handle an event of ``kind`` from protocol ``p`` (``_event``): the protocol acts,
    the event is recorded, the inputs settle and the extrapolation restarts."""
    if G.iset[I_CONTROLLERS] and _left_limits(G, S):
        return 1
    if G.pr_kind[p] == PR_RIGID and _rigid_event(G, S, p, kind):
        return 1
    n = int(S.ms[MS_N_EVENTS])
    time = S.ms[MS_TIME]
    S.ev_t[n] = time
    S.ev_kind[n] = kind
    S.ev_unit[n] = G.pr_stator[p]
    S.ms[MS_N_EVENTS] = n + 1
    S.cnt[N_EVENTS] += 1
    S.cnt[N_EV0 + kind] += 1
    if settle(G, S, False, S.scratch):
        return 1
    for c in range(S.hist.shape[0]):
        S.hist[c, 0] = 1.0
        S.hist[c, 1] = time
        S.hist[c, 2] = S.scratch[c]
    S.ms[MS_ERR_PREV] = PI_ERR_START
    first = int(S.ms[MS_RECENT])
    while first <= n and S.ev_t[first] < time - G.fset[F_PERIOD]:
        first += 1
    S.ms[MS_RECENT] = first
    if n + 1 - first > G.iset[I_MAX_EVENTS]:
        return fail(S, FAIL_EVENTS, G.pr_stator[p], 0)
    return 0
