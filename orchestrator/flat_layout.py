"""The compiled master's data: a coupled graph and its run state as flat arrays.

:class:`FlatGraph` (``G``) is what does not change during a run: the units' kinds,
parameters and orders, the connections (CSR lists of their sources), the event
protocols, what to record and the settings.  :class:`FlatState` (``S``) is
everything that does: the unit rows (:mod:`rubcosim.components.flat_units`), the
master's copy of the outputs, the input histories, the scales, the indicators'
acceleration bounds, the protocols' states, the counters, the recorded rows and
events, the snapshot and the checkpoint, and the controllers' history buffers
(``cbuf[G.ctl[k]]`` for controller ``k``, whose row holds the history's bounds, so
that restoring the rows restores the histories; ``cscr`` their scratch; ``ck_cbuf``
the checkpoint's copy).  Slot and
code constants are named here once for the kernels and the Python driver
(:mod:`.flat_master`).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba.core import types
from numba.experimental import structref

from rubcosim.components.contact_law import (  # noqa: F401 (EVENT_KINDS, EV_*: the layout's)
    EV_IMPACT,
    EV_OFF,
    EV_ON,
    EV_RELEASE,
    EV_SLIP,
    EVENT_KINDS,
    WATCHED,
)
from rubcosim.components.jit import njit
from rubcosim.components.rotor_unit import JeffcottRotorUnit, TwoMassRotorUnit
from rubcosim.components.stator_unit import (
    CasingStatorUnit,
    ElasticStatorUnit,
    RigidStatorUnit,
)

FlatGraph = namedtuple(
    "FlatGraph",
    [
        "kind", "ode", "exact", "ny", "nin", "nout", "ode_idx", "node", "p", "tol", "feed",
        "in_order", "order", "eval_order", "c_input", "src0", "src_unit", "src_out", "c_gs",
        "conn0", "conns", "nominal", "bound", "pr_kind", "pr_stator", "pr_rotor", "pr_f",
        "rec_unit", "rec_out", "out_times", "model", "iset", "fset", "omap", "mval", "ctl",
        "calls",
    ],
)  # fmt: skip

FlatState = namedtuple(
    "FlatState",
    [
        "ust", "out", "hist", "scale", "acc", "prs", "ms", "cnt", "given", "real", "scratch",
        "rows", "ev_t", "ev_kind", "ev_unit", "snap", "ck_ust", "ck_out", "ck_hist",
        "ck_scale", "ck_acc", "ck_prs", "ck_ms", "info", "finfo", "cbuf", "cscr",
        "ck_cbuf",
    ],
)  # fmt: skip


@structref.register
class FlatStateType(types.StructRef):
    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class FlatStateRef(structref.StructRefProxy):
    """:class:`FlatState`'s arrays behind one reference, as the compiled loop takes them.
    A tuple of arrays passed between compiled functions is taken apart, and each of its
    arrays reference-counted, at every call: adding one array to the tuple cost the
    loop 2.5 % of its time.  The driver keeps the tuple and reads the arrays from it."""


structref.define_proxy(FlatStateRef, FlatStateType, list(FlatState._fields))


@structref.register
class FlatGraphType(types.StructRef):
    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class FlatGraphRef(structref.StructRefProxy):
    """:class:`FlatGraph` behind one reference (as :class:`FlatStateRef`)."""


structref.define_proxy(FlatGraphRef, FlatGraphType, list(FlatGraph._fields))


def refs(G: FlatGraph, S: FlatState) -> tuple[FlatGraphRef, FlatStateRef]:
    """The compiled loop's views of the arrays of ``G`` and ``S`` (the same arrays, not
    copies), built by a cached compiled function: the proxies' own constructors compile
    anew in every process (0.8 s)."""
    return _refs(G, S)


@njit
def _refs(G, S):  # pragma: no cover - compiled
    return FlatGraphRef(*G), FlatStateRef(*S)


# integer settings (G.iset)
I_GS, I_ADAPTIVE, I_ITERATIONS, I_EVENTS, I_MAX_EVENTS, I_PI_ORDER, I_CONTROLLERS = range(7)
EVENTS_LOCATE, EVENTS_STEP, EVENTS_OFF = 0, 1, 2
# float settings (G.fset)
F_RTOL, F_ITER_TOL, F_MIN_STEP, F_MAX_STEP, F_T_TOL, F_PERIOD, F_T_END = range(7)
# master scalars (S.ms); the first MS_SAVED are what a checkpoint restores
MS_TIME, MS_H, MS_ERR_PREV, MS_K_OUT, MS_N_EVENTS, MS_RECENT = range(6)
MS_SAVED = 6
MS_SINCE_CHECKPOINT, MS_SNAP_UNTIL, MS_AT_FLOOR, MS_STARTED = range(6, 10)
MS_SIZE = 10

# counters (S.cnt), named as the Python master's
COUNTERS = (
    "steps", "unit_steps", "snapshots", "rejected", "replays", "event_probes", "accepted",
    "iterations", "events", "late_events", "events_impact", "events_release", "events_slip",
    "events_contact_on", "events_contact_off",
)  # fmt: skip
(
    N_STEPS, N_UNIT_STEPS, N_SNAPSHOTS, N_REJECTED, N_REPLAYS, N_PROBES, N_ACCEPTED,
    N_ITERATIONS, N_EVENTS, N_LATE, N_EV0,
) = range(11)  # fmt: skip

# event kinds (N_EV0 + kind is the kind's counter)

# protocols
PR_RIGID, PR_ELASTIC = 0, 1
PF_V_CHAT, PF_MIN_FLIGHT = 0, 1  # G.pr_f columns


# stator output and rotor input slots the protocols use: positions in the unit
# classes' signal tuples, read off the classes so the two cannot drift apart
def _slots(signals: tuple, *names: str) -> tuple[int, ...]:
    order = [s.name for s in signals]
    return tuple(order.index(n) for n in names)


RIGID_GAP, RIGID_GAP_RATE, RIGID_VX_PLUS, RIGID_VY_PLUS = _slots(
    RigidStatorUnit.outputs, "gap", "gap_rate", "vx_plus", "vy_plus"
)
RIGID_NORMAL, RIGID_SLIP, RIGID_HOLD_MARGIN, RIGID_HOLD_FORCE = _slots(
    RigidStatorUnit.outputs, "normal_force", "slip", "hold_margin", "hold_force"
)
PENALTY_GAP, PENALTY_GAP_RATE = _slots(ElasticStatorUnit.outputs, "gap", "gap_rate")
assert _slots(CasingStatorUnit.outputs, "gap", "gap_rate") == (PENALTY_GAP, PENALTY_GAP_RATE)
(RIGID_MODE_INPUT,) = _slots(RigidStatorUnit.inputs, "contact_mode")
RESET_VX_INPUT, RESET_VY_INPUT, RESET_COUNTER_INPUT = _slots(
    JeffcottRotorUnit.inputs, "reset_vx", "reset_vy", "reset_counter"
)
assert _slots(TwoMassRotorUnit.inputs, "reset_vx", "reset_vy", "reset_counter") == (
    RESET_VX_INPUT,
    RESET_VY_INPUT,
    RESET_COUNTER_INPUT,
)


# What the protocols watch (rubcosim.components.contact_law.WATCHED) as numbers, for the
# compiled master: WATCH[protocol kind, state, row] = (output slot, direction, event
# kind, rate slot or -1), rows past the state's last with output slot -1.
def _watch_table() -> np.ndarray:
    kinds = {PR_RIGID: ("rigid", RigidStatorUnit), PR_ELASTIC: ("penalty", ElasticStatorUnit)}
    rows = max(len(r) for table in WATCHED.values() for r in table)
    states = max(len(table) for table in WATCHED.values())
    watch = np.full((len(kinds), states, rows, 4), -1, np.int64)
    for code, (kind, unit) in kinds.items():
        for state, watched in enumerate(WATCHED[kind]):
            for j, (output, direction, event, rate) in enumerate(watched):
                rate_slot = _slots(unit.outputs, rate)[0] if rate else -1
                out_slot = _slots(unit.outputs, output)[0]
                watch[code, state, j] = out_slot, direction, EVENT_KINDS.index(event), rate_slot
    return watch


WATCH = _watch_table()

# how a run ends or pauses (what the loop returns), and why it failed (S.info)
RUNNING, DONE, PAUSED, NEED_ROOM, FAILED = range(5)
INFO_CODE, INFO_UNIT, INFO_DETAIL = range(3)
FAIL_STEP, FAIL_OUTPUT, FAIL_MACRO_STEP, FAIL_STALL, FAIL_NOT_FINITE, FAIL_UNSTABLE = range(1, 7)
FAIL_EVENTS = 7
FI_H, FI_TIME, FI_VALUE = range(3)  # S.finfo slots

CHECKPOINT_EVERY = 64
STALL_STEPS = 1000
