"""One model's kernels as C functions, the only per-model compiled code of the engines.

The engines' machinery (the step loop, the event search, the event handling, the
delay history, the tangent) is compiled once for every model: it calls the model
through the function pointers of a *model tuple* (:mod:`.model_calls`).  This module
is the other side: :mod:`.system`'s right-hand side, event functions, event map and
outputs compiled as C functions (``numba.cfunc``) with fixed signatures.
:mod:`.specialize` copies it, with :mod:`.system`, once per model family, with the
family's structural reads of ``ip`` compiled in as constants, so a copy compiles the
family's units and nothing else; numba caches each copy on disk.

A C function's signature is its contract with the machinery: every array C-contiguous
(``float64[::1]``, ``int64[::1]``), nothing allocated, nothing raised.  The event map
returns its ``(new mode, event kind)`` packed into one integer (C functions return a
scalar): :func:`pack_event`, unpacked by :func:`.model_calls.apply_event`.
"""

from __future__ import annotations

import numba as nb

from rubcosim.components.dop853 import dense_stages, rk_stages

from .model_calls import APPLY, DENSE, EVENTS, KIND_BASE, OUTPUTS, RHS, STEP
from .system import apply_event, events, rhs
from .system_outputs import outputs


@nb.njit(cache=True, inline="always")
def pack_event(mode: int, kind: int) -> int:
    return mode * KIND_BASE + kind


@nb.cfunc(RHS, cache=True, _nrt=False)
def rhs_c(t, y, yd, mode, p, ip, dy):  # pragma: no cover - compiled
    """dy/dt in ``mode`` (:func:`.system.rhs`)."""
    rhs(t, y, yd, mode, p, ip, dy)


@nb.cfunc(EVENTS, cache=True, _nrt=False)
def events_c(t, y, yd, mode, p, ip, g, dirs, rates):  # pragma: no cover - compiled
    """The event functions, their directions and rate slots (:func:`.system.events`)."""
    events(t, y, yd, mode, p, ip, g, dirs, rates)


@nb.cfunc(APPLY, cache=True, _nrt=False)
def apply_c(k, t, y, yd, mode, p, ip):  # pragma: no cover - compiled
    """The event map of slot ``k`` (:func:`.system.apply_event`), packed."""
    new_mode, kind = apply_event(k, t, y, yd, mode, p, ip)
    return pack_event(new_mode, kind)


@nb.cfunc(OUTPUTS, cache=True, _nrt=False)
def outputs_c(t, y, yd, mode, p, ip, out):  # pragma: no cover - compiled
    """The recorded outputs (:func:`.system.outputs`)."""
    outputs(t, y, yd, mode, p, ip, out)


@nb.njit(cache=True, inline="always")
def _rhs_in(ctx, t, y, dy):
    yd, mode, p, ip = ctx
    rhs(t, y, yd, mode, p, ip, dy)


@nb.cfunc(STEP, cache=True, _nrt=False)
def step_c(t, y, f, h, mode, p, ip, yd, K, y_new, f_new, ytmp):  # pragma: no cover - compiled
    """A DOP853 step's stages (:func:`rubcosim.components.dop853.rk_stages`) with the
    right-hand side inlined: one call a step, where the stages calling :func:`rhs_c`
    make twelve, each a wall to the optimiser (a cheap model, the impact Duffing
    oscillator, ran twice as long per period that way).  Delay-free models: the delayed
    state ``yd`` is passed through untouched."""
    rk_stages(_rhs_in, (yd, mode, p, ip), t, y, f, h, K, y_new, f_new, ytmp)


@nb.cfunc(DENSE, cache=True, _nrt=False)
def dense_c(t_old, h, y_old, y_new, f_new, mode, p, ip, yd, K, F, ytmp):  # pragma: no cover
    """The dense output of the step just taken (:func:`rubcosim.components.dop853.dense_stages`),
    the right-hand side inlined, as :func:`step_c`."""
    ctx = (yd, mode, p, ip)
    dense_stages(_rhs_in, ctx, t_old, h, y_old, y_new, f_new, K, F, ytmp)


KERNELS = (rhs_c, events_c, apply_c, outputs_c, step_c, dense_c)
