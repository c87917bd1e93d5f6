"""The delayed-feedback controller's step and outputs as compiled kernels on a buffer.

The fed-back signal's history (rows ``(t, zx, zy, Sx, Sy, kind)``, :mod:`.delay_history`)
lives in rows ``a .. b - 1`` of a fixed buffer ``buf``, with ``cs = [a, b, start]``:

* a step only writes at ``b`` and after (it may drop its last row, the second of two
  equal ones at its time, and write it again identically), and the
  front is dropped by moving ``a``; so restoring ``cs`` restores the history, which is
  how a master rolls a step back;
* :func:`make_room` moves the rows to the front when the buffer fills (only where no
  rollback to older bounds can follow: a master keeps a copy of the history in its
  checkpoint).

These kernels are the controller's one definition: the compiled master runs them on its
buffers, :class:`.controller_unit.DelayedFeedbackUnit` (the Python master's and the
FMU's unit) on its history with room for one step after it.  They are held, bit for
bit, to the same history kept by numpy array operations (``tests/test_flat_controller.py``).
The parameter row is :func:`controller_params`; :func:`row_step` and :func:`row_outputs`
are the compiled master's unit step and outputs on the controller's row.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from .controller import (
    MODULATION_SHAPES,
    PIECE_TOL,
    base_delay,
    delay_at,
    delayed_arrivals,
    etdas_blend,
    feedback_force,
    piece_index,
    switch_interval,
)
from .delay_history import FILTER_PAIR, SAMPLE, _lookup, first_kept
from .flat_rows import STEP_BAD_INPUT, STEP_NO_ROOM, STEP_NOT_FINITE, STEP_OK, T, U, Y
from .jit import njit

# the parameter row
C_GAIN, C_MEMORY, C_T_ON, C_VELOCITY, C_TAU0, C_EPS, C_NU, C_SHAPE, C_SEED = range(9)
N_FOUND = 64  # jumps and kinks of the filter one step may meet
OK, FULL = 0, 1  # statuses of controller_step: done; the buffer (or N_FOUND) too small


def controller_params(params: Mapping[str, Any]) -> np.ndarray:
    """The parameter row of a controller with (checked) ``params``."""
    p = np.zeros(9)
    p[C_GAIN], p[C_MEMORY], p[C_T_ON] = params["gain"], params["memory"], params["t_on"]
    p[C_VELOCITY] = params["feedback"] == "velocity"
    p[C_TAU0] = base_delay(params, params["speed"])
    p[C_EPS], p[C_NU] = params["modulation_amplitude"], params["modulation_frequency"]
    p[C_SHAPE] = MODULATION_SHAPES.index(params["modulation_shape"])
    p[C_SEED] = params["modulation_seed"]
    return p


@njit
def _delay(p, t):  # pragma: no cover - compiled
    return delay_at(t, p[C_TAU0], p[C_EPS], p[C_NU], int(p[C_SHAPE]), int(p[C_SEED]))


@njit
def _gather(buf, a, m, b, r, scratch):  # pragma: no cover - compiled
    """Rows ``a .. m - 1`` then ``b .. b + r - 1`` of ``buf`` into ``scratch``; their count."""
    k = 0
    for i in range(a, m):
        scratch[k, :] = buf[i, :]
        k += 1
    for i in range(b, b + r):
        scratch[k, :] = buf[i, :]
        k += 1
    return k


@njit
def _filter(p, scratch, k, tq, left, zx, zy, out):  # pragma: no cover - compiled
    """The ETDAS filter S at ``tq`` from the ``k`` rows in ``scratch`` (on the left of a
    jump there with ``left``); the signal itself before the first row."""
    if k == 0:
        return zx, zy
    _lookup(scratch[:k], tq, left, out)
    memory = p[C_MEMORY]
    return etdas_blend(memory, out[0], out[2]), etdas_blend(memory, out[1], out[3])


@njit
def _rows_before(buf, a, b, t):  # pragma: no cover - compiled
    """The end of the rows before ``t`` (the history is in time order; rows at ``t`` or
    later, if any, are the last few: searched from the end)."""
    m = b
    while m > a and buf[m - 1, 0] >= t:
        m -= 1
    return m


STENCIL_TIMES = 8  # distinct sample times past tq that decide a lookup's stencil


@njit
def _cut(buf, a, m, tq):  # pragma: no cover - compiled
    """Where the rows ``a .. m - 1`` stop mattering to a lookup at ``tq``: after the
    samples at :data:`STENCIL_TIMES` distinct times past ``tq``; ``m`` when that is
    all of them.  A lookup's result depends on the piece holding ``tq`` only within four
    samples of it (``delay_history._interpolate_rows``: the stencil's start is clamped
    by the piece's end only when that end is within four samples), and each distinct
    time keeps at least one sample of the signal, so the rows past the cut (and the
    current sample after them) change nothing: the lookup on ``buf[a:cut]`` is the
    same, bit for bit, without gathering the whole history."""
    lo, hi = a, m
    while lo < hi:  # the first row after tq
        mid = (lo + hi) // 2
        if buf[mid, 0] <= tq:
            lo = mid + 1
        else:
            hi = mid
    e = lo
    for _ in range(STENCIL_TIMES):
        if e >= m:
            return m
        t_g = buf[e, 0]
        while e < m and buf[e, 0] == t_g:
            e += 1
    return e


@njit
def _filter_jumps(p, buf, a, m, b, start, t, zx, zy, scratch):  # pragma: no cover
    """Rows for the jumps and kinks of the filter between row ``m - 1`` and ``t``, written
    from ``b`` on: two rows (left and right limit) at each time a recorded jump, or the
    start, arrives (``s - tau(s)`` = its time) and at each jump of a sawtooth or
    telegraph delay, so that no interpolation stencil spans them; returns their number,
    -1 when they do not fit."""
    if m == a:
        return 0
    tau0, eps, nu = p[C_TAU0], p[C_EPS], p[C_NU]
    shape, seed = int(p[C_SHAPE]), int(p[C_SEED])
    t_last = buf[m - 1, 0]
    # the recorded jumps (two rows at one time) and the start, sorted, each once
    times = np.empty(m - a)
    n_t = 0
    for i in range(a + 1, m):
        if buf[i, 0] == buf[i - 1, 0]:
            times[n_t] = buf[i, 0]
            n_t += 1
    times[n_t] = start
    n_t += 1
    times = np.unique(times[:n_t])
    found = np.empty((N_FOUND, 4))  # (arrival s, delayed time left, right, side: 0 left)
    n_f = 0
    arrivals = np.empty(4)
    for j in times:
        n = delayed_arrivals(j, tau0, eps, nu, shape, seed, arrivals)
        for i in range(n):
            s = arrivals[i]
            if t_last < s < t:
                if n_f == N_FOUND:
                    return -1
                found[n_f, 0], found[n_f, 1], found[n_f, 2], found[n_f, 3] = s, j, j, 0.0
                n_f += 1
    width = switch_interval(nu, shape) if eps > 0.0 else math.inf
    if width < math.inf:
        k = piece_index(t_last, width) + 1.0
        while k * width < t:
            if n_f == N_FOUND:
                return -1
            s = k * width
            before = (k - 2.0 * PIECE_TOL) * width
            found[n_f, 0], found[n_f, 1] = s, s - _delay(p, before)
            found[n_f, 2], found[n_f, 3] = s - _delay(p, s), 1.0
            n_f += 1
            k += 1.0
    # sorted as Python sorts the tuples: by s, then the delayed times, then the side
    for i in range(1, n_f):
        row = found[i].copy()
        k = i
        while k > 0 and (
            (found[k - 1, 0], found[k - 1, 1], found[k - 1, 2], found[k - 1, 3])
            > (row[0], row[1], row[2], row[3])
        ):
            found[k] = found[k - 1]
            k -= 1
        found[k] = row
    if b + 2 * n_f + 1 > buf.shape[0]:
        return -1
    out = np.empty(4)
    r = 0
    for i in range(n_f):
        s, tq_left, tq_right, side = found[i, 0], found[i, 1], found[i, 2], found[i, 3]
        k = _gather(buf, a, m, b, r, scratch)
        scratch[k, 0], scratch[k, 1], scratch[k, 2] = t, zx, zy
        scratch[k, 3], scratch[k, 4], scratch[k, 5] = math.nan, math.nan, SAMPLE
        _lookup(scratch[: k + 1], s, False, out)
        z0, z1 = out[0], out[1]
        lx, ly = _filter(p, scratch, k, tq_left, side == 0.0, zx, zy, out)
        rx, ry = _filter(p, scratch, k, tq_right, False, zx, zy, out)
        buf[b + r, 0], buf[b + r, 1], buf[b + r, 2] = s, z0, z1
        buf[b + r, 3], buf[b + r, 4], buf[b + r, 5] = lx, ly, FILTER_PAIR
        buf[b + r + 1, 0], buf[b + r + 1, 1], buf[b + r + 1, 2] = s, z0, z1
        buf[b + r + 1, 3], buf[b + r + 1, 4], buf[b + r + 1, 5] = rx, ry, FILTER_PAIR
        r += 2
    return r


@njit
def _signal(p, x, y, vx, vy):  # pragma: no cover - compiled
    if p[C_VELOCITY] != 0.0:
        return vx, vy
    return x, y


@njit
def controller_step(p, cs, buf, scratch, x, y, vx, vy, t):  # pragma: no cover - compiled
    """The controller's step at time ``t`` (s) with the disc state ``x, y, vx, vy`` as
    inputs, on the history ``buf`` and ``cs``: the sample at ``t`` (signal and filter)
    recorded, the rows no later lookup needs dropped (:func:`.delay_history.first_kept`);
    returns :data:`OK`, or :data:`FULL` with ``cs`` unchanged when the buffer is too
    small.

    Stepped again from an earlier time, it forgets the rows after it.  Two samples at one
    time mark a jump (a zero-length step recorded the signal just before an impact reset
    it): both stay, and no interpolation stencil spans them; equal ones mark a kink (a
    position fed back, whose velocity the impact reset); a third sample at that time (events
    at one time) replaces the second."""
    a, b, start = int(cs[0]), int(cs[1]), cs[2]
    zx, zy = _signal(p, x, y, vx, vy)
    while b > a and buf[b - 1, 0] > t:  # stepped again from an earlier time
        b -= 1
    if (
        b > a + 1
        and buf[b - 2, 0] == t
        and buf[b - 1, 0] == t
        and buf[b - 1, 1] == zx
        and buf[b - 1, 2] == zy
    ):
        b -= 1  # a third sample at one time replaces the second
    if math.isnan(start):
        start = t
    if p[C_MEMORY] == 0.0:
        sx, sy = zx, zy
    else:
        m = _rows_before(buf, a, b, t)
        r = _filter_jumps(p, buf, a, m, b, start, t, zx, zy, scratch)
        if r < 0:
            return FULL
        out = np.empty(4)
        tq = t - _delay(p, t)
        e = _cut(buf, a, m, tq)
        if e < m:  # the new rows (from b) lie past the cut too
            sx, sy = _filter(p, buf[a:e], e - a, tq, False, zx, zy, out)
        else:
            k = _gather(buf, a, m, b, r, scratch)
            sx, sy = _filter(p, scratch, k, tq, False, zx, zy, out)
        b += r
    a += first_kept(buf[a:b], t - p[C_TAU0] - p[C_EPS])
    if b >= buf.shape[0]:
        return FULL
    buf[b, 0], buf[b, 1], buf[b, 2], buf[b, 3], buf[b, 4] = t, zx, zy, sx, sy
    buf[b, 5] = SAMPLE
    cs[0], cs[1], cs[2] = a, b + 1, start
    return OK


@njit
def controller_outputs(p, cs, buf, scratch, x, y, vx, vy, t, out):  # pragma: no cover
    """The controller's outputs at time ``t`` into ``out``: ux, uy (N) and the current
    delay (s); the force ``K (S(t) - z(t))``, zero before ``t_on``."""
    tau = _delay(p, t)
    out[2] = tau
    if t < p[C_T_ON]:
        out[0], out[1] = 0.0, 0.0
        return
    a, b = int(cs[0]), int(cs[1])
    zx, zy = _signal(p, x, y, vx, vy)
    m = _rows_before(buf, a, b, t)
    v = np.empty(4)
    tq = t - tau
    e = _cut(buf, a, m, tq)
    if e < m:  # the current sample (and its filter) past the cut: looked up in place
        _lookup(buf[a:e], tq, False, v)
    else:
        k = _gather(buf, a, m, b, 0, scratch)
        if p[C_MEMORY] == 0.0:
            sx, sy = zx, zy
        else:
            sx, sy = _filter(p, scratch, k, t - _delay(p, t), False, zx, zy, v)
        scratch[k, 0], scratch[k, 1], scratch[k, 2] = t, zx, zy
        scratch[k, 3], scratch[k, 4], scratch[k, 5] = sx, sy, SAMPLE
        _lookup(scratch[: k + 1], tq, False, v)
    memory = p[C_MEMORY]
    dx, dy = etdas_blend(memory, v[0], v[2]), etdas_blend(memory, v[1], v[3])
    out[0] = feedback_force(p[C_GAIN], zx, dx)
    out[1] = feedback_force(p[C_GAIN], zy, dy)


@njit
def make_room(cs, buf, need):  # pragma: no cover - compiled
    """Make ``need`` rows free after the history with bounds ``cs``, moving it to the
    front of ``buf`` if they are not; returns whether they are free now (if not, the
    buffer must grow).  Only where no rollback to older bounds can follow."""
    a, b = int(cs[0]), int(cs[1])
    if buf.shape[0] - b >= need:
        return True
    if a > 0:
        for i in range(b - a):
            buf[i, :] = buf[a + i, :]
        cs[0], cs[1] = 0, b - a
    return buf.shape[0] - (b - a) >= need


@njit
def row_step(p, st, buf, scratch, t, h):  # pragma: no cover - compiled
    """``Unit.do_step`` of a controller whose bounds ``cs`` are ``st[Y:Y + 3]`` of its row
    (:mod:`.flat_rows`; inputs x, y, vx, vy): a row status (:data:`.flat_rows.STEP_OK`,
    or why it failed, the row as it was)."""
    if not (math.isfinite(t) and math.isfinite(h)) or h < 0.0:
        return STEP_BAD_INPUT
    for i in range(4):
        if not math.isfinite(st[U + 3 * i]):
            return STEP_BAD_INPUT
    cs = st[Y : Y + 3]
    saved = cs.copy()
    if controller_step(p, cs, buf, scratch, st[U], st[U + 3], st[U + 6], st[U + 9], t) != OK:
        return STEP_NO_ROOM
    b = int(cs[1]) - 1
    for j in range(1, 5):
        if not math.isfinite(buf[b, j]):
            cs[:] = saved
            return STEP_NOT_FINITE
    st[T] = t + h
    return STEP_OK


@njit
def row_outputs(p, st, buf, scratch, out):  # pragma: no cover - compiled
    """:func:`controller_outputs` of the controller in row ``st`` at its time."""
    controller_outputs(p, st[Y : Y + 3], buf, scratch, st[U], st[U + 3], st[U + 6], st[U + 9],
                       st[T], out)  # fmt: skip
    return STEP_OK
