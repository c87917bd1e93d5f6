"""The ``fast`` engine: an event-driven DOP853 integrator compiled with numba.

The Runge-Kutta step, its error estimate, the step-size controller and the
initial-step heuristic follow scipy's ``DOP853`` (same coefficients, read from
scipy), so the two engines take the same steps up to round-off; what is gained
is the absence of Python in the loop.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from rubcosim.components.dop853 import (
    N_DENSE,
    N_EXT,
    N_STAGES,
    below_min_step,
    dense_stages,
    error_norm,
    min_step,
    next_step,
    rk_stages,
)
from rubcosim.components.jit import njit
from rubcosim.components.kernels import all_finite

from .core import (
    C_EVAL,
    C_REJECTED,
    C_RESTARTS,
    C_RHS,
    C_STATUS,
    C_STEPS,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_STEP_TOO_SMALL,
    after_step,
    needs_dense,
    record_point,
)
from .event_search import (
    sides_from,
    start_sides,
    step_end_events,
)
from .history import (
    full_rhs,
    full_rhs_call,
    next_breakpoint,
    uses_history,
)
from .model_calls import dense_output
from .model_calls import rk_step as model_rk_step
from .stack_arrays import stack_floats, stack_ints, stack_matrix
from .system import MAX_STATES, N_DELAYED, N_EVENTS, N_P
from .tangent import tangent_after, tangent_step
from .unowned import keep_alive, unowned

K_CAPACITY = N_EXT * MAX_STATES
F_CAPACITY = N_DENSE * MAX_STATES


@nb.njit(cache=True)
def initial_step(t0, y0, f0, t_bound, max_step, rtol, atol, mode, p, model, hist, yd, y1, f1, cnt):
    """scipy's ``select_initial_step`` (Hairer, Norsett & Wanner II.4), order 7."""
    n = y0.shape[0]
    interval = abs(t_bound - t0)
    if interval == 0.0:
        return 0.0
    d0 = 0.0
    d1 = 0.0
    for i in range(n):
        sc = atol[i] + abs(y0[i]) * rtol
        d0 += (y0[i] / sc) ** 2
        d1 += (f0[i] / sc) ** 2
    d0 = math.sqrt(d0 / n)
    d1 = math.sqrt(d1 / n)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, interval)
    for i in range(n):
        y1[i] = y0[i] + h0 * f0[i]
    full_rhs_call(t0 + h0, y1, mode, p, model, hist, yd, f1)
    cnt[C_RHS] += 1
    d2 = 0.0
    for i in range(n):
        sc = atol[i] + abs(y0[i]) * rtol
        d2 += ((f1[i] - f0[i]) / sc) ** 2
    d2 = math.sqrt(d2 / n) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100.0 * h0, h1, interval, max_step)


@nb.njit(cache=True, inline="always")
def _full_rhs_in(ctx, t, y, dy):
    mode, p, model, hist, yd = ctx
    full_rhs(t, y, mode, p, model, hist, yd, dy)


# calls, not inlined: compiled apart for each variant, where ``hist is None`` is known and
# the delay path is pruned (inlined, both paths went into the delay-free engine's IR);
# LLVM inlines the delay-free body, a pointer call, into the loop all the same
@njit(borrows=True)
def rk_step(t, y, f, h, mode, p, model, hist, yd, K, y_new, f_new, ytmp, cnt):
    """One DOP853 step of size ``h`` from ``(t, y)`` with ``f`` the slope there: the stages
    into ``K`` (a view that is not reference-counted: its rows are written in place),
    the solution into ``y_new`` and its slope into ``f_new``.  Without a delay, one call
    of the model's own step (its right-hand side inlined in it); with one, the stages
    here, each looking up the delayed state and calling the right-hand side."""
    if hist is None:
        model_rk_step(t, y, f, h, mode, p, model, yd, K, y_new, f_new, ytmp)
    else:
        ctx = (mode, p, model, hist, yd)
        rk_stages(_full_rhs_in, ctx, t, y, f, h, K, y_new, f_new, ytmp)
    cnt[C_RHS] += N_STAGES


