"""The delay equation's memory: DOP853 dense segments, the history ring buffer and the
breakpoints a delayed jump creates.

The delayed-feedback controller feeds back the disc state of ``tau`` seconds
ago; the engines store the dense output of every step of the disc components
in a ring buffer and look the delayed state up there.  A jump of the state (an
impact) reaches the delayed term one delay later: that time is a breakpoint
where the engines restart their step.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from rubcosim.components.dop853 import dense_eval

from .system import (
    CONTROLLER_NONE,
    FAMILY_ROTOR,
    IP_CONTROLLER,
    IP_FAMILY,
    N_DELAYED,
    P_CONTROLLER_BASE_DELAY,
    P_CONTROLLER_MODULATION_AMPLITUDE,
    P_CONTROLLER_MODULATION_FREQUENCY,
    P_CONTROLLER_T_ON,
    current_delay,
    rhs,
)

# hmeta layout: start, count, capacity overflow flag
HM_START, HM_COUNT, HM_OVERFLOW = 0, 1, 2
# queue meta: start, count, dropped
Q_START, Q_COUNT, Q_DROPPED = 0, 1, 2


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
    return ip[IP_FAMILY] == FAMILY_ROTOR and ip[IP_CONTROLLER] != CONTROLLER_NONE


@nb.njit(cache=True, inline="always")
def delayed_state(t, p, ip, hist, yd):
    """Delayed disc state into ``yd``.  ``hist is None`` (no controller) compiles
    to nothing: the engines are specialised for systems without delay."""
    if hist is None:
        return
    if t >= p[P_CONTROLLER_T_ON]:
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
    s = tj + p[P_CONTROLLER_BASE_DELAY]
    if p[P_CONTROLLER_MODULATION_AMPLITUDE] == 0.0:
        return s
    for _ in range(60):  # Newton on a function with derivative 1 - eps nu cos(nu s) > 0
        f = s - current_delay(s, p) - tj
        df = 1.0 - p[P_CONTROLLER_MODULATION_AMPLITUDE] * p[
            P_CONTROLLER_MODULATION_FREQUENCY
        ] * math.cos(p[P_CONTROLLER_MODULATION_FREQUENCY] * s)
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
    if p[P_CONTROLLER_T_ON] > t + eps_t:
        tb = min(tb, p[P_CONTROLLER_T_ON])
    cap = queue.shape[0]
    while qmeta[Q_COUNT] > 0 and queue[qmeta[Q_START]] <= t + eps_t:
        qmeta[Q_START] = (qmeta[Q_START] + 1) % cap
        qmeta[Q_COUNT] -= 1
    if qmeta[Q_COUNT] > 0:
        tb = min(tb, queue[qmeta[Q_START]])
    return tb


@nb.njit(cache=True)
def max_history_age(p, ip):
    """How far back the delay can reach, s."""
    if not uses_history(p, ip):
        return 0.0
    return p[P_CONTROLLER_BASE_DELAY] + p[P_CONTROLLER_MODULATION_AMPLITUDE]
