"""Compiled loops over the ``fast`` engine with a tangent matrix: the monodromy matrix
over n forcing periods and the Lyapunov spectrum by repeated Gram-Schmidt.

Each interval is one call of the engine's compiled integrator with the tangent
(:mod:`rubcosim.reference.tangent`), from inside these loops: no Python per period.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from rubcosim.reference.core import C_EVENTS, C_STATUS, N_COUNTERS, STATUS_OK, new_event_log
from rubcosim.reference.fast import integrate
from rubcosim.reference.tangent import new_tangent

from .strobe_kernels import _period_events


@nb.njit(cache=True, inline="always")
def _interval(y, mode, t_a, t_b, p, model, tol, out, dde, y_end, tan):
    """One interval [t_a, t_b] (with the tangent ``tan``, or None); y advanced in
    place; returns ``(status, mode, impacts)``."""
    cnt = out[3]
    cnt[:] = 0
    dde[1][:] = 0
    _, mode = integrate(y, mode, t_a, t_b, p, model, tol, out, None, dde, y_end, tan)
    if cnt[C_STATUS] != STATUS_OK:
        return cnt[C_STATUS], mode, 0
    for i in range(y.shape[0]):
        y[i] = y_end[i]
    return STATUS_OK, mode, _period_events(out[2], cnt[C_EVENTS])


@nb.njit(cache=True)
def _buffers(n, max_events):
    out = (
        np.empty(0),
        np.empty((0, 0)),
        new_event_log(max_events, n),
        np.zeros(N_COUNTERS, dtype=np.int64),
    )
    dde = (np.zeros((1, 2)), np.zeros(4, dtype=np.int64))
    return out, dde


@nb.njit(cache=True)
def tangent_periods(
    y, mode, t0, period, n_periods, p, model, tol, max_events, Phi, fd, t_fd, stats
):
    """Integrate ``n_periods`` intervals of ``period`` from ``(t0, y, mode)`` carrying
    ``Phi`` (advanced in place, as is ``y``); ``stats`` receives the tangent's
    statistics.  Returns ``(status, periods done, mode, impacts)``."""
    out, dde = _buffers(y.shape[0], max_events)
    y_end = np.empty(y.shape[0])
    tan = new_tangent(Phi, fd, t_fd)
    impacts = 0
    for k in range(n_periods):
        st, mode, m = _interval(
            y, mode, t0 + k * period, t0 + (k + 1) * period, p, model, tol, out, dde, y_end, tan
        )
        if st != STATUS_OK:
            return st, k, mode, impacts
        impacts += m
    stats[:] = tan[-1]
    return STATUS_OK, n_periods, mode, impacts


@nb.njit(cache=True)
def _column_norm(Q, c):
    return math.sqrt(np.sum(Q[:, c] * Q[:, c]))


@nb.njit(cache=True)
def _project_out(Q, c, passes):
    """Remove from column c its components along columns 0..c-1 (orthonormal)."""
    n = Q.shape[0]
    for _ in range(passes):
        for b in range(c):
            dot = 0.0
            for i in range(n):
                dot += Q[i, b] * Q[i, c]
            for i in range(n):
                Q[i, c] -= dot * Q[i, b]


@nb.njit(cache=True)
def gram_schmidt(Q, logs):
    """Orthonormalise the columns of Q in place (modified Gram-Schmidt, twice for
    round-off) and write the log of each column's norm after projection to
    ``logs`` (-inf for a column that collapsed, which is then replaced by a unit
    vector orthogonal to the others, so the later columns stay defined)."""
    n, k = Q.shape
    for c in range(k):
        norm0 = _column_norm(Q, c)
        _project_out(Q, c, 2)
        norm = _column_norm(Q, c)
        if norm > 1e-300 and norm > 1e-14 * norm0:
            logs[c] = math.log(norm)
            Q[:, c] /= norm
            continue
        logs[c] = -math.inf
        for e in range(n):  # the first basis vector not in the span of the others
            Q[:, c] = 0.0
            Q[e, c] = 1.0
            _project_out(Q, c, 1)
            norm = _column_norm(Q, c)
            if norm > 0.5:
                Q[:, c] /= norm
                break


@nb.njit(cache=True)
def lyapunov_run(
    y,
    mode,
    t0,
    interval,
    n_transient,
    n_intervals,
    p,
    model,
    tol,
    max_events,
    Q,
    fd,
    t_fd,
    logs,
    stats,
):
    """``n_transient`` intervals of ``interval`` s without the tangent, then
    ``n_intervals`` with the k columns of ``Q`` (orthonormal) carried and
    re-orthonormalised after each interval: ``logs[i, c]`` the log growth of
    column c over interval i.  ``stats`` accumulates the tangent's statistics over
    the measured intervals.  Returns ``(status, intervals measured, mode, impacts)``."""
    out, dde = _buffers(y.shape[0], max_events)
    y_end = np.empty(y.shape[0])
    for k in range(n_transient):
        t_a = t0 + k * interval
        st, mode, _ = _interval(y, mode, t_a, t_a + interval, p, model, tol, out, dde, y_end, None)
        if st != STATUS_OK:
            return st, 0, mode, 0
    tan = new_tangent(Q, fd, t_fd)
    impacts = 0
    for k in range(n_intervals):
        t_a = t0 + (n_transient + k) * interval
        st, mode, m = _interval(y, mode, t_a, t_a + interval, p, model, tol, out, dde, y_end, tan)
        if st != STATUS_OK:
            return st, k, mode, impacts
        impacts += m
        gram_schmidt(Q, logs[k])
    stats[:] = tan[-1]
    return STATUS_OK, n_intervals, mode, impacts
