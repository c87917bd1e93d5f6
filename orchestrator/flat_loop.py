"""The compiled master's run loop: the Python master's ``run`` and ``_loop`` in numba.

:func:`start` settles the inputs and records the first outputs; :func:`run_loop`
takes macro steps (snapshot, step, reject or accept, replay from the checkpoint,
locate, events, checks, recording) exactly as :meth:`.master.Master._loop` does,
and returns :data:`.flat_layout.DONE` at the end, :data:`.flat_layout.PAUSED`
after ``max_steps`` loop passes (the driver shows progress and resumes),
:data:`.flat_layout.NEED_ROOM` when the event buffer or a controller's history
buffer must grow, or
:data:`.flat_layout.FAILED` with the reason in ``S.info``.  Every variable of the
loop lives in ``S``, so a pause and a resume are seamless.
"""

from __future__ import annotations

import math

import numpy as np

from rubcosim.components.flat_controller import N_FOUND, make_room
from rubcosim.components.flat_rows import Y
from rubcosim.components.jit import njit

from .coupling_kernels import pi_accept, pi_reject
from .flat_events import (
    MAX_INDICATORS,
    event,
    first_crossing,
    indicators,
    learn_rates,
    locate,
    may_cross,
    overdue,
    value,
)
from .flat_layout import (
    CHECKPOINT_EVERY,
    DONE,
    EV_IMPACT,
    EVENTS_LOCATE,
    EVENTS_OFF,
    F_MAX_STEP,
    F_MIN_STEP,
    F_T_END,
    FAIL_NOT_FINITE,
    FAIL_STALL,
    FAIL_UNSTABLE,
    FAILED,
    FI_H,
    FI_TIME,
    FI_VALUE,
    I_ADAPTIVE,
    I_CONTROLLERS,
    I_EVENTS,
    I_ITERATIONS,
    I_PI_ORDER,
    MS_AT_FLOOR,
    MS_ERR_PREV,
    MS_H,
    MS_K_OUT,
    MS_N_EVENTS,
    MS_SAVED,
    MS_SINCE_CHECKPOINT,
    MS_SNAP_UNTIL,
    MS_STARTED,
    MS_TIME,
    N_ACCEPTED,
    N_LATE,
    N_REJECTED,
    N_REPLAYS,
    N_SNAPSHOTS,
    N_STEPS,
    NEED_ROOM,
    PAUSED,
    STALL_STEPS,
)
from .flat_round import fail, settle, step, unit_outputs

EVENT_ROOM = 16  # free event slots a loop pass needs


@njit
def controller_room(G, S):
    """Whether every controller's buffer has the rows a loop pass may write: a step and
    the left-limit steps of the events after it (each at most ``2 N_FOUND + 1`` rows),
    after moving the histories to the front if need be (the checkpoint has its copy)."""
    need = (2 * N_FOUND + 1) * (2 + G.pr_kind.shape[0])
    for k in range(G.kind.shape[0]):
        c = G.ctl[k]
        if c >= 0 and not make_room(S.ust[k, Y : Y + 3], S.cbuf[c], need):
            return False
    return True


@njit(inline="always")
def _set_time(G, S, t):
    S.ms[MS_TIME] = t
    for k in range(G.kind.shape[0]):
        if unit_outputs(G, S, k):
            return 1
    return 0


@njit(inline="always")
def _record_due(G, S):
    tol = 1e-9 * G.fset[F_MIN_STEP]
    k = int(S.ms[MS_K_OUT])
    while k < G.out_times.shape[0] and G.out_times[k] <= S.ms[MS_TIME] + tol:
        for i in range(G.rec_unit.shape[0]):
            S.rows[k, i] = S.out[G.rec_unit[i], G.rec_out[i]]
        k += 1
    S.ms[MS_K_OUT] = k


# inlined: a call of its own would carry another copy of _copy's code (numba links a
# callee's code into each caller and optimises it again there)
@njit(inline="always")
def _checkpoint(G, S):
    """Save what a replay restores: the units and the master's state (``_master_state``)."""
    S.cnt[N_SNAPSHOTS] += 1
    _copy(G, S, np.bool_(True))


@njit(inline="always")
def _replay(G, S):
    _copy(G, S, np.bool_(False))


