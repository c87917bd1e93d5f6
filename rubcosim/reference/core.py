"""Engine pieces shared by the ``fast`` and ``accurate`` engines.

Both engines produce, for every accepted step, a DOP853 dense-output segment
``(t_old, h, y_old, F)`` (scipy's layout).  Everything that happens after a
step is taken lives here and is compiled once: evaluating the dense output,
the delay history, finding and locating events, recording outputs, the
breakpoints of the delay equation.

Event location follows Feng & Yang: quadratic (three-point) interpolation of
the event function, here inverse quadratic interpolation in Brent's safeguarded
form, so a bad interpolation step falls back to bisection of the bracket.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from .system import (
    CONTROL_NONE,
    FAMILY_ROTOR,
    IP_CONTROL,
    IP_FAMILY,
    KIND_IMPACT,
    N_DELAYED,
    N_EVENTS,
    P_EPS,
    P_NU,
    P_TAU0,
    P_TON,
    apply_event,
    current_delay,
    events,
    outputs,
    rhs,
)

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

# hmeta layout: start, count, capacity overflow flag
HM_START, HM_COUNT, HM_OVERFLOW = 0, 1, 2
# queue meta: start, count, dropped
Q_START, Q_COUNT, Q_DROPPED = 0, 1, 2


@nb.njit(cache=True, inline="always")
def dense_eval(t_old, h, y_old, F, t, out, ncomp):
    """Evaluate scipy's DOP853 dense output on the first ``ncomp`` components."""
    x = (t - t_old) / h
    npow = F.shape[0]
    for c in range(ncomp):
        acc = 0.0
        for i in range(npow):
            acc += F[npow - 1 - i, c]
            if i % 2 == 0:
                acc *= x
            else:
                acc *= 1.0 - x
        out[c] = acc + y_old[c]


# ---------------------------------------------------------------- history
def new_history(capacity: int, t_init: float, y_init: np.ndarray):
    """Ring buffer of dense segments of the delayed (disc) components."""
    return (
        np.zeros(capacity),  # t_old
        np.ones(capacity),  # h
        np.zeros(capacity),  # t_end (segment valid on [t_old, t_end])
        np.zeros((capacity, N_DELAYED)),  # y_old
        np.zeros((capacity, 7, N_DELAYED)),  # F
        np.zeros(3, dtype=np.int64),  # meta
        np.concatenate(([t_init], y_init[:N_DELAYED])),  # initial function: constant
    )


@nb.njit(cache=True)
def history_eval(hist, tq, out):
    """Delayed disc state at time ``tq`` (the initial state before the start)."""
    t0s, hs, tends, y0s, Fs, meta, init = hist
    start, count = meta[HM_START], meta[HM_COUNT]
    cap = t0s.shape[0]
    if count == 0 or tq <= init[0] or tq < t0s[start]:
        for c in range(N_DELAYED):
            out[c] = init[1 + c]
        return
    lo, hi = 0, count - 1
    # last segment whose start is <= tq: the later one wins at a jump
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if t0s[(start + mid) % cap] <= tq:
            lo = mid
        else:
            hi = mid - 1
    k = (start + lo) % cap
    dense_eval(t0s[k], hs[k], y0s[k], Fs[k], tq, out, N_DELAYED)


@nb.njit(cache=True)
def history_push(hist, t_old, h, t_end, y_old, F, keep_after):
    """Store a segment; drop segments that end before ``keep_after``."""
    t0s, hs, tends, y0s, Fs, meta, init = hist
    cap = t0s.shape[0]
    while meta[HM_COUNT] > 1 and tends[meta[HM_START]] < keep_after:
        meta[HM_START] = (meta[HM_START] + 1) % cap
        meta[HM_COUNT] -= 1
    if meta[HM_COUNT] == cap:
        meta[HM_OVERFLOW] = 1
        return
    k = (meta[HM_START] + meta[HM_COUNT]) % cap
    t0s[k] = t_old
    hs[k] = h
    tends[k] = t_end
    for c in range(N_DELAYED):
        y0s[k, c] = y_old[c]
        for i in range(F.shape[0]):
            Fs[k, i, c] = F[i, c]
    meta[HM_COUNT] += 1


