"""Single-DOF impact oscillator: one declaration, its kernels compiled by the reference
and stepped by the co-simulation unit (a hybrid unit type, :mod:`.hybrid`).

``x'' + b x' + a x + c3 x^3 = f cos(w t) + force + F_stop`` per unit mass, with
the stops of :mod:`.oscillator`.  At a rigid barrier Newton's law ``v+ = -R v-``
applies; a rebound slower than ``chatter_tol * |D| w`` ends a chattering
sequence and the mass sticks to the barrier while the free acceleration pushes
it into the barrier, until that acceleration changes sign (the release event).
The edges of an elastic stop are events too (the force has a kink there).
Modes: free, stuck on +D, stuck on -D.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from .declaration import FmuIdentity, State, UnitType
from .hybrid import HybridKernels, HybridUnit, input_value
from .hybrid_dispatch import KIND_CONTACT_OFF, KIND_CONTACT_ON, KIND_IMPACT, KIND_RELEASE
from .jit import njit
from .oscillator import (
    OSCILLATOR_PARAMS,
    STOP_ELASTIC_ONE,
    STOP_ELASTIC_TWO,
    STOP_KINDS,
    STOP_NONE,
    STOP_RIGID_ONE,
    STOP_RIGID_TWO,
    barrier_gap,
    check_oscillator,
    elastic_stop_force,
    free_acceleration,
    pressing,
    stop_impact,
)
from .parameters import positive
from .unit import INTEGRATOR_PARAMS, integer_signal, real_signal

FREE, STUCK_UPPER, STUCK_LOWER = 0, 1, 2
# parameter array slots (pack below); the input acceleration from INPUTS on
A, B, C3, F, WF, DB, RR, KSTOP, STOP, VCHAT, INPUTS = range(11)

CHATTER_TOL = positive(
    "chatter_tol",
    1e-10,
    "1",
    "rebound speed, in units of |barrier| * forcing_frequency, below which the mass sticks",
)


@njit(inline="always")
def acceleration(t: float, x: float, v: float, p: np.ndarray) -> float:
    """Free acceleration plus the input one (another unit's force per unit mass), m/s^2."""
    acc = free_acceleration(t, x, v, p[A], p[B], p[C3], p[F], p[WF])
    return acc + input_value(p, INPUTS, 0, t)


@njit(inline="always")
def resting_acceleration(t: float, side: int, p: np.ndarray) -> float:
    """Acceleration (m/s^2) of the mass at rest on the barrier on ``side`` (+1: +D)."""
    return acceleration(t, side * p[DB], 0.0, p)


@njit(inline="always")
def rhs(t: float, y: np.ndarray, mode: int, p: np.ndarray, dy: np.ndarray) -> None:
    """dy/dt = (v, a); at rest while stuck on a barrier."""
    if mode != FREE:
        dy[0] = 0.0
        dy[1] = 0.0
        return
    acc = acceleration(t, y[0], y[1], p)
    acc += elastic_stop_force(y[0], int(p[STOP]), p[DB], p[KSTOP])
    dy[0] = y[1]
    dy[1] = acc


@njit(inline="always")
def events(t, y, mode, p, g, dirs, rates) -> None:
    """Slot 0: the barrier +D (impact, or an edge of an elastic stop) or, stuck there,
    its release; slot 2: the same for -D; slots 1 and 3: their rates."""
    stop = int(p[STOP])
    if stop == STOP_NONE:
        return
    D = p[DB]
    if mode == STUCK_UPPER:
        g[0] = pressing(1, resting_acceleration(t, 1, p))
        dirs[0] = -1
        return
    if mode == STUCK_LOWER:
        g[2] = pressing(-1, resting_acceleration(t, -1, p))
        dirs[2] = -1
        return
    rigid = stop == STOP_RIGID_ONE or stop == STOP_RIGID_TWO
    g[0] = barrier_gap(y[0], D, 1)
    g[1] = -y[1]
    dirs[0] = -1 if rigid else 2
    rates[0] = 1
    if stop == STOP_RIGID_TWO or stop == STOP_ELASTIC_TWO:
        g[2] = barrier_gap(y[0], D, -1)
        g[3] = y[1]
        dirs[2] = -1 if rigid else 2
        rates[2] = 3


@njit
def apply(k: int, t: float, y: np.ndarray, mode: int, p: np.ndarray):
    """Event of slot ``k``: crossing an elastic stop's edge, release from a barrier,
    or an impact (which may end chattering and stick).  Returns ``(mode, kind)``."""
    stop = int(p[STOP])
    if stop == STOP_ELASTIC_ONE or stop == STOP_ELASTIC_TWO:
        entering = y[1] > 0.0 if k == 0 else y[1] < 0.0
        return mode, KIND_CONTACT_ON if entering else KIND_CONTACT_OFF
    if mode != FREE:
        return FREE, KIND_RELEASE
    side = 1 if k == 0 else -1
    y[0] = side * p[DB]  # the locator leaves the mass within round-off of the barrier
    v, stuck = stop_impact(y[1], p[RR], p[VCHAT], side, resting_acceleration(t, side, p))
    y[1] = v
    if stuck:
        return (STUCK_UPPER if k == 0 else STUCK_LOWER), KIND_IMPACT
    return FREE, KIND_IMPACT


@njit
def output(t: float, y: np.ndarray, mode: int, p: np.ndarray, out: np.ndarray) -> None:
    """x, v and contact (0 free, 1 inside an elastic stop, 2 stuck on a barrier)."""
    out[0] = y[0]
    out[1] = y[1]
    out[2] = 0.0 if mode == FREE else 2.0
    stop = int(p[STOP])
    if (stop == STOP_ELASTIC_ONE or stop == STOP_ELASTIC_TWO) and (
        y[0] > p[DB] or (stop == STOP_ELASTIC_TWO and y[0] < -p[DB])
    ):
        out[2] = 1.0


def pack(q: Mapping[str, Any]) -> np.ndarray:
    """The kernels' parameters (slots A..VCHAT); the chattering speed is
    ``chatter_tol * |D| * w`` (|D| = 1 when the barrier is at 0)."""
    length = abs(q["barrier"]) if q["barrier"] != 0.0 else 1.0
    v_chat = q.get("chatter_tol", CHATTER_TOL.default) * (length * q["forcing_frequency"])
    names = ("linear_stiffness", "damping", "cubic_stiffness", "forcing_amplitude")
    stop = ("forcing_frequency", "barrier", "restitution", "stop_stiffness")
    kind = float(STOP_KINDS.index(q["stop"]))
    return np.array([*(q[n] for n in (*names, *stop)), kind, v_chat], dtype=float)


def initial(q: Mapping[str, Any]) -> tuple[np.ndarray, int]:
    check_oscillator(dict(q))
    return np.array([q["x0"], q["v0"]]), FREE


KERNELS = HybridKernels(
    rhs,
    events,
    apply,
    output,
    ("x", "v", "contact"),
    pack,
    initial,
    inputs=("force",),
    input_base=INPUTS,
)


class ImpactOscillatorUnit(HybridUnit):
    """``x'' + b x' + a x + c3 x^3 = f cos(w t) + force + F_stop`` with rigid or elastic stops."""

    role = "oscillator"
    type_name = "impact_oscillator"
    summary = "single-DOF (Duffing) impact oscillator with rigid or elastic stops"
    params_spec = (*OSCILLATOR_PARAMS, *INTEGRATOR_PARAMS, CHATTER_TOL)
    kernels = KERNELS
    # "stuck" by mode: FREE 0, STUCK_UPPER +1, STUCK_LOWER -1
    mode_outputs = {"stuck": tuple({STUCK_UPPER: 1, STUCK_LOWER: -1}.get(m, 0) for m in range(3))}
    inputs = (real_signal("force", "m/s^2", "external force per unit mass"),)
    outputs = (
        real_signal("x", "m", "displacement"),
        real_signal("v", "m/s", "velocity"),
        real_signal("contact", "1", "0 free, 1 in an elastic stop, 2 stuck on a barrier"),
        integer_signal("stuck", "1 stuck on the barrier +D, -1 on -D, 0 free"),
        integer_signal("impacts", "number of impacts on a rigid stop so far"),
        integer_signal("mode", "0 free, 1 stuck on +D, 2 stuck on -D"),
    )

    def _check(self, params: Mapping[str, Any]) -> None:
        check_oscillator(dict(params), self.name)


IMPACT_OSCILLATOR = UnitType(
    ImpactOscillatorUnit,
    OSCILLATOR_PARAMS,
    FmuIdentity("RubcosimImpactOscillator"),
    states=(State("x", "m", "length"), State("v", "m/s", "velocity")),
    # the barrier's distance, or 1 (a nondimensional oscillator) when it is at 0
    length_scale=lambda q: abs(q["barrier"]) if q["barrier"] != 0.0 else 1.0,
    clock=lambda q: (q["forcing_frequency"], q["forcing_frequency"]),
    kernels=(free_acceleration, elastic_stop_force, barrier_gap, pressing, stop_impact),
    hybrid=KERNELS,
)
