"""The compiled calls of the ``accurate`` engine, which is a Python loop over scipy's
steps: each takes the model behind one reference (:class:`.model_calls.ModelRef`) and
hands the machinery its model tuple.  Passing the tuple itself from Python made numba
look up the address of each of the model's C functions at every call, and this engine
calls compiled code at every Runge-Kutta stage."""

from __future__ import annotations

import numba as nb

from . import core
from .event_search import start_sides, step_end_events
from .history import full_rhs_alloc, next_breakpoint
from .model_calls import unpack


@nb.njit(cache=True)
def rhs(t, y, mode, p, ref, hist):
    """dy/dt at (t, y) in ``mode``, a new array (:func:`.history.full_rhs_alloc`)."""
    return full_rhs_alloc(t, y, mode, p, unpack(ref), hist)


@nb.njit(cache=True)
def first_record(t, y, mode, p, ref, hist, t_eval, rec, yd, obuf):
    """:func:`.core.record_point` from the start."""
    return core.record_point(t, y, mode, p, unpack(ref), hist, t_eval, 0, rec, yd, obuf)


@nb.njit(cache=True)
def bound(t, t_end, p, ref, queue, qmeta):
    """:func:`.history.next_breakpoint`."""
    return next_breakpoint(t, t_end, p, unpack(ref), queue, qmeta)


@nb.njit(cache=True)
def sides(t, y, mode, p, ref, hist, g, dirs, rates, side, yd, forced_slot, forced_side):
    """:func:`.event_search.start_sides`."""
    start_sides(t, y, mode, p, unpack(ref), hist, g, dirs, rates, side, yd, forced_slot,
                forced_side)  # fmt: skip


@nb.njit(cache=True)
def end_events(t, y, mode, p, ref, hist, yd, g_b, dirs_b, rates_b):
    """:func:`.event_search.step_end_events`."""
    step_end_events(t, y, mode, p, unpack(ref), hist, yd, g_b, dirs_b, rates_b)


@nb.njit(cache=True)
def after(t_a, t_b, y_old, y_b, F, mode, p, ref, hist, dde, ev, out, y_out, work):
    """:func:`.core.after_step`."""
    model = unpack(ref)
    return core.after_step(t_a, t_b, y_old, y_b, F, mode, p, model, hist, dde, ev, out, y_out, work)
