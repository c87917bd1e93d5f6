"""The delay equation's memory: DOP853 dense segments, the history ring buffer, the
ETDAS filter and the breakpoints a delayed jump creates.

The delayed-feedback controller feeds back the disc state of ``tau`` seconds
ago; the engines store the dense output of every step of the disc components
in a ring buffer and look the delayed state up there.  With ETDAS memory R > 0
the buffer also holds the filter ``S(t) = (1 - R) z(t - tau) + R S(t - tau)``
on each step, fitted at push time from older segments (``tau`` exceeds the
step, so S on a step depends on the past only) as a polynomial of the same
degree and form as the dense output.  A jump of the state (an impact) reaches
the delayed term one delay later, and with R > 0 the filter carries it on, one
delay at a time, with weight R^k: those times are breakpoints where the
engines restart their step, down to a weight of :data:`ETDAS_BREAKPOINT_FLOOR`.
A sawtooth or telegraph modulation of the delay jumps: its jump times are
breakpoints too.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from rubcosim.components.controller import (
    PIECE_TOL,
    delayed_arrivals,
    etdas_blend,
    piece_index,
    switch_interval,
)
from rubcosim.components.dop853 import dense_eval, dense_poly
from rubcosim.components.jit import njit

from .model_calls import ip_of, rhs
from .system import (
    CONTROLLER_NONE,
    FAMILY_ROTOR,
    IP_CONTROLLER,
    IP_CONTROLLER_MODULATION_SHAPE,
    IP_FAMILY,
    N_DELAYED,
    P_CONTROLLER_BASE_DELAY,
    P_CONTROLLER_MEMORY,
    P_CONTROLLER_MODULATION_AMPLITUDE,
    P_CONTROLLER_MODULATION_FREQUENCY,
    P_CONTROLLER_MODULATION_SEED,
    P_CONTROLLER_T_ON,
    current_delay,
)

# hmeta layout: start, count, capacity overflow flag
HM_START, HM_COUNT, HM_OVERFLOW = 0, 1, 2
# queue meta: start, count, dropped, index of the last modulation jump whose arrivals
# were queued; queue rows: (time, level), level k = the jump's weight R^(k-1) there
Q_START, Q_COUNT, Q_DROPPED, Q_SWITCH = 0, 1, 2, 3
Q_META_SIZE = 4
# a delayed jump of weight below this (R^k) is left to the step-size control
ETDAS_BREAKPOINT_FLOOR = 1e-10


def _filter_fit() -> np.ndarray:
    """The map from the ETDAS filter's values at :data:`FILTER_NODES` to the 8
    coefficients (value at the start, then ``F``) of the dense output's polynomial."""
    basis = np.empty((FILTER_NODES.size, 8))
    for i, x in enumerate(FILTER_NODES):
        basis[i, 0] = 1.0
        for j in range(7):  # dense_poly with F = e_j
            acc = 0.0
            for k in range(7):
                acc += 1.0 if 6 - k == j else 0.0
                acc *= x if k % 2 == 0 else 1.0 - x
            basis[i, 1 + j] = acc
    return np.linalg.inv(basis)


# Chebyshev points inside the step: no node sits on a step's ends, where the
# filter may jump (a delayed impact arrives at a breakpoint, which ends a step).
FILTER_NODES = 0.5 - 0.5 * np.cos((2.0 * np.arange(8) + 1.0) * np.pi / 16.0)
FILTER_FIT = _filter_fit()


# ---------------------------------------------------------------- history
def new_history(capacity: int, t_init: float, y_init: np.ndarray):
    """Ring buffer of dense segments of the delayed (disc) components and of their
    ETDAS filter.  The initial function is constant, and so is its filter."""
    return (
        np.zeros(capacity),  # t_old
        np.ones(capacity),  # h
        np.zeros(capacity),  # t_end (segment valid on [t_old, t_end])
        np.zeros((capacity, N_DELAYED)),  # y_old
        np.zeros((capacity, 7, N_DELAYED)),  # F
        np.zeros(3, dtype=np.int64),  # meta
        np.concatenate(([t_init], y_init[:N_DELAYED])),  # initial function: constant
        np.ones(capacity),  # the filter's polynomial: its time scale (t_end - t_old)
        np.zeros((capacity, N_DELAYED)),  # its value at t_old
        np.zeros((capacity, 7, N_DELAYED)),  # its coefficients
        np.zeros((FILTER_NODES.size, N_DELAYED)),  # scratch: the filter at its nodes
    )


@nb.njit(cache=True, inline="always")
def _segment(hist, tq):
    """Ring index of the segment holding ``tq`` (-1: the initial function)."""
    t0s, meta, init = hist[0], hist[5], hist[6]
    start, count = meta[HM_START], meta[HM_COUNT]
    cap = t0s.shape[0]
    if count == 0 or tq <= init[0] or tq < t0s[start]:
        return -1
    lo, hi = 0, count - 1
    # last segment whose start is <= tq: the later one wins at a jump
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if t0s[(start + mid) % cap] <= tq:
            lo = mid
        else:
            hi = mid - 1
    return (start + lo) % cap


