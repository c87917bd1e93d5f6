"""Compiled loops of the stroboscopic maps: one orbit, many maps in one call, the
obstacle gap of many states.

Each forcing period is one call of the ``fast`` engine's compiled integrator
from inside these loops, so a sweep or a cell mapping pays no Python per
period (:mod:`.maps` wraps them).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rubcosim.reference import system as S
from rubcosim.reference.core import C_EVENTS, C_STATUS, N_COUNTERS, STATUS_OK, new_event_log
from rubcosim.reference.fast import integrate
from rubcosim.reference.model_calls import events
from rubcosim.reference.unowned import keep_alive, unowned


@nb.njit(cache=True)
def _period_events(evlog, n_events):
    """Impacts and contact onsets among the first ``n_events`` logged events."""
    kinds = evlog[1]
    m = 0
    for i in range(min(n_events, kinds.shape[0])):
        if kinds[i] == S.KIND_IMPACT or kinds[i] == S.KIND_CONTACT_ON:
            m += 1
    return m


@nb.njit(cache=True)
def _log_impacts(evlog, n_events, imp_t, imp_y, imp_count):
    """Append the logged impacts and contact onsets to the impact-section buffers."""
    times, kinds, states = evlog[0], evlog[1], evlog[4]
    for i in range(min(n_events, kinds.shape[0])):
        if kinds[i] == S.KIND_IMPACT or kinds[i] == S.KIND_CONTACT_ON:
            c = imp_count[0]
            if c < imp_t.shape[0]:
                imp_t[c] = times[i]
                for j in range(imp_y.shape[1]):
                    imp_y[c, j] = states[i, j]
            imp_count[0] = c + 1


@nb.njit(cache=True)
def strobe_buffers(n, max_events):
    """The engine's arguments besides the state, made once for a batch of runs: output
    (no dense grid, the event log, the counters), an empty breakpoint queue (no delay)
    and the state at a period's end."""
    out = (np.empty(0), np.empty((0, 0)), new_event_log(max_events, n),
           np.zeros(N_COUNTERS, dtype=np.int64))  # fmt: skip
    dde = (np.zeros((1, 2)), np.zeros(4, dtype=np.int64))
    return out, dde, np.empty(n)


@nb.njit(cache=True, inline="always")
def _unowned_buffers(bufs):  # pragma: no cover - compiled
    """:func:`strobe_buffers`' arrays as views that are not reference-counted (``bufs``
    must stay alive while they are used)."""
    out, dde, y_end = bufs
    log = out[2]
    log = (unowned(log[0]), unowned(log[1]), unowned(log[2]), unowned(log[3]), unowned(log[4]))
    out = (unowned(out[0]), unowned(out[1]), log, unowned(out[3]))
    return out, (unowned(dde[0]), unowned(dde[1])), unowned(y_end)


@nb.njit(cache=True)
def strobe_run(
    y0,
    mode0,
    t0,
    period,
    n_skip,
    n_keep,
    p,
    model,
    rtol,
    atol,
    max_step,
    max_events,
    points,
    impacts,
    modes,
    imp_t,
    imp_y,
    imp_count,
):
    """Integrate ``n_skip + n_keep`` periods from ``(t0, y0, mode0)``.

    Writes the state at the end of each of the last ``n_keep`` periods to
    ``points[k]``, that period's impacts to ``impacts[k]`` and the discrete
    mode there to ``modes[k]``.  The impacts of the kept periods (the impact
    section) go to ``imp_t`` (time) and ``imp_y`` (state just after), as many
    as fit; ``imp_count[0]`` counts them.  Returns
    ``(status, periods_done, mode)``; the state after the last period done is
    ``points[periods_done - n_skip - 1]`` when ``periods_done > n_skip``.
    """
    y = y0.copy()
    bufs = strobe_buffers(y.shape[0], max_events)
    tol = (rtol, atol, max_step)
    return _strobe(y, mode0, t0, period, n_skip, n_keep, p, model, tol, bufs, points, impacts,
                   modes, (imp_t, imp_y, imp_count))  # fmt: skip