@nb.njit(cache=True)
def uses_history(p, ip):
    return ip[IP_FAMILY] == FAMILY_ROTOR and ip[IP_CONTROL] != CONTROL_NONE


@nb.njit(cache=True, inline="always")
def delayed_state(t, p, ip, hist, yd):
    """Delayed disc state into ``yd``.  ``hist is None`` (no controller) compiles
    to nothing: the engines are specialised for systems without delay."""
    if hist is None:
        return
    if t >= p[P_TON]:
        history_eval(hist, t - current_delay(t, p), yd)
    else:
        for c in range(N_DELAYED):
            yd[c] = 0.0


@nb.njit(cache=True, inline="always")
def full_rhs(t, y, mode, p, ip, hist, yd, dy):
    """Right-hand side with the delayed state looked up in the history."""
    delayed_state(t, p, ip, hist, yd)
    rhs(t, y, yd, mode, p, ip, dy)


@nb.njit(cache=True)
def full_rhs_alloc(t, y, mode, p, ip, hist):
    dy = np.empty_like(y)
    yd = np.empty(N_DELAYED)
    full_rhs(t, y, mode, p, ip, hist, yd, dy)
    return dy


# ---------------------------------------------------------------- delay breakpoints
@nb.njit(cache=True)
def delayed_arrival(tj, p):
    """Time s > tj at which s - tau(s) = tj: a jump at tj reaches the delayed term."""
    s = tj + p[P_TAU0]
    if p[P_EPS] == 0.0:
        return s
    for _ in range(60):  # Newton on a function with derivative 1 - eps nu cos(nu s) > 0
        f = s - current_delay(s, p) - tj
        df = 1.0 - p[P_EPS] * p[P_NU] * math.cos(p[P_NU] * s)
        step = f / df
        s -= step
        if abs(step) <= 1e-15 * max(1.0, abs(s)):
            break
    return s


@nb.njit(cache=True)
def queue_push(queue, qmeta, value):
    cap = queue.shape[0]
    if qmeta[Q_COUNT] == cap:
        qmeta[Q_DROPPED] += 1
        return
    queue[(qmeta[Q_START] + qmeta[Q_COUNT]) % cap] = value
    qmeta[Q_COUNT] += 1


@nb.njit(cache=True)
def next_breakpoint(t, t_end, p, ip, queue, qmeta):
    """Next time the delay equation has a known nonsmooth point after t."""
    tb = t_end
    if not uses_history(p, ip):
        return tb
    eps_t = 4.0 * np.finfo(np.float64).eps * max(1.0, abs(t))
    if p[P_TON] > t + eps_t:
        tb = min(tb, p[P_TON])
    cap = queue.shape[0]
    while qmeta[Q_COUNT] > 0 and queue[qmeta[Q_START]] <= t + eps_t:
        qmeta[Q_START] = (qmeta[Q_START] + 1) % cap
        qmeta[Q_COUNT] -= 1
    if qmeta[Q_COUNT] > 0:
        tb = min(tb, queue[qmeta[Q_START]])
    return tb


# ---------------------------------------------------------------- events
@nb.njit(cache=True, inline="always")
def event_value(slot, t, seg, ctx, hist, scratch):
    """Event function ``slot`` at time t on the dense segment ``seg``.

    ``seg = (t_old, h, y_old, F)``; ``ctx = (mode, p, ip)``;
    ``scratch = (ybuf, yd, g, dirs, rates)``.  ``hist`` stays an argument of
    its own so that numba can compile away the delay when it is None.
    """
    t_old, h, y_old, F = seg
    mode, p, ip = ctx
    ybuf, yd, g, dirs, rates = scratch
    dense_eval(t_old, h, y_old, F, t, ybuf, ybuf.shape[0])
    delayed_state(t, p, ip, hist, yd)
    events(t, ybuf, yd, mode, p, ip, g, dirs, rates)
    return g[slot]


