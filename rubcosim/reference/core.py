"""Engine pieces shared by the ``fast`` and ``accurate`` engines.

Both engines produce, for every accepted step, a DOP853 dense-output segment
``(t_old, h, y_old, F)`` (scipy's layout).  Everything that happens after a
step is taken is compiled once: :mod:`.history` (the delay history and its
breakpoints), :mod:`.event_search` (finding and locating events) and, here,
recording outputs, applying an event and the run's counters and status.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rubcosim.components.jit import njit

from .event_search import event_candidate, find_event, sides_from, time_round_off
from .history import (
    delayed_state,
    dense_eval,
    history_push,
    max_history_age,
    push_arrivals,
)
from .model_calls import apply_event, outputs
from .system import KIND_IMPACT, N_DELAYED, N_EVENTS

STATUS_OK = 0
STATUS_EVENT_LIMIT = 1
STATUS_STEP_TOO_SMALL = 2
STATUS_NONFINITE = 3
STATUS_HISTORY_OVERFLOW = 4
STATUS_EVENT_LOOP = 5
STATUS_MESSAGES = (
    "ok",
    "event limit reached (raise sim.max_events)",
    "step size fell below round-off: the state left the model's domain or the model is unstable",
    "the state became non-finite: the model is unstable or left its domain",
    "delay history overflow",
    "events keep firing at one instant: the event sequence does not advance",
)


@nb.njit(cache=True, inline="always")
def record_row(t, y, mode, p, model, hist, yd, obuf, rec, i):
    """Outputs at time t of the state y into row i of ``rec``."""
    delayed_state(t, p, model, hist, yd)
    outputs(t, y, yd, mode, p, model, obuf)
    for c in range(rec.shape[1]):
        rec[i, c] = obuf[c]


@njit(borrows=True)
def record(
    t_lo, t_hi, t_old, h, y_old, F, mode, p, model, hist, t_eval, i_eval, rec, ybuf, yd, obuf
):
    """Record outputs at the grid times in (t_lo, t_hi]; returns the next grid index."""
    while i_eval < t_eval.shape[0] and t_eval[i_eval] <= t_hi:
        te = t_eval[i_eval]
        if te > t_lo:
            dense_eval(t_old, h, y_old, F, te, ybuf, ybuf.shape[0])
            record_row(te, ybuf, mode, p, model, hist, yd, obuf, rec, i_eval)
        i_eval += 1
    return i_eval


@nb.njit(cache=True)
def record_point(t, y, mode, p, model, hist, t_eval, i_eval, rec, yd, obuf):
    """Record outputs at grid times <= t from the state y (used at the start)."""
    while i_eval < t_eval.shape[0] and t_eval[i_eval] <= t:
        record_row(t, y, mode, p, model, hist, yd, obuf, rec, i_eval)
        i_eval += 1
    return i_eval


# ---------------------------------------------------------------- bookkeeping
@nb.njit(cache=True)
def new_event_log(max_events: int, n_state: int):
    """Event log arrays: time, kind, slot, mode after, state after."""
    # np.empty: only the pages of events that happen are ever touched
    return (
        np.empty(max_events),
        np.empty(max_events, dtype=np.int64),
        np.empty(max_events, dtype=np.int64),
        np.empty(max_events, dtype=np.int64),
        np.empty((max_events, n_state)),
    )


@nb.njit(cache=True)
def new_event_state():
    """Event functions, sides, directions and rate slots at a step's start
    (``g_a, side, dirs, rates``) and end (``g_b, dirs_b, rates_b``)."""
    return (
        np.empty(N_EVENTS),
        np.zeros(N_EVENTS, dtype=np.int64),
        np.zeros(N_EVENTS, dtype=np.int64),
        np.zeros(N_EVENTS, dtype=np.int64),
        np.empty(N_EVENTS),
        np.zeros(N_EVENTS, dtype=np.int64),
        np.zeros(N_EVENTS, dtype=np.int64),
    )


@nb.njit(cache=True)
def new_workspace(n_state, n_outputs):
    """Scratch arrays for :func:`after_step`, allocated once per run."""
    return (
        np.empty(n_state),
        np.empty(N_DELAYED),
        np.empty(n_outputs),
        np.empty(N_EVENTS),
        np.empty(N_EVENTS, dtype=np.int64),
        np.empty(N_EVENTS, dtype=np.int64),
    )


# counters layout
C_STEPS, C_REJECTED, C_RHS, C_EVENTS, C_IMPACTS, C_STATUS, C_EVAL, C_RESTARTS, C_SAME_TIME = range(
    9
)
N_COUNTERS = 9
MAX_SAME_TIME_EVENTS = 64


@nb.njit(cache=True, inline="always")
def needs_dense(t_b, hist, g_a, side, dirs, rates, g_b, t_eval, cnt):
    """Whether a step needs its dense output: delay history, outputs or a possible event."""
    if hist is not None:
        return True
    if cnt[C_EVAL] < t_eval.shape[0] and t_eval[cnt[C_EVAL]] <= t_b:
        return True
    return event_candidate(g_a, side, dirs, rates, g_b)


# a call from the fast engine's loop, made only on a step that records or may hold an
# event: inlined into the loop (as it was until 2026-11-28) it cost 4.4 s of the
# engine's 23 s cold compile (benchmarks/profile_compile.py)
@njit(borrows=True)
def after_step(t_a, t_b, y_old, y_b, F, mode, p, model, hist, dde, ev, out, y_out, work):
    """Process an accepted step [t_a, t_b] with dense output F; ``ev = (g_a, side,
    dirs, rates, g_b)`` holds the event functions at t_a (with their sides,
    directions and rate slots) and at t_b; ``dde`` and ``out`` as for the engines'
    ``integrate``.

    Finds the earliest event, records outputs, extends the delay history and,
    on an event, applies it.  Returns ``(t_next, mode, forced_slot,
    forced_side)``; ``forced_slot >= 0`` means an event was applied at
    ``t_next`` and ``y_out`` holds the post-event state (else ``y_out = y_b``).
    """
    queue, qmeta = dde
    g_a, side, dirs, rates, g_b = ev
    t_eval, rec, evlog, cnt = out
    n = y_b.shape[0]
    h = t_b - t_a
    ybuf, yd, obuf, g, dtmp, rtmp = work
    seg = (t_a, h, y_old, F)
    k, te = find_event(
        t_a,
        t_b,
        seg,
        (mode, p, model),
        hist,
        (ybuf, yd, g, dtmp, rtmp),
        g_a,
        side,
        dirs,
        rates,
        g_b,
    )
    t_hi = te if k >= 0 else t_b
    if cnt[C_EVAL] < t_eval.shape[0] and t_eval[cnt[C_EVAL]] <= t_hi:  # else: no call
        cnt[C_EVAL] = record(
            t_a,
            t_hi,
            t_a,
            h,
            y_old,
            F,
            mode,
            p,
            model,
            hist,
            t_eval,
            cnt[C_EVAL],
            rec,
            ybuf,
            yd,
            obuf,
        )
    if hist is not None:
        history_push(hist, t_a, h, t_hi, y_old, F, t_hi - max_history_age(p, model) - h, p, model)
    if k < 0:
        for i in range(n):
            y_out[i] = y_b[i]
        for i in range(N_EVENTS):
            g_a[i] = g_b[i]
        sides_from(g_b, side)
        return t_b, mode, -1, 0
    dense_eval(t_a, h, y_old, F, te, y_out, n)
    delayed_state(te, p, model, hist, yd)
    new_mode, kind = apply_event(k, te, y_out, yd, mode, p, model)
    i_ev = cnt[C_EVENTS]
    ev_t, ev_kind, ev_slot, ev_mode, ev_y = evlog
    if i_ev < ev_t.shape[0]:
        ev_t[i_ev] = te
        ev_kind[i_ev] = kind
        ev_slot[i_ev] = k
        ev_mode[i_ev] = new_mode
        for i in range(n):
            ev_y[i_ev, i] = y_out[i]
    cnt[C_EVENTS] += 1
    if kind == KIND_IMPACT:
        cnt[C_IMPACTS] += 1
    if hist is not None:
        # an impact makes the disc state jump, any other event (contact on or off, a
        # slip or a stick) its derivative: the delayed term inherits the jump or kink
        # one delay later, and the ETDAS filter, fitted per step, must not straddle it
        push_arrivals(queue, qmeta, te, 1.0, p, model)
    if te - t_a <= time_round_off(te):
        cnt[C_SAME_TIME] += 1
    else:
        cnt[C_SAME_TIME] = 0
    if cnt[C_EVENTS] >= ev_t.shape[0]:
        cnt[C_STATUS] = STATUS_EVENT_LIMIT
    elif cnt[C_SAME_TIME] > MAX_SAME_TIME_EVENTS:
        cnt[C_STATUS] = STATUS_EVENT_LOOP
    if new_mode != mode:
        return te, new_mode, -1, 0
    d = dirs[k]
    if d == -1:
        return te, new_mode, k, 1
    if d == 1:
        return te, new_mode, k, -1
    return te, new_mode, k, -side[k]
