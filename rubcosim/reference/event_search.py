"""Finding and locating events on a step's dense output (both engines).

After every accepted step the event functions at its two ends are compared;
a sign change, or a rate companion that changes sign (a contact that opens
and closes inside the step, a rebound that returns), brackets an event, which
:mod:`rubcosim.components.root_finding` locates to round-off of t.  An event
function whose time derivative is another slot (the gap and its rate, a barrier
and the velocity) goes to the rate-aware locator (:func:`locate_with_rate`: the
root of the cubic Hermite interpolant, then Newton's steps inside the bracket);
any other to Brent's method (:func:`locate`: Feng & Yang's three-point
interpolation, safeguarded by the bracket).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rubcosim.components.jit import njit
from rubcosim.components.root_finding import (
    F_CUR,
    MAX_TRIALS,
    R_B,
    R_D,
    R_F,
    R_X,
    RATE_STATE_SIZE,
    STATE_SIZE,
    X_CUR,
    advance,
    advance_with_rates,
    crossed_end,
    start,
    start_with_rates,
)

from .history import delayed_state, dense_eval
from .model_calls import events
from .stack_arrays import stack_floats
from .system import N_EVENTS


@nb.njit(cache=True, inline="always")
def event_value(slot, t, seg, ctx, hist, scratch):
    """Event function ``slot`` at time t on the dense segment ``seg``.

    ``seg = (t_old, h, y_old, F)``; ``ctx = (mode, p, model)``;
    ``scratch = (ybuf, yd, g, dirs, rates)``.  ``hist`` stays an argument of
    its own so that numba can compile away the delay when it is None.
    """
    t_old, h, y_old, F = seg
    mode, p, model = ctx
    ybuf, yd, g, dirs, rates = scratch
    dense_eval(t_old, h, y_old, F, t, ybuf, ybuf.shape[0])
    delayed_state(t, p, model, hist, yd)
    events(t, ybuf, yd, mode, p, model, g, dirs, rates)
    return g[slot]


@njit(borrows=True)
def value_at(slot, t, seg, ctx, hist, scratch):
    """:func:`event_value` as a call, not inlined: for the sites that run a few times
    per event, each inlined copy of the system's event functions costing seconds of
    compilation."""
    return event_value(slot, t, seg, ctx, hist, scratch)


@nb.njit(cache=True, inline="always")
def time_round_off(t: float) -> float:
    """The round-off scale of a time t, s: 4 eps max(|t|, 1).  An event is located to it,
    and a step shorter than it is no step (``core.after_step``'s restart test)."""
    return 4.0 * np.finfo(np.float64).eps * max(abs(t), 1.0)


@njit(borrows=True)
def locate(slot, sgn, ta, fa, tb, fb, seg, ctx, hist, scratch):
    """Bracket [ta, tb] of a zero of ``sgn * g_slot`` (fa > 0 >= fb), located to
    round-off of t; returns the end point on the crossed side (sgn * g <= 0), so
    the event is known to have happened there."""
    s = stack_floats(STATE_SIZE, STATE_SIZE)  # the locator's state: no allocation
    start(s, ta, fa, tb, fb, time_round_off(max(abs(ta), abs(tb))))
    for _ in range(MAX_TRIALS):
        if advance(s):
            break
        s[F_CUR] = sgn * value_at(slot, s[X_CUR], seg, ctx, hist, scratch)
    return crossed_end(s)


@njit(borrows=True)
def locate_with_rate(slot, j, sgn, ta, fa, da, tb, fb, db, seg, ctx, hist, scratch):
    """:func:`locate` for a slot whose time derivative is slot ``j`` (``da``, ``db`` that
    of ``sgn * g_slot`` at the ends): the same evaluation gives it at every trial, so
    the locator interpolates with it and then takes Newton's steps (about 3 trials
    where Brent's method, with values only, takes 5 or 6)."""
    s = stack_floats(RATE_STATE_SIZE, RATE_STATE_SIZE)  # no allocation
    start_with_rates(s, ta, fa, da, tb, fb, db, time_round_off(max(abs(ta), abs(tb))))
    for _ in range(MAX_TRIALS):
        if advance_with_rates(s):
            break
        s[R_F] = sgn * value_at(slot, s[R_X], seg, ctx, hist, scratch)
        s[R_D] = sgn * scratch[2][j]  # the same evaluation filled every slot
    return s[R_B]


@nb.njit(cache=True)
def pre_side(direction, side):
    """Sign of an event function before it fires: +1 for a falling event, -1
    for a rising one, the current side for a breakpoint; 0 for a slot that is not
    an event (direction 0) or whose side is undetermined."""
    if direction == -1:
        return 1.0
    if direction == 1:
        return -1.0
    if direction == 0:
        return 0.0
    return float(side)


# first_return samples the rate at t_a + h / 4**i, i = RETURN_LEVELS .. 0 (h/64, h/16, h/4
# and the step's end, whose values are known).  It sees a return whose rate stays
# negative from its top to four times as long after the step's start, or past h/64: a
# return needs about twice (the top halfway to it, under a steady pull back), so what it
# can miss is a rate that turned down and back up again within a factor of four in time
# and above h/64, or altogether below h/64: a flight that changes its curvature twice
# on a time scale the step-size controller resolves in 12 stages.  A rebound much
# shorter than the step (chattering) keeps its rate negative from its top to the
# step's end, where the pull that brought it back reverses; any sample catches it.
RETURN_LEVELS = 3
QUARTERS = np.ldexp(1.0, -2 * np.arange(RETURN_LEVELS + 1))  # 4**-i: exact powers of two


@njit(borrows=True)
def first_return(k, j, sgn, t_a, t_b, rate_a, fb, rate_b, seg, ctx, hist, scratch):
    """Bracket ``(left, right)`` of the first return of ``sgn * g_k`` through zero in a
    step that starts on the surface moving away (``rate_a = sgn * g_j(t_a) > 0``)
    and ends with the rate on the same side (``fb = sgn * g_k(t_b)``, ``rate_b =
    sgn * g_j(t_b) >= 0``); ``(-1, -1)`` if it does not come back.

    g rose, and turned an even number of times, if at all: it may have come back
    through zero (and even left again) inside the step, which neither end shows.
    The rate is sampled at ``t_a + h / 4**i``, i = RETURN_LEVELS..0 (see there);
    its first turn (the top) starts the bracket, which ends at the first sample on the
    crossed side, or at the bottom of the return if g turns up again there.
    """
    h = t_b - t_a
    tp, rp = t_a, rate_a
    top = -1.0
    last = t_a  # latest point with sgn * g > 0 and no zero of it found before
    for i in range(RETURN_LEVELS, -1, -1):
        if i == 0:
            tm, rm, gm = t_b, rate_b, fb  # the step's end: known
        else:
            tm = t_a + h * QUARTERS[i]
            if tm <= tp:
                continue
            rm = sgn * value_at(j, tm, seg, ctx, hist, scratch)
            gm = sgn * scratch[2][k]  # the same evaluation filled every slot: g_k at tm too
        if top < 0.0:
            if rm > 0.0:
                tp, rp = tm, rm
                continue
            top = locate(j, sgn, tp, rp, tm, rm, seg, ctx, hist, scratch)
            last = top
        if gm <= 0.0:
            return last, tm
        if rm > 0.0:
            # turned up again before reaching zero? the bottom of the return decides
            fa = -rp if rp < 0.0 else 1e-300
            bottom = locate(j, -sgn, tp, fa, tm, -rm, seg, ctx, hist, scratch)
            if sgn * value_at(k, bottom, seg, ctx, hist, scratch) <= 0.0:
                return last, bottom
            last = bottom
            break
        last = tm
        tp, rp = tm, rm
    if fb <= 0.0:
        return last, t_b
    return -1.0, -1.0


@njit(borrows=True, inline="always")  # into after_step: see there
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
                k, j, sgn, t_a, t_b, sgn * g_a[j], sgn * g_b[k], sgn * g_b[j],
                seg, ctx, hist, scratch,
            )  # fmt: skip
        elif sgn * g_b[k] <= 0.0:
            right = t_b
            if leaving:
                # moving away, then back through zero: bracket from the extremum,
                # not from the start
                left = locate(j, sgn, t_a, sgn * g_a[j], t_b, sgn * g_b[j], seg, ctx, hist, scratch)
        elif j >= 0 and sgn * g_a[j] < 0.0 and sgn * g_b[j] > 0.0:
            # Approaching, then receding within the step: does it touch at the extremum?
            ts = locate(j, -sgn, t_a, -sgn * g_a[j], t_b, -sgn * g_b[j], seg, ctx, hist, scratch)
            if sgn * value_at(k, ts, seg, ctx, hist, scratch) <= 0.0:
                right = ts
        if right < 0.0 or right > best_t or (right == best_t and best_k >= 0):
            continue
        # At the step's ends the values are known: g_a at y_old, which the dense output
        # gives back exactly (but a slot starting on its surface, whose value the
        # restart set to zero, is evaluated for its residue), and g_b at y_new (the
        # brackets above take it too, and it decided that the slot crossed).  So are
        # the rates, where the slot has one (an evaluation fills every slot).
        if left == t_a and sgn * g_a[k] > 0.0:
            fl = sgn * g_a[k]
            dl = sgn * g_a[j] if j >= 0 else 0.0
        else:
            fl = sgn * value_at(k, left, seg, ctx, hist, scratch)
            dl = sgn * scratch[2][j] if j >= 0 else 0.0
        if right == t_b:
            fr = sgn * g_b[k]
            dr = sgn * g_b[j] if j >= 0 else 0.0
        else:
            fr = sgn * value_at(k, right, seg, ctx, hist, scratch)
            dr = sgn * scratch[2][j] if j >= 0 else 0.0
        if fl <= 0.0:
            # Round-off at the start of a step just after an event: treat it as the pre side.
            fl = 1e-300
        if fr > 0.0:
            continue
        if j >= 0:
            te = locate_with_rate(k, j, sgn, left, fl, dl, right, fr, dr, seg, ctx, hist, scratch)
        else:
            te = locate(k, sgn, left, fl, right, fr, seg, ctx, hist, scratch)
        if best_k < 0 or te < best_t:
            best_k = k
            best_t = te
    return best_k, best_t