@nb.njit(cache=True)
def locate(slot, sgn, ta, fa, tb, fb, seg, ctx, hist, scratch):
    """Bracket [ta, tb] of a zero of ``sgn * g_slot`` (fa > 0 >= fb).

    Brent's method: inverse quadratic interpolation through three points,
    secant when only two are distinct, bisection when interpolation does not
    shrink the bracket fast enough.  Returns the end point on the crossed
    side (sgn * g <= 0), so the event is known to have happened there.
    """
    xtol = 4.0 * np.finfo(np.float64).eps * max(abs(ta), abs(tb), 1.0)
    xpre, xcur = ta, tb
    fpre, fcur = fa, fb
    xblk, fblk = xpre, fpre
    spre = scur = xcur - xpre
    for _ in range(200):
        if fpre != 0.0 and fcur != 0.0 and (fpre < 0.0) != (fcur < 0.0):
            xblk, fblk = xpre, fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = 0.5 * xtol
        sbis = 0.5 * (xblk - xcur)
        if fcur == 0.0 or abs(sbis) < delta:
            break
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):
                spre = scur
                scur = stry
            else:
                spre = scur = sbis
        else:
            spre = scur = sbis
        xpre, fpre = xcur, fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0.0 else -delta
        fcur = sgn * event_value(slot, xcur, seg, ctx, hist, scratch)
    if fcur <= 0.0:
        return xcur
    return xblk


@nb.njit(cache=True)
def pre_side(direction, side):
    """Sign of an event function before it fires: +1 for a falling event, -1
    for a rising one, the current side for a breakpoint; 0 if undetermined."""
    if direction == -1:
        return 1.0
    if direction == 1:
        return -1.0
    return float(side)


RETURN_LEVELS = 60  # first_return samples down to 2**-60 of the step: below round-off of t


@nb.njit(cache=True)
def first_return(k, j, sgn, t_a, t_b, rate_a, fb, seg, ctx, hist, scratch):
    """Bracket ``(left, right)`` of the first return of ``sgn * g_k`` through zero in a
    step that starts on the surface moving away (``rate_a = sgn * g_j(t_a) > 0``)
    and ends with the rate on the same side (``fb = sgn * g_k(t_b)``); ``(-1, -1)``
    if it does not come back.

    g rose, and turned an even number of times, if at all: it may have come back
    through zero (and even left again) inside the step, which neither end shows.
    A rebound much shorter than the step (chattering) is the usual case, so the
    rate is sampled at ``t_a + h / 2**i``, i = RETURN_LEVELS..0; its first turn
    (the top) starts the bracket, which ends at the first sample on the crossed
    side, or at the bottom of the return if g turns up again there.
    """
    h = t_b - t_a
    tp, rp = t_a, rate_a
    top = -1.0
    last = t_a  # latest point with sgn * g > 0 and no zero of it found before
    for i in range(RETURN_LEVELS, -1, -1):
        tm = t_b if i == 0 else t_a + math.ldexp(h, -i)
        if tm <= tp:
            continue
        rm = sgn * event_value(j, tm, seg, ctx, hist, scratch)
        if top < 0.0:
            if rm > 0.0:
                tp, rp = tm, rm
                continue
            top = locate(j, sgn, tp, rp, tm, rm, seg, ctx, hist, scratch)
            last = top
        if sgn * event_value(k, tm, seg, ctx, hist, scratch) <= 0.0:
            return last, tm
        if rm > 0.0:
            # turned up again before reaching zero? the bottom of the return decides
            fa = -rp if rp < 0.0 else 1e-300
            bottom = locate(j, -sgn, tp, fa, tm, -rm, seg, ctx, hist, scratch)
            if sgn * event_value(k, bottom, seg, ctx, hist, scratch) <= 0.0:
                return last, bottom
            last = bottom
            break
        last = tm
        tp, rp = tm, rm
    if fb <= 0.0:
        return last, t_b
    return -1.0, -1.0