@nb.njit(cache=True, inline="always")
def _strobe(
    y, mode, t0, period, n_skip, n_keep, p, model, tol, bufs, points, impacts, modes, section
):
    """:func:`strobe_run` on the batch's buffers ``bufs`` (:func:`strobe_buffers`); ``y``
    is advanced in place; ``section = (imp_t, imp_y, imp_count)``."""
    n = y.shape[0]
    out, dde, y_end = bufs
    evlog, cnt = out[2], out[3]
    qmeta = dde[1]
    imp_t, imp_y, imp_count = section
    for k in range(n_skip + n_keep):
        cnt[:] = 0
        qmeta[:] = 0
        t_a = t0 + k * period
        t_b = t0 + (k + 1) * period
        t, mode = integrate(y, mode, t_a, t_b, p, model, tol, out, None, dde, y_end, None)
        if cnt[C_STATUS] != STATUS_OK:
            return cnt[C_STATUS], k, mode
        for i in range(n):
            y[i] = y_end[i]
        if k >= n_skip:
            for i in range(n):
                points[k - n_skip, i] = y[i]
            impacts[k - n_skip] = _period_events(evlog, cnt[C_EVENTS])
            modes[k - n_skip] = mode
            _log_impacts(evlog, cnt[C_EVENTS], imp_t, imp_y, imp_count)
    return STATUS_OK, n_skip + n_keep, mode


@nb.njit(cache=True)
def map_many(
    Y0,
    modes0,
    t0,
    period,
    n_periods,
    p,
    model,
    rtol,
    atol,
    max_step,
    max_events,
    Y1,
    modes1,
    impacts,
    status,
):
    """Map every row of ``Y0`` through ``n_periods`` forcing periods (cell mapping's kernel).

    ``impacts[j]`` counts all impacts along the way; ``status[j]`` is the
    engine's status (0: ok) and row j of ``Y1`` is NaN when it is not 0.
    """
    n = Y0.shape[1]
    owners = (np.empty((1, n)), np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64),
              (np.empty(0), np.empty((0, n)), np.zeros(1, dtype=np.int64)),
              strobe_buffers(n, max_events), np.empty(n))  # fmt: skip
    # once for the batch, not per map; views that are not reference-counted at each of
    # the maps' calls (owners is kept alive to the end)
    pts, imp, md, y = unowned(owners[0]), unowned(owners[1]), unowned(owners[2]), unowned(owners[5])
    no_section = (unowned(owners[3][0]), unowned(owners[3][1]), unowned(owners[3][2]))
    bufs = _unowned_buffers(owners[4])
    tol = (rtol, unowned(atol), max_step)
    for j in range(Y0.shape[0]):
        total = 0
        for i in range(n):
            y[i] = Y0[j, i]
        mode = modes0[j]
        st = STATUS_OK
        for k in range(n_periods):
            st, done, mode = _strobe(y, mode, t0 + k * period, period, 0, 1, p, model, tol,
                                     bufs, pts, imp, md, no_section)  # fmt: skip
            if st != STATUS_OK:
                break
            total += imp[0]
        status[j] = st
        impacts[j] = total
        modes1[j] = mode
        for i in range(n):
            Y1[j, i] = y[i] if st == STATUS_OK else np.nan
    keep_alive(owners)


@nb.njit(cache=True)
def obstacle_gaps(Y, mode, p, model, gap, rate):
    """For each state row: the smallest event function among the obstacle slots in
    ``mode`` (the gaps: a rigid obstacle's fires on a decrease through zero; an elastic
    stop's, where only the force's law changes, either way, and has a rate slot, unlike a
    breakpoint in time), and its rate (``NaN`` without a rate slot); ``inf`` when there is
    no obstacle."""
    g = np.empty(S.N_EVENTS)
    dirs = np.empty(S.N_EVENTS, dtype=np.int64)
    rates = np.empty(S.N_EVENTS, dtype=np.int64)
    yd = np.zeros(S.N_DELAYED)
    for j in range(Y.shape[0]):
        events(0.0, Y[j], yd, mode, p, model, g, dirs, rates)
        gap[j] = np.inf
        rate[j] = np.nan
        for k in range(S.N_EVENTS):
            if (dirs[k] == -1 or (dirs[k] == 2 and rates[k] >= 0)) and g[k] < gap[j]:
                gap[j] = g[k]
                rate[j] = g[rates[k]] if rates[k] >= 0 else np.nan