@njit
def _copy(G, S, save):
    """Unit rows, outputs, histories, scales, acceleration bounds, protocol states,
    the master's saved scalars and the controllers' histories: into the checkpoint
    (``save``) or back from it."""
    pairs = ((S.ust, S.ck_ust), (S.out, S.ck_out), (S.hist, S.ck_hist), (S.acc, S.ck_acc),
             (S.prs, S.ck_prs))  # fmt: skip
    for live, kept in pairs:
        if save:
            kept[:] = live
        else:
            live[:] = kept
    if save:
        S.ck_scale[:] = S.scale
        S.ck_ms[:] = S.ms[:MS_SAVED]
    else:
        S.scale[:] = S.ck_scale
        S.ms[:MS_SAVED] = S.ck_ms
    if G.iset[I_CONTROLLERS]:
        _copy_histories(G, S, save)


@njit
def _copy_histories(G, S, save):
    """The controllers' histories into the checkpoint's buffers (``save``; each to the
    front, its bounds there 0, n) or back from them."""
    for k in range(G.kind.shape[0]):
        c = G.ctl[k]
        if c < 0:
            continue
        if save:
            a, b = int(S.ust[k, Y]), int(S.ust[k, Y + 1])
            S.ck_cbuf[c, : b - a] = S.cbuf[c, a:b]
            S.ck_ust[k, Y], S.ck_ust[k, Y + 1] = 0.0, float(b - a)
        else:
            n = int(S.ust[k, Y + 1])
            S.cbuf[c, :n] = S.ck_cbuf[c, :n]


@njit(inline="always")
def _accept(G, S, t, h, inds, n, bef):
    time = t + h
    S.ms[MS_TIME] = time
    for c in range(S.hist.shape[0]):
        hist = S.hist[c]
        m = int(hist[0])
        if m == 3:
            hist[1:5] = hist[3:7].copy()
            m = 2
        hist[1 + 2 * m] = time
        hist[2 + 2 * m] = S.real[c]
        hist[0] = m + 1
        S.scale[c] = max(S.scale[c], abs(S.real[c]))
    if h > 0.0:
        learn_rates(S, inds, n, bef, h)
    S.cnt[N_ACCEPTED] += 1


@njit(inline="always")
def _check_finite(G, S):
    for k in range(G.kind.shape[0]):
        for o in range(G.nout[k]):
            if not math.isfinite(S.out[k, o]):
                S.finfo[FI_VALUE] = S.out[k, o]
                return fail(S, FAIL_NOT_FINITE, k, o)
    for c in range(S.hist.shape[0]):
        v = S.hist[c, 2 * int(S.hist[c, 0])]
        if abs(v) > G.bound[c]:
            S.finfo[FI_VALUE] = v
            return fail(S, FAIL_UNSTABLE, c, 0)
    return 0


@njit
def start(G, S):
    """Settle the inputs at the start time, start the histories and record."""
    for k in range(G.kind.shape[0]):
        if unit_outputs(G, S, k):
            return FAILED
    if settle(G, S, False, S.real):
        return FAILED
    for c in range(S.hist.shape[0]):
        S.hist[c, 0] = 1.0
        S.hist[c, 1] = S.ms[MS_TIME]
        S.hist[c, 2] = S.real[c]
        S.scale[c] = max(abs(S.real[c]), G.nominal[c])
    _record_due(G, S)
    return 0