@nb.njit(cache=True)
def find_event(t_a, t_b, seg, ctx, hist, scratch, g_a, side_a, dirs_a, rates_a, g_b):
    """Earliest event in (t_a, t_b] of the step's dense output, or (-1, t_b).

    ``side_a[k]`` is the side (+1/-1) of slot k at t_a, ``g_b`` the event
    functions at t_b.  A contact that opens and closes inside the step
    (grazing) is found through the rate companion: the extremum of g is
    located first and g is checked there.
    """
    best_k = -1
    best_t = t_b
    for k in range(N_EVENTS):
        if dirs_a[k] == 0:
            continue
        sgn = pre_side(dirs_a[k], side_a[k])
        if sgn == 0.0:
            continue
        left = t_a
        right = -1.0
        j = rates_a[k]
        # Starting on the surface (just after an event) and moving away?
        leaving = j >= 0 and sgn * g_a[k] <= 0.0 and sgn * g_a[j] > 0.0
        if leaving and sgn * g_b[j] >= 0.0:
            # The rate has not turned between the ends: a return through zero, if
            # any, lies between turns inside the step.  A bracket from t_a would let
            # the locator settle on the zero at t_a itself (the same event then
            # fires again at one instant), and g_b alone misses a return that has
            # left again by t_b.
            left, right = first_return(
                k, j, sgn, t_a, t_b, sgn * g_a[j], sgn * g_b[k], seg, ctx, hist, scratch
            )
        elif sgn * g_b[k] <= 0.0:
            right = t_b
            if leaving:
                # moving away, then back through zero: bracket from the extremum,
                # not from the start
                left = locate(j, sgn, t_a, sgn * g_a[j], t_b, sgn * g_b[j], seg, ctx, hist, scratch)
        elif j >= 0 and sgn * g_a[j] < 0.0 and sgn * g_b[j] > 0.0:
            # Approaching, then receding within the step: does it touch at the extremum?
            ts = locate(j, -sgn, t_a, -sgn * g_a[j], t_b, -sgn * g_b[j], seg, ctx, hist, scratch)
            if sgn * event_value(k, ts, seg, ctx, hist, scratch) <= 0.0:
                right = ts
        if right < 0.0 or right > best_t or (right == best_t and best_k >= 0):
            continue
        fl = sgn * event_value(k, left, seg, ctx, hist, scratch)
        fr = sgn * event_value(k, right, seg, ctx, hist, scratch)
        if fl <= 0.0:
            # Round-off at the start of a step just after an event: treat it as the pre side.
            fl = 1e-300
        if fr > 0.0:
            continue
        te = locate(k, sgn, left, fl, right, fr, seg, ctx, hist, scratch)
        if best_k < 0 or te < best_t:
            best_k = k
            best_t = te
    return best_k, best_t


@nb.njit(cache=True)
def event_candidate(g_a, side_a, dirs_a, rates_a, g_b):
    """Whether the step may hold an event: a sign change, or a rate companion
    that changes sign (a possible grazing contact).  Cheap; no dense output."""
    for k in range(N_EVENTS):
        if dirs_a[k] == 0:
            continue
        sgn = pre_side(dirs_a[k], side_a[k])
        if sgn == 0.0:
            continue
        if sgn * g_b[k] <= 0.0:
            return True
        j = rates_a[k]
        if j >= 0 and sgn * g_a[j] < 0.0 and sgn * g_b[j] > 0.0:
            return True
        if j >= 0 and sgn * g_a[k] <= 0.0 and sgn * g_a[j] > 0.0 and sgn * g_b[j] >= 0.0:
            # left the surface at the start: it may have come back inside the step
            return True
    return False


@nb.njit(cache=True)
def step_end_events(t, y, mode, p, ip, hist, yd, g_b, dirs_b, rates_b):
    """Event functions at the end of a step (same mode as at its start)."""
    delayed_state(t, p, ip, hist, yd)
    events(t, y, yd, mode, p, ip, g_b, dirs_b, rates_b)


@nb.njit(cache=True)
def start_sides(t, y, mode, p, ip, hist, g, dirs, rates, side, yd, forced_slot, forced_side):
    """Event functions at the start of a step and the side each one is on."""
    delayed_state(t, p, ip, hist, yd)
    events(t, y, yd, mode, p, ip, g, dirs, rates)
    for k in range(N_EVENTS):
        side[k] = 1 if g[k] > 0.0 else (-1 if g[k] < 0.0 else 0)
    if forced_slot >= 0:
        side[forced_slot] = forced_side
        # The step starts at this slot's event: its function is zero there (the
        # event map's projection onto the surface may leave a round-off residue).
        g[forced_slot] = 0.0


@nb.njit(cache=True)
def sides_from(g, side):
    for k in range(N_EVENTS):
        side[k] = 1 if g[k] > 0.0 else (-1 if g[k] < 0.0 else 0)