@nb.njit(cache=True, inline="always")
def event_candidate(g_a, side_a, dirs_a, rates_a, g_b):
    """Whether the step may hold an event: a sign change, or a rate companion
    that changes sign (a possible grazing contact).  Cheap; no dense output."""
    for k in range(N_EVENTS):
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


@nb.njit(cache=True, inline="always")
def step_end_events(t, y, mode, p, model, hist, yd, g_b, dirs_b, rates_b):
    """Event functions at the end of a step (same mode as at its start)."""
    delayed_state(t, p, model, hist, yd)
    events(t, y, yd, mode, p, model, g_b, dirs_b, rates_b)


# a call, not inlined: it runs once per restart (after an event), and each inlined copy of
# the system's event functions costs seconds of a cold compile
@njit(borrows=True)
def start_sides(t, y, mode, p, model, hist, g, dirs, rates, side, yd, forced_slot, forced_side):
    """Event functions at the start of a step and the side each one is on."""
    delayed_state(t, p, model, hist, yd)
    events(t, y, yd, mode, p, model, g, dirs, rates)
    for k in range(N_EVENTS):
        side[k] = 1 if g[k] > 0.0 else (-1 if g[k] < 0.0 else 0)
    if forced_slot >= 0:
        side[forced_slot] = forced_side
        # The step starts at this slot's event: its function is zero there (the
        # event map's projection onto the surface may leave a round-off residue).
        g[forced_slot] = 0.0


@nb.njit(cache=True, inline="always")
def sides_from(g, side):
    for k in range(N_EVENTS):
        side[k] = 1 if g[k] > 0.0 else (-1 if g[k] < 0.0 else 0)