@njit
def run_loop(G, S, max_steps):  # noqa: C901 - one loop, as the Python master's
    st_adaptive = G.iset[I_ADAPTIVE] != 0
    iterations = G.iset[I_ITERATIONS]
    events_mode = G.iset[I_EVENTS]
    min_step, max_step = G.fset[F_MIN_STEP], G.fset[F_MAX_STEP]
    t_end = G.fset[F_T_END]
    order = G.iset[I_PI_ORDER]
    controllers = G.iset[I_CONTROLLERS] > 0
    inds = np.zeros((MAX_INDICATORS, 6), dtype=np.int64)
    bef = np.zeros((MAX_INDICATORS, 2))
    if S.ms[MS_STARTED] == 0.0:
        _checkpoint(G, S)
        S.ms[MS_STARTED] = 1.0
        S.ms[MS_SNAP_UNTIL] = -math.inf
    passes = 0
    while S.ms[MS_TIME] < t_end:
        if passes >= max_steps:
            return PAUSED
        if S.ev_t.shape[0] - int(S.ms[MS_N_EVENTS]) < EVENT_ROOM:
            return NEED_ROOM
        if controllers and not controller_room(G, S):
            return NEED_ROOM
        passes += 1
        t = S.ms[MS_TIME]
        target = t_end
        k_out = int(S.ms[MS_K_OUT])
        if k_out < G.out_times.shape[0]:
            target = min(target, G.out_times[k_out])
        h_nominal = min(S.ms[MS_H], max_step)
        h = h_nominal
        if t + h >= target - 1e-9 * h:
            h = target - t
        n = indicators(G, S, inds)
        snap = False
        if st_adaptive or iterations > 1 or t < S.ms[MS_SNAP_UNTIL] or may_cross(S, inds, n, h):
            snap = True
            S.cnt[N_SNAPSHOTS] += 1
            S.snap[:] = S.ust
        elif S.ms[MS_SINCE_CHECKPOINT] >= CHECKPOINT_EVERY:
            _checkpoint(G, S)
            S.ms[MS_SINCE_CHECKPOINT] = 0.0
        for i in range(n):
            bef[i, 0], bef[i, 1] = value(S, inds[i])
        S.cnt[N_STEPS] += 1
        status, err = step(G, S, t, h)
        if status:
            if not snap or h <= min_step:
                S.finfo[FI_H] = h
                S.finfo[FI_TIME] = t
                return FAILED
            S.ust[:] = S.snap
            if _set_time(G, S, t):
                return FAILED
            S.cnt[N_REJECTED] += 1
            S.ms[MS_H] = h / 4.0
            continue
        if st_adaptive and err > 1.0 and h > min_step:
            S.ust[:] = S.snap
            if _set_time(G, S, t):
                return FAILED
            S.cnt[N_REJECTED] += 1
            S.ms[MS_H] = max(pi_reject(h, err, order), min_step)
            continue
        hit, lo, hi = first_crossing(S, inds, n, bef, h) if n else (-1, 0.0, 0.0)
        if hit >= 0 and not snap and events_mode == EVENTS_LOCATE:
            # an unannounced crossing: replay deterministically from the checkpoint
            _replay(G, S)
            S.ms[MS_SNAP_UNTIL] = t + h
            S.cnt[N_REPLAYS] += 1
            continue
        if hit >= 0 and events_mode == EVENTS_LOCATE:
            status, confirmed, h_cut = locate(G, S, inds[hit], bef[hit], t, h, lo, hi)
            if status:
                return FAILED
            if confirmed:
                h = h_cut
            else:  # an interior extremum that did not reach zero after all
                hit = -1
                S.ust[:] = S.snap
                status, _ = step(G, S, t, h)
                if status:
                    return FAILED
        elif hit >= 0 and not (lo == 0.0 and hi == h):
            hit = -1  # a plain master only sees sign changes at communication points
        _accept(G, S, t, h, inds, n, bef)
        if st_adaptive and hit < 0 and h >= 0.5 * h_nominal:
            h_next, S.ms[MS_ERR_PREV] = pi_accept(h_nominal, err, S.ms[MS_ERR_PREV], order)
            S.ms[MS_H] = min(max(h_next, min_step), max_step)
        # accepted only because the step could not shrink further
        at_floor = S.ms[MS_AT_FLOOR] + 1.0 if st_adaptive and err > 1.0 else 0.0
        S.ms[MS_AT_FLOOR] = at_floor
        if at_floor > STALL_STEPS:
            fail(S, FAIL_STALL, 0, 0)
            return FAILED
        S.ms[MS_SINCE_CHECKPOINT] += 1.0
        if hit >= 0 and event(G, S, inds[hit, 3], inds[hit, 5]):
            return FAILED
        if events_mode != EVENTS_OFF:
            for p in range(G.pr_kind.shape[0]):
                if overdue(G, S, p):
                    S.cnt[N_LATE] += 1
                    # np.int64: a literal argument would be a compiled version of its own
                    if event(G, S, np.int64(EV_IMPACT), p):
                        return FAILED
        if _check_finite(G, S):
            return FAILED
        _record_due(G, S)
    return DONE