@nb.njit(cache=True)
def record(t_lo, t_hi, t_old, h, y_old, F, mode, p, ip, hist, t_eval, i_eval, rec, ybuf, yd, obuf):
    """Record outputs at the grid times in (t_lo, t_hi]; returns the next grid index."""
    n_out = rec.shape[1]
    while i_eval < t_eval.shape[0] and t_eval[i_eval] <= t_hi:
        te = t_eval[i_eval]
        if te > t_lo:
            dense_eval(t_old, h, y_old, F, te, ybuf, ybuf.shape[0])
            delayed_state(te, p, ip, hist, yd)
            outputs(te, ybuf, yd, mode, p, ip, obuf)
            for c in range(n_out):
                rec[i_eval, c] = obuf[c]
        i_eval += 1
    return i_eval


@nb.njit(cache=True)
def record_point(t, y, mode, p, ip, hist, t_eval, i_eval, rec, yd, obuf):
    """Record outputs at grid times <= t from the state y (used at the start)."""
    n_out = rec.shape[1]
    while i_eval < t_eval.shape[0] and t_eval[i_eval] <= t:
        delayed_state(t, p, ip, hist, yd)
        outputs(t, y, yd, mode, p, ip, obuf)
        for c in range(n_out):
            rec[i_eval, c] = obuf[c]
        i_eval += 1
    return i_eval


@nb.njit(cache=True)
def max_history_age(p, ip):
    """How far back the delay can reach, s."""
    if not uses_history(p, ip):
        return 0.0
    return p[P_TAU0] + p[P_EPS]


# ---------------------------------------------------------------- bookkeeping
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


@nb.njit(cache=True)
def needs_dense(t_b, hist, g_a, side, dirs, rates, g_b, t_eval, cnt):
    """Whether a step needs its dense output: delay history, outputs or a possible event."""
    if hist is not None:
        return True
    if cnt[C_EVAL] < t_eval.shape[0] and t_eval[cnt[C_EVAL]] <= t_b:
        return True
    return event_candidate(g_a, side, dirs, rates, g_b)


@nb.njit(cache=True)
def after_step(
    t_a,
    t_b,
    y_old,
    y_b,
    F,
    mode,
    p,
    ip,
    hist,
    queue,
    qmeta,
    g_a,
    side,
    dirs,
    rates,
    g_b,
    t_eval,
    rec,
    evlog,
    cnt,
    y_out,
    work,
):
    """Process an accepted step [t_a, t_b] with dense output F and the event
    functions ``g_b`` at t_b.

    Finds the earliest event, records outputs, extends the delay history and,
    on an event, applies it.  Returns ``(t_next, mode, forced_slot,
    forced_side)``; ``forced_slot >= 0`` means an event was applied at
    ``t_next`` and ``y_out`` holds the post-event state (else ``y_out = y_b``).
    """
    n = y_b.shape[0]
    h = t_b - t_a
    ybuf, yd, obuf, g, dtmp, rtmp = work
    seg = (t_a, h, y_old, F)
    k, te = find_event(
        t_a, t_b, seg, (mode, p, ip), hist, (ybuf, yd, g, dtmp, rtmp), g_a, side, dirs, rates, g_b
    )
    t_hi = te if k >= 0 else t_b
    cnt[C_EVAL] = record(
        t_a, t_hi, t_a, h, y_old, F, mode, p, ip, hist, t_eval, cnt[C_EVAL], rec, ybuf, yd, obuf
    )
    if hist is not None:
        history_push(hist, t_a, h, t_hi, y_old, F, t_hi - max_history_age(p, ip) - h)
    if k < 0:
        for i in range(n):
            y_out[i] = y_b[i]
        for i in range(N_EVENTS):
            g_a[i] = g_b[i]
        sides_from(g_b, side)
        return t_b, mode, -1, 0
    dense_eval(t_a, h, y_old, F, te, y_out, n)
    delayed_state(te, p, ip, hist, yd)
    new_mode, kind = apply_event(k, te, y_out, yd, mode, p, ip)
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
            queue_push(queue, qmeta, delayed_arrival(te, p))
    if te - t_a <= 4.0 * np.finfo(np.float64).eps * max(1.0, abs(te)):
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