@njit(borrows=True)
def history_eval(hist, tq, out):
    """Delayed disc state at time ``tq`` (the initial state before the start)."""
    k = _segment(hist, tq)
    if k < 0:
        for c in range(N_DELAYED):
            out[c] = hist[6][1 + c]
        return
    dense_eval(hist[0][k], hist[1][k], hist[3][k], hist[4][k], tq, out, N_DELAYED)


@njit(borrows=True)
def filtered_eval(hist, tq, memory, out):
    """``(1 - R) z(tq) + R S(tq)``: the ETDAS filter one delay after ``tq``."""
    k = _segment(hist, tq)
    if k < 0:
        for c in range(N_DELAYED):
            out[c] = etdas_blend(memory, hist[6][1 + c], hist[6][1 + c])
        return
    x = (tq - hist[0][k]) / hist[1][k]
    xs = (tq - hist[0][k]) / hist[7][k]
    for c in range(N_DELAYED):
        z = dense_poly(x, hist[4][k], c) + hist[3][k, c]
        sf = dense_poly(xs, hist[9][k], c) + hist[8][k, c]
        out[c] = etdas_blend(memory, z, sf)


@njit(borrows=True)
def _fit_filter(hist, k, t_old, span, p, model):
    """The ETDAS filter on ``[t_old, t_old + span]`` into slot ``k``, from older segments."""
    nodes = hist[10]
    memory = p[P_CONTROLLER_MEMORY]
    for i in range(FILTER_NODES.shape[0]):
        t = t_old + FILTER_NODES[i] * span
        filtered_eval(hist, t - current_delay(t, p, ip_of(model)), memory, nodes[i])
    hist[7][k] = span
    for c in range(N_DELAYED):
        for j in range(8):
            acc = 0.0
            for i in range(FILTER_NODES.shape[0]):
                acc += FILTER_FIT[j, i] * nodes[i, c]
            if j == 0:
                hist[8][k, c] = acc
            else:
                hist[9][k, j - 1, c] = acc


@njit(borrows=True)
def history_push(hist, t_old, h, t_end, y_old, F, keep_after, p, model):
    """Store a segment (and, with ETDAS memory, its filter); drop segments that end
    before ``keep_after``."""
    t0s, hs, tends, y0s, Fs, meta = hist[0], hist[1], hist[2], hist[3], hist[4], hist[5]
    cap = t0s.shape[0]
    while meta[HM_COUNT] > 1 and tends[meta[HM_START]] < keep_after:
        meta[HM_START] = (meta[HM_START] + 1) % cap
        meta[HM_COUNT] -= 1
    if meta[HM_COUNT] == cap:
        meta[HM_OVERFLOW] = 1
        return
    k = (meta[HM_START] + meta[HM_COUNT]) % cap
    if p[P_CONTROLLER_MEMORY] > 0.0:
        # before the segment joins the buffer: the filter's lookups reach back at
        # least the shortest delay, which exceeds the step
        span = t_end - t_old
        _fit_filter(hist, k, t_old, span if span > 0.0 else h, p, model)
    t0s[k] = t_old
    hs[k] = h
    tends[k] = t_end
    for c in range(N_DELAYED):
        y0s[k, c] = y_old[c]
        for i in range(F.shape[0]):
            Fs[k, i, c] = F[i, c]
    meta[HM_COUNT] += 1


@nb.njit(cache=True, inline="always")
def uses_history(p, model):
    """Whether the system has a delay (a controller on a rotor)."""
    return (
        ip_of(model)[IP_FAMILY] == FAMILY_ROTOR and ip_of(model)[IP_CONTROLLER] != CONTROLLER_NONE
    )


@nb.njit(cache=True, inline="always")
def delayed_state(t, p, model, hist, yd):
    """The fed-back delayed disc state into ``yd``: ``z(t - tau)`` (Pyragas) or the
    ETDAS filter ``(1 - R) z(t - tau) + R S(t - tau)``; zero before ``t_on``.
    ``hist is None`` (no controller) compiles to nothing: the engines are
    specialised for systems without delay."""
    if hist is None:
        return
    if t >= p[P_CONTROLLER_T_ON]:
        tq = t - current_delay(t, p, ip_of(model))
        if p[P_CONTROLLER_MEMORY] == 0.0:
            history_eval(hist, tq, yd)
        else:
            filtered_eval(hist, tq, p[P_CONTROLLER_MEMORY], yd)
    else:
        for c in range(N_DELAYED):
            yd[c] = 0.0


@nb.njit(cache=True, inline="always")
def full_rhs(t, y, mode, p, model, hist, yd, dy):
    """Right-hand side with the delayed state looked up in the history."""
    delayed_state(t, p, model, hist, yd)
    rhs(t, y, yd, mode, p, model, dy)


