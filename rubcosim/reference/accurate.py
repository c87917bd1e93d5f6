"""The ``accurate`` engine: scipy's DOP853 steps, the shared event machinery.

Each smooth stretch between events or delay breakpoints is a fresh
``scipy.integrate.DOP853`` solver object; after every accepted step its dense
output goes through :func:`rubcosim.reference.core.after_step`, the same code
the ``fast`` engine uses.  This is the trusted reference: it can run at rtol
down to 1e-12 (scipy refuses tighter than 100 machine epsilons).
"""

from __future__ import annotations

import numpy as np

from . import accurate_calls as calls
from . import core
from .event_search import sides_from
from .model_calls import as_ref
from .system import N_DELAYED


def integrate(y0, mode, t0, t_end, p, model, tol, out, hist, dde, y_final, tan=None):
    """Same contract as :func:`rubcosim.reference.fast.integrate`, without a tangent."""
    if tan is not None:
        raise ValueError("the accurate engine carries no tangent: use the fast engine")
    from scipy.integrate import DOP853  # here: only this engine needs scipy at run time

    rtol, atol, max_step = tol
    t_eval, rec, evlog, cnt = out
    queue, qmeta = dde
    y = np.array(y0, dtype=float)
    t = float(t0)
    n = y.shape[0]
    yd = np.empty(N_DELAYED)
    g_a, side, dirs, rates, g_b, dirs_b, rates_b = core.new_event_state()
    ev = (g_a, side, dirs, rates, g_b)  # what core.after_step reads and updates
    y_next = np.empty(n)
    work = core.new_workspace(n, rec.shape[1])
    forced_slot, forced_side = -1, 0
    h_last = 0.0
    ref = as_ref(model)  # one reference for the many calls below
    cnt[core.C_EVAL] = calls.first_record(t, y, mode, p, ref, hist, t_eval, rec, yd,
                                          np.empty(rec.shape[1]))  # fmt: skip
    while t < t_end and cnt[core.C_STATUS] == core.STATUS_OK:
        bound = calls.bound(t, t_end, p, ref, queue, qmeta)
        calls.sides(t, y, mode, p, ref, hist, g_a, dirs, rates, side, yd, forced_slot, forced_side)
        forced_slot = -1
        current_mode = mode

        def fun(tt, yy, _mode=current_mode):
            return calls.rhs(tt, yy, _mode, p, ref, hist)

        # Same restart rule as the fast engine: after an event, the last accepted step.
        first_step = min(h_last, max_step, bound - t) if h_last > 0.0 else None
        solver = DOP853(
            fun, t, y, bound, rtol=rtol, atol=atol, max_step=max_step, first_step=first_step
        )
        cnt[core.C_RESTARTS] += 1
        while solver.status == "running" and cnt[core.C_STATUS] == core.STATUS_OK:
            solver.step()
            if solver.status == "failed":
                cnt[core.C_STATUS] = core.STATUS_STEP_TOO_SMALL
                break
            if not np.all(np.isfinite(solver.y)):
                cnt[core.C_STATUS] = core.STATUS_NONFINITE
                break
            cnt[core.C_STEPS] += 1
            h_last = solver.step_size
            calls.end_events(solver.t, solver.y, mode, p, ref, hist, yd, g_b, dirs_b, rates_b)
            if not core.needs_dense(solver.t, hist, g_a, side, dirs, rates, g_b, t_eval, cnt):
                g_a[:] = g_b
                sides_from(g_b, side)
                y = solver.y.copy()
                t = solver.t
                continue
            dense = solver.dense_output()
            t_next, mode_next, fs, fside = calls.after(
                solver.t_old,
                solver.t,
                dense.y_old,
                solver.y,
                dense.F,
                mode,
                p,
                ref,
                hist,
                dde,
                ev,
                out,
                y_next,
                work,
            )
            y = y_next.copy()
            t = t_next
            if fs >= 0 or mode_next != mode:
                mode = mode_next
                forced_slot, forced_side = fs, fside
                break
        cnt[core.C_RHS] += solver.nfev
    y_final[:] = y
    return t, mode
