"""One macro step of the compiled master: inputs, unit steps, settling, coupling error.

The compiled counterpart of :meth:`.master.Master._round`, ``settle``, ``_error``
and ``_step``, over the arrays of :mod:`.flat_layout` (``G`` the graph, ``S`` the
state).  Every function returns a status (0: fine); a nonzero one is recorded in
``S.info`` and ends the step, as a :class:`StepError` does in the Python master.
"""

from __future__ import annotations

from rubcosim.components.flat_units import K_HYBRID, STEP_OK, U
from rubcosim.components.jit import njit
from rubcosim.components.kernels import polynomial_at

from .coupling_kernels import polynomial3
from .flat_layout import (
    F_ITER_TOL,
    F_RTOL,
    FAIL_OUTPUT,
    FAIL_STEP,
    I_GS,
    I_ITERATIONS,
    INFO_CODE,
    INFO_DETAIL,
    INFO_UNIT,
    MS_TIME,
    N_ITERATIONS,
    N_UNIT_STEPS,
)


@njit(inline="always")
def fail(S, code, unit, detail):
    S.info[INFO_CODE] = code
    S.info[INFO_UNIT] = unit
    S.info[INFO_DETAIL] = detail
    return code


@njit(inline="always")
def unit_outputs(G, S, k):
    """Refresh the master's copy of unit ``k``'s outputs (``get_outputs``), through the
    C functions of :mod:`rubcosim.components.flat_calls`."""
    kind = G.kind[k]
    if kind < K_HYBRID:  # the rotors, stators and bearings: the most common, four arguments
        status = G.calls[1](kind, G.p[k], S.ust[k], S.out[k])
    else:
        status = G.calls[2](kind, G.ny[k], G.node[k], G.nout[k], G.ode_idx[k], G.omap[k],
                            G.mval[k], G.p[k], S.ust[k], S.cbuf[max(G.ctl[k], 0)], S.cscr,
                            S.out[k])  # fmt: skip
    if status != STEP_OK:
        return fail(S, FAIL_OUTPUT, k, status)
    return 0


@njit(inline="always")
def unit_step(G, S, k, t, h):
    """Advance unit ``k`` from ``t`` by ``h`` (s), through the C function
    :func:`rubcosim.components.flat_calls.step_c`."""
    A, Bu, a, b, c = G.model
    status = G.calls[0](G.kind[k], G.ode[k], G.exact[k], G.ny[k], G.nin[k], G.node[k],
                        G.ode_idx[k], G.p[k], G.tol[k], A, Bu, a, b, c, S.ust[k],
                        S.cbuf[max(G.ctl[k], 0)], S.cscr, t, h)  # fmt: skip
    if status != STEP_OK:
        return fail(S, FAIL_STEP, k, status)
    return 0


@njit(inline="always")
def set_input(S, k, i, value):
    """Set input ``i`` of unit ``k`` (its derivatives cleared: held constant)."""
    j = U + 3 * i
    S.ust[k, j] = value
    S.ust[k, j + 1] = 0.0
    S.ust[k, j + 2] = 0.0


@njit(inline="always")
def conn_sum(G, S, c):
    total = 0.0
    for j in range(G.src0[c], G.src0[c + 1]):
        total += S.out[G.src_unit[j], G.src_out[j]]
    return total


@njit(inline="always")
def settle(G, S, fresh, real):
    """Set every connected input from its sources' outputs and refresh the outputs
    (:meth:`.master.Master.settle`); the input values go to ``real``."""
    n = G.kind.shape[0]
    for late in range(2):
        for e in range(n):
            k = G.eval_order[e]
            if late and G.feed[k]:
                continue
            for q in range(G.conn0[k], G.conn0[k + 1]):
                c = G.conns[q]
                value = conn_sum(G, S, c)
                real[c] = value
                set_input(S, k, G.c_input[c], value)
            if not late and not (fresh and not G.feed[k]) and unit_outputs(G, S, k):
                return 1
    return 0


@njit(inline="always")
def _input_polynomial(S, c, t, h, end, have_end, order):
    hist = S.hist[c]
    n = int(hist[0])
    ts = [0.0, 0.0, 0.0]
    us = [0.0, 0.0, 0.0]
    m = 0
    first = n - min(order + 1, n) if not have_end else n - min(order, n)
    for i in range(first, n):
        ts[m] = hist[1 + 2 * i]
        us[m] = hist[2 + 2 * i]
        m += 1
    if have_end:
        ts[m] = t + h
        us[m] = end
        m += 1
    return polynomial3(m, ts[0], us[0], ts[1], us[1], ts[2], us[2], t)


@njit(inline="always")
def round_(G, S, t, h, use_ends):
    """Step every unit from ``t`` to ``t + h`` (:meth:`.master.Master._round`): the
    values the units were given for ``t + h`` go to ``S.given``, the values their
    sources gave there to ``S.real`` (``use_ends``: the inputs end on ``S.real``)."""
    n = G.kind.shape[0]
    gs = G.iset[I_GS] != 0
    for oi in range(n):
        k = G.order[oi]
        po = G.in_order[k]
        for q in range(G.conn0[k], G.conn0[k + 1]):
            c = G.conns[q]
            have_end = use_ends
            end = S.real[c] if use_ends else 0.0
            if not have_end and gs and G.c_gs[c]:
                end = conn_sum(G, S, c)
                have_end = True
            v, d1, d2 = _input_polynomial(S, c, t, h, end, have_end, po)
            j = U + 3 * G.c_input[c]
            S.ust[k, j] = v
            if po:
                S.ust[k, j + 1] = d1
                S.ust[k, j + 2] = d2
                S.given[c] = polynomial_at(v, d1, d2, h)
            else:
                S.ust[k, j + 1] = 0.0
                S.ust[k, j + 2] = 0.0
                S.given[c] = v
        if unit_step(G, S, k, t, h):
            return 1
        S.cnt[N_UNIT_STEPS] += 1
        if G.feed[k]:
            # its outputs at t + h follow its inputs there
            for q in range(G.conn0[k], G.conn0[k + 1]):
                c = G.conns[q]
                set_input(S, k, G.c_input[c], S.given[c])
        if unit_outputs(G, S, k):
            return 1
    S.ms[MS_TIME] = t + h
    return settle(G, S, True, S.real)


@njit(inline="always")
def coupling_error(S, tol):
    """The largest coupling error relative to ``tol`` times the signal's scale."""
    err = 0.0
    for c in range(S.real.shape[0]):
        g = S.given[c]
        r = S.real[c]
        scale = max(S.scale[c], abs(r), abs(g))
        if g != r:
            err = max(err, abs(g - r) / (tol * scale))
    return err


@njit
def step(G, S, t, h):
    """One macro step with the fixed-point iteration if asked (``_step``); returns
    ``(status, error norm of the first pass)``."""
    if round_(G, S, t, h, False):
        return 1, 0.0
    err = coupling_error(S, G.fset[F_RTOL])
    for _ in range(1, G.iset[I_ITERATIONS]):
        if coupling_error(S, G.fset[F_ITER_TOL]) <= 1.0:
            break
        S.ust[:] = S.snap
        if round_(G, S, t, h, True):
            return 1, 0.0
        S.cnt[N_ITERATIONS] += 1
    return 0, err