@njit(borrows=True)
def dense_coefficients(t_old, h, y_old, y_new, f_new, K, mode, p, model, hist, yd, F, ytmp, cnt):
    """DOP853 dense output (scipy's F layout) for the step just taken; ``K`` a view that is
    not reference-counted (its rows are written in place).  Without a delay, one call
    of the model's own (:func:`rk_step`)."""
    if hist is None:
        dense_output(t_old, h, y_old, y_new, f_new, mode, p, model, yd, K, F, ytmp)
    else:
        ctx = (mode, p, model, hist, yd)
        dense_stages(_full_rhs_in, ctx, t_old, h, y_old, y_new, f_new, K, F, ytmp)
    cnt[C_RHS] += N_EXT - N_STAGES - 1


# nogil: a progress thread (rubcosim.progress) reads the counters while it runs
@nb.njit(cache=True, nogil=True)
def integrate(y0, mode, t0, t_end, p, model, tol, out, hist, dde, y_final, tan):
    """Integrate from t0 to t_end; returns ``(t, mode)`` reached (t < t_end on failure).

    ``tol = (rtol, atol array, max_step)``; ``out = (t_eval, rec, evlog, cnt)``: the
    output times, the recorded outputs there, the event log and the counters;
    ``hist`` the delay history (None without delay) and ``dde = (queue, qmeta)`` its
    breakpoint queue; the final state goes to ``y_final``.  ``tan``: a tangent matrix
    carried along (:func:`rubcosim.reference.tangent.new_tangent`; delay-free systems)
    or None.  Every caller passes it, None included: numba compiles an omitted
    argument and a None apart, and this engine takes the best part of a minute to compile.
    """
    rtol, atol, max_step = tol
    t_eval, rec, evlog, cnt = out
    queue, qmeta = dde
    # The caller's arrays, used at every step (the counters, the tolerance, the output
    # grid): views that are not reference-counted (the caller keeps the arrays alive)
    atol, t_eval, rec, cnt = unowned(atol), unowned(t_eval), unowned(rec), unowned(cnt)
    queue, qmeta = unowned(queue), unowned(qmeta)
    evlog = (unowned(evlog[0]), unowned(evlog[1]), unowned(evlog[2]), unowned(evlog[3]),
             unowned(evlog[4]))  # fmt: skip
    out, dde = (t_eval, rec, evlog, cnt), (queue, qmeta)
    n = y0.shape[0]
    if n > MAX_STATES or len(p) > N_P:
        raise ValueError("integrate: more states or parameters than the layout's")
    # The parameters on this function's stack: the optimiser knows that no store into a
    # stage or the state changes them (stack_arrays)
    p_arr = stack_floats(N_P, len(p))
    for i in range(len(p)):
        p_arr[i] = p[i]
    p = p_arr
    # The step loop's scratch arrays live on this function's stack: no allocation, and
    # the optimiser knows that none of them overlaps another (stack_arrays).
    y, y_next, y_new = (
        stack_floats(MAX_STATES, n),
        stack_floats(MAX_STATES, n),
        stack_floats(MAX_STATES, n),
    )
    f, f_new, ytmp = (
        stack_floats(MAX_STATES, n),
        stack_floats(MAX_STATES, n),
        stack_floats(MAX_STATES, n),
    )
    K, F = stack_matrix(K_CAPACITY, N_EXT, n), stack_matrix(F_CAPACITY, N_DENSE, n)
    yd = stack_floats(N_DELAYED, N_DELAYED)
    for i in range(n):
        y[i] = y0[i]
    g_a, g_b = stack_floats(N_EVENTS, N_EVENTS), stack_floats(N_EVENTS, N_EVENTS)
    side, dirs, rates = (
        stack_ints(N_EVENTS, N_EVENTS),
        stack_ints(N_EVENTS, N_EVENTS),
        stack_ints(N_EVENTS, N_EVENTS),
    )
    dirs_b, rates_b = stack_ints(N_EVENTS, N_EVENTS), stack_ints(N_EVENTS, N_EVENTS)
    for k in range(N_EVENTS):
        side[k], dirs[k], rates[k], dirs_b[k], rates_b[k] = 0, 0, 0, 0, 0
    # after_step's scratch (core.new_workspace's arrays); the outputs' two on the heap
    owners = (np.empty(rec.shape[1]), np.empty(rec.shape[1]))
    work = (stack_floats(MAX_STATES, n), stack_floats(N_DELAYED, N_DELAYED), unowned(owners[0]),
            stack_floats(N_EVENTS, N_EVENTS), stack_ints(N_EVENTS, N_EVENTS),
            stack_ints(N_EVENTS, N_EVENTS))  # fmt: skip
    obuf = unowned(owners[1])
    t = t0
    ev = (g_a, side, dirs, rates, g_b)  # what after_step reads and updates
    forced_slot, forced_side = -1, 0
    h_last = 0.0
    cnt[C_EVAL] = record_point(t, y, mode, p, model, hist, t_eval, np.int64(0), rec, yd, obuf)
    while t < t_end and cnt[C_STATUS] == STATUS_OK:
        bound = t_end
        # Without a delay (hist None) the branch is pruned at compile time: the
        # breakpoint machinery is not compiled into the delay-free variant at all.
        if hist is not None and uses_history(p, model):
            bound = next_breakpoint(t, t_end, p, model, queue, qmeta)
        start_sides(
            t, y, mode, p, model, hist, g_a, dirs, rates, side, yd, forced_slot, forced_side
        )
        forced_slot = -1
        full_rhs_call(t, y, mode, p, model, hist, yd, f)
        cnt[C_RHS] += 1
        cnt[C_RESTARTS] += 1
        if h_last > 0.0:
            # After an event the last accepted step is a better guess than the
            # starting heuristic, which overshoots and gets rejected after most impacts.
            h_abs = min(h_last, max_step, bound - t)
        else:
            h_abs = initial_step(
                t,
                y,
                f,
                bound,
                max_step,
                rtol,
                atol,
                mode,
                p,
                model,
                hist,
                yd,
                ytmp,
                y_new,
                cnt,
            )
        while t < bound and cnt[C_STATUS] == STATUS_OK:
            if h_abs > max_step:
                h_abs = max_step
            elif below_min_step(h_abs, t):
                h_abs = min_step(t)
            rejected = False
            while True:
                if below_min_step(h_abs, t):
                    cnt[C_STATUS] = STATUS_STEP_TOO_SMALL
                    break
                t_new = t + h_abs
                if t_new > bound:
                    t_new = bound
                h = t_new - t
                h_abs = abs(h)
                rk_step(t, y, f, h, mode, p, model, hist, yd, K, y_new, f_new, ytmp, cnt)
                accepted, h_abs = next_step(error_norm(K, h, y, y_new, rtol, atol), h_abs, rejected)
                if accepted:
                    break
                rejected = True
                cnt[C_REJECTED] += 1
            if cnt[C_STATUS] != STATUS_OK:
                break
            if not all_finite(y_new, y_new.shape[0]):
                cnt[C_STATUS] = STATUS_NONFINITE
                break
            cnt[C_STEPS] += 1
            h_last = h
            step_end_events(t_new, y_new, mode, p, model, hist, yd, g_b, dirs_b, rates_b)
            if not needs_dense(t_new, hist, g_a, side, dirs, rates, g_b, t_eval, cnt):
                # Nothing to record, no delay to feed, no event possible: move on.
                if tan is not None:  # compiled away without one: no call, no arguments
                    tangent_step(tan, t, h, y, K, mode, p, model, hist, yd)
                # the new state and slope by exchanging the arrays' roles, not by
                # copying: LLVM makes a copy loop two memcpy calls, at every step
                y, y_new = y_new, y
                f, f_new = f_new, f
                for i in range(N_EVENTS):
                    g_a[i] = g_b[i]
                sides_from(g_b, side)
                t = t_new
                continue
            dense_coefficients(t, h, y, y_new, f_new, K, mode, p, model, hist, yd, F, ytmp, cnt)
            t_next, mode_next, fs, fside = after_step(
                t, t_new, y, y_new, F, mode, p, model, hist, dde, ev, out, y_next, work
            )
            if tan is not None:
                modes = (mode, mode_next, fs)
                tangent_after(tan, (t, h, y, F), K, t_next, modes, y_next, out, p, model, hist, yd)
            y, y_next = y_next, y
            t = t_next
            if fs >= 0 or mode_next != mode:
                mode = mode_next
                forced_slot, forced_side = fs, fside
                break
            f, f_new = f_new, f
    # a loop, not y_final[:] = y: a slice copy compiles numba's shape-mismatch message
    # (string formatting, seconds of a cold compile) for a mismatch that cannot happen
    for i in range(n):
        y_final[i] = y[i]
    keep_alive(owners)
    return t, mode