@njit(borrows=True)
def full_rhs_call(t, y, mode, p, model, hist, yd, dy):
    """:func:`full_rhs` as a call, not inlined: for the sites that run once per restart
    (each inlined copy of the right-hand side costs seconds of a cold compile)."""
    full_rhs(t, y, mode, p, model, hist, yd, dy)


@nb.njit(cache=True)
def full_rhs_alloc(t, y, mode, p, model, hist):
    dy = np.empty_like(y)
    yd = np.empty(N_DELAYED)
    full_rhs(t, y, mode, p, model, hist, yd, dy)
    return dy


# ---------------------------------------------------------------- delay breakpoints
def new_queue(capacity: int):
    """The breakpoint queue: rows ``(time, level)`` sorted by time, and its meta."""
    qmeta = np.zeros(Q_META_SIZE, dtype=np.int64)
    qmeta[Q_SWITCH] = np.iinfo(np.int64).min
    return np.zeros((capacity, 2)), qmeta


@njit(borrows=True)
def queue_insert(queue, qmeta, value, level):
    """Insert a breakpoint, keeping the queue sorted by time."""
    cap = queue.shape[0]
    if qmeta[Q_COUNT] == cap:
        qmeta[Q_DROPPED] += 1
        return
    start = qmeta[Q_START]
    i = qmeta[Q_COUNT]
    while i > 0 and queue[(start + i - 1) % cap, 0] > value:
        queue[(start + i) % cap, 0] = queue[(start + i - 1) % cap, 0]
        queue[(start + i) % cap, 1] = queue[(start + i - 1) % cap, 1]
        i -= 1
    queue[(start + i) % cap, 0] = value
    queue[(start + i) % cap, 1] = level
    qmeta[Q_COUNT] += 1


@nb.njit(cache=True)
def push_arrivals(queue, qmeta, tj, level, p, model):
    """Queue the times a jump at ``tj`` reaches the delayed term, at ``level``."""
    times = np.empty(4)
    n = delayed_arrivals(
        tj,
        p[P_CONTROLLER_BASE_DELAY],
        p[P_CONTROLLER_MODULATION_AMPLITUDE],
        p[P_CONTROLLER_MODULATION_FREQUENCY],
        ip_of(model)[IP_CONTROLLER_MODULATION_SHAPE],
        int(p[P_CONTROLLER_MODULATION_SEED]),
        times,
    )
    for i in range(n):
        queue_insert(queue, qmeta, times[i], level)


@nb.njit(cache=True)
def _modulation_jump_interval(p, model):
    if p[P_CONTROLLER_MODULATION_AMPLITUDE] == 0.0:
        return math.inf
    return switch_interval(
        p[P_CONTROLLER_MODULATION_FREQUENCY], ip_of(model)[IP_CONTROLLER_MODULATION_SHAPE]
    )


@nb.njit(cache=True)
def next_breakpoint(t, t_end, p, model, queue, qmeta):
    """Next time the delay equation has a known nonsmooth point after t.

    Passing a queued breakpoint of level k queues its own arrivals at level k + 1
    (the ETDAS filter carries the jump on) while R^k is above the floor; reaching
    a jump of the delay's modulation queues its arrivals at level 1 (with R > 0:
    the filter jumps there)."""
    tb = t_end
    if not uses_history(p, model):
        return tb
    eps_t = 4.0 * np.finfo(np.float64).eps * max(1.0, abs(t))
    if p[P_CONTROLLER_T_ON] > t + eps_t:
        tb = min(tb, p[P_CONTROLLER_T_ON])
    memory = p[P_CONTROLLER_MEMORY]
    cap = queue.shape[0]
    while qmeta[Q_COUNT] > 0 and queue[qmeta[Q_START], 0] <= t + eps_t:
        passed, level = queue[qmeta[Q_START], 0], queue[qmeta[Q_START], 1]
        qmeta[Q_START] = (qmeta[Q_START] + 1) % cap
        qmeta[Q_COUNT] -= 1
        if memory > 0.0 and memory**level >= ETDAS_BREAKPOINT_FLOOR:
            push_arrivals(queue, qmeta, passed, level + 1.0, p, model)
    width = _modulation_jump_interval(p, model)
    if width < math.inf:
        m = piece_index(t, width)
        if memory > 0.0 and t - m * width <= PIECE_TOL * width + eps_t and m != qmeta[Q_SWITCH]:
            qmeta[Q_SWITCH] = int(m)
            push_arrivals(queue, qmeta, m * width, 1.0, p, model)
        tb = min(tb, (m + 1.0) * width)
    if qmeta[Q_COUNT] > 0:
        tb = min(tb, queue[qmeta[Q_START], 0])
    return tb


@nb.njit(cache=True)
def max_history_age(p, model):
    """How far back the delay can reach, s."""
    if not uses_history(p, model):
        return 0.0
    return p[P_CONTROLLER_BASE_DELAY] + p[P_CONTROLLER_MODULATION_AMPLITUDE]
